//! Which bricks a classification can see, and how opaque they can be: the rules of empty-space
//! skipping and their f64 twins.
//!
//! Decisions: the GPU computes each brick's I_norm range once per volume (passes/occupancy.rs);
//! turning ranges into occupancy bits and opacity bounds is the brick-bounds pass
//! (shaders/brick_bounds.comp, run when the windows or the visible tissues change). This file
//! holds its inputs ([`bound_channels`]: the windows as they reach the GPU, supports rounded
//! outward to f32 so the GPU's f32 test decides exactly as the f64 one here) and its twins
//! ([`BrickRanges::reference_bits`], [`BrickRanges::reference_bounds`]); the CPU bits are still
//! what decides a bricked volume's resident bricks ([`BrickRanges::needed_bits`]). A brick is
//! occupied when its range meets the open support `(lo - e, hi + e)` of any visible tissue window
//! with non-zero opacity (outside it the smoothstep weight is exactly 0), widened by 1e-6 so f32
//! rounding of the window bounds on the GPU can never turn a zero weight into a non-zero one:
//! skipping is conservative, hence lossless. The vessel channel is the same test on the
//! ranges of the vesselness volume ([`BrickRanges::vessel_bits`], ORed in by the engine).
//!
//! What a brick must hold to matter depends on the mode, because each mode reads the volume
//! differently ([`BrickRanges::needed_bits`], which decides a bricked volume's resident bricks):
//! DVR sees only values inside a visible tissue window; MIP and MinIP ignore the tissue windows
//! and see every value, and a brick that is not resident reads as 0. So for MIP a brick is
//! needed when its maximum is above 0 and above the display window's black point (below it, 0
//! and the true values both show black); for MinIP when its maximum is above 0 and reaches the
//! MinIP floor (samples below the floor are ignored, and 0 is below any positive floor).

use super::classification::{Classification, MIN_EDGE};
use super::{RenderMode, Scene};

/// Margin that keeps the f64 test conservative against the shader's f32 window bounds.
const MARGIN: f64 = 1e-6;

/// The open interval outside which `window`'s smoothstep weight is exactly 0, widened by
/// [`MARGIN`] and by one entry of the transfer-function table: the table interpolates entries
/// up to 1/4095 away from a sample's value, so with it the weight is 0 only that far outside
/// the window (`transfer_table`); skipping stays lossless with either classification.
fn support(window: &super::Window) -> (f64, f64) {
    let e = window.edge.max(MIN_EDGE) + super::transfer_table::ENTRY_SPACING;
    (window.lo - e - MARGIN, window.hi + e + MARGIN)
}

/// Longer steps where the brick-bounds pass says opacity is low (issue 17 item 2): inside an
/// occupied brick whose opacity bound is below the threshold, one sample stands for up to
/// `factor` lattice samples (never past the brick's exit), composited with the opacity of that
/// length. An approximation (the accuracy study measures it: `morphray accuracy`, ACCURACY.md),
/// so off by default. Integers so [`super::Quality`] stays a hashable pipeline key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct LongSteps {
    /// Lattice samples one long step stands for (1: off).
    pub factor: u32,
    /// Opacity bound per mm below which a brick takes long steps, in units of 1e-4 (so 100 is
    /// 0.01 per mm; 0: off). Labelled bricks (bound >= 1) never qualify.
    pub threshold_e4: u32,
}

impl LongSteps {
    /// No long steps.
    pub const OFF: LongSteps = LongSteps {
        factor: 1,
        threshold_e4: 0,
    };

    /// Whether any brick can take long steps.
    pub fn is_on(&self) -> bool {
        self.factor > 1 && self.threshold_e4 > 0
    }

    /// The threshold per mm, at most 1 (so a labelled brick never qualifies).
    pub fn threshold(&self) -> f64 {
        (f64::from(self.threshold_e4) * 1e-4).min(1.0)
    }
}

impl Default for LongSteps {
    fn default() -> Self {
        LongSteps::OFF
    }
}

/// Slack added to every opacity bound (GPU and twin) so the f32 arithmetic of the pass can never
/// put a bound below the exact one.
pub const BOUND_MARGIN: f64 = 1e-6;

/// One channel of the brick-bounds pass (a tissue window on I_norm or the vessel window on the
/// vesselness), in the f32 values the GPU gets.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundChannel {
    /// Window bounds.
    pub lo: f32,
    /// Window bounds.
    pub hi: f32,
    /// Edge half-width, at least [`MIN_EDGE`].
    pub edge: f32,
    /// Opacity per mm, clamped to [0, 1] as the raymarch's uniforms clamp it.
    pub opacity: f32,
    /// The open support (`support`), rounded outward to f32: for every f32 `x`, `x > lo` and
    /// `x < hi` decide as the f64 comparisons with the unrounded support do.
    pub support: (f32, f32),
}

/// The largest f32 at or below `x`.
fn f32_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) > x { f.next_down() } else { f }
}

/// The smallest f32 at or above `x`.
fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) < x { f.next_up() } else { f }
}

fn bound_channel(window: &super::Window, opacity: f32) -> BoundChannel {
    let (s_lo, s_hi) = support(window);
    BoundChannel {
        lo: window.lo as f32,
        hi: window.hi as f32,
        edge: window.edge.max(MIN_EDGE) as f32,
        opacity: opacity.clamp(0.0, 1.0),
        support: (f32_down(s_lo), f32_up(s_hi)),
    }
}

/// The channels of the brick-bounds pass: the four tissues (None where invisible, without a
/// window or of zero opacity, exactly the tissues [`BrickRanges::occupancy_bits`] counts) and,
/// when `vessels`, the vessel channel (None at zero opacity).
pub fn bound_channels(classification: &Classification, vessels: bool) -> [Option<BoundChannel>; 5] {
    let mut channels = [None; 5];
    for (slot, t) in channels.iter_mut().zip(&classification.tissues) {
        if let (true, true, Some(w)) = (t.visible, t.opacity > 0.0, t.window) {
            *slot = Some(bound_channel(&w, t.opacity));
        }
    }
    let v = &classification.vessels;
    if vessels && v.opacity > 0.0 {
        channels[4] = Some(bound_channel(&v.window, v.opacity));
    }
    channels
}

/// f64 smoothstep(centre - e, centre + e, x), the pass's `edge_step`.
fn edge_step(centre: f64, e: f64, x: f64) -> f64 {
    let t = (((x - centre) + e) / (2.0 * e)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The largest weight `channel`'s window takes over [lo, hi], times its opacity (an upper
/// bound: 1 where the range meets the window, else the nearer edge's smoothstep).
fn channel_bound(channel: &BoundChannel, lo: f64, hi: f64) -> f64 {
    let [w_lo, w_hi, e] = [channel.lo, channel.hi, channel.edge].map(f64::from);
    let weight = if hi < w_lo {
        edge_step(w_lo, e, hi)
    } else if lo > w_hi {
        1.0 - edge_step(w_hi, e, lo)
    } else {
        1.0
    };
    f64::from(channel.opacity) * weight
}

/// Per-brick I_norm ranges of one volume.
#[derive(Clone, Debug, PartialEq)]
pub struct BrickRanges {
    /// Bricks along each axis.
    pub grid: [u32; 3],
    /// Brick side in voxels.
    pub side: u32,
    /// (min, max) per brick, x fastest.
    pub ranges: Vec<(f32, f32)>,
}

impl BrickRanges {
    /// These ranges with every brick not `inside` made empty (min above max): no tissue window
    /// meets an empty range and its opacity bound is 0, so the brick-bounds pass skips it for
    /// the tissues (the brain mask's bricks, `reference::brain_mask::BrainCells`). A length
    /// other than the bricks' changes nothing.
    pub fn only_inside(&self, inside: &[bool]) -> BrickRanges {
        let mut out = self.clone();
        if inside.len() == out.ranges.len() {
            for (r, &keep) in out.ranges.iter_mut().zip(inside) {
                if !keep {
                    *r = (f32::MAX, f32::MIN);
                }
            }
        }
        out
    }

    /// One bit per brick (u32 words, bit b of word b / 32): set where some visible tissue can
    /// have non-zero opacity.
    pub fn occupancy_bits(&self, classification: &Classification) -> Vec<u32> {
        let supports: Vec<(f64, f64)> = classification
            .tissues
            .iter()
            .filter(|t| t.visible && t.opacity > 0.0)
            .filter_map(|t| t.window)
            .map(|w| support(&w))
            .collect();
        self.bits_meeting(&supports)
    }

    /// One bit per brick of these (vesselness) ranges: set where the vessel channel's window
    /// can be non-zero (the same conservative support test as the tissues').
    pub fn vessel_bits(&self, classification: &Classification) -> Vec<u32> {
        let vessels = &classification.vessels;
        let supports = if vessels.opacity > 0.0 {
            vec![support(&vessels.window)]
        } else {
            Vec::new()
        };
        self.bits_meeting(&supports)
    }

    /// Bits of the bricks whose range meets any of the open intervals `supports`.
    fn bits_meeting(&self, supports: &[(f64, f64)]) -> Vec<u32> {
        let mut bits = vec![0u32; self.ranges.len().div_ceil(32).max(1)];
        for (b, &(lo, hi)) in self.ranges.iter().enumerate() {
            let (lo, hi) = (lo as f64, hi as f64);
            if supports.iter().any(|&(s_lo, s_hi)| hi > s_lo && lo < s_hi) {
                bits[b / 32] |= 1 << (b % 32);
            }
        }
        bits
    }

    /// The twin of the brick-bounds pass's bits: [`BrickRanges::occupancy_bits`], ORed with the
    /// vessel channel's bits on `vessels` (the vesselness's ranges, same grid) and with
    /// `labels` (bricks holding a drawn label are never skipped).
    pub fn reference_bits(
        &self,
        classification: &Classification,
        vessels: Option<&BrickRanges>,
        labels: Option<&[u32]>,
    ) -> Vec<u32> {
        let mut bits = self.occupancy_bits(classification);
        if let Some(label_bits) = labels {
            for (word, extra) in bits.iter_mut().zip(label_bits) {
                *word |= extra;
            }
        }
        if let Some(vessel_ranges) = vessels {
            for (word, extra) in bits
                .iter_mut()
                .zip(vessel_ranges.vessel_bits(classification))
            {
                *word |= extra;
            }
        }
        bits
    }

    /// The twin of the brick-bounds pass's bounds: per brick an upper bound of f(v)
    /// (classification.rs) over every sample the brick can hold, `min(1, BOUND_MARGIN + sum of
    /// channel bounds)`, plus 1 where a label is drawn; f64 arithmetic on the f32 channel values.
    pub fn reference_bounds(
        &self,
        classification: &Classification,
        vessels: Option<&BrickRanges>,
        labels: Option<&[u32]>,
    ) -> Vec<f64> {
        let channels = bound_channels(classification, vessels.is_some());
        let range = |r: &(f32, f32)| (f64::from(r.0), f64::from(r.1));
        (0..self.ranges.len())
            .map(|b| {
                let (lo, hi) = range(&self.ranges[b]);
                let mut sum: f64 = channels[..4]
                    .iter()
                    .flatten()
                    .map(|c| channel_bound(c, lo, hi))
                    .sum();
                if let (Some(c), Some(v)) = (&channels[4], vessels) {
                    let (v_lo, v_hi) = v.ranges.get(b).map_or((0.0, 0.0), range);
                    sum += channel_bound(c, v_lo, v_hi);
                }
                let mut bound = (sum + BOUND_MARGIN).min(1.0);
                if labels.is_some_and(|l| l.get(b / 32).is_some_and(|w| w >> (b % 32) & 1 == 1)) {
                    bound += 1.0;
                }
                bound
            })
            .collect()
    }

    /// Fraction of bricks occupied for a classification (for reports).
    pub fn occupied_fraction(&self, classification: &Classification) -> f64 {
        fraction_set(&self.occupancy_bits(classification), self.ranges.len())
    }

    /// One bit per brick: set where the scene's mode can read a value that changes the image
    /// (see the module doc). These are the bricks a bricked volume must hold for `scene`.
    pub fn needed_bits(&self, scene: &Scene) -> Vec<u32> {
        match scene.effects.mode {
            RenderMode::Dvr => self.occupancy_bits(&scene.classification),
            RenderMode::Mip => {
                let black = f64::from(scene.intensity_window[0]) - MARGIN;
                self.bits_where(|hi| hi > 0.0 && hi > black)
            }
            RenderMode::MinIp => {
                let floor = f64::from(scene.minip_floor) - MARGIN;
                self.bits_where(|hi| hi > 0.0 && hi >= floor)
            }
        }
    }

    /// Fraction of bricks [`BrickRanges::needed_bits`] sets (for plans and reports).
    pub fn needed_fraction(&self, scene: &Scene) -> f64 {
        fraction_set(&self.needed_bits(scene), self.ranges.len())
    }

    /// Bits of the bricks whose maximum passes `keep`.
    fn bits_where(&self, keep: impl Fn(f64) -> bool) -> Vec<u32> {
        let mut bits = vec![0u32; self.ranges.len().div_ceil(32).max(1)];
        for (b, &(_, hi)) in self.ranges.iter().enumerate() {
            if keep(f64::from(hi)) {
                bits[b / 32] |= 1 << (b % 32);
            }
        }
        bits
    }
}

/// Set bits over `count` bricks.
fn fraction_set(bits: &[u32], count: usize) -> f64 {
    let set: u32 = bits.iter().map(|w| w.count_ones()).sum();
    set as f64 / count.max(1) as f64
}

/// The f64 twin of the brick-range kernel: (min, max) over each brick plus a 2-voxel halo.
pub fn reference_ranges(norm: &[f64], dims: [u32; 3], side: u32) -> BrickRanges {
    let grid = dims.map(|d| d.div_ceil(side));
    let mut ranges = Vec::with_capacity((grid[0] * grid[1] * grid[2]) as usize);
    let at = |x: u32, y: u32, z: u32| norm[(x + dims[0] * (y + dims[1] * z)) as usize];
    for bz in 0..grid[2] {
        for by in 0..grid[1] {
            for bx in 0..grid[0] {
                let lo = [bx, by, bz].map(|b| (b * side).saturating_sub(2));
                let hi = [bx, by, bz].map(|b| b * side + side + 1);
                let (mut mn, mut mx) = (f64::INFINITY, f64::NEG_INFINITY);
                for z in lo[2]..=hi[2].min(dims[2] - 1) {
                    for y in lo[1]..=hi[1].min(dims[1] - 1) {
                        for x in lo[0]..=hi[0].min(dims[0] - 1) {
                            let v = at(x, y, z).max(0.0);
                            mn = mn.min(v);
                            mx = mx.max(v);
                        }
                    }
                }
                ranges.push((mn as f32, mx as f32));
            }
        }
    }
    BrickRanges { grid, side, ranges }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::Window;

    #[test]
    fn bricks_outside_every_visible_window_are_empty() {
        let ranges = BrickRanges {
            grid: [3, 1, 1],
            side: 8,
            ranges: vec![(0.0, 0.05), (0.2, 0.3), (0.0, 1.0)],
        };
        let mut c = Classification::with_windows([
            Some(Window {
                lo: 0.2,
                hi: 0.4,
                edge: 0.01,
            }),
            None,
            None,
            None,
        ]);
        assert_eq!(ranges.occupancy_bits(&c), vec![0b110]);
        c.show_only(&[]);
        assert_eq!(ranges.occupancy_bits(&c), vec![0]);
    }

    #[test]
    fn the_test_is_conservative_at_the_window_edge() {
        // The support of [0.2, 0.4] with edge 0.01 starts at 0.19, and one table entry
        // (1/4095) below for the classification table: a brick whose maximum is exactly at 0.19
        // has weight 0 everywhere, but counts as occupied within the widening; one whose maximum
        // is below 0.19 - 1/4095 = 0.18976 is empty.
        let ranges = BrickRanges {
            grid: [3, 1, 1],
            side: 8,
            ranges: vec![(0.0, 0.19), (0.0, 0.1898), (0.0, 0.1897)],
        };
        let c = Classification::with_windows([
            Some(Window {
                lo: 0.2,
                hi: 0.4,
                edge: 0.01,
            }),
            None,
            None,
            None,
        ]);
        assert_eq!(ranges.occupancy_bits(&c), vec![0b011]);
    }

    #[test]
    fn mip_and_minip_need_bricks_by_value_not_by_tissue_window() {
        // No tissue window at all (a volume without peaks): DVR needs nothing, MIP and MinIP
        // need every brick that holds a value above 0.
        let ranges = BrickRanges {
            grid: [4, 1, 1],
            side: 8,
            ranges: vec![(0.0, 0.0), (0.0, 0.3), (0.5, 1.0), (0.0, 0.05)],
        };
        let mut scene = Scene::new(Classification::with_windows([None; 4]));
        assert_eq!(ranges.needed_bits(&scene), vec![0]);
        scene.effects.mode = RenderMode::Mip;
        assert_eq!(ranges.needed_bits(&scene), vec![0b1110]);
        // Below the display window's black point a brick shows black either way.
        scene.intensity_window = [0.1, 1.0];
        assert_eq!(ranges.needed_bits(&scene), vec![0b0110]);
        scene.effects.mode = RenderMode::MinIp;
        assert_eq!(ranges.needed_bits(&scene), vec![0b1110]);
        // Samples under the MinIP floor are ignored, so are bricks that never reach it.
        scene.minip_floor = 0.2;
        assert_eq!(ranges.needed_bits(&scene), vec![0b0110]);
        assert_eq!(ranges.needed_fraction(&scene), 0.5);
    }

    #[test]
    fn reference_ranges_include_the_halo() {
        // A single bright voxel at x = 9 lies in brick 1, and in brick 0's halo (bricks 0..8).
        let dims = [24, 1, 1];
        let mut norm = vec![0.0; 24];
        norm[9] = 1.0;
        let r = reference_ranges(&norm, dims, 8);
        assert_eq!(r.ranges, vec![(0.0, 1.0), (0.0, 1.0), (0.0, 0.0)]);
    }
}
