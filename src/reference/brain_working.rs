//! The f64 twin of brain extraction as the engine runs it: on the working grid
//! (`passes::brain::working_factors`, blocks of about 1.75 mm averaged as
//! shaders/brain_downsample.comp does), the chain of `reference::brain` there, and the decision
//! from the coarse cells (`reference::brain_report`), exactly as `engine/brain.rs`.
//!
//! Decisions: the block mean is over the voxels inside the volume (a far block clipped by the
//! faces averages fewer); the working spacing is the volume's times the block edges.

use super::brain::{BrainError, BrainOutcome, extract};
use super::brain_params::BrainParams;
use super::brain_report::{BrainReport, DecisionCells};

/// The twin's result on the working grid.
#[derive(Clone, Debug)]
pub struct WorkingOutcome {
    /// Every step's result on the working grid.
    pub outcome: BrainOutcome,
    /// Working grid dimensions.
    pub dims: [usize; 3],
    /// Block edge per axis.
    pub factors: [u32; 3],
    /// Working voxel lengths in mm.
    pub spacing: [f64; 3],
    /// The decision (head, stripped, none), as the engine reports it.
    pub report: BrainReport,
}

/// Block means of `volume` (`dims`, x fastest) over blocks of `factors` voxels.
pub fn downsample(volume: &[f64], dims: [usize; 3], factors: [u32; 3]) -> (Vec<f64>, [usize; 3]) {
    let f = factors.map(|v| v.max(1) as usize);
    let w: [usize; 3] = std::array::from_fn(|a| dims[a].div_ceil(f[a]));
    let mut out = Vec::with_capacity(w[0] * w[1] * w[2]);
    for qz in 0..w[2] {
        for qy in 0..w[1] {
            for qx in 0..w[0] {
                let (mut sum, mut n) = (0.0, 0usize);
                for z in qz * f[2]..((qz + 1) * f[2]).min(dims[2]) {
                    for y in qy * f[1]..((qy + 1) * f[1]).min(dims[1]) {
                        for x in qx * f[0]..((qx + 1) * f[0]).min(dims[0]) {
                            sum += volume[x + dims[0] * (y + dims[1] * z)];
                            n += 1;
                        }
                    }
                }
                out.push(if n == 0 { 0.0 } else { sum / n as f64 });
            }
        }
    }
    (out, w)
}

/// The chain on the working grid of `factors` blocks of `volume` (`I_norm`, voxels of
/// `spacing` mm), with the engine's decision.
pub fn extract_working(
    volume: &[f64],
    dims: [usize; 3],
    spacing: [f64; 3],
    factors: [u32; 3],
    params: &BrainParams,
) -> Result<WorkingOutcome, BrainError> {
    if volume.len() != dims.iter().product::<usize>() {
        return Err(BrainError::Length {
            expected: dims.iter().product(),
            got: volume.len(),
        });
    }
    let (means, wdims) = downsample(volume, dims, factors);
    let wspacing: [f64; 3] = std::array::from_fn(|a| spacing[a] * f64::from(factors[a].max(1)));
    let outcome = extract(&means, wdims, wspacing, params)?;
    let report = if outcome.found {
        let f = params.coarse;
        let cell_mm3 = wspacing.iter().product::<f64>() * (f * f * f) as f64;
        BrainReport::decide(
            params,
            cell_mm3,
            DecisionCells {
                band: &outcome.band_cells,
                closed: &outcome.coarse_closed,
                fill: &outcome.fill,
            },
            outcome.bridge_cut,
            std::time::Duration::ZERO,
        )
    } else {
        BrainReport::not_found(params, std::time::Duration::ZERO)
    };
    Ok(WorkingOutcome {
        outcome,
        dims: wdims,
        factors,
        spacing: wspacing,
        report,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_means_clip_at_the_far_faces() {
        // 3x1x1 in blocks of 2: (1 + 3) / 2 and 5 alone.
        let (m, d) = downsample(&[1.0, 3.0, 5.0], [3, 1, 1], [2, 1, 1]);
        assert_eq!(d, [2, 1, 1]);
        assert_eq!(m, [2.0, 5.0]);
    }
}
