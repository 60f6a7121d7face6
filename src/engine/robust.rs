//! The robust range on the GPU: fine-histogram passes over the uploaded samples until the
//! percentiles are resolved (src/analysis/range.rs has the rule and the estimator).
//!
//! Decisions: one submission and readback per pass (each pass's interval depends on the last
//! one's counts); most volumes need one pass, a volume with hot voxels far above the tissue
//! two. The final mapping is planned by `normalize::plan_physical`; when the rule falls back
//! (no range) or the range cannot be mapped in f32, eq. 1's min/max plan is kept.

use super::Engine;
use super::readback::read_buffer;
use crate::analysis::range::{RobustStep, finish, robust_step_at};
use crate::analysis::{NormalizeMode, RangeChoice, RobustRange};
use crate::gpu::{Access, Buffer, BufferDesc, GpuResult, PassTiming, Recording};
use crate::passes::fine_histogram::{RESULT_BYTES, decode};
use crate::passes::normalize::{Normalization, plan_physical};
use crate::reference::fine_histogram::fine_histogram;
use crate::volume::{LinearMap, SampleKind, Volume};
use std::sync::Arc;

/// The fine histogram's counts (read back through [`super::readback::readback_desc`]), as the
/// robust range creates them and as the pass plan declares them.
pub fn fine_histogram_desc() -> BufferDesc {
    BufferDesc::gpu_storage("fine histogram", RESULT_BYTES)
}

impl Engine {
    /// The normalization the engine's mode asks for, given eq. 1's min/max plan `minmax`:
    /// `minmax` itself in min/max mode (or for a constant volume), else the robust range's.
    /// Appends the passes' GPU times to `timings`.
    pub(crate) fn choose_normalization(
        &mut self,
        volume: &Volume,
        samples: &Arc<Buffer>,
        minmax: Normalization,
        timings: &mut Vec<PassTiming>,
    ) -> GpuResult<(Normalization, RangeChoice)> {
        let mut choice = RangeChoice {
            mode: self.config.normalize,
            data_min: minmax.imin,
            data_max: minmax.imax,
            robust: None,
        };
        let (Some(data_min), Some(data_max)) = (minmax.imin, minmax.imax) else {
            return Ok((minmax, choice));
        };
        if self.config.normalize == NormalizeMode::MinMax || minmax.constant {
            return Ok((minmax, choice));
        }
        let kind = volume.samples.kind();
        let data = (data_min, data_max);
        let high = self.config.normalize.high_percentile();
        let found = self.robust_range(
            kind,
            samples,
            volume.to_physical,
            &minmax,
            (data, high),
            timings,
        )?;
        let Some(range) = found else {
            return Ok((minmax, choice));
        };
        choice.robust = Some(range);
        if range.fell_back {
            return Ok((minmax, choice));
        }
        let robust = plan_physical(minmax.params.dims, range.lo, range.hi, volume.to_physical);
        Ok((if robust.constant { minmax } else { robust }, choice))
    }

    /// Runs fine-histogram passes until the estimator is done.
    fn robust_range(
        &mut self,
        kind: SampleKind,
        samples: &Arc<Buffer>,
        to_physical: LinearMap,
        minmax: &Normalization,
        (data, high_percent): ((f64, f64), f64),
        timings: &mut Vec<PassTiming>,
    ) -> GpuResult<Option<RobustRange>> {
        let device = self.device.clone();
        let voxels = minmax.params.dims.iter().map(|&d| d as u64).product();
        let counts = Buffer::new(&device, fine_histogram_desc())?;
        let mut mapping = *minmax;
        let mut bytes = vec![0u8; RESULT_BYTES as usize];
        for pass in 1.. {
            let (Some(lo), Some(hi)) = (mapping.imin, mapping.imax) else {
                return Ok(None);
            };
            let passes = self.kind_passes(kind)?;
            let mut rec = Recording::new(&device, "fine histogram")?;
            rec.begin_pass("fine histogram");
            passes.fine_histogram.record(
                &device,
                &mut rec,
                samples,
                voxels,
                &mapping.params,
                &counts,
            )?;
            rec.end_pass();
            timings.extend(rec.submit()?.wait()?);
            read_buffer(&device, &counts, Access::ComputeWriteBuffer, &mut bytes)?;
            match robust_step_at(&decode(&bytes, lo, hi), pass, data, high_percent) {
                None => return Ok(None),
                Some(RobustStep::Done(range)) => return Ok(Some(range)),
                Some(RobustStep::Refine { lo, hi }) => {
                    mapping = plan_physical(mapping.params.dims, lo, hi, to_physical);
                    if mapping.constant {
                        // An interval too narrow for f32 at the data's magnitude: eq. 1's range.
                        return Ok(Some(finish(f64::NAN, f64::NAN, f64::NAN, data, pass)));
                    }
                }
            }
        }
        Ok(None)
    }
}

/// The host twin of [`Engine::choose_normalization`] for bricked volumes (whose samples are not
/// on the GPU): the same estimator over f64 fine histograms of the samples.
pub(crate) fn host_normalization(
    volume: &Volume,
    minmax: Normalization,
    mode: NormalizeMode,
) -> (Normalization, RangeChoice) {
    let mut choice = RangeChoice {
        mode,
        data_min: minmax.imin,
        data_max: minmax.imax,
        robust: None,
    };
    let (Some(data_min), Some(data_max)) = (minmax.imin, minmax.imax) else {
        return (minmax, choice);
    };
    if mode == NormalizeMode::MinMax || minmax.constant {
        return (minmax, choice);
    }
    let data = (data_min, data_max);
    let (mut lo, mut hi) = data;
    let mut range = None;
    for pass in 1..=crate::analysis::range::MAX_PASSES {
        let h = fine_histogram(&volume.samples, volume.to_physical, lo, hi);
        match robust_step_at(&h, pass, data, mode.high_percentile()) {
            None => break,
            Some(RobustStep::Done(found)) => {
                range = Some(found);
                break;
            }
            Some(RobustStep::Refine { lo: a, hi: b }) => (lo, hi) = (a, b),
        }
    }
    let Some(range) = range else {
        return (minmax, choice);
    };
    choice.robust = Some(range);
    if range.fell_back {
        return (minmax, choice);
    }
    let robust = plan_physical(minmax.params.dims, range.lo, range.hi, volume.to_physical);
    (if robust.constant { minmax } else { robust }, choice)
}
