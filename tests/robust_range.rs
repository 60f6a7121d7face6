//! Robust normalization (`--normalize robust`): the fine-histogram kernel against its twin at
//! awkward counts for every sample kind, and the robust range the GPU finds against its exact
//! f64 definition (sorted values) on hot voxels, NaN/Inf, negative slopes, constant and
//! two-valued volumes, on the GPU path and the bricked host path, with zero validation errors.

mod common;

use common::volumes::{Rng, volume};
use morphray::analysis::NormalizeMode;
use morphray::analysis::range::{MIN_SPAN_BINS, exact_robust_range};
use morphray::engine::readback::read_buffer;
use morphray::engine::upload::upload_samples;
use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::{Access, Buffer, BufferDesc, DeviceConfig, Recording, Validation};
use morphray::passes::fine_histogram::{FineHistogramPass, RESULT_BYTES, decode};
use morphray::passes::normalize::{self, NormalizeParams};
use morphray::reference::fine_histogram::{FINE_BINS, RangeHistogram};
use morphray::volume::{LinearMap, SampleKind, Samples, Volume};

fn robust_engine() -> Engine {
    let config = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        normalize: NormalizeMode::Robust,
        ..Default::default()
    };
    Engine::new(config).unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        )
    })
}

/// Runs only the fine-histogram pass over `samples` with `mapping`.
fn gpu_counts(engine: &Engine, samples: &Samples, mapping: &NormalizeParams) -> RangeHistogram {
    let device = engine.device();
    let pass = FineHistogramPass::new(device, samples.kind(), ash::vk::PipelineCache::null())
        .expect("pipeline");
    let mut rec = Recording::new(device, "test fine histogram").unwrap();
    let (buffer, _) = upload_samples(device, &mut rec, samples).unwrap();
    let counts = Buffer::new(device, BufferDesc::gpu_storage("counts", RESULT_BYTES)).unwrap();
    rec.begin_pass("fine histogram");
    pass.record(
        device,
        &mut rec,
        &buffer,
        samples.len() as u64,
        mapping,
        &counts,
    )
    .unwrap();
    rec.end_pass();
    rec.submit().unwrap().wait().unwrap();
    let mut bytes = vec![0u8; RESULT_BYTES as usize];
    read_buffer(device, &counts, Access::ComputeWriteBuffer, &mut bytes).unwrap();
    decode(&bytes, 0.0, 1.0)
}

/// The kernel's own f32 arithmetic (`(ldexp(s, e) - offset) * scale`, then the bin rule), which
/// it must match exactly: a subtraction followed by a product leaves a compiler nothing to fuse.
fn f32_counts(samples: &Samples, p: &NormalizeParams) -> RangeHistogram {
    let mut h = RangeHistogram::empty(0.0, 1.0);
    for i in 0..samples.len() {
        let s = samples.get(i);
        if !s.is_finite() {
            continue;
        }
        let scaled = (s * 2f64.powi(p.pre_exponent)) as f32;
        let x = (scaled - p.offset) * p.scale;
        if x < 0.0 {
            h.under += 1;
        } else if x > 1.0 {
            h.over += 1;
        } else {
            h.bins[((x * FINE_BINS as f32) as usize).min(FINE_BINS - 1)] += 1;
            let x = f64::from(x.abs());
            h.inside = Some(h.inside.map_or((x, x), |(a, b)| (a.min(x), b.max(x))));
        }
    }
    h
}

fn random_samples(kind: SampleKind, rng: &mut Rng, n: usize) -> Samples {
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
        SampleKind::F32 => {
            let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 3e38, -1e-40];
            let values: Vec<f32> = (0..n)
                .map(|i| match i % 97 {
                    0..=4 => specials[i % 97],
                    _ => rng.range(-50.0, 900.0) as f32,
                })
                .collect();
            Samples::from_f32(&values)
        }
    }
}

#[test]
fn fine_histogram_matches_its_twin_at_awkward_counts_for_every_kind() {
    let engine = robust_engine();
    let mut rng = Rng(11);
    let kinds = [
        SampleKind::U8,
        SampleKind::I8,
        SampleKind::U16,
        SampleKind::I16,
        SampleKind::F32,
    ];
    let mut compared = 0;
    for kind in kinds {
        for n in [1usize, 31, 33, 257, 100_003] {
            let samples = random_samples(kind, &mut rng, n);
            let map = LinearMap {
                slope: -1.5,
                intercept: 7.0,
            };
            // An interval inside the data, so under, over and every bin are exercised.
            let Some((lo, hi)) = morphray::reference::finite_min_max(&samples)
                .map(|(a, b)| morphray::reference::physical_range(a, b, map))
            else {
                continue;
            };
            let (a, b) = (lo + (hi - lo) * 0.1, lo + (hi - lo) * 0.8);
            let plan = normalize::plan_physical([n as u32, 1, 1], a, b, map);
            if plan.constant {
                continue;
            }
            let gpu = gpu_counts(&engine, &samples, &plan.params);
            assert_eq!(gpu, f32_counts(&samples, &plan.params), "{kind:?} x {n}");
            // The f64 twin differs only for values within an f32 rounding of a bin edge.
            let twin = morphray::reference::fine_histogram::fine_histogram(
                &samples,
                map,
                plan.imin.unwrap(),
                b,
            );
            assert_eq!(gpu.total(), twin.total(), "{kind:?} x {n}");
            let moved: u64 = gpu
                .bins
                .iter()
                .zip(&twin.bins)
                .map(|(g, t)| g.abs_diff(*t))
                .sum();
            assert!(
                moved * 100 <= twin.total().max(100),
                "{kind:?} x {n}: {moved} moved"
            );
            compared += 1;
        }
    }
    // Volumes without a usable interval (1 voxel, constant) are passed over; the rest ran.
    assert!(compared >= 16, "only {compared} of 25 cases compared");
    common::assert_no_validation_errors(&engine);
}

/// A head-like volume: 60 % air at 0..4, tissue 200..1000, and `hot` voxels at 40x the tissue.
fn head_like(dims: [usize; 3], hot: usize, seed: u64) -> Vec<f32> {
    let mut rng = Rng(seed);
    let n = dims.iter().product();
    let mut values: Vec<f32> = (0..n)
        .map(|_| {
            if rng.unit() < 0.6 {
                rng.range(0.0, 4.0) as f32
            } else {
                rng.range(200.0, 1000.0) as f32
            }
        })
        .collect();
    for k in 0..hot {
        values[(k * 7919 + 13) % n] = 40_000.0;
    }
    values
}

/// Checks the GPU and host robust ranges of `v` against the exact definition.
fn check_against_definition(engine: &mut Engine, v: &Volume, what: &str) {
    let exact = exact_robust_range(&v.samples, v.to_physical).expect("finite voxels");
    assert!(!exact.fell_back, "{what}: {exact:?}");
    // The documented bound: one final-pass bin, at most 1/MIN_SPAN_BINS of the range; one more
    // for an f32 rounding across an edge.
    let tolerance = 2.0 * (exact.hi - exact.lo) / (MIN_SPAN_BINS - 1) as f64;
    let prepared = engine.prepare(v).expect("prepare");
    let gpu = prepared.range.robust.expect("a robust range");
    let host = engine
        .prepare_on_host(v, ash::vk::Format::R16_UNORM)
        .expect("host")
        .range
        .robust
        .expect("a host robust range");
    for (path, found) in [("gpu", gpu), ("host", host)] {
        assert!(
            (found.lo - exact.lo).abs() <= tolerance && (found.hi - exact.hi).abs() <= tolerance,
            "{what} ({path}): {found:?} vs exact {exact:?} (tolerance {tolerance})"
        );
    }
    let n = &prepared.normalization;
    assert!(!n.constant, "{what}");
    assert!(
        (n.imax.unwrap() - gpu.hi).abs() <= tolerance,
        "{what}: {n:?}"
    );
    assert!(
        (n.imin.unwrap() - gpu.lo).abs() <= tolerance,
        "{what}: {n:?}"
    );
}

#[test]
fn robust_ranges_match_the_exact_definition_on_hard_volumes() {
    let mut engine = robust_engine();
    // Hot voxels in u16 (one refinement pass), at an awkward size.
    let dims = [33, 17, 9];
    let values = head_like(dims, 5, 1);
    let u16s: Vec<u16> = values.iter().map(|&v| v as u16).collect();
    check_against_definition(
        &mut engine,
        &volume(dims, [1.0; 3], Samples::from_u16(&u16s)),
        "u16 hot voxels",
    );
    // f32 with NaN and infinities and a negative slope (physical = 100 - 2 stored).
    let dims = [31, 7, 5];
    let mut values = head_like(dims, 3, 2);
    values[0] = f32::NAN;
    values[100] = f32::INFINITY;
    values[200] = f32::NEG_INFINITY;
    let mut v = volume(dims, [1.0; 3], Samples::from_f32(&values));
    v.to_physical = LinearMap {
        slope: -2.0,
        intercept: 100.0,
    };
    check_against_definition(&mut engine, &v, "f32 NaN/Inf, negative slope");
    // i16 with scl_slope/intercept into negative physical values.
    let dims = [19, 23, 3];
    let i16s: Vec<i16> = head_like(dims, 4, 3)
        .iter()
        .map(|&v| (v / 2.0) as i16)
        .collect();
    let mut v = volume(dims, [1.0; 3], Samples::from_i16(&i16s));
    v.to_physical = LinearMap {
        slope: 0.25,
        intercept: -3000.0,
    };
    check_against_definition(&mut engine, &v, "i16 slope/intercept");
    // Tissue at 1..2 with a hot voxel at 1e30: several refinement passes.
    let dims = [17, 13, 11];
    let mut rng = Rng(4);
    let mut values: Vec<f32> = (0..dims.iter().product::<usize>())
        .map(|_| rng.range(1.0, 2.0) as f32)
        .collect();
    values[7] = 1e30;
    check_against_definition(
        &mut engine,
        &volume(dims, [1.0; 3], Samples::from_f32(&values)),
        "a hot voxel at 1e30",
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_handful_of_hot_voxels_leaves_the_robust_range_where_the_clean_scan_has_it() {
    let mut engine = robust_engine();
    let dims = [40, 36, 28];
    let clean = volume(dims, [1.0; 3], Samples::from_f32(&head_like(dims, 0, 5)));
    let hot = volume(dims, [1.0; 3], Samples::from_f32(&head_like(dims, 6, 5)));
    let a = engine.prepare(&clean).unwrap().normalization;
    let b = engine.prepare(&hot).unwrap().normalization;
    let span = a.imax.unwrap() - a.imin.unwrap();
    assert!(
        (a.imax.unwrap() - b.imax.unwrap()).abs() < 0.005 * span
            && (a.imin.unwrap() - b.imin.unwrap()).abs() < 0.005 * span,
        "clean {a:?} vs hot {b:?}"
    );
    // 10 % headroom above the tissue (P99.5 of the foreground near 1000), far below 40 000.
    assert!(b.imax.unwrap() < 1110.0, "{b:?}");
    common::assert_no_validation_errors(&engine);
}

#[test]
fn constant_two_valued_and_empty_volumes_keep_the_min_max_rules() {
    let mut engine = robust_engine();
    let constant = volume([5, 3, 2], [1.0; 3], Samples::from_f32(&[7.0; 30]));
    let p = engine.prepare(&constant).unwrap();
    assert!(p.normalization.constant && p.range.robust.is_none());
    assert_eq!(p.histogram[0], 30);

    // 99.8 % zeros and 0.2 % at 1000: both percentiles are 0, so the rule gives no range and
    // eq. 1's min/max is used; 1 % at 1000 is a range (the foreground's 99.5th percentile is
    // 1000, plus 10 % headroom).
    for (high, fell_back, top) in [(2, true, 1000.0), (10, false, 1100.0)] {
        let mut values = vec![0u16; 1000];
        for v in values.iter_mut().take(high) {
            *v = 1000;
        }
        let two = volume([10, 10, 10], [1.0; 3], Samples::from_u16(&values));
        let p = engine.prepare(&two).unwrap();
        let robust = p.range.robust.expect("the rule ran");
        assert_eq!(robust.fell_back, fell_back, "{robust:?}");
        let n = &p.normalization;
        assert!(
            n.imin.unwrap().abs() < 0.5 && (n.imax.unwrap() - top).abs() < 0.5,
            "{n:?}"
        );
        let bright = p.histogram.iter().rposition(|&c| c > 0).unwrap();
        assert_eq!(
            (p.histogram[0], p.histogram[bright]),
            (1000 - high as u32, high as u32)
        );
    }

    let nan = volume([3, 1, 1], [1.0; 3], Samples::from_f32(&[f32::NAN; 3]));
    let p = engine.prepare(&nan).unwrap();
    assert!(p.normalization.constant && p.range.robust.is_none());
    assert_eq!(p.range.data_min, None);
    common::assert_no_validation_errors(&engine);
}
