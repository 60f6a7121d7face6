//! What brain extraction decided and why (shared by the GPU path, `engine/brain.rs`, and the f64
//! twin): a head whose brain is masked, a volume already skull-stripped (left alone), or nothing
//! brain-like found.
//!
//! Decisions (measured on the real scans named in ACCURACY.md "Brain extraction"):
//! - From the coarse cells only, so the GPU path reads back no volume: band cells (any voxel of
//!   the cell in the tissue band), brain cells (any voxel of the closed mask, or filled).
//! - A head has much tissue-band signal outside the brain: scalp muscle, skin, marrow.
//!   `outside_fraction >= HEAD_OUTSIDE_FRACTION` says head; a skull-stripped brain has almost
//!   none (its band cells are the brain's). A scalp bridge that the component step cut
//!   (`reference::brain_depth`) also says head: there was scalp to cut off.
//! - A brain is 500 to 3000 cm^3 (adult brains with their CSF are 1100-1900; the bounds leave room
//!   for children, large heads and the coarse cells' clipped faces); outside it the component
//!   found is not a brain (a phantom, an organ, a limb) and nothing is masked.

use super::brain_params::BrainParams;
use std::time::Duration;

/// Band-cell fraction outside the brain above which the volume is a head.
pub const HEAD_OUTSIDE_FRACTION: f64 = 0.25;
/// Band-cell fraction outside the brain at or above which (and below [`HEAD_OUTSIDE_FRACTION`])
/// the component probably ran into the scalp through a bridge, and the chain is run again with
/// the bridge cut (`reference::brain_depth`). Measured with `derive --maps brain` (this machine):
/// the skull-stripped MNI152 template leaves 0 %, chris_t1's mask 47 %, the bridged T2w head's 21 %.
pub const BRIDGE_OUTSIDE_FRACTION: f64 = 0.05;
/// Plausible brain volumes in cm^3 (inclusive).
pub const BRAIN_CM3: (f64, f64) = (500.0, 3000.0);

/// The outcome.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BrainDecision {
    /// A head: tissue is classified only inside the mask.
    Head,
    /// Already skull-stripped: left alone.
    SkullStripped,
    /// No brain-like component (or one of implausible size): left alone.
    NotFound,
    /// Not run: the scan is not a structural MR head (a CT, PET, an angiogram, an EPI series).
    NotAHeadScan,
}

impl BrainDecision {
    /// One line for reports.
    pub fn describe(self) -> &'static str {
        match self {
            BrainDecision::Head => "head: the brain is extracted, the rest is the head layer",
            BrainDecision::SkullStripped => "already skull-stripped: left alone",
            BrainDecision::NotFound => "no brain-like region found: left alone",
            BrainDecision::NotAHeadScan => {
                "not extracted: brain extraction is for structural MR heads (not CT, PET, \
                 angiography or EPI series)"
            }
        }
    }
}

/// Band, sizes, decision and times of one extraction.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BrainReport {
    /// The parameters (band included).
    pub params: BrainParams,
    /// Brain volume from the coarse cells, cm^3.
    pub brain_cm3: f64,
    /// Band cells outside the brain over band cells.
    pub outside_fraction: f64,
    /// The outcome.
    pub decision: BrainDecision,
    /// Whether the component step cut a bridge into the scalp (`reference::brain_depth`).
    pub bridge_cut: bool,
    /// Whether the band's upper end came from the tissue fit inside a first, open-band mask
    /// (bright CSF: `analysis::brain_band_csf`).
    pub band_from_fit: bool,
    /// Host time of the coarse-grid steps, ms.
    pub host_ms: f64,
    /// Wall time of the whole extraction, ms.
    pub total_ms: f64,
}

impl BrainReport {
    /// The one line the commands print: the decision, the brain's volume, the band's share
    /// outside it, the band, and the second try when it ran.
    pub fn summary(&self) -> String {
        if self.decision == BrainDecision::NotAHeadScan {
            return format!("brain: {}", self.decision.describe());
        }
        let cut = if self.bridge_cut {
            "; a bridge into the scalp was cut"
        } else {
            ""
        };
        let fitted = if self.band_from_fit {
            "; the band's upper end from the tissue fit inside a first mask"
        } else {
            ""
        };
        format!(
            "brain: {} ({:.0} cm^3, {:.0} % of the tissue band I_norm {:.3}..{:.3} outside it{fitted}{cut})",
            self.decision.describe(),
            self.brain_cm3,
            100.0 * self.outside_fraction,
            self.params.lo,
            self.params.hi.min(1.0),
        )
    }

    /// Not run: the scan is not a structural MR head.
    pub fn not_a_head_scan() -> Self {
        BrainReport {
            decision: BrainDecision::NotAHeadScan,
            ..BrainReport::not_found(&BrainParams::default(), Duration::ZERO)
        }
    }

    /// No component at all.
    pub fn not_found(params: &BrainParams, elapsed: Duration) -> Self {
        BrainReport {
            params: *params,
            brain_cm3: 0.0,
            outside_fraction: 0.0,
            decision: BrainDecision::NotFound,
            bridge_cut: false,
            band_from_fit: false,
            host_ms: 0.0,
            total_ms: elapsed.as_secs_f64() * 1e3,
        }
    }

    /// The decision from the coarse cells (module decisions). `cell_mm3` is one cell's volume;
    /// `bridge_cut` whether the component step cut a scalp bridge.
    pub fn decide(
        params: &BrainParams,
        cell_mm3: f64,
        cells: DecisionCells<'_>,
        bridge_cut: bool,
        elapsed: Duration,
    ) -> Self {
        let (brain_count, outside_fraction) = cells.counts();
        let brain_cm3 = brain_count as f64 * cell_mm3 / 1000.0;
        let plausible = (BRAIN_CM3.0..=BRAIN_CM3.1).contains(&brain_cm3);
        let decision = if !plausible {
            BrainDecision::NotFound
        } else if bridge_cut || outside_fraction >= HEAD_OUTSIDE_FRACTION {
            BrainDecision::Head
        } else {
            BrainDecision::SkullStripped
        };
        BrainReport {
            params: *params,
            brain_cm3,
            outside_fraction,
            decision,
            bridge_cut,
            band_from_fit: false,
            host_ms: 0.0,
            total_ms: elapsed.as_secs_f64() * 1e3,
        }
    }
}

/// The coarse cells the decision reads (0/1, one per cell).
#[derive(Clone, Copy, Debug)]
pub struct DecisionCells<'a> {
    /// Cells with any voxel in the tissue band.
    pub band: &'a [u8],
    /// Cells with any voxel of the closed mask.
    pub closed: &'a [u8],
    /// Cells the hole filling set.
    pub fill: &'a [u8],
}

impl DecisionCells<'_> {
    /// Brain cells (closed or filled) and the fraction of band cells outside them.
    pub fn counts(&self) -> (usize, f64) {
        let brain = |i: usize| self.closed[i] != 0 || self.fill[i] != 0;
        let n = self.band.len().min(self.closed.len()).min(self.fill.len());
        let brain_count = (0..n).filter(|&i| brain(i)).count();
        let band_count = (0..n).filter(|&i| self.band[i] != 0).count();
        let outside = (0..n).filter(|&i| self.band[i] != 0 && !brain(i)).count();
        let fraction = if band_count == 0 {
            0.0
        } else {
            outside as f64 / band_count as f64
        };
        (brain_count, fraction)
    }

    /// Whether the mask leaves the ambiguous share of the band outside that a bridge into the
    /// scalp does ([`BRIDGE_OUTSIDE_FRACTION`]).
    pub fn bridge_suspected(&self) -> bool {
        let (_, f) = self.counts();
        (BRIDGE_OUTSIDE_FRACTION..HEAD_OUTSIDE_FRACTION).contains(&f)
    }
}
