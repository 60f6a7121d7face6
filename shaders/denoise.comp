#version 450
// Edge-aware denoising of I_norm before the derivatives (twin: src/reference/denoise.rs, whose
// decisions this follows). One dispatch, `mode` chooses:
// - MODE_MEDIAN: the median of the 3x3x3 neighbourhood (clamp-to-edge at the faces): the 14th
//   smallest of 27, by 14 rounds of selection (no sort of the rest);
// - MODE_BILATERAL: Tomasi and Manduchi's bilateral filter: weights exp(-|d|^2 / 2 s^2) in mm
//   (world offsets along each index axis, anisotropic spacing honoured) times exp(-(I_q - I_p)^2
//   / 2 r^2) in I_norm; taps within `radius` voxels per axis; the centre always counts, so the
//   weight sum is >= 1.
// (The Gaussian option runs gaussian_axis.comp three times instead.) Output without a format
// qualifier, in I_norm's own format, so the result replaces I_norm for every later pass.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D source;
layout(set = 0, binding = 1) uniform writeonly image3D denoised;

layout(push_constant) uniform Params {
    ivec4 dims;       // xyz = dimensions
    ivec4 radius;     // xyz = bilateral taps per axis
    vec4 spacing;     // xyz = voxel length per index axis (mm)
    int mode;         // MODE_MEDIAN or MODE_BILATERAL
    float inv_2s2;    // 1 / (2 s^2), s the spatial sigma (mm)
    float inv_2r2;    // 1 / (2 r^2), r the range sigma (I_norm)
} params;

const int MODE_MEDIAN = 0;
const int MODE_BILATERAL = 1;

float I(ivec3 q) {
    return texelFetch(source, clamp(q, ivec3(0), params.dims.xyz - 1), 0).r;
}

float median3(ivec3 p) {
    float v[27];
    int n = 0;
    for (int dz = -1; dz <= 1; dz++) {
        for (int dy = -1; dy <= 1; dy++) {
            for (int dx = -1; dx <= 1; dx++) {
                v[n] = I(p + ivec3(dx, dy, dz));
                n++;
            }
        }
    }
    // After round i, v[i] is the (i+1)-th smallest.
    for (int i = 0; i < 14; i++) {
        int best = i;
        for (int j = i + 1; j < 27; j++) {
            if (v[j] < v[best]) {
                best = j;
            }
        }
        float t = v[i];
        v[i] = v[best];
        v[best] = t;
    }
    return v[13];
}

float bilateral(ivec3 p) {
    float centre = I(p);
    float acc = 0.0;
    float total = 0.0;
    ivec3 r = params.radius.xyz;
    for (int dz = -r.z; dz <= r.z; dz++) {
        for (int dy = -r.y; dy <= r.y; dy++) {
            for (int dx = -r.x; dx <= r.x; dx++) {
                vec3 d = vec3(dx, dy, dz) * params.spacing.xyz;
                float q = I(p + ivec3(dx, dy, dz));
                float dv = q - centre;
                float w = exp(-dot(d, d) * params.inv_2s2 - dv * dv * params.inv_2r2);
                acc += w * q;
                total += w;
            }
        }
    }
    return acc / total;
}

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p, params.dims.xyz))) {
        return;
    }
    float v = params.mode == MODE_MEDIAN ? median3(p) : bilateral(p);
    imageStore(denoised, p, vec4(v, 0.0, 0.0, 0.0));
}
