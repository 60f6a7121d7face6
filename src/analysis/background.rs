//! Background: what lies below the tissue, and the threshold that separates it.
//!
//! Two kinds of background occur, often together:
//! - spikes (see `spikes`): masked or padded voxels, for example the 6.8 M exact zeros of the
//!   skull-stripped MNI152 template, whose brain tissue starts right above them;
//! - background modes: the air-noise mode near 0 of an unmasked scan, and any further dark mode
//!   before the tissue (for example a dark skull shell), as long as it is darker than
//!   `background_max_ratio` (0.12) times the brightest major mode (the WM candidate). The ratio
//!   is taken from `I_norm = 0`, because no zero reference is known yet at this point.
//!
//! Decisions:
//! - Background modes are taken from the dark end only, one at a time, and at least one mode
//!   always remains: a histogram with a single mode has no brighter reference and no background
//!   mode. So a noise-only volume keeps its one mode (reported unassigned, see `assign`).
//! - The threshold is a bin edge `t`: a voxel is "used" when its bin is `>= t`. With background
//!   modes, `t` is the bin holding the valley after the last of them (the valley's own bin
//!   counts as used); with background spikes, `t` is at least one past the highest spike that
//!   lies below the first tissue mode. With neither, `t = 0` and every finite voxel is used.
//! - The intensity "zero" that tissue ratios are measured from is the darkest background mode
//!   (air signal is the physical zero of a magnitude image), else the lowest background spike,
//!   else `I_norm = 0`.

use super::params::AnalysisParams;
use super::peaks::{Mode, valley_between};
use crate::reference::BINS;

/// Where the background ends.
#[derive(Clone, Debug, PartialEq)]
pub struct Background {
    /// Number of leading (darkest) modes that are background.
    pub modes: usize,
    /// Spikes below the first tissue mode (all spikes when there is none).
    pub spikes: Vec<usize>,
    /// First used bin (0..=256).
    pub threshold_bin: usize,
    /// Intensity zero for tissue ratios, in bins.
    pub zero: f64,
}

/// The brightest mode among those at least `major_fraction` of the tallest.
pub fn brightest_major(modes: &[Mode], major_fraction: f64) -> Option<&Mode> {
    let tallest = modes.iter().map(|m| m.height).fold(0.0, f64::max);
    modes
        .iter()
        .filter(|m| m.height >= major_fraction * tallest)
        .max_by(|a, b| a.position.total_cmp(&b.position))
}

/// Splits significant `modes` (ascending) into background and tissue candidates.
pub fn find_background(
    s: &[f64; BINS],
    modes: &[Mode],
    spikes: &[usize],
    params: &AnalysisParams,
) -> Background {
    let mut n = 0;
    while n + 1 < modes.len() {
        let Some(reference) = brightest_major(&modes[n + 1..], params.major_fraction) else {
            break;
        };
        if modes[n].position < params.background_max_ratio * reference.position {
            n += 1;
        } else {
            break;
        }
    }
    let first_tissue = modes.get(n).map_or(BINS, |m| m.first);
    let spikes: Vec<usize> = spikes
        .iter()
        .copied()
        .filter(|&b| b < first_tissue)
        .collect();
    let mut threshold = spikes.iter().max().map_or(0, |&b| b + 1);
    if n > 0 {
        let last_bg = &modes[n - 1];
        let end = modes.get(n).map_or(BINS, |m| m.first);
        let valley = valley_between(s, last_bg.last, end);
        // No bin between: the next mode starts right after the background mode.
        let t = valley.map_or(end.min(last_bg.last + 1), |v| v.floor() as usize);
        threshold = threshold.max(t);
    }
    let zero = if n > 0 {
        modes[0].position
    } else {
        spikes.first().map_or(0.0, |&b| b as f64 + 0.5)
    };
    Background {
        modes: n,
        spikes,
        threshold_bin: threshold.min(BINS),
        zero,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(first: usize, last: usize, height: f64) -> Mode {
        Mode {
            first,
            last,
            position: (first + last) as f64 / 2.0 + 0.5,
            height,
            prominence: height,
        }
    }

    #[test]
    fn dark_leading_modes_are_background_and_the_threshold_is_their_valley() {
        let p = AnalysisParams::default();
        let mut s = [0.0; BINS];
        s[12] = 1.0; // a bump inside the valley between the shell (bin 10) and CSF (bin 30)
        let modes = [
            mode(2, 2, 1e5),
            mode(10, 10, 500.0),
            mode(30, 30, 300.0),
            mode(100, 100, 1000.0),
        ];
        let bg = find_background(&s, &modes, &[], &p);
        // 2.5 and 10.5 are below 0.12 * 100.5; 30.5 is not.
        assert_eq!(bg.modes, 2);
        // The minima between bins 10 and 30 are 11 and 13..=29: their span's centre is 20.5.
        assert_eq!(bg.threshold_bin, 20);
        assert_eq!(bg.zero, 2.5);
    }

    #[test]
    fn spikes_below_tissue_set_the_threshold_and_one_mode_always_remains() {
        let p = AnalysisParams::default();
        let s = [0.0; BINS];
        let modes = [mode(60, 60, 100.0), mode(200, 200, 1000.0)];
        let bg = find_background(&s, &modes, &[0, 30, 255], &p);
        assert_eq!(
            (bg.modes, bg.spikes.clone(), bg.threshold_bin, bg.zero),
            (0, vec![0, 30], 31, 0.5)
        );
        let single = [mode(3, 3, 1e5)];
        assert_eq!(find_background(&s, &single, &[], &p).modes, 0);
        let none = find_background(&s, &[], &[0], &p);
        assert_eq!((none.modes, none.threshold_bin), (0, 1));
    }
}
