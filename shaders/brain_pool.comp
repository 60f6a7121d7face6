#version 450
// Coarse cells of brain extraction (the algorithm: src/analysis/brain_params.rs's module doc;
// twin: src/reference/brain.rs `pool_all` / `pool_any`): one invocation per cell of edge `f`
// voxels (clipped at the faces) writes 1 or 0 for the host's connected-component and hole steps.
//   mode 0 ALL:  every voxel has D > t (the eroded band)
//   mode 1 ANY:  some voxel has D > t  (the closed mask)
//   mode 2 BAND: some voxel has lo < S < hi
//   mode 3 FOREGROUND: some voxel has S > t (the head, reference/brain_depth.rs)

layout(local_size_x = 4, local_size_y = 4, local_size_z = 4) in;

layout(set = 0, binding = 0) uniform sampler3D distance_field;
layout(set = 0, binding = 1) uniform sampler3D smoothed;
layout(set = 0, binding = 2, std430) writeonly buffer Cells { uint flags[]; } cells;

layout(push_constant) uniform Params {
    ivec4 dims;     // xyz = dimensions, w = mode
    ivec4 coarse;   // xyz = coarse grid dimensions, w = cell edge in voxels
    float lo;
    float hi;
    float threshold;
    float unused;
} params;

bool voxel_test(ivec3 p, int mode) {
    if (mode == 2) {
        float s = texelFetch(smoothed, p, 0).r;
        return params.lo < s && s < params.hi;
    }
    if (mode == 3) {
        return texelFetch(smoothed, p, 0).r > params.threshold;
    }
    return texelFetch(distance_field, p, 0).r > params.threshold;
}

void main() {
    ivec3 c = ivec3(gl_GlobalInvocationID);
    if (any(greaterThanEqual(c, params.coarse.xyz))) {
        return;
    }
    int mode = params.dims.w;
    int f = params.coarse.w;
    ivec3 lo = c * f;
    ivec3 hi = min(lo + f, params.dims.xyz);
    bool all_set = true;
    bool any_set = false;
    for (int z = lo.z; z < hi.z; z++) {
        for (int y = lo.y; y < hi.y; y++) {
            for (int x = lo.x; x < hi.x; x++) {
                bool v = voxel_test(ivec3(x, y, z), mode);
                all_set = all_set && v;
                any_set = any_set || v;
            }
        }
    }
    bool flag = mode == 0 ? all_set : any_set;
    cells.flags[c.x + params.coarse.x * (c.y + params.coarse.y * c.z)] = flag ? 1u : 0u;
}
