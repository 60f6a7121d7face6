//! Brick ranges of a prepared volume, computed once on the GPU and kept with the volume, and a
//! render target's occupancy buffers: the bits and opacity bounds the brick-bounds pass makes
//! from the ranges under the scene's classification (`render.rs` says why they are cached).
//!
//! Decisions (issue 17 item 2):
//! - The brick-bounds pass runs only when the classification (or the volume, vesselness or
//!   labels) changes, once per frame in flight, each in a submission of its own that is waited
//!   for: the frame needs the count of occupied bricks to choose the raymarch variant (no
//!   skipping when nearly every brick is occupied), and a change of windows is rare enough for
//!   one wait. An orbit runs nothing and writes nothing.
//! - The pass's inputs (ranges, vesselness ranges, label bits) are copied into each frame slot's
//!   buffer by the host when they change (a new volume), 8-16 bytes a brick; the GPU copy of the
//!   ranges is not kept by the prepared volume (`prepare.rs`), so it is not reused here.

use super::Engine;
use super::prepare::PreparedVolume;
use crate::gpu::{Access, Buffer, BufferDesc, GpuResult, PassTiming, Recording};
use crate::passes::brick_bounds::{
    BrickBoundsLayout, BrickBoundsParams, EMPTY_SUPPORT, LABEL_BIT, VESSEL_BIT,
};
use crate::passes::occupancy::{BRICK_SIDE, brick_grid};
use crate::scene::occupancy::{BrickRanges, bound_channels};
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

impl Engine {
    /// Whether this engine's raymarch reads its per-sample tables through texel buffers
    /// (`EngineConfig::texel_lookups`, else the device's preference).
    pub fn texel_lookups(&self) -> bool {
        self.config
            .texel_lookups
            .unwrap_or_else(|| self.device.adapter().prefers_texel_lookups())
    }
}

/// One frame in flight's occupancy buffer for `bricks` bricks ([`BrickBoundsLayout`]: bits,
/// opacity bounds, and the brick-bounds pass's inputs), host-visible so the host writes the
/// inputs and reads the count of occupied bricks.
///
/// With `texel_view` the raymarch reads the bits and bounds per sample through an R32_UINT
/// texel view (devices that prefer texel lookups: `AdapterInfo::prefers_texel_lookups`); the
/// brick-bounds pass writes it as a storage buffer.
pub fn occupancy_bits_desc(bricks: u64, texel_view: bool) -> BufferDesc {
    let desc = BufferDesc::host_storage("occupancy bits", BrickBoundsLayout::new(bricks).bytes());
    if texel_view {
        desc.with_texel_view(ash::vk::Format::R32_UINT)
    } else {
        desc
    }
}

/// Whether the raymarch can read the occupancy buffer of `bricks` bricks: always through a
/// storage buffer; through a texel view (`texels`) only where the device's texel buffers address
/// every word (Vulkan guarantees 65536 texels; lavapipe 2^27). Where they do not, the raymarch
/// does not skip (lossless either way).
pub fn occupancy_addressable(device: &crate::gpu::Device, bricks: u64, texels: bool) -> bool {
    !texels
        || BrickBoundsLayout::new(bricks).bytes() / 4
            <= device.adapter().max_texel_buffer_elements as u64
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
    /// over each brick and its 2-voxel halo, by the occupancy pass.
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

/// What a brick-bounds buffer's inputs are made of.
#[derive(Clone)]
pub(super) struct BoundsInputs {
    /// The volume's I_norm ranges.
    pub(super) ranges: Arc<BrickRanges>,
    /// The vesselness's ranges (the vessel channel is drawn).
    pub(super) vessels: Option<Arc<BrickRanges>>,
    /// Bricks holding a drawn label.
    pub(super) labels: Option<Arc<Vec<u32>>>,
}

fn same<T>(a: &Option<Arc<T>>, b: &Option<Arc<T>>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => Arc::ptr_eq(a, b),
        _ => false,
    }
}

impl BoundsInputs {
    fn same(&self, other: &BoundsInputs) -> bool {
        Arc::ptr_eq(&self.ranges, &other.ranges)
            && same(&self.vessels, &other.vessels)
            && same(&self.labels, &other.labels)
    }

    fn layout(&self) -> BrickBoundsLayout {
        BrickBoundsLayout::new(self.ranges.ranges.len() as u64)
    }

    /// The input words from the layout's ranges to its count word (zeroed), inclusive.
    fn words(&self) -> GpuResult<Vec<u32>> {
        let layout = self.layout();
        let bricks = self.ranges.ranges.len();
        let mut words = vec![0u32; (layout.count() + 1 - layout.ranges()) as usize];
        let ranges = |out: &mut [u32], r: &BrickRanges| {
            for (pair, &(lo, hi)) in out.chunks_exact_mut(2).zip(&r.ranges) {
                pair[0] = lo.to_bits();
                pair[1] = hi.to_bits();
            }
        };
        ranges(&mut words[..2 * bricks], &self.ranges);
        if let Some(v) = &self.vessels {
            if v.ranges.len() != bricks {
                return Err(crate::gpu::GpuError::Internal(format!(
                    "the vesselness has {} bricks, the volume {bricks}",
                    v.ranges.len()
                )));
            }
            ranges(&mut words[2 * bricks..4 * bricks], v);
        }
        if let Some(l) = &self.labels {
            let start = 4 * bricks;
            for (w, &bits) in words[start..start + layout.words as usize]
                .iter_mut()
                .zip(l.iter())
            {
                *w = bits;
            }
        }
        Ok(words)
    }
}

/// The brick-bounds pass's push constants for `classification` over `inputs`.
fn bounds_params(inputs: &BoundsInputs, classification: &Classification) -> BrickBoundsParams {
    let channels = bound_channels(classification, inputs.vessels.is_some());
    let mut params = BrickBoundsParams {
        windows: [[0.0; 4]; 5],
        supports: [EMPTY_SUPPORT; 5],
        bricks: inputs.ranges.ranges.len() as u32,
        flags: 0,
    };
    for (i, c) in channels.iter().enumerate() {
        if let Some(c) = c {
            params.windows[i] = [c.lo, c.hi, c.edge, c.opacity];
            params.supports[i] = [c.support.0, c.support.1];
        }
    }
    if inputs.vessels.is_some() {
        params.flags |= VESSEL_BIT;
    }
    if inputs.labels.is_some() {
        params.flags |= LABEL_BIT;
    }
    params
}

/// Occupancy bits and opacity bounds read back from the brick-bounds pass.
#[derive(Clone, Debug)]
pub struct BrickBounds {
    /// One bit per brick (32 to a word), as the raymarch reads them.
    pub bits: Vec<u32>,
    /// Upper bound of the opacity per mm a sample in each brick can have (plus 1 with a label).
    pub bounds: Vec<f32>,
    /// Per brick, the Chebyshev distance in bricks to the nearest occupied brick (0 when
    /// occupied, at most 255), as the raymarch reads it (`passes::brick_distance`).
    pub distances: Vec<u8>,
    /// Fraction of bricks occupied.
    pub occupied: f64,
    /// GPU time of the pass.
    pub timings: Vec<PassTiming>,
}

impl Engine {
    /// Runs the brick-bounds pass over `data` (inputs written, count zeroed) and the distance
    /// map of its bits over the brick grid `grid`, and waits; returns the fraction of bricks
    /// occupied and the passes' GPU times.
    fn run_brick_bounds(
        &mut self,
        data: &Arc<Buffer>,
        params: &BrickBoundsParams,
        grid: [u32; 3],
    ) -> GpuResult<(f64, Vec<PassTiming>)> {
        self.occupancy_pass()?;
        let Some(pass) = &self.occupancy_pass else {
            return Err(crate::gpu::GpuError::Internal(
                "occupancy pass missing".into(),
            ));
        };
        self.counters.brick_bounds_runs += 1;
        let mut rec = Recording::new(&self.device, "brick bounds")?;
        rec.begin_pass("brick bounds");
        pass.bounds().record(&mut rec, data, params)?;
        rec.end_pass();
        rec.begin_pass("brick distance");
        pass.distance().record(&mut rec, data, grid)?;
        rec.end_pass();
        // Orders the passes' writes before the host reads the count, and before the raymarch
        // of any later submission reads the bits, bounds and distances.
        rec.barriers(&[(data, Access::ComputeWriteBuffer, Access::HostRead)], &[]);
        rec.barriers(
            &[(data, Access::ComputeWriteBuffer, Access::ComputeReadBuffer)],
            &[],
        );
        let timings = rec.submit()?.wait()?;
        let layout = BrickBoundsLayout::new(u64::from(params.bricks));
        let mut count = [0u8; 4];
        data.read(4 * layout.count(), &mut count)?;
        let occupied = f64::from(u32::from_le_bytes(count)) / layout.bricks.max(1) as f64;
        Ok((occupied, timings))
    }

    /// The brick-bounds pass of `classification` over `ranges` (with the vesselness's ranges
    /// and label bits when given), in a buffer of its own, read back: for tests (against
    /// `BrickRanges::reference_bits` and `reference_bounds`) and for timing the pass.
    pub fn brick_bounds(
        &mut self,
        ranges: &Arc<BrickRanges>,
        classification: &Classification,
        vessels: Option<&Arc<BrickRanges>>,
        labels: Option<&Arc<Vec<u32>>>,
    ) -> GpuResult<BrickBounds> {
        let inputs = BoundsInputs {
            ranges: ranges.clone(),
            vessels: vessels.cloned(),
            labels: labels.cloned(),
        };
        let layout = inputs.layout();
        let data = Buffer::new(&self.device, occupancy_bits_desc(layout.bricks, false))?;
        data.write(4 * layout.ranges(), bytemuck::cast_slice(&inputs.words()?))?;
        let params = bounds_params(&inputs, classification);
        let (occupied, timings) = self.run_brick_bounds(&data, &params, ranges.grid)?;
        let mut out = vec![0u32; (layout.words + layout.bricks) as usize];
        data.read(0, bytemuck::cast_slice_mut(&mut out))?;
        let bounds = out[layout.words as usize..]
            .iter()
            .map(|&w| f32::from_bits(w))
            .collect();
        out.truncate(layout.words as usize);
        let mut distances = vec![0u8; 4 * layout.distance_words() as usize];
        data.read(4 * layout.distances(), &mut distances)?;
        distances.truncate(layout.bricks as usize);
        Ok(BrickBounds {
            bits: out,
            bounds,
            distances,
            occupied,
            timings,
        })
    }

    /// Makes frame slot `slot`'s occupancy buffer hold the bits and bounds of `scene` over
    /// `inputs` (running the brick-bounds pass only when they changed since that slot's last
    /// frame); returns the buffer and the fraction of bricks occupied.
    pub(super) fn occupancy_for_frame(
        &mut self,
        slots: &mut OccupancySlots,
        slot: usize,
        inputs: BoundsInputs,
        scene: &Scene,
    ) -> GpuResult<(Arc<Buffer>, f64)> {
        let layout = inputs.layout();
        // The generation of the inputs and of the classification over them.
        let (inputs_changed, fresh) = match &slots.cache {
            Some(c) => (
                !c.inputs.same(&inputs),
                c.inputs.same(&inputs) && c.classification == scene.classification,
            ),
            None => (true, false),
        };
        if !fresh {
            let old = slots.cache.as_ref();
            let generation = old.map_or(1, |c| c.generation + 1);
            let inputs_generation = old.map_or(1, |c| c.inputs_generation + inputs_changed as u64);
            slots.cache = Some(OccupancyCache {
                inputs,
                classification: scene.classification,
                occupied: None,
                generation,
                inputs_generation,
            });
        }
        let Some(cache) = slots.cache.as_mut() else {
            return Err(crate::gpu::GpuError::Internal(
                "the occupancy cache is empty".into(),
            ));
        };
        let buffer = match &slots.buffers[slot] {
            Some(b) if b.size() >= layout.bytes() => b.clone(),
            _ => {
                let texels = self.texel_lookups();
                let b = Buffer::new(&self.device, occupancy_bits_desc(layout.bricks, texels))?;
                slots.buffers[slot] = Some(b.clone());
                slots.written[slot] = [0, 0];
                b
            }
        };
        // Host writes before the submission that reads them; the other frame slot's buffer,
        // which a frame in flight may read, is untouched.
        let [bits_written, inputs_written] = &mut slots.written[slot];
        if *bits_written != cache.generation {
            if *inputs_written != cache.inputs_generation {
                let words = cache.inputs.words()?;
                buffer.write(4 * layout.ranges(), bytemuck::cast_slice(&words))?;
                *inputs_written = cache.inputs_generation;
            } else {
                buffer.write(4 * layout.count(), &[0; 4])?;
            }
            let params = bounds_params(&cache.inputs, &cache.classification);
            let grid = cache.inputs.ranges.grid;
            let (occupied, timings) = self.run_brick_bounds(&buffer, &params, grid)?;
            cache.occupied = Some(occupied);
            slots.timings = timings;
            *bits_written = cache.generation;
        }
        let occupied = cache.occupied.unwrap_or(1.0);
        Ok((buffer, occupied))
    }
}

/// The classification whose bits the occupancy buffers hold.
pub(super) struct OccupancyCache {
    inputs: BoundsInputs,
    classification: Classification,
    // Known once one slot ran the pass for this generation.
    occupied: Option<f64>,
    // Start at 1 and grow with every change (0: a slot holds nothing yet).
    generation: u64,
    inputs_generation: u64,
}

/// A render target's occupancy buffers, one per frame in flight, and what each holds.
pub(super) struct OccupancySlots {
    buffers: Vec<Option<Arc<Buffer>>>,
    // Per slot: the generation of its bits and of its inputs.
    written: Vec<[u64; 2]>,
    cache: Option<OccupancyCache>,
    /// GPU time of the last brick-bounds pass a frame ran.
    pub(super) timings: Vec<PassTiming>,
}

impl OccupancySlots {
    /// Empty slots for `frames` frames in flight.
    pub(super) fn new(frames: usize) -> Self {
        OccupancySlots {
            buffers: vec![None; frames],
            written: vec![[0, 0]; frames],
            cache: None,
            timings: Vec::new(),
        }
    }
}
