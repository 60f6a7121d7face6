// A streaming copy, each 16-byte quad read once and written once: the ceiling that bandwidth-
// bound compute passes are compared with, measured in the same run on the same device
// (vkCmdCopyBuffer is not that ceiling: on the H200 it ran at 0.85 TB/s, below our own min/max
// kernel, because it goes through a copy engine rather than the shader cores).

struct Params {
    quad_count: u32,
    iterations: u32,
    stride: u32,
}

var<immediate> params: Params;

@group(0) @binding(0) var<storage, read> source: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read_write> destination: array<vec4<u32>>;

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    for (var step = 0u; step < params.iterations; step++) {
        let q = id.x + step * params.stride;
        if q < params.quad_count {
            destination[q] = source[q];
        }
    }
}
