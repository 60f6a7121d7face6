//! Modes (local maxima) of the smoothed histogram, their prominence and significance, and the
//! valleys between them.
//!
//! Decisions:
//! - Positions are continuous bin coordinates: bin `b` covers `[b, b + 1)`, its centre is
//!   `b + 0.5`, and `I_norm = position / 256`.
//! - Plateaus: runs of equal values (relative tolerance 1e-12, so bit-level summation noise does
//!   not split a flat top) are one mode or one valley, located at the run's centre.
//! - A single-bin top is refined by the vertex of the parabola through it and its two
//!   neighbours, clamped to its own bin (`±0.5`); a top at bin 0 or 255 is not refined.
//! - Prominence is the topographic one (as in `scipy.signal.peak_prominences`): walk each way
//!   until a strictly higher bin or the end, take the lowest bin passed on each side, and
//!   subtract the higher of the two bases from the height. A side that does not exist (a mode
//!   touching bin 0 or 255) is ignored; a histogram that is flat everywhere has prominence 0.
//! - Significance ([`is_significant`]): the prominence must exceed both `noise_z` Poisson
//!   standard deviations of the smoothed counts at the top and at the base, and
//!   `min_relative_prominence` of the height. The first rejects noise wiggles whatever the voxel
//!   count, the second rejects bumps that are statistically real but negligible (partial-volume
//!   ripples on a large mode).
//! - Shoulders ([`find_shoulders`]) are the fallback for a tissue that is not a local maximum
//!   (GM and WM merged by a bias field, CSF on GM's rising flank): a flank of the histogram
//!   whose slope flattens to at most `shoulder_max_slope_ratio` of its steeper stretches on both
//!   sides, the dip being `noise_z` standard deviations of the slope's Poisson noise. They are
//!   searched on a wider smoothing (`shoulder_sigma_bins`), because a slope is noisier than a
//!   count, and reported as modes at the flattest bin with prominence 0 (a shoulder has no
//!   topographic prominence), so a real mode always wins over one in the assignment.

use super::params::AnalysisParams;
use crate::reference::BINS;

/// A local maximum of the smoothed histogram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mode {
    /// First bin of the top (plateau).
    pub first: usize,
    /// Last bin of the top (plateau); equal to `first` for a single-bin top.
    pub last: usize,
    /// Refined location in bins (see the module doc).
    pub position: f64,
    /// Smoothed count at the top.
    pub height: f64,
    /// Topographic prominence, in smoothed counts.
    pub prominence: f64,
}

impl Mode {
    /// Location in `I_norm`.
    pub fn norm(&self) -> f64 {
        self.position / BINS as f64
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
}

/// Runs of equal values: `(first, last, value)`.
fn runs(s: &[f64; BINS]) -> Vec<(usize, usize, f64)> {
    let mut out: Vec<(usize, usize, f64)> = Vec::new();
    for (b, &v) in s.iter().enumerate() {
        match out.last_mut() {
            Some(run) if close(run.2, v) => run.1 = b,
            _ => out.push((b, b, v)),
        }
    }
    out
}

/// Vertex offset of the parabola through `(b-1, b, b+1)`, clamped to `±0.5`; 0 at the ends.
fn vertex_offset(s: &[f64; BINS], b: usize) -> f64 {
    if b == 0 || b + 1 >= BINS {
        return 0.0;
    }
    let (l, c, r) = (s[b - 1], s[b], s[b + 1]);
    let denom = l - 2.0 * c + r;
    if denom == 0.0 || !denom.is_finite() {
        return 0.0;
    }
    (0.5 * (l - r) / denom).clamp(-0.5, 0.5)
}

/// Every local maximum with a positive height, ascending, with its prominence.
pub fn find_modes(s: &[f64; BINS]) -> Vec<Mode> {
    let runs = runs(s);
    let mut modes = Vec::new();
    for (r, &(first, last, height)) in runs.iter().enumerate() {
        let higher_than = |n: Option<&(usize, usize, f64)>| n.is_none_or(|n| n.2 < height);
        if height <= 0.0
            || !higher_than(r.checked_sub(1).and_then(|i| runs.get(i)))
            || !higher_than(runs.get(r + 1))
        {
            continue;
        }
        let stops = |run: &&(usize, usize, f64)| run.2 > height && !close(run.2, height);
        let base = |side: &mut dyn Iterator<Item = &(usize, usize, f64)>| {
            side.take_while(|run| !stops(run))
                .map(|run| run.2)
                .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.min(v))))
        };
        let left = base(&mut runs[..r].iter().rev());
        let right = base(&mut runs[r + 1..].iter());
        let prominence = match (left, right) {
            (None, None) => 0.0,
            (Some(a), None) | (None, Some(a)) => height - a,
            (Some(a), Some(b)) => height - a.max(b),
        };
        let position = if first == last {
            first as f64 + 0.5 + vertex_offset(s, first)
        } else {
            (first + last) as f64 / 2.0 + 0.5
        };
        modes.push(Mode {
            first,
            last,
            position,
            height,
            prominence,
        });
    }
    modes
}

/// Whether a mode stands out from noise (see the module doc); `noise_factor` comes from
/// [`super::smoothing::noise_factor`].
pub fn is_significant(mode: &Mode, noise_factor: f64, params: &AnalysisParams) -> bool {
    let base = (mode.height - mode.prominence).max(0.0);
    let noise = (noise_factor * (mode.height + base)).sqrt();
    mode.prominence > 0.0
        && mode.prominence >= params.noise_z * noise
        && mode.prominence >= params.min_relative_prominence * mode.height
}

/// How flat and how significant a flattening must be to be a shoulder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShoulderTest {
    /// Largest slope at the flattening, as a fraction of the steeper stretches on both sides.
    pub max_slope_ratio: f64,
    /// Smallest dip (steeper stretch minus flattening), in Poisson deviations of the slope.
    pub noise_z: f64,
}

/// A shoulder: the mode it is reported as, and how flat it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shoulder {
    /// At the flattest bin, prominence 0.
    pub mode: Mode,
    /// Its slope as a fraction of the steeper stretches on both sides (smaller = clearer).
    pub slope_ratio: f64,
}

/// Shoulders of `wide` (the histogram smoothed with `shoulder_sigma_bins`) at bins above
/// `from` (see the module doc), ascending; `heights` gives each one's height (the analysis'
/// own smoothing), `slope_noise` is [`super::smoothing::slope_noise_factor`] of `wide`'s width.
pub fn find_shoulders(
    wide: &[f64; BINS],
    heights: &[f64; BINS],
    from: usize,
    slope_noise: f64,
    test: ShoulderTest,
) -> Vec<Shoulder> {
    let mut d = [0.0; BINS];
    for b in 1..BINS - 1 {
        d[b] = 0.5 * (wide[b + 1] - wide[b - 1]);
    }
    let lo = from.max(1);
    let mut out = Vec::new();
    for b in lo + 1..BINS - 2 {
        let (l, c, r) = (d[b - 1], d[b], d[b + 1]);
        // The slope is least steep here (a local extremum of d of the flank's own sign).
        let sign = if c > 0.0 && c <= l && c < r {
            1.0
        } else if c < 0.0 && c >= l && c > r {
            -1.0
        } else {
            continue;
        };
        let steepest = |bins: &mut dyn Iterator<Item = usize>| {
            bins.take_while(|&i| sign * d[i] > 0.0)
                .map(|i| sign * d[i])
                .fold(0.0, f64::max)
        };
        let steeper = steepest(&mut (lo..b).rev()).min(steepest(&mut (b + 1..BINS - 1)));
        let flat = sign * c;
        // The dip is a difference of two noisy slopes: sqrt(2) of one's deviation.
        let noise = (2.0 * slope_noise * wide[b].max(1.0)).sqrt();
        if flat <= test.max_slope_ratio * steeper && steeper - flat >= test.noise_z * noise {
            out.push(Shoulder {
                mode: Mode {
                    first: b,
                    last: b,
                    position: b as f64 + 0.5,
                    height: heights[b],
                    prominence: 0.0,
                },
                slope_ratio: flat / steeper,
            });
        }
    }
    out
}

/// Location (bins) of the lowest point strictly between bins `after` and `before`: the centre of
/// the span of equal minima, or a parabola-refined single minimum. `None` when no bin lies
/// between them.
pub fn valley_between(s: &[f64; BINS], after: usize, before: usize) -> Option<f64> {
    let lo = after.checked_add(1)?;
    let hi = before.checked_sub(1)?.min(BINS - 1);
    if lo > hi {
        return None;
    }
    let min = (lo..=hi).map(|b| s[b]).fold(f64::INFINITY, f64::min);
    let at_min: Vec<usize> = (lo..=hi).filter(|&b| close(s[b], min)).collect();
    let (first, last) = (*at_min.first()?, *at_min.last()?);
    Some(if first == last {
        first as f64 + 0.5 + vertex_offset(s, first)
    } else {
        (first + last) as f64 / 2.0 + 0.5
    })
}

/// Position (bins, continuous) where `s` first falls below half of `s[top]` going right from
/// the mode, linearly interpolated; `None` if it never does.
pub fn right_half_maximum(s: &[f64; BINS], mode: &Mode) -> Option<f64> {
    let half = 0.5 * mode.height;
    (mode.last + 1..BINS).find(|&b| s[b] < half).map(|b| {
        // s[b - 1] >= half > s[b]: interpolate between the two bin centres.
        let (a, c) = (s[b - 1], s[b]);
        let t = if a > c { (a - half) / (a - c) } else { 0.0 };
        b as f64 - 0.5 + t
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hist(points: &[(usize, f64)]) -> [f64; BINS] {
        let mut h = [0.0; BINS];
        for &(b, v) in points {
            h[b] = v;
        }
        h
    }

    #[test]
    fn prominence_is_topographic() {
        // Two peaks: 10 at bin 5, 6 at bin 9, valley 2 between them, 0 elsewhere.
        let h = hist(&[
            (4, 4.0),
            (5, 10.0),
            (6, 4.0),
            (7, 2.0),
            (8, 3.0),
            (9, 6.0),
            (10, 3.0),
        ]);
        let m = find_modes(&h);
        assert_eq!(m.len(), 2);
        assert_eq!((m[0].first, m[0].height, m[0].prominence), (5, 10.0, 10.0));
        assert_eq!((m[1].first, m[1].height, m[1].prominence), (9, 6.0, 4.0));
        // Symmetric neighbours: the parabola vertex is the bin centre.
        assert_eq!(m[0].position, 5.5);
        assert_eq!(
            valley_between(&h, m[0].last, m[1].first).map(|v| v.floor()),
            Some(7.0)
        );
    }

    #[test]
    fn parabola_refines_within_the_bin() {
        let h = hist(&[(19, 8.0), (20, 10.0), (21, 9.0)]);
        let m = find_modes(&h);
        // Vertex of the parabola through (19, 8), (20, 10), (21, 9): 20 + 1/6.
        assert!((m[0].position - (20.5 + 1.0 / 6.0)).abs() < 1e-12, "{m:?}");
    }

    #[test]
    fn plateau_tops_report_their_centre_and_edges_count() {
        let mut h = [0.0; BINS];
        h[0] = 5.0; // mode touching bin 0: only its right side counts
        h[10..=13].fill(3.0);
        let m = find_modes(&h);
        assert_eq!(m.len(), 2);
        assert_eq!((m[0].position, m[0].prominence), (0.5, 5.0));
        assert_eq!((m[1].first, m[1].last, m[1].position), (10, 13, 12.0));
        assert!(find_modes(&[2.0; BINS])[0].prominence == 0.0);
        assert!(find_modes(&[0.0; BINS]).is_empty());
    }

    #[test]
    fn significance_needs_both_noise_and_relative_margin() {
        let p = AnalysisParams::default();
        let mode = |height: f64, prominence: f64| Mode {
            first: 0,
            last: 0,
            position: 0.5,
            height,
            prominence,
        };
        // Poisson: prominence 100 on a 10000 count top is 0.7 sigma at nf 0.28.
        assert!(!is_significant(&mode(10_000.0, 100.0), 0.28, &p));
        assert!(is_significant(&mode(10_000.0, 2_000.0), 0.28, &p));
        // Relative: 40 counts on 1e6 is many sigma of noise but only 0.004 % of the height.
        assert!(!is_significant(&mode(1e9, 4e4), 1e-9, &p));
        assert!(!is_significant(&mode(5.0, 0.0), 0.28, &p));
    }

    #[test]
    fn a_flattening_flank_is_a_shoulder_and_a_single_bell_has_none() {
        let p = AnalysisParams::default();
        let bell = |x: f64, mu: f64, sd: f64| (-0.5 * ((x - mu) / sd).powi(2)).exp();
        let mut merged = [0.0; BINS];
        let mut single = [0.0; BINS];
        for (b, (m, s)) in merged.iter_mut().zip(single.iter_mut()).enumerate() {
            let x = b as f64 + 0.5;
            *m = 1e5 * bell(x, 150.0, 12.0) + 0.5e5 * bell(x, 178.0, 10.0);
            *s = 1e5 * bell(x, 150.0, 15.0);
        }
        let test = ShoulderTest {
            max_slope_ratio: p.shoulder_max_slope_ratio,
            noise_z: p.noise_z,
        };
        let found = find_shoulders(&merged, &merged, 0, 0.005, test);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(
            (165.0..178.0).contains(&found[0].mode.position),
            "{found:?}"
        );
        assert_eq!(found[0].mode.prominence, 0.0);
        assert!(found[0].slope_ratio < 0.2, "{found:?}");
        assert!(
            find_modes(&merged).len() == 1,
            "merged into one local maximum"
        );
        assert!(find_shoulders(&single, &single, 0, 0.005, test).is_empty());
        assert!(find_shoulders(&[0.0; BINS], &[0.0; BINS], 0, 0.005, test).is_empty());
    }

    #[test]
    fn half_maximum_is_interpolated() {
        let h = hist(&[(50, 10.0), (51, 8.0), (52, 4.0)]);
        let m = find_modes(&h)[0];
        // Crosses 5 between bin centres 51.5 (8) and 52.5 (4): at 51.5 + 3/4.
        assert_eq!(right_half_maximum(&h, &m), Some(52.25));
    }
}
