// Ray generation and the robust ray/box test. The f64 twins are
// src/scene/camera.rs (CameraRays::ray) and src/scene/geometry.rs (intersect_box).
#ifndef MORPHRAY_GEOMETRY_GLSL
#define MORPHRAY_GEOMETRY_GLSL

const float MIN_DIRECTION = 1e-20;

// World-space ray through the centre of `pixel` (y down), unit direction.
void camera_ray_world(uvec2 pixel, out vec3 origin, out vec3 direction) {
    vec2 ndc = vec2((float(pixel.x) + 0.5) / float(params.image.x) * 2.0 - 1.0,
                    1.0 - (float(pixel.y) + 0.5) / float(params.image.y) * 2.0);
    vec2 s = ndc * vec2(params.camera_right.w, params.camera_up.w);
    if (params.camera_origin.w > 0.5) {
        origin = params.camera_origin.xyz + params.camera_right.xyz * s.x + params.camera_up.xyz * s.y;
        direction = params.camera_forward.xyz;
    } else {
        origin = params.camera_origin.xyz;
        direction = normalize(params.camera_forward.xyz + params.camera_right.xyz * s.x + params.camera_up.xyz * s.y);
    }
}

// Slab test against [-0.5, dims - 0.5] in index space. Zero direction components become
// +-1e-20 with their sign (no 0 * inf); returns false on a miss or a box behind the ray.
bool intersect_box(vec3 origin, vec3 direction, vec3 dims, out float t_near, out float t_far) {
    vec3 d = direction;
    for (int a = 0; a < 3; a++) {
        if (abs(d[a]) < MIN_DIRECTION) {
            d[a] = d[a] < 0.0 ? -MIN_DIRECTION : MIN_DIRECTION;
        }
    }
    vec3 inv = 1.0 / d;
    vec3 t_lo = (vec3(-0.5) - origin) * inv;
    vec3 t_hi = (dims - vec3(0.5) - origin) * inv;
    vec3 t_min = min(t_lo, t_hi);
    vec3 t_max = max(t_lo, t_hi);
    t_near = max(max(t_min.x, t_min.y), t_min.z);
    t_far = min(min(t_max.x, t_max.y), t_max.z);
    bool hit = t_near <= t_far && t_far >= 0.0;
    t_near = max(t_near, 0.0);
    return hit;
}

// Index-space position to normalized texture coordinates (voxel centres at integers).
vec3 index_to_texture(vec3 p, vec3 dims) {
    return (p + 0.5) / dims;
}

#endif
