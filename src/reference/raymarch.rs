//! f64 CPU twin of the raymarch (`shaders/raymarch.comp` with its includes `geometry.glsl`,
//! `jitter.glsl`, `classification.glsl`, `compositing.glsl`, `gradients.glsl`): slow and
//! straightforward, for tests (GPU image vs this image within stated bounds) and accuracy studies.
//!
//! Decisions:
//! - **Same steps, same scene types, f64 arithmetic.** Rays come from `Camera::rays` and
//!   `CameraRays::ray` (pixel centres), go to index space with `VolumeGeometry::ray_to_index`
//!   (direction not normalized, so the ray parameter stays in mm) and meet the box through
//!   `scene::geometry::intersect_box`. Samples sit at `start + i * dt` for
//!   `i < clamp(floor((t_far - start) / dt) + 1, 0, MAX_STEPS)`, with `dt = step_voxels *
//!   voxel_mm` (mm) and `start = t_near + offset * dt` (offset 0.5, or the jitter hash). Per sample the
//!   shader's order is kept: classify, skip `f <= 0`, gradient magnitude, opacity
//!   `clamp(f |g| / |g|max, 0, 1)`, curvature weight, opacity correction, shading, compositing,
//!   then the early-termination test. Where the shader has a choice of formula for speed, the
//!   reference uses the exact one: opacity correction is `-expm1(r * ln_1p(-a))` (the GPU's
//!   series/`pow` form is measured against it) and the curvature weight uses `tanh` (the shader's
//!   `exp` form with its argument clamped at 20 differs by at most `s * 1e-17`).
//!   [`ReferenceRaymarch::ray`] exposes each pixel's samples and [`ReferenceRaymarch::dvr_sample`]
//!   every intermediate of one sample, for explaining a GPU-vs-reference difference.
//! - **The jitter hash is bit-exact** (u32 wrapping arithmetic, `(h >> 8) / 2^24` is exact in f32
//!   and f64), so GPU and reference sample at the same ray positions up to f32 rounding.
//! - **Trilinear sampling is a Vulkan `LINEAR` + `CLAMP_TO_EDGE` fetch** at texture coordinate
//!   `(p + 0.5) / dim`: texel coordinate `p`, neighbours `floor(p)` and `floor(p) + 1` clamped
//!   to `[0, dim - 1]`, weights from the unclamped fractional part, so a position beyond a face
//!   sees the border voxel. The reference's weights are exact; hardware quantizes them to a few
//!   bits of sub-texel precision (commonly 8), which belongs in every GPU-vs-reference bound.
//!   Derived volumes (|g|, k, normals) are interpolated the same way, component by component.
//! - **Inputs are validated once**, in [`ReferenceRaymarch::new`] (lengths against dims, finite
//!   values, dims consistent with the geometry, the derived volumes the scene needs, finite
//!   parameters). After that nothing fails and no output is NaN.
//! - **The output is the shader's `result` before storage**: RGBA with alpha 1, rows top to
//!   bottom, not clamped to [0, 1] (shading's highlight can reach 1.25 for a white sample; an
//!   RGBA8 target clamps it, an RGBA32F target keeps it).
//!
//! Deviations from the shader, each outside the domain the shader handles:
//! - Tissue opacities are clamped to [0, 1] before `Classification::classify`, because
//!   `RaymarchUniforms::new` clamps them on the way to the GPU and `classify` alone does not.
//! - A ray whose origin or direction is not finite (a camera zoom so extreme that the eye
//!   distance overflows) takes no samples and shows the background; on the GPU the result is
//!   undefined.
//! - Non-finite scene or gradient parameters, and a negative `tau`, are rejected with
//!   [`ReferenceError`] instead of producing NaN.
//!
//! Ray/box: `scene::geometry::intersect_box` and `geometry.glsl` share one rule for direction
//! components below 1e-20 (a containment test on the closed slab, whatever the zero's sign), so
//! rays lying in either face plane hit in both.
//!
//! Opacity: the correction exponent is the step length in mm over `scene::REFERENCE_LENGTH_MM`
//! (1 mm), so tissue opacities are per millimetre and a world-space object renders alike on any
//! grid.

use crate::scene::camera::CameraRays;
use crate::scene::geometry::{VolumeGeometry, intersect_box};
use crate::scene::uniforms::{GradientStats, MAX_STEPS};
use crate::scene::{
    Classification, CurvatureMode, GradientFilter, GradientSource, Interpolation,
    OpacityCorrection, RenderMode, Scene,
};
use glam::{DMat3, DVec3};

/// Why the reference cannot render the given inputs.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// A dimension is zero, or the voxel count does not fit in memory addresses.
    #[error("volume dimensions {dims:?} are empty or too large")]
    BadDims {
        /// The offending dimensions.
        dims: [u32; 3],
    },
    /// A voxel array's length does not match the dimensions.
    #[error("the {what} has {actual} values, but dimensions {dims:?} need {expected}")]
    Length {
        /// Which array (`I_norm`, `gradient magnitude`, ...).
        what: &'static str,
        /// Dimensions it was checked against.
        dims: [u32; 3],
        /// Voxel count of `dims`.
        expected: usize,
        /// Values given.
        actual: usize,
    },
    /// A voxel value is NaN or infinite.
    #[error("the {what} has a non-finite value at voxel {index}")]
    NonFiniteVoxel {
        /// Which array.
        what: &'static str,
        /// Linear index of the first bad voxel (x fastest).
        index: usize,
    },
    /// The geometry describes a different grid than the volume.
    #[error("the geometry's dimensions {geometry:?} differ from the volume's {volume:?}")]
    DimsMismatch {
        /// `VolumeGeometry::dims`.
        geometry: [u32; 3],
        /// `ReferenceVolume::dims`.
        volume: [u32; 3],
    },
    /// The scene reads a precomputed derived volume that was not supplied.
    #[error(
        "the scene reads a precomputed {what} volume, but none was given (supply it, or render \
         with GradientSource::OnTheFly)"
    )]
    MissingDerived {
        /// `gradient magnitude`, `curvature` or `normals`.
        what: &'static str,
    },
    /// A scene, geometry or gradient parameter is out of its domain.
    #[error("the parameter {what} is {value}, which the raymarch cannot use")]
    BadParameter {
        /// Which parameter.
        what: &'static str,
        /// Its value.
        value: f64,
    },
}

/// The normalized volume I_norm, validated: `dims` are all >= 1, `norm` holds exactly
/// `dims[0] * dims[1] * dims[2]` finite values, x fastest.
#[derive(Clone, Copy)]
pub struct ReferenceVolume<'a> {
    dims: [u32; 3],
    norm: &'a [f64],
}

impl<'a> ReferenceVolume<'a> {
    /// Validates and wraps I_norm (x fastest, then y, then z).
    pub fn new(dims: [u32; 3], norm: &'a [f64]) -> Result<Self, ReferenceError> {
        check_values("I_norm", dims, norm, |v| v.is_finite())?;
        Ok(ReferenceVolume { dims, norm })
    }

    /// Voxels along i, j, k.
    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    /// The values, x fastest.
    pub fn norm(&self) -> &'a [f64] {
        self.norm
    }
}

/// Per-voxel derived volumes for `GradientSource::Precomputed` (same dims and order as I_norm),
/// in the units the derivative pass stores: |g| in I_norm per mm, k in I_norm per mm^2, normals
/// as world-space vectors (unit, or zero where |g| <= tau). Only those the scene reads are
/// required; any that is given is validated.
#[derive(Clone, Copy, Default)]
pub struct ReferenceDerived<'a> {
    /// |grad I_norm| per voxel (the gradient texture's `.r`).
    pub gradient_magnitude: Option<&'a [f64]>,
    /// Directional curvature k per voxel (the gradient texture's `.g`).
    pub curvature: Option<&'a [f64]>,
    /// World-space unit gradient direction per voxel (the normal texture's `.xyz`).
    pub normals: Option<&'a [[f64; 3]]>,
}

impl ReferenceDerived<'static> {
    /// No derived volumes (MIP, MinIP, on-the-fly gradients).
    pub const NONE: ReferenceDerived<'static> = ReferenceDerived {
        gradient_magnitude: None,
        curvature: None,
        normals: None,
    };
}

// Debug output names sizes, not millions of voxel values.
impl std::fmt::Debug for ReferenceVolume<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ReferenceVolume({:?}, {} values)",
            self.dims,
            self.norm.len()
        )
    }
}

impl std::fmt::Debug for ReferenceDerived<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ReferenceDerived")
            .field(
                "gradient_magnitude",
                &self.gradient_magnitude.map(<[f64]>::len),
            )
            .field("curvature", &self.curvature.map(<[f64]>::len))
            .field("normals", &self.normals.map(<[[f64; 3]]>::len))
            .finish()
    }
}

fn voxel_count(dims: [u32; 3]) -> Result<usize, ReferenceError> {
    let bad = ReferenceError::BadDims { dims };
    if dims.contains(&0) {
        return Err(bad);
    }
    dims.iter()
        .try_fold(1usize, |n, &d| n.checked_mul(d as usize))
        .ok_or(bad)
}

fn check_values<T>(
    what: &'static str,
    dims: [u32; 3],
    values: &[T],
    finite: impl Fn(&T) -> bool,
) -> Result<(), ReferenceError> {
    let expected = voxel_count(dims)?;
    if values.len() != expected {
        return Err(ReferenceError::Length {
            what,
            dims,
            expected,
            actual: values.len(),
        });
    }
    match values.iter().position(|v| !finite(v)) {
        Some(index) => Err(ReferenceError::NonFiniteVoxel { what, index }),
        None => Ok(()),
    }
}

/// A grid of voxel values of any arity, sampled like a clamp-to-edge linear texture. Only built
/// from validated arrays, so every clamped index is in bounds.
#[derive(Clone, Copy)]
struct Grid<'a, T> {
    dims: [u32; 3],
    data: &'a [T],
}

/// One axis of a linear clamp-to-edge fetch: the two texel indices and the weight of the second.
fn axis_taps(dim: u32, x: f64) -> ([usize; 2], f64) {
    let base = x.floor();
    let t = x - base;
    // `as` saturates (NaN -> 0), and `last >= 0` keeps `clamp` from ever seeing min > max.
    let first = base as i64;
    let last = (i64::from(dim) - 1).max(0);
    let clamp = |i: i64| i.clamp(0, last) as usize;
    ([clamp(first), clamp(first.saturating_add(1))], t)
}

fn lerp<const N: usize>(a: [f64; N], b: [f64; N], t: f64) -> [f64; N] {
    // a + t (b - a): exact when a == b, so a constant volume samples to exactly its constant.
    std::array::from_fn(|c| a[c] + t * (b[c] - a[c]))
}

impl<T: Copy> Grid<'_, T> {
    fn sample<const N: usize>(&self, p: DVec3, value: impl Fn(T) -> [f64; N]) -> [f64; N] {
        let (xi, tx) = axis_taps(self.dims[0], p.x);
        let (yi, ty) = axis_taps(self.dims[1], p.y);
        let (zi, tz) = axis_taps(self.dims[2], p.z);
        let nx = self.dims[0] as usize;
        let nxy = nx * self.dims[1] as usize;
        // Indices are clamped into the validated grid; the fallback is unreachable and only
        // keeps library code free of panicking paths.
        let fetch = |i: usize, j: usize, k: usize| {
            self.data
                .get(i + nx * j + nxy * k)
                .map_or([0.0; N], |&v| value(v))
        };
        let plane = |k: usize| {
            let row = |j: usize| lerp(fetch(xi[0], j, k), fetch(xi[1], j, k), tx);
            lerp(row(yi[0]), row(yi[1]), ty)
        };
        lerp(plane(zi[0]), plane(zi[1]), tz)
    }
}

impl<T: Copy> Grid<'_, T> {
    fn at<const N: usize>(
        &self,
        i: i64,
        j: i64,
        k: i64,
        value: &impl Fn(T) -> [f64; N],
    ) -> [f64; N] {
        let c = |v: i64, d: u32| v.clamp(0, (i64::from(d) - 1).max(0)) as usize;
        let nx = self.dims[0] as usize;
        let nxy = nx * self.dims[1] as usize;
        self.data
            .get(c(i, self.dims[0]) + nx * c(j, self.dims[1]) + nxy * c(k, self.dims[2]))
            .map_or([0.0; N], |&v| value(v))
    }

    /// A fetch with the scene's interpolation: the nearest voxel (centres at integers, ties
    /// rounding up like `floor(p + 0.5)`), trilinear, or the cubic B-spline as its 64-tap
    /// convolution with clamped indices (the shader computes the same sum with 8 linear
    /// fetches).
    fn fetch<const N: usize>(
        &self,
        p: DVec3,
        value: impl Fn(T) -> [f64; N],
        interpolation: Interpolation,
    ) -> [f64; N] {
        match interpolation {
            Interpolation::Trilinear => self.sample(p, value),
            Interpolation::Nearest => {
                let r = (p + DVec3::splat(0.5)).floor();
                self.at(r.x as i64, r.y as i64, r.z as i64, &value)
            }
            Interpolation::Tricubic => {
                let base = p.floor();
                let t = p - base;
                let weights = |t: f64| {
                    let (t2, t3) = (t * t, t * t * t);
                    [
                        (1.0 - 3.0 * t + 3.0 * t2 - t3) / 6.0,
                        (4.0 - 6.0 * t2 + 3.0 * t3) / 6.0,
                        (1.0 + 3.0 * t + 3.0 * t2 - 3.0 * t3) / 6.0,
                        t3 / 6.0,
                    ]
                };
                let (wx, wy, wz) = (weights(t.x), weights(t.y), weights(t.z));
                let (bx, by, bz) = (base.x as i64, base.y as i64, base.z as i64);
                let mut acc = [0.0; N];
                for (dz, wz) in wz.iter().enumerate() {
                    for (dy, wy) in wy.iter().enumerate() {
                        for (dx, wx) in wx.iter().enumerate() {
                            let v = self.at(
                                bx + dx as i64 - 1,
                                by + dy as i64 - 1,
                                bz + dz as i64 - 1,
                                &value,
                            );
                            let w = wx * wy * wz;
                            for c in 0..N {
                                acc[c] += w * v[c];
                            }
                        }
                    }
                }
                acc
            }
        }
    }
}

/// A fetch of I_norm at `p` with `interpolation` (see the shader's `sampling.glsl`).
pub fn fetch(volume: &ReferenceVolume<'_>, p: DVec3, interpolation: Interpolation) -> f64 {
    Grid {
        dims: volume.dims,
        data: volume.norm,
    }
    .fetch(p, |v: f64| [v], interpolation)[0]
}

/// Trilinear, clamp-to-edge sample of I_norm at index-space position `p` (voxel centres at
/// integers), exactly what `textureLod(volume, (p + 0.5) / dims, 0)` computes with a `LINEAR`,
/// `CLAMP_TO_EDGE` sampler, with exact weights.
pub fn trilinear(volume: &ReferenceVolume<'_>, p: DVec3) -> f64 {
    let grid = Grid {
        dims: volume.dims,
        data: volume.norm,
    };
    grid.sample(p, |v: f64| [v])[0]
}

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
fn gradient_central_with(
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
fn gradient_sobel_with(
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
fn curvature_with(
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

/// Where one pixel's samples are: `position(i)` for `i < count`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayPlan {
    /// Ray origin in index space.
    pub origin: DVec3,
    /// Ray direction in index space per mm of ray length (not normalized).
    pub direction: DVec3,
    /// Unit world-space ray direction (the shading's view vector).
    pub view_direction: DVec3,
    /// `(t_near, t_far)` in mm from `intersect_box` (t_near clamped at 0), None on a miss.
    pub hit: Option<(f64, f64)>,
    /// Start offset in steps: the jitter value, or 0.5.
    pub offset: f64,
    /// Ray parameter of sample 0, mm.
    pub start: f64,
    /// Step length, mm.
    pub step_mm: f64,
    /// Number of samples (0 on a miss).
    pub count: u32,
}

impl RayPlan {
    /// Index-space position of sample `i`: `origin + direction * (start + i * dt)`.
    pub fn position(&self, i: u32) -> DVec3 {
        self.origin + self.direction * self.parameter(i)
    }

    /// Ray parameter (mm) of sample `i`.
    pub fn parameter(&self, i: u32) -> f64 {
        self.start + f64::from(i) * self.step_mm
    }
}

/// The intermediate values of one DVR sample, named as in the shader's loop body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DvrSample {
    /// Trilinear I_norm `v`.
    pub value: f64,
    /// `f(v)`, in (0, 1].
    pub f: f64,
    /// `C_s(v)`, before shading.
    pub colour: [f64; 3],
    /// |grad I| per mm (precomputed and interpolated, or on the fly).
    pub magnitude: f64,
    /// Curvature k per mm^2 (0 unless the curvature effect is on).
    pub curvature: f64,
    /// Shading normal, not normalized (0 unless shading is on, or where |g| <= tau on the fly).
    pub normal: DVec3,
    /// Opacity of eq. 4 for one voxel of step: `clamp(f |g| / |g|max, 0, 1)`, times `w(k)` and
    /// capped at 1 when the curvature effect is on.
    pub opacity: f64,
    /// `opacity` corrected for the step (`opacity_correct(opacity, r)`): what is composited.
    pub corrected: f64,
    /// The colour composited (shaded when shading is on).
    pub shaded: [f64; 3],
}

/// A validated raymarch of one scene on one volume and image size: the f64 counterpart of the
/// uniform block plus the bound textures. [`render`] is `ReferenceRaymarch::new(..)?.render()`;
/// the type also gives single pixels and the sample positions of a ray.
#[derive(Clone, Debug)]
pub struct ReferenceRaymarch<'a> {
    volume: ReferenceVolume<'a>,
    gradient_magnitude: Option<Grid<'a, f64>>,
    curvature: Option<Grid<'a, f64>>,
    normals: Option<Grid<'a, [f64; 3]>>,
    rays: CameraRays,
    geometry: VolumeGeometry,
    classification: Classification,
    mode: RenderMode,
    curvature_on: bool,
    curvature_mode: CurvatureMode,
    shading: bool,
    on_the_fly: bool,
    gradient_filter: GradientFilter,
    interpolation: Interpolation,
    naive_opacity: bool,
    opacity_exponent: f64,
    step_mm: f64,
    early_termination: f64,
    jitter: bool,
    frame: u32,
    background: [f64; 3],
    inv_max_magnitude: f64,
    curvature_strength: f64,
    k_ref: f64,
    tau: f64,
    intensity_window: [f64; 2],
    minip_floor: f64,
    width: u32,
    height: u32,
}

impl<T> std::fmt::Debug for Grid<'_, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Grid({:?}, {} values)", self.dims, self.data.len())
    }
}

fn finite(what: &'static str, value: f64) -> Result<f64, ReferenceError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ReferenceError::BadParameter { what, value })
    }
}

impl<'a> ReferenceRaymarch<'a> {
    /// Validates the inputs for rendering `scene` at `width` x `height`.
    pub fn new(
        scene: &Scene,
        geometry: &VolumeGeometry,
        gradients: &GradientStats,
        volume: &ReferenceVolume<'a>,
        derived: &ReferenceDerived<'a>,
        width: u32,
        height: u32,
    ) -> Result<Self, ReferenceError> {
        let dims = volume.dims;
        if geometry.dims != dims {
            return Err(ReferenceError::DimsMismatch {
                geometry: geometry.dims,
                volume: dims,
            });
        }
        if !(geometry.world_to_index.is_finite()
            && geometry.index_to_world.is_finite()
            && geometry.gradient_to_world.is_finite())
        {
            return Err(ReferenceError::BadParameter {
                what: "geometry matrix",
                value: f64::NAN,
            });
        }
        let voxel_mm = finite("geometry.voxel_mm", geometry.voxel_mm)?;
        if voxel_mm <= 0.0 {
            return Err(ReferenceError::BadParameter {
                what: "geometry.voxel_mm",
                value: voxel_mm,
            });
        }

        let gradient_magnitude = derived
            .gradient_magnitude
            .map(|d| {
                check_values("gradient magnitude", dims, d, |v| v.is_finite())
                    .map(|()| Grid { dims, data: d })
            })
            .transpose()?;
        let curvature = derived
            .curvature
            .map(|d| {
                check_values("curvature", dims, d, |v| v.is_finite())
                    .map(|()| Grid { dims, data: d })
            })
            .transpose()?;
        let normals = derived
            .normals
            .map(|d| {
                check_values("normals", dims, d, |n| n.iter().all(|c| c.is_finite()))
                    .map(|()| Grid { dims, data: d })
            })
            .transpose()?;

        let effects = scene.effects;
        let dvr = effects.mode == RenderMode::Dvr;
        // Specialization constants: curvature and shading exist only in the DVR variant.
        let curvature_mode = effects.curvature_mode();
        let curvature_on = curvature_mode != CurvatureMode::Off;
        let shading = dvr && effects.shading;
        let on_the_fly = effects.gradient_source == GradientSource::OnTheFly;
        if dvr && !on_the_fly {
            let missing = |what| Err(ReferenceError::MissingDerived { what });
            if gradient_magnitude.is_none() {
                return missing("gradient magnitude");
            }
            if curvature_mode == CurvatureMode::Stored && curvature.is_none() {
                return missing("curvature");
            }
            if shading && normals.is_none() {
                return missing("normals");
            }
        }

        // Classification as it reaches the GPU: RaymarchUniforms::new clamps opacity to [0, 1].
        let mut classification = scene.classification;
        for style in &mut classification.tissues {
            finite("tissue opacity", f64::from(style.opacity))?;
            for c in style.colour {
                finite("tissue colour", f64::from(c))?;
            }
            if let Some(w) = style.window {
                finite("window lo", w.lo)?;
                finite("window hi", w.hi)?;
                finite("window edge", w.edge)?;
            }
            style.opacity = style.opacity.clamp(0.0, 1.0);
        }
        let background = scene.background.map(f64::from);
        for &c in &background {
            finite("background", c)?;
        }
        let early_termination = f64::from(scene.early_termination);
        if early_termination.is_nan() {
            return Err(ReferenceError::BadParameter {
                what: "early_termination",
                value: early_termination,
            });
        }
        let intensity_window = scene.intensity_window.map(f64::from);
        for &w in &intensity_window {
            finite("intensity_window", w)?;
        }
        let minip_floor = finite("minip_floor", f64::from(scene.minip_floor))?;
        let curvature_strength = finite("curvature_strength", f64::from(scene.curvature_strength))?;
        let max_magnitude = finite("max_magnitude", gradients.max_magnitude)?;
        let tau = finite("tau", gradients.tau)?;
        if tau < 0.0 {
            // A negative tau would let the zero gradient through to g / |g|.
            return Err(ReferenceError::BadParameter {
                what: "tau",
                value: tau,
            });
        }

        let step_voxels = scene.sanitized_step_voxels();
        let rays = scene.camera.rays(geometry.world_bounds(), width, height);
        Ok(ReferenceRaymarch {
            volume: *volume,
            gradient_magnitude,
            curvature,
            normals,
            rays,
            geometry: *geometry,
            classification,
            mode: effects.mode,
            curvature_on,
            curvature_mode,
            shading,
            on_the_fly,
            gradient_filter: effects.quality.gradient_filter,
            interpolation: effects.quality.interpolation,
            naive_opacity: dvr && effects.quality.opacity_correction == OpacityCorrection::Naive,
            opacity_exponent: scene.opacity_exponent(voxel_mm),
            step_mm: step_voxels * voxel_mm,
            early_termination,
            jitter: scene.jitter,
            frame: scene.frame,
            background,
            inv_max_magnitude: if max_magnitude > 0.0 {
                1.0 / max_magnitude
            } else {
                0.0
            },
            curvature_strength,
            k_ref: gradients.k_ref(voxel_mm),
            tau,
            intensity_window,
            minip_floor,
            width,
            height,
        })
    }

    /// The resolved camera.
    pub fn camera_rays(&self) -> &CameraRays {
        &self.rays
    }

    /// Step length in mm (`step_voxels * voxel_mm`, step sanitized).
    pub fn step_mm(&self) -> f64 {
        self.step_mm
    }

    /// The opacity-correction exponent r (the step length in mm over 1 mm).
    pub fn opacity_exponent(&self) -> f64 {
        self.opacity_exponent
    }

    /// `k_ref` of the curvature weight (`GradientStats::k_ref(voxel_mm)`).
    pub fn k_ref(&self) -> f64 {
        self.k_ref
    }

    /// The samples of pixel (x, y): ray, box hit, start and count, as the shader computes them.
    pub fn ray(&self, x: u32, y: u32) -> RayPlan {
        let (origin_world, direction_world) =
            self.rays
                .ray(f64::from(x), f64::from(y), self.width, self.height);
        let (origin, direction) = self.geometry.ray_to_index(origin_world, direction_world);
        let offset = if self.jitter {
            jitter(x, y, self.frame)
        } else {
            0.5
        };
        let dt = self.step_mm;
        let finite = origin.is_finite() && direction.is_finite() && direction_world.is_finite();
        let hit = if finite {
            intersect_box(origin, direction, self.volume.dims)
        } else {
            None
        };
        let t_near = hit.map_or(0.0, |(t_near, _)| t_near);
        let start = t_near + offset * dt;
        let count = match hit {
            // Clamped before the conversion, like the shader (NaN converts to 0).
            Some((_, t_far)) => {
                (((t_far - start) / dt).floor() + 1.0).clamp(0.0, f64::from(MAX_STEPS)) as u32
            }
            None => 0,
        };
        RayPlan {
            origin,
            direction,
            view_direction: direction_world,
            hit,
            offset,
            start,
            step_mm: dt,
            count,
        }
    }

    /// RGBA of pixel (x, y) (alpha 1), before quantization.
    pub fn pixel(&self, x: u32, y: u32) -> [f64; 4] {
        let plan = self.ray(x, y);
        match self.mode {
            RenderMode::Dvr => self.dvr(&plan),
            RenderMode::Mip | RenderMode::MinIp => self.projection(&plan),
        }
    }

    /// The whole image, rows top to bottom.
    pub fn render(&self) -> Vec<[f64; 4]> {
        let mut image = Vec::with_capacity(self.width as usize * self.height as usize);
        for y in 0..self.height {
            for x in 0..self.width {
                image.push(self.pixel(x, y));
            }
        }
        image
    }

    fn with_background(&self, acc: [f64; 4]) -> [f64; 4] {
        let t = 1.0 - acc[3];
        [
            acc[0] + t * self.background[0],
            acc[1] + t * self.background[1],
            acc[2] + t * self.background[2],
            1.0,
        ]
    }

    /// I_norm at `p` with the scene's interpolation.
    fn value(&self, p: DVec3) -> f64 {
        fetch(&self.volume, p, self.interpolation)
    }

    /// |g|, k and the shading normal at `p` (k and the normal are 0 when their effect is off).
    fn derivatives(&self, p: DVec3, v: f64) -> (f64, f64, DVec3) {
        let m = self.geometry.gradient_to_world;
        let sample = |q: DVec3| self.value(q);
        let (magnitude, mut normal, central) = if self.on_the_fly {
            let g = match self.gradient_filter {
                GradientFilter::Central => gradient_central_with(&sample, m, p),
                GradientFilter::Sobel => gradient_sobel_with(&sample, m, p),
            };
            let magnitude = g.length();
            let normal = if magnitude > self.tau {
                g / magnitude
            } else {
                DVec3::ZERO
            };
            let central = (self.gradient_filter == GradientFilter::Central).then_some(g);
            (magnitude, normal, central)
        } else {
            let scalar = |grid: Option<Grid<'_, f64>>| {
                grid.map_or(0.0, |g| g.fetch(p, |v| [v], self.interpolation)[0])
            };
            let normal = match self.normals {
                Some(grid) => DVec3::from_array(grid.fetch(p, |n| n, self.interpolation)),
                None => DVec3::ZERO,
            };
            (scalar(self.gradient_magnitude), normal, None)
        };
        let k = match self.curvature_mode {
            CurvatureMode::Off => 0.0,
            CurvatureMode::Stored => self
                .curvature
                .map_or(0.0, |g| g.fetch(p, |v| [v], self.interpolation)[0]),
            CurvatureMode::OnTheFly => {
                let g = central.unwrap_or_else(|| gradient_central_with(&sample, m, p));
                curvature_with(&sample, m, self.tau, p, v, g)
            }
        };
        if !self.shading {
            normal = DVec3::ZERO;
        }
        (magnitude, k, normal)
    }

    /// The DVR terms of one sample at index position `p` seen along the unit world direction
    /// `view_direction`, or None where the shader skips it (`f(v) <= 0`). For finding out why a
    /// GPU pixel differs: every intermediate of the shader's loop body.
    pub fn dvr_sample(&self, p: DVec3, view_direction: DVec3) -> Option<DvrSample> {
        let value = self.value(p);
        let (f, colour) = self.classification.classify(value);
        if f <= 0.0 {
            return None;
        }
        let (magnitude, curvature, normal) = self.derivatives(p, value);
        let mut opacity = (f * magnitude * self.inv_max_magnitude).clamp(0.0, 1.0);
        if self.curvature_on {
            opacity = (opacity * curvature_weight(curvature, self.curvature_strength, self.k_ref))
                .min(1.0);
        }
        let corrected = if self.naive_opacity {
            opacity_correct_naive(opacity, self.opacity_exponent)
        } else {
            opacity_correct(opacity, self.opacity_exponent)
        };
        let shaded = if self.shading {
            shade(colour, normal, view_direction)
        } else {
            colour
        };
        Some(DvrSample {
            value,
            f,
            colour,
            magnitude,
            curvature,
            normal,
            opacity,
            corrected,
            shaded,
        })
    }

    fn dvr(&self, plan: &RayPlan) -> [f64; 4] {
        let mut acc = [0.0; 4];
        for i in 0..plan.count {
            let Some(sample) = self.dvr_sample(plan.position(i), plan.view_direction) else {
                continue;
            };
            composite(&mut acc, sample.shaded, sample.corrected);
            // After compositing, like the shader: the sample that crosses the threshold counts.
            if acc[3] > self.early_termination {
                break;
            }
        }
        self.with_background(acc)
    }

    fn projection(&self, plan: &RayPlan) -> [f64; 4] {
        let mip = self.mode == RenderMode::Mip;
        let mut found = false;
        let mut extreme: f64 = if mip { 0.0 } else { 1.0 };
        for i in 0..plan.count {
            let v = self.value(plan.position(i));
            if mip {
                extreme = extreme.max(v);
                found = true;
            } else if v >= self.minip_floor {
                extreme = extreme.min(v);
                found = true;
            }
        }
        if !found {
            return self.with_background([0.0; 4]);
        }
        let [lo, hi] = self.intensity_window;
        let grey = ((extreme - lo) / (hi - lo).max(1e-6)).clamp(0.0, 1.0);
        [grey, grey, grey, 1.0]
    }
}

/// Renders `scene` on `volume` at `width` x `height` exactly as `shaders/raymarch.comp` does, in
/// f64: RGBA per pixel (alpha 1), rows top to bottom, before 8-bit quantization.
pub fn render(
    scene: &Scene,
    geometry: &VolumeGeometry,
    gradients: &GradientStats,
    volume: &ReferenceVolume<'_>,
    derived: &ReferenceDerived<'_>,
    width: u32,
    height: u32,
) -> Result<Vec<[f64; 4]>, ReferenceError> {
    Ok(
        ReferenceRaymarch::new(scene, geometry, gradients, volume, derived, width, height)?
            .render(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Classification, Effects, Window};

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
        let r = ReferenceRaymarch::new(&scene, &g, &STATS, &vol, &ReferenceDerived::NONE, 5, 5)
            .unwrap();
        assert_eq!(r.ray(2, 2).count, MAX_STEPS);
        // Jittered starts use the hash of (x, y, frame).
        scene.jitter = true;
        scene.frame = 9;
        let r = ReferenceRaymarch::new(&scene, &g, &STATS, &vol, &ReferenceDerived::NONE, 5, 5)
            .unwrap();
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
}
