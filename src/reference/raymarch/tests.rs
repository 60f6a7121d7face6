//! Tests of the reference raymarch against formulas and hand-computed cases.

use super::*;
use crate::scene::{Classification, Effects, Window};
use glam::{DMat3, DVec3};

#[test]
fn pcg_hash_matches_independently_computed_values() {
    // pcg_hash(0) by hand: state = 0 * 747796405 + 2891336453 = 0xAC564B05; the shift is
    // (state >> 28) + 4 = 0xA + 4 = 14; state >> 14 = 0x0002B159; xor = 0xAC54FA5C;
    // word = 0xAC54FA5C * 277803737 mod 2^32, then (word >> 22) ^ word = 0x07BB2FE2.
    // The other values come from a separate Python implementation of jitter.glsl with
    // explicit `& 0xffffffff` after every product and sum.
    assert_eq!(pcg_hash(0), 0x07BB_2FE2);
    assert_eq!(pcg_hash(1), 0xA8BE_EA3C);
    assert_eq!(pcg_hash(12345), 0xF45E_AD0E);
    assert_eq!(pcg_hash(u32::MAX), 0xE62A_4902);
    // jitter = (h >> 8) / 2^24 with h = pcg(x ^ pcg(y ^ pcg(frame))).
    for ((x, y, frame), top24) in [
        ((0, 0, 0), 8_379_828u32),
        ((1, 0, 0), 13_186_708),
        ((0, 1, 0), 13_339_483),
        ((7, 3, 42), 8_984_476),
        ((4095, 4095, u32::MAX), 4_950_090),
    ] {
        assert_eq!(jitter(x, y, frame), f64::from(top24) / 16_777_216.0);
    }
}

fn ramp_volume(dims: [u32; 3], f: impl Fn(f64, f64, f64) -> f64) -> Vec<f64> {
    let mut v = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                v.push(f(f64::from(i), f64::from(j), f64::from(k)));
            }
        }
    }
    v
}

#[test]
fn trilinear_is_exact_on_multilinear_data_and_clamps_to_the_edge() {
    let dims = [4, 5, 3];
    // Trilinear interpolation reproduces any function a + b i + c j + d k + e i j k exactly
    // between voxel centres (up to rounding, 1e-12 here).
    let f = |i: f64, j: f64, k: f64| 0.1 + 0.02 * i - 0.03 * j + 0.05 * k + 0.004 * i * j * k;
    let data = ramp_volume(dims, f);
    let vol = ReferenceVolume::new(dims, &data).unwrap();
    for p in [
        DVec3::new(0.25, 1.5, 0.75),
        DVec3::new(2.9, 3.1, 1.999),
        DVec3::new(3.0, 4.0, 2.0),
    ] {
        assert!((trilinear(&vol, p) - f(p.x, p.y, p.z)).abs() < 1e-12, "{p}");
    }
    // Voxel centres give the stored values exactly.
    assert_eq!(trilinear(&vol, DVec3::new(1.0, 2.0, 1.0)), f(1.0, 2.0, 1.0));
    // Beyond a face the border voxel is seen: at the box face (-0.5) and far outside, the
    // x-interpolation collapses onto i = 0 while y/z still interpolate.
    let inside = trilinear(&vol, DVec3::new(0.0, 1.5, 0.5));
    assert!((trilinear(&vol, DVec3::new(-0.5, 1.5, 0.5)) - inside).abs() < 1e-15);
    assert!((trilinear(&vol, DVec3::new(-7.3, 1.5, 0.5)) - inside).abs() < 1e-15);
    let corner = trilinear(&vol, DVec3::new(3.0, 4.0, 2.0));
    assert_eq!(trilinear(&vol, DVec3::new(9.0, 40.0, 2.6)), corner);
    // A 1-voxel-thick axis is constant along that axis.
    let flat = vec![0.25, 0.75];
    let flat_vol = ReferenceVolume::new([2, 1, 1], &flat).unwrap();
    assert_eq!(trilinear(&flat_vol, DVec3::new(0.5, 0.3, -0.4)), 0.5);
}

#[test]
fn opacity_correction_is_exact_and_composes() {
    // Against the closed form where it is well conditioned.
    for (a, r) in [(0.3, 0.5), (0.05, 2.0), (0.9, 0.125), (0.5, 4.0)] {
        let exact: f64 = 1.0 - (1.0f64 - a).powf(r);
        assert!((opacity_correct(a, r) - exact).abs() < 1e-15, "{a} {r}");
    }
    // Tiny a keeps full relative precision: 1 - (1 - a)^r = r a (1 + (1 - r) a / 2 + O(a^2)),
    // the O(a^2) part is ~1e-25 relative here, so the two-term series is exact to rounding
    // (1e-15 relative); the naive f64 form 1 - (1 - a)^r is off by ~1e-4 relative at 1e-12.
    let (a, r) = (1e-12, 0.25);
    let series = r * a * (1.0 + (1.0 - r) * a / 2.0);
    assert!((opacity_correct(a, r) / series - 1.0).abs() < 1e-15);
    let naive = 1.0 - (1.0 - a).powf(r);
    assert!(
        (naive / series - 1.0).abs() > 1e-6,
        "the test would not notice the naive form"
    );
    // Two steps of r1 and r2 voxels absorb as much as one of r1 + r2.
    let (a, r1, r2) = (0.2, 0.3, 0.45);
    let two = 1.0 - (1.0 - opacity_correct(a, r1)) * (1.0 - opacity_correct(a, r2));
    assert!((two - opacity_correct(a, r1 + r2)).abs() < 1e-15);
    assert_eq!(opacity_correct(0.0, 2.0), 0.0);
    assert_eq!(opacity_correct(-0.1, 2.0), 0.0);
    assert_eq!(opacity_correct(1.0, 0.25), 1.0);
    assert_eq!(opacity_correct(1.5, 0.25), 1.0);
}

#[test]
fn composite_and_shade_follow_the_formulas() {
    let mut acc = [0.0; 4];
    composite(&mut acc, [1.0, 0.5, 0.0], 0.5);
    composite(&mut acc, [0.0, 0.0, 1.0], 0.5);
    // (1 - 0.5) * 0.5 = 0.25 of the second colour.
    assert_eq!(acc, [0.5, 0.25, 0.25, 0.75]);
    let view = DVec3::new(0.0, -1.0, 0.0);
    // Facing the light: 1 * (0.35 + 0.65) + 0.25; the normal's length and sign do not matter.
    assert_eq!(shade([0.5; 3], DVec3::new(0.0, 3.0, 0.0), view), [0.75; 3]);
    // Perpendicular: ambient only.
    assert_eq!(shade([0.5; 3], DVec3::X, view), [0.175; 3]);
    // ndl = 0.8 (a 3-4-5 normal): diffuse 0.35 + 0.52 and the highlight 0.25 * 0.8^24.
    let expected = 0.5 * 0.87 + 0.25 * 0.8f64.powi(24);
    let got = shade([0.5; 3], DVec3::new(0.0, 4.0, 3.0), view);
    assert!(got.iter().all(|c| (c - expected).abs() < 1e-15), "{got:?}");
    // No reliable normal: unshaded.
    assert_eq!(shade([0.5; 3], DVec3::splat(1e-4), view), [0.5; 3]);
}

#[test]
fn curvature_weight_matches_the_shaders_exp_form() {
    let shader = |k: f64, s: f64, k_ref: f64| {
        let x = (k.abs() / k_ref).min(20.0);
        let e = (-2.0 * x).exp();
        1.0 + s * (1.0 - e) / (1.0 + e)
    };
    for k in [0.0, 1e-6, -0.3, 2.0, 1e3, -1e9] {
        let (w, s) = (curvature_weight(k, 1.5, 0.4), shader(k, 1.5, 0.4));
        assert!((w - s).abs() < 1e-15, "{k}: {w} vs {s}");
    }
    assert_eq!(curvature_weight(0.0, 3.0, 1.0), 1.0);
    assert!((curvature_weight(1e9, 3.0, 1.0) - 4.0).abs() < 1e-15);
}

fn geometry(dims: [u32; 3], affine: [[f64; 4]; 4]) -> VolumeGeometry {
    VolumeGeometry::new(dims, affine).unwrap()
}

/// An oblique, anisotropic, mirrored affine: columns are the index axes in world mm.
fn oblique_affine() -> [[f64; 4]; 4] {
    let (c, s) = (0.8, 0.6);
    [
        [-0.5 * c, -s, 0.0, 3.0],
        [0.5 * s, -c, 0.0, -2.0],
        [0.0, 0.0, 3.0, 1.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

#[test]
fn on_the_fly_derivatives_are_exact_world_derivatives_of_a_quadratic() {
    // f(x) = b . x + x^T Q x / 2 in world mm, sampled on an oblique anisotropic grid. Central
    // differences at voxel centres are exact for quadratics, so at an interior voxel the
    // on-the-fly gradient is grad f and the curvature is g_hat^T Q g_hat (to 1e-12).
    let dims = [7, 7, 7];
    let g = geometry(dims, oblique_affine());
    let b = DVec3::new(0.03, -0.02, 0.01);
    let q = DMat3::from_cols(
        DVec3::new(0.004, 0.001, -0.0005),
        DVec3::new(0.001, -0.002, 0.0003),
        DVec3::new(-0.0005, 0.0003, 0.001),
    );
    let world =
        |i: f64, j: f64, k: f64| (g.index_to_world * glam::DVec4::new(i, j, k, 1.0)).truncate();
    let f = |x: DVec3| 0.5 + b.dot(x) + 0.5 * x.dot(q * x);
    let data = ramp_volume(dims, |i, j, k| f(world(i, j, k)));
    let vol = ReferenceVolume::new(dims, &data).unwrap();
    let p = DVec3::new(3.0, 2.0, 4.0);
    let x = world(p.x, p.y, p.z);
    let grad = b + q * x;
    let got = gradient_on_the_fly(&vol, g.gradient_to_world, p);
    assert!((got - grad).length() < 1e-12, "{got} vs {grad}");
    let n = grad.normalize();
    let k = curvature_on_the_fly(&vol, g.gradient_to_world, 0.0, p, trilinear(&vol, p), got);
    assert!((k - n.dot(q * n)).abs() < 1e-12, "{k} vs {}", n.dot(q * n));
    // The tau gate.
    assert_eq!(
        curvature_on_the_fly(&vol, g.gradient_to_world, 1.0, p, trilinear(&vol, p), got),
        0.0
    );
}

fn visible_scene() -> Scene {
    let window = Window {
        lo: 0.2,
        hi: 0.8,
        edge: 0.05,
    };
    Scene::new(Classification::with_windows([
        Some(window),
        None,
        None,
        None,
    ]))
}

const STATS: GradientStats = GradientStats {
    max_magnitude: 1.0,
    tau: 1e-6,
};

#[test]
fn inconsistent_inputs_are_typed_errors() {
    let dims = [3, 3, 3];
    let data = vec![0.5; 27];
    assert!(matches!(
        ReferenceVolume::new(dims, &data[..26]),
        Err(ReferenceError::Length {
            expected: 27,
            actual: 26,
            ..
        })
    ));
    assert!(matches!(
        ReferenceVolume::new([3, 0, 3], &[]),
        Err(ReferenceError::BadDims { .. })
    ));
    assert!(matches!(
        ReferenceVolume::new([u32::MAX; 3], &[]),
        Err(ReferenceError::BadDims { .. })
    ));
    let mut bad = data.clone();
    bad[5] = f64::NAN;
    assert_eq!(
        ReferenceVolume::new(dims, &bad).unwrap_err(),
        ReferenceError::NonFiniteVoxel {
            what: "I_norm",
            index: 5
        }
    );

    let vol = ReferenceVolume::new(dims, &data).unwrap();
    let g = geometry(dims, oblique_affine());
    let mut scene = visible_scene();
    let none = ReferenceDerived::NONE;
    let run = |scene: &Scene, derived: &ReferenceDerived<'_>| {
        ReferenceRaymarch::new(scene, &g, &STATS, &vol, derived, 4, 4).map(|r| r.render())
    };
    assert_eq!(
        run(&scene, &none).unwrap_err(),
        ReferenceError::MissingDerived {
            what: "gradient magnitude"
        }
    );
    let magnitude = vec![1.0; 27];
    let with_magnitude = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        ..ReferenceDerived::NONE
    };
    assert!(run(&scene, &with_magnitude).is_ok());
    scene.effects.curvature = true;
    assert_eq!(
        run(&scene, &with_magnitude).unwrap_err(),
        ReferenceError::MissingDerived { what: "curvature" }
    );
    scene.effects.curvature = false;
    scene.effects.shading = true;
    assert_eq!(
        run(&scene, &with_magnitude).unwrap_err(),
        ReferenceError::MissingDerived { what: "normals" }
    );
    // On the fly needs nothing; MIP needs nothing even with the effect flags set.
    scene.effects.gradient_source = GradientSource::OnTheFly;
    assert!(run(&scene, &none).is_ok());
    scene.effects = Effects {
        mode: RenderMode::Mip,
        curvature: true,
        shading: true,
        gradient_source: GradientSource::Precomputed,
        quality: Default::default(),
        vessels: true,
        brain: crate::passes::brain::BrainSwitch::Off,
        lighting: Default::default(),
    };
    assert!(run(&scene, &none).is_ok());
    // A given derived volume is validated even when unused.
    let short = vec![0.0; 8];
    let wrong = ReferenceDerived {
        curvature: Some(&short),
        ..ReferenceDerived::NONE
    };
    assert!(matches!(
        run(&scene, &wrong),
        Err(ReferenceError::Length {
            what: "curvature",
            ..
        })
    ));
    // Grid mismatch and bad parameters.
    let other = geometry([3, 3, 4], oblique_affine());
    assert!(matches!(
        ReferenceRaymarch::new(&scene, &other, &STATS, &vol, &none, 4, 4),
        Err(ReferenceError::DimsMismatch { .. })
    ));
    let negative_tau = GradientStats {
        max_magnitude: 1.0,
        tau: -1.0,
    };
    assert!(matches!(
        ReferenceRaymarch::new(&scene, &g, &negative_tau, &vol, &none, 4, 4),
        Err(ReferenceError::BadParameter { what: "tau", .. })
    ));
    scene.background[1] = f32::INFINITY;
    assert!(matches!(
        run(&scene, &none),
        Err(ReferenceError::BadParameter {
            what: "background",
            ..
        })
    ));
}

#[test]
fn opacities_are_clamped_like_the_uniforms() {
    // RaymarchUniforms::new clamps tissue opacity to [0, 1]; classify alone does not. An
    // opacity of 3 must render like 1 (and -2 like 0), bit for bit.
    let dims = [6, 6, 6];
    let g = geometry(dims, oblique_affine());
    // 0.12 .. 0.57: across the window's lower edge (0.15 .. 0.25), where w < 1 and an
    // unclamped opacity 3 would give f = min(3 w, 1) != w.
    let data = ramp_volume(dims, |i, j, k| 0.12 + 0.03 * (i + j + k));
    let vol = ReferenceVolume::new(dims, &data).unwrap();
    let mut scene = visible_scene();
    scene.effects.gradient_source = GradientSource::OnTheFly;
    scene.early_termination = 2.0;
    let draw =
        |scene: &Scene| render(scene, &g, &STATS, &vol, &ReferenceDerived::NONE, 6, 6).unwrap();
    scene.classification.tissues[0].opacity = 1.0;
    let one = draw(&scene);
    assert!(one.iter().any(|p| p[0] > 1e-3), "visible");
    scene.classification.tissues[0].opacity = 3.0;
    assert_eq!(draw(&scene), one);
    scene.classification.tissues[0].opacity = -2.0;
    assert!(draw(&scene).iter().all(|p| p == &[0.0, 0.0, 0.0, 1.0]));
}

#[test]
fn early_termination_keeps_the_sample_that_crossed_the_threshold() {
    // Constant volume inside the window, |g| = max: every sample has a = opacity = 0.5
    // (exact in f32), r = 1: A after n samples is 1 - 0.5^n, all exact in f64. With the
    // threshold 0.9 the march stops after the 4th sample (A = 0.9375 > 0.9), which is
    // composited: A = 0.9375 exactly, not 0.875 and not the 1 - 0.5^16 of the full ray.
    let dims = [4, 16, 4];
    let g = geometry(
        dims,
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
    );
    let data = vec![0.5; 256];
    let magnitude = vec![1.0; 256];
    let vol = ReferenceVolume::new(dims, &data).unwrap();
    let derived = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        ..ReferenceDerived::NONE
    };
    let mut scene = visible_scene();
    scene.camera.projection = crate::scene::Projection::Orthographic;
    scene.classification.tissues[0].opacity = 0.5;
    scene.classification.tissues[0].colour = [1.0, 1.0, 1.0];
    scene.step_voxels = 1.0;
    scene.jitter = false;
    scene.background = [0.0; 3];
    for (threshold, expected) in [
        (0.9, 0.9375),
        (0.9375, 1.0 - 0.5f64.powi(5)),
        (1.0, 1.0 - 0.5f64.powi(16)),
    ] {
        scene.early_termination = threshold as f32;
        let r = ReferenceRaymarch::new(&scene, &g, &STATS, &vol, &derived, 5, 5).unwrap();
        assert_eq!(r.ray(2, 2).count, 16);
        assert_eq!(r.pixel(2, 2)[0], expected, "threshold {threshold}");
    }
}

fn identity_affine() -> [[f64; 4]; 4] {
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

#[test]
fn precomputed_terms_are_interpolated_and_combined_as_in_eq_4() {
    // I_norm 0.5 (window weight 1, f = opacity 0.8), |g| = 0.1 i, k = 0.2 i - 0.3, normals
    // +x for i <= 1 and +y for i >= 2. At p = (1.25, 1, 1) trilinear interpolation gives
    // |g| = 0.125, k = -0.05 and n = (0.75, 0.25, 0) (component-wise, not renormalized).
    let dims = [4, 3, 3];
    let g = geometry(dims, identity_affine());
    let n = 36;
    let data = vec![0.5; n];
    let index_x = |v: usize| (v % 4) as f64;
    let magnitude: Vec<f64> = (0..n).map(|v| 0.1 * index_x(v)).collect();
    let curvature: Vec<f64> = (0..n).map(|v| 0.2 * index_x(v) - 0.3).collect();
    let normals: Vec<[f64; 3]> = (0..n)
        .map(|v| {
            if index_x(v) <= 1.0 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            }
        })
        .collect();
    let vol = ReferenceVolume::new(dims, &data).unwrap();
    let derived = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        curvature: Some(&curvature),
        normals: Some(&normals),
    };
    let stats = GradientStats {
        max_magnitude: 0.2,
        tau: 0.0,
    };
    let mut scene = visible_scene();
    scene.classification.tissues[0].opacity = 0.8;
    scene.effects.curvature = true;
    scene.effects.shading = true;
    scene.curvature_strength = 0.5;
    scene.step_voxels = 0.7;
    let r = ReferenceRaymarch::new(&scene, &g, &stats, &vol, &derived, 4, 4).unwrap();
    let view = DVec3::new(0.6, 0.0, -0.8);
    let s = r.dvr_sample(DVec3::new(1.25, 1.0, 1.0), view).unwrap();
    let close = |a: f64, b: f64| (a - b).abs() < 1e-15;
    assert!(close(s.f, f64::from(0.8f32)));
    assert!(
        close(s.magnitude, 0.125) && close(s.curvature, -0.05),
        "{s:?}"
    );
    assert!((s.normal - DVec3::new(0.75, 0.25, 0.0)).length() < 1e-15);
    // k_ref = max|g| / (4 voxel_mm) = 0.05, so |k| / k_ref = 1 and w = 1 + 0.5 tanh(1).
    assert_eq!(r.k_ref(), 0.05);
    let unweighted = s.f * 0.125 / 0.2;
    let expected = (unweighted * (1.0 + 0.5 * 1f64.tanh())).min(1.0);
    assert!(expected < 1.0 && close(s.opacity, expected), "{s:?}");
    assert_eq!(s.corrected, opacity_correct(s.opacity, 0.7));
    assert_eq!(s.shaded, shade(s.colour, s.normal, view));
    // Effects off: no weight, no normal, no shading (the stored volumes are not read).
    scene.effects.curvature = false;
    scene.effects.shading = false;
    let r = ReferenceRaymarch::new(&scene, &g, &stats, &vol, &derived, 4, 4).unwrap();
    let s = r.dvr_sample(DVec3::new(1.25, 1.0, 1.0), view).unwrap();
    assert_eq!((s.curvature, s.normal), (0.0, DVec3::ZERO));
    assert!(close(s.opacity, unweighted));
    assert_eq!(s.shaded, s.colour);
    // f(v) = 0: skipped.
    scene.classification.show_only(&[]);
    let r = ReferenceRaymarch::new(&scene, &g, &stats, &vol, &derived, 4, 4).unwrap();
    assert_eq!(r.dvr_sample(DVec3::new(1.25, 1.0, 1.0), view), None);
}

#[test]
fn on_the_fly_normals_are_gated_by_tau() {
    // A linear ramp of world gradient (0.02, 0.03, 0.06) mm^-1 (|g| = 0.07) on a 1 mm grid.
    let dims = [6, 6, 6];
    let g = geometry(dims, identity_affine());
    let data = ramp_volume(dims, |i, j, k| 0.3 + 0.02 * i + 0.03 * j + 0.06 * k);
    let vol = ReferenceVolume::new(dims, &data).unwrap();
    let mut scene = visible_scene();
    scene.effects.gradient_source = GradientSource::OnTheFly;
    scene.effects.shading = true;
    let view = DVec3::new(0.0, 0.0, -1.0);
    let p = DVec3::new(2.5, 2.2, 2.7);
    let sample = |tau: f64| {
        let stats = GradientStats {
            max_magnitude: 0.1,
            tau,
        };
        let r = ReferenceRaymarch::new(&scene, &g, &stats, &vol, &ReferenceDerived::NONE, 2, 2)
            .unwrap();
        r.dvr_sample(p, view).unwrap()
    };
    let below = sample(0.05);
    assert!((below.magnitude - 0.07).abs() < 1e-12);
    assert!((below.normal - DVec3::new(2.0, 3.0, 6.0) / 7.0).length() < 1e-12);
    assert_ne!(below.shaded, below.colour);
    // |g| <= tau: no direction, unshaded; the opacity still uses |g|.
    let above = sample(0.07 + 1e-9);
    assert_eq!(above.normal, DVec3::ZERO);
    assert_eq!(above.shaded, above.colour);
    assert_eq!(above.opacity, below.opacity);
}

#[test]
fn sample_count_and_start_follow_the_shader() {
    // Orthographic view along -y through a 1 mm grid of depth 10: t_far - t_near = 10 mm.
    let dims = [4, 10, 4];
    let g = geometry(
        dims,
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
    );
    let data = vec![0.5; 160];
    let vol = ReferenceVolume::new(dims, &data).unwrap();
    let mut scene = visible_scene();
    scene.effects.gradient_source = GradientSource::OnTheFly;
    scene.camera.projection = crate::scene::Projection::Orthographic;
    scene.jitter = false;
    for (step, count) in [
        (1.0, 10),
        (0.5, 20),
        (0.3, 33),
        (3.0, 3),
        (-1.0, 20),
        (f64::NAN, 20),
    ] {
        scene.step_voxels = step;
        let r = ReferenceRaymarch::new(&scene, &g, &STATS, &vol, &ReferenceDerived::NONE, 5, 5)
            .unwrap();
        let plan = r.ray(2, 2);
        let (t_near, t_far) = plan.hit.unwrap();
        assert!((t_far - t_near - 10.0).abs() < 1e-9);
        let dt = sanitized_step_voxels(step);
        assert_eq!(plan.step_mm, dt);
        assert_eq!(plan.start, t_near + 0.5 * dt);
        // floor((10 - dt/2) / dt) + 1 samples: the last one is the last inside the box.
        assert_eq!(plan.count, count, "step {step}");
        assert!(plan.parameter(plan.count - 1) <= t_far);
        assert!(plan.parameter(plan.count) > t_far);
    }
    // 10 mm at 1e-4 voxel would be 100000 samples: capped at MAX_STEPS.
    scene.step_voxels = 1e-4;
    let r =
        ReferenceRaymarch::new(&scene, &g, &STATS, &vol, &ReferenceDerived::NONE, 5, 5).unwrap();
    assert_eq!(r.ray(2, 2).count, MAX_STEPS);
    // Jittered starts use the hash of (x, y, frame).
    scene.jitter = true;
    scene.frame = 9;
    let r =
        ReferenceRaymarch::new(&scene, &g, &STATS, &vol, &ReferenceDerived::NONE, 5, 5).unwrap();
    let plan = r.ray(2, 2);
    assert_eq!(plan.offset, jitter(2, 2, 9));
    assert_eq!(
        plan.start,
        plan.hit.unwrap().0 + jitter(2, 2, 9) * plan.step_mm
    );
    // A corner ray of this orthographic view misses the box: no samples, the background.
    let corner = r.ray(0, 0);
    assert_eq!((corner.hit, corner.count), (None, 0));
    assert_eq!(r.pixel(0, 0), [0.0, 0.0, 0.0, 1.0]);
}
