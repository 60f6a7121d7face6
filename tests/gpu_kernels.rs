//! GPU kernels against their f64 CPU twins at sizes that are multiples of nothing
//! (1, 31, 33, 1000003 samples; 7x5x3 and 130x97x61 volumes), for every sample kind, with
//! zero validation-layer errors. Runs on lavapipe (subgroup size 8) in CI and on the H100
//! (subgroup size 32).

mod common;

use common::volumes::{Rng, smooth_field, volume, volume_with_affine};
use morphray::engine::readback::{read_buffer, read_image};
use morphray::engine::upload::upload_samples;
use morphray::gpu::{Access, Buffer, BufferDesc, Recording};
use morphray::passes::derivatives::DerivativeOutputs;
use morphray::passes::minmax::{MinMaxPass, decode_result};
use morphray::reference;
use morphray::reference::derivatives::{DerivativeOptions, IndexToWorld};
use morphray::volume::{SampleKind, Samples};

/// Runs only the min/max pass over `samples` (any count, no 3D-image limit).
fn gpu_min_max(engine: &morphray::engine::Engine, samples: &Samples) -> Option<(f64, f64)> {
    let device = engine.device();
    let pass = MinMaxPass::new(device, samples.kind(), ash::vk::PipelineCache::null()).unwrap();
    let mut rec = Recording::new(device, "test min/max").unwrap();
    let (buffer, _) = upload_samples(device, &mut rec, samples).unwrap();
    let result = Buffer::new(device, BufferDesc::gpu_storage("result", 8)).unwrap();
    rec.begin_pass("minmax");
    pass.record(device, &mut rec, &buffer, samples.len() as u64, &result)
        .unwrap();
    rec.end_pass();
    rec.submit().unwrap().wait().unwrap();
    let mut bytes = [0u8; 8];
    read_buffer(device, &result, Access::ComputeWriteBuffer, &mut bytes).unwrap();
    let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    decode_result(word(0), word(4))
}

fn random_f32(rng: &mut Rng, n: usize) -> Vec<f32> {
    let specials = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        -0.0,
        0.0,
        f32::MAX,
        f32::MIN,
        1e-45,
        -1e-40,
        f32::MIN_POSITIVE,
    ];
    (0..n)
        .map(|_| {
            let r = rng.unit();
            if r < 0.05 {
                specials[(rng.next_u64() % specials.len() as u64) as usize]
            } else {
                rng.range(-1e4, 1e4) as f32
            }
        })
        .collect()
}

fn samples_of_kind(kind: SampleKind, rng: &mut Rng, n: usize) -> Samples {
    match kind {
        SampleKind::U8 => Samples::from_u8((0..n).map(|_| rng.next_u64() as u8).collect()),
        SampleKind::I8 => {
            Samples::from_i8(&(0..n).map(|_| rng.next_u64() as i8).collect::<Vec<_>>())
        }
        SampleKind::U16 => {
            Samples::from_u16(&(0..n).map(|_| rng.next_u64() as u16).collect::<Vec<_>>())
        }
        SampleKind::I16 => {
            Samples::from_i16(&(0..n).map(|_| rng.next_u64() as i16).collect::<Vec<_>>())
        }
        SampleKind::F32 => Samples::from_f32(&random_f32(rng, n)),
    }
}

const KINDS: [SampleKind; 5] = [
    SampleKind::U8,
    SampleKind::I8,
    SampleKind::U16,
    SampleKind::I16,
    SampleKind::F32,
];

#[test]
fn min_max_is_exact_at_awkward_counts_for_every_kind() {
    let engine = common::engine();
    let mut rng = Rng(7);
    for kind in KINDS {
        for n in [1usize, 31, 32, 33, 63, 64, 65, 1000, 1_000_003] {
            let samples = samples_of_kind(kind, &mut rng, n);
            let gpu = gpu_min_max(&engine, &samples);
            let cpu = reference::minmax::finite_min_max(&samples);
            match (gpu, cpu) {
                (Some((g0, g1)), Some((c0, c1))) => {
                    assert_eq!(
                        (g0.to_bits(), g1.to_bits()),
                        (c0.to_bits(), c1.to_bits()),
                        "{kind:?} n={n}"
                    )
                }
                other => assert_eq!(other.0, other.1, "{kind:?} n={n}"),
            }
        }
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn min_max_handles_signed_zero_extremes_subnormals_and_all_nan() {
    let engine = common::engine();
    let cases: [&[f32]; 5] = [
        &[-0.0, 0.0],
        &[f32::MAX, f32::MIN, 0.0],
        &[1e-45, -1e-45, 2e-45],
        &[f32::NAN, f32::INFINITY, f32::NEG_INFINITY],
        &[-3e38, -1.0, -2e-38],
    ];
    for values in cases {
        let samples = Samples::from_f32(values);
        let gpu = gpu_min_max(&engine, &samples).map(|(a, b)| (a.to_bits(), b.to_bits()));
        let cpu =
            reference::minmax::finite_min_max(&samples).map(|(a, b)| (a.to_bits(), b.to_bits()));
        assert_eq!(gpu, cpu, "{values:?}");
    }
    common::assert_no_validation_errors(&engine);
}

/// Normalization within one R16 step of the f64 twin, and the histogram bit-exact with its twin
/// on the GPU's own normalized values.
fn check_normalize_and_histogram(
    engine: &mut morphray::engine::Engine,
    v: &morphray::volume::Volume,
) {
    let prepared = engine.prepare(v).unwrap();
    let cpu_range = reference::minmax::finite_min_max(&v.samples);
    assert_eq!(prepared.stored_range, cpu_range, "{:?}", v.dims);
    let image = read_image(
        engine.device(),
        &prepared.normalized,
        Access::ComputeSampled,
    )
    .unwrap();
    let finite: Vec<bool> = (0..v.voxel_count())
        .map(|i| v.samples.get(i).is_finite())
        .collect();
    if let Some((smin, smax)) = cpu_range {
        let (imin, imax) = reference::normalize::physical_range(smin, smax, v.to_physical);
        let expected = reference::normalize::normalize(&v.samples, v.to_physical, imin, imax);
        for (i, (&g, &e)) in image.values.iter().zip(&expected).enumerate() {
            assert!(
                (g as f64 - e).abs() <= 1.0 / 65535.0,
                "voxel {i} of {:?}: gpu {g} vs f64 {e}",
                v.dims
            );
        }
    }
    let twin = reference::histogram::histogram(&image.values, |i| finite[i]);
    assert_eq!(prepared.histogram, twin, "histogram of {:?}", v.dims);
    let finite_count = finite.iter().filter(|&&f| f).count() as u64;
    assert_eq!(prepared.finite_voxels, finite_count);
}

#[test]
fn normalize_and_histogram_match_their_twins_on_awkward_volumes() {
    let mut engine = common::engine();
    let mut rng = Rng(11);
    for dims in [
        [1usize, 1, 1],
        [31, 1, 1],
        [33, 1, 1],
        [7, 5, 3],
        [130, 97, 61],
    ] {
        let n = dims.iter().product();
        for kind in KINDS {
            if n > 100_000 && kind != SampleKind::I16 && kind != SampleKind::F32 {
                continue; // the large volume runs for the two common kinds (CI time)
            }
            check_normalize_and_histogram(
                &mut engine,
                &volume(dims, [1.0; 3], samples_of_kind(kind, &mut rng, n)),
            );
        }
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn histogram_puts_one_in_the_last_bin_and_sums_to_the_finite_count() {
    let mut engine = common::engine();
    let values: Vec<f32> = (0..105)
        .map(|i| if i % 10 == 3 { f32::NAN } else { i as f32 })
        .collect();
    let v = volume([7, 5, 3], [1.0; 3], Samples::from_f32(&values));
    let prepared = engine.prepare(&v).unwrap();
    assert!(
        prepared.histogram[255] >= 1,
        "the maximum (I_norm = 1.0) belongs to bin 255"
    );
    assert_eq!(
        prepared.histogram.iter().map(|&c| c as u64).sum::<u64>(),
        105 - 11
    );
    assert_eq!(prepared.nonfinite_voxels(), 11);
    common::assert_no_validation_errors(&engine);
}

#[test]
fn hard_ranges_normalize_finite_in_range_and_monotone() {
    let mut engine = common::engine();
    let cases: Vec<Vec<f32>> = vec![
        vec![7.0; 24],                                               // constant
        vec![f32::NAN; 24],                                          // all NaN
        (0..24).map(|i| -3e38 + i as f32 * 2.6e37).collect(),        // +-3e38
        (0..24).map(|i| 1e30 * (1.0 + i as f32 * 1.2e-7)).collect(), // 1e30 + tiny
        (0..24).map(|i| i as f32 * 1e-45).collect(),                 // subnormal
        (0..24).map(|i| -100.0 - i as f32).collect(),                // negative
    ];
    for values in cases {
        let v = volume([4, 3, 2], [1.0; 3], Samples::from_f32(&values));
        let prepared = engine.prepare(&v).unwrap();
        let image = read_image(
            engine.device(),
            &prepared.normalized,
            Access::ComputeSampled,
        )
        .unwrap();
        assert!(
            image
                .values
                .iter()
                .all(|x| x.is_finite() && (0.0..=1.0).contains(x)),
            "{values:?}"
        );
        let finite: Vec<(f32, f32)> = values
            .iter()
            .zip(&image.values)
            .filter(|(s, _)| s.is_finite())
            .map(|(&s, &n)| (s, n))
            .collect();
        for a in &finite {
            for b in &finite {
                if a.0 < b.0 {
                    assert!(a.1 <= b.1, "not monotone: {a:?} vs {b:?}");
                }
            }
        }
        let distinct_inputs = finite
            .iter()
            .map(|p| p.0.to_bits())
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        if prepared.normalization.constant {
            assert!(
                image.values.iter().all(|&x| x == 0.0),
                "constant volume normalizes to 0"
            );
            assert_eq!(prepared.histogram[0] as usize, finite.len());
        } else {
            assert!(distinct_inputs > 1);
            let lo = finite.iter().map(|p| p.1).fold(f32::INFINITY, f32::min);
            let hi = finite.iter().map(|p| p.1).fold(0.0, f32::max);
            assert_eq!((lo, hi), (0.0, 1.0), "the range spans [0, 1]: {values:?}");
        }
    }
    common::assert_no_validation_errors(&engine);
}

/// Compares the GPU derivative volumes (f16 storage) with the f64 twin run on the GPU's own
/// normalized values, so only the derivative kernel is under test.
fn check_derivatives(engine: &mut morphray::engine::Engine, v: &morphray::volume::Volume) {
    let prepared = engine.prepare(v).unwrap();
    let outputs = DerivativeOutputs {
        magnitude: true,
        curvature: true,
        normal: true,
        ..Default::default()
    };
    let derived = engine.derive(&prepared, outputs).unwrap();
    let device = engine.device();
    let norm = read_image(device, &prepared.normalized, Access::ComputeSampled).unwrap();
    let grad = read_image(
        device,
        derived.volumes.gradient.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    let normals = read_image(
        device,
        derived.volumes.normal.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    let values: Vec<f64> = norm.values.iter().map(|&x| x as f64).collect();
    let to_world = IndexToWorld::new(v.orientation.linear_part()).unwrap();
    let twin = reference::derivatives::derivatives(
        &values,
        v.dims,
        &to_world,
        &DerivativeOptions::default(),
    )
    .unwrap();
    let magnitude = twin.gradient_magnitude.unwrap();
    let curvature = twin.curvature.unwrap();
    let gradient = twin.gradient.unwrap();
    let g_scale = magnitude.iter().cloned().fold(0.0, f64::max).max(1e-9);
    let k_scale = curvature
        .iter()
        .map(|k| k.abs())
        .fold(0.0, f64::max)
        .max(1e-9);
    assert!(
        (derived.stats.max_magnitude - g_scale).abs() <= 1e-6 * g_scale + 1e-7,
        "max |g|"
    );
    // Stored in voxel units (|g| h, k h^2); back to world units.
    let [sg, sk] = derived.volumes.store_scale.map(f64::from);
    for i in 0..values.len() {
        let (gm, gk) = (
            grad.values[2 * i] as f64 / sg,
            grad.values[2 * i + 1] as f64 / sk,
        );
        // f16 storage: 2^-11 relative; f32 arithmetic on the same inputs: far below that.
        assert!(
            (gm - magnitude[i]).abs() <= 1e-3 * magnitude[i] + 1e-5 * g_scale,
            "|g| at {i}: {gm} vs {}",
            magnitude[i]
        );
        if magnitude[i] > 1e-3 * g_scale {
            assert!(
                (gk - curvature[i]).abs() <= 2e-3 * k_scale,
                "k at {i}: {gk} vs {}",
                curvature[i]
            );
            let n = &normals.values[4 * i..4 * i + 3];
            let unit = gradient[i].map(|c| c / magnitude[i]);
            for c in 0..3 {
                // RGBA8_SNORM: one step is 1/127.
                assert!(
                    (n[c] as f64 - unit[c]).abs() <= 1.0 / 127.0 + 1e-6,
                    "normal at {i}"
                );
            }
        }
    }
}

#[test]
fn derivatives_match_the_twin_on_anisotropic_and_oblique_volumes() {
    let mut engine = common::engine();
    let mut rng = Rng(5);
    let dims = [7usize, 5, 3];
    let field = smooth_field(dims, &mut rng, 0.0, 1000.0);
    let samples = Samples::from_f32(&field.iter().map(|&x| x as f32).collect::<Vec<_>>());
    check_derivatives(&mut engine, &volume(dims, [0.5, 1.0, 3.0], samples.clone()));
    let dims = [33usize, 29, 17];
    let field = smooth_field(dims, &mut rng, -500.0, 1500.0);
    let samples = Samples::from_i16(&field.iter().map(|&x| x as i16).collect::<Vec<_>>());
    // Oblique: rotated 30 degrees about z, anisotropic, flipped x.
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let affine = [
        [-0.8 * c, -1.2 * s, 0.0, 10.0],
        [-0.8 * s, 1.2 * c, 0.0, -5.0],
        [0.0, 0.0, 2.0, 3.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    check_derivatives(&mut engine, &volume_with_affine(dims, affine, samples));
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_linear_ramp_gives_the_exact_world_gradient_and_zero_curvature() {
    let mut engine = common::engine();
    // I = i + 2j + 3k on 6x4x3: the maximum 17 divides 65535, so R16 stores every value exactly.
    let dims = [6usize, 4, 3];
    let mut values = Vec::new();
    for k in 0..3 {
        for j in 0..4 {
            for i in 0..6 {
                values.push((i + 2 * j + 3 * k) as u16);
            }
        }
    }
    let v = volume(dims, [0.5, 1.0, 3.0], Samples::from_u16(&values));
    let prepared = engine.prepare(&v).unwrap();
    let derived = engine
        .derive(
            &prepared,
            DerivativeOutputs {
                magnitude: true,
                curvature: true,
                normal: false,
                ..Default::default()
            },
        )
        .unwrap();
    let grad = read_image(
        engine.device(),
        derived.volumes.gradient.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    let expected =
        ((1.0f64 / 17.0 / 0.5).powi(2) + (2.0f64 / 17.0).powi(2) + (3.0f64 / 17.0 / 3.0).powi(2))
            .sqrt();
    let [sg, sk] = derived.volumes.store_scale.map(f64::from);
    for i in 0..values.len() {
        let (m, k) = (
            grad.values[2 * i] as f64 / sg,
            grad.values[2 * i + 1] as f64 / sk,
        );
        assert!(
            (m - expected).abs() <= expected * 1e-3,
            "voxel {i}: |g| {m} vs {expected}"
        );
        assert!(k.abs() <= 1e-4, "voxel {i}: k = {k} on a linear ramp");
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_quadratic_bowl_has_constant_directional_curvature() {
    let mut engine = common::engine();
    // I = |x - c|^2 (mm^2) on a 1 mm grid: H = 2 I3 so k = 2 everywhere (in I units); after
    // normalization by the range R, k = 2 / R.
    let n = 24usize;
    let c = 11.3;
    let mut values = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                values.push(
                    ((i as f64 - c).powi(2) + (j as f64 - c).powi(2) + (k as f64 - c).powi(2))
                        as f32,
                );
            }
        }
    }
    let range = values.iter().cloned().fold(f32::MIN, f32::max)
        - values.iter().cloned().fold(f32::MAX, f32::min);
    let v = volume([n, n, n], [1.0; 3], Samples::from_f32(&values));
    let prepared = engine.prepare(&v).unwrap();
    let derived = engine
        .derive(
            &prepared,
            DerivativeOutputs {
                magnitude: true,
                curvature: true,
                normal: false,
                ..Default::default()
            },
        )
        .unwrap();
    let grad = read_image(
        engine.device(),
        derived.volumes.gradient.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    let expected = 2.0 / range as f64;
    let [sg, sk] = derived.volumes.store_scale.map(f64::from);
    let mut worst = 0.0f64;
    for i in 0..values.len() {
        if grad.values[2 * i] as f64 / sg > 1e-4 {
            worst = worst.max((grad.values[2 * i + 1] as f64 / sk - expected).abs() / expected);
        }
    }
    // R16 quantization of I (1/65535 of the range) against a second difference of 2/R: 1.5 %.
    assert!(worst < 0.02, "worst relative curvature error {worst}");
    common::assert_no_validation_errors(&engine);
}

#[test]
fn derived_outputs_are_only_those_requested() {
    let mut engine = common::engine();
    let v = volume(
        [9, 8, 7],
        [1.0; 3],
        Samples::from_u8((0..504).map(|i| (i % 251) as u8).collect()),
    );
    let prepared = engine.prepare(&v).unwrap();
    let before = engine.device().ledger().total_bytes();
    let only_max = engine
        .derive(&prepared, DerivativeOutputs::default())
        .unwrap();
    assert!(only_max.volumes.gradient.is_none() && only_max.volumes.normal.is_none());
    assert!(
        only_max.stats.max_magnitude > 0.0,
        "the maximum is computed even with no stored output"
    );
    let magnitude_only = engine
        .derive(
            &prepared,
            DerivativeOutputs {
                magnitude: true,
                ..Default::default()
            },
        )
        .unwrap();
    let g = magnitude_only.volumes.gradient.as_ref().unwrap();
    assert_eq!(
        g.format(),
        ash::vk::Format::R16_SFLOAT,
        "no curvature channel without curvature"
    );
    assert!(magnitude_only.volumes.normal.is_none());
    assert!(engine.device().ledger().total_bytes() > before);
    let _ = Buffer::new(engine.device(), BufferDesc::readback("probe", 4)).unwrap();
    common::assert_no_validation_errors(&engine);
}

#[test]
fn plateaus_and_constant_volumes_have_zero_gradient_curvature_and_normal() {
    let mut engine = common::engine();
    // Two exact plateaus (0 and 100) meeting at x = 10: away from the step every derivative is
    // exactly zero, and nothing anywhere is NaN.
    let dims = [21usize, 9, 7];
    let values: Vec<f32> = (0..dims.iter().product::<usize>())
        .map(|i| if i % 21 < 10 { 0.0 } else { 100.0 })
        .collect();
    let v = volume(dims, [1.0, 2.0, 0.5], Samples::from_f32(&values));
    let prepared = engine.prepare(&v).unwrap();
    let all = DerivativeOutputs {
        magnitude: true,
        curvature: true,
        normal: true,
        ..Default::default()
    };
    let derived = engine.derive(&prepared, all).unwrap();
    let device = engine.device();
    let grad = read_image(
        device,
        derived.volumes.gradient.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    let normals = read_image(
        device,
        derived.volumes.normal.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    for i in 0..values.len() {
        let x = i % 21;
        assert!(grad.values[2 * i].is_finite() && grad.values[2 * i + 1].is_finite());
        if !(8..=11).contains(&x) {
            assert_eq!(
                (grad.values[2 * i], grad.values[2 * i + 1]),
                (0.0, 0.0),
                "voxel {i}"
            );
            assert!(
                normals.values[4 * i..4 * i + 3].iter().all(|&c| c == 0.0),
                "voxel {i}: no direction on a plateau"
            );
        }
    }
    // A constant volume: I_norm = 0 everywhere, so everything is zero and max |g| is 0.
    let constant = volume([5, 4, 3], [1.0; 3], Samples::from_i16(&[42; 60]));
    let prepared = engine.prepare(&constant).unwrap();
    let derived = engine.derive(&prepared, all).unwrap();
    assert_eq!(derived.stats.max_magnitude, 0.0);
    let grad = read_image(
        engine.device(),
        derived.volumes.gradient.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    assert!(grad.values.iter().all(|&v| v == 0.0));
    common::assert_no_validation_errors(&engine);
}
