// Studio lighting, the matcap and depth cues (issue 34 item 2). The f64 twin is
// src/reference/raymarch/lighting.rs; src/scene/lighting.rs documents the choices.
//
// LIGHTING == 1 (studio): per sample, the normal turned to face the viewer, an ambient term, a
// headlight fill on |n . v|, a key light from the upper left (params.key_light.xyz, fixed to the
// camera) with a Blinn highlight, and silhouette darkening (1 - s (1 - |n . v|)^2) that draws the
// outline of every surface seen edge-on. No pow(): the highlight's exponent 32 is five squarings.
//
// DEPTH_CUES: ambient occlusion and a soft shadow toward the key light, evaluated once per ray at
// the visible surface (the sample where the accumulated opacity first reaches CUE_SURFACE_ALPHA
// = 0.05: at 0.5 a ray that enters a gently rising edge is millimetres deep and the cues drew
// iso-depth rings; at 0.2 a few pixels' points still lay inside the tissue and their occlusion
// went black, a speckle on the phantom's gyral crowns), not per sample: 14 fetches per pixel instead of 12 per classified sample.
// Both integrate the classified opacity f(v) (per mm, the windows only: matter occludes whether
// or not it is on an edge; scaled by CUE_EXTINCTION) along a short ray from CUE_BACKOFF units back
// along the view ray, at the middle of equal intervals (jittered offsets only added noise): the
// occlusion along the normal's side with less matter (an obscurance along the normal: a sulcus's
// opposite wall darkens its floor; the ray goes halfway toward the viewer), the shadow toward the
// key light. Outside the volume and in
// cut-away regions nothing occludes.
#ifndef MORPHRAY_LIGHTING_GLSL
#define MORPHRAY_LIGHTING_GLSL

const uint OCCLUSION_SAMPLES = 4u;
const uint SHADOW_SAMPLES = 8u;
// In units of max(1 mm, the finest voxel side) (params.cap.y): a fixed millimetre is less
// than a voxel on a coarse grid, where the probes then read one voxel's noise.
const float CUE_BACKOFF = 1.5;
const float CUE_SIDE_PROBE = 1.5;
const float CUE_EXTINCTION = 0.5;
const float CUE_SURFACE_ALPHA = 0.05;

// x^32 by five squarings.
float pow32(float x) {
    float x2 = x * x;
    float x4 = x2 * x2;
    float x8 = x4 * x4;
    float x16 = x8 * x8;
    return x16 * x16;
}

// The studio model (twin: shade_studio). `view_direction` is the unit ray direction.
vec3 shade_studio(vec3 colour, vec3 normal, vec3 view_direction) {
    float len2 = dot(normal, normal);
    if (len2 < 1e-6) {
        return colour;
    }
    vec3 n = normal * inversesqrt(len2);
    float ndv = dot(n, view_direction);
    if (ndv > 0.0) {
        n = -n;
    }
    float facing = abs(ndv);
    vec3 light = params.key_light.xyz;
    float key = max(dot(n, light), 0.0);
    vec3 halfway = normalize(light - view_direction);
    float highlight = 0.2 * pow32(max(dot(n, halfway), 0.0));
    float rim = 1.0 - facing;
    float outline = 1.0 - params.key_light.w * rim * rim;
    vec3 lit = (colour * (0.3 + 0.3 * facing + 0.55 * key) + vec3(highlight)) * outline;
    return min(lit, vec3(1.0));
}

// The matcap's texel (x, y), RGB in 0..1.
const int MATCAP_SIDE = 256;
vec3 matcap_texel(int x, int y) {
    return unpackUnorm4x8(matcap.texels[y * MATCAP_SIDE + x]).rgb;
}

// The matcap at camera-space normal components (x, y) = (n . right, n . up): the texel they fall
// in, clamped to the image (twin: MatcapImage::sample). One load: bilinear (four loads) made a
// matcap frame 1.48x the headlight's on the H200, where the raymarch waits on each dependent load.
vec3 matcap_rgb(float x, float y) {
    int tx = clamp(int(floor((0.5 + 0.5 * x) * float(MATCAP_SIDE))), 0, MATCAP_SIDE - 1);
    int ty = clamp(int(floor((0.5 - 0.5 * y) * float(MATCAP_SIDE))), 0, MATCAP_SIDE - 1);
    return matcap_texel(tx, ty);
}

// The matcap model (twin: shade_matcap): the colour times the matcap at the normal turned to face
// the viewer, in camera coordinates.
vec3 shade_matcap(vec3 colour, vec3 normal, vec3 view_direction) {
    float len2 = dot(normal, normal);
    if (len2 < 1e-6) {
        return colour;
    }
    vec3 n = normal * inversesqrt(len2);
    if (dot(n, view_direction) > 0.0) {
        n = -n;
    }
    vec3 m = matcap_rgb(dot(n, params.camera_right.xyz), dot(n, params.camera_up.xyz));
    return min(colour * m, vec3(1.0));
}

// exp(-integral of f(v) dl) over `count` samples at reach * (j + 1) / count mm from p along the
// index-space direction `step_index` (per mm). `density` is the caller's classified opacity at an
// index position (0 outside what is kept).
float cue_transmittance(vec3 p, vec3 step_index, float reach_mm, uint count) {
    float dl = reach_mm / float(count);
    float sum = 0.0;
    for (uint j = 0u; j < count; j++) {
        sum += cue_density(p + step_index * (dl * (float(j) + 0.5)));
    }
    return exp(-CUE_EXTINCTION * sum * dl);
}

// The factor the surface's colour is multiplied by: occlusion and shadow, each mixed with 1 by its
// strength. `normal` is world space (any length; 0: the occlusion looks back along the ray).
float surface_cues(vec3 p, vec3 normal, vec3 view_direction) {
    mat3 to_index = mat3(params.world_to_index);
    // From CUE_BACKOFF units back along the ray: the surface sample lies inside the tissue, and
    // rays from there would measure the tissue itself (noise, not occlusion).
    float unit = params.cap.y;
    vec3 origin = p - to_index * view_direction * (CUE_BACKOFF * unit);
    vec3 outward = -view_direction;
    float len2 = dot(normal, normal);
    if (len2 >= 1e-6) {
        // The normal's side with less matter CUE_SIDE_PROBE units away: the gradient's sign depends
        // on the contrast (T1 tissue is brighter than CSF, T2 darker), and its side relative to
        // the ray flips at grazing angles, where either choice would be noise.
        vec3 n = normal * inversesqrt(len2);
        vec3 n_index = to_index * n * (CUE_SIDE_PROBE * unit);
        outward = cue_density(p + n_index) <= cue_density(p - n_index) ? n : -n;
    }
    // Halfway between the open side and the viewer: along the normal alone, a crown's noisy
    // normal sent some pixels' rays into the tissue (a speckle of black pixels); toward the
    // viewer the ray came through empty space, so the halfway ray only meets what overhangs.
    vec3 halfway_open = outward - view_direction;
    float halfway_len2 = dot(halfway_open, halfway_open);
    vec3 occlusion_direction = halfway_len2 > 1e-6 ? halfway_open * inversesqrt(halfway_len2) : -view_direction;
    float occlusion = cue_transmittance(origin, to_index * occlusion_direction, params.cues.z, OCCLUSION_SAMPLES);
    float shadow = cue_transmittance(origin, to_index * params.key_light.xyz, params.cues.w, SHADOW_SAMPLES);
    return mix(1.0, occlusion, params.cues.x) * mix(1.0, shadow, params.cues.y);
}

#endif
