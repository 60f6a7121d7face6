#version 450
// The empty-space distance map (issue 33 item 3): per brick, the Chebyshev distance in bricks to
// the nearest occupied brick (0: occupied), capped at 255, so the raymarch can jump across the
// whole cube of empty bricks around a sample instead of one brick at a time (as VkVolume's
// distance maps do). It runs right after the brick-bounds pass, when the classification
// changes, never per frame.
//
// The L-infinity distance transform is separable: three dispatches of this shader, one per axis
// (the axis is the push constant grid.w), each a 1-D min-max scan along its brick lines:
//   x: a(p) = min over occupied q on p's x line of |p.x - q.x|      (from the occupancy bits)
//   y: b(p) = min over q on p's y line of max(|p.y - q.y|, a(q))
//   z: d(p) = min over q on p's z line of max(|p.z - q.z|, b(q))
// which is min over every occupied q of max(|dx|, |dy|, |dz|). A line with no occupied brick
// gives 255; capping an intermediate at 255 can only lower the result, and a lower distance is
// a shorter jump, never a skipped occupied brick. The scans cost O(n) per brick per axis
// (n <= 256 bricks on an axis of a 2048-voxel volume), a few hundred thousand reads for a head.
//
// Distances are bytes, four bricks to a word (brick b in byte b & 3 of word b >> 2). One
// invocation writes one whole word, so no atomics and no clearing. The buffer is the
// brick-bounds pass's (BrickBoundsLayout, src/passes/brick_bounds.rs): the x pass reads its bits
// and writes the distance region, y reads that and writes the scratch region, z reads the
// scratch and writes the distance region, where the raymarch reads it.
// The twin is src/reference/brick_distance.rs (brute force over every occupied brick).

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(set = 0, binding = 0, std430) buffer Data { uint words[]; } data;

layout(push_constant) uniform Params {
    uvec4 grid;      // xyz: brick grid; w: the axis this dispatch scans (0, 1, 2)
    uvec4 offsets;   // x: first word of the bits, y: of the source bytes, z: of the destination
} params;

const uint FAR = 255u;

uint source_byte(uint b) {
    return (data.words[params.offsets.y + (b >> 2u)] >> (8u * (b & 3u))) & 0xffu;
}

bool occupied(uint b) {
    return ((data.words[params.offsets.x + (b >> 5u)] >> (b & 31u)) & 1u) != 0u;
}

// The distance of brick `b` (at grid position `p`) along this dispatch's axis.
uint scan(uint b, uvec3 p) {
    uint axis = params.grid.w;
    uint n = params.grid[axis];
    uint stride = axis == 0u ? 1u : (axis == 1u ? params.grid.x : params.grid.x * params.grid.y);
    uint first = b - p[axis] * stride;
    uint best = FAR;
    for (uint q = 0u; q < n; q++) {
        uint offset = q > p[axis] ? q - p[axis] : p[axis] - q;
        if (offset >= best) {
            // Further bricks along the line only lie further away.
            if (q > p[axis]) {
                break;
            }
            continue;
        }
        uint at = first + q * stride;
        uint d = axis == 0u ? (occupied(at) ? 0u : FAR) : source_byte(at);
        best = min(best, max(offset, d));
    }
    return best;
}

void main() {
    uint word = gl_GlobalInvocationID.x;
    uint count = params.grid.x * params.grid.y * params.grid.z;
    if (word >= (count + 3u) / 4u) {
        return;
    }
    uint packed = 0u;
    for (uint k = 0u; k < 4u; k++) {
        uint b = 4u * word + k;
        if (b >= count) {
            break;
        }
        uvec3 p = uvec3(b % params.grid.x, (b / params.grid.x) % params.grid.y,
                        b / (params.grid.x * params.grid.y));
        packed |= scan(b, p) << (8u * k);
    }
    data.words[params.offsets.z + word] = packed;
}
