//! A real scan is never blank (issue 28, item 4): when no tissue class was found, the
//! foreground (everything above the background) becomes one window, and the report says so.
//!
//! Decisions:
//! - Only for a histogram with a background (an air-noise mode, or a spike of masked zeros):
//!   every real scan has air around the head or a mask, and its foreground is what the scanner
//!   saw. A volume without one (a ramp, uniform noise) is no scan; it keeps its empty picture
//!   and the empty-image note, which says what to try.
//! - The window starts at the background threshold with the adaptive windows' nominal edge
//!   above it (background voxels get weight 0, so skipping still removes the air), and is open
//!   above (`hi = 1 + edge`), like the brightest tissue window.
//! - It needs at least [`MIN_FOREGROUND_VOXELS`] voxels above the threshold: a handful of bright
//!   voxels is noise, not a picture.
//! - The window takes the WM slot of the adaptive windows (the class every scene shows by
//!   default); the peaks stay missing, so nothing pretends that WM was found.

use super::background::Background;
use super::params::AnalysisParams;
use super::windows::{TissueWindows, Window};
use crate::reference::BINS;

/// Fewest voxels above the background for a foreground window.
pub const MIN_FOREGROUND_VOXELS: u64 = 64;

/// The foreground window and why it is shown.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Fallback {
    /// The window (I_norm), shown in the WM slot.
    pub window: Window,
    /// Voxels at or above the background threshold.
    pub voxels: u64,
    /// One line for people.
    pub reason: String,
}

/// The foreground window of the module doc, or None when tissue windows exist, there is no
/// background, or too little above it.
pub fn foreground(
    hist: &[u32; BINS],
    windows: &TissueWindows,
    bg: &Background,
    background_mode: bool,
    params: &AnalysisParams,
) -> Option<Fallback> {
    if windows.csf.is_some() || windows.gm.is_some() || windows.wm.is_some() {
        return None;
    }
    let has_background = background_mode || !bg.spikes.is_empty();
    if !has_background || bg.threshold_bin == 0 || bg.threshold_bin >= BINS {
        return None;
    }
    let voxels: u64 = hist[bg.threshold_bin..].iter().map(|&c| u64::from(c)).sum();
    if voxels < MIN_FOREGROUND_VOXELS {
        return None;
    }
    let n = BINS as f64;
    let edge = params.edge_bins / n;
    let lo = bg.threshold_bin as f64 / n + edge;
    Some(Fallback {
        window: Window {
            lo,
            hi: 1.0 + edge,
            edge,
        },
        voxels,
        reason: format!(
            "no tissue class could be found in the histogram; showing the foreground (I_norm \
             above {lo:.3}, the background's end: {voxels} voxels) as one class"
        ),
    })
}
