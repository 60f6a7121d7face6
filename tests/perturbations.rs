//! The perturbation study (issue 11, item 2) in small: the built-in phantom (64^3, Rician noise)
//! with its GM, WM and CSF labels as tissue masks, the original and five scanner perturbations
//! (src/study/perturb.rs), each run through the real GPU path (lavapipe in CI) under both
//! normalization modes, and the perturbations themselves checked.
//!
//! The full-size study on the MNI152 template is tools/examples/perturbation_study.rs
//! (ACCURACY.md, "Peaks under scanner perturbations").

mod common;

use morphray::analysis::NormalizeMode;
use morphray::engine::EngineConfig;
use morphray::gpu::{DeviceConfig, Validation};
use morphray::study::perturb::{
    Label, PerturbationKind, Perturbed, build_all, hot_voxel_indices, physical,
};
use morphray::study::perturb_run::{StudyReport, markdown, run_study};
use morphray::volume::Volume;
use morphray::volume::phantom::{PhantomSpec, Tissue, generate};

fn phantom_volumes() -> (Volume, Vec<Label>, Vec<Perturbed>) {
    let phantom = generate(&PhantomSpec::cube(64)).unwrap();
    let labels: Vec<Label> = phantom
        .labels
        .iter()
        .map(|&l| match Tissue::from_label(l) {
            Some(Tissue::Background) | None => Label::Outside,
            Some(Tissue::Csf) => Label::Csf,
            Some(Tissue::Gm) => Label::Gm,
            Some(Tissue::Wm) => Label::Wm,
            Some(_) => Label::Head,
        })
        .collect();
    let volumes = build_all(&phantom.volume, &labels).unwrap();
    (phantom.volume, labels, volumes)
}

fn of(volumes: &[Perturbed], kind: PerturbationKind) -> &Perturbed {
    volumes.iter().find(|p| p.kind == kind).unwrap()
}

fn world(v: &Volume, idx: [usize; 3]) -> [f64; 3] {
    let a = &v.orientation.affine;
    let p = idx.map(|x| x as f64);
    [0, 1, 2].map(|r| a[r][0] * p[0] + a[r][1] * p[1] + a[r][2] * p[2] + a[r][3])
}

#[test]
fn thick_lps_slices_hold_the_mean_of_the_thin_slices_at_the_same_world_position() {
    let (original, labels, volumes) = phantom_volumes();
    let thick = of(&volumes, PerturbationKind::ThickLps);
    assert_eq!(thick.volume.dims, [64, 64, 21]);
    assert_eq!(thick.volume.spacing_mm, [1.0, 1.0, 3.0]);
    let a = &original.orientation.affine;
    // The phantom's affine is diagonal (RAS), the thick one's stores i and j reversed (LPS).
    assert!(a[0][0] > 0.0 && a[1][1] > 0.0);
    let t = &thick.volume.orientation.affine;
    assert!(t[0][0] < 0.0 && t[1][1] < 0.0 && t[2][2] > 0.0);
    let (thin, thick_values) = (physical(&original), physical(&thick.volume));
    let mut wm_voxels = 0;
    for k in 0..21 {
        for j in 0..64 {
            for i in 0..64 {
                // The thin voxel at the same world position (diagonal affine: invert per axis).
                let w = world(&thick.volume, [i, j, k]);
                let idx = [0, 1, 2].map(|r| (w[r] - a[r][3]) / a[r][r]);
                assert!(idx.iter().all(|x| (x - x.round()).abs() < 1e-9), "{idx:?}");
                let [ti, tj, tk] = idx.map(|x| x.round() as usize);
                assert_eq!(tk, 3 * k + 1, "a thick slice sits at its middle thin slice");
                let at = |kk: usize| ti + 64 * (tj + 64 * kk);
                let mean = (thin[at(tk - 1)] + thin[at(tk)] + thin[at(tk + 1)]) / 3.0;
                let got = thick_values[i + 64 * (j + 64 * k)];
                assert!(
                    (got - mean).abs() < 1e-3,
                    "({i}, {j}, {k}): {got} vs {mean}"
                );
                let thin_labels = [at(tk - 1), at(tk), at(tk + 1)].map(|x| labels[x]);
                if thick.labels[i + 64 * (j + 64 * k)] == Label::Wm {
                    assert!(thin_labels.iter().filter(|&&l| l == Label::Wm).count() >= 2);
                    wm_voxels += 1;
                }
            }
        }
    }
    assert!(wm_voxels > 1000, "{wm_voxels} thick WM voxels");
}

#[test]
fn the_other_perturbations_store_what_they_say() {
    let (original, labels, volumes) = phantom_volumes();
    let orig = physical(&original);
    let head_max = orig
        .iter()
        .zip(&labels)
        .filter(|(_, l)| l.in_head())
        .map(|(v, _)| *v)
        .fold(f64::MIN, f64::max);

    let hot = physical(&of(&volumes, PerturbationKind::HotVoxels).volume);
    let found = hot_voxel_indices(&hot);
    assert_eq!(found.len(), 8, "eight hot voxels");
    for &i in &found {
        assert!(labels[i].in_head());
        assert!(
            (19.0 * head_max..=41.0 * head_max).contains(&hot[i]),
            "{}",
            hot[i]
        );
    }

    let negative = of(&volumes, PerturbationKind::FloatNegative);
    assert!(
        negative.volume.to_physical.slope != 1.0 && negative.volume.to_physical.intercept < 0.0
    );
    assert!(physical(&negative.volume).iter().all(|&v| v < 0.0));

    let scaled = of(&volumes, PerturbationKind::ScaleOffset);
    assert_eq!(
        scaled.volume.samples.kind(),
        morphray::volume::SampleKind::I16
    );
    let s = physical(&scaled.volume);
    let tolerance = scaled.volume.to_physical.slope;
    assert!(
        orig.iter()
            .zip(&s)
            .all(|(a, b)| (3.2 * a + 150.0 - b).abs() <= tolerance)
    );

    // Rician noise on a +-15 % bias: air becomes a positive floor, WM spreads.
    let biased = physical(&of(&volumes, PerturbationKind::BiasRician).volume);
    let air = biased
        .iter()
        .zip(&labels)
        .filter(|(_, l)| **l == Label::Outside)
        .map(|(v, _)| *v);
    let (count, sum) = air.fold((0usize, 0.0), |(n, s), v| (n + 1, s + v));
    assert!(sum / count as f64 > 5.0, "mean air {}", sum / count as f64);
}

fn study() -> StudyReport {
    let (_, _, volumes) = phantom_volumes();
    let base = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        ..Default::default()
    };
    run_study(
        "phantom 64^3",
        &volumes,
        &[NormalizeMode::MinMax, NormalizeMode::Robust],
        &base,
    )
    .unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        )
    })
}

#[test]
fn peaks_survive_the_perturbations_on_the_gpu_path() {
    let report = study();
    let table = markdown(&report);
    println!("{table}");
    assert_eq!(report.rows.len(), 12);
    for t in &report.totals {
        assert_eq!(t.totals.volumes, 6);
    }
    // Minmax: every perturbation but the hot voxels keeps all three peaks inside their truth
    // (the hot voxels squeeze the tissue into the first bins). Robust (the range a handful of
    // hot voxels cannot move): every perturbation, so the target holds.
    for row in &report.rows {
        let s = &row.score;
        let all = s.csf.inside && s.gm.inside && s.wm.inside;
        if row.mode == NormalizeMode::Robust || row.volume != "hot_voxels" {
            assert!(all, "{} under {}:\n{table}", row.volume, row.mode.name());
        }
    }
    for t in &report.totals {
        assert_eq!(
            t.target_met,
            t.mode == NormalizeMode::Robust,
            "{}:\n{table}",
            t.mode.name()
        );
    }
}

/// A skull-stripped brain: a ball of WM inside a GM shell with a small CSF ventricle, exact 0
/// outside, and the ball's outer layer (every voxel touching the outside) a dark partial-volume
/// value, as thick slices through a stripped brain make it (the MNI152 study's `thick_lps`).
/// Deterministic noise of +-6 keeps the modes realistic.
fn masked_brain_with_a_dark_edge() -> Volume {
    let n = 40usize;
    let c = (n as f64 - 1.0) / 2.0;
    let r = |i: usize, j: usize, k: usize| {
        let d = [i, j, k].map(|x| x as f64 - c);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    };
    let inside = |i: usize, j: usize, k: usize| r(i, j, k) < 17.0;
    let mut values = vec![0.0f32; n * n * n];
    for k in 1..n - 1 {
        for j in 1..n - 1 {
            for i in 1..n - 1 {
                if !inside(i, j, k) {
                    continue;
                }
                let edge = !(inside(i - 1, j, k)
                    && inside(i + 1, j, k)
                    && inside(i, j - 1, k)
                    && inside(i, j + 1, k)
                    && inside(i, j, k - 1)
                    && inside(i, j, k + 1));
                let d = r(i, j, k);
                let tissue = if edge {
                    40.0
                } else if d < 4.0 {
                    75.0
                } else if d < 10.0 {
                    200.0
                } else {
                    150.0
                };
                let at = i + n * (j + n * k);
                let noise = ((at.wrapping_mul(2654435761) >> 7) % 13) as f32 - 6.0;
                values[at] = tissue + noise;
            }
        }
    }
    let mut affine = [[0.0; 4]; 4];
    (0..4).for_each(|i| affine[i][i] = 1.0);
    Volume::from_voxels(
        "masked_T1w.nii",
        [n; 3],
        morphray::volume::Samples::from_f32(&values),
        affine,
        morphray::volume::LinearMap::IDENTITY,
    )
    .unwrap()
}

#[test]
fn a_masked_volumes_edge_is_not_taken_for_csf() {
    let volume = masked_brain_with_a_dark_edge();
    if let Ok(path) = std::env::var("MORPHRAY_WRITE_MASKED_BRAIN") {
        morphray::volume::nifti::write_new_nifti1(&volume, std::path::Path::new(&path), false)
            .unwrap();
    }
    let mut engine = morphray::engine::Engine::new(EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        ..Default::default()
    })
    .unwrap_or_else(|e| panic!("this test needs a Vulkan device with the validation layer: {e}"));
    let mut prepared = engine.prepare(&volume).unwrap();
    let before = engine.analyze(&prepared);
    prepared.leave_out_mask_edge(&volume);
    let after = engine.analyze(&prepared);
    let csf = |r: &morphray::analysis::TissueReport| r.peaks.csf.map(|p| p.raw);
    // The edge layer (about 3000 voxels at 40) outnumbers the ventricle (about 250 at 75): with
    // it the darkest mode is the edge, without it the ventricle.
    assert!(
        csf(&before).is_some_and(|p| p < 55.0),
        "with the edge: {:?} {:?}",
        csf(&before),
        before.modes
    );
    assert!(
        csf(&after).is_some_and(|p| (65.0..85.0).contains(&p)),
        "without the edge: {:?} {:?}",
        csf(&after),
        after.modes
    );
    assert!(
        prepared.mask_edge_voxels > 2000,
        "{}",
        prepared.mask_edge_voxels
    );
    let gm = after.peaks.gm.map(|p| p.raw);
    let wm = after.peaks.wm.map(|p| p.raw);
    assert!(gm.is_some_and(|p| (140.0..160.0).contains(&p)), "{gm:?}");
    assert!(wm.is_some_and(|p| (190.0..210.0).contains(&p)), "{wm:?}");
}
