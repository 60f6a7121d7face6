#version 450
// Frangi vesselness of one scale, folded into the running maximum over scales (twin:
// src/reference/vesselness.rs `vesselness_at_scale`, whose decisions this follows):
// - the Hessian of the smoothed volume with the derivative pass's stencils (derivatives.comp:
//   three-point second differences centred at clamp(p, 1, n - 2), mixed terms from the lo/hi
//   corners), taken to world units H_w = M H_idx M^T (M = A^-T) and scaled by sigma_mm^2;
// - its eigenvalues by shaders/include/eigen3.glsl (Jacobi, NUMERICS.md);
// - Frangi's measure for bright tubes (0 unless l2 < 0 and l3 < 0, |l1| <= |l2| <= |l3|);
// - response = first ? v : max(response, v): each invocation reads and writes only its own
//   texel, so no synchronization inside the dispatch; the host orders the scales.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D smoothed;
layout(set = 0, binding = 1, r32f) uniform image3D response;

layout(push_constant) uniform Params {
    ivec4 dims;          // xyz = dimensions
    vec4 m_rows[3];      // rows of M = A^-T (xyz)
    float sigma2;        // sigma_mm^2, the scale normalization
    float alpha;         // Frangi's alpha, beta, c
    float beta;
    float c;
    int first;           // 1: the first scale overwrites instead of taking the maximum
} params;

#include "eigen3.glsl"

float I(ivec3 p) {
    return texelFetch(smoothed, p, 0).r;
}

ivec3 axis_offset(int axis, int d) {
    ivec3 o = ivec3(0);
    o[axis] = d;
    return o;
}

float mixed(ivec3 p, ivec3 lo, ivec3 hi, int a, int b) {
    if (hi[a] == lo[a] || hi[b] == lo[b]) {
        return 0.0;
    }
    ivec3 hh = p, hl = p, lh = p, ll = p;
    hh[a] = hi[a]; hh[b] = hi[b];
    hl[a] = hi[a]; hl[b] = lo[b];
    lh[a] = lo[a]; lh[b] = hi[b];
    ll[a] = lo[a]; ll[b] = lo[b];
    return (I(hh) - I(hl) - I(lh) + I(ll)) / float((hi[a] - lo[a]) * (hi[b] - lo[b]));
}

float frangi(vec3 l) {
    // Order by magnitude: |l1| <= |l2| <= |l3|.
    if (abs(l.x) > abs(l.y)) { l.xy = l.yx; }
    if (abs(l.y) > abs(l.z)) { l.yz = l.zy; }
    if (abs(l.x) > abs(l.y)) { l.xy = l.yx; }
    if (!(l.y < 0.0 && l.z < 0.0)) {
        return 0.0;
    }
    float ra2 = (l.y / l.z) * (l.y / l.z);
    float rb2 = l.x * l.x / abs(l.y * l.z);
    float s2 = dot(l, l);
    return (1.0 - exp(-ra2 / (2.0 * params.alpha * params.alpha)))
        * exp(-rb2 / (2.0 * params.beta * params.beta))
        * (1.0 - exp(-s2 / (2.0 * params.c * params.c)));
}

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec3 n = params.dims.xyz;
    if (any(greaterThanEqual(p, n))) {
        return;
    }
    vec3 second = vec3(0.0);
    for (int a = 0; a < 3; a++) {
        if (n[a] < 3) {
            continue;
        }
        int c = clamp(p[a], 1, n[a] - 2);
        ivec3 pc = p + axis_offset(a, c - p[a]);
        second[a] = I(pc + axis_offset(a, 1)) - 2.0 * I(pc) + I(pc + axis_offset(a, -1));
    }
    ivec3 lo = max(p - 1, ivec3(0));
    ivec3 hi = min(p + 1, n - 1);
    float h_xy = mixed(p, lo, hi, 0, 1);
    float h_xz = mixed(p, lo, hi, 0, 2);
    float h_yz = mixed(p, lo, hi, 1, 2);
    mat3 h_idx = mat3(second.x, h_xy, h_xz,
                      h_xy, second.y, h_yz,
                      h_xz, h_yz, second.z);
    mat3 m_t = mat3(params.m_rows[0].xyz, params.m_rows[1].xyz, params.m_rows[2].xyz); // M^T
    mat3 h_w = transpose(m_t) * h_idx * m_t * params.sigma2;
    vec3 l = sym3_eigenvalues(h_w[0][0], h_w[1][1], h_w[2][2], h_w[1][0], h_w[2][0], h_w[2][1]);
    float v = frangi(l);
    if (params.first == 0) {
        v = max(v, imageLoad(response, p).r);
    }
    imageStore(response, p, vec4(v, 0.0, 0.0, 0.0));
}
