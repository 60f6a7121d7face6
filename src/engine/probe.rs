//! A device-memory bandwidth probe: the ceiling passes are compared against, measured in the same
//! run on the same device (measure the ceiling, do not trust the datasheet).

use super::Engine;
use crate::gpu::{Access, Buffer, BufferDesc, GpuResult, Recording};
use crate::passes::bandwidth::CopyPass;

impl Engine {
    /// Median bandwidth (bytes read + written per second) of `repeats` device-local copies of
    /// `bytes` bytes by a compute kernel (the path compute passes use), from timestamps. None
    /// when the device has no timestamps.
    pub fn copy_bandwidth(&self, bytes: u64, repeats: u32) -> GpuResult<Option<f64>> {
        let src = Buffer::new(
            &self.device,
            BufferDesc::gpu_storage("bandwidth probe (source)", bytes),
        )?;
        let dst = Buffer::new(
            &self.device,
            BufferDesc::gpu_storage("bandwidth probe (target)", bytes),
        )?;
        let kernel = CopyPass::new(&self.device, self.pipeline_cache.raw())?;
        let mut rates = Vec::new();
        for _ in 0..repeats.max(1) {
            let mut rec = Recording::new(&self.device, "bandwidth probe")?;
            // Fill first so the copy reads written memory, not untouched pages.
            rec.fill_buffer(&src, 0, bytes, 0x3c3c_3c3c);
            // Orders the fill before the kernel's reads.
            rec.barriers(
                &[(&src, Access::TransferWrite, Access::ComputeReadBuffer)],
                &[],
            );
            rec.begin_pass("copy");
            kernel.record(&self.device, &mut rec, &src, &dst)?;
            rec.end_pass();
            let timings = rec.submit()?.wait()?;
            if let Some(t) = timings.iter().find(|t| t.name == "copy" && t.gpu_ms > 0.0) {
                rates.push(2.0 * bytes as f64 / (t.gpu_ms * 1e-3));
            }
        }
        rates.sort_by(f64::total_cmp);
        Ok(rates.get(rates.len() / 2).copied())
    }
}
