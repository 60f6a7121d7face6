//! Contrast awareness (issue 11, item 3): a T2-like volume made from the phantom's labels is
//! detected as T2 and its peaks land in the right tissues, on the GPU path (lavapipe here) and
//! through the command line; the ordinary T1 phantom stays T1; `--contrast t1` is obeyed and
//! reported as forced; histograms of random counts are never taken for T2.

mod common;

use common::mni152::MNI152_HIST;

use morphray::analysis::{
    self, AnalysisParams, Contrast, ContrastBasis, ContrastChoice, Peak, TissueReport,
};
use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::{DeviceConfig, Validation};
use morphray::reference::{BINS, finite_min_max, histogram_of_samples};
use morphray::volume::phantom::{PhantomSpec, Tissue, generate};
use morphray::volume::{Samples, Volume};
use std::path::PathBuf;
use std::process::{Command, Output};

/// T2-like intensities per phantom label: WM darkest, GM 1.5x WM, CSF brightest (3.3x WM), as
/// in `analysis::contrast`'s worked example; a dark skull, a bright lesion between GM and CSF
/// and dark vessels (flow voids).
fn t2_value(tissue: Tissue) -> f64 {
    match tissue {
        Tissue::Background => 0.0,
        Tissue::SkullFat => 120.0,
        Tissue::Csf => 1000.0,
        Tissue::Gm => 450.0,
        Tissue::Wm => 300.0,
        Tissue::Lesion => 800.0,
        Tissue::Vessel => 80.0,
        // Vasogenic edema: extra water, bright on T2 (between GM and the lesion).
        Tissue::Edema => 600.0,
        // The head's layers (src/volume/phantom_head.rs) are not in the plain phantom used here.
        other => unreachable!("{} is not in the plain phantom", other.name()),
    }
}

/// Noise of each component of the complex signal (Rician magnitude), raw units.
const SIGMA: f64 = 20.0;

/// Relative spread of CSF intensities (pulsation, partial volume): CSF is the broad mode in a
/// real histogram of either contrast, which `analysis::contrast` relies on.
const CSF_SPREAD: f64 = 0.06;

/// The phantom's labels remapped to T2 intensities with Rician noise (deterministic), and the
/// labels.
fn t2_phantom(n: usize) -> (Volume, Vec<u8>) {
    let phantom = generate(&PhantomSpec::cube(n)).unwrap();
    let mut rng = common::volumes::Rng(0x7432);
    let mut normal = || {
        // Irwin-Hall(12) - 6: close enough to a unit normal for noise.
        (0..12).map(|_| rng.unit()).sum::<f64>() - 6.0
    };
    let samples: Vec<i16> = phantom
        .labels
        .iter()
        .map(|&l| {
            let tissue = Tissue::from_label(l).unwrap();
            let spread = if tissue == Tissue::Csf {
                1.0 + CSF_SPREAD * normal()
            } else {
                1.0
            };
            let v = t2_value(tissue) * spread;
            let (re, im) = (v + SIGMA * normal(), SIGMA * normal());
            (re * re + im * im).sqrt().round() as i16
        })
        .collect();
    let mut volume = phantom.volume;
    volume.name = "t2-phantom".into();
    volume.samples = Samples::from_i16(&samples);
    (volume, phantom.labels)
}

/// The 5th to 95th percentile of the raw values of `tissue`'s voxels.
fn tissue_range(volume: &Volume, labels: &[u8], tissue: Tissue) -> (f64, f64) {
    let values = volume.samples.to_f64_vec();
    let mut xs: Vec<f64> = values
        .iter()
        .zip(labels)
        .filter(|(_, l)| **l == tissue as u8)
        .map(|(v, _)| *v)
        .collect();
    assert!(xs.len() > 20, "{tissue:?}: {} voxels", xs.len());
    xs.sort_by(f64::total_cmp);
    let at = |q: f64| xs[((xs.len() - 1) as f64 * q).round() as usize];
    (at(0.05), at(0.95))
}

fn assert_peak_in(peak: Option<Peak>, range: (f64, f64), what: &str, r: &TissueReport) {
    let p = peak.unwrap_or_else(|| panic!("{what} peak missing: {:?} {:?}", r.peaks, r.modes));
    assert!(
        (range.0..=range.1).contains(&p.raw),
        "{what} peak {} outside the tissue's range {range:?}: {:?}",
        p.raw,
        r.peaks
    );
}

fn engine_with(contrast: ContrastChoice) -> Engine {
    let config = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        analysis: AnalysisParams {
            contrast,
            ..AnalysisParams::default()
        },
        ..Default::default()
    };
    Engine::new(config).unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        )
    })
}

fn gpu_report(engine: &mut Engine, volume: &Volume) -> TissueReport {
    let prepared = engine.prepare(volume).unwrap();
    let report = engine.analyze(&prepared);
    common::assert_no_validation_errors(engine);
    report
}

/// The CPU twin of the engine's analysis input.
fn cpu_report(volume: &Volume, params: &AnalysisParams) -> TissueReport {
    let (lo, hi) = finite_min_max(&volume.samples).unwrap();
    let (imin, imax) = (volume.to_physical.apply(lo), volume.to_physical.apply(hi));
    let hist = histogram_of_samples(&volume.samples, volume.to_physical, imin, imax);
    analysis::analyze_with(&hist, imin, imax, volume.voxel_count(), 0, params)
}

#[test]
fn t2_phantom_is_detected_as_t2_and_each_peak_is_in_its_tissue() {
    let (volume, labels) = t2_phantom(64);
    let mut engine = engine_with(ContrastChoice::Auto);
    let r = gpu_report(&mut engine, &volume);
    eprintln!("{:?}\n{:?}", r.contrast, r.modes);
    assert_eq!(
        (r.contrast.contrast, r.contrast.basis),
        (Contrast::T2, ContrastBasis::Histogram),
        "{:?}",
        r.modes
    );
    assert!(
        r.contrast.reason.contains("T2 shape"),
        "{}",
        r.contrast.reason
    );
    assert_peak_in(
        r.peaks.wm,
        tissue_range(&volume, &labels, Tissue::Wm),
        "WM",
        &r,
    );
    assert_peak_in(
        r.peaks.gm,
        tissue_range(&volume, &labels, Tissue::Gm),
        "GM",
        &r,
    );
    assert_peak_in(
        r.peaks.csf,
        tissue_range(&volume, &labels, Tissue::Csf),
        "CSF",
        &r,
    );
    // Windows in intensity order WM < GM < CSF, sharing boundaries, each around its own peak.
    let w = &r.adaptive_windows;
    let (wm, gm, csf) = (w.wm.unwrap(), w.gm.unwrap(), w.csf.unwrap());
    assert_eq!((wm.hi, gm.hi), (gm.lo, csf.lo), "{w:?}");
    for (win, peak) in [(wm, r.peaks.wm), (gm, r.peaks.gm), (csf, r.peaks.csf)] {
        assert_eq!(win.weight(peak.unwrap().norm), 1.0, "{win:?} {peak:?}");
    }
    // The pathology band sits above CSF, the brightest tissue in T2.
    assert!(w.pathology.is_none_or(|p| p.lo >= csf.hi), "{w:?}");
}

#[test]
fn forced_t1_on_the_t2_phantom_is_obeyed_and_reported_as_forced() {
    let (volume, labels) = t2_phantom(48);
    let mut engine = engine_with(ContrastChoice::T1);
    let r = gpu_report(&mut engine, &volume);
    assert_eq!(
        (r.contrast.contrast, r.contrast.basis),
        (Contrast::T1, ContrastBasis::Given)
    );
    assert_eq!(r.params.contrast, ContrastChoice::T1);
    // Labelled the T1 way: the brightest large mode (CSF here) is called WM.
    assert_peak_in(
        r.peaks.wm,
        tissue_range(&volume, &labels, Tissue::Csf),
        "WM (forced T1, really CSF)",
        &r,
    );
}

#[test]
fn t1_phantom_stays_t1_at_every_test_size() {
    let p = AnalysisParams::default();
    // 20^3 and 24^3 have CSF as their tallest mode (partial volume), told from T2 by its width.
    for n in [20, 24, 32, 40, 48, 64] {
        let volume = generate(&PhantomSpec::cube(n)).unwrap().volume;
        let r = cpu_report(&volume, &p);
        assert_eq!(
            (r.contrast.contrast, r.contrast.basis),
            (Contrast::T1, ContrastBasis::Histogram),
            "{n}^3: {} {:?}",
            r.contrast.reason,
            r.modes
        );
    }
    // 16^3: the tallest mode is air noise on the zero; no evidence, T1 assumed as before.
    let volume = generate(&PhantomSpec::cube(16)).unwrap().volume;
    let r = cpu_report(&volume, &p);
    assert_eq!(
        (r.contrast.contrast, r.contrast.basis),
        (Contrast::T1, ContrastBasis::Assumed),
        "{}",
        r.contrast.reason
    );
    // And on the GPU path.
    let volume = generate(&PhantomSpec::cube(40)).unwrap().volume;
    let r = gpu_report(&mut engine_with(ContrastChoice::Auto), &volume);
    assert_eq!(
        (r.contrast.contrast, r.contrast.basis),
        (Contrast::T1, ContrastBasis::Histogram)
    );
}

#[test]
fn random_histograms_are_never_taken_for_t2() {
    // The distribution of tests/peaks.rs's arbitrary-histogram property (whose invariants
    // assume the T1 order CSF < GM < WM): each bin 0, 0..50, 0..100000 or u32::MAX / 256.
    let mut rng = common::volumes::Rng(0x5eed);
    let cases: usize = std::env::var("CONTRAST_RANDOM_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let mut t2 = 0;
    for _ in 0..cases {
        let mut h = [0u32; BINS];
        for c in h.iter_mut() {
            let r = rng.next_u64();
            *c = match r % 4 {
                0 => 0,
                1 => ((r >> 8) % 50) as u32,
                2 => ((r >> 8) % 100_000) as u32,
                _ => u32::MAX / 256,
            };
        }
        let n: u64 = h.iter().map(|&c| c as u64).sum();
        let r = analysis::analyze(&h, 0.0, 1000.0, n as usize, 0);
        if r.contrast.contrast == Contrast::T2 {
            t2 += 1;
            eprintln!("{:?}", r.contrast);
        }
    }
    assert_eq!(t2, 0, "{t2} of {cases} random histograms read as T2");
}

// ---------------------------------------------------------------------------------------------
// Real data: the MNI152 T1 template, and the same turned upside down (inverted contrast).

#[test]
fn mni152_is_t1_and_its_inversion_is_labelled_the_t2_way() {
    let n: u64 = MNI152_HIST.iter().map(|&c| c as u64).sum();
    let r = analysis::analyze(&MNI152_HIST, 0.0, 255.0, n as usize, 0);
    assert_eq!(
        (r.contrast.contrast, r.contrast.basis),
        (Contrast::T1, ContrastBasis::Histogram)
    );
    // Inverted: WM darkest (1 - 0.861), GM (1 - 0.669), CSF brightest (1 - 0.259); the masked
    // zeros become a spike at the top, which is not tissue.
    let mut inverted = [0u32; BINS];
    for (b, &c) in MNI152_HIST.iter().enumerate() {
        inverted[BINS - 1 - b] = c;
    }
    let r = analysis::analyze(&inverted, 0.0, 255.0, n as usize, 0);
    assert_eq!(
        (r.contrast.contrast, r.contrast.basis),
        (Contrast::T2, ContrastBasis::Histogram),
        "{}",
        r.contrast.reason
    );
    let near = |p: Option<Peak>, want: f64| p.is_some_and(|p| (p.norm - want).abs() < 0.01);
    assert!(
        near(r.peaks.wm, 1.0 - 0.861)
            && near(r.peaks.gm, 1.0 - 0.669)
            && near(r.peaks.csf, 1.0 - 0.259),
        "{:?}",
        r.peaks
    );
}

// ---------------------------------------------------------------------------------------------
// The command line.

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

fn t2_file() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-contrast-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A name without contrast words: the histogram decides (a name with T2 in it would be
    // metadata, tests/modality.rs).
    let path = dir.join("phantom48.nii");
    let (mut volume, _) = t2_phantom(48);
    // The writer puts the name in `descrip`, whose words are metadata too.
    volume.name = "phantom48".into();
    morphray::volume::nifti::write_nifti1(&volume, &path, false).unwrap();
    path
}

#[test]
fn peaks_json_and_text_report_the_contrast_and_render_says_it_once() {
    let path = t2_file();
    let input = path.to_str().unwrap();
    let json = |extra: &[&str]| -> serde_json::Value {
        let mut args = extra.to_vec();
        args.extend(["peaks", input, "--json"]);
        let o = morphray(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).unwrap()
    };
    let v = json(&[]);
    assert_eq!(v["contrast"]["contrast"], "t2", "{}", v["contrast"]);
    assert_eq!(v["contrast"]["basis"], "histogram");
    assert!(v["contrast"]["reason"].as_str().unwrap().contains("T2"));
    assert_eq!(v["paper_windows_contrast"], "t1");
    let forced = json(&["--contrast", "t1"]);
    assert_eq!(forced["contrast"]["contrast"], "t1");
    assert_eq!(forced["contrast"]["basis"], "given");

    let o = morphray(&["peaks", input]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("contrast T2 (histogram)"), "{text}");
    assert!(text.contains("paper window (T1)"), "{text}");
    assert!(text.contains("n/a: T1 window, T2 volume"), "{text}");

    // render: exactly one contrast note, which warns about the paper's T1 windows.
    let png = path.with_file_name("t2.png");
    let o = morphray(&[
        "render",
        input,
        "-o",
        png.to_str().unwrap(),
        "--size",
        "32x32",
        "--windows",
        "paper",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let notes: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("T2 (histogram)"))
        .collect();
    assert_eq!(notes.len(), 1, "{err}");
    assert!(
        notes[0].starts_with("morphray: note: ") && notes[0].contains("T1 windows"),
        "{err}"
    );
    if let Some(dir) = path.parent() {
        let _ = std::fs::remove_dir_all(dir);
    }
}
