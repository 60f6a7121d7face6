// Decoding of stored samples packed in 32-bit words, one variant per SampleKind
// (src/volume/samples.rs). SAMPLE_KIND is a specialization constant, so the unused branches are
// removed when the pipeline is created and no per-voxel branch on the datatype remains.
#ifndef MORPHRAY_SAMPLES_GLSL
#define MORPHRAY_SAMPLES_GLSL

const uint KIND_U8 = 0u;
const uint KIND_I8 = 1u;
const uint KIND_U16 = 2u;
const uint KIND_I16 = 3u;
const uint KIND_F32 = 4u;

// The sample's value as an f32 (exact for 8- and 16-bit data).
float sample_value(uint index) {
    if (SAMPLE_KIND == KIND_U8) {
        return float(bitfieldExtract(samples.words[index >> 2], int((index & 3u) * 8u), 8));
    } else if (SAMPLE_KIND == KIND_I8) {
        return float(bitfieldExtract(int(samples.words[index >> 2]), int((index & 3u) * 8u), 8));
    } else if (SAMPLE_KIND == KIND_U16) {
        return float(bitfieldExtract(samples.words[index >> 1], int((index & 1u) * 16u), 16));
    } else if (SAMPLE_KIND == KIND_I16) {
        return float(bitfieldExtract(int(samples.words[index >> 1]), int((index & 1u) * 16u), 16));
    }
    return uintBitsToFloat(samples.words[index]);
}

// False for NaN and infinities. Tested on bits: GPU float rules allow isnan() to be folded away.
bool sample_is_finite(uint index) {
    if (SAMPLE_KIND != KIND_F32) {
        return true;
    }
    return (samples.words[index] & 0x7f800000u) != 0x7f800000u;
}

// ldexp(sample, e) computed without ever handing a subnormal f32 to the float unit: GPUs may
// flush subnormal operands to zero, which would erase subnormal data (NUMERICS.md). A subnormal's
// value is mantissa * 2^-149 exactly, and float(mantissa) is exact (< 2^23).
float sample_scaled(uint index, int e) {
    if (SAMPLE_KIND != KIND_F32) {
        return ldexp(sample_value(index), e);
    }
    uint bits = samples.words[index];
    if ((bits & 0x7f800000u) == 0u) {
        float magnitude = ldexp(float(bits & 0x007fffffu), e - 149);
        return (bits & 0x80000000u) != 0u ? -magnitude : magnitude;
    }
    return ldexp(uintBitsToFloat(bits), e);
}

#endif
