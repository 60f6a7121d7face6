//! Which tissue modes are CSF, GM and WM (adult T1 contrast: CSF < GM < WM).
//!
//! Rules, applied to the significant modes above the background (the candidates):
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
//! Limits (documented, not solved): inverted contrast (T2, neonatal T1) is misread; a bright
//! tail larger than `major_fraction` of the tallest tissue mode would be called WM; when GM and
//! WM merge into one mode it is called WM.

use super::params::AnalysisParams;
use super::peaks::Mode;

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

/// Assigns tissues among `candidates` (ascending significant modes above the background).
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
}
