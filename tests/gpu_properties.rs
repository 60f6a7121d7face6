//! Property tests of the GPU kernels against their f64 CPU twins on random volumes: random sizes
//! (1..=40 per axis, 1 and primes favoured), random anisotropic spacings (0.1..10 mm), random
//! affines (rotation, flips, shear, translation), random intensity maps, and random values of
//! every sample kind (full and partial integer ranges; f32 ordinary, negative, subnormal,
//! 1e30 + tiny, +-3e38, with NaN/Inf sprinkled or everywhere), through `Engine::prepare` and
//! `Engine::derive`.
//!
//! What each case asserts (tolerances as in tests/gpu_kernels.rs, NUMERICS.md):
//! - min/max bit-exact with `reference::minmax::finite_min_max`; the finite count exact;
//! - I_norm within 1/65535 of `reference::normalize::normalize` (R16_UNORM storage), finite and
//!   in [0, 1];
//! - the histogram bit-exact with `reference::histogram::histogram` of the GPU's own read-back
//!   I_norm (so R16 rounding at a bin edge is not counted against the histogram kernel), summing
//!   to the finite count;
//! - gradient magnitude, curvature and normals against `reference::derivatives::derivatives` on
//!   the read-back I_norm with the volume's affine: |g| within 1e-3 relative + 1e-5 of max |g|
//!   (f16 storage), curvature within 2e-3 of max |k| where |g| > 1e-3 max |g|, both plus 2^-24
//!   (f16's resolution below 2^-14, see `F16_FLOOR`), normals within
//!   1/127 (RGBA8_SNORM), max |g| within 1e-6 relative (f32, no storage), and every output
//!   finite.
//!
//! One engine serves the whole run (a new one per case would rebuild every pipeline): it lives in a thread-local,
//! leaked on purpose so no Vulkan teardown runs during thread exit. Validation errors are checked
//! after every case, so a failure names the case that caused it.
//!
//! Cases: 128 by default (about 1 s on lavapipe on 2 cores); `PROPTEST_CASES=N` changes it.
//! Failures shrink and are saved to tests/gpu_properties.proptest-regressions.

mod common;

use common::volumes::{Rng, smooth_field};
use morphray::engine::Engine;
use morphray::engine::readback::read_image;
use morphray::gpu::Access;
use morphray::passes::derivatives::DerivativeOutputs;
use morphray::reference;
use morphray::reference::derivatives::{DerivativeOptions, IndexToWorld};
use morphray::volume::{AffineSource, LinearMap, Orientation, Samples, Volume};
use proptest::prelude::*;
use std::cell::RefCell;

thread_local! {
    static ENGINE: &'static RefCell<Engine> = Box::leak(Box::new(RefCell::new(common::engine())));
}

/// 128 cases unless `PROPTEST_CASES` says otherwise: every case is a GPU round trip, but small
/// volumes make one take about 7 ms on lavapipe; 32 cases once missed a min/max off-by-one
/// mutant that 128 caught 8 times out of 8.
fn config() -> ProptestConfig {
    let mut config = ProptestConfig::default();
    if std::env::var_os("PROPTEST_CASES").is_none() {
        config.cases = 128;
    }
    // Each shrink step is a GPU round trip too; a few hundred are plenty for these inputs.
    config.max_shrink_iters = 400;
    config
}

/// How the values of a case are drawn.
#[derive(Clone, Copy, Debug)]
enum Values {
    U8 { lo: u8, hi: u8 },
    I8 { lo: i8, hi: i8 },
    U16 { lo: u16, hi: u16 },
    I16 { lo: i16, hi: i16 },
    F32 { range: F32Range, nonfinite: f64 },
}

/// Ranges of f32 data that break naive kernels (NUMERICS.md "huge ranges").
#[derive(Clone, Copy, Debug)]
enum F32Range {
    /// Uniform in [lo, hi].
    Ordinary { lo: f32, hi: f32 },
    /// Entirely negative, far from zero.
    Negative,
    /// Subnormal values only (multiples of the smallest subnormal).
    Subnormal,
    /// 1e30 plus a relative spread of about 1e-6: a handful of distinct f32 values.
    HugeTiny,
    /// Spanning +-3e38: `max - min` overflows f32.
    Extreme,
}

/// One random volume.
#[derive(Clone, Debug)]
struct Case {
    dims: [usize; 3],
    spacing: [f64; 3],
    /// Euler angles (radians) of the rotation, applied z * y * x.
    angles: [f64; 3],
    flips: [bool; 3],
    /// Shears xy, xz, yz of a unit upper-triangular factor.
    shear: [f64; 3],
    translation: [f64; 3],
    map: LinearMap,
    values: Values,
    /// Smooth (sum of sinusoids) or white noise.
    smooth: bool,
    seed: u64,
}

fn axis() -> impl Strategy<Value = usize> {
    prop_oneof![
        2 => Just(1usize),
        3 => prop::sample::select(vec![2usize, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37]),
        5 => 1usize..=40,
    ]
}

fn values() -> impl Strategy<Value = Values> {
    let f32_range = prop_oneof![
        (-1e4f32..1e4, 0f32..1e4).prop_map(|(lo, w)| F32Range::Ordinary { lo, hi: lo + w }),
        Just(F32Range::Negative),
        Just(F32Range::Subnormal),
        Just(F32Range::HugeTiny),
        Just(F32Range::Extreme),
    ];
    let nonfinite = prop_oneof![
        4 => Just(0.0f64),
        3 => Just(0.02),
        2 => Just(0.3),
        1 => Just(1.0),
    ];
    prop_oneof![
        1 => any::<(u8, u8)>().prop_map(|(a, b)| Values::U8 {
            lo: a.min(b),
            hi: a.max(b)
        }),
        1 => any::<(i8, i8)>().prop_map(|(a, b)| Values::I8 {
            lo: a.min(b),
            hi: a.max(b)
        }),
        1 => any::<(u16, u16)>().prop_map(|(a, b)| Values::U16 {
            lo: a.min(b),
            hi: a.max(b)
        }),
        1 => any::<(i16, i16)>().prop_map(|(a, b)| Values::I16 {
            lo: a.min(b),
            hi: a.max(b)
        }),
        1 => Just(Values::U16 { lo: 0, hi: 65535 }),
        1 => Just(Values::I16 {
            lo: i16::MIN,
            hi: i16::MAX
        }),
        3 => (f32_range, nonfinite).prop_map(|(range, nonfinite)| Values::F32 { range, nonfinite }),
    ]
}

fn map() -> impl Strategy<Value = LinearMap> {
    (
        prop::sample::select(vec![1.0f64, 2.5, -1.0, -0.01, 1e-3, 7.0]),
        prop::sample::select(vec![0.0f64, 1000.0, -5e4, 0.5]),
    )
        .prop_map(|(slope, intercept)| LinearMap { slope, intercept })
}

fn case() -> impl Strategy<Value = Case> {
    let spacing = 0.1f64..10.0;
    let angle = -std::f64::consts::PI..std::f64::consts::PI;
    let shear = -0.3f64..0.3;
    (
        [axis(), axis(), axis()],
        [spacing.clone(), spacing.clone(), spacing],
        [angle.clone(), angle.clone(), angle],
        any::<[bool; 3]>(),
        [shear.clone(), shear.clone(), shear],
        [-100f64..100.0, -100f64..100.0, -100f64..100.0],
        map(),
        values(),
        any::<bool>(),
        any::<u64>(),
    )
        .prop_map(
            |(dims, spacing, angles, flips, shear, translation, map, values, smooth, seed)| Case {
                dims,
                spacing,
                angles,
                flips,
                shear,
                translation,
                map,
                values,
                smooth,
                seed,
            },
        )
}

fn mul3(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| a[r][k] * b[k][c]).sum()))
}

/// Index-to-world affine `R * Shear * diag(+-spacing)` plus the translation.
fn affine(case: &Case) -> [[f64; 4]; 4] {
    let [ax, ay, az] = case.angles;
    let (sx, cx) = ax.sin_cos();
    let (sy, cy) = ay.sin_cos();
    let (sz, cz) = az.sin_cos();
    let rx = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
    let ry = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
    let rz = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
    let [xy, xz, yz] = case.shear;
    let shear = [[1.0, xy, xz], [0.0, 1.0, yz], [0.0, 0.0, 1.0]];
    let scale: [[f64; 3]; 3] = std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            if r != c {
                0.0
            } else if case.flips[r] {
                -case.spacing[r]
            } else {
                case.spacing[r]
            }
        })
    });
    let linear = mul3(&mul3(&mul3(&rz, &ry), &rx), &mul3(&shear, &scale));
    let mut a = [[0.0; 4]; 4];
    for r in 0..3 {
        a[r][..3].copy_from_slice(&linear[r]);
        a[r][3] = case.translation[r];
    }
    a[3][3] = 1.0;
    a
}

/// `n` values in [lo, hi]: a smooth field or white noise.
fn field(case: &Case, rng: &mut Rng, lo: f64, hi: f64) -> Vec<f64> {
    let n = case.dims.iter().product();
    if case.smooth {
        smooth_field(case.dims, rng, lo, hi)
    } else {
        (0..n).map(|_| rng.range(lo, hi)).collect()
    }
}

fn samples(case: &Case) -> Samples {
    let mut rng = Rng(case.seed);
    // The top of an integer range is reachable: draw in [lo, hi + 1) and clamp.
    let ints = |rng: &mut Rng, lo: f64, hi: f64| -> Vec<f64> {
        field(case, rng, lo, hi + 1.0)
            .into_iter()
            .map(|x| x.floor().min(hi))
            .collect()
    };
    match case.values {
        Values::U8 { lo, hi } => Samples::from_u8(
            ints(&mut rng, lo.into(), hi.into())
                .into_iter()
                .map(|x| x as u8)
                .collect(),
        ),
        Values::I8 { lo, hi } => Samples::from_i8(
            &ints(&mut rng, lo.into(), hi.into())
                .into_iter()
                .map(|x| x as i8)
                .collect::<Vec<_>>(),
        ),
        Values::U16 { lo, hi } => Samples::from_u16(
            &ints(&mut rng, lo.into(), hi.into())
                .into_iter()
                .map(|x| x as u16)
                .collect::<Vec<_>>(),
        ),
        Values::I16 { lo, hi } => Samples::from_i16(
            &ints(&mut rng, lo.into(), hi.into())
                .into_iter()
                .map(|x| x as i16)
                .collect::<Vec<_>>(),
        ),
        Values::F32 { range, nonfinite } => {
            let base: Vec<f32> = match range {
                F32Range::Ordinary { lo, hi } => field(case, &mut rng, lo.into(), hi.into())
                    .into_iter()
                    .map(|x| x as f32)
                    .collect(),
                F32Range::Negative => field(case, &mut rng, -1e4, -1.0)
                    .into_iter()
                    .map(|x| x as f32)
                    .collect(),
                F32Range::Subnormal => field(case, &mut rng, -5000.0, 5000.0)
                    .into_iter()
                    .map(|x| x.round() as f32 * 1e-45)
                    .collect(),
                F32Range::HugeTiny => field(case, &mut rng, 0.0, 1e-6)
                    .into_iter()
                    .map(|x| (1e30 * (1.0 + x)) as f32)
                    .collect(),
                F32Range::Extreme => field(case, &mut rng, -3e38, 3e38)
                    .into_iter()
                    .map(|x| x as f32)
                    .collect(),
            };
            let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
            let values: Vec<f32> = base
                .into_iter()
                .map(|x| {
                    if rng.unit() < nonfinite {
                        specials[(rng.next_u64() % 3) as usize]
                    } else {
                        x
                    }
                })
                .collect();
            Samples::from_f32(&values)
        }
    }
}

fn volume(case: &Case) -> Volume {
    let affine = affine(case);
    let spacing_mm =
        std::array::from_fn(|c| (0..3).map(|r| affine[r][c].powi(2)).sum::<f64>().sqrt());
    Volume {
        name: "property".into(),
        dims: case.dims,
        spacing_mm,
        orientation: Orientation {
            affine,
            source: AffineSource::Synthetic,
        },
        samples: samples(case),
        to_physical: case.map,
        warnings: vec![],
        facts: Default::default(),
    }
}

/// f16's smallest step (2^-24): the absolute error of storing a value below 2^-14 (f16's
/// smallest normal number) in R16_SFLOAT/R16G16_SFLOAT, where the relative tolerances of
/// gpu_kernels.rs no longer hold. A full step, not half: Vulkan lets the conversion round toward
/// zero, and lavapipe stored a twin k of -1.777e-7 (2.98 steps) as -1.192e-7 (2 steps). Found by
/// this test: a 1x2x2 volume of 0.1 x 0.1 x 4.5 mm voxels has max |k| = 1.5e-6 per mm^2, so 2e-3
/// of it (3e-9) is far below what f16 can store.
const F16_FLOOR: f64 = 1.0 / (1u64 << 24) as f64;

/// `Err` with a message instead of a panic, so proptest shrinks the case.
macro_rules! ensure {
    ($cond:expr, $($fmt:tt)*) => {
        // Bound first: a NaN makes the comparison false, which must fail too.
        let holds: bool = $cond;
        if !holds {
            return Err(TestCaseError::fail(format!($($fmt)*)));
        }
    };
}

/// Every check of the module doc on one volume.
fn check(engine: &mut Engine, v: &Volume) -> Result<(), TestCaseError> {
    let n = v.voxel_count();
    let prepared = engine
        .prepare(v)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;

    // Min/max: bit-exact; finite count exact.
    let twin_range = reference::minmax::finite_min_max(&v.samples);
    let bits = |r: Option<(f64, f64)>| r.map(|(a, b)| (a.to_bits(), b.to_bits()));
    ensure!(
        bits(prepared.stored_range) == bits(twin_range),
        "min/max: gpu {:?} vs twin {:?}",
        prepared.stored_range,
        twin_range
    );
    let finite: Vec<bool> = (0..n).map(|i| v.samples.get(i).is_finite()).collect();
    let finite_count = finite.iter().filter(|&&f| f).count() as u64;
    ensure!(
        prepared.finite_voxels == finite_count,
        "finite count: gpu {} vs {finite_count}",
        prepared.finite_voxels
    );
    ensure!(
        n as u64 - finite_count == reference::minmax::nonfinite_count(&v.samples) as u64,
        "nonfinite count of the twin"
    );

    // Normalization: within one R16 step of the f64 twin, every value finite and in [0, 1].
    let device = engine.device();
    let norm = read_image(device, &prepared.normalized, Access::ComputeSampled)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    ensure!(
        norm.values.len() == n,
        "normalized image has {} values",
        norm.values.len()
    );
    for (i, &g) in norm.values.iter().enumerate() {
        ensure!(
            g.is_finite() && (0.0..=1.0).contains(&g),
            "I_norm[{i}] = {g} is outside [0, 1]"
        );
    }
    let expected = match twin_range {
        Some((smin, smax)) => {
            let (imin, imax) = reference::normalize::physical_range(smin, smax, v.to_physical);
            reference::normalize::normalize(&v.samples, v.to_physical, imin, imax)
        }
        // No finite voxel: the constant-volume policy, I_norm = 0 everywhere.
        None => vec![0.0; n],
    };
    for (i, (&g, &e)) in norm.values.iter().zip(&expected).enumerate() {
        ensure!(
            (f64::from(g) - e).abs() <= 1.0 / 65535.0,
            "I_norm[{i}]: gpu {g} vs f64 {e} (stored {})",
            v.samples.get(i)
        );
    }

    // Histogram: bit-exact with the twin on the GPU's own I_norm.
    let twin_hist = reference::histogram::histogram(&norm.values, |i| finite[i]);
    if prepared.histogram != twin_hist {
        let first = (0..twin_hist.len())
            .find(|&b| prepared.histogram[b] != twin_hist[b])
            .unwrap_or(0);
        return Err(TestCaseError::fail(format!(
            "histogram differs first at bin {first}: gpu {} vs twin {}",
            prepared.histogram[first], twin_hist[first]
        )));
    }
    let sum: u64 = prepared.histogram.iter().map(|&c| u64::from(c)).sum();
    ensure!(
        sum == finite_count,
        "histogram sums to {sum}, not {finite_count}"
    );

    // Derivatives against the twin on the read-back I_norm.
    let all = DerivativeOutputs {
        magnitude: true,
        curvature: true,
        normal: true,
        ..Default::default()
    };
    let derived = engine
        .derive(&prepared, all)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let device = engine.device();
    let image = |img: Option<&std::sync::Arc<morphray::gpu::Image>>| {
        img.ok_or_else(|| TestCaseError::fail("a requested output is missing"))
            .and_then(|img| {
                read_image(device, img, Access::ComputeSampled)
                    .map_err(|e| TestCaseError::fail(e.to_string()))
            })
    };
    let grad = image(derived.volumes.gradient.as_ref())?;
    let normals = image(derived.volumes.normal.as_ref())?;
    ensure!(
        grad.values.len() == 2 * n && normals.values.len() == 4 * n,
        "derived image sizes"
    );
    ensure!(
        grad.values
            .iter()
            .chain(&normals.values)
            .all(|x| x.is_finite()),
        "a derived output is not finite"
    );
    let values: Vec<f64> = norm.values.iter().map(|&x| f64::from(x)).collect();
    let to_world = IndexToWorld::new(v.orientation.linear_part())
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let twin = reference::derivatives::derivatives(
        &values,
        v.dims,
        &to_world,
        &DerivativeOptions::default(),
    )
    .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let (Some(magnitude), Some(curvature), Some(gradient)) =
        (twin.gradient_magnitude, twin.curvature, twin.gradient)
    else {
        return Err(TestCaseError::fail("the twin computed no gradient"));
    };
    let g_scale = magnitude.iter().copied().fold(0.0, f64::max).max(1e-9);
    let k_scale = curvature
        .iter()
        .map(|k| k.abs())
        .fold(0.0, f64::max)
        .max(1e-9);
    let max_g = derived.stats.max_magnitude;
    ensure!(
        max_g.is_finite() && (max_g - g_scale).abs() <= 1e-6 * g_scale + 1e-7,
        "max |g|: gpu {max_g} vs twin {g_scale}"
    );
    // Stored values are |g| s[0] and k s[1] (voxel units, s = [h, h^2]); the f16 floor applies
    // to the stored value, so in world units it is F16_FLOOR / s.
    let [sg, sk] = derived.volumes.store_scale.map(f64::from);
    for i in 0..n {
        let (gm, gk) = (
            f64::from(grad.values[2 * i]) / sg,
            f64::from(grad.values[2 * i + 1]) / sk,
        );
        // f16 storage: 2^-11 relative for normal f16 values, plus F16_FLOOR for values in f16's
        // subnormal range; f32 arithmetic on the same inputs: far below that.
        ensure!(
            (gm - magnitude[i]).abs() <= 1e-3 * magnitude[i] + 1e-5 * g_scale + F16_FLOOR / sg,
            "|g| at {i}: gpu {gm} vs twin {} (max {g_scale})",
            magnitude[i]
        );
        if magnitude[i] > 1e-3 * g_scale {
            ensure!(
                (gk - curvature[i]).abs() <= 2e-3 * k_scale + F16_FLOOR / sk,
                "k at {i}: gpu {gk} vs twin {} (max |k| {k_scale})",
                curvature[i]
            );
            let unit = gradient[i].map(|c| c / magnitude[i]);
            for (c, (&got, want)) in normals.values[4 * i..4 * i + 3]
                .iter()
                .zip(unit)
                .enumerate()
            {
                let got = f64::from(got);
                // RGBA8_SNORM: one step is 1/127.
                ensure!(
                    (got - want).abs() <= 1.0 / 127.0 + 1e-6,
                    "normal[{c}] at {i}: gpu {got} vs twin {want}"
                );
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn kernels_match_their_f64_twins_on_random_volumes(case in case()) {
        let v = volume(&case);
        ENGINE.with(|engine| {
            let mut engine = engine.borrow_mut();
            let result = check(&mut engine, &v);
            common::assert_no_validation_errors(&engine);
            result
        })?;
    }
}

/// The two cases the property test found (shrunk), pinned: curvatures in f16's subnormal range
/// (max |k| 1.5e-6 and 1.8e-7 per mm^2), where storage rounds by up to 2^-24 (`F16_FLOOR`).
#[test]
fn derivatives_in_f16_subnormal_range_match_within_one_f16_step() {
    let axis_aligned = |dims, spacing, values, seed| Case {
        dims,
        spacing,
        angles: [0.0; 3],
        flips: [false; 3],
        shear: [0.0; 3],
        translation: [0.0; 3],
        map: LinearMap::IDENTITY,
        values,
        smooth: true,
        seed,
    };
    let cases = [
        axis_aligned(
            [1, 2, 2],
            [0.1, 0.1, 4.490360022077925],
            Values::I8 { lo: -75, hi: -50 },
            1967819307573548750,
        ),
        axis_aligned(
            [1, 1, 3],
            [0.1, 0.1, 9.265825980181367],
            Values::U8 { lo: 88, hi: 113 },
            7484345476307438817,
        ),
    ];
    ENGINE.with(|engine| {
        let mut engine = engine.borrow_mut();
        for case in &cases {
            if let Err(e) = check(&mut engine, &volume(case)) {
                panic!("{case:?}: {e}");
            }
        }
        common::assert_no_validation_errors(&engine);
    });
}
