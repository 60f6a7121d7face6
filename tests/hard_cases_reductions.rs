//! Reductions at sizes that are multiples of nothing (NUMERICS.md rows "subgroup reductions at
//! sizes not multiple of workgroup or subgroup", "float atomics", "value exactly 1.0 in the
//! histogram", and the test "histogram sum = number of finite voxels"), through the real
//! `Engine::prepare` and `Engine::derive`: the histogram at n = 1, 31, 32, 33, 63, 64, 65, ...,
//! 4096 voxels and on a 101 x 103 x 97 volume (1,009,091 voxels, prime sides); the derivative
//! pass's max |g| at awkward shapes; min/max over negatives, +-0, FLT_MAX and subnormals.
//! Lavapipe runs subgroups of 8, the H100 of 32; workgroups are 256 (histogram, min/max) and
//! 8 x 8 x 4 (derivatives).
//!
//! The table mapping every NUMERICS.md row to its tests is at the top of tests/hard_cases.rs.

mod common;
mod hard_support;

use common::volumes::Rng;
use hard_support::{CheckedPrepare, derived_data, normalized, prepare_checked, volume};
use morphray::engine::Engine;
use morphray::passes::derivatives::DerivativeOutputs;
use morphray::reference;
use morphray::reference::derivatives::{DerivativeOptions, IndexToWorld};
use morphray::volume::{Samples, Volume};

/// f32 samples: mostly uniform in [-1000, 1000], with NaN, +-Inf, +-0, subnormals, FLT_MAX and
/// its negative sprinkled in (about 1 in 8), and the extremes at random positions.
fn awkward_samples(rng: &mut Rng, n: usize) -> Vec<f32> {
    let specials = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        -0.0,
        1e-45,
        -3e-39,
        f32::from_bits(0xffc0_0000), // negative quiet NaN
    ];
    (0..n)
        .map(|_| {
            if rng.unit() < 0.125 {
                specials[(rng.next_u64() % specials.len() as u64) as usize]
            } else {
                rng.range(-1000.0, 1000.0) as f32
            }
        })
        .collect()
}

/// Prepares `v` and checks range, histogram (bit-exact with its twin on the GPU's own I_norm;
/// bin(1.0) = 255; sum = finite count) against the CPU.
fn check_histogram(label: &str, engine: &mut Engine, v: &Volume) {
    let CheckedPrepare {
        prepared,
        finite,
        finite_count,
        cpu_range,
        norm,
    } = prepare_checked(label, engine, v);
    let n = v.voxel_count();
    let twin = reference::histogram::histogram(&norm, |i| finite[i]);
    assert_eq!(prepared.histogram, twin, "{label}: histogram");
    let sum: u64 = prepared.histogram.iter().map(|&c| c as u64).sum();
    assert_eq!(
        sum, finite_count as u64,
        "{label}: histogram sum = finite count"
    );
    assert_eq!(prepared.finite_voxels, finite_count as u64, "{label}");
    if let Some((lo, hi)) = cpu_range
        && lo < hi
    {
        // The finite maximum normalizes to exactly 1.0 and lands in the last bin.
        let ones = (0..n).filter(|&i| finite[i] && norm[i] == 1.0).count();
        assert!(ones >= 1, "{label}: the maximum maps to 1.0");
        assert!(
            prepared.histogram[255] as usize >= ones,
            "{label}: bin(1.0) = 255"
        );
    }
}

#[test]
fn histogram_and_range_are_exact_at_awkward_voxel_counts() {
    let mut engine = common::engine();
    let mut rng = Rng(31337);
    for n in [
        1usize, 2, 7, 31, 32, 33, 63, 64, 65, 255, 256, 257, 1000, 4093, 4096,
    ] {
        // [n, 1, 1]: one row, so the count is exactly n in every pass.
        let values = awkward_samples(&mut rng, n);
        check_histogram(
            &format!("[{n}, 1, 1]"),
            &mut engine,
            &volume([n, 1, 1], [1.0; 3], Samples::from_f32(&values)),
        );
        // The same count as an integer kind (no non-finite path, 2 samples per 32-bit word).
        let ints: Vec<i16> = (0..n).map(|_| rng.next_u64() as i16).collect();
        check_histogram(
            &format!("[{n}, 1, 1] i16"),
            &mut engine,
            &volume([n, 1, 1], [1.0; 3], Samples::from_i16(&ints)),
        );
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn histogram_of_a_million_voxels_with_prime_sides_sums_to_the_finite_count() {
    let mut engine = common::engine();
    let mut rng = Rng(1_009_091);
    let dims = [101usize, 103, 97]; // 1,009,091 voxels; 101, 103, 97 are prime
    let n: usize = dims.iter().product();
    let values = awkward_samples(&mut rng, n);
    check_histogram(
        "101 x 103 x 97",
        &mut engine,
        &volume(dims, [1.0; 3], Samples::from_f32(&values)),
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn range_is_exact_over_negatives_signed_zeros_flt_max_and_subnormals_at_awkward_counts() {
    let mut engine = common::engine();
    // Integer atomics on order-preserving keys: -0 orders below +0, subnormals are kept (not
    // flushed), FLT_MAX and -FLT_MAX are ordinary keys. The extreme sits at the last index, the
    // first, and in the middle, for counts around the subgroup and workgroup sizes.
    let cases: Vec<Vec<f32>> = vec![
        vec![-0.0, 0.0],
        vec![0.0, -0.0],
        vec![-0.0; 33],
        vec![f32::MAX, f32::MIN, 0.0],
        vec![1e-45, -1e-45, 2e-45],
        vec![-3e38, -1.0, -2e-38, -1e-45],
        vec![f32::MIN_POSITIVE, 1e-45, f32::MIN_POSITIVE * 0.5],
    ];
    for base in cases {
        for n in [base.len(), 31, 33, 65, 257, 1000] {
            if n < base.len() {
                continue;
            }
            for place in [0usize, (n - base.len()) / 2, n - base.len()] {
                // Filler strictly inside the case's range (its median), the case at `place`.
                let mut sorted = base.clone();
                sorted.sort_by(|a, b| a.total_cmp(b));
                let mut values = vec![sorted[sorted.len() / 2]; n];
                values[place..place + base.len()].copy_from_slice(&base);
                let samples = Samples::from_f32(&values);
                let prepared = engine
                    .prepare(&volume([n, 1, 1], [1.0; 3], samples.clone()))
                    .unwrap();
                let cpu = reference::minmax::finite_min_max(&samples);
                assert_eq!(
                    prepared
                        .stored_range
                        .map(|(a, b)| (a.to_bits(), b.to_bits())),
                    cpu.map(|(a, b)| (a.to_bits(), b.to_bits())),
                    "{base:?} at {place} of {n}"
                );
            }
        }
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn derivative_maximum_is_exact_at_awkward_shapes() {
    let mut engine = common::engine();
    let mut rng = Rng(8_675_309);
    // Workgroups are 8 x 8 x 4 and subgroups 8 (lavapipe) or 32: shapes with every side 1, prime,
    // or one past a multiple, so partial workgroups and idle lanes exist along every axis.
    let shapes = [
        [1usize, 1, 1],
        [2, 1, 1],
        [9, 1, 1],
        [1, 9, 1],
        [1, 1, 5],
        [7, 5, 3],
        [33, 1, 1],
        [17, 9, 5],
        [65, 3, 2],
        [31, 29, 7],
    ];
    for dims in shapes {
        for trial in 0..3 {
            let n: usize = dims.iter().product();
            // Random u16 data with one spike at a random voxel: the maximum |g| sits next to it,
            // in a different lane each trial.
            let mut values: Vec<u16> = (0..n).map(|_| (rng.next_u64() % 1000) as u16).collect();
            let spike = (rng.next_u64() % n as u64) as usize;
            values[spike] = 60_000;
            let v = volume(dims, [0.7, 1.3, 2.1], Samples::from_u16(&values));
            let prepared = engine.prepare(&v).unwrap();
            let derived = engine
                .derive(
                    &prepared,
                    DerivativeOutputs {
                        magnitude: true,
                        ..Default::default()
                    },
                )
                .unwrap();
            let norm: Vec<f64> = normalized(&engine, &prepared)
                .iter()
                .map(|&x| x as f64)
                .collect();
            let twin = reference::derivatives::derivatives(
                &norm,
                dims,
                &IndexToWorld::new(v.orientation.linear_part()).unwrap(),
                &DerivativeOptions {
                    hessian: false,
                    ..DerivativeOptions::default()
                },
            )
            .unwrap();
            let twin_max = twin
                .gradient_magnitude
                .unwrap()
                .iter()
                .cloned()
                .fold(0.0, f64::max);
            // The GPU's f32 |g| of the same stencil differs from f64 by a few 2^-24 relative; the
            // reduction itself is exact (bits of non-negative floats order as integers).
            let gpu_max = derived.stats.max_magnitude;
            assert!(
                (gpu_max - twin_max).abs() <= 1e-6 * twin_max,
                "{dims:?} trial {trial}: max |g| {gpu_max} vs {twin_max}"
            );
            // And it is the maximum of what the pass stored, to one f16 ulp (2^-10 relative:
            // Vulkan lets the f16 conversion round toward zero, and lavapipe does).
            let stored = derived_data(&engine, &derived).magnitude;
            let stored_max = stored.iter().cloned().fold(0.0, f64::max);
            assert!(
                (stored_max - gpu_max).abs() <= gpu_max * 2f64.powi(-10),
                "{dims:?}: stored max {stored_max} vs reduced {gpu_max}"
            );
        }
    }
    common::assert_no_validation_errors(&engine);
}
