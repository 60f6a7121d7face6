//! Getting stored samples onto the GPU.
//!
//! Decision (Granite's `BufferDomain`): on unified memory (lavapipe, integrated GPUs) the kernels
//! read a host-visible buffer the host wrote in place: no staging copy. On a discrete GPU (the
//! H100) the samples go through a host-memory staging buffer and one transfer into device-local
//! memory, recorded into the caller's recording so it overlaps nothing and is timed as a pass.
//! The buffer is zero-padded to whole 16-byte quads, which the min/max kernel reads.
//!
//! A third path, for discrete GPUs with resizable BAR (a device-local heap that host-visible
//! memory reaches, large enough: at least [`REBAR_HEADROOM`] times the samples), writes the
//! samples straight into device-local memory: no staging buffer, no copy. It is chosen by
//! default ([`DEFAULT_REBAR`], measured: BENCHMARKS.md "Streamed loading");
//! `MORPHRAY_UPLOAD=staged` forces the copy, so both can be measured in the same run
//! (`benches/device-streamed.sh`).

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
    /// Written through resizable BAR straight into device-local memory.
    Rebar,
}

/// The environment variable choosing between [`UploadPath::Rebar`] and [`UploadPath::Staged`]
/// on a discrete GPU (`rebar` or `staged`).
pub const UPLOAD_ENV: &str = "MORPHRAY_UPLOAD";

/// Whether a discrete GPU with a large enough BAR uses it when `MORPHRAY_UPLOAD` is unset: yes.
/// On the H100 (benches/results/h100-2026-11-24-streamed) the 268 MB of the 134 M-voxel
/// phantom took 20-22 ms through the BAR (about 13 GB/s from 16 threads) against 90-93 ms of
/// staging writes plus a 25 ms submission holding the 5.3 ms copy; first pixel 267-298 ms
/// against 336-364 ms.
pub const DEFAULT_REBAR: bool = true;

/// The BAR heap must hold this many times the samples: a small (256 MiB) BAR stays for what the
/// driver and the uniforms need.
pub const REBAR_HEADROOM: u64 = 4;

/// True when the samples of `padded` bytes go through the BAR on this device.
pub fn use_rebar(device: &Device, padded: u64) -> bool {
    let adapter = device.adapter();
    let wanted = match std::env::var(UPLOAD_ENV).as_deref() {
        Ok("rebar") => true,
        Ok("staged") => false,
        _ => DEFAULT_REBAR,
    };
    wanted
        && !adapter.unified_memory
        && adapter.host_visible_device_bytes >= padded.saturating_mul(REBAR_HEADROOM)
}

/// Bytes of the sample buffer for `sample_bytes` of samples: a multiple of 16 (the kernels read
/// whole 16-byte vectors), at least 16.
pub fn padded_sample_bytes(sample_bytes: u64) -> u64 {
    sample_bytes.div_ceil(16).max(1) * 16
}

/// The sample buffer and, on a discrete device, its staging buffer (as [`upload_samples`] creates
/// them, and as the pass plan declares them): on unified memory the host writes the buffer the
/// kernels read, otherwise a staging copy goes to device-local memory.
pub fn sample_descs(padded: u64, unified_memory: bool) -> (BufferDesc, Option<BufferDesc>) {
    if unified_memory {
        (BufferDesc::host_storage("volume samples", padded), None)
    } else {
        (
            BufferDesc::gpu_storage("volume samples", padded),
            Some(BufferDesc::staging("volume samples (staging)", padded)),
        )
    }
}

/// Uploads `samples`; for a staged upload the copy is recorded into `rec` (as pass `upload`),
/// followed by the barrier that makes it visible to compute shaders.
pub fn upload_samples(
    device: &Device,
    rec: &mut Recording,
    samples: &Samples,
) -> GpuResult<(Arc<Buffer>, UploadPath)> {
    let bytes = samples.as_bytes();
    let padded = padded_sample_bytes(bytes.len() as u64);
    let limit = device.adapter().max_storage_buffer_range as u64;
    if padded > limit {
        return Err(GpuError::Unsupported(format!(
            "the volume's {} bytes of samples exceed this device's largest storage buffer ({limit} bytes)",
            bytes.len()
        )));
    }
    let pad = vec![0u8; (padded - bytes.len() as u64) as usize];
    if use_rebar(device, padded) {
        // A full BAR heap (other processes' buffers) is no error: the staged path follows.
        match Buffer::new(device, BufferDesc::host_storage("volume samples", padded)) {
            Ok(buffer) => {
                buffer.write(0, bytes)?;
                buffer.write(bytes.len() as u64, &pad)?;
                // Host writes before vkQueueSubmit are visible to the submitted work (Vulkan's
                // implicit host-write ordering), so no barrier is needed here.
                return Ok((buffer, UploadPath::Rebar));
            }
            Err(e) if e.is_out_of_memory() => {}
            Err(e) => return Err(e),
        }
    }
    let (sample_desc, staging_desc) = sample_descs(padded, device.adapter().unified_memory);
    let Some(staging_desc) = staging_desc else {
        let buffer = Buffer::new(device, sample_desc)?;
        buffer.write(0, bytes)?;
        buffer.write(bytes.len() as u64, &pad)?;
        // As above: host writes before the submission need no barrier.
        return Ok((buffer, UploadPath::Direct));
    };
    let staging = Buffer::new(device, staging_desc)?;
    staging.write(0, bytes)?;
    staging.write(bytes.len() as u64, &pad)?;
    let buffer = Buffer::new(device, sample_desc)?;
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
