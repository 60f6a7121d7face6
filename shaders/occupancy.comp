#version 450
// Per-brick min/max of I_norm for empty-space skipping: one workgroup per brick of side S,
// reducing over the brick's voxels plus a halo of 2 voxels on every side, the footprint of any
// sample position inside the brick under every interpolation the raymarch offers (trilinear
// reads floor(p) and floor(p) + 1; the cubic B-spline reads floor(p) - 1 .. floor(p) + 2). The
// brick's range therefore bounds every value a sample in it can take, which is what makes
// skipping lossless. Values are in [0, 1], so their float bits order like unsigned integers.
// The CPU twin is src/scene/occupancy.rs's `reference_ranges`.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D volume;
layout(set = 0, binding = 1, std430) writeonly buffer Ranges { uint values[]; } ranges;

layout(push_constant) uniform Params {
    ivec4 dims;     // xyz: volume dimensions
    ivec4 bricks;   // xyz: brick grid, w: brick side in voxels
} params;

const int HALO = 2;

shared uint workgroup_min;
shared uint workgroup_max;

void main() {
    if (gl_LocalInvocationIndex == 0u) {
        workgroup_min = 0xffffffffu;
        workgroup_max = 0u;
    }
    // Orders the initialisation before every subgroup's shared atomics.
    barrier();
    ivec3 brick = ivec3(gl_WorkGroupID);
    int side = params.bricks.w;
    ivec3 lo = max(brick * side - HALO, ivec3(0));
    ivec3 hi = min(brick * side + side - 1 + HALO, params.dims.xyz - 1);
    uint lo_bits = 0xffffffffu;
    uint hi_bits = 0u;
    ivec3 local = ivec3(gl_LocalInvocationID);
    for (int z = lo.z + local.z; z <= hi.z; z += 4) {
        for (int y = lo.y + local.y; y <= hi.y; y += 4) {
            for (int x = lo.x + local.x; x <= hi.x; x += 4) {
                uint bits = floatBitsToUint(max(texelFetch(volume, ivec3(x, y, z), 0).r, 0.0));
                lo_bits = min(lo_bits, bits);
                hi_bits = max(hi_bits, bits);
            }
        }
    }
    uint subgroup_lo = subgroupMin(lo_bits);
    uint subgroup_hi = subgroupMax(hi_bits);
    if (subgroupElect()) {
        atomicMin(workgroup_min, subgroup_lo);
        atomicMax(workgroup_max, subgroup_hi);
    }
    // Orders every subgroup's shared atomics before the write below.
    barrier();
    if (gl_LocalInvocationIndex == 0u) {
        uint b = uint(brick.x) + uint(params.bricks.x) * (uint(brick.y) + uint(params.bricks.y) * uint(brick.z));
        ranges.values[2u * b] = workgroup_min;
        ranges.values[2u * b + 1u] = workgroup_max;
    }
}
