//! Bricked volumes: for volumes over the memory budget or the device's 3D image limit.
//!
//! Decisions:
//! - Preparation runs on the host. What does not fit is exactly the whole-volume sample buffer
//!   and image the GPU kernels (min/max, normalize, histogram) work on, so the f64 twins do that
//!   work: min/max over finite samples, `I_norm` in f64, quantized to the atlas format the way
//!   the GPU stores it (round to nearest), and the histogram binned with the GPU's f32 rule from
//!   the quantized values, so peaks and windows come out as on a whole volume.
//! - Only resident bricks go to the GPU: a 32^3 brick (plus a 3-voxel halo) is resident when the
//!   scene can read a value from its halo-extended range that changes the image
//!   (`BrickRanges::needed_bits`: a visible tissue window in DVR, any value above the display
//!   window's black point in MIP, any value reaching the floor in MinIP). Skipped bricks hold
//!   nothing a ray could see in that scene, so the image matches the whole volume's; a scene
//!   that needs more bricks needs a new upload (`render` refuses it with a typed error rather
//!   than drawing holes).
//! - Slots are packed into an atlas that respects the 3D image limit (slots along x first), and
//!   filled through one staging buffer reused batch by batch, so the upload itself stays within
//!   a few megabytes.

use super::Engine;
use super::prepare::{BrickAtlas, PrepareTimings, PreparedVolume, VolumeLayout};
use super::upload::UploadPath;
use crate::engine::plan::{STORAGE_BRICK, STORAGE_HALO, atlas_slots};
use crate::gpu::{Access, Buffer, BufferDesc, GpuError, GpuResult, Image, ImageDesc, Recording};
use crate::passes::histogram::BINS;
use crate::passes::normalize::{self, Normalization};
use crate::passes::occupancy::BRICK_SIDE;
use crate::reference;
use crate::scene::Scene;
use crate::scene::occupancy::BrickRanges;
use crate::volume::{SampleKind, Volume};
use ash::vk;
use std::sync::Arc;
use std::time::Instant;

/// A volume normalized on the host, ready to be bricked.
pub struct HostPrepared {
    /// Dimensions.
    pub dims: [u32; 3],
    /// Stored sample encoding.
    pub kind: SampleKind,
    /// Stored-sample min/max over finite voxels.
    pub stored_range: Option<(f64, f64)>,
    /// Physical range (and the GPU normalization's parameters, for reports).
    pub normalization: Normalization,
    /// How the range was chosen (mode, data min/max, robust range).
    pub range: crate::analysis::RangeChoice,
    /// 256-bin histogram of the quantized I_norm over finite voxels.
    pub histogram: [u32; BINS],
    /// `histogram` less a mask's edge (`super::mask_edge`), what the tissue analysis reads.
    pub tissue_histogram: [u32; BINS],
    /// Voxels left out of `tissue_histogram`.
    pub mask_edge_voxels: u64,
    /// Voxels in the volume.
    pub voxel_count: u64,
    /// Finite voxels.
    pub finite_voxels: u64,
    /// Index-to-world linear part.
    pub linear_part: [[f64; 3]; 3],
    /// Index-to-world affine (row-major).
    pub affine: [[f64; 4]; 4],
    /// Atlas format: R8_UNORM or R16_UNORM.
    pub format: vk::Format,
    /// Quantized I_norm per voxel (0..=255 for R8, 0..=65535 for R16).
    texels: Vec<u16>,
    /// Host time of the preparation.
    pub host_ms: f64,
}

impl HostPrepared {
    /// Leaves a mask's edge out of `tissue_histogram` when `volume` (what this was prepared
    /// from) is masked (`super::mask_edge`; the caller decides that the modality wants it). Each
    /// edge voxel binned from its stored texel, as `histogram` was.
    pub fn leave_out_mask_edge(&mut self, volume: &Volume) {
        let unit = self.unit();
        let Some((stored_min, _)) = self.stored_range else {
            return;
        };
        if self.normalization.constant || !super::mask_edge::may_be_masked(&self.histogram) {
            return;
        }
        let texels = &self.texels;
        let bin = |i: usize| {
            let t = texels.get(i).copied().unwrap_or(0);
            reference::histogram::bin_of(f32::from(t) / unit)
        };
        if let Some(edge) = super::mask_edge::mask_edge(volume, stored_min, bin) {
            self.tissue_histogram = super::mask_edge::without_edge(&self.histogram, &edge);
            self.mask_edge_voxels = edge.voxels;
        }
    }

    fn unit(&self) -> f32 {
        if self.format == vk::Format::R8_UNORM {
            255.0
        } else {
            65535.0
        }
    }

    fn texel(&self, x: i64, y: i64, z: i64) -> u16 {
        let c = |v: i64, d: u32| v.clamp(0, d as i64 - 1) as usize;
        let [nx, ny, nz] = self.dims;
        let i = c(x, nx) + nx as usize * (c(y, ny) + ny as usize * c(z, nz));
        self.texels.get(i).copied().unwrap_or(0)
    }

    /// I_norm ranges of cubic bricks of `side` voxels extended by `halo` on every side.
    pub fn brick_ranges(&self, side: u32, halo: u32) -> BrickRanges {
        let grid = self.dims.map(|d| d.div_ceil(side));
        let unit = self.unit();
        let mut ranges = Vec::with_capacity(grid.iter().map(|&g| g as usize).product());
        let (side, halo) = (side as i64, halo as i64);
        for bz in 0..grid[2] as i64 {
            for by in 0..grid[1] as i64 {
                for bx in 0..grid[0] as i64 {
                    let (mut lo, mut hi) = (u16::MAX, 0u16);
                    let span = |b: i64, d: u32| {
                        (b * side - halo).max(0)..=(b * side + side - 1 + halo).min(d as i64 - 1)
                    };
                    for z in span(bz, self.dims[2]) {
                        for y in span(by, self.dims[1]) {
                            for x in span(bx, self.dims[0]) {
                                let t = self.texel(x, y, z);
                                lo = lo.min(t);
                                hi = hi.max(t);
                            }
                        }
                    }
                    ranges.push((lo as f32 / unit, hi as f32 / unit));
                }
            }
        }
        BrickRanges {
            grid,
            side: side as u32,
            ranges,
        }
    }
}

/// x | y << 8 | z << 16 (slot coordinates are below 256).
fn pack_box(corner: [u32; 3]) -> u32 {
    corner[0] | corner[1] << 8 | corner[2] << 16
}

fn texel_bytes(format: vk::Format) -> usize {
    if format == vk::Format::R8_UNORM { 1 } else { 2 }
}

/// The brick atlas of `extent` texels (resident slots with their halos), as
/// [`Engine::upload_bricks`] creates it and as the pass plan declares it.
pub fn atlas_desc(extent: [u32; 3], format: vk::Format) -> ImageDesc {
    ImageDesc::volume("normalized volume (brick atlas)", extent, format)
}

/// The brick table of `bricks` bricks (the slot of each, 0 when not resident).
pub fn brick_table_desc(bricks: u64) -> BufferDesc {
    BufferDesc::host_storage("brick table", 4 * bricks.max(1))
}

/// Each of `slots` atlas slots' box inside the volume (two packed words).
pub fn slot_bounds_desc(slots: u64) -> BufferDesc {
    BufferDesc::host_storage("atlas slot bounds", 8 * slots)
}

/// The staging buffer bricks go up through, `bytes` of slots per batch.
pub fn brick_staging_desc(bytes: u64) -> BufferDesc {
    BufferDesc::staging("brick upload (staging)", bytes)
}

impl Engine {
    /// Normalizes `volume` on the host into `format` (R8_UNORM or R16_UNORM) with its histogram.
    pub fn prepare_on_host(&self, volume: &Volume, format: vk::Format) -> GpuResult<HostPrepared> {
        let _span = crate::files::trace::span("prepare on the host (bricked)", "prepare");
        let start = Instant::now();
        if format != vk::Format::R8_UNORM && format != vk::Format::R16_UNORM {
            return Err(GpuError::InvalidRequest(format!(
                "bricked volumes are stored as R8 or R16 UNORM, not {format:?}"
            )));
        }
        let dims = volume.dims.map(|d| u32::try_from(d).unwrap_or(u32::MAX));
        if volume.samples.len() != volume.voxel_count() {
            return Err(GpuError::InvalidRequest(
                "the volume's sample count does not match its dims".into(),
            ));
        }
        let stored_range = reference::minmax::finite_min_max(&volume.samples);
        let minmax = normalize::plan(dims, stored_range, volume.to_physical);
        let (normalization, range) =
            super::robust::host_normalization(volume, minmax, self.config.normalize);
        let (imin, imax) = (
            normalization.imin.unwrap_or(0.0),
            normalization.imax.unwrap_or(0.0),
        );
        let unit = if format == vk::Format::R8_UNORM {
            255.0
        } else {
            65535.0
        };
        let n = volume.voxel_count();
        let mut texels = vec![0u16; n];
        let mut finite = vec![false; n];
        let threads = std::thread::available_parallelism()
            .map(|t| t.get())
            .unwrap_or(1)
            .max(1);
        let chunk = n.div_ceil(threads).max(1);
        let samples = &volume.samples;
        let map = volume.to_physical;
        let constant = normalization.constant;
        std::thread::scope(|scope| {
            for ((t, f), start) in texels
                .chunks_mut(chunk)
                .zip(finite.chunks_mut(chunk))
                .zip((0..n).step_by(chunk))
            {
                scope.spawn(move || {
                    for i in 0..t.len() {
                        let s = samples.get(start + i);
                        f[i] = s.is_finite();
                        let v = if !f[i] || constant {
                            0.0
                        } else {
                            reference::normalize::normalize_value(map.apply(s), imin, imax)
                        };
                        t[i] = (v * unit).round().clamp(0.0, unit) as u16;
                    }
                });
            }
        });
        let norm: Vec<f32> = texels.iter().map(|&t| t as f32 / unit as f32).collect();
        let histogram = reference::histogram::histogram(&norm, |i| finite[i]);
        let finite_voxels = histogram.iter().map(|&c| c as u64).sum();
        Ok(HostPrepared {
            dims,
            kind: volume.samples.kind(),
            stored_range,
            normalization,
            range,
            histogram,
            tissue_histogram: histogram,
            mask_edge_voxels: 0,
            voxel_count: n as u64,
            finite_voxels,
            linear_part: volume.orientation.linear_part(),
            affine: volume.orientation.affine,
            format,
            texels,
            host_ms: start.elapsed().as_secs_f64() * 1e3,
        })
    }

    /// Uploads the bricks `scene` can see into an atlas; everything else stays on the host. The
    /// result renders like a whole volume for that scene.
    pub fn upload_bricked(
        &mut self,
        host: &HostPrepared,
        scene: &Scene,
        staging_slots: u32,
    ) -> GpuResult<PreparedVolume> {
        let slots_per_batch = staging_slots.max(1) as usize;
        let start = Instant::now();
        let storage = host.brick_ranges(STORAGE_BRICK, STORAGE_HALO);
        let bits = storage.needed_bits(scene);
        let resident: Vec<usize> = (0..storage.ranges.len())
            .filter(|&b| bits[b / 32] >> (b % 32) & 1 == 1)
            .collect();
        let slot = (STORAGE_BRICK + 2 * STORAGE_HALO) as usize;
        let max = self.device.adapter().max_image_dimension_3d as usize;
        let count = resident.len().max(1);
        let Some([sx, sy, sz]) = atlas_slots(count as u32, (max / slot) as u32) else {
            return Err(GpuError::Unsupported(format!(
                "{count} resident bricks do not fit an atlas within the 3D image limit of {max}"
            )));
        };
        let [sx, sy, sz] = [sx as usize, sy as usize, sz as usize];
        let atlas_dims = [(sx * slot) as u32, (sy * slot) as u32, (sz * slot) as u32];
        let atlas = Image::new(&self.device, atlas_desc(atlas_dims, host.format))?;
        let mut table = vec![0u32; storage.ranges.len()];
        for (s, &b) in resident.iter().enumerate() {
            table[b] = s as u32 + 1;
        }
        let table_buffer = Buffer::with_data(
            &self.device,
            brick_table_desc(table.len() as u64),
            bytemuck::cast_slice(if table.is_empty() {
                &[0u32][..]
            } else {
                &table[..]
            }),
        )?;

        // Fill the slots batch by batch through one staging buffer.
        let bytes = texel_bytes(host.format);
        let slot_texels = slot * slot * slot;
        let staging = Buffer::new(
            &self.device,
            brick_staging_desc((slots_per_batch.min(count) * slot_texels * bytes) as u64),
        )?;
        let grid = storage.grid;
        let mut first = true;
        let mut gpu_timings = Vec::new();
        for batch in resident
            .chunks(slots_per_batch)
            .enumerate()
            .map(|(k, c)| (k * slots_per_batch, c))
        {
            let (first_slot, bricks) = batch;
            let mut data = vec![0u8; bricks.len() * slot_texels * bytes];
            let mut regions = Vec::with_capacity(bricks.len());
            for (k, &b) in bricks.iter().enumerate() {
                let (bx, by, bz) = (
                    b % grid[0] as usize,
                    (b / grid[0] as usize) % grid[1] as usize,
                    b / (grid[0] as usize * grid[1] as usize),
                );
                let origin =
                    [bx, by, bz].map(|c| (c * STORAGE_BRICK as usize) as i64 - STORAGE_HALO as i64);
                let base = k * slot_texels * bytes;
                for z in 0..slot {
                    for y in 0..slot {
                        for x in 0..slot {
                            let t = host.texel(
                                origin[0] + x as i64,
                                origin[1] + y as i64,
                                origin[2] + z as i64,
                            );
                            let at = base + ((z * slot + y) * slot + x) * bytes;
                            if bytes == 1 {
                                data[at] = t as u8;
                            } else {
                                data[at..at + 2].copy_from_slice(&t.to_le_bytes());
                            }
                        }
                    }
                }
                let s = first_slot + k;
                let slot_origin = [s % sx, (s / sx) % sy, s / (sx * sy)].map(|c| (c * slot) as i32);
                regions.push(vk::BufferImageCopy {
                    buffer_offset: base as u64,
                    buffer_row_length: 0,
                    buffer_image_height: 0,
                    image_subresource: vk::ImageSubresourceLayers {
                        aspect_mask: vk::ImageAspectFlags::COLOR,
                        mip_level: 0,
                        base_array_layer: 0,
                        layer_count: 1,
                    },
                    image_offset: vk::Offset3D {
                        x: slot_origin[0],
                        y: slot_origin[1],
                        z: slot_origin[2],
                    },
                    image_extent: vk::Extent3D {
                        width: slot as u32,
                        height: slot as u32,
                        depth: slot as u32,
                    },
                });
            }
            staging.write(0, &data)?;
            let mut rec = Recording::new(&self.device, "brick upload")?;
            // Moves the atlas to TRANSFER_DST: discarding its contents the first time, after the
            // previous batch's copy (a write the new one must not race) afterwards.
            let before = if first {
                Access::Nothing
            } else {
                Access::TransferWrite
            };
            rec.barriers(&[], &[(&atlas, before, Access::TransferWrite)]);
            rec.begin_pass("brick upload");
            rec.copy_buffer_to_image_regions(&staging, &atlas, &regions);
            rec.end_pass();
            gpu_timings.extend(rec.submit()?.wait()?);
            first = false;
        }
        let mut rec = Recording::new(&self.device, "atlas layout")?;
        // Orders the uploads (or, with no resident brick, nothing) before every sampling.
        rec.barriers(
            &[],
            &[(
                &atlas,
                if first {
                    Access::Nothing
                } else {
                    Access::TransferWrite
                },
                Access::ComputeSampled,
            )],
        );
        rec.submit()?.wait()?;

        // Empty-space skipping's 8^3 ranges come from the host data too.
        let fine = host.brick_ranges(BRICK_SIDE, 2);
        let ranges = std::sync::OnceLock::new();
        let _ = ranges.set(Arc::new(fine));
        // Each slot's box inside the volume (unused slots: the whole slot), for the derivative
        // stencils.
        let mut bounds = vec![[0u32, pack_box([slot as u32; 3])]; sx * sy * sz];
        for (s, &b) in resident.iter().enumerate() {
            let brick = [
                b % grid[0] as usize,
                (b / grid[0] as usize) % grid[1] as usize,
                b / (grid[0] as usize * grid[1] as usize),
            ];
            let mut lo = [0u32; 3];
            let mut hi = [0u32; 3];
            for axis in 0..3 {
                let origin = (brick[axis] * STORAGE_BRICK as usize) as i64 - STORAGE_HALO as i64;
                lo[axis] = (-origin).clamp(0, slot as i64) as u32;
                hi[axis] = (host.dims[axis] as i64 - origin).clamp(0, slot as i64) as u32;
            }
            bounds[s] = [pack_box(lo), pack_box(hi)];
        }
        let slot_bounds = Buffer::with_data(
            &self.device,
            slot_bounds_desc(bounds.len() as u64),
            bytemuck::cast_slice(&bounds),
        )?;
        let layout = VolumeLayout::Bricked(BrickAtlas {
            brick: STORAGE_BRICK,
            halo: STORAGE_HALO,
            grid,
            slots: [sx as u32, sy as u32, sz as u32],
            resident: resident.len() as u32,
            table: table_buffer,
            slot_bounds,
        });
        Ok(PreparedVolume {
            dims: host.dims,
            kind: host.kind,
            upload_path: UploadPath::Staged,
            normalized: atlas,
            layout,
            stored_range: host.stored_range,
            normalization: host.normalization,
            range: host.range,
            histogram: host.histogram,
            tissue_histogram: host.tissue_histogram,
            mask_edge_voxels: host.mask_edge_voxels,
            voxel_count: host.voxel_count,
            finite_voxels: host.finite_voxels,
            linear_part: host.linear_part,
            affine: host.affine,
            identity: crate::analysis::Identity::from_choices(
                self.config.analysis.modality,
                self.config.analysis.contrast,
            ),
            gpu_timings,
            timings: PrepareTimings {
                pipelines_ms: 0.0,
                upload_write_ms: host.host_ms,
                // Host normalization and the brick uploads: no GPU analysis passes run.
                upload_ms: start.elapsed().as_secs_f64() * 1e3 + host.host_ms,
                wall_ms: start.elapsed().as_secs_f64() * 1e3 + host.host_ms,
                ..Default::default()
            },
            brick_ranges: ranges,
        })
    }
}

/// Fails when `scene` can see a brick that is not resident in the atlas.
pub(super) fn check_residency(
    prepared: &PreparedVolume,
    atlas: &BrickAtlas,
    scene: &Scene,
) -> GpuResult<()> {
    let Some(ranges) = prepared.brick_ranges.get() else {
        return Ok(());
    };
    // The fine (8^3) ranges say which fine bricks the scene can see; each must lie in a resident
    // storage brick. Storage bricks are a whole number of fine bricks (32 = 4 x 8).
    let bits = ranges.needed_bits(scene);
    let mut table = vec![0u8; 4 * atlas.grid.iter().map(|&g| g as usize).product::<usize>()];
    atlas.table.read(0, &mut table)?;
    let ratio = atlas.brick / ranges.side;
    let [gx, gy, _] = ranges.grid;
    for (b, _) in ranges.ranges.iter().enumerate() {
        if bits[b / 32] >> (b % 32) & 1 == 0 {
            continue;
        }
        let (x, y, z) = (b as u32 % gx, (b as u32 / gx) % gy, b as u32 / (gx * gy));
        let s = [x / ratio, y / ratio, z / ratio];
        let index = (s[0] + atlas.grid[0] * (s[1] + atlas.grid[1] * s[2])) as usize * 4;
        let slot = table
            .get(index..index + 4)
            .map_or(0, |w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]));
        if slot == 0 {
            return Err(GpuError::InvalidRequest(
                "this bricked volume was uploaded for another scene (tissue windows or mode); this \
                 scene sees bricks that are not resident (open it again with this scene)"
                    .into(),
            ));
        }
    }
    Ok(())
}
