#version 450
// Test probe for shaders/include/compositing.glsl: runs the raymarch's own `opacity_correct` and
// `composite` on host-chosen inputs, so tests can measure them against their f64 twins
// (src/reference/raymarch.rs `opacity_correct`, `composite`) over whole parameter grids, which a
// render cannot reach. Each job also computes the formula NUMERICS.md warns against, so a test can
// show that the bound it asserts would catch the naive form on this device.
//
// One invocation per item; `job` selects what an item means:
// - JOB_OPACITY: item = (a, r) -> (opacity_correct(a, r), 1 - pow(1 - a, r) in f32);
// - JOB_ACCUMULATE: item = (a, n) -> alpha after n `composite` steps of opacity a in f32, and
//   the same recurrence with every intermediate rounded to f16 precision (an f16 accumulator,
//   emulated in integer arithmetic so no float16 device feature is needed).
// The f64 twin of the probe is the twin of what it includes; it adds no arithmetic of its own
// beyond the naive and f16 comparisons.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(set = 0, binding = 0, std430) readonly buffer ProbeInputs { vec2 items[]; } inputs;
layout(set = 0, binding = 1, std430) writeonly buffer ProbeOutputs { vec2 items[]; } outputs;

layout(push_constant) uniform Params {
    uint count;   // items in both buffers
    uint job;     // JOB_OPACITY or JOB_ACCUMULATE
} params;

#include "compositing.glsl"

const uint JOB_OPACITY = 0u;
const uint JOB_ACCUMULATE = 1u;
// Upper bound on composite steps per item, so a bad input cannot hang the device.
const uint MAX_STEPS = 100000u;

// x rounded to f16 precision, to nearest even (as an f16 register would hold it), for values in
// f16's normal range (all of them here). Done on the bits: packHalf2x16's rounding is left to the
// device, and the H100's compiler folded unpackHalf2x16(packHalf2x16(x)) to x altogether.
float to_f16(float x) {
    uint bits = floatBitsToUint(x);
    uint odd = (bits >> 13u) & 1u;
    return uintBitsToFloat((bits + 0xFFFu + odd) & ~0x1FFFu);
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= params.count) {
        return;
    }
    vec2 item = inputs.items[i];
    if (params.job == JOB_OPACITY) {
        float naive = 1.0 - pow(1.0 - item.x, item.y);
        outputs.items[i] = vec2(opacity_correct(item.x, item.y), naive);
        return;
    }
    uint steps = uint(clamp(item.y, 0.0, float(MAX_STEPS)));
    vec4 acc = vec4(0.0);
    float a16 = to_f16(item.x);
    float alpha16 = 0.0;
    for (uint s = 0u; s < steps; s++) {
        composite(acc, vec3(1.0), item.x);
        alpha16 = to_f16(alpha16 + to_f16(to_f16(1.0 - alpha16) * a16));
    }
    outputs.items[i] = vec2(acc.a, alpha16);
}
