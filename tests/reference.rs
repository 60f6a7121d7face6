//! Tests of the CPU twins (`morphray::reference`): each checks a property that a wrong stencil,
//! a wrong transform or a wrong edge case would break.

use morphray::reference::{
    BINS, bin_of, finite_min_max, histogram, histogram_of_samples, nonfinite_count, normalize,
    normalize_value, physical_range,
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
    let finite = |i: usize| i % 3 != 0;
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
