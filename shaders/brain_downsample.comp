#version 450
// Brain extraction's working grid (the algorithm: src/reference/brain.rs's module doc; twin:
// `reference::brain::downsample`): the mean of I_norm over each block of `factors` voxels
// (clipped at the far faces). The chain runs on this grid of about 1.75 mm voxels: 8x fewer
// voxels than a 0.9 mm head, with the same Dice against ROBEX (ACCURACY.md "Brain extraction").

layout(local_size_x = 8, local_size_y = 8, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D source;
// R32F (no format qualifier).
layout(set = 0, binding = 1) uniform writeonly image3D result;

layout(push_constant) uniform Params {
    ivec4 fine;     // xyz = the volume's dimensions
    ivec4 working;  // xyz = the working grid's dimensions
    ivec4 factors;  // xyz = block edge in voxels per axis
} params;

void main() {
    ivec3 q = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(q, params.working.xyz))) {
        return;
    }
    ivec3 lo = q * params.factors.xyz;
    ivec3 hi = min(lo + params.factors.xyz, params.fine.xyz);
    float sum = 0.0;
    for (int z = lo.z; z < hi.z; z++) {
        for (int y = lo.y; y < hi.y; y++) {
            for (int x = lo.x; x < hi.x; x++) {
                sum += texelFetch(source, ivec3(x, y, z), 0).r;
            }
        }
    }
    ivec3 n = hi - lo;
    imageStore(result, q, vec4(sum / float(n.x * n.y * n.z), 0.0, 0.0, 0.0));
}
