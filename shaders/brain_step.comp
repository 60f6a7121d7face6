#version 450
// The per-voxel steps of brain extraction between distance transforms (the algorithm:
// src/analysis/brain_params.rs's module doc; twin: src/reference/brain.rs). One shader with a
// uniform `mode` (the same branch for every invocation of a dispatch, so no divergence):
//   0 BAND_SOURCES     out = band(S) ? BIG : 0          (sources of the erosion: not the band)
//   1 CORE_SOURCES     out = D > t && cell ? 0 : BIG     (the largest component's core)
//   2 GROWN_SOURCES    out = D <= t && band(S) ? 0 : BIG (re-grown brain, sources of the closing)
//   3 OUTSIDE_SOURCES  out = D <= t ? BIG : 0            (not the dilated brain)
//   4 FINAL            out = D > t || cell ? 1 : 0       (the mask, R8_UNORM)
//   5 HEAD_SOURCES     out = cell ? BIG : 0              (sources of the depth: not the head)
//   6 DEPTH_CUT        out = D > t ? S : 0               (S without the head's outer shell)
// D is a squared distance in mm^2 (brain_distance_axis.comp), S the smoothed I_norm, `cell` the
// host's coarse-cell flag (component selection, hole filling or the head) of the voxel's cell.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D distance_field;
layout(set = 0, binding = 1) uniform sampler3D smoothed;
layout(set = 0, binding = 2, std430) readonly buffer Cells { uint flags[]; } cells;
// R32F scratch or the R8_UNORM mask (no format qualifier).
layout(set = 0, binding = 3) uniform writeonly image3D result;

layout(push_constant) uniform Params {
    ivec4 dims;     // xyz = dimensions, w = mode
    ivec4 coarse;   // xyz = coarse grid dimensions, w = cell edge in voxels
    float lo;       // band: lo < S < hi
    float hi;
    float threshold; // t, mm^2
    float unused;
} params;

const float BIG = 1e30;

bool band(ivec3 p) {
    float s = texelFetch(smoothed, p, 0).r;
    return params.lo < s && s < params.hi;
}

bool cell_flag(ivec3 p) {
    ivec3 c = p / params.coarse.w;
    int index = c.x + params.coarse.x * (c.y + params.coarse.y * c.z);
    return cells.flags[index] != 0u;
}

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(p, params.dims.xyz))) {
        return;
    }
    int mode = params.dims.w;
    float t = params.threshold;
    float out_value;
    if (mode == 0) {
        out_value = band(p) ? BIG : 0.0;
    } else if (mode == 1) {
        out_value = texelFetch(distance_field, p, 0).r > t && cell_flag(p) ? 0.0 : BIG;
    } else if (mode == 2) {
        out_value = texelFetch(distance_field, p, 0).r <= t && band(p) ? 0.0 : BIG;
    } else if (mode == 3) {
        out_value = texelFetch(distance_field, p, 0).r <= t ? BIG : 0.0;
    } else if (mode == 4) {
        out_value = texelFetch(distance_field, p, 0).r > t || cell_flag(p) ? 1.0 : 0.0;
    } else if (mode == 5) {
        out_value = cell_flag(p) ? BIG : 0.0;
    } else {
        out_value = texelFetch(distance_field, p, 0).r > t ? texelFetch(smoothed, p, 0).r : 0.0;
    }
    imageStore(result, p, vec4(out_value, 0.0, 0.0, 0.0));
}
