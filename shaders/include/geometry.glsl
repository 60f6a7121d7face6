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

// How far outside a face a ray parallel to it may lie and still count as on the face, in voxels.
// f32 rounding, and the fused multiply-adds a GPU compiler may form (NVIDIA's do; lavapipe's do
// not), move a ray origin that lies exactly on a face by a few ulps of its magnitude: without a
// tolerance such a ray hits on one device and misses on another. Within it, clamp-to-edge sampling
// returns the border voxels, exactly what a ray on the face sees. 1e-4 voxel plus 3e-6 of the
// magnitude (about 25 f32 ulps) is far above that rounding and far below any real offset. Rays
// that cross the faces keep the exact slab parameters (their chord is not lengthened).
float face_tolerance(vec3 origin, vec3 dims) {
    vec3 o = abs(origin);
    float scale = max(max(max(o.x, o.y), o.z), max(max(dims.x, dims.y), dims.z));
    return 1e-4 + 3e-6 * scale;
}

// Slab test against the closed box [-0.5, dims - 0.5] in index space. An axis whose direction
// component is below 1e-20 in magnitude (+-0 included: GPUs need not keep the sign of zero) is a
// containment test instead of a division (no 0 * inf): inside the slab, boundary included and
// widened by face_tolerance, constrains nothing; outside misses. Returns false on a miss or a
// box behind the ray.
bool intersect_box(vec3 origin, vec3 direction, vec3 dims, out float t_near, out float t_far) {
    t_near = -3.0e38;
    t_far = 3.0e38;
    bool inside_parallel_slabs = true;
    float tolerance = face_tolerance(origin, dims);
    for (int a = 0; a < 3; a++) {
        float lo_face = -0.5;
        float hi_face = dims[a] - 0.5;
        if (abs(direction[a]) < MIN_DIRECTION) {
            inside_parallel_slabs = inside_parallel_slabs && origin[a] >= lo_face - tolerance
                && origin[a] <= hi_face + tolerance;
            continue;
        }
        float inv = 1.0 / direction[a];
        float t_lo = (lo_face - origin[a]) * inv;
        float t_hi = (hi_face - origin[a]) * inv;
        t_near = max(t_near, min(t_lo, t_hi));
        t_far = min(t_far, max(t_lo, t_hi));
    }
    bool hit = inside_parallel_slabs && t_near <= t_far && t_far >= 0.0;
    t_near = max(t_near, 0.0);
    return hit;
}

// Index-space position to normalized texture coordinates (voxel centres at integers).
vec3 index_to_texture(vec3 p, vec3 dims) {
    return (p + 0.5) / dims;
}

#endif
