// 256-bin histogram of I_norm over the finite voxels: bin = min(u32(clamp(v, 0, 1) * 256), 255),
// so I_norm = 1.0 lands in bin 255 and the bins sum to the number of finite voxels.
//
// Stages: each invocation bins a run of RUN consecutive voxels per step (one index division per
// run instead of per voxel, and neighbouring texels) and folds the run to one (bin, count) when
// its voxels agree -> subgroup aggregation (MRI has long runs of one bin, above all the
// background: when the whole subgroup agrees, one lane adds the subgroup's count) -> 256
// shared-memory bins per workgroup -> one global atomicAdd per non-empty bin per workgroup. The
// loop trip count is the same for every invocation, so subgroup operations and barriers are in
// uniform control flow.
//
// variants: SAMPLE_KIND = u8:0 i8:1 u16:2 i16:3 f32:4
override SAMPLE_KIND: u32 = 4u;

struct Params {
    dim_x: u32,
    dim_y: u32,
    voxel_count: u32,
    // Loop steps per invocation, identical for all invocations.
    iterations: u32,
    // Runs between one invocation's consecutive steps (= invocations in the dispatch).
    stride: u32,
}

var<immediate> params: Params;

// The normalized volume (any float-sampleable format; read with textureLoad, no filtering).
@group(0) @binding(0) var normalized: texture_3d<f32>;
// The raw samples, read only for f32 data to exclude non-finite voxels (normalization wrote 0
// there, which must not be counted).
@group(0) @binding(1) var<storage, read> words: array<u32>;
@group(0) @binding(2) var<storage, read_write> bins: array<atomic<u32>, 256>;

var<workgroup> local_bins: array<atomic<u32>, 256>;

const WORKGROUP_SIZE: u32 = 256u;
const NO_BIN: u32 = 256u;
// A run's voxels fall in different bins.
const MIXED: u32 = 257u;
// Consecutive voxels per invocation and step (src/passes/histogram.rs sizes the dispatch by it).
const RUN: u32 = 4u;

fn bin_of(v: f32) -> u32 {
    return min(u32(clamp(v, 0.0, 1.0) * 256.0), 255u);
}

fn is_finite_voxel(index: u32) -> bool {
    if SAMPLE_KIND != 4u {
        return true;
    }
    return (words[index] & 0x7f800000u) != 0x7f800000u;
}

@compute @workgroup_size(256)
fn main(
    @builtin(local_invocation_index) local: u32,
    @builtin(workgroup_id) workgroup: vec3<u32>,
    @builtin(subgroup_invocation_id) lane: u32,
) {
    atomicStore(&local_bins[local], 0u);
    // Orders the zeroing of the shared bins before any invocation adds to them.
    workgroupBarrier();

    let first = workgroup.x * WORKGROUP_SIZE + local;
    for (var step = 0u; step < params.iterations; step++) {
        let start = (first + step * params.stride) * RUN;
        // The run's first voxel in index space; the others follow along x, wrapping to the next
        // row and slice (a run may cross them: the volume's width need not be a multiple of RUN).
        var x = start % params.dim_x;
        let yz = start / params.dim_x;
        var y = yz % params.dim_y;
        var z = yz / params.dim_y;
        var bins_of_run: array<u32, 4>;
        for (var k = 0u; k < RUN; k++) {
            let index = start + k;
            var bin = NO_BIN;
            if index < params.voxel_count && is_finite_voxel(index) {
                bin = bin_of(textureLoad(normalized, vec3<i32>(vec3<u32>(x, y, z)), 0).x);
            }
            bins_of_run[k] = bin;
            x += 1u;
            if x == params.dim_x {
                x = 0u;
                y += 1u;
                if y == params.dim_y {
                    y = 0u;
                    z += 1u;
                }
            }
        }
        // The run as one (bin, count) when its voxels agree (voxels past the end or non-finite
        // count for nothing, so a run that is all NO_BIN is an agreeing run of count 0).
        var run_bin = NO_BIN;
        var run_count = 0u;
        for (var k = 0u; k < RUN; k++) {
            let bin = bins_of_run[k];
            if bin != NO_BIN {
                if run_bin == NO_BIN {
                    run_bin = bin;
                } else if run_bin != bin {
                    run_bin = MIXED;
                }
                run_count += 1u;
            }
        }
        let leader_bin = subgroupBroadcastFirst(run_bin);
        if subgroupAll(run_bin == leader_bin && leader_bin != MIXED) {
            let voxels = subgroupAdd(run_count);
            if lane == subgroupBroadcastFirst(lane) && run_bin != NO_BIN {
                atomicAdd(&local_bins[run_bin], voxels);
            }
        } else if run_bin == MIXED {
            for (var k = 0u; k < RUN; k++) {
                if bins_of_run[k] != NO_BIN {
                    atomicAdd(&local_bins[bins_of_run[k]], 1u);
                }
            }
        } else if run_bin != NO_BIN {
            atomicAdd(&local_bins[run_bin], run_count);
        }
    }

    // Orders every invocation's shared-bin additions before the flush below.
    workgroupBarrier();
    let count = atomicLoad(&local_bins[local]);
    if count != 0u {
        atomicAdd(&bins[local], count);
    }
}
