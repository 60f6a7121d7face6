//! Brick ranges of a prepared volume, computed once on the GPU and kept with the volume, and a
//! render target's cache of the occupancy bits classified from them (`render.rs` says why).

use super::Engine;
use super::prepare::PreparedVolume;
use crate::gpu::{Access, Buffer, BufferDesc, GpuResult, PassTiming, Recording};
use crate::passes::occupancy::{BRICK_SIDE, brick_grid};
use crate::scene::occupancy::BrickRanges;
use crate::scene::{Classification, Scene};
use std::sync::Arc;

/// The per-brick ranges of `bricks` bricks and their host copy (as [`Engine::brick_ranges`]
/// creates them, and as the pass plan declares them).
pub fn brick_range_descs(bricks: u64) -> [BufferDesc; 2] {
    [
        BufferDesc::gpu_storage("brick ranges", 8 * bricks),
        BufferDesc::readback("brick ranges (host)", 8 * bricks),
    ]
}

/// One frame in flight's occupancy bits for `bricks` bricks (32 to a word), written by the host
/// before the frame that reads them.
pub fn occupancy_bits_desc(bricks: u64) -> BufferDesc {
    BufferDesc::host_storage("occupancy bits", 4 * bricks.div_ceil(32))
}

impl Engine {
    /// The per-brick I_norm ranges of `prepared` (one GPU pass the first time, cached after).
    pub fn brick_ranges(&mut self, prepared: &PreparedVolume) -> GpuResult<Arc<BrickRanges>> {
        self.brick_ranges_timed(prepared).map(|(ranges, _)| ranges)
    }

    /// [`Engine::brick_ranges`] with the GPU time of its pass (empty when they were cached).
    pub fn brick_ranges_timed(
        &mut self,
        prepared: &PreparedVolume,
    ) -> GpuResult<(Arc<BrickRanges>, Vec<PassTiming>)> {
        if let Some(r) = prepared.brick_ranges.get() {
            return Ok((r.clone(), Vec::new()));
        }
        let (ranges, timings) = self.ranges_of(&prepared.normalized)?;
        Ok((
            prepared.brick_ranges.get_or_init(|| ranges).clone(),
            timings,
        ))
    }

    /// Per-brick (min, max) of any whole single-channel float `image` (I_norm, the vesselness),
    /// over each brick and its one-voxel halo, by the occupancy pass.
    pub(super) fn ranges_of(
        &mut self,
        image: &Arc<crate::gpu::Image>,
    ) -> GpuResult<(Arc<BrickRanges>, Vec<PassTiming>)> {
        self.occupancy_pass()?;
        self.counters.occupancy_runs += 1;
        let Some(pass) = &self.occupancy_pass else {
            return Err(crate::gpu::GpuError::Internal(
                "occupancy pass missing".into(),
            ));
        };
        let grid = brick_grid(image.extent());
        let bricks = (grid[0] * grid[1] * grid[2]) as u64;
        let [gpu, host] = brick_range_descs(bricks);
        let gpu = Buffer::new(&self.device, gpu)?;
        let host = Buffer::new(&self.device, host)?;
        let mut rec = Recording::new(&self.device, "brick ranges")?;
        rec.begin_pass("occupancy");
        pass.record(&mut rec, image, &self.nearest, &gpu)?;
        rec.end_pass();
        // Orders the range writes before the copy, and the copy before the host reads it.
        rec.barriers(
            &[(&gpu, Access::ComputeWriteBuffer, Access::TransferRead)],
            &[],
        );
        rec.copy_buffer(&gpu, &host, 8 * bricks);
        rec.barriers(&[(&host, Access::TransferWrite, Access::HostRead)], &[]);
        let timings = rec.submit()?.wait()?;
        let mut bytes = vec![0u8; 8 * bricks as usize];
        host.read(0, &mut bytes)?;
        let ranges = bytes
            .chunks_exact(8)
            .map(|c| {
                let lo = f32::from_bits(u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
                let hi = f32::from_bits(u32::from_le_bytes([c[4], c[5], c[6], c[7]]));
                (lo, hi)
            })
            .collect();
        let ranges = Arc::new(BrickRanges {
            grid,
            side: BRICK_SIDE,
            ranges,
        });
        Ok((ranges, timings))
    }
}

/// The occupancy bits of one volume (its brick ranges) under one classification.
pub(super) struct OccupancyCache {
    pub(super) ranges: Arc<BrickRanges>,
    pub(super) classification: Classification,
    pub(super) labels: Option<Arc<Vec<u32>>>,
    pub(super) vessels: Option<Arc<BrickRanges>>,
    pub(super) bits: Vec<u32>,
    pub(super) occupied: f64,
    // Starts at 1 and grows with every recomputation (0: a slot holds nothing yet).
    pub(super) generation: u64,
}

impl OccupancyCache {
    /// The cached bits when volume and classification are unchanged, else recomputed.
    pub(super) fn update<'a>(
        slot: &'a mut Option<OccupancyCache>,
        ranges: &Arc<BrickRanges>,
        scene: &Scene,
        labels: Option<Arc<Vec<u32>>>,
        vessels: Option<&Arc<BrickRanges>>,
    ) -> Option<&'a OccupancyCache> {
        let fresh = slot.as_ref().is_some_and(|c| {
            Arc::ptr_eq(&c.ranges, ranges)
                && c.classification == scene.classification
                && match (&c.labels, &labels) {
                    (None, None) => true,
                    (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                    _ => false,
                }
                && match (&c.vessels, vessels) {
                    (None, None) => true,
                    (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                    _ => false,
                }
        });
        if !fresh {
            let mut bits = ranges.occupancy_bits(&scene.classification);
            // Bricks holding a drawn label are never skipped (labels.rs).
            if let Some(label_bits) = &labels {
                for (word, extra) in bits.iter_mut().zip(label_bits.iter()) {
                    *word |= extra;
                }
            }
            // Bricks where the vessel channel can be non-zero (its own ranges, same grid).
            if let Some(vessel_ranges) = vessels {
                let vessel_bits = vessel_ranges.vessel_bits(&scene.classification);
                for (word, extra) in bits.iter_mut().zip(vessel_bits) {
                    *word |= extra;
                }
            }
            let occupied = bits.iter().map(|w| w.count_ones() as u64).sum::<u64>() as f64
                / ranges.ranges.len().max(1) as f64;
            let generation = slot.as_ref().map_or(1, |c| c.generation + 1);
            *slot = Some(OccupancyCache {
                ranges: ranges.clone(),
                classification: scene.classification,
                labels,
                vessels: vessels.cloned(),
                bits,
                occupied,
                generation,
            });
        }
        slot.as_ref()
    }
}
