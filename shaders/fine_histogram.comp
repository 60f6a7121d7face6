#version 450
// Fine histogram of the finite voxels' physical values over one interval, for the robust
// range's percentiles (src/analysis/range.rs): FINE_BINS equal bins plus a count under and one
// over the interval. The interval arrives as a normalization (src/passes/normalize.rs):
// x = (ldexp(s, pre_exponent) - offset) * scale maps it to [0, 1] with the same f64-planned
// pre-scale that keeps extreme data finite; x < 0 is under, x > 1 over (a sample whose pre-scale
// overflows to +-inf is over or under, never lost), bin = min(uint(x * FINE_BINS), FINE_BINS - 1)
// so the interval's top lands in the last bin. It also keeps the smallest and largest x inside
// the interval (as float bits, which order like unsigned integers for x >= 0): the next pass's
// interval shrinks to them, so a few hot voxels far above the tissue, or a foreground of one
// value, resolve in two or three passes. The f64 twin is src/reference/fine_histogram.rs.
//
// Stages: grid-stride loop (the same trip count for every invocation, so subgroup operations
// stay in uniform control flow) -> when a whole subgroup lands in one bin (background, runs of
// one value), one lane adds the subgroup's count -> FINE_BINS + 4 shared counters (8 KiB) per
// workgroup -> one global atomicAdd per non-empty counter per workgroup. The extremes inside are
// kept per invocation and reduced once at the end (subgroup, then shared, then global).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_arithmetic : require

layout(local_size_x = 256, local_size_y = 1, local_size_z = 1) in;

layout(constant_id = 0) const uint SAMPLE_KIND = 4u;

layout(set = 0, binding = 0, std430) readonly buffer SampleWords { uint words[]; } samples;
// FINE_BINS bins, then under, over, the smallest and the largest x inside (float bits).
layout(set = 0, binding = 1, std430) buffer Counts { uint counts[]; } result;

layout(push_constant) uniform Params {
    uint voxel_count;
    // Loop steps per invocation, identical for all invocations.
    uint iterations;
    // Voxels between one invocation's consecutive steps (= invocations in the dispatch).
    uint stride;
    int pre_exponent;
    float offset;
    float scale;
} params;

#include "samples.glsl"

const uint FINE_BINS = 2048u;
const uint UNDER = FINE_BINS;
const uint OVER = FINE_BINS + 1u;
const uint MIN_INSIDE = FINE_BINS + 2u;
const uint MAX_INSIDE = FINE_BINS + 3u;
const uint COUNTERS = FINE_BINS + 4u;
// Not counted: past the end, or a non-finite sample.
const uint SKIP = 0xffffffffu;

shared uint local_counts[COUNTERS];

// The counter of one voxel, and x's bits when it is inside the interval (else 0xffffffff).
uint counter_of(uint index, out uint inside_key) {
    inside_key = 0xffffffffu;
    if (index >= params.voxel_count || !sample_is_finite(index)) {
        return SKIP;
    }
    float x = (sample_scaled(index, params.pre_exponent) - params.offset) * params.scale;
    if (x < 0.0) {
        return UNDER;
    }
    if (x > 1.0) {
        return OVER;
    }
    // The sign bit is cleared so that -0.0 orders as 0.
    inside_key = floatBitsToUint(x) & 0x7fffffffu;
    // x is in [0, 1] here, so the conversion is defined.
    return min(uint(x * float(FINE_BINS)), FINE_BINS - 1u);
}

void main() {
    uint local = gl_LocalInvocationIndex;
    for (uint i = local; i < COUNTERS; i += gl_WorkGroupSize.x) {
        local_counts[i] = i == MIN_INSIDE ? 0xffffffffu : 0u;
    }
    // Orders the zeroing of the shared counters before any invocation adds to them.
    barrier();

    // Active lanes of this subgroup: the loop runs in uniform control flow, so it is the same at
    // every step and is counted once.
    uint lanes = subgroupBallotBitCount(subgroupBallot(true));
    // The extremes inside the interval stay in registers until the loop ends (no per-voxel
    // subgroup reduction or shared atomic for them).
    uint key_min = 0xffffffffu;
    uint key_max = 0u;
    uint first = gl_WorkGroupID.x * gl_WorkGroupSize.x + local;
    for (uint step = 0u; step < params.iterations; step++) {
        uint key;
        uint counter = counter_of(first + step * params.stride, key);
        if (key != 0xffffffffu) {
            key_min = min(key_min, key);
            key_max = max(key_max, key);
        }
        if (subgroupAllEqual(counter)) {
            if (counter != SKIP && subgroupElect()) {
                atomicAdd(local_counts[counter], lanes);
            }
        } else if (counter != SKIP) {
            atomicAdd(local_counts[counter], 1u);
        }
    }
    key_min = subgroupMin(key_min);
    key_max = subgroupMax(key_max);
    if (subgroupElect() && key_min != 0xffffffffu) {
        atomicMin(local_counts[MIN_INSIDE], key_min);
        atomicMax(local_counts[MAX_INSIDE], key_max);
    }
    // Orders every invocation's shared adds before the flush reads them.
    barrier();
    for (uint i = local; i < FINE_BINS + 2u; i += gl_WorkGroupSize.x) {
        uint count = local_counts[i];
        if (count != 0u) {
            atomicAdd(result.counts[i], count);
        }
    }
    if (local == 0u && local_counts[MIN_INSIDE] != 0xffffffffu) {
        atomicMin(result.counts[MIN_INSIDE], local_counts[MIN_INSIDE]);
        atomicMax(result.counts[MAX_INSIDE], local_counts[MAX_INSIDE]);
    }
}
