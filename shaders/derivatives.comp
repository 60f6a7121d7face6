#version 450
// Derivatives of I_norm: world-space gradient (paper eq. 2), Hessian, and the directional
// curvature k = g^T H g with g normalized (paper eq. 3). The f64 twin is
// src/reference/derivatives.rs; the stencils are exactly its stencils:
// - d/da: (I[hi] - I[lo]) / (hi - lo), lo = max(p - 1, 0), hi = min(p + 1, n - 1) (one-sided at
//   the borders, so a linear ramp is exact everywhere; 0 when n == 1);
// - d2/da2: I[c + 1] - 2 I[c] + I[c - 1] with c = clamp(p, 1, n - 2) (0 when n < 3);
// - d2/dadb: the four (lo/hi) corners over (hi_a - lo_a)(hi_b - lo_b).
// World space: g_w = M g_idx and H_w = M H_idx M^T with M = A^-T (A = the affine's linear part),
// so k = v^T H_idx v with v = M^T (g_w / |g_w|). Where |g_w| <= tau the direction is undefined:
// k = 0 and the normal is 0 (NUMERICS.md "zero gradient").
//
// Only requested outputs are computed: WANT_* are specialization constants, so a pipeline without
// curvature fetches 7 texels per voxel instead of 19 and does no Hessian arithmetic.
// Outputs have no format qualifier (shaderStorageImageWriteWithoutFormat):
// - gradient_out: |g_w| or (|g_w|, k) in I_norm per mm and per mm^2, times scale_g / scale_k
//   (R16F/RG16F by default; R32F/RG32F, or R8/RG8 SNORM scaled by 1/max, for the accuracy study);
// - normal_out: RGBA8_SNORM unit world-space gradient direction (xyz), for shading.
// Always: the largest |g_w| of the volume (paper eq. 4's |grad I|max) into `stats`, as the bits
// of a non-negative float (which order like unsigned integers): subgroupMax, a shared-memory max
// per workgroup, then one atomicMax per workgroup into one of 256 slots (the host takes the max
// of the slots). One address for every subgroup serialized ~400k atomics and cost 0.3 ms on an
// H200; spread over slots they proceed in parallel. With every WANT_* off the pass computes only
// the maximum (the on-the-fly gradient path needs it but stores no volume).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require

// The workgroup size is specializable (spec ids 100-102) for profiling variants (`--wg`); the
// numbers here are the defaults.
layout(local_size_x_id = 100, local_size_y_id = 101, local_size_z_id = 102) in;
layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(constant_id = 0) const bool WANT_MAGNITUDE = true;
layout(constant_id = 1) const bool WANT_CURVATURE = false;
layout(constant_id = 2) const bool WANT_NORMAL = false;

layout(set = 0, binding = 0) uniform sampler3D volume;
layout(set = 0, binding = 1) uniform writeonly image3D gradient_out;
layout(set = 0, binding = 2) uniform writeonly image3D normal_out;
const uint STAT_SLOTS = 256u;
layout(set = 0, binding = 3, std430) buffer GradientStats { uint max_magnitude_bits[STAT_SLOTS]; } stats;
// Brick atlas only: per slot, the box of texels inside the volume, as x | y << 8 | z << 16 for
// the low corner (.x) and the exclusive high corner (.y). Read only when slot_side > 0.
layout(set = 0, binding = 4, std430) readonly buffer SlotBounds { uvec2 bounds[]; } slot_bounds;

shared uint workgroup_max_bits;

layout(push_constant) uniform Params {
    ivec4 dims;          // xyz = dimensions, w unused
    vec4 m_rows[3];      // rows of M = A^-T (xyz), w unused
    float tau;           // |g_w| at or below which the gradient direction is treated as undefined
    float scale_g;       // multiplies |g_w| before it is stored (1, or 1/max for 8-bit storage)
    float scale_k;       // multiplies k before it is stored
    int slot_side;       // > 0: the volume is a brick atlas of slots of this side (see main)
    int slot_halo;       // the slots' halo: only a slot's own brick counts towards max |g|
} params;

// Origin of the region the stencils see: the whole volume, or the current atlas slot.
ivec3 region_origin = ivec3(0);

float I(ivec3 p) {
    return texelFetch(volume, region_origin + p, 0).r;
}

ivec3 axis_offset(int axis, int d) {
    ivec3 o = ivec3(0);
    o[axis] = d;
    return o;
}

// Derivatives of voxel p of the region (extent n): stores the requested outputs at texel `store`
// and returns |g_w|.
float derive_voxel(ivec3 p, ivec3 n, ivec3 store) {
    float center = I(p);
    vec3 g_idx = vec3(0.0);
    vec3 second = vec3(0.0);   // d2/dx2, d2/dy2, d2/dz2 in index space
    ivec3 lo = max(p - 1, ivec3(0));
    ivec3 hi = min(p + 1, n - 1);
    for (int a = 0; a < 3; a++) {
        if (n[a] == 1) {
            continue;
        }
        if (n[a] == 2) {
            // lo and hi are the two voxels; no second derivative on two samples.
            g_idx[a] = I(p + axis_offset(a, 1 - 2 * p[a])) * (p[a] == 0 ? 1.0 : -1.0) + center * (p[a] == 0 ? -1.0 : 1.0);
            continue;
        }
        // Three samples around c = clamp(p, 1, n - 2); at interior voxels c == p and the same
        // three samples give the central difference.
        int c = clamp(p[a], 1, n[a] - 2);
        ivec3 pc = p + axis_offset(a, c - p[a]);
        float s_minus = I(pc + axis_offset(a, -1));
        float s_mid = (c == p[a]) ? center : I(pc);
        float s_plus = I(pc + axis_offset(a, 1));
        if (p[a] == c) {
            g_idx[a] = 0.5 * (s_plus - s_minus);
        } else if (p[a] < c) {
            g_idx[a] = s_mid - s_minus;    // p = 0: I[1] - I[0]
        } else {
            g_idx[a] = s_plus - s_mid;     // p = n - 1: I[n-1] - I[n-2]
        }
        second[a] = s_plus - 2.0 * s_mid + s_minus;
    }

    mat3 m_t = mat3(params.m_rows[0].xyz, params.m_rows[1].xyz, params.m_rows[2].xyz); // columns = rows of M, i.e. M^T
    vec3 g_w = transpose(m_t) * g_idx;
    float magnitude = length(g_w);
    bool has_direction = magnitude > params.tau;
    vec3 direction = has_direction ? g_w / magnitude : vec3(0.0);

    float k = 0.0;
    if (WANT_CURVATURE && has_direction) {
        // Mixed second derivatives from the four lo/hi corners of each axis pair.
        vec3 extent = vec3(hi - lo);
        float h_xy = 0.0, h_xz = 0.0, h_yz = 0.0;
        if (extent.x > 0.0 && extent.y > 0.0) {
            h_xy = (I(ivec3(hi.x, hi.y, p.z)) - I(ivec3(hi.x, lo.y, p.z)) - I(ivec3(lo.x, hi.y, p.z)) + I(ivec3(lo.x, lo.y, p.z))) / (extent.x * extent.y);
        }
        if (extent.x > 0.0 && extent.z > 0.0) {
            h_xz = (I(ivec3(hi.x, p.y, hi.z)) - I(ivec3(hi.x, p.y, lo.z)) - I(ivec3(lo.x, p.y, hi.z)) + I(ivec3(lo.x, p.y, lo.z))) / (extent.x * extent.z);
        }
        if (extent.y > 0.0 && extent.z > 0.0) {
            h_yz = (I(ivec3(p.x, hi.y, hi.z)) - I(ivec3(p.x, hi.y, lo.z)) - I(ivec3(p.x, lo.y, hi.z)) + I(ivec3(p.x, lo.y, lo.z))) / (extent.y * extent.z);
        }
        mat3 h_idx = mat3(second.x, h_xy, h_xz,
                          h_xy, second.y, h_yz,
                          h_xz, h_yz, second.z);
        vec3 v = m_t * direction;   // M^T g_hat: the direction expressed in index space
        k = dot(v, h_idx * v);
    }

    // Two ifs, not `||`: glslang would fold `||` of two specialization constants into an
    // OpSpecConstantOp, which the build's reflection cannot evaluate.
    bool store_gradient = false;
    if (WANT_MAGNITUDE) {
        store_gradient = true;
    }
    if (WANT_CURVATURE) {
        store_gradient = true;
    }
    if (store_gradient) {
        imageStore(gradient_out, store, vec4(magnitude * params.scale_g, k * params.scale_k, 0.0, 0.0));
    }
    if (WANT_NORMAL) {
        imageStore(normal_out, store, vec4(direction, 0.0));
    }
    return magnitude;
}

void main() {
    if (gl_LocalInvocationIndex == 0u) {
        workgroup_max_bits = 0u;
    }
    // Orders the initialisation of the shared maximum before every subgroup's atomicMax on it.
    // (No invocation returns early: every one must reach the barriers.)
    barrier();
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec3 n = params.dims.xyz;
    bool inside = all(lessThan(p, n));
    bool counted = inside;
    // A brick atlas: each slot is its own little volume, the box of its texels that lie inside
    // the scan (a brick plus its halo, cut at the volume's faces). The stencils see only that
    // box, so at the volume's faces they are one-sided exactly as for the whole volume, and
    // never read a neighbouring slot. Texels outside the box (replicated past the volume's
    // faces) store their nearest inside texel's values, which is what clamp-to-edge sampling of
    // a whole derived volume returns there.
    ivec3 store = p;
    if (params.slot_side > 0 && inside) {
        ivec3 slot = p / params.slot_side;
        ivec3 slots = params.dims.xyz / params.slot_side;
        uvec2 box = slot_bounds.bounds[slot.x + slots.x * (slot.y + slots.y * slot.z)];
        ivec3 lo = ivec3(box.x & 0xffu, (box.x >> 8) & 0xffu, (box.x >> 16) & 0xffu);
        ivec3 hi = ivec3(box.y & 0xffu, (box.y >> 8) & 0xffu, (box.y >> 16) & 0xffu);
        ivec3 local = p - slot * params.slot_side;
        region_origin = slot * params.slot_side + lo;
        n = max(hi - lo, ivec3(1));
        p = clamp(local - lo, ivec3(0), n - 1);
        // Halo texels repeat a neighbour brick's voxels and replicated texels repeat the face's,
        // so each voxel counts towards the maximum once: in its own brick, inside the volume.
        counted = inside && all(greaterThanEqual(local, max(lo, ivec3(params.slot_halo))))
            && all(lessThan(local, min(hi, ivec3(params.slot_side - params.slot_halo))));
    }
    float magnitude = inside ? derive_voxel(p, n, store) : 0.0;
    float subgroup_max = subgroupMax(counted ? magnitude : 0.0);
    if (subgroupElect()) {
        atomicMax(workgroup_max_bits, floatBitsToUint(subgroup_max));
    }
    // Orders every subgroup's shared atomicMax before the read below.
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        uint group = gl_WorkGroupID.x + gl_NumWorkGroups.x * (gl_WorkGroupID.y + gl_NumWorkGroups.y * gl_WorkGroupID.z);
        atomicMax(stats.max_magnitude_bits[group % STAT_SLOTS], workgroup_max_bits);
    }
}
