#version 450
// One axis of the bounded squared Euclidean distance transform of brain extraction (the exact
// algorithm: src/analysis/brain_params.rs's module doc; twin: src/reference/brain.rs
// `squared_distance`). g_out(p) = min over |t| <= bound of (t * h)^2 + g_in(p + t e_axis), taps
// outside the volume skipped (outside is never a source). Three dispatches (x, y, z) give the
// squared distance in mm^2 to the nearest source (g = 0 there, BIG elsewhere), exact while it is
// at most (bound * h)^2 on every axis; the host picks the bound from the radius it compares with.
// f32 in and out: distances to at most ~80 mm (6400 mm^2) keep 1e-3 mm^2 resolution.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D source;
// R32F scratch (no format qualifier: written through shaderStorageImageWriteWithoutFormat).
layout(set = 0, binding = 1) uniform writeonly image3D distance;

layout(push_constant) uniform Params {
    ivec4 dims;     // xyz = dimensions
    int axis;       // 0, 1, 2
    int bound;      // taps -bound..bound
    float spacing;  // voxel length of `axis` in mm
    float unused;
} params;

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec3 n = params.dims.xyz;
    if (any(greaterThanEqual(p, n))) {
        return;
    }
    int a = params.axis;
    int first = max(-params.bound, -p[a]);
    int last = min(params.bound, n[a] - 1 - p[a]);
    float best = texelFetch(source, p, 0).r;
    for (int t = first; t <= last; t++) {
        ivec3 q = p;
        q[a] = p[a] + t;
        float d = float(t) * params.spacing;
        best = min(best, d * d + texelFetch(source, q, 0).r);
    }
    imageStore(distance, p, vec4(best, 0.0, 0.0, 0.0));
}
