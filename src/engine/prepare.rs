//! Upload, min/max, normalization and histogram of one volume.

use super::Engine;
use super::readback::read_buffer;
use super::upload::{UploadPath, upload_samples};
use crate::gpu::{
    Access, Buffer, BufferDesc, GpuError, GpuResult, Image, ImageDesc, PassTiming, Recording,
};
use crate::passes::histogram::BINS;
use crate::passes::minmax::decode_result;
use crate::passes::normalize::{self, Normalization};
use crate::volume::{SampleKind, Volume};
use ash::vk;
use std::sync::Arc;
use std::time::Instant;

/// The min/max result and the host buffer it is copied to (as [`Engine::prepare`] creates
/// them, and as the pass plan declares them).
pub fn minmax_descs() -> [BufferDesc; 2] {
    [
        BufferDesc::gpu_storage("min/max result", 8),
        BufferDesc::readback("min/max result (host)", 8),
    ]
}

/// The whole volume's I_norm image.
pub fn normalized_desc(dims: [u32; 3], format: vk::Format) -> ImageDesc {
    ImageDesc::volume("normalized volume", dims, format)
}

/// The histogram's bins (read back through [`super::readback::readback_desc`]).
pub fn histogram_desc() -> BufferDesc {
    BufferDesc::gpu_storage("histogram bins", (BINS * 4) as u64)
}

/// Host-side times of [`Engine::prepare`] (GPU pass times are in `PreparedVolume::gpu_timings`).
/// The per-pass walls follow one another and add up to (nearly) `wall_ms`.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PrepareTimings {
    /// Creating pipelines for this sample kind (0 when cached).
    pub pipelines_ms: f64,
    /// Writing the samples into mapped memory.
    pub upload_write_ms: f64,
    /// The whole upload on the host: allocating the buffers and writing the samples (a staged
    /// upload's GPU copy runs in the min/max submission).
    pub upload_ms: f64,
    /// Recording, submitting and waiting for the min/max submission, and reading its result.
    pub minmax_ms: f64,
    /// The robust range's fine-histogram passes (0 in min/max mode).
    pub range_ms: f64,
    /// Allocating I_norm, recording, submitting and waiting for the normalization.
    pub normalize_ms: f64,
    /// Waiting for the histogram (submitted right behind the normalization) and reading its bins.
    pub histogram_ms: f64,
    /// Wall time of the whole preparation.
    pub wall_ms: f64,
}

/// A volume on the GPU: samples, normalized image, histogram.
pub struct PreparedVolume {
    /// Dimensions.
    pub dims: [u32; 3],
    /// Stored sample encoding.
    pub kind: SampleKind,
    /// How the samples were uploaded.
    pub upload_path: UploadPath,
    /// I_norm (the brick atlas when bricked); last accessed as [`Access::ComputeSampled`].
    pub normalized: Arc<Image>,
    /// Whole volume or brick atlas.
    pub layout: VolumeLayout,
    /// Stored-sample min/max over finite voxels (None if none is finite).
    pub stored_range: Option<(f64, f64)>,
    /// Physical range and shader parameters.
    pub normalization: Normalization,
    /// How the range was chosen (mode, data min/max, robust range).
    pub range: crate::analysis::RangeChoice,
    /// 256-bin histogram of I_norm over finite voxels.
    pub histogram: [u32; BINS],
    /// The histogram the tissue analysis reads: `histogram` less a mask's edge when the volume
    /// is a masked structural MR scan (`super::mask_edge`), `histogram` otherwise.
    pub tissue_histogram: [u32; BINS],
    /// Voxels left out of `tissue_histogram` (0 when the volume is not masked).
    pub mask_edge_voxels: u64,
    /// Voxels in the volume.
    pub voxel_count: u64,
    /// Finite voxels (= sum of the histogram).
    pub finite_voxels: u64,
    /// Index-to-world linear part, for derivatives.
    pub linear_part: [[f64; 3]; 3],
    /// Full index-to-world affine (row-major), for rendering.
    pub affine: [[f64; 4]; 4],
    /// What the volume is (modality, contrast): the user's choices until the open path sets
    /// what the metadata says (`Engine::identify`); brain extraction reads it.
    pub identity: crate::analysis::Identity,
    /// GPU time per pass.
    pub gpu_timings: Vec<PassTiming>,
    /// Host-side times.
    pub timings: PrepareTimings,
    /// Per-brick I_norm ranges for empty-space skipping, computed on first use.
    pub(crate) brick_ranges: std::sync::OnceLock<Arc<crate::scene::occupancy::BrickRanges>>,
}

/// How I_norm (and every derived volume) is laid out on the GPU.
#[derive(Clone)]
pub enum VolumeLayout {
    /// One 3D image of the whole volume.
    Whole,
    /// Resident bricks in an atlas, found through a brick table.
    Bricked(BrickAtlas),
}

/// The atlas of a bricked volume.
#[derive(Clone)]
pub struct BrickAtlas {
    /// Brick side without halo (voxels).
    pub brick: u32,
    /// Halo on each side (voxels).
    pub halo: u32,
    /// Bricks along each axis.
    pub grid: [u32; 3],
    /// Slots along each atlas axis.
    pub slots: [u32; 3],
    /// Bricks held in the atlas.
    pub resident: u32,
    /// Slot + 1 per brick, 0 when not resident (host-visible storage buffer).
    pub table: Arc<Buffer>,
    /// Per atlas slot, the box of its texels inside the volume (low corner, exclusive high
    /// corner, 8 bits per axis), so the derivative stencils end at the volume's faces.
    pub slot_bounds: Arc<Buffer>,
}

impl BrickAtlas {
    /// Side of one atlas slot (brick plus two halos).
    pub fn slot_side(&self) -> u32 {
        self.brick + 2 * self.halo
    }
}

impl PreparedVolume {
    /// Side and halo of the atlas slots when bricked, [0, 0] for a whole volume (the derivative
    /// pass clamps its stencils at slot faces and takes max |g| over each slot's own brick).
    pub fn slot_shape(&self) -> [i32; 2] {
        match &self.layout {
            VolumeLayout::Whole => [0, 0],
            VolumeLayout::Bricked(atlas) => [atlas.slot_side() as i32, atlas.halo as i32],
        }
    }

    /// Voxels that are NaN or infinite.
    pub fn nonfinite_voxels(&self) -> u64 {
        self.voxel_count - self.finite_voxels
    }
}

/// Milliseconds since `since`.
fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Checks that the volume's size fits the 32-bit indices and the 3D image limit.
fn checked_dims(engine: &Engine, volume: &Volume) -> GpuResult<[u32; 3]> {
    let max = engine.device.adapter().max_image_dimension_3d;
    let mut dims = [0u32; 3];
    for (axis, &d) in volume.dims.iter().enumerate() {
        dims[axis] = u32::try_from(d).ok().filter(|&d| d >= 1 && d <= max).ok_or_else(|| {
            GpuError::Unsupported(format!(
                "volume side {d} along axis {axis} exceeds this device's 3D image limit of {max}"
            ))
        })?;
    }
    let count = volume.voxel_count() as u64;
    if count > u32::MAX as u64 || volume.samples.len() as u64 != count {
        return Err(GpuError::InvalidRequest(format!(
            "volume of {count} voxels holds {} samples (or exceeds 2^32 voxels)",
            volume.samples.len()
        )));
    }
    Ok(dims)
}

impl Engine {
    /// Uploads `volume` and computes min/max, I_norm and its histogram on the GPU.
    pub fn prepare(&mut self, volume: &Volume) -> GpuResult<PreparedVolume> {
        let start = Instant::now();
        let _span = crate::files::trace::span(
            "prepare (upload, min/max, range, normalize, histogram)",
            "prepare",
        );
        let dims = checked_dims(self, volume)?;
        self.counters.prepares += 1;
        let kind = volume.samples.kind();
        let voxel_count = volume.voxel_count() as u64;
        let device = self.device.clone();
        let normalized_format = self.config.normalized_format;

        // Submission 1: upload and min/max; the host needs the range before normalizing.
        // The upload needs no pipeline, so it runs first: analysis pipelines still compiling on
        // a worker (`Engine::start_pipelines`) get that much longer before they are waited for.
        let before_upload = Instant::now();
        let mut rec = Recording::new(&device, "upload and min/max")?;
        let before_write = Instant::now();
        let (samples, upload_path) = upload_samples(&device, &mut rec, &volume.samples)?;
        let upload_write_ms = before_write.elapsed().as_secs_f64() * 1e3;
        let upload_ms = ms(before_upload);
        let before_pipelines = Instant::now();
        self.kind_passes(kind)?;
        let pipelines_ms = ms(before_pipelines);
        let passes = self.kind_passes(kind)?;
        let before_minmax = Instant::now();
        let [range_gpu, range_host] = minmax_descs();
        let range_gpu = Buffer::new(&device, range_gpu)?;
        let range_host = Buffer::new(&device, range_host)?;
        rec.begin_pass("minmax");
        passes
            .minmax
            .record(&device, &mut rec, &samples, voxel_count, &range_gpu)?;
        rec.end_pass();
        // Orders the min/max atomics before the copy to host memory.
        rec.barriers(
            &[(&range_gpu, Access::ComputeWriteBuffer, Access::TransferRead)],
            &[],
        );
        rec.copy_buffer(&range_gpu, &range_host, 8);
        // Makes the copied result visible to the host.
        rec.barriers(
            &[(&range_host, Access::TransferWrite, Access::HostRead)],
            &[],
        );
        let mut gpu_timings = rec.submit()?.wait()?;
        let mut words = [0u8; 8];
        range_host.read(0, &mut words)?;
        let min_key = u32::from_le_bytes([words[0], words[1], words[2], words[3]]);
        let max_key = u32::from_le_bytes([words[4], words[5], words[6], words[7]]);
        let stored_range = decode_result(min_key, max_key);
        let minmax_plan = normalize::plan(dims, stored_range, volume.to_physical);
        let minmax_ms = ms(before_minmax);
        let before_range = Instant::now();
        let (normalization, range) =
            self.choose_normalization(volume, &samples, minmax_plan, &mut gpu_timings)?;
        let range_ms = ms(before_range);
        let passes = self.kind_passes(kind)?;

        // Submissions 2 and 3: normalize, then histogram of what was written. Two submissions,
        // so the host sees when each pass ends (their walls are measured separately). The
        // histogram is recorded while the normalization runs and submitted when it is done:
        // drivers may signal fences of queued submissions together (lavapipe does), which would
        // hide where one pass ends; the GPU idles only for one submission's latency.
        let before_normalize = Instant::now();
        let normalized = Image::new(&device, normalized_desc(dims, normalized_format))?;
        let bins = Buffer::new(&device, histogram_desc())?;
        let mut rec = Recording::new(&device, "normalize")?;
        passes.normalize.record_for_sampling(
            &mut rec,
            &samples,
            &normalization.params,
            &normalized,
        )?;
        let normalizing = rec.submit()?;
        let mut rec = Recording::new(&device, "histogram")?;
        rec.begin_pass("histogram");
        passes
            .histogram
            .record(&device, &mut rec, &normalized, &samples, &bins)?;
        rec.end_pass();
        gpu_timings.extend(normalizing.wait()?);
        let normalize_ms = ms(before_normalize);
        let before_histogram = Instant::now();
        gpu_timings.extend(rec.submit()?.wait()?);
        let mut bin_bytes = vec![0u8; BINS * 4];
        read_buffer(&device, &bins, Access::ComputeWriteBuffer, &mut bin_bytes)?;
        let mut histogram = [0u32; BINS];
        for (bin, chunk) in histogram.iter_mut().zip(bin_bytes.chunks_exact(4)) {
            *bin = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
        }
        let finite_voxels = histogram.iter().map(|&c| c as u64).sum();
        let histogram_ms = ms(before_histogram);

        Ok(PreparedVolume {
            dims,
            kind,
            upload_path,
            normalized,
            layout: VolumeLayout::Whole,
            stored_range,
            normalization,
            range,
            histogram,
            // The mask's edge is left out once the modality is known
            // (`Engine::leave_out_mask_edge`).
            tissue_histogram: histogram,
            mask_edge_voxels: 0,
            voxel_count,
            finite_voxels,
            linear_part: volume.orientation.linear_part(),
            affine: volume.orientation.affine,
            identity: crate::analysis::Identity::from_choices(
                self.config.analysis.modality,
                self.config.analysis.contrast,
            ),
            gpu_timings,
            brick_ranges: std::sync::OnceLock::new(),
            timings: PrepareTimings {
                pipelines_ms,
                upload_write_ms,
                upload_ms,
                minmax_ms,
                range_ms,
                normalize_ms,
                histogram_ms,
                wall_ms: ms(start),
            },
        })
    }
}
