//! The head phantom (src/volume/phantom_head.rs) and the phantom's contrasts
//! (src/volume/phantom_contrast.rs): determinism, every head tissue present, per-label medians
//! ordered as each contrast promises, layer thicknesses in mm, the true brain mask, the plain
//! phantom unchanged, and `morphray phantom --head --contrast`.

use morphray::volume::phantom::{Phantom, PhantomSpec, Tissue, generate, generate_with_threads};
use morphray::volume::phantom_contrast::Contrast;
use morphray::volume::phantom_head::{
    Anatomy, DIPLOE_MM, FAT_MM, INNER_TABLE_MM, Layers, MUSCLE_MM, OUTER_TABLE_MM, SKIN_MM,
    foramen_k, head_phantom, head_volume,
};

const SMALL: [usize; 3] = [48, 56, 44];
const ODD: [usize; 3] = [45, 53, 41];

/// FNV-1a 64 over the samples and then the labels.
fn checksum(p: &Phantom) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in p.volume.samples.as_bytes().iter().chain(&p.labels) {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fn ijk(index: usize, dims: [usize; 3]) -> [usize; 3] {
    [
        index % dims[0],
        (index / dims[0]) % dims[1],
        index / (dims[0] * dims[1]),
    ]
}

fn at(p: &Phantom, [i, j, k]: [usize; 3]) -> Tissue {
    let [nx, ny, _] = p.volume.dims;
    p.tissue(i + nx * (j + ny * k)).unwrap()
}

/// Median stored value of each label (None where the label is absent).
fn medians(p: &Phantom) -> Vec<Option<f64>> {
    let v = p.volume.samples.to_f64_vec();
    Tissue::ALL
        .iter()
        .map(|&t| {
            let mut xs: Vec<f64> = v
                .iter()
                .zip(&p.labels)
                .filter(|(_, l)| **l == t as u8)
                .map(|(x, _)| *x)
                .collect();
            xs.sort_by(f64::total_cmp);
            (!xs.is_empty()).then(|| xs[xs.len() / 2])
        })
        .collect()
}

#[test]
fn head_is_deterministic_across_runs_and_thread_counts() {
    for contrast in [Contrast::T1, Contrast::Ct] {
        let spec = PhantomSpec::head(ODD, contrast, true);
        let one = generate_with_threads(&spec, 1).unwrap();
        for threads in [3, 16] {
            let p = generate_with_threads(&spec, threads).unwrap();
            assert_eq!(p.volume.samples, one.volume.samples, "{threads} threads");
            assert_eq!(p.labels, one.labels, "{threads} threads");
        }
        assert_eq!(checksum(&generate(&spec).unwrap()), checksum(&one));
        // The contrast changes intensities only, never the anatomy.
        let t2 = generate(&PhantomSpec::head(ODD, Contrast::T2, true)).unwrap();
        assert_eq!(t2.labels, one.labels);
        assert_ne!(t2.volume.samples, one.volume.samples);
    }
    // Stored checksum: the head's bytes must not change silently.
    let p = generate(&PhantomSpec::head(ODD, Contrast::T2, true)).unwrap();
    assert_eq!(checksum(&p), HEAD_T2_CHECKSUM, "got {:#018x}", checksum(&p));
}

const HEAD_T2_CHECKSUM: u64 = 0xb64e_eadd_1809_20b1;

#[test]
fn the_plain_phantom_is_unchanged_by_contrasts_and_heads() {
    // tests/phantom.rs pins the same checksum; here with the new fields spelled out.
    let spec = PhantomSpec {
        dims: [40, 36, 30],
        anatomy: Anatomy::Shell,
        contrast: Contrast::T1,
        ..PhantomSpec::cube(1)
    };
    let p = generate_with_threads(&spec, 1).unwrap();
    assert_eq!(checksum(&p), 0x83cc_1f40_9645_3476);
    assert!(p.labels.iter().all(|&l| l <= Tissue::Edema as u8));
}

#[test]
fn every_head_tissue_is_present_and_the_shell_is_gone() {
    for dims in [SMALL, ODD] {
        let p = head_phantom(dims, Contrast::T1, false).unwrap();
        let mut count = [0usize; Tissue::ALL.len()];
        for &l in &p.labels {
            count[usize::from(l)] += 1;
        }
        eprintln!(
            "{dims:?}: {:?}",
            Tissue::ALL
                .iter()
                .map(|t| (t.name(), count[*t as usize]))
                .collect::<Vec<_>>()
        );
        assert_eq!(count[Tissue::SkullFat as usize], 0);
        for t in Tissue::ALL.iter().filter(|t| **t != Tissue::SkullFat) {
            assert!(count[*t as usize] > 0, "{dims:?}: no {}", t.name());
        }
        // The head fits: nothing but air on every face of the volume except the bottom,
        // where the neck leaves the field of view.
        let [nx, ny, nz] = dims;
        for (index, &l) in p.labels.iter().enumerate() {
            let [i, j, k] = ijk(index, dims);
            let edge = i == 0 || i == nx - 1 || j == 0 || j == ny - 1 || k == nz - 1;
            if edge && k > 0 {
                assert_eq!(
                    l,
                    0,
                    "{dims:?}: {:?} at {:?}",
                    Tissue::from_label(l),
                    [i, j, k]
                );
            }
        }
        let bottom: Vec<u8> = p.labels[..nx * ny].to_vec();
        for t in [Tissue::Skin, Tissue::Muscle, Tissue::Cord, Tissue::Bone] {
            assert!(
                bottom.contains(&(t as u8)),
                "{dims:?}: no {} at the bottom",
                t.name()
            );
        }
    }
}

#[test]
fn the_scalp_anatomy_has_the_layers_without_eyes_or_neck() {
    let spec = PhantomSpec {
        dims: ODD,
        anatomy: Anatomy::Scalp,
        ..PhantomSpec::cube(1)
    };
    let p = generate(&spec).unwrap();
    let has = |t: Tissue| p.labels.contains(&(t as u8));
    for t in [
        Tissue::Skin,
        Tissue::Fat,
        Tissue::Muscle,
        Tissue::Bone,
        Tissue::Marrow,
    ] {
        assert!(has(t), "no {}", t.name());
    }
    for t in [Tissue::Eye, Tissue::Cord, Tissue::SkullFat] {
        assert!(!has(t), "{} in the scalp-only head", t.name());
    }
    // Without a neck, the truth is every intracranial label.
    let truth = p.brain_mask();
    let intracranial = p.labels.iter().filter(|&&l| (2..=7).contains(&l)).count();
    assert_eq!(truth.iter().filter(|&&b| b).count(), intracranial);
}

#[test]
fn eyes_are_two_globes_in_front_below_the_brain_centre() {
    let p = head_phantom(SMALL, Contrast::T1, false).unwrap();
    let centre = SMALL.map(|n| (n as f64 - 1.0) / 2.0);
    let (mut left, mut right) = (0, 0);
    for (index, &l) in p.labels.iter().enumerate() {
        if l == Tissue::Eye as u8 {
            let c = ijk(index, SMALL);
            assert!(c[1] as f64 > centre[1] + 8.0, "eye at {c:?}");
            assert!((c[2] as f64) < centre[2], "eye at {c:?}");
            if (c[0] as f64) < centre[0] {
                left += 1;
            } else {
                right += 1;
            }
        }
    }
    assert!(left > 10 && left == right, "{left} {right}");
}

/// Runs of labels from the volume's edge in to the centre along axis `axis` (direction
/// `sign`), through the centre voxel of odd `dims`: (tissue, voxels), outermost first.
fn runs_inward(p: &Phantom, axis: usize, sign: i64) -> Vec<(Tissue, usize)> {
    let dims = p.volume.dims;
    let c = dims.map(|n| (n - 1) / 2);
    let mut out: Vec<(Tissue, usize)> = Vec::new();
    let steps = if sign > 0 {
        dims[axis] - 1 - c[axis]
    } else {
        c[axis]
    };
    for s in (0..=steps).rev() {
        let mut x = c;
        x[axis] = (c[axis] as i64 + sign * s as i64) as usize;
        let t = at(p, x);
        match out.last_mut() {
            Some((last, n)) if *last == t => *n += 1,
            _ => out.push((t, 1)),
        }
    }
    out
}

#[test]
fn layer_thicknesses_match_their_mm_at_two_sizes() {
    for dims in [[113, 113, 97], [161, 151, 131]] {
        let p = head_phantom(dims, Contrast::T1, false).unwrap();
        let l = Layers::of(dims);
        let s = l.voxels_per_mm;
        assert!(s >= 0.5, "{dims:?}: floors would bind at {s} voxels/mm");
        // Side (+x, muscle) and top (+z, no muscle) of the head.
        for (axis, expected) in [
            (
                0,
                vec![
                    (Tissue::Skin, SKIN_MM.0),
                    (Tissue::Fat, FAT_MM.0),
                    (Tissue::Muscle, MUSCLE_MM.0),
                    (Tissue::Bone, OUTER_TABLE_MM.0),
                    (Tissue::Marrow, DIPLOE_MM.0),
                    (Tissue::Bone, INNER_TABLE_MM.0),
                ],
            ),
            (
                2,
                vec![
                    (Tissue::Skin, SKIN_MM.0),
                    (Tissue::Fat, FAT_MM.0),
                    (Tissue::Bone, OUTER_TABLE_MM.0),
                    (Tissue::Marrow, DIPLOE_MM.0),
                    (Tissue::Bone, INNER_TABLE_MM.0),
                ],
            ),
        ] {
            let runs = runs_inward(&p, axis, 1);
            eprintln!("{dims:?} axis {axis}: {runs:?}");
            assert_eq!(runs[0].0, Tissue::Background);
            let got = &runs[1..=expected.len()];
            for ((t, n), (want, mm)) in got.iter().zip(&expected) {
                assert_eq!(t, want, "{dims:?} axis {axis}: {runs:?}");
                let measured = *n as f64 / s;
                // Voxel centres sample each layer: within one voxel of its thickness.
                assert!(
                    (measured - mm).abs() < 1.0 / s,
                    "{dims:?} axis {axis} {}: {measured:.2} mm vs {mm} mm",
                    t.name()
                );
            }
            // The whole skull, 7 mm, within one voxel.
            let skull: usize = got[got.len() - 3..].iter().map(|r| r.1).sum();
            assert!(
                (skull as f64 / s - 7.0).abs() < 1.0 / s,
                "{dims:?}: skull {skull}"
            );
            // Then the subarachnoid space (the superior sagittal sinus lies in it on top).
            let inside = runs[expected.len() + 1].0;
            assert!(matches!(inside, Tissue::Csf | Tissue::Vessel), "{runs:?}");
        }
    }
}

#[test]
fn each_contrast_orders_its_tissues_as_promised() {
    use Tissue::*;
    for dims in [SMALL, ODD] {
        for contrast in Contrast::ALL {
            let p = head_phantom(dims, contrast, true).unwrap();
            let m = medians(&p);
            let med = |t: Tissue| m[t as usize].unwrap();
            eprintln!(
                "{dims:?} {}: {:?}",
                contrast.name(),
                Tissue::ALL
                    .iter()
                    .filter_map(|t| m[*t as usize].map(|x| (t.name(), x)))
                    .collect::<Vec<_>>()
            );
            let order = |tissues: &[Tissue]| {
                for w in tissues.windows(2) {
                    assert!(
                        med(w[0]) > med(w[1]),
                        "{dims:?} {}: {} {} <= {} {}",
                        contrast.name(),
                        w[0].name(),
                        med(w[0]),
                        w[1].name(),
                        med(w[1])
                    );
                }
            };
            let near = |a: Tissue, b: Tissue, frac: f64| {
                assert!(
                    (med(a) - med(b)).abs() <= frac * med(b).abs(),
                    "{dims:?} {}: {} {} vs {} {}",
                    contrast.name(),
                    a.name(),
                    med(a),
                    b.name(),
                    med(b)
                );
            };
            match contrast {
                Contrast::T1 => {
                    order(&[Fat, Wm, Gm, Csf, Bone]);
                    order(&[Marrow, Wm]);
                    near(Muscle, Gm, 0.15);
                    near(Cord, Wm, 0.1);
                    near(Eye, Csf, 0.2);
                }
                Contrast::T2 => {
                    order(&[Csf, Lesion, Gm, Wm, Muscle, Bone]);
                    order(&[Fat, Gm]);
                    // CSF-like (the thin CSF layers lose more to partial volume).
                    near(Eye, Csf, 0.15);
                }
                Contrast::Pd => {
                    order(&[Csf, Gm, Wm, Bone]);
                    assert!(med(Csf) - med(Wm) < 0.35 * med(Csf));
                }
                Contrast::Flair => {
                    order(&[Lesion, Edema, Gm, Wm, Csf]);
                    assert!(med(Csf) < med(Wm) / 2.0);
                }
                Contrast::Ct => {
                    order(&[Bone, Marrow, Gm, Wm, Edema, Csf, Fat, Background]);
                    assert!((med(Background) + 1000.0).abs() <= 2.0);
                    assert!(med(Fat) < 0.0);
                }
            }
        }
    }
}

#[test]
fn ct_noise_is_additive_without_a_floor() {
    let v = head_volume(SMALL, Contrast::Ct, true).unwrap();
    let p = head_phantom(SMALL, Contrast::Ct, true).unwrap();
    assert_eq!(v.samples, p.volume.samples);
    // Air far from the head: the volume's faces but the bottom (the neck leaves there).
    let dims = SMALL;
    let values = p.volume.samples.to_f64_vec();
    let air: Vec<f64> = (0..values.len())
        .filter(|&i| {
            let [x, y, z] = ijk(i, dims);
            z == dims[2] - 1 || y == 0 || y == dims[1] - 1 || x == 0 || x == dims[0] - 1
        })
        .filter(|&i| ijk(i, dims)[2] > 0)
        .map(|i| values[i])
        .collect();
    let mean = air.iter().sum::<f64>() / air.len() as f64;
    let sd = (air.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / air.len() as f64).sqrt();
    // Gaussian about -1000 (a Rician floor would shift the mean up and skew it).
    assert!((mean + 1000.0).abs() < 0.2, "{mean}");
    assert!((sd - 4.0).abs() < 0.2, "{sd}");
    assert!(air.iter().any(|&x| x < -1000.0) && air.iter().any(|&x| x > -1000.0));
}

#[test]
fn brain_truth_is_the_intracranial_space_only() {
    for dims in [SMALL, ODD] {
        let p = head_phantom(dims, Contrast::T1, false).unwrap();
        let truth = p.brain_mask();
        assert_eq!(truth.len(), p.labels.len());
        let n = truth.iter().filter(|&&b| b).count();
        assert!(n > 2000, "{dims:?}: {n}");
        let fk = foramen_k(dims);
        let [nx, ny, _] = dims;
        let stride = [1, nx, nx * ny];
        for (index, _) in truth.iter().enumerate().filter(|(_, b)| **b) {
            let c = ijk(index, dims);
            let l = p.tissue(index).unwrap();
            assert!(
                matches!(
                    l,
                    Tissue::Csf
                        | Tissue::Gm
                        | Tissue::Wm
                        | Tissue::Lesion
                        | Tissue::Vessel
                        | Tissue::Edema
                ),
                "{dims:?}: {} in the truth at {c:?}",
                l.name()
            );
            assert!(
                c[2] as f64 >= fk - 1.0,
                "{dims:?}: truth below the foramen at {c:?}"
            );
            // Contained in the skull: walking out along +-x, +-y and +z, bone comes before any
            // scalp, face, eye or air (down, the foramen magnum opens onto the canal).
            for (axis, sign) in [(0, 1i64), (0, -1), (1, 1), (1, -1), (2, 1)] {
                let mut x = c;
                loop {
                    let next = x[axis] as i64 + sign;
                    assert!(
                        next >= 0 && (next as usize) < dims[axis],
                        "{dims:?}: left the volume from {c:?}"
                    );
                    x[axis] = next as usize;
                    let t = p.tissue(x[0] * stride[0] + x[1] * stride[1] + x[2] * stride[2]);
                    match t.unwrap() {
                        Tissue::Bone => break,
                        Tissue::Csf
                        | Tissue::Gm
                        | Tissue::Wm
                        | Tissue::Lesion
                        | Tissue::Vessel
                        | Tissue::Edema => {}
                        other => panic!(
                            "{dims:?}: {} before bone from {c:?} along {axis}{sign:+}",
                            other.name()
                        ),
                    }
                }
            }
        }
        // The cord and the canal below the foramen are not brain, but they touch it: the
        // bridge a brain extractor must cut. Along the canal's axis, WM/cord signal runs
        // without a gap from the bottom of the volume up into the brain.
        let c = dims.map(|n| (n - 1) / 2);
        let axis_j = (0..ny)
            .find(|&j| at(&p, [c[0], j, 0]) == Tissue::Cord)
            .expect("the cord reaches the bottom");
        let mut k = 0;
        while matches!(at(&p, [c[0], axis_j, k]), Tissue::Cord) {
            k += 1;
        }
        assert!(
            (k as f64 - fk).abs() <= 1.0,
            "{dims:?}: cord ends at {k}, foramen {fk}"
        );
        assert_eq!(
            at(&p, [c[0], axis_j, k]),
            Tissue::Wm,
            "{dims:?}: brainstem at {k}"
        );
        assert!(truth[c[0] + nx * (axis_j + ny * k)]);
        assert!(!truth[c[0] + nx * (axis_j + ny * (k - 1))]);
    }
}

#[test]
fn cli_writes_a_head_in_the_contrast_asked() {
    let dir = std::env::temp_dir().join(format!("morphray-phantom-head-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("sub-01_T2w.nii.gz");
    let labels = dir.join("labels.nii.gz");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args([
            "phantom",
            "--head",
            "--contrast",
            "t2",
            "--dims",
            "45x53x41",
            "-o",
        ])
        .arg(&out)
        .arg("--labels")
        .arg(&labels)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("45x53x41") && stdout.contains("head, T2w"),
        "{stdout}"
    );
    use morphray::volume::nifti::{LoadOptions, load_path};
    let read = load_path(&out, &LoadOptions::default()).unwrap().volume;
    assert_eq!(read.dims, ODD);
    let expected = head_volume(ODD, Contrast::T2, true).unwrap();
    assert_eq!(read.samples, expected.samples);
    let read_labels = load_path(&labels, &LoadOptions::default()).unwrap().volume;
    let expected = head_phantom(ODD, Contrast::T2, true).unwrap().labels;
    assert_eq!(
        read_labels.samples.to_f64_vec(),
        expected.iter().map(|&l| f64::from(l)).collect::<Vec<_>>()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn analysis_commands_refuse_the_phantom_only_contrasts() {
    // ct names a phantom contrast; a CT file's is its modality (`--modality ct`), so tissue
    // analysis says so in one line before any file or GPU work.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(["peaks", "no-such-file.nii", "--contrast", "ct"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("--contrast ct is only for `morphray phantom`"),
        "{err}"
    );
}
