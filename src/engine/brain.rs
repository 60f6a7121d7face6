//! Brain extraction of a prepared volume (`passes::brain` on the GPU, the coarse-grid host steps
//! of `reference::brain`), the algorithm whose text and f64 twin are `reference::brain`.
//!
//! Decisions:
//! - Three submissions: the GPU work up to the eroded band's coarse cells (and the band's and the
//!   head's foreground's); the host's largest connected component (a few ms on the coarse grid:
//!   one cell is `coarse` voxels on an edge);
//!   the re-growth, closing and the closed mask's cells; the host's hole filling; the final mask.
//!   The host steps read and write the cells in host-visible buffers, so nothing else is copied.
//!   When the mask leaves the share of the band outside that a bridge into the scalp does, the
//!   first two submissions run again from the deep component (`reference::brain_depth`): two
//!   more submissions for such heads only, none for the others.
//! - Whole volumes only: the distance transforms read up to `erode_mm` across brick faces, which
//!   the atlas's 2-voxel halo does not hold, so a bricked volume is a typed refusal.
//! - The decision (head, already stripped, nothing brain-like) comes from the coarse cells
//!   (`reference::brain::decide`), so no volume-sized readback is needed.

use super::Engine;
use super::prepare::{PreparedVolume, VolumeLayout};
use super::readback::read_image;
use crate::gpu::{Access, Buffer, GpuError, GpuResult, Image, PassTiming, Recording};
use crate::passes::brain::{
    BrainGrid, BrainPass, BrainSwitch, PoolMode, StepMode, Tracked, brain_descs, cells_desc,
    working_extent, working_factors,
};
use crate::passes::occupancy::OCCUPANCY_HALO;
use crate::reference::BINS;
use crate::reference::brain_components::{hole_fill_cells, largest_component_selection, slab_axis};
use crate::reference::brain_depth::head_cells;
use crate::reference::brain_mask::BrainCells;
use crate::reference::brain_params::{BrainParams, close_threshold, spacing_mm};
use crate::reference::brain_report::{BrainDecision, BrainReport, DecisionCells};
use crate::reference::histogram::bin_of;
use crate::scene::occupancy::BrickRanges;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

/// The brain mask and how it was decided.
pub struct BrainMask {
    /// R8_UNORM on the working grid, 1 inside the brain; left in `Access::ComputeSampled`. None
    /// when no component was found (the chain stopped before the mask).
    pub image: Option<Arc<Image>>,
    /// Block edge per axis of the working grid the mask is on (voxel `q` of the mask covers the
    /// volume's voxels `q * factors ..`).
    pub factors: [u32; 3],
    /// Whether the raymarch classifies tissues inside the mask (the switch and the decision:
    /// [`BrainMask::use_for`]).
    pub used: bool,
    /// Band, sizes, decision and times.
    pub report: BrainReport,
    /// GPU time of the passes.
    pub gpu_timings: Vec<PassTiming>,
    /// The brain's coarse cells (closed or filled), for empty-space skipping; None without a
    /// mask.
    pub cells: Option<BrainCells>,
    /// The working-grid mask (0 or 1, x fastest) the tissue fit reads instead of `image`, kept
    /// on the host: a bright-CSF head's first, open-band mask, the brain with its CSF
    /// (`brain_extract.rs`). None: the fit reads `image`.
    pub fit_mask: Option<Vec<u8>>,
    /// The volume's brick ranges restricted to the bricks the mask reaches, made on first use
    /// ([`BrainMask::ranges_inside`]).
    skipping: OnceLock<Arc<BrickRanges>>,
}

/// The images and buffers of one extraction.
struct Work {
    grid: BrainGrid,
    mask: Tracked,
    smoothed: Tracked,
    a: Tracked,
    b: Tracked,
    cells: Arc<Buffer>,
    band_cells: Arc<Buffer>,
    head_cells: Arc<Buffer>,
}

/// The closed mask's and the filled cells of one closing round, and its host time.
struct ClosingRound {
    closed: Vec<u8>,
    fill: Vec<u8>,
    host_ms: f64,
}

impl ClosingRound {
    fn cells<'a>(&'a self, band: &'a [u8]) -> DecisionCells<'a> {
        DecisionCells {
            band,
            closed: &self.closed,
            fill: &self.fill,
        }
    }
}

impl BrainMask {
    /// No mask (nothing brain-like, or not a head scan), with the GPU time spent finding out.
    pub(super) fn none(params: &BrainParams, gpu_timings: Vec<PassTiming>) -> Self {
        BrainMask {
            image: None,
            factors: [1, 1, 1],
            used: false,
            report: BrainReport::not_found(params, std::time::Duration::ZERO),
            gpu_timings,
            cells: None,
            fit_mask: None,
            skipping: OnceLock::new(),
        }
    }

    /// `ranges` (the volume's brick ranges) with the bricks the mask cannot reach made empty,
    /// so empty-space skipping skips the head around the brain when the head layer is hidden
    /// (`reference::brain_mask` says why that is exact). The same `Arc` every call, so the
    /// brick-bounds pass reruns only when the classification changes.
    pub fn ranges_inside(&self, ranges: &Arc<BrickRanges>) -> Arc<BrickRanges> {
        let Some(cells) = &self.cells else {
            return ranges.clone();
        };
        self.skipping
            .get_or_init(|| {
                let inside = cells.bricks_inside(ranges.grid, ranges.side, OCCUPANCY_HALO);
                Arc::new(ranges.only_inside(&inside))
            })
            .clone()
    }

    /// The extent in the volume's voxels the mask's texture spans (its dimensions times the
    /// block edges; at least the volume's), for the raymarch's texture coordinates.
    pub fn grid_extent(&self) -> [f32; 3] {
        match &self.image {
            Some(image) => {
                let e = image.extent();
                std::array::from_fn(|a| (e[a] * self.factors[a]) as f32)
            }
            None => [1.0; 3],
        }
    }

    /// Whether `switch` masks with this outcome: `Auto` a head only, `On` any brain found.
    pub fn use_for(&self, switch: BrainSwitch) -> bool {
        self.image.is_some()
            && match switch {
                BrainSwitch::Off => false,
                BrainSwitch::Auto => self.report.decision == BrainDecision::Head,
                BrainSwitch::On => self.report.decision != BrainDecision::NotFound,
            }
    }
}

impl Engine {
    /// Extracts the brain of `prepared` with `params` (module decisions). The caller chooses the
    /// band (`reference::brain::band_for`) from the histogram and the contrast.
    pub fn brain_mask(
        &mut self,
        prepared: &PreparedVolume,
        params: &BrainParams,
    ) -> GpuResult<BrainMask> {
        Ok(self.brain_chain(prepared, params, false)?.0)
    }

    /// [`Engine::brain_mask`], and with `keep_inside` the histogram of the smoothed volume inside
    /// the mask (`brain_extract.rs` chooses a bright-CSF band's upper end from it); None without
    /// a mask.
    pub(super) fn brain_chain(
        &mut self,
        prepared: &PreparedVolume,
        params: &BrainParams,
        keep_inside: bool,
    ) -> GpuResult<(BrainMask, Option<[u32; BINS]>)> {
        let _span = crate::files::trace::span("brain extraction", "prepare");
        if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(GpuError::InvalidRequest(
                "brain extraction needs the whole volume on the GPU; this one is bricked (raise the memory budget, or pass --brain off)".into(),
            ));
        }
        params
            .validate()
            .map_err(|e| GpuError::InvalidRequest(e.to_string()))?;
        let started = Instant::now();
        let device = self.device.clone();
        let pass = self.brain_pass()?;
        let mut work = self.brain_work(prepared, params)?;
        let mut timings = Vec::new();
        let mut host_ms = 0.0;

        // 1. Smooth, band, erode; the eroded band's, the band's and the foreground's cells.
        self.erosion_round(&pass, &mut work, prepared, params, &mut timings)?;
        let coarse = work.grid.coarse.map(|c| c as usize);
        let host = Instant::now();
        let eroded = read_cells(&work.cells)?;
        let band_cells = read_cells(&work.band_cells)?;
        let Some(whole) = largest_component_selection(&eroded, coarse) else {
            let mut none = BrainMask::none(params, timings);
            none.report.total_ms = started.elapsed().as_secs_f64() * 1e3;
            return Ok((none, None));
        };
        host_ms += host.elapsed().as_secs_f64() * 1e3;

        // 2. Core, re-growth, closing, hole filling from the largest component.
        let mut round = self.closing_round(&pass, &mut work, params, &whole, &mut timings)?;
        host_ms += round.host_ms;
        let mut bridge_cut = false;
        if round.cells(&band_cells).bridge_suspected() && params.scalp_mm > 0.0 {
            // 2b. The second try without the head's outer shell (reference::brain_depth).
            let host = Instant::now();
            let cell_mm = work.grid.spacing.map(|h| h * f64::from(work.grid.cell));
            let head = head_cells(&read_cells(&work.head_cells)?, coarse, cell_mm);
            host_ms += host.elapsed().as_secs_f64() * 1e3;
            self.depth_cut_round(&pass, &mut work, params, &head, &mut timings)?;
            let host = Instant::now();
            let cut = largest_component_selection(&read_cells(&work.cells)?, coarse);
            host_ms += host.elapsed().as_secs_f64() * 1e3;
            if let Some(selected) = cut {
                round = self.closing_round(&pass, &mut work, params, &selected, &mut timings)?;
                host_ms += round.host_ms;
                bridge_cut = true;
            }
        }
        let cell_mm3 =
            work.grid.spacing.iter().product::<f64>() * f64::from(work.grid.cell).powi(3);
        let report = BrainReport::decide(
            params,
            cell_mm3,
            round.cells(&band_cells),
            bridge_cut,
            started.elapsed(),
        );

        // 3. The mask.
        // The filled cells written by the host are read by the final step.
        let mut rec = after_host_cells(&device, "brain extraction: mask", &work.cells)?;
        pass.record_step(
            &mut rec,
            &work.grid,
            &self.nearest,
            StepMode::Final,
            close_threshold(params),
            [&work.b, &work.smoothed],
            &work.cells,
            &mut work.mask,
        )?;
        rec.end_pass();
        timings.extend(rec.submit()?.wait()?);
        let mut report = report;
        report.host_ms = host_ms;
        report.total_ms = started.elapsed().as_secs_f64() * 1e3;
        let set = round
            .closed
            .iter()
            .zip(&round.fill)
            .map(|(&c, &f)| c | f)
            .collect();
        let inside = if keep_inside {
            Some(smoothed_inside(&device, &work)?)
        } else {
            None
        };
        let mask = BrainMask {
            image: Some(work.mask.image.clone()),
            factors: work.grid.factors,
            used: false,
            report,
            gpu_timings: timings,
            cells: Some(BrainCells {
                dims: coarse,
                cell: work.grid.cell as usize,
                factors: work.grid.factors,
                set,
            }),
            fit_mask: None,
            skipping: OnceLock::new(),
        };
        Ok((mask, inside))
    }

    /// Submission 1: smoothing, band, erosion and the coarse cells of each.
    fn erosion_round(
        &self,
        pass: &BrainPass,
        work: &mut Work,
        prepared: &PreparedVolume,
        params: &BrainParams,
        timings: &mut Vec<PassTiming>,
    ) -> GpuResult<()> {
        let mut rec = Recording::new(&self.device, "brain extraction: erosion")?;
        rec.begin_pass("brain extraction: erosion");
        self.record_erosion(pass, &mut rec, work, prepared, params)?;
        rec.end_pass();
        timings.extend(rec.submit()?.wait()?);
        Ok(())
    }

    /// The second try's submission: the head's cells (`head`, written by the host) give each
    /// voxel's depth; the smoothed volume loses its outer `scalp_mm`; the band is eroded again
    /// and pooled into the cells. A first try without a component leaves the erosion's
    /// distances where they were.
    fn depth_cut_round(
        &self,
        pass: &BrainPass,
        work: &mut Work,
        params: &BrainParams,
        head: &[u8],
        timings: &mut Vec<PassTiming>,
    ) -> GpuResult<()> {
        write_cells(&work.cells, head)?;
        // The head's cells written by the host are read by the first step.
        let mut rec = after_host_cells(&self.device, "brain extraction: depth cut", &work.cells)?;
        {
            let Work {
                grid,
                smoothed,
                a,
                b,
                cells,
                ..
            } = &mut *work;
            let nearest = &self.nearest;
            let s2 = params.scalp_mm * params.scalp_mm;
            let step = StepMode::HeadSources;
            pass.record_step(&mut rec, grid, nearest, step, 0.0, [b, smoothed], cells, a)?;
            pass.record_distance(&mut rec, grid, nearest, [a, b], params.scalp_mm)?;
            let step = StepMode::DepthCut;
            pass.record_step(&mut rec, grid, nearest, step, s2, [b, smoothed], cells, a)?;
        }
        // The cut volume is the smoothed one from here on; the old one is scratch.
        std::mem::swap(&mut work.smoothed, &mut work.a);
        self.record_eroding(pass, &mut rec, work, params)?;
        rec.end_pass();
        timings.extend(rec.submit()?.wait()?);
        Ok(())
    }

    /// Submission 2 from the host's `selected` cells: core, re-growth, closing and the closed
    /// mask's cells; then the host's hole filling, written back for the final step.
    fn closing_round(
        &self,
        pass: &BrainPass,
        work: &mut Work,
        params: &BrainParams,
        selected: &[u8],
        timings: &mut Vec<PassTiming>,
    ) -> GpuResult<ClosingRound> {
        write_cells(&work.cells, selected)?;
        // The selection written by the host is read by the core step.
        let mut rec = after_host_cells(&self.device, "brain extraction: closing", &work.cells)?;
        self.record_closing(pass, &mut rec, work, params)?;
        rec.end_pass();
        timings.extend(rec.submit()?.wait()?);
        let host = Instant::now();
        let coarse = work.grid.coarse.map(|c| c as usize);
        let closed = read_cells(&work.cells)?;
        let fill = hole_fill_cells(&closed, coarse, slab_axis(work.grid.spacing));
        write_cells(&work.cells, &fill)?;
        Ok(ClosingRound {
            closed,
            fill,
            host_ms: host.elapsed().as_secs_f64() * 1e3,
        })
    }

    fn brain_work(&self, prepared: &PreparedVolume, params: &BrainParams) -> GpuResult<Work> {
        let fine_spacing = spacing_mm(prepared.linear_part);
        let factors = working_factors(fine_spacing);
        let extent = working_extent(prepared.dims, factors);
        let spacing: [f64; 3] = std::array::from_fn(|a| fine_spacing[a] * f64::from(factors[a]));
        let cell = params.coarse as u32;
        let coarse = extent.map(|n| n.div_ceil(cell));
        let cells = (coarse[0] * coarse[1] * coarse[2]) as usize;
        let [mask, smoothed, a, b] = brain_descs(extent).map(|d| Image::new(&self.device, d));
        let grid = BrainGrid {
            fine: prepared.dims,
            factors,
            extent,
            spacing,
            coarse,
            cell,
            band: (params.lo as f32, params.hi as f32),
        };
        Ok(Work {
            grid,
            mask: Tracked::new(mask?),
            smoothed: Tracked::new(smoothed?),
            a: Tracked::new(a?),
            b: Tracked::new(b?),
            cells: Buffer::new(&self.device, cells_desc("brain cells", cells))?,
            band_cells: Buffer::new(&self.device, cells_desc("brain band cells", cells))?,
            head_cells: Buffer::new(&self.device, cells_desc("brain head cells", cells))?,
        })
    }

    fn record_erosion(
        &self,
        pass: &BrainPass,
        rec: &mut Recording,
        work: &mut Work,
        prepared: &PreparedVolume,
        params: &BrainParams,
    ) -> GpuResult<()> {
        // The Gaussian in voxels of the working grid: the linear part's columns scaled by the
        // block edges.
        let mut working_linear = prepared.linear_part;
        for row in &mut working_linear {
            for (a, v) in row.iter_mut().enumerate() {
                *v *= f64::from(work.grid.factors[a]);
            }
        }
        let kernels =
            crate::passes::vesselness::axis_kernels(working_linear, params.sigma_mm as f32);
        let Work {
            grid,
            smoothed,
            a,
            b,
            band_cells,
            head_cells,
            ..
        } = &mut *work;
        let nearest = &self.nearest;
        // Block means into `smoothed`, then the Gaussian from there back into it.
        pass.record_downsample(rec, grid, nearest, &prepared.normalized, smoothed)?;
        let means = smoothed.image.clone();
        pass.record_smooth(rec, grid, nearest, &means, [smoothed, a, b], kernels)?;
        pass.record_pool(
            rec,
            grid,
            nearest,
            PoolMode::Band,
            0.0,
            [smoothed, smoothed],
            band_cells,
        )?;
        pass.record_pool(
            rec,
            grid,
            nearest,
            PoolMode::Foreground,
            params.head_lo,
            [smoothed, smoothed],
            head_cells,
        )?;
        self.record_eroding(pass, rec, work, params)
    }

    /// Band sources, the erosion's distances (left in `b`) and its ALL-pool into the cells.
    fn record_eroding(
        &self,
        pass: &BrainPass,
        rec: &mut Recording,
        work: &mut Work,
        params: &BrainParams,
    ) -> GpuResult<()> {
        let Work {
            grid,
            smoothed,
            a,
            b,
            cells,
            ..
        } = work;
        let nearest = &self.nearest;
        pass.record_step(
            rec,
            grid,
            nearest,
            StepMode::BandSources,
            0.0,
            [smoothed, smoothed],
            cells,
            a,
        )?;
        pass.record_distance(rec, grid, nearest, [a, b], params.erode_mm)?;
        let r2 = params.erode_mm * params.erode_mm;
        pass.record_pool(rec, grid, nearest, PoolMode::All, r2, [b, smoothed], cells)
    }

    fn record_closing(
        &self,
        pass: &BrainPass,
        rec: &mut Recording,
        work: &mut Work,
        params: &BrainParams,
    ) -> GpuResult<()> {
        let Work {
            grid,
            smoothed,
            a,
            b,
            cells,
            ..
        } = work;
        let nearest = &self.nearest;
        let r2 = params.erode_mm * params.erode_mm;
        let rc = params.close_mm;
        // The core (b holds the erosion's distances) -> a; its dilation, inside the band -> a.
        pass.record_step(
            rec,
            grid,
            nearest,
            StepMode::CoreSources,
            r2,
            [b, smoothed],
            cells,
            a,
        )?;
        pass.record_distance(rec, grid, nearest, [a, b], params.erode_mm)?;
        pass.record_step(
            rec,
            grid,
            nearest,
            StepMode::GrownSources,
            r2,
            [b, smoothed],
            cells,
            a,
        )?;
        // Closing: dilate by rc, then erode by rc - grow.
        pass.record_distance(rec, grid, nearest, [a, b], rc)?;
        pass.record_step(
            rec,
            grid,
            nearest,
            StepMode::OutsideSources,
            rc * rc,
            [b, smoothed],
            cells,
            a,
        )?;
        pass.record_distance(rec, grid, nearest, [a, b], rc - params.grow_mm)?;
        let t = close_threshold(params);
        pass.record_pool(rec, grid, nearest, PoolMode::Any, t, [b, smoothed], cells)
    }
}

/// A recording (and its timed pass) named `name` whose first barrier orders the host's writes of
/// `cells` before the shaders' reads.
fn after_host_cells(
    device: &crate::gpu::Device,
    name: &str,
    cells: &Arc<Buffer>,
) -> GpuResult<Recording> {
    let mut rec = Recording::new(device, name)?;
    rec.begin_pass(name);
    // Orders the host's writes of the cells before every later dispatch's reads.
    rec.barriers(
        &[(cells, Access::HostWrite, Access::ComputeReadBuffer)],
        &[],
    );
    Ok(rec)
}

/// The 256-bin histogram of the smoothed volume (I_norm) over the working voxels inside the mask:
/// two working-grid readbacks (4 + 1 bytes a working voxel, an eighth of a 0.9 mm volume's).
fn smoothed_inside(device: &crate::gpu::Device, work: &Work) -> GpuResult<[u32; BINS]> {
    let mask = read_image(device, &work.mask.image, work.mask.state)?.values;
    let smoothed = read_image(device, &work.smoothed.image, work.smoothed.state)?.values;
    let mut bins = [0u32; BINS];
    for (&m, &v) in mask.iter().zip(&smoothed) {
        if m >= 0.5 && v.is_finite() {
            let b = bin_of(v);
            bins[b] = bins[b].saturating_add(1);
        }
    }
    Ok(bins)
}

fn read_cells(buffer: &Arc<Buffer>) -> GpuResult<Vec<u8>> {
    let mut bytes = vec![0u8; buffer.size() as usize];
    buffer.read(0, &mut bytes)?;
    Ok(bytes
        .chunks_exact(4)
        .map(|w| u8::from(u32::from_le_bytes([w[0], w[1], w[2], w[3]]) != 0))
        .collect())
}

fn write_cells(buffer: &Arc<Buffer>, flags: &[u8]) -> GpuResult<()> {
    let bytes: Vec<u8> = flags
        .iter()
        .flat_map(|&f| u32::from(f != 0).to_le_bytes())
        .collect();
    buffer.write(0, &bytes)
}
