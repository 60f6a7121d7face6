//! The built-in phantom: tissues present, intensities where documented, left lesion,
//! determinism, and a histogram with CSF / GM / WM modes.

use morphray::volume::phantom::{
    NOMINAL, Phantom, PhantomError, PhantomSpec, Tissue, generate, generate_with_threads,
};
use morphray::volume::{AffineSource, SampleKind};

fn small_specs() -> [PhantomSpec; 2] {
    [
        PhantomSpec::cube(64),
        PhantomSpec {
            dims: [72, 60, 48],
            ..PhantomSpec::cube(1)
        },
    ]
}

fn values(p: &Phantom) -> Vec<f64> {
    p.volume.samples.to_f64_vec()
}

/// Per tissue: (count, mean, min, max) of the stored values.
fn per_tissue(p: &Phantom) -> Vec<(Tissue, usize, f64, f64, f64)> {
    let v = values(p);
    Tissue::ALL
        .iter()
        .map(|&t| {
            let xs: Vec<f64> = v
                .iter()
                .zip(&p.labels)
                .filter(|(_, l)| **l == t as u8)
                .map(|(x, _)| *x)
                .collect();
            let n = xs.len();
            let mean = xs.iter().sum::<f64>() / n.max(1) as f64;
            let min = xs.iter().copied().fold(f64::INFINITY, f64::min);
            let max = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (t, n, mean, min, max)
        })
        .collect()
}

fn stat(p: &Phantom, t: Tissue) -> (usize, f64, f64, f64) {
    let s = per_tissue(p);
    let (_, n, mean, min, max) = s[t as usize];
    (n, mean, min, max)
}

#[test]
fn cohort_a_spec_is_the_papers_size() {
    let spec = PhantomSpec::cohort_a();
    assert_eq!(spec.dims, [256, 256, 192]);
    assert_eq!(spec.dims.iter().product::<usize>(), 12_582_912);
    assert_eq!(spec.spacing_mm, [1.0; 3]);
    assert!(spec.noise);
}

#[test]
fn volume_metadata() {
    for spec in small_specs() {
        let p = generate(&spec).unwrap();
        let v = &p.volume;
        assert_eq!(v.name, "phantom");
        assert_eq!(v.dims, spec.dims);
        assert_eq!(v.samples.kind(), SampleKind::I16);
        assert_eq!(v.samples.len(), v.voxel_count());
        assert_eq!(p.labels.len(), v.voxel_count());
        assert_eq!(v.orientation.source, AffineSource::Synthetic);
        assert!(v.warnings.is_empty());
        // RAS+, spacing on the diagonal, world origin at the volume centre.
        let a = v.orientation.affine;
        for (axis, row) in a.iter().take(3).enumerate() {
            let mut expected = [0.0; 4];
            expected[axis] = spec.spacing_mm[axis];
            let centre = (spec.dims[axis] as f64 - 1.0) / 2.0;
            expected[3] = -centre * spec.spacing_mm[axis];
            assert_eq!(*row, expected);
            assert_eq!(row[axis] * centre + row[3], 0.0);
        }
        assert_eq!(a[3], [0.0, 0.0, 0.0, 1.0]);
        assert!(p.labels.iter().all(|&l| Tissue::from_label(l).is_some()));
    }
}

#[test]
fn anisotropic_spacing_only_changes_the_affine() {
    let iso = generate(&PhantomSpec::cube(24)).unwrap();
    let aniso = generate(&PhantomSpec {
        spacing_mm: [0.5, 1.0, 3.0],
        ..PhantomSpec::cube(24)
    })
    .unwrap();
    assert_eq!(iso.volume.samples, aniso.volume.samples);
    assert_eq!(aniso.volume.orientation.affine[2][2], 3.0);
    assert_eq!(aniso.volume.spacing_mm, [0.5, 1.0, 3.0]);
}

#[test]
fn every_tissue_is_present_with_a_sensible_count() {
    for spec in small_specs() {
        let p = generate(&spec).unwrap();
        let total = p.labels.len() as f64;
        let s = per_tissue(&p);
        let frac = |t: Tissue| s[t as usize].1 as f64 / total;
        let count = |t: Tissue| s[t as usize].1;
        eprintln!(
            "{:?}: {:?}",
            spec.dims,
            s.iter().map(|x| (x.0.name(), x.1)).collect::<Vec<_>>()
        );
        assert!(
            (0.45..0.85).contains(&frac(Tissue::Background)),
            "{}",
            frac(Tissue::Background)
        );
        assert!(
            (0.03..0.15).contains(&frac(Tissue::SkullFat)),
            "{}",
            frac(Tissue::SkullFat)
        );
        assert!(
            (0.02..0.10).contains(&frac(Tissue::Csf)),
            "{}",
            frac(Tissue::Csf)
        );
        assert!(
            (0.03..0.10).contains(&frac(Tissue::Gm)),
            "{}",
            frac(Tissue::Gm)
        );
        assert!(
            (0.02..0.10).contains(&frac(Tissue::Wm)),
            "{}",
            frac(Tissue::Wm)
        );
        // Enough voxels per brain class for a histogram mode (a few thousand at 64^3).
        for t in [Tissue::Csf, Tissue::Gm, Tissue::Wm] {
            assert!(count(t) > 4000, "{}: {}", t.name(), count(t));
        }
        assert!(
            (20..200).contains(&count(Tissue::Lesion)),
            "lesion {}",
            count(Tissue::Lesion)
        );
        // The edema shell (at least 2 voxels thick) outnumbers the lesion it wraps.
        assert!(
            count(Tissue::Edema) > 2 * count(Tissue::Lesion),
            "edema {}",
            count(Tissue::Edema)
        );
        assert!(
            (100..2000).contains(&count(Tissue::Vessel)),
            "vessels {}",
            count(Tissue::Vessel)
        );
    }
}

#[test]
fn intensities_follow_the_documented_nominal_values() {
    for spec in small_specs() {
        let p = generate(&spec).unwrap();
        assert_eq!(p.nominal, NOMINAL);
        let mean = |t: Tissue| stat(&p, t).1;
        let near = |t: Tissue, tol: f64| {
            let (m, n) = (mean(t), NOMINAL.of(t));
            assert!(
                (m - n).abs() <= tol * n,
                "{:?} {}: mean {m} vs nominal {n}",
                spec.dims,
                t.name()
            );
        };
        // Rician noise (sigma 20) lifts a dark mean (sqrt(80^2 + 20^2) = 82.5) and the shell's
        // inner voxels blend with CSF: 15 %.
        near(Tissue::SkullFat, 0.15);
        near(Tissue::Csf, 0.20); // partial volume with the thin sulci and the GM around them
        near(Tissue::Gm, 0.06);
        near(Tissue::Wm, 0.04);
        near(Tissue::Lesion, 0.10);
        near(Tissue::Edema, 0.06);
        assert!(mean(Tissue::Background) < 40.0, "Rayleigh noise floor ~25");
        // T1 order, with the dark shell below CSF and pathology above WM.
        assert!(mean(Tissue::Background) < mean(Tissue::SkullFat));
        assert!(mean(Tissue::SkullFat) < mean(Tissue::Csf));
        assert!(mean(Tissue::Csf) < mean(Tissue::Gm));
        assert!(mean(Tissue::Gm) < mean(Tissue::Wm));
        assert!(mean(Tissue::Wm) < mean(Tissue::Lesion));
        // Edema: T1-hypointense to WM, above GM (src/volume/phantom_edema.rs).
        assert!(mean(Tissue::Gm) < mean(Tissue::Edema) && mean(Tissue::Edema) < mean(Tissue::Wm));
        assert!(mean(Tissue::Wm) < mean(Tissue::Vessel));
        // Nothing but lesion and vessels reaches the pathology band; both do reach it.
        let v = values(&p);
        let brightest_other = v
            .iter()
            .zip(&p.labels)
            .filter(|(_, l)| **l != Tissue::Lesion as u8 && **l != Tissue::Vessel as u8)
            .map(|(x, _)| *x)
            .fold(f64::MIN, f64::max);
        assert!(
            brightest_other < 1250.0,
            "brightest non-pathology voxel {brightest_other}"
        );
        assert!(stat(&p, Tissue::Lesion).3 > 1300.0);
        assert!(stat(&p, Tissue::Vessel).3 > 1400.0);
        // The shell stays dark: almost all of it below the CSF nominal.
        let shell: Vec<f64> = v
            .iter()
            .zip(&p.labels)
            .filter(|(_, l)| **l == Tissue::SkullFat as u8)
            .map(|(x, _)| *x)
            .collect();
        let dark = shell.iter().filter(|&&x| x < NOMINAL.csf).count() as f64 / shell.len() as f64;
        assert!(
            dark > 0.97,
            "only {dark} of the shell is below the CSF nominal"
        );
    }
}

/// Per label, how many face neighbours of `tissue`'s voxels (outside it) carry that label.
fn outside_neighbours(p: &Phantom, dims: [usize; 3], tissue: Tissue) -> Vec<usize> {
    let [nx, ny, _] = dims;
    let mut neighbours = vec![0usize; Tissue::ALL.len()];
    for (index, &l) in p.labels.iter().enumerate() {
        if l != tissue as u8 {
            continue;
        }
        let ijk = [index % nx, (index / nx) % ny, index / (nx * ny)];
        for (a, stride) in [1, nx, nx * ny].into_iter().enumerate() {
            for step in [-1i64, 1] {
                let c = ijk[a] as i64 + step;
                if c >= 0 && (c as usize) < dims[a] {
                    let j = (index as i64 + step * stride as i64) as usize;
                    neighbours[p.labels[j] as usize] += 1;
                }
            }
        }
    }
    neighbours[tissue as usize] = 0;
    neighbours
}

#[test]
fn lesion_is_in_the_left_hemisphere_white_matter() {
    for spec in small_specs() {
        let p = generate(&spec).unwrap();
        let [nx, ny, _] = spec.dims;
        let (mut sum, mut n) = ([0.0; 3], 0.0);
        for (index, &l) in p.labels.iter().enumerate() {
            if l == Tissue::Lesion as u8 {
                let ijk = [index % nx, (index / nx) % ny, index / (nx * ny)];
                for a in 0..3 {
                    sum[a] += ijk[a] as f64;
                }
                n += 1.0;
            }
        }
        let a = p.volume.orientation.affine;
        let world_x = a[0][0] * sum[0] / n + a[0][1] * sum[1] / n + a[0][2] * sum[2] / n + a[0][3];
        assert!(
            world_x < -5.0,
            "lesion centroid at world x = {world_x} mm, must be left (x < 0)"
        );
        // The lesion is wrapped in its edema, and the edema lies in WM (and around the lesion).
        let lesion = outside_neighbours(&p, spec.dims, Tissue::Lesion);
        let outside: usize = lesion.iter().sum();
        assert_eq!(
            outside,
            lesion[Tissue::Edema as usize],
            "lesion touches only edema: {lesion:?}"
        );
    }
    // The edema lies in WM once the lengths are not at their voxel floors: on the 64^3 and
    // 72x60x48 grids the floored lesion (2 voxels) and shell (2 voxels) reach the floored GM
    // ribbon and the ventricle, as the phantom's module doc says of its floors.
    let dims = [128, 128, 128];
    let p = generate(&PhantomSpec {
        dims,
        ..PhantomSpec::cube(1)
    })
    .unwrap();
    let edema = outside_neighbours(&p, dims, Tissue::Edema);
    let outside: usize = edema.iter().sum();
    assert_eq!(
        outside,
        edema[Tissue::Wm as usize] + edema[Tissue::Lesion as usize],
        "edema touches only WM and the lesion: {edema:?}"
    );
}

#[test]
fn boundaries_are_blended_over_about_one_voxel() {
    let p = generate(&PhantomSpec {
        noise: false,
        ..PhantomSpec::cube(64)
    })
    .unwrap();
    let v = values(&p);
    // Noise-free: air away from the head is exactly 0; air voxels touching the shell carry
    // less than half of its signal; partial-volume voxels sit between tissue values.
    let zeros = v.iter().filter(|&&x| x == 0.0).count();
    assert!(zeros as f64 > 0.4 * v.len() as f64, "{zeros}");
    assert!(stat(&p, Tissue::Background).3 <= (0.5 * NOMINAL.skull_fat * 1.07).ceil());
    let gm_wm_mix = v.iter().filter(|&&x| (680.0..770.0).contains(&x)).count();
    let csf_gm_mix = v.iter().filter(|&&x| (350.0..500.0).contains(&x)).count();
    assert!(
        gm_wm_mix > 500 && csf_gm_mix > 500,
        "{gm_wm_mix} {csf_gm_mix}"
    );
    // Blending is local: a GM voxel next to WM differs from it by less than the full contrast,
    // and along x the step between neighbours never exceeds one tissue jump.
    let [nx, _, _] = p.volume.dims;
    let max_step = v
        .windows(2)
        .enumerate()
        .filter(|(i, _)| (i + 1) % nx != 0)
        .map(|(_, w)| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    assert!(max_step < NOMINAL.vessel * 1.08, "{max_step}");
}

/// FNV-1a 64 over the samples and then the labels.
fn checksum(p: &Phantom) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in p.volume.samples.as_bytes().iter().chain(&p.labels) {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[test]
fn generation_is_deterministic_across_runs_and_thread_counts() {
    let spec = PhantomSpec {
        dims: [40, 36, 30],
        ..PhantomSpec::cube(1)
    };
    let reference = generate_with_threads(&spec, 1).unwrap();
    for threads in [2, 3, 7, 64] {
        let p = generate_with_threads(&spec, threads).unwrap();
        assert_eq!(
            p.volume.samples, reference.volume.samples,
            "{threads} threads"
        );
        assert_eq!(p.labels, reference.labels, "{threads} threads");
    }
    assert_eq!(checksum(&generate(&spec).unwrap()), checksum(&reference));
    // Stored checksum: the phantom's bytes must not change silently (geometry, intensities,
    // noise and rounding are all pure IEEE arithmetic, so this holds on every platform).
    assert_eq!(
        checksum(&reference),
        EXPECTED_CHECKSUM,
        "got {:#018x}",
        checksum(&reference)
    );
    // The seed changes the noise only.
    let other = generate(&PhantomSpec {
        seed: 7,
        ..spec.clone()
    })
    .unwrap();
    assert_eq!(other.labels, reference.labels);
    assert_ne!(other.volume.samples, reference.volume.samples);
}

// Changed with the known-radius vessels and the lesion's edema (issue 15 item 6).
const EXPECTED_CHECKSUM: u64 = 0x83cc_1f40_9645_3476;

#[test]
fn histogram_has_csf_gm_and_wm_modes_near_their_nominal_values() {
    for spec in small_specs() {
        let p = generate(&spec).unwrap();
        let v = values(&p);
        let (min, max) = v
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        let mut hist = [0usize; 256];
        for &x in &v {
            let t = (x - min) / (max - min);
            hist[((t * 256.0) as usize).min(255)] += 1;
        }
        assert_eq!(hist.iter().sum::<usize>(), v.len());
        // Light smoothing (5 bins), as a peak finder would do.
        let smooth: Vec<f64> = (0..256usize)
            .map(|i| {
                let (lo, hi) = (i.saturating_sub(2), (i + 2).min(255));
                hist[lo..=hi].iter().sum::<usize>() as f64 / (hi - lo + 1) as f64
            })
            .collect();
        let bin = |x: f64| (((x - min) / (max - min) * 256.0) as usize).min(255);
        let peak = |nominal: f64| {
            let (lo, hi) = (bin(nominal * 0.85), bin(nominal * 1.15));
            (lo..=hi)
                .max_by(|&a, &b| smooth[a].total_cmp(&smooth[b]))
                .unwrap()
        };
        let peaks = [peak(NOMINAL.csf), peak(NOMINAL.gm), peak(NOMINAL.wm)];
        for (&b, name) in peaks.iter().zip(["csf", "gm", "wm"]) {
            let local_max =
                (b.saturating_sub(4)..=(b + 4).min(255)).all(|j| smooth[j] <= smooth[b]);
            assert!(
                local_max,
                "{:?}: {name} peak at bin {b} is not a local maximum",
                spec.dims
            );
            let (lo, hi) = (b.saturating_sub(6), b + 6);
            assert!(smooth[b] > 0.0 && lo < b && hi > b);
        }
        for w in peaks.windows(2) {
            let valley = (w[0]..=w[1]).map(|j| smooth[j]).fold(f64::MAX, f64::min);
            let lower_peak = smooth[w[0]].min(smooth[w[1]]);
            assert!(
                valley < 0.5 * lower_peak,
                "{:?}: modes at bins {} and {} are not separated (valley {valley}, peaks {lower_peak})",
                spec.dims,
                w[0],
                w[1]
            );
        }
        // Each peak is within 8 % of its nominal intensity.
        for (&b, nominal) in peaks.iter().zip([NOMINAL.csf, NOMINAL.gm, NOMINAL.wm]) {
            let centre = min + (b as f64 + 0.5) * (max - min) / 256.0;
            assert!(
                (centre - nominal).abs() < 0.08 * nominal,
                "peak at {centre}, nominal {nominal}"
            );
        }
    }
}

#[test]
fn bad_specs_are_typed_errors() {
    let zero = PhantomSpec {
        dims: [0, 4, 4],
        ..PhantomSpec::cube(1)
    };
    assert!(matches!(generate(&zero), Err(PhantomError::BadSpec { .. })));
    let nan = PhantomSpec {
        spacing_mm: [1.0, f64::NAN, 1.0],
        ..PhantomSpec::cube(4)
    };
    assert!(matches!(generate(&nan), Err(PhantomError::BadSpec { .. })));
    let huge = PhantomSpec {
        dims: [usize::MAX / 2, 4, 4],
        ..PhantomSpec::cube(1)
    };
    let e = generate(&huge).unwrap_err();
    assert!(matches!(e, PhantomError::TooLarge { .. }), "{e}");
    // More than the machine has is refused before allocating (2048^3 used to be accepted on a
    // 24 GB machine, each of its two buffers alone being reservable, and the process was killed
    // while filling them), with the bytes it needs. Sized from this machine's memory so that
    // each buffer alone is below what is available and both together above it.
    let available = morphray::volume::host_memory::available_bytes()
        .expect("this test reads /proc/meminfo (Linux)");
    let planes = (available as f64 * 0.4 / (1u64 << 20) as f64).ceil() as usize;
    let absurd = PhantomSpec {
        dims: [1024, 1024, planes],
        ..PhantomSpec::cube(1)
    };
    let e = generate(&absurd).unwrap_err();
    let text = e.to_string();
    let needed = (3 * (planes as u64)) << 20;
    assert!(
        text.contains(&format!("needs {needed} bytes")) && text.contains("available"),
        "{text}"
    );
    // A 1-voxel phantom is valid.
    assert_eq!(generate(&PhantomSpec::cube(1)).unwrap().labels.len(), 1);
}

#[test]
fn the_known_vessels_have_their_radii() {
    use morphray::volume::phantom_vessels::KNOWN_VESSELS;
    // At 128^3 the phantom's mm is 0.583 voxel (smallest brain semi-axis 0.56 * 64 = 35.84
    // voxels, over 61.44 at cohort A): the 3 and 2 mm vessels are 1.75 and 1.17 voxels in
    // radius; the 1 and 0.5 mm ones are sub-voxel (module doc of phantom_vessels.rs).
    let n = 128usize;
    let p = generate(&PhantomSpec::cube(n)).unwrap();
    let brain = [0.56, 0.68, 0.64].map(|f| f * n as f64 / 2.0);
    let centre = (n as f64 - 1.0) / 2.0;
    let voxels_per_mm = 0.56 * 64.0 / 61.44;
    let mut areas = Vec::new();
    for k in KNOWN_VESSELS.iter().filter(|k| k.radius_mm >= 2.0) {
        let axis = match k.axis {
            "x" => 0,
            "y" => 1,
            _ => 2,
        };
        let mid: [f64; 3] =
            std::array::from_fn(|a| centre + (k.from[a] + k.to[a]) / 2.0 * brain[a]);
        // Vessel voxels in the cross-section through the middle, within 6 voxels of the line.
        let mut area = 0usize;
        for du in -6i64..=6 {
            for dv in -6i64..=6 {
                let mut ijk = mid.map(|m| m.round() as i64);
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                ijk[u] += du;
                ijk[v] += dv;
                let index = ijk[0] as usize + n * (ijk[1] as usize + n * ijk[2] as usize);
                area += usize::from(p.labels[index] == Tissue::Vessel as u8);
            }
        }
        let r = k.radius_mm * voxels_per_mm;
        let expected = std::f64::consts::PI * r * r;
        eprintln!(
            "{} vessel, {} mm: {area} voxels, pi r^2 = {expected:.1}",
            k.axis, k.radius_mm
        );
        assert!(
            (0.5 * expected..=1.8 * expected).contains(&(area as f64)),
            "{} vessel of {} mm: {area} voxels in its cross-section, pi r^2 = {expected:.1}",
            k.axis,
            k.radius_mm
        );
        areas.push(area);
    }
    assert_eq!(areas.len(), 2);
    assert!(
        areas[0] > areas[1],
        "3 mm vessel not wider than the 2 mm one: {areas:?}"
    );
}
