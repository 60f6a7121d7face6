//! Derived volumes (gradient magnitude, curvature, normals) of a prepared volume.

use super::Engine;
use super::prepare::PreparedVolume;
use crate::gpu::{Access, Buffer, BufferDesc, GpuResult, PassTiming, Recording};
use crate::passes::derivatives::{DEFAULT_TAU, DerivativeOutputs, DerivedVolumes};
use crate::scene::uniforms::GradientStats;

/// Derived volumes and the GPU time they took.
pub struct Derived {
    /// The images (left in `Access::ComputeSampled`).
    pub volumes: DerivedVolumes,
    /// max |g| and the zero-gradient threshold.
    pub stats: GradientStats,
    /// GPU time of the derivative pass.
    pub gpu_timings: Vec<PassTiming>,
}

impl Engine {
    /// Computes the requested derived volumes of `prepared` (nothing else).
    pub fn derive(
        &mut self,
        prepared: &PreparedVolume,
        outputs: DerivativeOutputs,
    ) -> GpuResult<Derived> {
        let device = self.device.clone();
        let nearest = self.nearest.clone();
        let pass = self.derivative_pass(outputs)?;
        let stats_gpu = Buffer::new(&device, BufferDesc::gpu_storage("gradient maximum", 4))?;
        let stats_host = Buffer::new(&device, BufferDesc::readback("gradient maximum (host)", 4))?;
        let mut rec = Recording::new(&device, "derivatives")?;
        rec.begin_pass("derivatives");
        let volumes = pass.record(
            &device,
            &mut rec,
            &prepared.normalized,
            &nearest,
            prepared.linear_part,
            DEFAULT_TAU,
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
        rec.copy_buffer(&stats_gpu, &stats_host, 4);
        // Makes the copy visible to the host.
        rec.barriers(
            &[(&stats_host, Access::TransferWrite, Access::HostRead)],
            &[],
        );
        let gpu_timings = rec.submit()?.wait()?;
        let mut bits = [0u8; 4];
        stats_host.read(0, &mut bits)?;
        let max_magnitude = f32::from_bits(u32::from_le_bytes(bits)) as f64;
        let stats = GradientStats {
            max_magnitude,
            tau: DEFAULT_TAU as f64,
        };
        Ok(Derived {
            volumes,
            stats,
            gpu_timings,
        })
    }
}
