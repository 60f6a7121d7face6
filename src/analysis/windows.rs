//! Tissue windows in `I_norm`: the paper's fixed constants and adaptive ones placed around the
//! detected modes.
//!
//! The renderer classifies with smooth edges:
//! `weight(x) = smoothstep(lo - edge, lo + edge, x) * (1 - smoothstep(hi - edge, hi + edge, x))`
//! ([`Window::weight`] is the reference). Decisions:
//! - Adaptive boundaries between two present tissues sit at the valley of the smoothed histogram
//!   between their modes (the midpoint of the modes when no bin lies between them). Adjacent
//!   windows share the boundary and one `edge`, so their weights sum to exactly 1 across it.
//! - The darkest present tissue starts at the valley after the nearest darker significant mode
//!   (a dark shell, the background mode), and its smooth edge never reaches below the
//!   background threshold (the boundary is at least threshold + edge, when the darkest mode
//!   stays clear of the edge): background voxels get weight exactly 0, so a zero background
//!   (skull-stripped or masked scans) is empty space that skipping removes, not a faint fog.
//! - Windows follow the intensity order of the modes, whichever tissue each is: CSF, GM, WM in
//!   T1, WM, GM, CSF in T2 (see `contrast`).
//! - The brightest present tissue (WM in T1, CSF in T2) ends `wm_upper_sigmas` (3) standard
//!   deviations above its mode, the standard deviation estimated from the right half-width at
//!   half maximum (`sigma = HWHM / sqrt(2 ln 2)`; the bright side of the brightest tissue is free
//!   of partial volume with the others), or at the valley before a brighter significant mode if
//!   that comes first. The pathology/contrast band starts there and is open above.
//! - What the pathology band means depends on the contrast. T1: what is brighter than WM
//!   (gadolinium enhancement, fat, vessels), the paper's meaning. T2: what is brighter than CSF
//!   (fat on fast spin echo, inflow artefacts); T2-bright lesions and oedema lie between GM and
//!   CSF, inside the GM and CSF windows, so in T2 the band is "brighter than every tissue", not
//!   a lesion detector. Keeping one definition (above the brightest tissue) keeps the windows a
//!   partition of unity for both contrasts.
//! - Open-ended windows (WM and pathology in the paper preset; pathology in the adaptive one, or
//!   WM when no pathology band fits above it) have `hi = 1 + edge`, so that `I_norm = 1` gets full weight under the formula above
//!   (with `hi = 1` it would get 0.5).
//! - `edge` of the adaptive windows = `edge_bins` (2 bins, about how well a valley is located),
//!   capped at a quarter of the narrowest window and at the distance from each mode to its
//!   window's boundaries, so that every window reaches full weight and every mode has it; one
//!   edge for all adaptive windows, so shared boundaries stay a partition of unity.
//! - A tissue whose mode is missing gets no window (`None`). The renderer should treat it as
//!   absent: weight 0 and its toggle disabled. Its voxels are not lost: the neighbouring present
//!   windows extend to the boundary with the next present tissue, so they take them in.

use super::assign::Assignment;
use super::params::AnalysisParams;
use super::peaks::{Mode, right_half_maximum, valley_between};
use crate::reference::BINS;

/// Edge half-width of the paper preset: half a histogram bin, i.e. practically the paper's hard
/// thresholds while keeping `smoothstep` well defined (`edge0 < edge1`).
pub const PAPER_EDGE: f64 = 0.5 / BINS as f64;

/// Which path placed the adaptive windows (reported by `peaks` and `render`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum WindowsFrom {
    /// The mixture fitted to the histogram (`tissue_fit`).
    Fit,
    /// The histogram's modes and valleys ([`adaptive`]).
    #[default]
    Modes,
    /// No tissue class: the foreground as one window (`fallback`).
    Fallback,
    /// No window at all.
    None,
}

impl WindowsFrom {
    /// Words for reports.
    pub fn words(self) -> &'static str {
        match self {
            WindowsFrom::Fit => "the fitted tissue mixture",
            WindowsFrom::Modes => {
                "the histogram's modes (no brain mask to fit inside, or the fit inside it was not sound)"
            }
            WindowsFrom::Fallback => "the foreground fallback (no tissue class)",
            WindowsFrom::None => "nothing (no tissue class, no foreground)",
        }
    }
}

/// One classification window in `I_norm`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Window {
    /// Lower boundary (weight 0.5 there).
    pub lo: f64,
    /// Upper boundary (weight 0.5 there); `1 + edge` for a window open above.
    pub hi: f64,
    /// Half-width of the smooth transition at both boundaries.
    pub edge: f64,
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    if e1 <= e0 {
        return if x < e0 { 0.0 } else { 1.0 };
    }
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl Window {
    /// The renderer's classification weight at `x` (a hard step when `edge` is 0).
    pub fn weight(&self, x: f64) -> f64 {
        smoothstep(self.lo - self.edge, self.lo + self.edge, x)
            * (1.0 - smoothstep(self.hi - self.edge, self.hi + self.edge, x))
    }

    /// Whether `x` lies in `[lo, hi]`.
    pub fn contains(&self, x: f64) -> bool {
        (self.lo..=self.hi).contains(&x)
    }
}

/// One window per tissue class plus the pathology/contrast band; `None` = class absent.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TissueWindows {
    /// Cerebrospinal fluid.
    pub csf: Option<Window>,
    /// Grey matter.
    pub gm: Option<Window>,
    /// White matter.
    pub wm: Option<Window>,
    /// Pathology / contrast enhancement: above the brightest tissue (WM in T1, CSF in T2; module
    /// doc).
    pub pathology: Option<Window>,
}

impl TissueWindows {
    /// The paper's fixed "biological radiometric constants": CSF 0.05-0.12, GM 0.12-0.18,
    /// WM > 0.18, pathology/contrast > 0.20 (WM and pathology overlap, as in the paper). These
    /// are T1 windows (CSF darkest, WM brightest): on a T2 volume they select the wrong tissues.
    pub fn paper() -> Self {
        let w = |lo: f64, hi: f64| {
            Some(Window {
                lo,
                hi,
                edge: PAPER_EDGE,
            })
        };
        TissueWindows {
            csf: w(0.05, 0.12),
            gm: w(0.12, 0.18),
            wm: w(0.18, 1.0 + PAPER_EDGE),
            pathology: w(0.20, 1.0 + PAPER_EDGE),
        }
    }

    /// No windows at all (no tissue found).
    pub fn none() -> Self {
        TissueWindows {
            csf: None,
            gm: None,
            wm: None,
            pathology: None,
        }
    }
}

/// Places adaptive windows.
///
/// `modes` are all significant modes (ascending); `first_candidate` is the index of the first
/// non-background one, and `assignment` indexes `modes[first_candidate..]`.
pub fn adaptive(
    s: &[f64; BINS],
    modes: &[Mode],
    first_candidate: usize,
    assignment: &Assignment,
    threshold_bin: usize,
    params: &AnalysisParams,
) -> TissueWindows {
    let global = |i: Option<usize>| i.map(|i| i + first_candidate).filter(|&i| i < modes.len());
    let mut present: Vec<(usize, usize)> = [assignment.csf, assignment.gm, assignment.wm]
        .into_iter()
        .enumerate()
        .filter_map(|(tissue, i)| global(i).map(|i| (tissue, i)))
        .collect();
    // Ascending intensity: CSF, GM, WM in T1 (already so), WM, GM, CSF in T2.
    present.sort_by_key(|&(_, i)| i);
    let (Some(&(_, lowest)), Some(&(_, highest))) = (present.first(), present.last()) else {
        return TissueWindows::none();
    };
    let n = BINS as f64;
    let threshold = threshold_bin as f64 / n;

    // Lower end: valley after the nearest darker significant mode, at least the threshold; and
    // the window's support (lower - edge) starts at the threshold, not below it, so background
    // voxels get weight exactly 0 (no background fog, and background bricks stay empty for
    // skipping), unless that would leave the darkest mode without full weight.
    let below = lowest.checked_sub(1).map(|i| &modes[i]);
    let lower = below
        .and_then(|m| valley_between(s, m.last, modes[lowest].first))
        .map_or(threshold, |v| v / n)
        .max(threshold);
    let nominal_edge = params.edge_bins / n;
    let support_floor = threshold + nominal_edge;
    let lower = if support_floor + nominal_edge <= modes[lowest].norm() {
        lower.max(support_floor)
    } else {
        lower
    };

    // Boundaries between consecutive present tissues.
    let boundaries: Vec<f64> = present
        .windows(2)
        .map(|w| {
            let (a, b) = (&modes[w[0].1], &modes[w[1].1]);
            valley_between(s, a.last, b.first).unwrap_or(0.5 * (a.position + b.position)) / n
        })
        .collect();

    // Upper end of the brightest tissue.
    let top = &modes[highest];
    let spread = right_half_maximum(s, top).map(|h| {
        top.position + params.wm_upper_sigmas * (h - top.position) / (2.0 * 2f64.ln()).sqrt()
    });
    let next_valley = modes
        .get(highest + 1)
        .and_then(|m| valley_between(s, top.last, m.first));
    let upper = match (spread, next_valley) {
        (Some(a), Some(b)) => a.min(b),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => n,
    } / n;
    let upper = upper.min(1.0);

    let mut bounds = Vec::with_capacity(present.len() + 1);
    bounds.push(lower);
    bounds.extend(boundaries);
    bounds.push(upper);
    let pathology = (upper < 1.0).then_some((upper, 1.0));
    let narrowest = bounds
        .windows(2)
        .map(|w| w[1] - w[0])
        .chain(pathology.map(|(lo, hi)| hi - lo))
        .fold(f64::INFINITY, f64::min);
    // Every mode keeps full weight: no transition reaches it.
    let clearance = present
        .iter()
        .enumerate()
        .map(|(k, &(_, i))| (modes[i].norm() - bounds[k]).min(bounds[k + 1] - modes[i].norm()))
        .fold(f64::INFINITY, f64::min);
    let edge = (params.edge_bins / n)
        .min(0.25 * narrowest)
        .min(clearance)
        .max(0.0);

    let mut out = TissueWindows::none();
    for (k, &(tissue, _)) in present.iter().enumerate() {
        // The brightest window is open above when no pathology band fits over it.
        let open = k + 1 == present.len() && pathology.is_none();
        let hi = if open { 1.0 + edge } else { bounds[k + 1] };
        let w = Some(Window {
            lo: bounds[k],
            hi,
            edge,
        });
        match tissue {
            0 => out.csf = w,
            1 => out.gm = w,
            _ => out.wm = w,
        }
    }
    out.pathology = pathology.map(|(lo, _)| Window {
        lo,
        hi: 1.0 + edge,
        edge,
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_preset_holds_the_papers_constants() {
        let p = TissueWindows::paper();
        let lohi = |w: Option<Window>| w.map(|w| (w.lo, w.hi));
        assert_eq!(lohi(p.csf), Some((0.05, 0.12)));
        assert_eq!(lohi(p.gm), Some((0.12, 0.18)));
        assert_eq!(lohi(p.wm), Some((0.18, 1.0 + PAPER_EDGE)));
        assert_eq!(lohi(p.pathology), Some((0.20, 1.0 + PAPER_EDGE)));
        assert_eq!(p.wm.map(|w| w.weight(1.0)), Some(1.0));
    }

    #[test]
    fn weight_is_the_smoothstep_product() {
        let w = Window {
            lo: 0.2,
            hi: 0.4,
            edge: 0.05,
        };
        assert_eq!(w.weight(0.1), 0.0);
        assert_eq!(w.weight(0.2), 0.5);
        assert_eq!(w.weight(0.3), 1.0);
        assert_eq!(w.weight(0.4), 0.5);
        assert_eq!(w.weight(0.5), 0.0);
        let next = Window {
            lo: 0.4,
            hi: 0.6,
            edge: 0.05,
        };
        for x in [0.36, 0.38, 0.4, 0.42, 0.44] {
            assert!((w.weight(x) + next.weight(x) - 1.0).abs() < 1e-12);
        }
        let hard = Window {
            lo: 0.2,
            hi: 0.4,
            edge: 0.0,
        };
        assert_eq!(
            (
                hard.weight(0.19),
                hard.weight(0.2),
                hard.weight(0.39),
                hard.weight(0.4)
            ),
            (0.0, 1.0, 1.0, 0.0)
        );
    }
}
