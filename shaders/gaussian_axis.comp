#version 450
// One axis of the separable Gaussian of the vesselness scale space (twin:
// src/reference/vesselness.rs `gaussian_axis`, whose decisions this follows): taps -r..r along
// index axis `axis`, weights exp(-i^2 / (2 sigma^2)) normalized to sum 1 (computed here in f32:
// cheaper than a weight buffer and exact to rounding), clamp-to-edge at the faces. Sigma and r are
// in voxels of that axis (the host divides sigma in mm by the axis's voxel length); r = 0 copies.
// Three dispatches (x, y, z) make one scale; f32 in and out.

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D source;
// No format qualifier: the scratch volumes are R32F; the denoising Gaussian writes its last axis
// into an I_norm-format (R16/R8 UNORM) volume.
layout(set = 0, binding = 1) uniform writeonly image3D blurred;

layout(push_constant) uniform Params {
    ivec4 dims;     // xyz = dimensions
    int axis;       // 0, 1, 2
    int radius;     // taps -radius..radius
    float sigma;    // in voxels of `axis` (> 0 when radius > 0)
    float unused;
} params;

void main() {
    ivec3 p = ivec3(gl_GlobalInvocationID);
    ivec3 n = params.dims.xyz;
    if (any(greaterThanEqual(p, n))) {
        return;
    }
    int a = params.axis;
    float acc = 0.0;
    float total = 0.0;
    float inv = params.radius > 0 ? 1.0 / (2.0 * params.sigma * params.sigma) : 0.0;
    for (int i = -params.radius; i <= params.radius; i++) {
        float w = exp(-float(i * i) * inv);
        ivec3 q = p;
        q[a] = clamp(p[a] + i, 0, n[a] - 1);
        acc += w * texelFetch(source, q, 0).r;
        total += w;
    }
    imageStore(blurred, p, vec4(acc / total, 0.0, 0.0, 0.0));
}
