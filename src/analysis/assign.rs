//! Which tissue modes are CSF, GM and WM, for the contrast `contrast` decided: adult T1 (CSF <
//! GM < WM, [`assign`]), T2 (WM < GM < CSF, [`assign_t2`]), PD (WM < GM < CSF with less
//! contrast: [`assign_t2`]'s rule with CSF from [`PD_CSF_MIN_RATIO`] times WM), FLAIR and CT
//! (CSF < WM < GM: [`assign`]'s rule with GM and WM swapped, since in both the brightest large
//! class is GM, the next one WM at more than half its intensity, and CSF is dark).
//!
//! T1 rules, applied to the significant modes above the background (the candidates):
//! 1. Fewer than two candidates: nothing is assigned. One mode alone has no intensity ratio to
//!    classify it by (it could be any tissue, or noise), and a mode is never guessed.
//! 2. WM is the brightest major candidate (height at least `major_fraction` of the tallest
//!    candidate): GM and WM are the two largest brain classes, while bright tails (vessels, fat,
//!    enhancing lesions) are small.
//! 3. Candidates below WM are classified by their intensity ratio to WM measured from the
//!    background zero, `r = (p - zero) / (wm - zero)`:
//!    - GM: `r >= gm_min_ratio` (0.5); the most prominent such candidate;
//!    - CSF: `csf_min_ratio <= r < gm_min_ratio` (0.12-0.5), below GM when GM exists; the
//!      most prominent such candidate. Partial-volume voxels between CSF and GM form small
//!      bumps on either side of the CSF mode (seen in the phantom at about halfway to GM), and
//!      the CSF mode itself is broad and prominent; dark shells (bone) sit below 0.12.
//!
//!    So with two modes, the one that is missing follows from their ratio: a second mode at
//!    `r >= 0.5` is GM (CSF missing), one at `0.12 <= r < 0.5` is CSF (GM missing, for example
//!    merged into WM), one darker than that is neither.
//! 4. Everything else stays unassigned ("other") and is still reported.
//!
//! T2 rules ([`assign_t2`]), same candidates, fewer than two still assign nothing:
//! 1. WM is the darkest major candidate at least `TISSUE_MIN_RATIO` (0.15) of the brightest
//!    major one's intensity: WM and GM are the two largest classes, and in T2 WM is the darker;
//!    modes below it, however large (bone, muscle, the skull of an unmasked head), are not
//!    tissue.
//! 2. Candidates above WM are classified by their ratio to WM from the background zero, `r =
//!    (p - zero) / (wm - zero)`, split at `T2_CSF_MIN_RATIO` (2.0). T2 GM is 1.2-1.6 times WM,
//!    CSF 2.7-4.7 times (module doc of `contrast`: TE 80-120 ms), so 2.0 separates the two with
//!    room for bias fields and partial volume:
//!    - CSF: the *brightest* candidate with `r >= 2`. Partial-volume bumps between GM and CSF
//!      lie below the CSF mode, so the brightest one is CSF itself (a bright mode above CSF is
//!      rare in T2; it would be taken for CSF);
//!    - GM: the most prominent candidate between WM and CSF that is below `2 WM` or major. A
//!      major mode is a tissue class, never a bump: an inverted T1 (the MNI152 template turned
//!      upside down, in tests/contrast.rs) has GM at 2.4 times WM from the zero, because its
//!      physical zero is at the wrong end.
//!
//! Limits (documented, not solved): FLAIR without metadata and neonatal T1 are read as adult T1
//! (see `contrast`); a bright tail larger than `major_fraction` of the tallest tissue mode would be
//! called WM in T1; when GM and WM merge into one mode it is called WM.

use super::contrast::{Contrast, TISSUE_MIN_RATIO};
use super::params::AnalysisParams;
use super::peaks::Mode;

/// In T2, candidates at least this many times WM's intensity (from zero) are CSF, those between
/// WM and this are GM (module doc).
pub const T2_CSF_MIN_RATIO: f64 = 2.0;

/// In PD, candidates at least this many times WM's intensity (from zero) are CSF. Proton
/// densities WM 0.7, GM 0.8, CSF 1.0 (the `contrast` module's worked example) give GM 1.15 and
/// CSF 1.4 times WM at long TR and short TE; 1.3 lies between, with room for T2 decay of WM.
pub const PD_CSF_MIN_RATIO: f64 = 1.3;

/// Indices (into the candidate slice) of the assigned tissues.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Assignment {
    /// CSF mode.
    pub csf: Option<usize>,
    /// GM mode.
    pub gm: Option<usize>,
    /// WM mode.
    pub wm: Option<usize>,
}

/// Assigns tissues among `candidates` for `contrast`.
pub fn assign_for(
    contrast: Contrast,
    candidates: &[Mode],
    zero: f64,
    params: &AnalysisParams,
) -> Assignment {
    match contrast {
        Contrast::T1 => assign(candidates, zero, params),
        Contrast::T2 => assign_t2(candidates, zero, params),
        Contrast::Pd => assign_dark_wm(candidates, zero, params, PD_CSF_MIN_RATIO),
        Contrast::Flair | Contrast::Ct => {
            // T1's rule finds the brightest large class and the one at more than half of it:
            // here GM and WM.
            let a = assign(candidates, zero, params);
            Assignment {
                gm: a.wm,
                wm: a.gm,
                csf: a.csf,
            }
        }
    }
}

/// The most prominent of `indices`.
fn most_prominent(candidates: &[Mode], indices: impl Iterator<Item = usize>) -> Option<usize> {
    indices.max_by(|&a, &b| {
        candidates[a]
            .prominence
            .total_cmp(&candidates[b].prominence)
    })
}

/// Assigns tissues among `candidates` (ascending) for T2 contrast (module doc).
pub fn assign_t2(candidates: &[Mode], zero: f64, params: &AnalysisParams) -> Assignment {
    assign_dark_wm(candidates, zero, params, T2_CSF_MIN_RATIO)
}

/// The T2 rule (module doc) with CSF from `csf_min_ratio` times WM (2 in T2, 1.3 in PD).
fn assign_dark_wm(
    candidates: &[Mode],
    zero: f64,
    params: &AnalysisParams,
    csf_min_ratio: f64,
) -> Assignment {
    if candidates.len() < 2 {
        return Assignment::default();
    }
    let tallest = candidates.iter().map(|m| m.height).fold(0.0, f64::max);
    let major = |i: &usize| candidates[*i].height >= params.major_fraction * tallest;
    let Some(brightest) = (0..candidates.len()).rev().find(major) else {
        return Assignment::default();
    };
    // Candidates are ascending: the first major tissue mode is the darkest.
    let tissue = |i: &usize| {
        let r = (candidates[*i].position - zero) / (candidates[brightest].position - zero);
        r >= TISSUE_MIN_RATIO
    };
    let wm = (0..brightest)
        .find(|i| major(i) && tissue(i))
        .unwrap_or(brightest);
    let span = candidates[wm].position - zero;
    if span.is_nan() || span <= 0.0 {
        return Assignment {
            wm: Some(wm),
            ..Assignment::default()
        };
    }
    let ratio = |i: usize| (candidates[i].position - zero) / span;
    let csf = (wm + 1..candidates.len())
        .rev()
        .find(|&i| ratio(i) >= csf_min_ratio);
    let gm = most_prominent(
        candidates,
        (wm + 1..csf.unwrap_or(candidates.len()))
            .filter(|&i| ratio(i) < csf_min_ratio || major(&i)),
    );
    Assignment {
        csf,
        gm,
        wm: Some(wm),
    }
}

/// Assigns tissues among `candidates` (ascending significant modes above the background) for
/// adult T1 contrast.
pub fn assign(candidates: &[Mode], zero: f64, params: &AnalysisParams) -> Assignment {
    if candidates.len() < 2 {
        return Assignment::default();
    }
    let tallest = candidates.iter().map(|m| m.height).fold(0.0, f64::max);
    let Some(wm) = (0..candidates.len())
        .filter(|&i| candidates[i].height >= params.major_fraction * tallest)
        .max_by(|&a, &b| candidates[a].position.total_cmp(&candidates[b].position))
    else {
        return Assignment::default();
    };
    let span = candidates[wm].position - zero;
    if span.is_nan() || span <= 0.0 {
        return Assignment {
            wm: Some(wm),
            ..Assignment::default()
        };
    }
    let ratio = |i: usize| (candidates[i].position - zero) / span;
    let gm = (0..wm)
        .filter(|&i| ratio(i) >= params.gm_min_ratio)
        .max_by(|&a, &b| {
            candidates[a]
                .prominence
                .total_cmp(&candidates[b].prominence)
        });
    let csf = (0..gm.unwrap_or(wm))
        .filter(|&i| (params.csf_min_ratio..params.gm_min_ratio).contains(&ratio(i)))
        .max_by(|&a, &b| {
            candidates[a]
                .prominence
                .total_cmp(&candidates[b].prominence)
        });
    Assignment {
        csf,
        gm,
        wm: Some(wm),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(position: f64, height: f64) -> Mode {
        let b = position as usize;
        Mode {
            first: b,
            last: b,
            position,
            height,
            prominence: height,
        }
    }

    #[test]
    fn ratios_decide_which_tissue_is_missing() {
        let p = AnalysisParams::default();
        // CSF 0.3, GM 0.75 of WM.
        let all = [mode(30.0, 50.0), mode(75.0, 900.0), mode(100.0, 1000.0)];
        assert_eq!(
            assign(&all, 0.0, &p),
            Assignment {
                csf: Some(0),
                gm: Some(1),
                wm: Some(2)
            }
        );
        // Two modes at ratio 0.75: GM and WM.
        assert_eq!(
            assign(&all[1..], 0.0, &p),
            Assignment {
                csf: None,
                gm: Some(0),
                wm: Some(1)
            }
        );
        // Two modes at ratio 0.3: CSF and WM.
        let two = [mode(30.0, 500.0), mode(100.0, 1000.0)];
        assert_eq!(
            assign(&two, 0.0, &p),
            Assignment {
                csf: Some(0),
                gm: None,
                wm: Some(1)
            }
        );
        // A mode darker than 0.12 of WM is neither.
        let dark = [mode(10.0, 500.0), mode(100.0, 1000.0)];
        assert_eq!(
            assign(&dark, 0.0, &p),
            Assignment {
                csf: None,
                gm: None,
                wm: Some(1)
            }
        );
        // ... measured from the background zero: 40 is 0.33 of the way from 10 to 100.
        let shifted = [mode(40.0, 500.0), mode(100.0, 1000.0)];
        assert_eq!(assign(&shifted, 10.0, &p).csf, Some(0));
    }

    #[test]
    fn small_bright_tail_is_not_wm_and_single_modes_are_not_guessed() {
        let p = AnalysisParams::default();
        let tail = [
            mode(30.0, 50.0),
            mode(75.0, 900.0),
            mode(100.0, 1000.0),
            mode(140.0, 100.0),
        ];
        assert_eq!(
            assign(&tail, 0.0, &p),
            Assignment {
                csf: Some(0),
                gm: Some(1),
                wm: Some(2)
            }
        );
        assert_eq!(assign(&tail[2..3], 0.0, &p), Assignment::default());
        assert_eq!(assign(&[], 0.0, &p), Assignment::default());
        // A dark (bone) shell below 0.12 of WM is not CSF, however tall.
        let shell = [
            mode(8.0, 800.0),
            mode(30.0, 100.0),
            mode(75.0, 900.0),
            mode(100.0, 1000.0),
        ];
        assert_eq!(assign(&shell, 0.0, &p).csf, Some(1));
        // A small partial-volume bump between CSF and GM is not CSF (the phantom has one at
        // about half of WM).
        let bump = [
            mode(30.0, 300.0),
            mode(49.0, 20.0),
            mode(75.0, 900.0),
            mode(100.0, 1000.0),
        ];
        assert_eq!(assign(&bump, 0.0, &p).csf, Some(0));
    }

    #[test]
    fn t2_labels_wm_darkest_gm_next_csf_brightest() {
        let p = AnalysisParams::default();
        // WM 0.17, GM 0.25, CSF 0.60 of the range (the `contrast` doc's example), a dark bone
        // mode below WM and a small partial-volume bump between GM and CSF.
        let t2 = [
            mode(10.0, 100.0),
            mode(43.0, 1000.0),
            mode(64.0, 900.0),
            mode(110.0, 40.0),
            mode(154.0, 300.0),
        ];
        let want = Assignment {
            csf: Some(4),
            gm: Some(2),
            wm: Some(1),
        };
        assert_eq!(assign_t2(&t2, 0.0, &p), want);
        assert_eq!(assign_for(Contrast::T2, &t2, 0.0, &p), want);
        // The same modes read as T1 come out the other way round (why the contrast matters).
        assert_ne!(assign_for(Contrast::T1, &t2, 0.0, &p).wm, Some(1));
        // Ratios split at 2.0 of WM, measured from zero: 90 is 2.09 times 43 from 0 (CSF) but
        // 1.89 times from -10 (GM).
        let two = [mode(43.0, 1000.0), mode(90.0, 500.0)];
        assert_eq!(
            assign_t2(&two, 0.0, &p),
            Assignment {
                csf: Some(1),
                gm: None,
                wm: Some(0)
            }
        );
        assert_eq!(
            assign_t2(&two, -10.0, &p),
            Assignment {
                csf: None,
                gm: Some(1),
                wm: Some(0)
            }
        );
        assert_eq!(assign_t2(&two[..1], 0.0, &p), Assignment::default());
        // CSF is the brightest mode at 2x WM or more, however small; a major mode between is GM
        // whatever its ratio (the inverted MNI152 template: WM, GM at 2.4x WM, small CSF).
        let inverted = [
            mode(36.0, 25487.0),
            mode(85.0, 25090.0),
            mode(190.0, 1216.0),
        ];
        assert_eq!(
            assign_t2(&inverted, 0.0, &p),
            Assignment {
                csf: Some(2),
                gm: Some(1),
                wm: Some(0)
            }
        );
        // A large dark shell (skull, 0.13 of CSF) below WM is not WM.
        let shell = [
            mode(20.0, 1400.0),
            mode(43.0, 1100.0),
            mode(64.0, 1250.0),
            mode(154.0, 900.0),
        ];
        assert_eq!(
            assign_t2(&shell, 0.0, &p),
            Assignment {
                csf: Some(3),
                gm: Some(2),
                wm: Some(1)
            }
        );
    }
}
