//! Tissue windows from a fitted mixture (`tissue_fit`): the same kind of windows as
//! `windows::adaptive` (shared boundaries, one edge, the pathology band above the brightest
//! tissue), placed from the fitted means and spreads instead of the histogram's valleys.
//!
//! Decisions:
//! - The boundary between two neighbouring pure classes is where their weighted densities
//!   cross (`w_a N_a(x) = w_b N_b(x)`, the Bayes boundary of the two), searched between the two
//!   means; the midpoint when they do not cross there.
//! - The darkest class starts `sigmas` standard deviations below its mean, never below the
//!   background threshold plus the nominal edge (background voxels get weight 0, as with the
//!   mode windows).
//! - The brightest class ends `sigmas` standard deviations above its mean; above that is the
//!   pathology band (T1: a post-contrast scan's enhancement above WM; FLAIR: bright lesions
//!   above GM). The tail class of the fit is what lives there, so enhancement never takes a
//!   tissue's place.

use super::tissue_fit::tissue_order;
use super::windows::{TissueWindows, Window};
use crate::analysis::contrast::Contrast;
use crate::reference::BINS;
use crate::reference::tissue_fit::{Mixture, PURE};

fn log_density(x: f64, w: f64, mean: f64, sd: f64) -> f64 {
    let z = (x - mean) / sd;
    w.max(1e-300).ln() - sd.ln() - 0.5 * z * z
}

/// Where the weighted densities of classes `a < b` cross between their means.
fn crossing(m: &Mixture, a: usize, b: usize) -> f64 {
    let f = |x: f64| {
        log_density(x, m.weights[a], m.means[a], m.sds[a])
            - log_density(x, m.weights[b], m.means[b], m.sds[b])
    };
    let (mut lo, mut hi) = (m.means[a], m.means[b]);
    if !(f(lo) > 0.0 && f(hi) < 0.0) {
        return 0.5 * (lo + hi);
    }
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if f(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Windows of a sound mixture (ascending pure classes) under `contrast`; `threshold` is the
/// background threshold (I_norm), `edge_bins` the nominal edge, `sigmas` the outer extent.
pub fn from_fit(
    m: &Mixture,
    contrast: Contrast,
    threshold: f64,
    edge_bins: f64,
    sigmas: f64,
) -> TissueWindows {
    let n = BINS as f64;
    let nominal = edge_bins / n;
    let lower = (m.means[0] - sigmas * m.sds[0]).max(threshold + nominal);
    let upper = (m.means[PURE - 1] + sigmas * m.sds[PURE - 1]).min(1.0);
    let mut bounds = vec![lower.min(m.means[0])];
    bounds.extend((0..PURE - 1).map(|k| crossing(m, k, k + 1)));
    bounds.push(upper.max(m.means[PURE - 1]));
    let pathology = (upper < 1.0).then_some(upper);
    let narrowest = bounds
        .windows(2)
        .map(|w| w[1] - w[0])
        .chain(pathology.map(|lo| 1.0 - lo))
        .fold(f64::INFINITY, f64::min);
    let clearance = (0..PURE)
        .map(|k| (m.means[k] - bounds[k]).min(bounds[k + 1] - m.means[k]))
        .fold(f64::INFINITY, f64::min);
    let edge = nominal.min(0.25 * narrowest).min(clearance).max(0.0);
    let order = tissue_order(contrast);
    let mut out = TissueWindows::none();
    for k in 0..PURE {
        let open = k + 1 == PURE && pathology.is_none();
        let w = Some(Window {
            lo: bounds[k],
            hi: if open { 1.0 + edge } else { bounds[k + 1] },
            edge,
        });
        match order[k] {
            0 => out.csf = w,
            1 => out.gm = w,
            _ => out.wm = w,
        }
    }
    out.pathology = pathology.map(|lo| Window {
        lo,
        hi: 1.0 + edge,
        edge,
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::tissue_fit::CLASSES;

    fn mixture(means: [f64; 3], sds: [f64; 3], w: [f64; 3]) -> Mixture {
        let mut weights = [0.0; CLASSES];
        weights[..3].copy_from_slice(&w);
        Mixture {
            means,
            sds,
            weights,
            goodness: 1.0,
            log_likelihood: 0.0,
            iterations: 1,
            voxels: 1.0,
        }
    }

    #[test]
    fn equal_classes_split_halfway_and_the_band_starts_three_sds_above_the_top() {
        let m = mixture([0.2, 0.4, 0.6], [0.03; 3], [1.0 / 3.0; 3]);
        let w = from_fit(&m, Contrast::T1, 0.01, 2.0, 3.0);
        let (csf, gm, wm) = (w.csf.unwrap(), w.gm.unwrap(), w.wm.unwrap());
        assert!((csf.hi - 0.3).abs() < 1e-9 && (gm.lo - 0.3).abs() < 1e-9);
        assert!((gm.hi - 0.5).abs() < 1e-9 && (wm.lo - 0.5).abs() < 1e-9);
        assert!((csf.lo - 0.11).abs() < 1e-9, "{csf:?}");
        let band = w.pathology.expect("a band");
        assert!((band.lo - 0.69).abs() < 1e-9, "{band:?}");
        // Every fitted mean keeps full weight.
        assert_eq!(csf.weight(0.2), 1.0);
        assert_eq!(wm.weight(0.6), 1.0);
    }

    #[test]
    fn t2_puts_wm_lowest_and_flair_puts_gm_highest() {
        let m = mixture([0.2, 0.4, 0.6], [0.03; 3], [0.4, 0.4, 0.2]);
        let t2 = from_fit(&m, Contrast::T2, 0.0, 2.0, 3.0);
        assert!(t2.wm.unwrap().hi <= t2.gm.unwrap().lo + 1e-12);
        assert!(t2.gm.unwrap().hi <= t2.csf.unwrap().lo + 1e-12);
        let flair = from_fit(&m, Contrast::Flair, 0.0, 2.0, 3.0);
        assert!(flair.csf.unwrap().hi <= flair.wm.unwrap().lo + 1e-12);
        assert!(flair.wm.unwrap().hi <= flair.gm.unwrap().lo + 1e-12);
    }

    #[test]
    fn a_heavier_class_pushes_the_boundary_towards_the_lighter_one() {
        let m = mixture([0.2, 0.4, 0.6], [0.05; 3], [0.1, 0.6, 0.3]);
        let w = from_fit(&m, Contrast::T1, 0.0, 2.0, 3.0);
        assert!(w.csf.unwrap().hi < 0.3, "{w:?}");
    }
}
