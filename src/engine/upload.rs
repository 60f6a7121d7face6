//! Getting stored samples onto the GPU.
//!
//! Decision (Granite's `BufferDomain`): on unified memory (lavapipe, integrated GPUs) the kernels
//! read a host-visible buffer the host wrote in place: no staging copy. On a discrete GPU (the
//! H100) the samples go through a host-memory staging buffer and one transfer into device-local
//! memory, recorded into the caller's recording so it overlaps nothing and is timed as a pass.
//! The buffer is zero-padded to whole 16-byte quads, which the min/max kernel reads.

use crate::gpu::{Access, Buffer, BufferDesc, Device, GpuError, GpuResult, Recording};
use crate::volume::Samples;
use std::sync::Arc;

/// How the samples reached the GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UploadPath {
    /// Written in place into host-visible memory the GPU reads.
    Direct,
    /// Written to host memory and copied into device-local memory.
    Staged,
}

/// Uploads `samples`; for a staged upload the copy is recorded into `rec` (as pass `upload`),
/// followed by the barrier that makes it visible to compute shaders.
pub fn upload_samples(
    device: &Device,
    rec: &mut Recording,
    samples: &Samples,
) -> GpuResult<(Arc<Buffer>, UploadPath)> {
    let bytes = samples.as_bytes();
    let padded = (bytes.len() as u64).div_ceil(16).max(1) * 16;
    let limit = device.adapter().max_storage_buffer_range as u64;
    if padded > limit {
        return Err(GpuError::Unsupported(format!(
            "the volume's {} bytes of samples exceed this device's largest storage buffer ({limit} bytes)",
            bytes.len()
        )));
    }
    let pad = vec![0u8; (padded - bytes.len() as u64) as usize];
    if device.adapter().unified_memory {
        let buffer = Buffer::new(device, BufferDesc::host_storage("volume samples", padded))?;
        buffer.write(0, bytes)?;
        buffer.write(bytes.len() as u64, &pad)?;
        // Host writes before vkQueueSubmit are visible to the submitted work (Vulkan's implicit
        // host-write ordering), so no barrier is needed here.
        return Ok((buffer, UploadPath::Direct));
    }
    let staging = Buffer::new(
        device,
        BufferDesc::staging("volume samples (staging)", padded),
    )?;
    staging.write(0, bytes)?;
    staging.write(bytes.len() as u64, &pad)?;
    let buffer = Buffer::new(device, BufferDesc::gpu_storage("volume samples", padded))?;
    rec.begin_pass("upload");
    rec.copy_buffer(&staging, &buffer, padded);
    rec.end_pass();
    // Orders the copy into the device-local buffer before the kernels that read it.
    rec.barriers(
        &[(&buffer, Access::TransferWrite, Access::ComputeReadBuffer)],
        &[],
    );
    Ok((buffer, UploadPath::Staged))
}
