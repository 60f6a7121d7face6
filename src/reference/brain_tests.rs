use super::*;
use crate::analysis::Contrast;
use crate::analysis::brain_band::band_for;
use crate::reference::{BINS, bin_of};

/// Deterministic uniform numbers in [0, 1).
fn uniforms(mut state: u64) -> impl FnMut() -> f64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Position in mm of voxel `p` relative to `centre` (voxels).
fn mm(p: [usize; 3], centre: [f64; 3], h: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|a| (p[a] as f64 - centre[a]) * h[a])
}

fn norm(x: [f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

/// `f(position)` over the grid, x fastest.
fn fill<T>(dims: [usize; 3], mut f: impl FnMut([usize; 3]) -> T) -> Vec<T> {
    let mut out = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                out.push(f([i, j, k]));
            }
        }
    }
    out
}

fn dice(a: &[u8], b: &[u8]) -> f64 {
    let both = a
        .iter()
        .zip(b)
        .filter(|(x, y)| **x != 0 && **y != 0)
        .count();
    let total = a.iter().chain(b).filter(|x| **x != 0).count();
    2.0 * both as f64 / total as f64
}

#[test]
fn squared_distance_is_exact_up_to_the_bound_on_random_sets() {
    let mut rnd = uniforms(0x9e37_79b9_7f4a_7c15);
    for (dims, h, bound, density) in [
        ([7, 9, 5], [0.7, 1.3, 2.1], 3.0, 0.05),
        ([13, 4, 11], [1.1, 0.45, 0.9], 2.2, 0.02),
        ([1, 17, 6], [0.8, 0.8, 3.0], 4.0, 0.1),
        ([5, 5, 5], [1.0, 1.0, 1.0], 10.0, 0.01),
    ] {
        let sources: Vec<u8> = fill(dims, |_| u8::from(rnd() < density));
        let d = squared_distance(&sources, dims, h, bound);
        let points: Vec<[usize; 3]> = fill(dims, |p| p);
        for (p, &got) in points.iter().zip(&d) {
            let brute = points
                .iter()
                .zip(&sources)
                .filter(|(_, s)| **s != 0)
                .map(|(q, _)| norm(mm(*q, p.map(|v| v as f64), h)).powi(2))
                .fold(f64::INFINITY, f64::min);
            if brute <= bound * bound {
                assert!(
                    (got - brute).abs() < 1e-9,
                    "{dims:?} {p:?}: {got} vs {brute}"
                );
            } else {
                assert!(got > bound * bound, "{dims:?} {p:?}: {got} vs {brute}");
            }
        }
    }
}

#[test]
fn taps_are_bounded() {
    assert_eq!(taps(4.5, 0.88), 6);
    assert_eq!(taps(5.0, 1.0), 5);
    assert_eq!(taps(5.0, 0.01), MAX_TAPS);
    assert_eq!(taps(5.0, f64::NAN), 0);
}

#[test]
fn erosion_and_dilation_of_a_sphere_move_its_radius_by_the_ball() {
    let (dims, h) = ([47, 39, 29], [0.9, 1.1, 1.6]);
    let centre = [23.0, 19.3, 14.2];
    let radius = |p: [usize; 3]| norm(mm(p, centre, h));
    let sphere: Vec<u8> = fill(dims, |p| u8::from(radius(p) <= 16.0));
    let half_diagonal = norm(h) / 2.0;
    let eroded = erode(&sphere, dims, h, 5.0);
    let dilated = dilate(&sphere, dims, h, 5.0);
    let points: Vec<[usize; 3]> = fill(dims, |p| p);
    let (mut max_eroded, mut min_not_dilated) = (0.0f64, f64::INFINITY);
    for ((p, &e), &d) in points.iter().zip(&eroded).zip(&dilated) {
        let r = radius(*p);
        // Exact sides: every voxel within 11 mm stays, none beyond 21 mm is reached.
        if r < 11.0 {
            assert_eq!(e, 1, "{p:?} at {r} mm eroded");
        }
        if r > 21.0 {
            assert_eq!(d, 0, "{p:?} at {r} mm dilated");
        }
        if e != 0 {
            max_eroded = max_eroded.max(r);
        }
        if d == 0 {
            min_not_dilated = min_not_dilated.min(r);
        }
    }
    // Discrete sides: within half a voxel diagonal of the expected radii.
    assert!(
        (max_eroded - 11.0).abs() <= half_diagonal,
        "eroded radius {max_eroded}"
    );
    assert!(
        (min_not_dilated - 21.0).abs() <= half_diagonal,
        "dilated radius {min_not_dilated}"
    );
}

#[test]
fn pools_clip_blocks_at_the_faces() {
    let dims = [5, 3, 1];
    assert_eq!(coarse_dims(dims, 2), [3, 2, 1]);
    #[rustfmt::skip]
    let set = [
        1, 1, 1, 1, 1,
        1, 1, 0, 1, 1,
        1, 0, 0, 0, 1,
    ];
    assert_eq!(pool_all(&set, dims, 2), vec![1, 0, 1, 0, 0, 1]);
    assert_eq!(pool_any(&set, dims, 2), vec![1, 1, 1, 1, 0, 1]);
    assert_eq!(pool_all(&set, dims, 1), set.to_vec());
}

/// A synthetic T1 head with voxels `h` mm: a brain sphere of radius 55 mm (I_norm 0.7), a
/// dark shell (CSF and skull, 0.1) to 63 mm, a scalp shell as bright as the brain to 70 mm, a
/// 4 mm wide bridge of brain intensity through the dark shell along +x, air (0.02) outside;
/// `scalp` false leaves only the brain (and no bridge). Returns the volume and the true brain.
fn head(dims: [usize; 3], h: [f64; 3], scalp: bool) -> (Vec<f64>, Vec<u8>) {
    let centre = dims.map(|n| (n as f64 - 1.0) / 2.0);
    let mut volume = Vec::new();
    let truth = fill(dims, |p| {
        let x = mm(p, centre, h);
        let r = norm(x);
        let bridge = x[0] > 0.0 && (x[1] * x[1] + x[2] * x[2]).sqrt() < 2.0;
        let v = match r {
            r if r <= 55.0 => 0.7,
            _ if !scalp => 0.02,
            r if r <= 63.0 && bridge => 0.7,
            r if r <= 63.0 => 0.1,
            r if r <= 70.0 => 0.7,
            _ => 0.02,
        };
        volume.push(v);
        u8::from(r <= 55.0)
    });
    (volume, truth)
}

fn histogram(volume: &[f64]) -> [u32; BINS] {
    let mut h = [0u32; BINS];
    for &v in volume {
        h[bin_of(v as f32)] += 1;
    }
    h
}

#[test]
fn the_chain_finds_the_brain_inside_a_synthetic_head() {
    let (dims, h) = ([64, 58, 50], [2.4, 2.6, 3.0]);
    let (volume, truth) = head(dims, h, true);
    let (lo, hi) = band_for(&histogram(&volume), Contrast::T1).expect("a band");
    assert!(lo > 0.1 && lo < 0.7 && hi > 0.7, "band {lo}..{hi}");
    // The phantom's edges are sharp (no partial-volume rim for the grow to give back), so the
    // grow is small here; the rest are the defaults.
    let params = BrainParams {
        grow_mm: 0.5,
        ..BrainParams::for_band(lo, hi)
    };
    let out = extract(&volume, dims, h, &params).expect("valid input");
    assert!(out.found);
    let d = dice(&out.mask, &truth);
    assert!(d > 0.95, "Dice {d}");
    // The scalp is in the band but not in the mask.
    let scalp_in_mask = fill(dims, |p| p)
        .iter()
        .zip(&out.mask)
        .filter(|(p, m)| {
            let r = norm(mm(**p, dims.map(|n| (n as f64 - 1.0) / 2.0), h));
            **m != 0 && r > 63.0
        })
        .count();
    assert_eq!(scalp_in_mask, 0);
    let voxel = h.iter().product::<f64>();
    let test = is_head(&out.smoothed, &out.mask, lo, voxel);
    assert!(test.is_head, "{test:?}");

    // The brain alone is already stripped.
    let (brain, truth) = head(dims, h, false);
    let out = extract(&brain, dims, h, &params).expect("valid input");
    assert!(dice(&out.mask, &truth) > 0.95);
    let test = is_head(&out.smoothed, &out.mask, lo, voxel);
    assert!(!test.is_head && test.outside_fraction < 0.05, "{test:?}");
}

#[test]
fn a_ventricle_open_to_a_slab_cut_is_filled() {
    // A brain cut by the last slab: a dark ventricle reaching the top face stays outside the
    // band, and the coarse 2D rule fills it.
    let (dims, h) = ([40, 40, 20], [2.0, 2.0, 2.5]);
    let centre = [19.5, 19.5, 19.0];
    let volume = fill(dims, |p| {
        let x = mm(p, centre, h);
        let ventricle = (x[0] * x[0] + x[1] * x[1]).sqrt() < 8.0;
        if norm(x) <= 36.0 && !ventricle {
            0.7
        } else {
            0.02
        }
    });
    let params = BrainParams::for_band(0.3, 0.9);
    let out = extract(&volume, dims, h, &params).expect("valid input");
    assert!(out.found);
    let at = |p: [usize; 3]| out.mask[p[0] + dims[0] * (p[1] + dims[1] * p[2])];
    assert_eq!(at([20, 20, 19]), 1, "ventricle at the cut filled");
    assert_eq!(at([20, 20, 10]), 1, "ventricle inside filled");
    assert_eq!(at([0, 0, 19]), 0);
}

#[test]
fn nothing_in_the_band_is_no_brain_and_bad_input_is_an_error() {
    let dims = [6, 5, 4];
    let out = extract(
        &[0.5; 120],
        dims,
        [1.0; 3],
        &BrainParams::for_band(0.6, 0.9),
    )
    .expect("valid input");
    assert!(!out.found);
    assert!(out.mask.iter().all(|&m| m == 0));
    let p = BrainParams::for_band(0.4, 0.9);
    assert_eq!(
        extract(&[0.5; 119], dims, [1.0; 3], &p),
        Err(BrainError::Length {
            expected: 120,
            got: 119
        })
    );
    assert!(matches!(
        extract(&[0.5; 120], dims, [1.0, f64::NAN, 1.0], &p),
        Err(BrainError::Spacing(_))
    ));
    assert_eq!(
        extract(&[], [0, 5, 4], [1.0; 3], &p),
        Err(BrainError::Dims([0, 5, 4]))
    );
    let bad = BrainParams::for_band(0.9, 0.4);
    assert!(matches!(
        extract(&[0.5; 120], dims, [1.0; 3], &bad),
        Err(BrainError::Params(_))
    ));
}
