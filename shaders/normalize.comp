#version 450
// Paper eq. 1, I_norm = (I - Imin) / (Imax - Imin), written into a 3D image.
//
// The scale and offset come from the CPU, computed in f64 from the GPU's min/max (NUMERICS.md):
// I_norm = clamp((ldexp(s, pre_exponent) - offset) * scale, 0, 1). The power-of-two pre-scale is
// exact and brings samples near +-1 first, so neither the subtraction nor the product overflows
// or goes subnormal for data near +-3e38; subtracting an offset that is itself a pre-scaled
// sample keeps "1e30 + tiny" ranges exact (Sterbenz). A constant volume arrives as scale = 0.
// Subnormal f32 samples are decoded from their bits (sample_scaled), so flush-to-zero hardware
// keeps them. Non-finite voxels are written as 0 and excluded by the histogram; they render transparent.
//
// The image format is the caller's choice (R16_UNORM by default; R8, R16F, R32F for the accuracy
// study): the binding has no format qualifier (shaderStorageImageWriteWithoutFormat).
#extension GL_GOOGLE_include_directive : require

// The workgroup size is specializable (spec ids 100-102) for profiling variants (`--wg`); the
// numbers here are the defaults.
layout(local_size_x_id = 100, local_size_y_id = 101, local_size_z_id = 102) in;
layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(constant_id = 0) const uint SAMPLE_KIND = 4u;

layout(set = 0, binding = 0, std430) readonly buffer SampleWords { uint words[]; } samples;
layout(set = 0, binding = 1) uniform writeonly image3D normalized;

layout(push_constant) uniform Params {
    uint dim_x;
    uint dim_y;
    uint dim_z;
    int pre_exponent;
    float offset;
    float scale;
} params;

#include "samples.glsl"

void main() {
    uvec3 p = gl_GlobalInvocationID;
    if (p.x >= params.dim_x || p.y >= params.dim_y || p.z >= params.dim_z) {
        return;
    }
    uint index = p.x + params.dim_x * (p.y + params.dim_y * p.z);
    float value = 0.0;
    if (sample_is_finite(index)) {
        float s = sample_scaled(index, params.pre_exponent);
        value = clamp((s - params.offset) * params.scale, 0.0, 1.0);
    }
    imageStore(normalized, ivec3(p), vec4(value));
}
