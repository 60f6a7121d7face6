// Crop box and clip planes (issue 16 item 2): the ray interval is cut to the kept region before
// any sample is placed, so nothing outside it is fetched and empty-space skipping and bricking,
// which move along those samples only, respect the cut. The f64 twin is
// src/scene/clip.rs (intersect_clipped); decisions are documented there.
#ifndef MORPHRAY_CLIP_GLSL
#define MORPHRAY_CLIP_GLSL

// Narrows [t_near, t_far] (already the volume box's interval) to the crop box
// [crop_lo, crop_hi] and every plane's half-space n . p + w >= 0 (index space, unit n).
// Returns false when nothing is left.
bool clip_ray(vec3 origin, vec3 direction, vec3 dims, inout float t_near, inout float t_far) {
    float tolerance = face_tolerance(origin, dims);
    float lo_t = -3.0e38;
    float hi_t = 3.0e38;
    bool inside_parallel = true;
    for (int a = 0; a < 3; a++) {
        float lo_face = params.crop_lo[a];
        float hi_face = params.crop_hi[a];
        if (abs(direction[a]) < MIN_DIRECTION) {
            inside_parallel = inside_parallel && origin[a] >= lo_face - tolerance
                && origin[a] <= hi_face + tolerance;
            continue;
        }
        float inv = 1.0 / direction[a];
        float t_lo = (lo_face - origin[a]) * inv;
        float t_hi = (hi_face - origin[a]) * inv;
        lo_t = max(lo_t, min(t_lo, t_hi));
        hi_t = min(hi_t, max(t_lo, t_hi));
    }
    uint planes = uint(params.crop_lo.w);
    for (uint i = 0u; i < planes && i < 4u; i++) {
        vec4 plane = params.clip_planes[i];
        float side = dot(plane.xyz, origin) + plane.w;
        float rate = dot(plane.xyz, direction);
        if (abs(rate) < MIN_DIRECTION) {
            inside_parallel = inside_parallel && side >= 0.0;
            continue;
        }
        float t = -side / rate;
        if (rate > 0.0) {
            lo_t = max(lo_t, t);
        } else {
            hi_t = min(hi_t, t);
        }
    }
    t_near = max(t_near, max(lo_t, 0.0));
    t_far = min(t_far, hi_t);
    return inside_parallel && t_near <= t_far && t_far >= 0.0;
}

// Whether index position p is kept: inside the volume box, the crop box and every plane's
// half-space (the depth cues' occluders; twin: IndexClip::keeps).
bool kept(vec3 p) {
    vec3 lo = max(params.crop_lo.xyz, vec3(-0.5));
    vec3 hi = min(params.crop_hi.xyz, params.dims.xyz - 0.5);
    if (any(lessThan(p, lo)) || any(greaterThan(p, hi))) {
        return false;
    }
    uint planes = uint(params.crop_lo.w);
    for (uint i = 0u; i < planes && i < 4u; i++) {
        vec4 plane = params.clip_planes[i];
        if (dot(plane.xyz, p) + plane.w < 0.0) {
            return false;
        }
    }
    return true;
}

#endif
