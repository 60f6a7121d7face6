//! Tests of the CPU twins (`morphray::reference`): each checks a property that a wrong stencil,
//! a wrong transform or a wrong edge case would break.

use morphray::reference::{
    self, BINS, DEFAULT_TAU, DerivativeError, DerivativeOptions, IndexToWorld, Sym3, bin_of,
    derivatives, finite_min_max, histogram, histogram_of_samples, nonfinite_count, normalize,
    normalize_value, physical_range, voxel_derivatives,
};
use morphray::volume::{LinearMap, Samples};
use proptest::prelude::*;

// ---------------------------------------------------------------------------------------------
// min / max

#[test]
fn minmax_integer_kinds_take_extremes_exactly() {
    assert_eq!(
        finite_min_max(&Samples::from_u8(vec![7, 0, 255, 3])),
        Some((0.0, 255.0))
    );
    assert_eq!(
        finite_min_max(&Samples::from_i8(&[5, -128, 127, 0])),
        Some((-128.0, 127.0))
    );
    assert_eq!(
        finite_min_max(&Samples::from_u16(&[65535, 1, 0])),
        Some((0.0, 65535.0))
    );
    assert_eq!(
        finite_min_max(&Samples::from_i16(&[-32768, 32767, -1])),
        Some((-32768.0, 32767.0))
    );
    assert_eq!(
        finite_min_max(&Samples::from_i16(&[-7])),
        Some((-7.0, -7.0))
    );
    assert_eq!(nonfinite_count(&Samples::from_i16(&[-32768, 32767])), 0);
}

#[test]
fn minmax_f32_skips_nonfinite_and_keeps_extremes_bit_exact() {
    let sub = f32::from_bits(1); // smallest positive subnormal
    let v = [
        f32::NAN,
        f32::INFINITY,
        -f32::MAX,
        sub,
        -sub,
        f32::MAX,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
    ];
    let s = Samples::from_f32(&v);
    let (lo, hi) = finite_min_max(&s).expect("finite values exist");
    assert_eq!(lo.to_bits(), (-f32::MAX as f64).to_bits());
    assert_eq!(hi.to_bits(), (f32::MAX as f64).to_bits());
    assert_eq!(nonfinite_count(&s), 3);
}

#[test]
fn minmax_orders_negative_zero_below_positive_zero() {
    for v in [[0.0f32, -0.0], [-0.0, 0.0]] {
        let (lo, hi) = finite_min_max(&Samples::from_f32(&v)).expect("finite");
        assert_eq!(lo.to_bits(), (-0.0f64).to_bits(), "min of {v:?}");
        assert_eq!(hi.to_bits(), 0.0f64.to_bits(), "max of {v:?}");
    }
}

#[test]
fn minmax_subnormals_and_negatives_are_not_flushed() {
    let a = f32::from_bits(1);
    let b = f32::from_bits(3);
    let (lo, hi) = finite_min_max(&Samples::from_f32(&[b, a])).expect("finite");
    assert_eq!((lo, hi), (a as f64, b as f64));
    assert!(lo > 0.0);
    let (lo, hi) = finite_min_max(&Samples::from_f32(&[-b, -a, -1e-3])).expect("finite");
    assert_eq!((lo, hi), (-1e-3f32 as f64, -a as f64));
}

#[test]
fn minmax_none_without_finite_values() {
    assert_eq!(finite_min_max(&Samples::from_f32(&[])), None);
    let s = Samples::from_f32(&[f32::NAN, f32::INFINITY, f32::NEG_INFINITY]);
    assert_eq!(finite_min_max(&s), None);
    assert_eq!(nonfinite_count(&s), 3);
}

proptest! {
    /// Against a sort-based oracle over arbitrary bit patterns (NaNs, infinities, subnormals,
    /// both zeros).
    #[test]
    fn minmax_matches_sorted_oracle(bits in prop::collection::vec(any::<u32>(), 0..64)) {
        let values: Vec<f32> = bits.iter().map(|&b| f32::from_bits(b)).collect();
        let mut finite: Vec<f64> =
            values.iter().filter(|v| v.is_finite()).map(|&v| v as f64).collect();
        finite.sort_by(|a, b| a.total_cmp(b));
        let expected = finite.first().zip(finite.last()).map(|(a, b)| (a.to_bits(), b.to_bits()));
        let s = Samples::from_f32(&values);
        let got = finite_min_max(&s).map(|(a, b)| (a.to_bits(), b.to_bits()));
        prop_assert_eq!(got, expected);
        prop_assert_eq!(nonfinite_count(&s), values.len() - finite.len());
    }
}

// ---------------------------------------------------------------------------------------------
// normalize

#[test]
fn physical_range_swaps_for_negative_slope() {
    let map = LinearMap {
        slope: -2.0,
        intercept: 10.0,
    };
    assert_eq!(physical_range(0.0, 3.0, map), (4.0, 10.0));
    assert_eq!(
        physical_range(
            0.0,
            3.0,
            LinearMap {
                slope: 0.5,
                intercept: -1.0
            }
        ),
        (-1.0, 0.5)
    );
}

#[test]
fn normalize_applies_eq1_with_slope_and_intercept() {
    let s = Samples::from_u8(vec![0, 128, 255]);
    let n = normalize(&s, LinearMap::IDENTITY, 0.0, 255.0);
    assert_eq!(n, vec![0.0, 128.0 / 255.0, 1.0]);

    let s = Samples::from_i16(&[0, 1, 2, 3]);
    let map = LinearMap {
        slope: -2.0,
        intercept: 10.0,
    };
    let (lo, hi) = physical_range(0.0, 3.0, map);
    let n = normalize(&s, map, lo, hi);
    let expected = [1.0, 4.0 / 6.0, 2.0 / 6.0, 0.0];
    for (a, b) in n.iter().zip(expected) {
        assert!((a - b).abs() < 1e-15, "{n:?}");
    }
}

#[test]
fn normalize_constant_volume_is_zero_and_histogram_is_one_bin() {
    let s = Samples::from_u16(&[700; 10]);
    let n = normalize(&s, LinearMap::IDENTITY, 700.0, 700.0);
    assert!(n.iter().all(|&v| v.to_bits() == 0));
    let h = histogram_of_samples(&s, LinearMap::IDENTITY, 700.0, 700.0);
    assert_eq!(h[0], 10);
    assert_eq!(h.iter().map(|&c| c as u64).sum::<u64>(), 10);
    // Swapped or non-finite bounds are unusable ranges, handled the same way.
    assert_eq!(normalize_value(5.0, 9.0, 1.0), 0.0);
    assert_eq!(normalize_value(5.0, f64::NEG_INFINITY, 1.0), 0.0);
    assert_eq!(normalize_value(5.0, 0.0, f64::NAN), 0.0);
}

#[test]
fn normalize_nonfinite_voxels_become_zero_and_are_not_counted() {
    let v = [f32::NAN, 1.0, f32::INFINITY, 3.0, f32::NEG_INFINITY, 2.0];
    let s = Samples::from_f32(&v);
    let (lo, hi) = finite_min_max(&s).expect("finite");
    let n = normalize(&s, LinearMap::IDENTITY, lo, hi);
    assert_eq!(n, vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.5]);
    let h = histogram_of_samples(&s, LinearMap::IDENTITY, lo, hi);
    assert_eq!(h.iter().map(|&c| c as u64).sum::<u64>(), 3);
    assert_eq!((h[0], h[128], h[255]), (1, 1, 1));
}

#[test]
fn normalize_huge_range_stays_finite_and_ordered() {
    let v = [-3e38f32, -f32::MAX, 0.0, 1.0, f32::MAX, 3e38];
    let s = Samples::from_f32(&v);
    let (lo, hi) = finite_min_max(&s).expect("finite");
    let n = normalize(&s, LinearMap::IDENTITY, lo, hi);
    assert_eq!(n[1], 0.0);
    assert_eq!(n[4], 1.0);
    assert!((n[2] - 0.5).abs() < 1e-15);
    // 1.0 is below the resolution of a 6.8e38 range (f64 has 53 bits), so it lands on 0.5.
    assert_eq!(n[3], n[2]);
    let expected = (f32::MAX as f64 - 3e38f32 as f64) / (2.0 * f32::MAX as f64);
    assert!(
        (n[0] - expected).abs() < 1e-15 && (n[5] - (1.0 - expected)).abs() < 1e-15,
        "{n:?}"
    );
    // An intercept that dwarfs the data (the loader's offset for f64 volumes) still separates
    // values, because the scale and bias are f64.
    let map = LinearMap {
        slope: 1.0,
        intercept: 1e6,
    };
    let s = Samples::from_f32(&[0.0, 1e-3, 2e-3]);
    let (lo, hi) = physical_range(0.0, 2e-3f32 as f64, map);
    let n = normalize(&s, map, lo, hi);
    assert!(
        n[0] == 0.0 && (n[1] - 0.5).abs() < 1e-6 && n[2] == 1.0,
        "{n:?}"
    );
}

proptest! {
    /// Outputs are finite, in [0, 1], never -0.0, and monotone in the stored value.
    #[test]
    fn normalize_is_bounded_and_monotone(
        values in prop::collection::vec(-1e30f32..1e30f32, 1..64),
        slope in prop::sample::select(vec![1.0, -1.0, 1e-20, 3.5e10, -0.25]),
    ) {
        let s = Samples::from_f32(&values);
        let map = LinearMap { slope, intercept: 17.0 };
        let (smin, smax) = finite_min_max(&s).expect("finite");
        let (lo, hi) = physical_range(smin, smax, map);
        let n = normalize(&s, map, lo, hi);
        for &x in &n {
            prop_assert!((0.0..=1.0).contains(&x) && x.to_bits() != (-0.0f64).to_bits());
        }
        let mut order: Vec<usize> = (0..values.len()).collect();
        order.sort_by(|&a, &b| (values[a] as f64 * slope).total_cmp(&(values[b] as f64 * slope)));
        for w in order.windows(2) {
            prop_assert!(n[w[0]] <= n[w[1]]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// histogram

#[test]
fn histogram_bin_edges_are_exact() {
    assert_eq!(bin_of(0.0), 0);
    assert_eq!(bin_of(-0.0), 0);
    assert_eq!(bin_of(1.0), 255);
    assert_eq!(bin_of(1.0f32.next_down()), 255);
    assert_eq!(bin_of(-5.0), 0);
    assert_eq!(bin_of(7.0), 255);
    assert_eq!(bin_of(f32::INFINITY), 255);
    assert_eq!(bin_of(f32::NEG_INFINITY), 0);
    assert_eq!(bin_of(f32::from_bits(1)), 0);
    for b in 1..BINS {
        let edge = b as f32 / 256.0;
        assert_eq!(bin_of(edge), b, "edge {b}");
        assert_eq!(bin_of(edge.next_down()), b - 1, "just below edge {b}");
    }
}

#[test]
fn histogram_counts_only_finite_voxels() {
    let norm: Vec<f32> = (0..1000).map(|i| i as f32 / 999.0).collect();
    let finite = |i: usize| !i.is_multiple_of(3);
    let h = histogram(&norm, finite);
    let expected = (0..1000).filter(|&i| finite(i)).count() as u64;
    assert_eq!(h.iter().map(|&c| c as u64).sum::<u64>(), expected);
    // 999 (exactly 1.0) is a multiple of 3: excluded; 998 is included and in the last bin.
    assert_eq!(
        h[255],
        (0..1000)
            .filter(|&i| finite(i) && i * 256 >= 255 * 999)
            .count() as u32
    );
}

proptest! {
    /// The f32 bin equals floor(256 v) computed exactly in f64, for every v in [0, 1].
    #[test]
    fn histogram_bin_is_exact_floor(v in 0.0f32..=1.0) {
        let exact = ((v as f64) * 256.0).floor().min(255.0) as usize;
        prop_assert_eq!(bin_of(v), exact);
    }
}

// ---------------------------------------------------------------------------------------------
// derivatives

/// A volume sampled from a world-space function: voxel (i, j, k) sits at `A (i, j, k) + t`.
fn sample(
    dims: [usize; 3],
    a: [[f64; 3]; 3],
    t: [f64; 3],
    f: impl Fn([f64; 3]) -> f64,
) -> Vec<f64> {
    let mut v = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                v.push(f(world(a, t, [i, j, k])));
            }
        }
    }
    v
}

fn world(a: [[f64; 3]; 3], t: [f64; 3], p: [usize; 3]) -> [f64; 3] {
    let p = p.map(|c| c as f64);
    [0, 1, 2].map(|r| a[r][0] * p[0] + a[r][1] * p[1] + a[r][2] * p[2] + t[r])
}

fn voxels(dims: [usize; 3]) -> impl Iterator<Item = [usize; 3]> {
    (0..dims[2])
        .flat_map(move |k| (0..dims[1]).flat_map(move |j| (0..dims[0]).map(move |i| [i, j, k])))
}

fn diag(s: [f64; 3]) -> [[f64; 3]; 3] {
    [[s[0], 0.0, 0.0], [0.0, s[1], 0.0], [0.0, 0.0, s[2]]]
}

/// Rotation by 30 degrees about z then 20 degrees about x, times an anisotropic spacing.
fn oblique() -> [[f64; 3]; 3] {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let rz = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
    let rx = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]];
    mul(mul(rx, rz), diag([0.9, 1.1, 1.7]))
}

fn mul(a: [[f64; 3]; 3], b: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (r, row) in m.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[r][k] * b[k][c]).sum();
        }
    }
    m
}

fn max_abs(h: &Sym3) -> f64 {
    [h.xx, h.yy, h.zz, h.xy, h.xz, h.yz]
        .iter()
        .fold(0.0, |m, v| m.max(v.abs()))
}

fn all(values: &[f64], dims: [usize; 3], a: [[f64; 3]; 3]) -> reference::Derivatives {
    let to_world = IndexToWorld::new(a).expect("invertible");
    derivatives(values, dims, &to_world, &DerivativeOptions::default()).expect("consistent sizes")
}

#[test]
fn stencils_match_their_definitions_on_a_row() {
    // I = i^2 along x on 4 voxels: one-sided ends, central inside, shifted second difference.
    let v = [0.0, 1.0, 4.0, 9.0];
    let d = all(&v, [4, 1, 1], diag([1.0; 3]));
    let g: Vec<f64> = d
        .gradient
        .expect("requested")
        .iter()
        .map(|g| g[0])
        .collect();
    assert_eq!(g, vec![1.0, 2.0, 4.0, 5.0]);
    let h = d.hessian.expect("requested");
    assert!(
        h.iter()
            .all(|h| h.xx == 2.0 && h.yy == 0.0 && h.zz == 0.0 && h.xy == 0.0)
    );
    // 2 voxels: first derivative is the one difference, second derivative 0 (n < 3).
    let d = all(&[1.0, 3.0], [2, 1, 1], diag([0.5, 1.0, 1.0]));
    assert_eq!(d.gradient.expect("requested"), vec![[4.0, 0.0, 0.0]; 2]);
    assert_eq!(d.hessian.expect("requested")[0].xx, 0.0);
}

#[test]
fn linear_ramp_on_anisotropic_grid_is_exact_everywhere() {
    let dims = [7, 6, 5];
    let a = diag([0.5, 1.0, 3.0]);
    let slope = [0.013, -0.021, 0.007];
    let f = |x: [f64; 3]| 0.3 + slope[0] * x[0] + slope[1] * x[1] + slope[2] * x[2];
    let v = sample(dims, a, [-1.0, 2.0, 0.5], f);
    let d = all(&v, dims, a);
    let (g, h, k) = (
        d.gradient.expect("g"),
        d.hessian.expect("h"),
        d.curvature.expect("k"),
    );
    for i in 0..v.len() {
        for c in 0..3 {
            assert!((g[i][c] - slope[c]).abs() < 1e-12, "voxel {i}: {:?}", g[i]);
        }
        assert!(max_abs(&h[i]) < 1e-12, "voxel {i}: {:?}", h[i]);
        assert!(k[i].abs() < 1e-12);
    }
}

#[test]
fn oblique_affine_gives_the_rotated_gradient() {
    let dims = [6, 5, 4];
    let a = oblique();
    let slope = [0.02, 0.05, -0.03];
    let v = sample(dims, a, [3.0, -2.0, 1.0], |x| {
        slope[0] * x[0] + slope[1] * x[1] + slope[2] * x[2]
    });
    let d = all(&v, dims, a);
    for (i, g) in d.gradient.expect("g").iter().enumerate() {
        for c in 0..3 {
            assert!((g[c] - slope[c]).abs() < 1e-12, "voxel {i}: {g:?}");
        }
    }
    // The index-space gradient is not the world gradient here: the transform matters.
    let (i0, i1) = (v[0], v[1]);
    assert!(((i1 - i0) - slope[0]).abs() > 1e-3);
}

#[test]
fn quadratic_bowl_has_hessian_2c_and_curvature_2c_everywhere() {
    let c = 0.01;
    let x0 = [2.3, -1.7, 4.1];
    let bowl = |x: [f64; 3]| {
        c * ((x[0] - x0[0]).powi(2) + (x[1] - x0[1]).powi(2) + (x[2] - x0[2]).powi(2))
    };
    for (a, t) in [
        (diag([0.5, 1.0, 3.0]), [0.0, -4.0, 0.0]),
        (oblique(), [0.5, -3.0, 1.0]),
    ] {
        let dims = [9, 8, 7];
        let v = sample(dims, a, t, bowl);
        let d = all(&v, dims, a);
        let (g, h, k) = (
            d.gradient.expect("g"),
            d.hessian.expect("h"),
            d.curvature.expect("k"),
        );
        for (n, p) in voxels(dims).enumerate() {
            let hm = h[n].to_matrix();
            for r in 0..3 {
                for q in 0..3 {
                    let want = if r == q { 2.0 * c } else { 0.0 };
                    assert!((hm[r][q] - want).abs() < 1e-12, "H at {p:?}: {hm:?}");
                }
            }
            assert!((k[n] - 2.0 * c).abs() < 1e-12, "k at {p:?}: {}", k[n]);
            // The gradient is exact only where all three stencils are central.
            let interior = (0..3).all(|ax| p[ax] > 0 && p[ax] + 1 < dims[ax]);
            if interior {
                let x = world(a, t, p);
                for ax in 0..3 {
                    assert!(
                        (g[n][ax] - 2.0 * c * (x[ax] - x0[ax])).abs() < 1e-12,
                        "g at {p:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn bowl_centred_on_a_voxel_has_zero_gradient_and_guarded_curvature_there() {
    let dims = [5, 5, 5];
    let v = sample(dims, diag([1.0; 3]), [-2.0; 3], |x| {
        0.1 * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2])
    });
    let d = all(&v, dims, diag([1.0; 3]));
    let centre = 2 + 5 * (2 + 5 * 2);
    assert_eq!(d.gradient_magnitude.expect("m")[centre], 0.0);
    assert_eq!(d.curvature.expect("k")[centre], 0.0, "tau guard, not 0.2");
    assert!((d.hessian.expect("h")[centre].xx - 0.2).abs() < 1e-12);
}

/// Worst `|k - I''(r)|` over voxels with `1 <= r <= 3 sigma`, relative to `max |I''| = 1/sigma²`,
/// for a Gaussian blob of width `sigma` voxels on a 1 mm grid.
fn blob_curvature_error(sigma: f64) -> f64 {
    let n = (6.0 * sigma).ceil() as usize + 5;
    let dims = [n, n, n];
    let c = (n / 2) as f64 + 0.3; // off-grid centre: no voxel at r = 0
    let r2 = |x: [f64; 3]| (0..3).map(|a| (x[a] - c).powi(2)).sum::<f64>();
    let v = sample(dims, diag([1.0; 3]), [0.0; 3], |x| {
        (-r2(x) / (2.0 * sigma * sigma)).exp()
    });
    let k = all(&v, dims, diag([1.0; 3])).curvature.expect("k");
    let mut worst: f64 = 0.0;
    let mut checked = 0;
    for (i, p) in voxels(dims).enumerate() {
        let rr = r2(p.map(|c| c as f64));
        if !(1.0..=3.0 * sigma).contains(&rr.sqrt()) {
            continue;
        }
        let exact =
            (rr / sigma.powi(4) - 1.0 / (sigma * sigma)) * (-rr / (2.0 * sigma * sigma)).exp();
        worst = worst.max((k[i] - exact).abs() * sigma * sigma);
        checked += 1;
    }
    assert!(checked > 5000, "{checked}");
    worst
}

/// Measured: worst relative error 2.43e-2 at sigma = 4 voxels and 6.20e-3 at sigma = 8 (ratio
/// 3.92). The stencils are second order, so doubling sigma must cut the error about 4x.
#[test]
fn gaussian_blob_curvature_is_the_radial_second_derivative() {
    let e4 = blob_curvature_error(4.0);
    let e8 = blob_curvature_error(8.0);
    assert!(e4 < 0.03, "sigma 4: {e4:e}");
    assert!(e8 < 0.008, "sigma 8: {e8:e}");
    assert!(
        (3.0..5.0).contains(&(e4 / e8)),
        "second-order convergence: {e4:e} / {e8:e}"
    );
}

#[test]
fn plateaus_have_zero_gradient_and_curvature() {
    let dims = [12, 6, 5];
    // Two exact plateaus with a step between i = 5 and 6.
    let v = sample(dims, diag([1.0; 3]), [0.0; 3], |x| {
        if x[0] < 5.5 { 0.25 } else { 0.75 }
    });
    let d = all(&v, dims, diag([0.7, 1.3, 2.0]));
    let (m, h, k) = (
        d.gradient_magnitude.expect("m"),
        d.hessian.expect("h"),
        d.curvature.expect("k"),
    );
    for (n, p) in voxels(dims).enumerate() {
        assert!(m[n].is_finite() && k[n].is_finite() && max_abs(&h[n]).is_finite());
        // Farther than the stencil reach (2 voxels for the shifted second difference) from the step.
        if p[0] <= 3 || p[0] >= 8 {
            assert_eq!((m[n], k[n], max_abs(&h[n])), (0.0, 0.0, 0.0), "at {p:?}");
        }
    }
    // Constant volume: everything exactly zero.
    let d = all(&vec![0.4; 60], [5, 4, 3], oblique());
    assert!(d.gradient_magnitude.expect("m").iter().all(|&m| m == 0.0));
    assert!(d.curvature.expect("k").iter().all(|&k| k == 0.0));
}

/// Measured (R = 10 mm, 1 mm grid, 1253 voxels within 0.5 mm of the sphere): `max |k| / |g|` =
/// 1.13e-3 per mm (0.57 % of 2/R) and `max |(tr H - k)/|g| - 2/r|` = 0.26 % of 2/R.
#[test]
fn sphere_distance_field_curvature_is_2_over_r() {
    let n = 29;
    let dims = [n, n, n];
    let centre = [14.2, 13.9, 14.1]; // off-grid, so no voxel sees the cone tip
    let big_r = 10.0;
    let dist = |x: [f64; 3]| {
        (0..3)
            .map(|a| (x[a] - centre[a]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    // Scaled into I_norm units (1/30 per mm), as a normalized volume would be.
    let s = 1.0 / 30.0;
    let v = sample(dims, diag([1.0; 3]), [0.0; 3], |x| s * dist(x));
    let d = all(&v, dims, diag([1.0; 3]));
    let (m, h, k) = (
        d.gradient_magnitude.expect("m"),
        d.hessian.expect("h"),
        d.curvature.expect("k"),
    );
    let (mut worst_k, mut worst_mean, mut checked) = (0.0f64, 0.0f64, 0);
    for (i, p) in voxels(dims).enumerate() {
        let r = dist(p.map(|c| c as f64));
        if (r - big_r).abs() > 0.5 {
            continue;
        }
        let mean2 = (h[i].trace() - k[i]) / m[i];
        worst_k = worst_k.max((k[i] / s).abs());
        worst_mean = worst_mean.max((mean2 - 2.0 / r).abs() / (2.0 / big_r));
        checked += 1;
    }
    assert!(checked > 500, "{checked}");
    assert!(worst_k < 2e-3, "k along the gradient {worst_k:e}");
    assert!(worst_mean < 5e-3, "2/r error {worst_mean:e}");
}

#[test]
fn degenerate_shapes_give_finite_outputs() {
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut rand = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for dims in [
        [1, 1, 9],
        [1, 9, 1],
        [9, 1, 1],
        [2, 2, 2],
        [1, 1, 1],
        [7, 5, 3],
        [3, 1, 2],
    ] {
        let v: Vec<f64> = (0..dims.iter().product()).map(|_| rand()).collect();
        let d = all(&v, dims, oblique());
        let g = d.gradient.expect("g");
        let h = d.hessian.expect("h");
        let k = d.curvature.expect("k");
        assert_eq!(g.len(), v.len());
        for i in 0..v.len() {
            assert!(g[i].iter().all(|c| c.is_finite()), "{dims:?}");
            assert!(max_abs(&h[i]).is_finite() && k[i].is_finite(), "{dims:?}");
        }
        // Index-space derivatives along a 1-voxel axis are exactly 0 (checked with a diagonal A,
        // where world axes are index axes).
        let d = all(&v, dims, diag([1.0; 3]));
        for (g, h) in d.gradient.expect("g").iter().zip(d.hessian.expect("h")) {
            for ax in 0..3 {
                if dims[ax] == 1 {
                    assert_eq!(g[ax], 0.0);
                    assert_eq!(h.to_matrix()[ax], [0.0; 3]);
                }
                if dims[ax] < 3 {
                    assert_eq!(h.to_matrix()[ax][ax], 0.0);
                }
            }
        }
    }
    let d = all(&[0.5], [1, 1, 1], diag([1.0; 3]));
    assert_eq!(d.gradient.expect("g"), vec![[0.0; 3]]);
    assert_eq!(d.curvature.expect("k"), vec![0.0]);
}

#[test]
fn options_select_outputs_and_voxel_probe_matches_bulk() {
    let dims = [5, 4, 3];
    let v = sample(dims, oblique(), [0.0; 3], |x| {
        (0.1 * x[0]).sin() + 0.05 * x[1] * x[2]
    });
    let to_world = IndexToWorld::new(oblique()).expect("invertible");
    let only_g = DerivativeOptions {
        gradient: true,
        hessian: false,
        tau: DEFAULT_TAU,
    };
    let d = derivatives(&v, dims, &to_world, &only_g).expect("sizes");
    assert!(d.gradient.is_some() && d.gradient_magnitude.is_some());
    assert!(d.hessian.is_none() && d.curvature.is_none());
    let only_h = DerivativeOptions {
        gradient: false,
        hessian: true,
        tau: DEFAULT_TAU,
    };
    let d = derivatives(&v, dims, &to_world, &only_h).expect("sizes");
    assert!(d.gradient.is_none() && d.hessian.is_some() && d.curvature.is_some());
    let none = DerivativeOptions {
        gradient: false,
        hessian: false,
        tau: DEFAULT_TAU,
    };
    assert_eq!(
        derivatives(&v, dims, &to_world, &none).expect("sizes"),
        Default::default()
    );

    let full = derivatives(&v, dims, &to_world, &DerivativeOptions::default()).expect("sizes");
    for (n, p) in voxels(dims).enumerate() {
        let one = voxel_derivatives(&v, dims, &to_world, p, DEFAULT_TAU).expect("inside");
        assert_eq!(one.gradient, full.gradient.as_ref().expect("g")[n]);
        assert_eq!(one.hessian, full.hessian.as_ref().expect("h")[n]);
        assert_eq!(one.curvature, full.curvature.as_ref().expect("k")[n]);
    }
    // A large tau switches curvature off everywhere.
    let big_tau = DerivativeOptions {
        tau: 1e3,
        ..DerivativeOptions::default()
    };
    let d = derivatives(&v, dims, &to_world, &big_tau).expect("sizes");
    assert!(d.curvature.expect("k").iter().all(|&k| k == 0.0));
}

#[test]
fn bad_inputs_are_typed_errors() {
    let to_world = IndexToWorld::from_spacing([1.0; 3]).expect("invertible");
    let opts = DerivativeOptions::default();
    assert!(matches!(
        derivatives(&[0.0; 5], [2, 2, 2], &to_world, &opts),
        Err(DerivativeError::LengthMismatch {
            len: 5,
            expected: Some(8),
            ..
        })
    ));
    assert!(matches!(
        derivatives(&[0.0; 5], [usize::MAX, 2, 2], &to_world, &opts),
        Err(DerivativeError::LengthMismatch { expected: None, .. })
    ));
    assert!(matches!(
        voxel_derivatives(&[0.0; 8], [2, 2, 2], &to_world, [0, 2, 0], DEFAULT_TAU),
        Err(DerivativeError::OutOfRange { .. })
    ));
    for a in [
        [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]],
        [[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        diag([1.0, 0.0, 1.0]),
        diag([1e-300, 1e-300, 1e-300]),
    ] {
        assert!(
            matches!(
                IndexToWorld::new(a),
                Err(DerivativeError::SingularAffine { .. })
            ),
            "{a:?}"
        );
    }
    // Tiny but well-conditioned spacings are fine (relative test, not absolute).
    assert!(IndexToWorld::from_spacing([1e-3, 2e-3, 5e-4]).is_ok());
    // A mirrored (negative determinant) affine is valid.
    assert!(IndexToWorld::from_spacing([-1.0, 1.0, 1.0]).is_ok());
    // The error message is one readable sentence.
    let msg = DerivativeError::LengthMismatch {
        len: 5,
        dims: [2, 2, 2],
        expected: Some(8),
    }
    .to_string();
    assert!(msg.contains("5 values") && msg.contains("need 8"), "{msg}");
}

#[test]
fn index_to_world_inverts_the_affine() {
    let a = oblique();
    let t = IndexToWorld::new(a).expect("invertible");
    let p = mul(a, t.inverse());
    for (r, row) in p.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            assert!((v - if r == c { 1.0 } else { 0.0 }).abs() < 1e-14);
        }
    }
}
