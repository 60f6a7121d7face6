//! The tissue band's upper end for contrasts whose CSF is bright (T2, PD): the second of brain
//! extraction's two bands (`engine/brain_extract.rs` runs the chain twice for them).
//!
//! Why: `brain_band::band_for` leaves a T2 band open above, because CSF is the brightest tissue
//! and belongs to the brain. But a T2's (and a PD's) scalp fat and the eyes' vitreous are just as
//! bright, so the band runs from the brain through the outer CSF into the scalp and the orbits
//! with nothing dark between them: on the clinical T2w head of ACCURACY.md the mask was 1953 cm^3
//! with the vertex scalp and the orbits inside it, and on the T2 head phantom its Dice against
//! the truth was 0.80 (the PD phantom's 3439 cm^3 "brain" was refused as implausible).
//!
//! Decisions:
//! - The upper end comes from the tissue mixture fitted (`tissue_fit::fit_tissues`, the analysis's
//!   own EM) to the histogram of the smoothed volume inside the first, open-band mask: GM and
//!   CSF are its two brighter classes, and the end is halfway between their means. That mask
//!   holds some scalp, but mostly brain, so the fit's classes are the brain's; and the cut is
//!   made on the very values the band tests (the smoothed ones), not on the raw ones.
//! - Halfway, not at GM's upper flank: the smoothing blurs sulcal CSF into GM, and the partial
//!   volume of a gyrus's crown sits between; the closing and the hole filling give back the
//!   CSF the band leaves out (ventricles, sulci), the outer CSF layer stays outside, so the
//!   mask is the brain's surface. Measured: the T2w head 1329 cm^3 at the midpoint (0.367 of
//!   I_norm), 1416 at 0.4, 1860 at 0.5 (a scipy prototype of the same chain, this machine).
//! - No second band (None) when the fit is not sound, when a class holds less than
//!   [`MIN_CLASS_WEIGHT`] (the EM took a scalp or partial-volume class for a tissue), when its
//!   CSF is not above its GM by at least [`MIN_SEPARATION`], or when the end would not be below
//!   the first band's: then the first mask stands.

use super::contrast::Contrast;
use super::tissue_fit::{self, FitDomain};
use crate::reference::BINS;

/// Least distance in I_norm between the fitted GM and CSF means for a second band (4 bins).
pub const MIN_SEPARATION: f64 = 4.0 / BINS as f64;

/// Least weight of each pure class of the fit inside the first mask: WM, GM and CSF are each a
/// good share of a brain with its CSF (the clinical T2w head: 0.44, 0.30, 0.15). Below it the
/// fit labelled something else: on the PD head phantom, whose fat is as bright as its GM, the
/// "WM" class held 0.05 (bone and muscle at 0.29) and the second band cut the brain to 673
/// cm^3; on a synthetic T2 head with a 15 mm scalp of fat, "GM" held 0.07 (the real GM went
/// into a partial-volume class).
pub const MIN_CLASS_WEIGHT: f64 = 0.07;

/// Where between the GM and CSF means the band ends (0 = GM's mean, 1 = CSF's).
pub const CSF_CUT: f64 = 0.5;

/// The second band's upper end in I_norm from `inside`, the histogram of the smoothed volume
/// inside the first mask, for a band `lo..hi` (module doc); None when the first band stands.
pub fn bright_csf_upper(
    inside: &[u32; BINS],
    (lo, hi): (f64, f64),
    contrast: Contrast,
) -> Option<f64> {
    if !matches!(contrast, Contrast::T2 | Contrast::Pd) {
        return None;
    }
    let h = inside.map(f64::from);
    // The fit starts at the band's lower end: what lies below is outside the band, in the mask
    // only through the closing (partial volume at the brain's edge).
    let from = ((lo * BINS as f64).floor() as usize).clamp(1, BINS - 1);
    let range = tissue_fit::occupied_range(&h, from);
    let (fit, mixture) =
        tissue_fit::fit_tissues(&h, range, contrast, FitDomain::BrainMask, (0.0, 1.0))?;
    if !fit.sound || mixture.weights[..3].iter().any(|&w| w < MIN_CLASS_WEIGHT) {
        return None;
    }
    // Ascending means: WM, GM, CSF for T2 and PD.
    let [_, gm, csf] = mixture.means;
    if csf - gm < MIN_SEPARATION {
        return None;
    }
    let upper = gm + CSF_CUT * (csf - gm);
    (upper > lo && upper < hi).then_some(upper)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gaussian classes `(mean I_norm, sd I_norm, voxels)` binned into 256 bins.
    fn classes(parts: &[(f64, f64, f64)]) -> [u32; BINS] {
        std::array::from_fn(|b| {
            let x = (b as f64 + 0.5) / BINS as f64;
            parts
                .iter()
                .map(|&(m, sd, n)| {
                    let z = (x - m) / sd;
                    n / BINS as f64 / (sd * (2.0 * std::f64::consts::PI).sqrt())
                        * (-0.5 * z * z).exp()
                })
                .sum::<f64>()
                .round() as u32
        })
    }

    #[test]
    fn a_t2_band_ends_halfway_between_gm_and_csf() {
        // WM 0.2, GM 0.28, CSF 0.46 (the clinical T2w head's fit inside its first mask).
        let h = classes(&[
            (0.2, 0.03, 400_000.0),
            (0.28, 0.05, 300_000.0),
            (0.46, 0.1, 150_000.0),
        ]);
        let upper = bright_csf_upper(&h, (0.12, 2.0), Contrast::T2).expect("a second band");
        assert!((upper - 0.37).abs() < 0.03, "{upper}");
        // PD takes the same rule; T1 and FLAIR (CSF dark) and CT never do.
        assert!(bright_csf_upper(&h, (0.12, 2.0), Contrast::Pd).is_some());
        for c in [Contrast::T1, Contrast::Flair, Contrast::Ct] {
            assert_eq!(bright_csf_upper(&h, (0.12, 2.0), c), None);
        }
    }

    #[test]
    fn no_second_band_without_a_csf_class_or_below_the_first() {
        // An empty histogram: nothing to fit.
        assert_eq!(bright_csf_upper(&[0; BINS], (0.1, 2.0), Contrast::T2), None);
        // The end would lie above the first band's.
        let h = classes(&[
            (0.2, 0.03, 400_000.0),
            (0.28, 0.05, 300_000.0),
            (0.46, 0.1, 150_000.0),
        ]);
        assert_eq!(bright_csf_upper(&h, (0.12, 0.3), Contrast::T2), None);
        // A class the fit can only fill with a few voxels: not three tissues.
        let thin = classes(&[
            (0.2, 0.03, 500_000.0),
            (0.28, 0.05, 450_000.0),
            (0.46, 0.1, 30_000.0),
        ]);
        assert_eq!(bright_csf_upper(&thin, (0.12, 2.0), Contrast::T2), None);
    }
}
