// Volume fetches at an index-space position p (voxel centres at integers) with the scene's
// interpolation, a specialization constant (INTERPOLATION): 0 nearest, 1 trilinear (hardware),
// 2 tricubic B-spline from 8 trilinear fetches (Sigg & Hadwiger, GPU Gems 2, ch. 20: per axis the
// four B-spline weights collapse into two linear fetches at offsets h0, h1 with weights g0, g1).
// The B-spline approximates rather than interpolates: it smooths, which the accuracy study
// measures. The f64 twin is src/reference/raymarch.rs (`fetch`).
#ifndef MORPHRAY_SAMPLING_GLSL
#define MORPHRAY_SAMPLING_GLSL

const uint INTERPOLATION_NEAREST = 0u;
const uint INTERPOLATION_TRILINEAR = 1u;
const uint INTERPOLATION_TRICUBIC = 2u;

vec4 fetch_linear(sampler3D tex, vec3 p, vec3 dims) {
    return textureLod(tex, (p + 0.5) / dims, 0.0);
}

vec4 fetch(sampler3D tex, vec3 p, vec3 dims) {
    if (INTERPOLATION == INTERPOLATION_NEAREST) {
        ivec3 q = clamp(ivec3(floor(p + 0.5)), ivec3(0), ivec3(dims) - 1);
        return texelFetch(tex, q, 0);
    } else if (INTERPOLATION == INTERPOLATION_TRICUBIC) {
        vec3 i = floor(p);
        vec3 t = p - i;
        vec3 t2 = t * t;
        vec3 t3 = t2 * t;
        vec3 w0 = (1.0 - 3.0 * t + 3.0 * t2 - t3) / 6.0;
        vec3 w1 = (4.0 - 6.0 * t2 + 3.0 * t3) / 6.0;
        vec3 w2 = (1.0 + 3.0 * t + 3.0 * t2 - 3.0 * t3) / 6.0;
        vec3 w3 = t3 / 6.0;
        vec3 g0 = w0 + w1;
        vec3 g1 = w2 + w3;
        vec3 p0 = i - 1.0 + w1 / g0;   // fetch positions in index space
        vec3 p1 = i + 1.0 + w3 / g1;
        vec4 r = vec4(0.0);
        r += g0.x * g0.y * g0.z * fetch_linear(tex, vec3(p0.x, p0.y, p0.z), dims);
        r += g1.x * g0.y * g0.z * fetch_linear(tex, vec3(p1.x, p0.y, p0.z), dims);
        r += g0.x * g1.y * g0.z * fetch_linear(tex, vec3(p0.x, p1.y, p0.z), dims);
        r += g1.x * g1.y * g0.z * fetch_linear(tex, vec3(p1.x, p1.y, p0.z), dims);
        r += g0.x * g0.y * g1.z * fetch_linear(tex, vec3(p0.x, p0.y, p1.z), dims);
        r += g1.x * g0.y * g1.z * fetch_linear(tex, vec3(p1.x, p0.y, p1.z), dims);
        r += g0.x * g1.y * g1.z * fetch_linear(tex, vec3(p0.x, p1.y, p1.z), dims);
        r += g1.x * g1.y * g1.z * fetch_linear(tex, vec3(p1.x, p1.y, p1.z), dims);
        return r;
    }
    return fetch_linear(tex, p, dims);
}

float sample_volume(vec3 p) {
    return fetch(volume, p, params.dims.xyz).r;
}

#endif
