#version 450
// Per-brick occupancy bits and opacity bounds from the brick ranges under the current
// classification (issue 17 item 2). It runs when the windows, opacities or visibility change
// (a new occupancy generation), never per frame. One invocation per word of 32 bricks, so each
// word of bits is written whole, with no atomics and no clearing.
//
// A brick is occupied when its range [min, max] meets the open support of a channel (a visible
// tissue window of non-zero opacity on I_norm, the vessel window on the vesselness), or holds a
// label. The supports come from the host in f64 rounded outward to f32 (lo down, hi up), so the
// f32 comparisons here decide exactly as the f64 twin does (`BrickRanges::occupancy_bits`,
// src/scene/occupancy.rs): for an f32 x, x > s holds iff x > round_down(s).
//
// The bound is an upper bound of f(v) (classification.glsl) over every value in the range:
// min(1, 1e-6 + sum over channels of opacity x the window's largest weight over [min, max]), where
// that weight is 1 when the range meets [lo, hi] and otherwise the window's rising (falling)
// smoothstep at the range's nearer end (the other factor is at most 1). A brick with a label
// adds 1 (a label's opacity per mm is at most 1). Values a sample takes inside the brick lie in
// the range (its 2-voxel halo covers every interpolation's footprint, occupancy.comp).
//
// The buffer `data` (u32 words; B bricks, W = ceil(B / 32) words of bits):
//   [0, W)              occupancy bits (out; the raymarch reads them here)
//   [W, W + B)          opacity bounds, f32 (out; the raymarch reads them here)
//   [W + B, W + 3B)     I_norm (min, max) per brick, f32 bits (in)
//   [W + 3B, W + 5B)    vesselness (min, max) per brick (in; read with VESSEL_BIT)
//   [W + 5B, 2W + 5B)   label bits (in; read with LABEL_BIT)
//   [2W + 5B]           occupied bricks (out, atomically added; zeroed before the pass)
//   then two regions of D = ceil(B / 4) words: the empty-space distance map (one byte per
//   brick; the raymarch reads it) and its scratch, both written by brick_distance.comp after
//   this pass.
// The f64 twin is `BrickRanges::reference_bounds` (src/scene/occupancy.rs).

layout(local_size_x = 64, local_size_y = 1, local_size_z = 1) in;

layout(set = 0, binding = 0, std430) buffer Data { uint words[]; } data;

layout(push_constant) uniform Params {
    vec4 windows[5];   // tissues 0-3, vessels 4: lo, hi, edge (>= MIN_EDGE), opacity (0: off)
    vec2 supports[5];  // open interval where the channel's weight can be non-zero
    uint bricks;       // B
    uint flags;        // VESSEL_BIT | LABEL_BIT
} params;

const uint VESSEL_BIT = 1u;
const uint LABEL_BIT = 2u;
const float BOUND_MARGIN = 1e-6;

float range_min(uint base, uint b) {
    return uintBitsToFloat(data.words[base + 2u * b]);
}

float range_max(uint base, uint b) {
    return uintBitsToFloat(data.words[base + 2u * b + 1u]);
}

// Whether [lo, hi] meets channel c's support (a channel that is off has the empty support
// (3e38, -3e38)).
bool meets_support(uint c, float lo, float hi) {
    return hi > params.supports[c].x && lo < params.supports[c].y;
}

// smoothstep(centre - e, centre + e, x) with t = ((x - centre) + e) / (2e): x - centre is exact
// near the centre (Sterbenz), so t is accurate to a few ulps even for the narrowest edge, where
// GLSL's (x - (centre - e)) / (2e) would lose up to ulp(centre) / 2e (3e-4 at e = 1e-4).
float edge_step(float centre, float e, float x) {
    float t = clamp(((x - centre) + e) / (2.0 * e), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// The largest weight channel c's window can take over [lo, hi], times its opacity.
float channel_bound(uint c, float lo, float hi) {
    vec4 w = params.windows[c];
    if (w.w <= 0.0) {
        return 0.0;
    }
    float weight = 1.0;
    if (hi < w.x) {
        weight = edge_step(w.x, w.z, hi);
    } else if (lo > w.y) {
        weight = 1.0 - edge_step(w.y, w.z, lo);
    }
    return w.w * weight;
}

void main() {
    uint word = gl_GlobalInvocationID.x;
    uint count = params.bricks;
    uint words = max((count + 31u) / 32u, 1u);
    if (word >= words) {
        return;
    }
    uint bounds_base = words;
    uint ranges_base = words + count;
    uint vessel_base = words + 3u * count;
    uint label_base = words + 5u * count;
    bool vessels = (params.flags & VESSEL_BIT) != 0u;
    bool labels = (params.flags & LABEL_BIT) != 0u;
    uint bits = 0u;
    uint first = 32u * word;
    uint last = min(first + 32u, count);
    for (uint b = first; b < last; b++) {
        float lo = range_min(ranges_base, b);
        float hi = range_max(ranges_base, b);
        bool occupied = false;
        float sum = 0.0;
        for (uint c = 0u; c < 4u; c++) {
            occupied = occupied || meets_support(c, lo, hi);
            sum += channel_bound(c, lo, hi);
        }
        if (vessels) {
            float vlo = range_min(vessel_base, b);
            float vhi = range_max(vessel_base, b);
            occupied = occupied || meets_support(4u, vlo, vhi);
            sum += channel_bound(4u, vlo, vhi);
        }
        // BOUND_MARGIN covers the f32 rounding of the sum (the twin adds it too).
        float bound = min(sum + BOUND_MARGIN, 1.0);
        if (labels && ((data.words[label_base + word] >> (b - first)) & 1u) != 0u) {
            occupied = true;
            bound += 1.0;
        }
        if (occupied) {
            bits |= 1u << (b - first);
        }
        data.words[bounds_base + b] = floatBitsToUint(bound);
    }
    data.words[word] = bits;
    atomicAdd(data.words[2u * words + 5u * count], uint(bitCount(bits)));
}
