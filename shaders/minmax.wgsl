// Min and max of the finite stored samples, as order-preserving u32 keys (no float atomics:
// Intel Xe-LP has none, and integer atomics on ordered keys are exact and order-independent).
//
// Stages: each invocation reduces its share in registers -> subgroupMin/Max -> one workgroup
// atomic per subgroup -> one global atomic per workgroup. Invocations with nothing to do keep the
// identities (0xffffffff for min, 0 for max), so any subgroup size (4..128) and any count works.
// The loop trip count is the same for every invocation (`iterations`), so the subgroup operations
// and the barrier sit in uniform control flow.
//
// variants: SAMPLE_KIND = u8:0 i8:1 u16:2 i16:3 f32:4
override SAMPLE_KIND: u32 = 4u;

struct Params {
    // Number of 16-byte quads in `quads` (the upload is zero-padded to a whole quad).
    quad_count: u32,
    // Number of real samples; padding after it is ignored.
    sample_count: u32,
    // Loop steps per invocation, identical for all invocations.
    iterations: u32,
    // Quads between one invocation's consecutive steps (= invocations in the dispatch).
    stride: u32,
}

var<immediate> params: Params;

@group(0) @binding(0) var<storage, read> quads: array<vec4<u32>>;
// [0] = min key, [1] = max key; the host fills them with the identities before the dispatch.
@group(0) @binding(1) var<storage, read_write> result: array<atomic<u32>, 2>;

var<workgroup> workgroup_min: atomic<u32>;
var<workgroup> workgroup_max: atomic<u32>;

const WORKGROUP_SIZE: u32 = 256u;
const NO_MIN: u32 = 0xffffffffu;
const NO_MAX: u32 = 0u;

// Order-preserving map from f32 bits to u32: negative values flip all bits, positive values set
// the sign bit. key(a) < key(b) exactly when a < b (with -0 just below +0).
fn key_of(bits: u32) -> u32 {
    if (bits & 0x80000000u) != 0u {
        return ~bits;
    }
    return bits | 0x80000000u;
}

fn samples_per_word() -> u32 {
    switch SAMPLE_KIND {
        case 0u, 1u: { return 4u; }
        case 2u, 3u: { return 2u; }
        default: { return 1u; }
    }
}

// Bits of sample `lane` of a 32-bit word, as an f32 (every 8/16-bit value is exact in f32).
fn sample_bits(word: u32, lane: u32) -> u32 {
    switch SAMPLE_KIND {
        case 0u: { return bitcast<u32>(f32(extractBits(word, lane * 8u, 8u))); }
        case 1u: { return bitcast<u32>(f32(extractBits(bitcast<i32>(word), lane * 8u, 8u))); }
        case 2u: { return bitcast<u32>(f32(extractBits(word, lane * 16u, 16u))); }
        case 3u: { return bitcast<u32>(f32(extractBits(bitcast<i32>(word), lane * 16u, 16u))); }
        default: { return word; }
    }
}

// NaN and infinities have an all-ones exponent; tested on bits because GPU float rules allow
// isnan() to be folded away (NUMERICS.md).
fn is_finite_bits(bits: u32) -> bool {
    return (bits & 0x7f800000u) != 0x7f800000u;
}

@compute @workgroup_size(256)
fn main(
    @builtin(local_invocation_index) local: u32,
    @builtin(workgroup_id) workgroup: vec3<u32>,
    @builtin(subgroup_invocation_id) lane: u32,
) {
    if local == 0u {
        atomicStore(&workgroup_min, NO_MIN);
        atomicStore(&workgroup_max, NO_MAX);
    }
    // Orders the initialisation above before any invocation's atomicMin/Max below.
    workgroupBarrier();

    let per_word = samples_per_word();
    let per_quad = 4u * per_word;
    var lo = NO_MIN;
    var hi = NO_MAX;
    let first = workgroup.x * WORKGROUP_SIZE + local;
    for (var step = 0u; step < params.iterations; step++) {
        let q = first + step * params.stride;
        if q < params.quad_count {
            let quad = quads[q];
            for (var w = 0u; w < 4u; w++) {
                for (var s = 0u; s < per_word; s++) {
                    let index = q * per_quad + w * per_word + s;
                    let bits = sample_bits(quad[w], s);
                    if index < params.sample_count && is_finite_bits(bits) {
                        let key = key_of(bits);
                        lo = min(lo, key);
                        hi = max(hi, key);
                    }
                }
            }
        }
    }

    let subgroup_lo = subgroupMin(lo);
    let subgroup_hi = subgroupMax(hi);
    // One lane per subgroup (the first active one; naga has no subgroupElect).
    if lane == subgroupBroadcastFirst(lane) {
        atomicMin(&workgroup_min, subgroup_lo);
        atomicMax(&workgroup_max, subgroup_hi);
    }
    // Orders every subgroup's shared-memory atomics before the read below.
    workgroupBarrier();
    if local == 0u {
        let wg_lo = atomicLoad(&workgroup_min);
        let wg_hi = atomicLoad(&workgroup_max);
        if wg_lo != NO_MIN {
            atomicMin(&result[0], wg_lo);
            atomicMax(&result[1], wg_hi);
        }
    }
}
