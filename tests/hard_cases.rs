//! Hard cases that must stay numerically stable (NUMERICS.md at the repository root), through the real engine
//! on the GPU: prepare (min/max, normalize, histogram), derive and render, on the data, shapes
//! and grids where a missing technique turns into NaN, a wrong range or a wrong image.
//!
//! # Every NUMERICS.md row and the tests that cover it
//!
//! Files: `hc` = this file, `hcc` = hard_cases_compositing.rs, `hcg` = hard_cases_geometry.rs,
//! `hcr` = hard_cases_reductions.rs; `gk` = gpu_kernels.rs, `gr` = gpu_raymarch.rs,
//! `rr` = reference_raymarch.rs, `ref` = reference.rs (CPU twins), `unit` = unit tests in src/.
//! "Mutation" is the technique removed once in a scratch build (lavapipe) and which test failed
//! (the results and the uncaught cases are in the issue-6 report).
//!
//! | row | technique | new tests (GPU) | existing tests | mutation -> failing test |
//! |---|---|---|---|---|
//! | constant volume (Imax == Imin) | CPU branch: scale 0, I_norm 0 | hc `hard_data_*` (constant: flag, finite params, I_norm 0, histogram [N, 0..], \|g\| 0, background image), hc `single_voxel_*` | gk `hard_ranges_*`, gk `plateaus_and_constant_*`, ref `normalize_constant_*`, unit `constant_and_empty_*` | drop the branch (scale = inf) -> hc `hard_data_*`, `single_voxel_*` |
//! | NaN / +-Inf voxels | bit tests in min/max, normalize, histogram; NaN -> I_norm 0 | hc `hard_data_*` (all NaN, all +-Inf, mixed incl. NaN payloads), hc `a_nan_block_*`, hcr `histogram_*` | gk `histogram_puts_one_*`, gk `min_max_handles_*`, ref `minmax_f32_skips_*`, ref `histogram_counts_only_finite_*` | each of the 3 bit tests -> hc `hard_data_*` (+ hcr, `a_nan_block_*`) |
//! | huge ranges (+-3e38, 1e30 + tiny) | f64 plan, power-of-two pre-exponent, offset = a sample | hc `hard_data_*` (+-3e38, +-FLT_MAX, 1e30 + 128 ulps, subnormal, negative: within 1/65535 of f64 eq. 1, monotone) | gk `hard_ranges_*`, unit `extreme_ranges_*`, ref `normalize_huge_range_*` | pre-exponent 0 -> hc `hard_data_*`; subnormal decode removed: NOT caught on lavapipe (no flush to zero) |
//! | float64 data at +-1.7e308 | half-range `imax/2 - imin/2`, scale `(slope / range) 2^-e`, peak raw `(1-n) imin + n imax` | hc `float64_data_near_the_f64_limit_*` (+-1.5e308 through a 2^1000 slope: within 1/65535 of the f64 twin, used voxels > 0, finite peaks) | unit `float64_ranges_near_the_f64_limit_*` | full range instead of half -> hc `float64_*`, unit `float64_*` |
//! | value exactly 1.0 in the histogram | `min(u32(clamp(x,0,1)*256), 255)` | hcr `histogram_and_range_*` (n = 1 .. 4096), hcr `histogram_of_a_million_*` | gk `histogram_puts_one_*`, ref `histogram_bin_edges_*`, ref `histogram_bin_is_exact_floor` | `* 255` and dropping `min` -> hcr both, hc `hard_data_*` |
//! | zero gradient | `\|g\| > tau ? g/\|g\| : 0`; curvature gated | hc `exact_plateaus_*` (precomputed + on the fly, shading + curvature), hc `hard_data_*` (constant) | gk `plateaus_and_constant_*`, gk `a_linear_ramp_*` (k = 0), ref `plateaus_*` | derivatives.comp guard -> hc `exact_plateaus_*`, `hard_data_*`, `single_voxel_*`; raymarch on-the-fly guards: NOT caught on lavapipe (see report) |
//! | anisotropic voxels | per-axis spacing, A^-T | hc `a_linear_ramp_on_a_0_1_x_0_1_x_10_*`, hc `a_world_object_on_a_0_1_x_0_1_x_10_*` | gk `a_linear_ramp_*` (0.5 x 1 x 3), gk `derivatives_match_*`, gr `anisotropic_and_flipped_*`, ref `linear_ramp_on_anisotropic_*` | A^-T dropped (stored or on the fly) -> hc both |
//! | curvature | H from f32 samples | hc `single_voxel_*` (k vs f64 twin), hc `f16_derivatives_*` | gk `a_quadratic_bowl_*`, ref `sphere_distance_field_*` | samples rounded to f16 -> gk bowl, hc `single_voxel_*`, hc `f16_derivatives_*` |
//! | f16 storage of derivatives | NUMERICS: voxel units, spacing at use | hc `f16_derivatives_*` (0.1 .. 10 mm: within one f16 ulp), hc `f16_curvature_stays_finite_at_micrometre_spacing` (1 and 3 um) | - | stored in voxel units (|g| h, k h^2); removing the scale fails hc `f16_curvature_*` |
//! | opacity correction `1-(1-a)^r` | `-expm1(r log1p(-a))` via series | hcc `gpu_opacity_correction_*` (probe, log grid, naive fails), hcc `homogeneous_medium_*` (a = 0.05, 1e-4, 1e-6) | gr `opacity_correction_makes_*`, rr `homogeneous_slab_*`, rr `oblique_rays_*` | naive pow -> hcc both; no correction -> hcc `homogeneous_*`, gr step size |
//! | accumulation | f32 registers | hcc `gpu_compositing_in_f32_*` (probe: f16 gives 0.756), hcc `three_thousand_*` (raymarch), hcc `early_termination_*` | - | f16 accumulator -> hcc `three_thousand_*`, `homogeneous_*`; ERT at 0.99 -> hcc `early_*` |
//! | ray-box with zero direction components, rays on faces, grazing rays, camera inside | \|d\| < 1e-20 containment, clamped count, start at max(t_near, 0) | hcg `gpu_rays_on_faces_*` (faces, edges, corners, grazing, eye on a face / at the centre; sample counts), hcg `gpu_rays_exactly_on_a_face_*`, hcg `views_at_90_degrees_keep_face_rays_on_the_face` (exact sin/cos of degrees) | gr `camera_inside_faces_*`, gr `no_nan_pixel_*`, rr `rays_exactly_on_faces_*`, rr `grazing_*`, unit `axis_aligned_rays_*` | containment branch -> hcg both; t_near clamp -> hcg `gpu_rays_on_faces_*`; count clamp: NOT caught (never negative here) |
//! | subgroup reductions at sizes not multiple of workgroup or subgroup | identity in idle lanes, uniform loops | hcr `histogram_and_range_*` (n = 1, 2, 7, 31, 32, 33, 63, 64, 65, 255 .. 257, 1000, 4093, 4096), hcr `histogram_of_a_million_*` (101 x 103 x 97), hcr `derivative_maximum_*` | gk `min_max_is_exact_*` (n up to 1000003), gk `normalize_and_histogram_match_*`, unit `linear_dispatch_*` | histogram / min-max range masks -> hcr; derivatives mask: NOT caught on lavapipe (see report) |
//! | float atomics | integer atomics on order-preserving keys | hcr `range_is_exact_over_negatives_*` | gk `min_max_handles_*`, ref `minmax_orders_negative_zero_*` | raw float bits as keys -> hcr, hc `hard_data_*` |
//! | trilinear sampling next to invalid voxels | NaN -> I_norm 0 (transparent), trilinear is convex | hc `a_nan_block_*` (= air block exactly; MIP never above the block-free MIP) | - | bit test dropped, or NaN -> 0.5 -> hc `a_nan_block_*` |
//! | eigenvalues of a symmetric 3x3 (Hessian, vesselness) | Jacobi on the max-entry-scaled matrix, bit test for NaN/Inf | `eigenvalues.rs` `gpu_eigenvalues_are_within_the_bound_where_the_naive_form_fails` (probe, hard spectra x 1e+-30/36; the naive closed form on the same device fails it), `eigenvalues.rs` `gpu_eigenvalues_of_non_finite_*`, `eigenvalues.rs` `twin_*` | unit `reference::eigen` | scaling removed (m = 1) -> `gpu_eigenvalues_are_within_*` (7.9e5 x the bound at rank 2 x 1e36); closed form instead of Jacobi -> the naive column of the same test (180 x on nearly repeated) |
//! | step-size invariance (cheapest test) | opacity correction | hcc `homogeneous_medium_*` (A = 1 - e^-tau L at 0.25 / 0.5 / 1 voxel) | gr `opacity_correction_makes_*`, rr `homogeneous_slab_*` | as opacity correction |
//! | histogram sum = finite voxels (cheapest test) | bit test + bin clamp | hcr both histogram tests, hc `hard_data_*` | gk `histogram_puts_one_*` | as NaN rows |

mod common;
mod hard_support;

use common::volumes::{Rng, smooth_field};
use hard_support::{
    ALL_OUTPUTS, CheckedPrepare, assert_finite_in_range, compare, derived_data, normalized,
    prepare_checked, reference, render, volume, volume_with_affine,
};
use morphray::engine::{Engine, PreparedVolume};
use morphray::reference;
use morphray::reference::derivatives::{DerivativeOptions, IndexToWorld};
use morphray::scene::{
    Camera, Classification, GradientSource, Projection, RenderMode, Scene, TissueClass,
    VolumeGeometry, Window,
};
use morphray::volume::{Samples, Volume};

// ---------------------------------------------------------------------------------------------
// Helpers

/// Three windows over (0.1, 1.05): I_norm 0 (where NaN voxels and the minimum go) has weight
/// exactly 0, so it is transparent.
fn tissue_scene() -> Scene {
    let window = |lo, hi| Some(Window { lo, hi, edge: 0.05 });
    let mut classification = Classification::with_windows([
        window(0.15, 0.4),
        window(0.4, 0.7),
        window(0.7, 1.05),
        None,
    ]);
    classification.show_only(&[TissueClass::Csf, TissueClass::Gm, TissueClass::Wm]);
    let mut scene = Scene::new(classification);
    scene.camera.azimuth_deg = 30.0;
    scene.camera.elevation_deg = 20.0;
    scene.background = [0.1, 0.2, 0.3];
    scene
}

/// Checks everything `prepare` promises on `v` against the f64 twins, and returns I_norm.
fn check_prepare(label: &str, engine: &mut Engine, v: &Volume) -> (PreparedVolume, Vec<f32>) {
    // Range = the finite range, bit for bit (asserted by prepare_checked).
    let CheckedPrepare {
        prepared,
        finite,
        finite_count,
        cpu_range,
        norm,
    } = prepare_checked(label, engine, v);
    let n = v.voxel_count();
    assert_eq!(norm.len(), n);
    for (i, x) in norm.iter().enumerate() {
        assert!(
            x.is_finite() && (0.0..=1.0).contains(x),
            "{label}: I_norm[{i}] = {x}"
        );
    }
    // Within one R16 step of eq. 1 evaluated in f64 (non-finite voxels -> 0). The GPU's f32
    // arithmetic on pre-scaled samples is exact to a few 2^-24, far below 1/65535; R16 rounding
    // is half a step.
    if let Some((smin, smax)) = cpu_range {
        let (imin, imax) = reference::normalize::physical_range(smin, smax, v.to_physical);
        let expected = reference::normalize::normalize(&v.samples, v.to_physical, imin, imax);
        for (i, (&g, &e)) in norm.iter().zip(&expected).enumerate() {
            assert!(
                (g as f64 - e).abs() <= 1.0 / 65535.0,
                "{label}: I_norm[{i}] = {g}, f64 eq. 1 gives {e} (sample {})",
                v.samples.get(i)
            );
        }
    }
    // Monotone over the finite voxels (sorted by stored value).
    let mut pairs: Vec<(f64, f32)> = (0..n)
        .filter(|&i| finite[i])
        .map(|i| (v.samples.get(i), norm[i]))
        .collect();
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    for w in pairs.windows(2) {
        if w[0].0 < w[1].0 {
            assert!(w[0].1 <= w[1].1, "{label}: not monotone: {w:?}");
        }
    }
    // Histogram: bit-exact with the twin on the GPU's own I_norm, summing to the finite count.
    let twin = reference::histogram::histogram(&norm, |i| finite[i]);
    assert_eq!(prepared.histogram, twin, "{label}: histogram");
    assert_eq!(prepared.finite_voxels, finite_count as u64, "{label}");
    assert_eq!(
        prepared.nonfinite_voxels(),
        (n - finite_count) as u64,
        "{label}"
    );
    // The plan the CPU computed in f64 reaches the GPU as finite push constants (GPU float
    // rules let the shader assume no inf or NaN), and a volume whose finite voxels are all
    // equal (or that has none) is flagged constant: I_norm = 0, histogram [N, 0, ...].
    let params = prepared.normalization.params;
    assert!(
        params.scale.is_finite() && params.offset.is_finite(),
        "{label}: normalization parameters {params:?}"
    );
    let constant = cpu_range.is_none_or(|(lo, hi)| lo == hi);
    assert_eq!(
        prepared.normalization.constant, constant,
        "{label}: constant flag"
    );
    if constant {
        assert_eq!(params.scale, 0.0, "{label}: a constant volume has scale 0");
        assert!(norm.iter().all(|&x| x == 0.0), "{label}: constant -> 0");
        assert_eq!(prepared.histogram[0] as usize, finite_count, "{label}");
    }
    (prepared, norm)
}

#[test]
fn float64_data_near_the_f64_limit_normalizes_like_eq_1_and_keeps_its_peaks() {
    // What the loader makes of float64 voxels at +-1.7e308: f32 samples and a power-of-two
    // slope. `imax - imin` overflows f64 here; the volume once came out "constant" (black) with
    // 0 used voxels.
    let dims = [19, 17, 13];
    let mut rng = Rng(1708);
    let field = smooth_field(dims, &mut rng, -1.0, 1.0);
    let samples: Vec<f32> = field
        .iter()
        .map(|&x| (x * 1.5e308 / 2f64.powi(1000)) as f32)
        .collect();
    let mut v = volume(dims, [1.0; 3], Samples::from_f32(&samples));
    v.to_physical = morphray::volume::LinearMap {
        slope: 2f64.powi(1000),
        intercept: 0.0,
    };
    let mut engine = common::engine();
    let (prepared, norm) = check_prepare("float64 +-1.5e308", &mut engine, &v);
    assert!(!prepared.normalization.constant);
    let (lo, hi) = norm
        .iter()
        .fold((1.0f32, 0.0f32), |(lo, hi), &x| (lo.min(x), hi.max(x)));
    assert!(lo == 0.0 && hi == 1.0, "I_norm spans [{lo}, {hi}]");
    let report = morphray::analysis::analyze(
        &prepared.histogram,
        prepared.normalization.imin.unwrap_or(0.0),
        prepared.normalization.imax.unwrap_or(0.0),
        v.voxel_count(),
        0,
    );
    assert!(report.used_voxels > 0, "{report:?}");
    for peak in [report.peaks.csf, report.peaks.gm, report.peaks.wm]
        .into_iter()
        .flatten()
    {
        assert!(peak.raw.is_finite(), "{peak:?}");
    }
    common::assert_no_validation_errors(&engine);
}

// ---------------------------------------------------------------------------------------------
// Data: constant, NaN / +-Inf, huge ranges, subnormals, negatives

fn hard_data(dims: [usize; 3]) -> Vec<(&'static str, Vec<f32>)> {
    let n = dims.iter().product::<usize>();
    let mut rng = Rng(2026);
    // A smooth field in [0, 1] (so derivatives and renders have structure), mapped per case.
    let field = smooth_field(dims, &mut rng, 0.0, 1.0);
    let map = |f: &dyn Fn(f64) -> f32| field.iter().map(|&x| f(x)).collect::<Vec<f32>>();
    let mut mixed = map(&|x| (100.0 + 800.0 * x) as f32);
    for (i, v) in mixed.iter_mut().enumerate() {
        match i % 7 {
            1 => *v = f32::NAN,
            3 => *v = f32::INFINITY,
            5 => *v = f32::NEG_INFINITY,
            _ => {}
        }
    }
    // A NaN with a payload and a negative NaN: the bit test must catch every NaN encoding.
    mixed[0] = f32::from_bits(0x7fc0_1234);
    mixed[2] = f32::from_bits(0xffc0_0000);
    let mut huge = map(&|x| (-3e38 + 6e38 * x) as f32);
    huge[0] = 3e38;
    huge[1] = -3e38;
    let mut near_max = map(&|x| (f32::MAX as f64 * (2.0 * x - 1.0)) as f32);
    near_max[0] = f32::MAX;
    near_max[1] = f32::MIN;
    vec![
        ("constant", vec![7.0; n]),
        ("all NaN", vec![f32::NAN; n]),
        (
            "all +-Inf",
            (0..n)
                .map(|i| {
                    if i % 2 == 0 {
                        f32::INFINITY
                    } else {
                        f32::NEG_INFINITY
                    }
                })
                .collect(),
        ),
        ("mixed NaN/+-Inf", mixed),
        ("+-3e38", huge),
        ("+-FLT_MAX", near_max),
        // 1e30 + tiny: 128 f32 ulps of 1e30 (ulp = 7.6e22) across the volume.
        (
            "1e30 + tiny",
            map(&|x| (1e30 + (x * 128.0).round() * 7.555786e22) as f32),
        ),
        // Subnormal: every sample below 2^-126; GPUs may flush such operands to zero.
        ("subnormal", map(&|x| (x * 1e-39) as f32)),
        ("subnormal, signed", map(&|x| ((x - 0.5) * 2e-40) as f32)),
        ("negative", map(&|x| (-1000.0 - 500.0 * x) as f32)),
    ]
}

#[test]
fn hard_data_prepares_derives_and_renders_finite_and_right() {
    let mut engine = common::engine();
    let dims = [9usize, 7, 5]; // 315 voxels: a multiple of no workgroup or subgroup size
    let scene = {
        let mut s = tissue_scene();
        s.effects.curvature = true;
        s.effects.shading = true;
        s
    };
    let (w, h) = (24, 24);
    for (label, values) in hard_data(dims) {
        let v = volume(dims, [1.0, 1.2, 2.0], Samples::from_f32(&values));
        let (prepared, norm) = check_prepare(label, &mut engine, &v);
        let derived = engine.derive(&prepared, hard_support::ALL_OUTPUTS).unwrap();
        let data = derived_data(&engine, &derived);
        assert!(
            derived.stats.max_magnitude.is_finite() && derived.stats.max_magnitude >= 0.0,
            "{label}: max |g| {}",
            derived.stats.max_magnitude
        );
        let k = data.curvature.as_ref().unwrap();
        let normals = data.normals.as_ref().unwrap();
        for i in 0..norm.len() {
            assert!(
                data.magnitude[i].is_finite() && k[i].is_finite(),
                "{label}: |g|, k at {i}: {}, {}",
                data.magnitude[i],
                k[i]
            );
            assert!(
                normals[i].iter().all(|c| c.is_finite()),
                "{label}: normal {i}"
            );
        }
        let gpu = render(&mut engine, &prepared, Some(&derived), &scene, w, h);
        // Colours, shaded ones included, are clamped to [0, 1]; so is the background.
        assert_finite_in_range(label, &gpu, 1.0 + 1e-6);
        let background = scene.background.map(f64::from);
        let only_background = gpu
            .iter()
            .all(|px| (0..3).all(|c| (px[c] - background[c]).abs() < 1e-6));
        if prepared.normalization.constant {
            // I_norm = 0 and |g| = 0 everywhere: nothing is opaque.
            assert!(
                only_background,
                "{label}: a constant volume renders only background"
            );
            let d = derived_data(&engine, &derived);
            assert!(d.magnitude.iter().all(|&m| m == 0.0), "{label}");
        } else {
            assert!(!only_background, "{label}: the tissue is visible");
            // Against the f64 reference raymarch of the same I_norm and derived volumes; bound as
            // in tests/gpu_raymarch.rs (hardware trilinear weights, f16 derived data, window
            // slopes), measured on lavapipe with a margin.
            let cpu = reference(&engine, &prepared, Some(&derived), &scene, w, h);
            let (psnr, p99, max) = compare(&gpu, &cpu, None);
            let contrast = gpu
                .iter()
                .map(|px| {
                    (0..3)
                        .map(|c| (px[c] - background[c]).abs())
                        .fold(0.0, f64::max)
                })
                .fold(0.0, f64::max);
            let covered = gpu
                .iter()
                .filter(|px| (0..3).any(|c| (px[c] - background[c]).abs() > 0.01))
                .count();
            eprintln!(
                "{label}: PSNR {psnr:.1} dB, p99 {p99:.4}, max {max:.4}; contrast {contrast:.3}, {covered} pixels"
            );
            assert!(
                psnr >= 35.0 && max <= 0.25,
                "{label}: PSNR {psnr:.1}, max {max:.4}"
            );
        }
        // MIP too: I_norm only.
        let mut mip = scene;
        mip.effects.mode = RenderMode::Mip;
        let image = render(&mut engine, &prepared, None, &mip, w, h);
        assert_finite_in_range(label, &image, 1.0);
    }
    common::assert_no_validation_errors(&engine);
}

// ---------------------------------------------------------------------------------------------
// Tiny shapes: one voxel, 1 x 1 x N, 2 x 2 x 2 and other degenerate grids

/// Checks the derivative pass against its f64 twin run on the GPU's own I_norm: |g| to f16
/// precision (2^-11 relative, plus 1e-5 of the largest |g| for f16's absolute floor), k within
/// 2e-3 of the largest |k| where the direction is defined (f16 storage of k and f32 sums), and
/// max |g| to f32 precision.
fn check_derivatives_against_twin(label: &str, engine: &mut Engine, v: &Volume) -> PreparedVolume {
    let (prepared, norm) = check_prepare(label, engine, v);
    let derived = engine.derive(&prepared, ALL_OUTPUTS).unwrap();
    let data = derived_data(engine, &derived);
    let values: Vec<f64> = norm.iter().map(|&x| x as f64).collect();
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
    let g_max = magnitude.iter().cloned().fold(0.0, f64::max);
    let k_max = curvature.iter().map(|k| k.abs()).fold(0.0, f64::max);
    assert!(
        (derived.stats.max_magnitude - g_max).abs() <= 1e-6 * g_max,
        "{label}: max |g| {} vs {g_max}",
        derived.stats.max_magnitude
    );
    let k = data.curvature.as_ref().unwrap();
    for i in 0..values.len() {
        assert!(
            data.magnitude[i].is_finite() && k[i].is_finite(),
            "{label} {i}"
        );
        assert!(
            (data.magnitude[i] - magnitude[i]).abs() <= 1e-3 * magnitude[i] + 1e-5 * g_max,
            "{label}: |g| at {i}: {} vs {}",
            data.magnitude[i],
            magnitude[i]
        );
        if magnitude[i] > 1e-3 * g_max {
            assert!(
                (k[i] - curvature[i]).abs() <= 2e-3 * k_max + 1e-6,
                "{label}: k at {i}: {} vs {}",
                k[i],
                curvature[i]
            );
        }
    }
    prepared
}

#[test]
fn single_voxel_thin_and_two_voxel_volumes_prepare_derive_and_render_sensibly() {
    let mut engine = common::engine();
    let mut rng = Rng(17);
    let mut scene = tissue_scene();
    scene.effects.curvature = true;
    scene.effects.shading = true;
    let (w, h) = (16, 16);
    let shapes: [[usize; 3]; 8] = [
        [1, 1, 1],
        [1, 1, 9],
        [9, 1, 1],
        [1, 9, 1],
        [2, 2, 2],
        [2, 1, 3],
        [1, 2, 2],
        [3, 3, 1],
    ];
    for dims in shapes {
        let n: usize = dims.iter().product();
        // Values 0..n-1 shuffled by the rng (a permutation: the full range is always present,
        // so every window sees something), as f32.
        let mut values: Vec<f32> = (0..n).map(|i| i as f32 * 10.0).collect();
        for i in (1..n).rev() {
            values.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
        }
        let label = format!("{dims:?}");
        let v = volume(dims, [1.0, 1.5, 0.7], Samples::from_f32(&values));
        let prepared = check_derivatives_against_twin(&label, &mut engine, &v);
        let derived = engine.derive(&prepared, ALL_OUTPUTS).unwrap();
        for (mode, on_the_fly) in [
            (RenderMode::Dvr, false),
            (RenderMode::Dvr, true),
            (RenderMode::Mip, false),
        ] {
            let mut s = scene;
            s.effects.mode = mode;
            if on_the_fly {
                s.effects.gradient_source = GradientSource::OnTheFly;
            }
            let d = engine
                .derive(
                    &prepared,
                    s.effects.derivative_outputs().unwrap_or_default(),
                )
                .unwrap();
            let d = if mode == RenderMode::Dvr && !on_the_fly {
                &derived
            } else {
                &d
            };
            let derived_arg = (mode == RenderMode::Dvr).then_some(d);
            let gpu = render(&mut engine, &prepared, derived_arg, &s, w, h);
            assert_finite_in_range(&label, &gpu, 1.0 + 1e-6);
            let cpu = reference(&engine, &prepared, derived_arg, &s, w, h);
            let (psnr, _, max) = compare(&gpu, &cpu, None);
            assert!(
                psnr >= 35.0 && max <= 0.25,
                "{label} {mode:?} on the fly {on_the_fly}: PSNR {psnr:.1}, max {max:.4}"
            );
            let background = s.background.map(f64::from);
            let visible = gpu
                .iter()
                .any(|px| (0..3).any(|c| (px[c] - background[c]).abs() > 1e-3));
            if n == 1 {
                // One voxel is a constant volume: I_norm 0 and |g| 0, so DVR shows only the
                // background (MIP shows I_norm 0 as black where rays meet the box).
                assert!(
                    mode == RenderMode::Mip || !visible,
                    "{label} {mode:?} on the fly {on_the_fly}: a single voxel renders only background"
                );
            } else if mode == RenderMode::Mip {
                assert!(visible, "{label}: MIP shows the volume");
            }
        }
    }
    common::assert_no_validation_errors(&engine);
}

// ---------------------------------------------------------------------------------------------
// Extreme anisotropy: 0.1 x 0.1 x 10 mm

#[test]
fn a_linear_ramp_on_a_0_1_x_0_1_x_10_mm_grid_gives_the_exact_world_gradient_and_zero_curvature() {
    let mut engine = common::engine();
    // I = i + 2j + 3k on 6x4x3: the maximum 17 divides 65535, so R16 stores I_norm exactly and
    // every stencil is exact; the world gradient is (1, 2, 3) / 17 / (0.1, 0.1, 10) per mm, a
    // factor 100 between axes.
    let dims = [6usize, 4, 3];
    let values: Vec<u16> = (0..72)
        .map(|i| (i % 6 + 2 * (i / 6 % 4) + 3 * (i / 24)) as u16)
        .collect();
    let v = volume(dims, [0.1, 0.1, 10.0], Samples::from_u16(&values));
    let prepared = engine.prepare(&v).unwrap();
    let derived = engine.derive(&prepared, ALL_OUTPUTS).unwrap();
    let data = derived_data(&engine, &derived);
    let g: [f64; 3] = [1.0 / 17.0 / 0.1, 2.0 / 17.0 / 0.1, 3.0 / 17.0 / 10.0];
    let expected = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    let normals = data.normals.as_ref().unwrap();
    let curvature = data.curvature.as_ref().unwrap();
    assert_eq!(data.magnitude.len(), values.len());
    for (i, ((m, k), n)) in data
        .magnitude
        .iter()
        .zip(curvature)
        .zip(normals)
        .enumerate()
    {
        // f16 storage: one ulp is 2^-10 relative (the conversion may round toward zero).
        assert!(
            (m - expected).abs() <= expected * 1e-3,
            "voxel {i}: |g| {m} vs {expected}"
        );
        // I_norm is exact, so every second difference is exactly 0.
        assert!(k.abs() <= 1e-4, "voxel {i}: k = {k} on a ramp");
        for c in 0..3 {
            // RGBA8_SNORM normals: one step is 1/127.
            assert!(
                (n[c] - g[c] / expected).abs() <= 1.0 / 127.0 + 1e-6,
                "voxel {i}: normal {n:?}"
            );
        }
    }
    assert!((derived.stats.max_magnitude - expected).abs() <= expected * 1e-6);
    common::assert_no_validation_errors(&engine);
}

/// A world-space cone around the z axis whose height grows linearly with z:
/// I = max(0, 1 - r / 2 mm) (0.5 + z / 50 mm). Linear in z, so trilinear sampling and every
/// z-stencil are exact on any z spacing; grids that share the x-y lattice sample it identically.
fn cone(dims: [usize; 3], spacing: [f64; 3]) -> Volume {
    let origin = [
        -(dims[0] as f64 - 1.0) * spacing[0] / 2.0,
        -(dims[1] as f64 - 1.0) * spacing[1] / 2.0,
        -(dims[2] as f64 - 1.0) * spacing[2] / 2.0,
    ];
    let mut values = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let x = origin[0] + i as f64 * spacing[0];
                let y = origin[1] + j as f64 * spacing[1];
                let z = origin[2] + k as f64 * spacing[2];
                let r = (x * x + y * y).sqrt();
                values.push(((1.0 - r / 2.0).max(0.0) * (0.5 + z / 50.0)) as f32);
            }
        }
    }
    let affine = [
        [spacing[0], 0.0, 0.0, origin[0]],
        [0.0, spacing[1], 0.0, origin[1]],
        [0.0, 0.0, spacing[2], origin[2]],
        [0.0, 0.0, 0.0, 1.0],
    ];
    volume_with_affine(dims, affine, Samples::from_f32(&values))
}

#[test]
fn a_world_object_on_a_0_1_x_0_1_x_10_mm_grid_renders_like_on_a_0_1_x_0_1_x_1_mm_grid() {
    let mut engine = common::engine();
    // The same cone on 41 x 41 x 7 voxels of 0.1 x 0.1 x 10 mm and on 41 x 41 x 61 voxels of
    // 0.1 x 0.1 x 1 mm (both z from -30 to 30 mm, same x-y lattice, same I range 0 .. 1.1).
    let coarse = cone([41, 41, 7], [0.1, 0.1, 10.0]);
    let fine = cone([41, 41, 61], [0.1, 0.1, 1.0]);
    let window = Some(Window {
        lo: 0.2,
        hi: 0.8,
        edge: 0.05,
    });
    let (w, h) = (32, 32);
    let mut images = Vec::new();
    let mut gradient_max = None;
    for (label, v) in [("0.1 x 0.1 x 10", &coarse), ("0.1 x 0.1 x 1", &fine)] {
        let prepared = engine.prepare(v).unwrap();
        let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
        let (lo, hi) = geometry.world_bounds();
        let mut classification = Classification::with_windows([window, None, None, None]);
        classification.show_only(&[TissueClass::Csf]);
        classification.style_mut(TissueClass::Csf).opacity = 0.5;
        let mut scene = Scene::new(classification);
        scene.jitter = false;
        scene.effects.shading = true;
        // Horizontal orthographic rays (elevation 0), oblique in x-y; the image spans 2.5 mm
        // either side of the origin on both grids (zoom scales the grid's own framing radius), so
        // it sees z in [-2.5, 2.5] mm, far inside both boxes.
        scene.camera = Camera {
            azimuth_deg: 30.0,
            elevation_deg: 0.0,
            zoom: (hi - lo).max_element() * 0.5 / 2.5,
            pan_mm: [0.0, 0.0],
            projection: Projection::Orthographic,
        };
        for source in [GradientSource::Precomputed, GradientSource::OnTheFly] {
            scene.effects.gradient_source = source;
            let mut d = engine
                .derive(&prepared, scene.effects.derivative_outputs().unwrap())
                .unwrap();
            let data = derived_data(&engine, &d);
            assert!(data.magnitude.iter().all(|m| m.is_finite()), "{label}");
            assert!(d.stats.max_magnitude.is_finite() && d.stats.max_magnitude > 0.0);
            // One normalizer for both grids (the coarse one's): only sampling may differ.
            d.stats.max_magnitude = *gradient_max.get_or_insert(d.stats.max_magnitude);
            let image = render(&mut engine, &prepared, Some(&d), &scene, w, h);
            assert_finite_in_range(label, &image, 1.0 + 1e-6);
            images.push((label, source, image));
        }
    }
    for i in 0..2 {
        let (coarse, fine) = (&images[i], &images[i + 2]);
        let (psnr, p99, max) = compare(&coarse.2, &fine.2, None);
        let covered = fine.2.iter().filter(|px| px[0] > 0.02).count();
        eprintln!(
            "{:?}: {} vs {}: PSNR {psnr:.1} dB, p99 {p99:.2e}, max {max:.2e}; {covered} pixels of cone",
            coarse.1, coarse.0, fine.0
        );
        // Plausible: the cone covers a good part of the image.
        assert!(covered > 200, "{covered} pixels");
        // Both grids sample a function linear in z exactly, so the images differ only by f32
        // rounding and the hardware's sub-texel weight precision along z (8 bits commonly: an
        // I error of 2^-9 x 0.2 per 10 mm cell = 4e-4, amplified by the window slope 1/(2 x 0.05)
        // to 4e-3 of opacity). Wrong z units (spacing not divided out) change g_z by 10x and
        // |g| by about 8 % in the core.
        assert!(
            psnr >= 50.0 && max <= 0.02,
            "{:?}: PSNR {psnr:.1}, max {max:.4}",
            coarse.1
        );
    }
    common::assert_no_validation_errors(&engine);
}

// ---------------------------------------------------------------------------------------------
// Zero gradient: exact plateaus inside a visible window

#[test]
fn exact_plateaus_inside_a_window_render_finite_with_shading_and_curvature_in_every_source() {
    let mut engine = common::engine();
    // Three exact plateaus (0, 50, 100 -> I_norm 0, 0.5, 1) in slabs along x; the middle one lies
    // inside the GM window, so its samples are classified (f > 0) with |g| = 0: exactly where
    // g / |g|, the curvature direction and the shading normal are undefined (NUMERICS.md).
    let dims = [24usize, 9, 7];
    let values: Vec<f32> = (0..dims.iter().product::<usize>())
        .map(|i| match i % 24 {
            0..8 => 0.0,
            8..16 => 50.0,
            _ => 100.0,
        })
        .collect();
    let v = volume(dims, [1.0, 2.0, 0.5], Samples::from_f32(&values));
    let prepared = engine.prepare(&v).unwrap();
    let mut scene = tissue_scene();
    scene.effects.curvature = true;
    scene.effects.shading = true;
    for source in [GradientSource::Precomputed, GradientSource::OnTheFly] {
        scene.effects.gradient_source = source;
        let derived = engine
            .derive(&prepared, scene.effects.derivative_outputs().unwrap())
            .unwrap();
        if source == GradientSource::Precomputed {
            let data = derived_data(&engine, &derived);
            for i in 0..values.len() {
                let x = i % 24;
                if [3, 4, 11, 12, 19, 20].contains(&x) {
                    // Plateau interiors: exactly zero, not NaN.
                    assert_eq!(data.magnitude[i], 0.0, "voxel {i}");
                    assert_eq!(data.curvature.as_ref().unwrap()[i], 0.0, "voxel {i}");
                    assert_eq!(data.normals.as_ref().unwrap()[i], [0.0; 3], "voxel {i}");
                }
            }
        }
        let gpu = render(&mut engine, &prepared, Some(&derived), &scene, 24, 24);
        assert_finite_in_range(&format!("{source:?}"), &gpu, 1.0 + 1e-6);
        let cpu = reference(&engine, &prepared, Some(&derived), &scene, 24, 24);
        let (psnr, _, max) = compare(&gpu, &cpu, None);
        assert!(
            psnr >= 35.0 && max <= 0.25,
            "{source:?}: PSNR {psnr:.1}, max {max:.4}"
        );
    }
    common::assert_no_validation_errors(&engine);
}

// ---------------------------------------------------------------------------------------------
// Trilinear sampling next to invalid voxels

#[test]
fn a_nan_block_inside_tissue_renders_finite_as_air_and_trilinear_never_rings() {
    let mut engine = common::engine();
    // Tissue: a smooth field in [400, 600] on 20^3 voxels, with one voxel at 0 and one at 1000
    // (corners) fixing the range, so the tissue's I_norm lies in [0.4, 0.6], inside the GM window.
    let dims = [20usize, 20, 20];
    let mut rng = Rng(99);
    let tissue: Vec<f32> = smooth_field(dims, &mut rng, 400.0, 600.0)
        .iter()
        .map(|&x| x as f32)
        .collect();
    let mut base = tissue.clone();
    base[0] = 0.0;
    let last = base.len() - 1;
    base[last] = 1000.0;
    // A 4^3 block of NaN, +Inf and -Inf at the centre.
    let in_block = |i: usize| {
        let (x, y, z) = (i % 20, i / 20 % 20, i / 400);
        (8..12).contains(&x) && (8..12).contains(&y) && (8..12).contains(&z)
    };
    let specials = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::from_bits(0xffc0_0001),
    ];
    let with_block: Vec<f32> = base
        .iter()
        .enumerate()
        .map(|(i, &v)| if in_block(i) { specials[i % 4] } else { v })
        .collect();
    // The same block as the finite minimum (I_norm exactly 0): what the renderer must make of
    // invalid voxels ("they render transparent", like air).
    let as_air: Vec<f32> = base
        .iter()
        .enumerate()
        .map(|(i, &v)| if in_block(i) { 0.0 } else { v })
        .collect();
    let mut scene = tissue_scene();
    scene.effects.shading = true;
    scene.camera.zoom = 1.5;
    let (w, h) = (32, 32);
    let mut renders = Vec::new();
    let mut norms = Vec::new();
    for (label, values) in [
        ("NaN block", &with_block),
        ("air block", &as_air),
        ("no block", &base),
    ] {
        let v = volume(dims, [1.0; 3], Samples::from_f32(values));
        let (prepared, norm) = check_prepare(label, &mut engine, &v);
        let derived = engine.derive(&prepared, ALL_OUTPUTS).unwrap();
        let data = derived_data(&engine, &derived);
        assert!(data.magnitude.iter().all(|m| m.is_finite()), "{label}");
        let mut per_mode = Vec::new();
        for mode in [RenderMode::Dvr, RenderMode::Mip] {
            let mut s = scene;
            s.effects.mode = mode;
            let image = render(
                &mut engine,
                &prepared,
                (mode == RenderMode::Dvr).then_some(&derived),
                &s,
                w,
                h,
            );
            assert_finite_in_range(label, &image, 1.0 + 1e-6);
            per_mode.push(image);
        }
        renders.push(per_mode);
        norms.push(norm);
    }
    // NaN/Inf voxels are written as I_norm 0 and everything else is untouched (the finite range
    // is the same), so the derivative pass and the raymarch see exactly the "air" volume.
    for (i, (invalid, air)) in norms[0].iter().zip(&norms[1]).enumerate() {
        if in_block(i) {
            assert_eq!(*invalid, 0.0, "invalid voxel {i} -> I_norm 0");
        }
        assert_eq!(invalid, air, "voxel {i}");
    }
    for (m, (invalid, air)) in renders[0].iter().zip(&renders[1]).enumerate() {
        let (_, _, max) = compare(invalid, air, None);
        assert!(
            max <= 1e-6,
            "mode {m}: the NaN block differs from air by {max}"
        );
    }
    // No ringing: trilinear weights are non-negative and sum to 1, so lowering voxels (tissue ->
    // 0 in the block) can only lower every sample; the MIP with the block is nowhere above the
    // MIP without it (an interpolator with negative lobes would overshoot next to the block).
    for (p, (a, b)) in renders[0][1].iter().zip(&renders[2][1]).enumerate() {
        assert!(
            a[0] <= b[0] + 1e-6,
            "pixel {p}: MIP {} with the block > {} without",
            a[0],
            b[0]
        );
    }
    // For the report: how visible the block's false wall is (air next to tissue has a large
    // gradient, so eq. 4 draws the cavity's boundary).
    let (psnr, _, max) = compare(&renders[0][0], &renders[2][0], None);
    eprintln!("NaN block vs no block (DVR): PSNR {psnr:.1} dB, max {max:.3}");
    common::assert_no_validation_errors(&engine);
}

// ---------------------------------------------------------------------------------------------
// f16 storage of derivatives

/// A field with large second differences: steps of the full range every third voxel along x,
/// a ramp along y, smooth along z: |H_idx| reaches 1 per voxel^2 where |g| is large.
fn stepped(dims: [usize; 3]) -> Vec<f32> {
    let mut values = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let step = if (i / 3) % 2 == 0 { 0.0 } else { 1000.0 };
                values.push(step + 20.0 * j as f32 + 50.0 * (k as f32 * 0.7).sin());
            }
        }
    }
    values
}

/// Worst error of the stored |g| and k (f16) relative to the f64 twin on the GPU's own I_norm,
/// in units of the quantity's largest magnitude; panics on a non-finite stored value.
fn f16_storage_errors(engine: &mut Engine, spacing: f64) -> (f64, f64, f64) {
    let dims = [13usize, 7, 5];
    let v = volume(dims, [spacing; 3], Samples::from_f32(&stepped(dims)));
    let prepared = engine.prepare(&v).unwrap();
    let derived = engine.derive(&prepared, ALL_OUTPUTS).unwrap();
    let data = derived_data(engine, &derived);
    let norm: Vec<f64> = normalized(engine, &prepared)
        .iter()
        .map(|&x| x as f64)
        .collect();
    let twin = reference::derivatives::derivatives(
        &norm,
        dims,
        &IndexToWorld::new(v.orientation.linear_part()).unwrap(),
        &DerivativeOptions::default(),
    )
    .unwrap();
    let (g, k) = (twin.gradient_magnitude.unwrap(), twin.curvature.unwrap());
    let k_stored = data.curvature.unwrap();
    let g_max = g.iter().cloned().fold(0.0, f64::max);
    let k_max = k.iter().map(|x| x.abs()).fold(0.0, f64::max);
    let (mut g_err, mut k_err) = (0.0f64, 0.0f64);
    for i in 0..norm.len() {
        assert!(
            data.magnitude[i].is_finite() && k_stored[i].is_finite(),
            "spacing {spacing} mm: voxel {i} stored |g| = {}, k = {} (f64: {}, {})",
            data.magnitude[i],
            k_stored[i],
            g[i],
            k[i]
        );
        g_err = g_err.max((data.magnitude[i] - g[i]).abs() / g_max);
        k_err = k_err.max((k_stored[i] - k[i]).abs() / k_max);
    }
    (g_err, k_err, k_max)
}

#[test]
fn f16_derivatives_stay_finite_and_within_one_f16_ulp_from_0_1_to_10_mm() {
    let mut engine = common::engine();
    for spacing in [0.1, 0.5, 1.0, 3.0, 10.0] {
        let (g_err, k_err, k_max) = f16_storage_errors(&mut engine, spacing);
        eprintln!(
            "spacing {spacing} mm: |g| error {g_err:.2e}, k error {k_err:.2e} (of max), max |k| {k_max:.3e}"
        );
        // f16 keeps 11 significant bits; Vulkan lets the conversion round toward zero (lavapipe
        // does): one ulp is 2^-10 of the value, and f32 arithmetic adds < 1e-6. Relative to the
        // largest magnitude, the error is at most 2^-10 (small values have smaller ulps, down to
        // f16's subnormal floor 2^-24, which stays below 2^-10 of every max here).
        assert!(
            g_err <= 2f64.powi(-10),
            "spacing {spacing}: |g| error {g_err:.2e}"
        );
        assert!(
            k_err <= 2f64.powi(-10) + 1e-6,
            "spacing {spacing}: k error {k_err:.2e}"
        );
    }
    common::assert_no_validation_errors(&engine);
}

/// NUMERICS.md: "f16 storage of derivatives: store derivatives of I_norm in voxel units; spacing
/// applied at use". Stored in world units (per mm, per mm^2), k would scale with 1 / spacing^2
/// and overflow f16 (65504)
/// once spacing < about 8 um for full-contrast edges (|H_idx| up to ~4 per voxel^2), e.g. a scan
/// whose pixdim is in metres but read as millimetres (1 mm = 0.001), or micro-MRI below 8 um.
/// Stored k saturates at 65504 on lavapipe (whose f16 conversion rounds toward zero: 31 % error
/// at 3 um) or becomes inf where it rounds to nearest (trilinear filtering of inf next to a
/// finite texel then gives NaN). The derivative pass now stores |g| h and k h^2 (h = finest
/// spacing), which this test checks at 3 um and 1 um.
#[test]
fn f16_curvature_stays_finite_at_micrometre_spacing() {
    let mut engine = common::engine();
    for spacing in [0.003, 0.001] {
        let (g_err, k_err, k_max) = f16_storage_errors(&mut engine, spacing);
        eprintln!(
            "spacing {spacing} mm: |g| error {g_err:.2e}, k error {k_err:.2e} (of max), max |k| {k_max:.3e}"
        );
        assert!(
            g_err <= 2f64.powi(-10),
            "spacing {spacing}: |g| error {g_err:.2e}"
        );
        assert!(
            k_err <= 2f64.powi(-10) + 1e-6,
            "spacing {spacing}: k error {k_err:.2e} of max |k| {k_max:.3e}"
        );
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn every_numerics_row_is_covered_by_the_hard_case_table() {
    // NUMERICS.md is the table the code cites; this file's module doc says which tests cover
    // each of its rows. A row added there without tests here fails.
    let numerics = include_str!("../NUMERICS.md");
    let table = include_str!("hard_cases.rs");
    let cases: Vec<&str> = numerics
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| case |"))
        .filter_map(|l| l.split('|').nth(1).map(str::trim))
        .collect();
    assert!(cases.len() >= 15, "{cases:?}");
    for case in cases {
        assert!(
            table.contains(&format!("//! | {case} |")),
            "NUMERICS.md row `{case}` has no row in tests/hard_cases.rs's table"
        );
    }
}
