//! Tests of the histogram analysis (`morphray::analysis`): the MNI152 template fixture, and
//! synthetic histograms for every hard case (missing tissues, merged modes, plateaus, spikes,
//! quantization combs, noise, empty and constant volumes).

mod common;

use common::mni152::{MNI152_HIST, MNI152_TOTAL};
use morphray::analysis::{self, AnalysisParams, ModeRole, TissueReport, TissueWindows, Window};
use morphray::reference::{BINS, bin_of};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// Helpers

/// splitmix64: a tiny deterministic generator, so fixtures need no extra dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let u = 1.0 - self.uniform(); // (0, 1]
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

#[derive(Clone, Copy)]
enum Shape {
    Normal(f64, f64),
    /// Magnitude of complex Gaussian noise (air in a magnitude MR image).
    Rayleigh(f64),
    Uniform(f64, f64),
}

/// Histogram of `n` samples of `I_norm` drawn from a weighted mixture, binned by the reference
/// twin (values outside [0, 1] clamp, as on the GPU).
fn mixture(parts: &[(f64, Shape)], n: usize, seed: u64) -> [u32; BINS] {
    let mut rng = Rng(seed);
    let total: f64 = parts.iter().map(|p| p.0).sum();
    let mut hist = [0u32; BINS];
    for _ in 0..n {
        let mut pick = rng.uniform() * total;
        let mut shape = parts[parts.len() - 1].1;
        for &(w, sh) in parts {
            if pick < w {
                shape = sh;
                break;
            }
            pick -= w;
        }
        let v = match shape {
            Shape::Normal(m, sd) => m + sd * rng.normal(),
            Shape::Rayleigh(sd) => sd * (rng.normal().powi(2) + rng.normal().powi(2)).sqrt(),
            Shape::Uniform(lo, hi) => lo + (hi - lo) * rng.uniform(),
        };
        hist[bin_of(v as f32)] += 1;
    }
    hist
}

fn run(hist: &[u32; BINS]) -> TissueReport {
    let n: u64 = hist.iter().map(|&c| c as u64).sum();
    let r = analysis::analyze(hist, 0.0, 1000.0, n as usize, 0);
    check_invariants(&r);
    r
}

fn near(peak: Option<analysis::Peak>, want: f64, tol: f64) -> bool {
    peak.is_some_and(|p| (p.norm - want).abs() <= tol)
}

/// Properties every report must have, whatever the histogram.
fn check_invariants(r: &TissueReport) {
    let p = &r.peaks;
    let w = &r.adaptive_windows;
    // A window exists exactly for each present tissue; pathology only above a present WM.
    assert_eq!(p.csf.is_some(), w.csf.is_some());
    assert_eq!(p.gm.is_some(), w.gm.is_some());
    assert_eq!(p.wm.is_some(), w.wm.is_some());
    assert!(w.pathology.is_none() || p.wm.is_some());
    // Any tissue implies WM; peaks ordered CSF < GM < WM.
    assert!(p.wm.is_some() || (p.csf.is_none() && p.gm.is_none()));
    let present: Vec<(analysis::Peak, Window)> = [(p.csf, w.csf), (p.gm, w.gm), (p.wm, w.wm)]
        .into_iter()
        .filter_map(|(a, b)| a.zip(b))
        .collect();
    for pair in present.windows(2) {
        assert!(
            pair[0].0.norm < pair[1].0.norm,
            "peaks out of order: {:?}",
            r.peaks
        );
        assert_eq!(
            pair[0].1.hi, pair[1].1.lo,
            "adjacent windows share their boundary"
        );
    }
    let all: Vec<Window> = [w.csf, w.gm, w.wm, w.pathology]
        .into_iter()
        .flatten()
        .collect();
    for win in &all {
        assert!(
            win.lo < win.hi && win.edge >= 0.0 && win.lo + win.edge <= win.hi - win.edge,
            "{win:?}"
        );
        assert_eq!(win.edge, all[0].edge, "one edge for all adaptive windows");
    }
    for (peak, win) in &present {
        assert!(
            win.lo < peak.norm && peak.norm < win.hi,
            "{peak:?} outside {win:?}"
        );
        assert!(
            (win.weight(peak.norm) - 1.0).abs() < 1e-12,
            "full weight at the mode"
        );
        assert_eq!(peak.raw, r.imin + peak.norm * (r.imax - r.imin));
    }
    if let Some(first) = all.first() {
        assert!(first.lo >= r.background_threshold);
        // Partition of unity from the first window's full-weight point up to I_norm = 1.
        let start = first.lo + first.edge;
        for i in 0..=1000 {
            let x = start + (1.0 - start) * i as f64 / 1000.0;
            let sum: f64 = all.iter().map(|w| w.weight(x)).sum();
            let covered_to = all.last().map_or(0.0, |w| w.hi - w.edge);
            if x <= covered_to {
                assert!(
                    (sum - 1.0).abs() < 1e-12,
                    "weights sum to {sum} at {x}: {all:?}"
                );
            }
        }
        // The windows are open at the top: I_norm = 1 is fully classified.
        let top: f64 = all.iter().map(|w| w.weight(1.0)).sum();
        assert!((top - 1.0).abs() < 1e-12, "weight {top} at 1.0");
    }
    // Counts.
    let finite: u64 = r.finite_voxels;
    assert!(r.used_voxels <= finite);
    assert!((0.0..=1.0).contains(&r.background_threshold));
    // in_paper_window is null exactly for missing tissues.
    assert_eq!(r.in_paper_window.csf.is_some(), p.csf.is_some());
    assert_eq!(r.in_paper_window.gm.is_some(), p.gm.is_some());
    assert_eq!(r.in_paper_window.wm.is_some(), p.wm.is_some());
    assert_eq!(r.paper_windows, TissueWindows::paper());
    // Roles agree with peaks.
    let with_role = |role| {
        r.modes
            .iter()
            .filter(|m| m.role == role)
            .map(|m| m.peak)
            .collect::<Vec<_>>()
    };
    assert_eq!(
        with_role(ModeRole::Csf),
        p.csf.into_iter().collect::<Vec<_>>()
    );
    assert_eq!(
        with_role(ModeRole::Gm),
        p.gm.into_iter().collect::<Vec<_>>()
    );
    assert_eq!(
        with_role(ModeRole::Wm),
        p.wm.into_iter().collect::<Vec<_>>()
    );
}

// ---------------------------------------------------------------------------------------------
// Real data: the MNI152 template

#[test]
fn mni152_fixture_matches_the_engine_binning_of_u8() {
    // u8 value v normalized over [0, 255] lands in bin v (255 in bin 255), so the fixture is
    // the value histogram of the file; this is what the engine's own binning gives too.
    for v in 0..=255u32 {
        let norm = morphray::reference::normalize_value(v as f64, 0.0, 255.0) as f32;
        assert_eq!(bin_of(norm), v as usize);
    }
    assert_eq!(
        MNI152_HIST.iter().map(|&c| c as usize).sum::<usize>(),
        MNI152_TOTAL
    );
}

#[test]
fn mni152_peaks_sit_at_026_067_086() {
    let r = analysis::analyze(&MNI152_HIST, 0.0, 255.0, MNI152_TOTAL, 0);
    check_invariants(&r);
    assert!(near(r.peaks.csf, 0.26, 0.01), "{:?}", r.peaks);
    assert!(near(r.peaks.gm, 0.67, 0.01), "{:?}", r.peaks);
    assert!(near(r.peaks.wm, 0.86, 0.01), "{:?}", r.peaks);
    // raw units: u8 grey levels.
    let wm = r.peaks.wm.expect("wm");
    assert!((wm.raw - 255.0 * wm.norm).abs() < 1e-9);
    // The 6788750 masked zeros are a background spike; every other voxel is brain.
    assert_eq!(r.spikes.len(), 1);
    assert_eq!(
        (r.spikes[0].bin, r.spikes[0].count, r.spikes[0].background),
        (0, 6_788_750, true)
    );
    assert_eq!(r.background_threshold, 1.0 / 256.0);
    assert_eq!(r.used_voxels, (MNI152_TOTAL - 6_788_750) as u64);
    assert_eq!(
        (r.total_voxels, r.nonfinite_voxels, r.finite_voxels),
        (MNI152_TOTAL, 0, MNI152_TOTAL as u64)
    );
    // Only three significant modes, no invented extras.
    assert_eq!(r.modes.len(), 3, "{:?}", r.modes);
    // The paper's fixed windows miss CSF and GM on this template; WM (> 0.18) trivially holds.
    assert_eq!(
        (
            r.in_paper_window.csf,
            r.in_paper_window.gm,
            r.in_paper_window.wm
        ),
        (Some(false), Some(false), Some(true))
    );
    // The GM/WM boundary is the valley between them (raw minimum at grey level 204).
    let gm = r.adaptive_windows.gm.expect("gm window");
    assert!((203.0 / 256.0..205.0 / 256.0).contains(&gm.hi), "{gm:?}");
    // Pathology starts above nearly all of the template's voxels.
    let path = r.adaptive_windows.pathology.expect("pathology");
    let above: u32 = MNI152_HIST[(path.lo * 256.0).ceil() as usize..]
        .iter()
        .sum();
    assert!(
        path.lo > 0.9 && (above as f64) < 1e-3 * r.used_voxels as f64,
        "{path:?}: {above}"
    );
}

#[test]
fn mni152_report_serializes_with_flat_table1_row() {
    let r = analysis::analyze(&MNI152_HIST, 0.0, 255.0, MNI152_TOTAL, 0);
    let row = r.table1();
    assert_eq!(row.csf_norm, r.peaks.csf.map(|p| p.norm));
    assert_eq!(row.wm_raw, r.peaks.wm.map(|p| p.raw));
    assert_eq!(row.used_voxels, r.used_voxels);
    let json = serde_json::to_value(&r).expect("serializable");
    assert_eq!(json["spikes"][0]["bin"], 0);
    assert_eq!(
        json["peaks"]["gm"]["norm"],
        serde_json::json!(r.peaks.gm.map(|p| p.norm))
    );
    assert_eq!(json["modes"][0]["role"], "csf");
}

// ---------------------------------------------------------------------------------------------
// Synthetic histograms

/// Like the built-in phantom: Rayleigh air noise at 0, a dark skull shell, CSF / GM / WM at
/// 0.18 / 0.42 / 0.60, and a small bright tail (vessels, a lesion).
fn phantom_like(seed: u64, csf: bool) -> [u32; BINS] {
    let mut parts = vec![
        (0.40, Shape::Rayleigh(0.012)),
        (0.06, Shape::Normal(0.08, 0.012)),
        (0.22, Shape::Normal(0.42, 0.035)),
        (0.22, Shape::Normal(0.60, 0.03)),
        (0.008, Shape::Uniform(0.7, 1.0)),
        (0.004, Shape::Normal(0.85, 0.02)),
    ];
    if csf {
        parts.push((0.08, Shape::Normal(0.18, 0.025)));
    }
    mixture(&parts, 2_000_000, seed)
}

#[test]
fn phantom_like_mixture_finds_csf_gm_wm_and_excludes_background() {
    for seed in 1..=3 {
        let h = phantom_like(seed, true);
        let r = run(&h);
        assert!(near(r.peaks.csf, 0.18, 0.01), "seed {seed}: {:?}", r.peaks);
        assert!(near(r.peaks.gm, 0.42, 0.01), "seed {seed}: {:?}", r.peaks);
        assert!(near(r.peaks.wm, 0.60, 0.01), "seed {seed}: {:?}", r.peaks);
        // The air mode is background; the threshold sits in the valley after it (Rayleigh mode
        // at 0.012), before the shell at 0.08.
        assert_eq!(r.modes[0].role, ModeRole::Background, "{:?}", r.modes);
        assert!(
            (0.02..0.07).contains(&r.background_threshold),
            "{}",
            r.background_threshold
        );
        let air: u64 = h[..(r.background_threshold * 256.0) as usize]
            .iter()
            .map(|&c| c as u64)
            .sum();
        assert_eq!(r.used_voxels + air, r.finite_voxels);
        assert!(
            (r.used_voxels as f64 / 2e6 - 0.6).abs() < 0.01,
            "used {}",
            r.used_voxels
        );
        // The dark shell is not CSF, and the CSF window starts after it.
        let shell = r
            .modes
            .iter()
            .find(|m| (m.peak.norm - 0.08).abs() < 0.01)
            .expect("shell mode");
        assert_ne!(shell.role, ModeRole::Csf);
        let csf = r.adaptive_windows.csf.expect("csf window");
        assert!(csf.lo > 0.09 && csf.lo < 0.16, "{csf:?}");
        // The bright tail is not WM; pathology starts between WM and the tail's bump.
        let path = r.adaptive_windows.pathology.expect("pathology");
        assert!((0.65..0.8).contains(&path.lo), "{path:?}");
    }
}

#[test]
fn two_class_histogram_reports_csf_missing() {
    for seed in 10..20 {
        let r = run(&phantom_like(seed, false));
        assert_eq!(
            r.peaks.csf, None,
            "seed {seed}: {:?} {:?}",
            r.peaks, r.modes
        );
        assert!(
            near(r.peaks.gm, 0.42, 0.01) && near(r.peaks.wm, 0.60, 0.01),
            "seed {seed}: {:?}",
            r.peaks
        );
        assert_eq!(r.adaptive_windows.csf, None);
        // GM's window takes everything down to the shell valley.
        assert!(r.adaptive_windows.gm.expect("gm").lo < 0.2);
    }
    // Without shell and air: just two Gaussians.
    let h = mixture(
        &[
            (0.5, Shape::Normal(0.5, 0.04)),
            (0.5, Shape::Normal(0.75, 0.03)),
        ],
        500_000,
        7,
    );
    let r = run(&h);
    assert_eq!(r.peaks.csf, None);
    assert!(
        near(r.peaks.gm, 0.5, 0.01) && near(r.peaks.wm, 0.75, 0.01),
        "{:?}",
        r.peaks
    );
    assert_eq!(r.background_threshold, 0.0);
    assert_eq!(r.used_voxels, 500_000);
}

#[test]
fn widely_spaced_second_mode_is_csf_with_gm_missing() {
    let h = mixture(
        &[
            (0.3, Shape::Rayleigh(0.01)),
            (0.2, Shape::Normal(0.2, 0.03)),
            (0.5, Shape::Normal(0.65, 0.04)),
        ],
        1_000_000,
        3,
    );
    let r = run(&h);
    assert!(near(r.peaks.csf, 0.2, 0.01), "{:?}", r.peaks);
    assert_eq!(r.peaks.gm, None);
    assert!(near(r.peaks.wm, 0.65, 0.01), "{:?}", r.peaks);
}

#[test]
fn merged_gm_wm_shoulder_gives_one_mode_not_two() {
    let parts = [
        (0.3, Shape::Rayleigh(0.012)),
        (0.08, Shape::Normal(0.2, 0.025)),
        (0.25, Shape::Normal(0.50, 0.045)),
        (0.30, Shape::Normal(0.58, 0.035)),
    ];
    let h = mixture(&parts, 2_000_000, 5);
    let r = run(&h);
    // The GM component is only a shoulder on the WM mode: not a local maximum, so not a peak.
    assert!(near(r.peaks.csf, 0.2, 0.01), "{:?}", r.peaks);
    assert_eq!(r.peaks.gm, None, "{:?}", r.modes);
    let wm = r.peaks.wm.expect("merged mode");
    assert!((0.53..0.59).contains(&wm.norm), "{wm:?}");
    // The merged mode's window reaches down to the CSF valley, so GM voxels stay classified.
    assert!(r.adaptive_windows.wm.expect("wm").lo < 0.35);
}

#[test]
fn plateaus_report_their_centre() {
    let mut h = [0u32; BINS];
    h[40..=50].fill(500);
    h[100..=121].fill(1000); // even length: the centre is a bin edge
    h[180..=200].fill(2000);
    let r = run(&h);
    let at = |x: f64| x / 256.0;
    assert_eq!(r.peaks.csf.map(|p| p.norm), Some(at(45.5)), "{:?}", r.peaks);
    assert_eq!(r.peaks.gm.map(|p| p.norm), Some(at(111.0)));
    assert_eq!(r.peaks.wm.map(|p| p.norm), Some(at(190.5)));
    // Boundaries: the centre of the empty run between two plateaus.
    assert_eq!(
        r.adaptive_windows.csf.expect("csf").hi,
        at((51.0 + 99.0) / 2.0 + 0.5)
    );
    assert_eq!(
        r.adaptive_windows.gm.expect("gm").hi,
        at((122.0 + 179.0) / 2.0 + 0.5)
    );
}

#[test]
fn sixty_percent_zeros_are_a_background_spike() {
    let tissue = mixture(
        &[
            (0.15, Shape::Normal(0.25, 0.03)),
            (0.45, Shape::Normal(0.6, 0.04)),
            (0.4, Shape::Normal(0.8, 0.03)),
        ],
        400_000,
        11,
    );
    let mut h = tissue;
    h[0] += 600_000;
    let r = run(&h);
    assert!(
        near(r.peaks.csf, 0.25, 0.01) && near(r.peaks.gm, 0.6, 0.01) && near(r.peaks.wm, 0.8, 0.01),
        "{:?}",
        r.peaks
    );
    assert_eq!(r.background_threshold, 1.0 / 256.0);
    assert_eq!(r.used_voxels, 400_000 - tissue[0] as u64);
    assert!(r.spikes.iter().any(|s| s.bin == 0 && s.background));
}

#[test]
fn spike_above_dark_outliers_is_still_background() {
    // A few negative outliers set Imin, so the masked zeros land in bin 30, not bin 0.
    let mut h = mixture(
        &[
            (0.3, Shape::Normal(0.5, 0.03)),
            (0.7, Shape::Normal(0.7, 0.03)),
        ],
        300_000,
        2,
    );
    h[0] += 2;
    h[2] += 1;
    h[30] += 500_000;
    let r = run(&h);
    assert_eq!(r.background_threshold, 31.0 / 256.0);
    // Ratios are measured from the spike (the physical zero): (0.5 - 0.12) / (0.7 - 0.12) = 0.66.
    assert!(
        near(r.peaks.gm, 0.5, 0.01) && near(r.peaks.wm, 0.7, 0.01),
        "{:?}",
        r.peaks
    );
    assert_eq!(r.peaks.csf, None);
}

#[test]
fn degenerate_histograms_give_no_peaks() {
    let empty = run(&[0; BINS]);
    assert_eq!(
        (
            empty.finite_voxels,
            empty.used_voxels,
            empty.background_threshold
        ),
        (0, 0, 0.0)
    );
    assert!(empty.modes.is_empty() && empty.spikes.is_empty());
    assert_eq!(empty.adaptive_windows, TissueWindows::none());

    let mut constant = [0; BINS];
    constant[0] = 4096; // NUMERICS.md: a constant volume normalizes to 0 everywhere
    let r = run(&constant);
    assert_eq!(r.peaks, analysis::Peaks::default());
    assert_eq!((r.used_voxels, r.background_threshold), (0, 1.0 / 256.0));

    for bin in [0, 128, 255] {
        let mut one = [0; BINS];
        one[bin] = 1;
        let r = run(&one);
        assert_eq!(
            r.peaks,
            analysis::Peaks::default(),
            "single voxel in bin {bin}"
        );
        assert_eq!(r.finite_voxels, 1);
    }
}

#[test]
fn uniform_and_noise_only_histograms_give_no_peaks() {
    let r = run(&[1000; BINS]);
    assert!(r.modes.is_empty(), "{:?}", r.modes);
    assert_eq!(r.peaks, analysis::Peaks::default());
    for seed in 0..20 {
        let r = run(&mixture(
            &[(1.0, Shape::Uniform(0.0, 1.0))],
            300_000,
            100 + seed,
        ));
        assert_eq!(
            r.peaks,
            analysis::Peaks::default(),
            "seed {seed}: {:?}",
            r.modes
        );
        assert!(r.modes.len() <= 1, "seed {seed}: {:?}", r.modes);
    }
    // Pure air noise, normalized by its own maximum (Rayleigh mode near 0.2 of the range).
    for seed in 0..5 {
        let r = run(&mixture(
            &[(1.0, Shape::Rayleigh(0.19))],
            500_000,
            200 + seed,
        ));
        assert_eq!(
            r.peaks,
            analysis::Peaks::default(),
            "seed {seed}: {:?}",
            r.modes
        );
    }
    let r = run(&mixture(&[(1.0, Shape::Normal(0.5, 0.1))], 500_000, 9));
    assert_eq!(r.peaks, analysis::Peaks::default(), "{:?}", r.modes);
    assert_eq!(r.modes.len(), 1);
    assert_eq!(r.modes[0].role, ModeRole::Other);
}

#[test]
fn paper_like_intensities_fall_in_the_paper_windows() {
    // A bright outlier range compresses the brain into the low end, as in the paper's data.
    let h = mixture(
        &[
            (0.4, Shape::Rayleigh(0.006)),
            (0.06, Shape::Normal(0.085, 0.008)),
            (0.25, Shape::Normal(0.15, 0.01)),
            (0.25, Shape::Normal(0.22, 0.01)),
            (0.005, Shape::Uniform(0.25, 1.0)),
        ],
        2_000_000,
        4,
    );
    let r = run(&h);
    assert!(
        near(r.peaks.csf, 0.085, 0.005)
            && near(r.peaks.gm, 0.15, 0.005)
            && near(r.peaks.wm, 0.22, 0.005),
        "{:?}",
        r.peaks
    );
    assert_eq!(
        (
            r.in_paper_window.csf,
            r.in_paper_window.gm,
            r.in_paper_window.wm
        ),
        (Some(true), Some(true), Some(true))
    );
}

#[test]
fn quantized_comb_histogram_is_smoothed_by_its_gap() {
    // An integer volume with 40 grey levels: every 6th or 7th bin is occupied.
    let mut rng = Rng(77);
    let mut h = [0u32; BINS];
    let parts = [(0.2, 0.25, 0.04), (0.4, 0.55, 0.05), (0.4, 0.8, 0.04)];
    for _ in 0..400_000 {
        let pick = rng.uniform();
        let (_, m, sd) = if pick < 0.2 {
            parts[0]
        } else if pick < 0.6 {
            parts[1]
        } else {
            parts[2]
        };
        let level = ((m + sd * rng.normal()) * 39.0).round().clamp(0.0, 39.0);
        h[bin_of((level / 39.0) as f32)] += 1;
    }
    assert!(h.iter().filter(|&&c| c > 0).count() <= 40);
    let r = run(&h);
    assert!(
        r.spikes.is_empty(),
        "comb teeth are not spikes: {:?}",
        r.spikes
    );
    assert!(r.smoothing_sigma_bins >= 6.0, "{}", r.smoothing_sigma_bins);
    let tol = 1.0 / 39.0;
    assert!(
        near(r.peaks.csf, 0.25, tol) && near(r.peaks.gm, 0.55, tol) && near(r.peaks.wm, 0.8, tol),
        "{:?}",
        r.peaks
    );
}

#[test]
fn one_hot_voxel_does_not_widen_the_smoothing() {
    let mut h = mixture(
        &[
            (0.15, Shape::Normal(0.05, 0.006)),
            (0.45, Shape::Normal(0.12, 0.008)),
            (0.4, Shape::Normal(0.16, 0.006)),
        ],
        500_000,
        8,
    );
    h[255] += 1;
    let r = run(&h);
    assert_eq!(r.smoothing_sigma_bins, 1.0);
    assert!(
        near(r.peaks.csf, 0.05, 0.005)
            && near(r.peaks.gm, 0.12, 0.005)
            && near(r.peaks.wm, 0.16, 0.005),
        "{:?}",
        r.peaks
    );
}

#[test]
fn parameters_change_the_outcome_where_documented() {
    // A stricter noise test drops the MNI152 CSF mode (it passes the default at about 4.3 sigma).
    let strict = AnalysisParams {
        noise_z: 5.0,
        ..AnalysisParams::default()
    };
    let r = analysis::analyze_with(&MNI152_HIST, 0.0, 255.0, MNI152_TOTAL, 0, &strict);
    check_invariants(&r);
    assert_eq!(r.peaks.csf, None);
    assert!(r.peaks.gm.is_some() && r.peaks.wm.is_some());
    // Wider smoothing erases it too (why the default sigma is 1 bin).
    let wide = AnalysisParams {
        sigma_bins: 2.0,
        ..AnalysisParams::default()
    };
    let r = analysis::analyze_with(&MNI152_HIST, 0.0, 255.0, MNI152_TOTAL, 0, &wide);
    assert_eq!(r.peaks.csf, None);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    /// Arbitrary histograms (sparse, spiky, huge counts) never panic and keep every invariant.
    #[test]
    fn arbitrary_histograms_keep_invariants(
        counts in prop::collection::vec(prop_oneof![Just(0u32), 0u32..50, 0u32..100_000, Just(u32::MAX / 256)], BINS),
        imin in -1e3f64..1e3,
        span in 0.0f64..1e4,
    ) {
        let mut h = [0u32; BINS];
        h.copy_from_slice(&counts);
        let n: u64 = h.iter().map(|&c| c as u64).sum();
        let r = analysis::analyze(&h, imin, imin + span, n as usize + 3, 3);
        check_invariants(&r);
        prop_assert_eq!(r.finite_voxels, n);
    }
}
