//! Derived volumes (gradient magnitude, curvature, normals) of a prepared volume.

use super::Engine;
use super::prepare::{PreparedVolume, VolumeLayout};
use crate::gpu::{Access, Buffer, BufferDesc, GpuResult, Image, PassTiming, Recording};
use crate::passes::derivatives::{DEFAULT_TAU, DerivativeOutputs, DerivedVolumes, STAT_BYTES};
use crate::scene::DerivedPrecision;
use crate::scene::uniforms::GradientStats;
use std::sync::Arc;

/// Derived volumes and the GPU time they took.
pub struct Derived {
    /// The images (left in `Access::ComputeSampled`).
    pub volumes: DerivedVolumes,
    /// max |g| and the zero-gradient threshold.
    pub stats: GradientStats,
    /// GPU time of the derivative pass (and of the vesselness passes).
    pub gpu_timings: Vec<PassTiming>,
    /// The multi-scale vesselness (R32F, `Access::ComputeSampled`) when
    /// `DerivativeOutputs::vesselness` asked for it.
    pub vesselness: Option<Arc<Image>>,
    /// The vesselness's per-brick ranges (for empty-space skipping with the vessel channel).
    pub vessel_ranges: Option<Arc<crate::scene::occupancy::BrickRanges>>,
    /// Brain extraction's outcome when `DerivativeOutputs::brain` asked for it; its mask is what
    /// the raymarch classifies tissues inside (`BrainMask::used`).
    pub brain: Option<Arc<super::brain::BrainMask>>,
}

/// The derivative pass's max |g| slots and their host copy (as [`Engine::derive`] creates them,
/// and as the pass plan declares them).
pub fn gradient_maximum_descs() -> [BufferDesc; 2] {
    [
        BufferDesc::gpu_storage("gradient maximum", STAT_BYTES),
        BufferDesc::readback("gradient maximum (host)", STAT_BYTES),
    ]
}

impl Engine {
    /// Computes the requested derived volumes of `prepared` (nothing else). 8-bit storage needs
    /// the maximum first (its scale), so it runs a max-only dispatch before the storing one.
    pub fn derive(
        &mut self,
        prepared: &PreparedVolume,
        outputs: DerivativeOutputs,
    ) -> GpuResult<Derived> {
        let mut derived = self.derive_gradients(prepared, outputs)?;
        if outputs.vesselness {
            // The default scales (0.6-3 mm, 4 of them: `VesselnessParams::default`).
            let params = crate::passes::vesselness::VesselnessParams::default();
            let vessels = self.vesselness(prepared, &params)?;
            derived.gpu_timings.extend(vessels.gpu_timings);
            // Its brick ranges, so empty-space skipping stays on (and lossless) with vessels.
            let (ranges, timings) = self.ranges_of(&vessels.image)?;
            derived.gpu_timings.extend(timings.into_iter().map(|mut t| {
                t.name = "vesselness brick ranges".into();
                t
            }));
            derived.vessel_ranges = Some(ranges);
            derived.vesselness = Some(vessels.image);
            derived.volumes.outputs.vesselness = true;
        }
        if outputs.brain != crate::passes::brain::BrainSwitch::Off {
            let brain = self.extract_brain(prepared, outputs.brain)?;
            derived
                .gpu_timings
                .extend(brain.gpu_timings.iter().cloned());
            derived.brain = Some(Arc::new(brain));
            derived.volumes.outputs.brain = outputs.brain;
        }
        Ok(derived)
    }

    fn derive_gradients(
        &mut self,
        prepared: &PreparedVolume,
        outputs: DerivativeOutputs,
    ) -> GpuResult<Derived> {
        // The vesselness is no output of the derivative shader: its pipelines ignore the flag.
        let outputs = DerivativeOutputs {
            vesselness: false,
            brain: crate::passes::brain::BrainSwitch::Off,
            ..outputs
        };
        let _span = crate::files::trace::span("derived volumes", "prepare");
        let stores = outputs.magnitude || outputs.curvature;
        let voxel_mm = finest_spacing(prepared.linear_part);
        if outputs.precision != DerivedPrecision::Snorm8 || !stores {
            // Stored in voxel units (|g| h, k h^2, h = finest spacing): world units overflow f16
            // for micrometre voxels (k ~ 1/h^2) and underflow it for huge ones (NUMERICS.md);
            // every reader divides by the scale it is handed.
            let h = voxel_mm as f32;
            return self.derive_scaled(prepared, outputs, [h, h * h]);
        }
        let max_only = max_only_pass(outputs);
        let first = self.derive_scaled(prepared, max_only, [1.0, 1.0])?;
        let g = first.stats.max_magnitude.max(1e-12);
        // |g| fills [0, 1]; k up to 2 g / voxel (twice the step-edge scale of k_ref) fills [-1, 1].
        let scale = [(1.0 / g) as f32, (voxel_mm / (2.0 * g)) as f32];
        let mut derived = self.derive_scaled(prepared, outputs, scale)?;
        let mut timings = first.gpu_timings;
        for t in &mut timings {
            t.name = "derivatives (max, for the 8-bit scale)".into();
        }
        timings.append(&mut derived.gpu_timings);
        derived.gpu_timings = timings;
        Ok(derived)
    }

    fn derive_scaled(
        &mut self,
        prepared: &PreparedVolume,
        outputs: DerivativeOutputs,
        store_scale: [f32; 2],
    ) -> GpuResult<Derived> {
        let device = self.device.clone();
        let nearest = self.nearest.clone();
        // Bound but unread for a whole volume (any small buffer satisfies the layout).
        let placeholder = self.placeholders.occupancy.clone();
        self.counters.derivative_runs += 1;
        let pass = self.derivative_pass(outputs)?;
        let [stats_gpu, stats_host] = gradient_maximum_descs();
        let stats_gpu = Buffer::new(&device, stats_gpu)?;
        let stats_host = Buffer::new(&device, stats_host)?;
        let mut rec = Recording::new(&device, "derivatives")?;
        rec.begin_pass("derivatives");
        let volumes = pass.record(
            &device,
            &mut rec,
            &prepared.normalized,
            &nearest,
            prepared.linear_part,
            DEFAULT_TAU,
            store_scale,
            prepared.slot_shape(),
            match &prepared.layout {
                VolumeLayout::Bricked(atlas) => &atlas.slot_bounds,
                VolumeLayout::Whole => &placeholder,
            },
            &stats_gpu,
        )?;
        rec.end_pass();
        // Orders the derived writes before every later sampling of them (the raymarch).
        let written: Vec<_> = [&volumes.gradient, &volumes.normal]
            .into_iter()
            .flatten()
            .cloned()
            .collect();
        let transitions: Vec<_> = written
            .iter()
            .map(|image| (image, Access::ComputeWriteImage, Access::ComputeSampled))
            .collect();
        rec.barriers(&[], &transitions);
        // Orders the maximum's atomics before the copy to host memory.
        rec.barriers(
            &[(&stats_gpu, Access::ComputeWriteBuffer, Access::TransferRead)],
            &[],
        );
        rec.copy_buffer(&stats_gpu, &stats_host, STAT_BYTES);
        // Makes the copy visible to the host.
        rec.barriers(
            &[(&stats_host, Access::TransferWrite, Access::HostRead)],
            &[],
        );
        let gpu_timings = rec.submit()?.wait()?;
        let mut bytes = vec![0u8; STAT_BYTES as usize];
        stats_host.read(0, &mut bytes)?;
        // Non-negative floats order like their bits: the largest slot is the maximum.
        let max_bits = bytes
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .max()
            .unwrap_or(0);
        let max_magnitude = f32::from_bits(max_bits) as f64;
        let stats = GradientStats {
            max_magnitude,
            tau: DEFAULT_TAU as f64,
        };
        Ok(Derived {
            volumes,
            stats,
            gpu_timings,
            vesselness: None,
            vessel_ranges: None,
            brain: None,
        })
    }
}

/// The dispatch that only finds max |g|, which 8-bit storage runs first for its scale.
fn max_only_pass(outputs: DerivativeOutputs) -> DerivativeOutputs {
    DerivativeOutputs {
        magnitude: false,
        curvature: false,
        normal: false,
        precision: outputs.precision,
        vesselness: false,
        brain: crate::passes::brain::BrainSwitch::Off,
    }
}

/// The derivative pipeline variants computing `outputs` runs, in order (two for 8-bit storage:
/// the maximum, then the stores).
pub(crate) fn derivative_variants(outputs: DerivativeOutputs) -> Vec<DerivativeOutputs> {
    let outputs = DerivativeOutputs {
        vesselness: false,
        brain: crate::passes::brain::BrainSwitch::Off,
        ..outputs
    };
    let stores = outputs.magnitude || outputs.curvature;
    if outputs.precision == DerivedPrecision::Snorm8 && stores {
        vec![max_only_pass(outputs), outputs]
    } else {
        vec![outputs]
    }
}

/// World length of the shortest index step (mm).
fn finest_spacing(linear: [[f64; 3]; 3]) -> f64 {
    (0..3)
        .map(|c| (0..3).map(|r| linear[r][c].powi(2)).sum::<f64>().sqrt())
        .fold(f64::INFINITY, f64::min)
}
