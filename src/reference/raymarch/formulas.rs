//! The per-sample formulas of the shader, in f64 and in their exact forms: the jitter hash,
//! opacity correction (exact and the naive form the accuracy study compares), compositing, the
//! curvature weight, shading, and on-the-fly gradients and curvature.

use super::inputs::ReferenceVolume;
use super::sampling::trilinear;
use crate::scene::{Classification, Scene};
use glam::{DMat3, DVec3};

/// The PCG hash of `jitter.glsl` (`pcg_hash`), in u32 wrapping arithmetic like GLSL `uint`.
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// Ray-start jitter of pixel (x, y) in frame `frame`, in [0, 1): `jitter.glsl` bit for bit
/// (`(h >> 8) / 2^24` is exact in f32 and f64).
pub fn jitter(x: u32, y: u32, frame: u32) -> f64 {
    let h = pcg_hash(x ^ pcg_hash(y ^ pcg_hash(frame)));
    f64::from(h >> 8) / 16_777_216.0
}

/// Opacity correction for a step of `r` voxels: `1 - (1 - a)^r`, evaluated as
/// `-expm1(r * ln_1p(-a))` so it keeps full relative precision for tiny `a` (NUMERICS.md).
/// 0 for `a <= 0` and 1 for `a >= 1`, like the shader.
pub fn opacity_correct(a: f64, r: f64) -> f64 {
    if a <= 0.0 {
        return 0.0;
    }
    if a >= 1.0 {
        return 1.0;
    }
    -(r * (-a).ln_1p()).exp_m1()
}

/// Front-to-back emission-absorption step (paper eqs. 5, 6): `C += (1 - A) a C_s`,
/// `A += (1 - A) a`, with `acc = [C.r, C.g, C.b, A]`.
pub fn composite(acc: &mut [f64; 4], colour: [f64; 3], a: f64) {
    let w = (1.0 - acc[3]) * a;
    for (c, s) in acc.iter_mut().zip(colour) {
        *c += w * s;
    }
    acc[3] += w;
}

/// The curvature weight `w(k) = 1 + s * tanh(|k| / k_ref)`.
pub fn curvature_weight(k: f64, strength: f64, k_ref: f64) -> f64 {
    1.0 + strength * (k.abs() / k_ref).tanh()
}

/// The shader's headlight Phong: `min(colour * (0.35 + 0.65 ndl) + 0.25 ndl^24, 1)` with
/// `ndl = |n / |n| . view|` (two-sided); the colour unchanged when `|n| < 1e-3`.
pub fn shade(colour: [f64; 3], normal: DVec3, view_direction: DVec3) -> [f64; 3] {
    let len = normal.length();
    if len < 1e-3 {
        return colour;
    }
    let ndl = (normal / len).dot(view_direction).abs();
    let highlight = 0.25 * ndl.powi(24);
    colour.map(|c| (c * (0.35 + 0.65 * ndl) + highlight).min(1.0))
}

/// World-space gradient at index position `p` from central differences of trilinear samples one
/// voxel apart (`gradient_on_the_fly`): `M g_idx` with `M = geometry.gradient_to_world`.
pub fn gradient_on_the_fly(
    volume: &ReferenceVolume<'_>,
    gradient_to_world: DMat3,
    p: DVec3,
) -> DVec3 {
    gradient_central_with(&|q: DVec3| trilinear(volume, q), gradient_to_world, p)
}

/// World gradient from central differences of `sample` one voxel apart.
pub(super) fn gradient_central_with(
    sample: &impl Fn(DVec3) -> f64,
    gradient_to_world: DMat3,
    p: DVec3,
) -> DVec3 {
    let s = |o: DVec3| sample(p + o);
    let g = DVec3::new(
        0.5 * (s(DVec3::X) - s(-DVec3::X)),
        0.5 * (s(DVec3::Y) - s(-DVec3::Y)),
        0.5 * (s(DVec3::Z) - s(-DVec3::Z)),
    );
    gradient_to_world * g
}

/// World gradient from the smoothed (Sobel-like) difference of `gradients.glsl`'s
/// `gradient_sobel`: the central difference along each axis averaged over the four positions at
/// +-0.5 voxel across it.
pub(super) fn gradient_sobel_with(
    sample: &impl Fn(DVec3) -> f64,
    gradient_to_world: DMat3,
    p: DVec3,
) -> DVec3 {
    let mut g = [0.0; 3];
    for (a, ga) in g.iter_mut().enumerate() {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for s in 0..4 {
            let mut o = [0.0; 3];
            o[b] = if s & 1 == 0 { -0.5 } else { 0.5 };
            o[c] = if s & 2 == 0 { -0.5 } else { 0.5 };
            let mut e = [0.0; 3];
            e[a] = 1.0;
            let (o, e) = (DVec3::from_array(o), DVec3::from_array(e));
            *ga += sample(p + o + e) - sample(p + o - e);
        }
    }
    gradient_to_world * (DVec3::from_array(g) * 0.125)
}

/// `curvature_on_the_fly` with any sampling function.
pub(super) fn curvature_with(
    sample: &impl Fn(DVec3) -> f64,
    gradient_to_world: DMat3,
    tau: f64,
    p: DVec3,
    center: f64,
    g_world: DVec3,
) -> f64 {
    let m = g_world.length();
    if m <= tau {
        return 0.0;
    }
    let s = |x: f64, y: f64, z: f64| sample(p + DVec3::new(x, y, z));
    let hxx = s(1.0, 0.0, 0.0) - 2.0 * center + s(-1.0, 0.0, 0.0);
    let hyy = s(0.0, 1.0, 0.0) - 2.0 * center + s(0.0, -1.0, 0.0);
    let hzz = s(0.0, 0.0, 1.0) - 2.0 * center + s(0.0, 0.0, -1.0);
    let hxy =
        0.25 * (s(1.0, 1.0, 0.0) - s(1.0, -1.0, 0.0) - s(-1.0, 1.0, 0.0) + s(-1.0, -1.0, 0.0));
    let hxz =
        0.25 * (s(1.0, 0.0, 1.0) - s(1.0, 0.0, -1.0) - s(-1.0, 0.0, 1.0) + s(-1.0, 0.0, -1.0));
    let hyz =
        0.25 * (s(0.0, 1.0, 1.0) - s(0.0, 1.0, -1.0) - s(0.0, -1.0, 1.0) + s(0.0, -1.0, -1.0));
    let h = DMat3::from_cols(
        DVec3::new(hxx, hxy, hxz),
        DVec3::new(hxy, hyy, hyz),
        DVec3::new(hxz, hyz, hzz),
    );
    let v = gradient_to_world.transpose() * (g_world / m);
    v.dot(h * v)
}

/// The naive opacity correction `1 - (1 - a)^r` evaluated in f32 like the shader's
/// `opacity_correct_naive` (its defect is f32 cancellation, so the twin keeps f32).
pub fn opacity_correct_naive(a: f64, r: f64) -> f64 {
    let a = (a as f32).clamp(0.0, 1.0);
    f64::from(1.0f32 - (1.0f32 - a).powf(r as f32))
}

/// Directional curvature `k = v^T H_idx v`, `v = M^T g_world / |g_world|`, at index position
/// `p` from the 19-tap stencil of `curvature_on_the_fly` (`center` is the sample at `p`); 0 where
/// `|g_world| <= tau`.
pub fn curvature_on_the_fly(
    volume: &ReferenceVolume<'_>,
    gradient_to_world: DMat3,
    tau: f64,
    p: DVec3,
    center: f64,
    g_world: DVec3,
) -> f64 {
    curvature_with(
        &|q: DVec3| trilinear(volume, q),
        gradient_to_world,
        tau,
        p,
        center,
        g_world,
    )
}

/// `Scene::step_voxels` as the raymarch uses it (`Scene::sanitized_step_voxels`, the rule the
/// GPU uniforms use too).
pub fn sanitized_step_voxels(step_voxels: f64) -> f64 {
    let probe = Scene {
        step_voxels,
        ..Scene::new(Classification::with_windows([None; 4]))
    };
    probe.sanitized_step_voxels()
}
