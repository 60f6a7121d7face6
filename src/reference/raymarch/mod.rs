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
//! Classification table (`Quality::classification = Table`, issue 33 item 1): the tissue and
//! head windows come from `scene::transfer_table::TransferTable::classify_masked`, the twin of
//! the shader's table lookup (the same f32 entries, interpolated in f64).
//!
//! Crop and clip: the box interval is cut by `scene::clip::intersect_clipped` (the twin of
//! `clip.glsl`); colour maps are `scene::colormap` (the twin of `colormap.glsl`).
//!
//! Ray/box: `scene::geometry::intersect_box` and `geometry.glsl` share one rule for direction
//! components below 1e-20 (a containment test on the closed slab, whatever the zero's sign), so
//! rays lying in either face plane hit in both.
//!
//! Opacity: the correction exponent is the step length in mm over `scene::REFERENCE_LENGTH_MM`
//! (1 mm), so tissue opacities are per millimetre and a world-space object renders alike on any
//! grid.

//!
//! Files: `inputs.rs` (validated inputs, errors), `sampling.rs` (texture fetches),
//! `formulas.rs` (per-sample formulas), this file (rays, samples, pixels).

mod brain;
mod classified;
mod dvr_sample;
mod formulas;
mod inputs;
mod labels;
mod layers;
mod lighting;
mod long_steps;
mod projection;
mod sampling;
#[cfg(test)]
mod tests;

pub use dvr_sample::DvrSample;
pub use formulas::*;
pub use inputs::{ReferenceDerived, ReferenceError, ReferenceVolume};
pub use labels::ReferenceLabels;
pub use layers::ReferenceLayer;
pub use long_steps::ReferenceLongSteps;
pub use sampling::{fetch, trilinear};

use crate::scene::camera::CameraRays;
use crate::scene::clip::{IndexClip, intersect_clipped};
use crate::scene::geometry::VolumeGeometry;
use crate::scene::uniforms::{GradientStats, MAX_STEPS};
use crate::scene::{
    Classification, ClassificationLookup, Colormap, CurvatureMode, GradientFilter, GradientSource,
    Interpolation, OpacityCorrection, RenderMode, Scene,
};
use glam::DVec3;
use inputs::{check_values, finite};
use sampling::Grid;

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
    /// Samples with a parameter below this lie in a cut face's cap (-1: the ray entered through
    /// no cut face).
    pub cap_end: f64,
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
    clip: IndexClip,
    colormap: Option<Colormap>,
    labels: Option<ReferenceLabels<'a>>,
    layers: Vec<ReferenceLayer<'a>>,
    vesselness: Option<Grid<'a, f64>>,
    vessels_on: bool,
    brain_mask: Option<crate::reference::brain_mask::WorkingMask<'a>>,
    // The scene's long steps (DVR with skipping only) and, once given, the brick bounds.
    long_step_setting: Option<crate::scene::occupancy::LongSteps>,
    long_steps: Option<ReferenceLongSteps<'a>>,
    // The transfer-function table when the scene classifies through it (issue 33 item 1).
    table: Option<crate::scene::transfer_table::TransferTable>,
    // Lighting model, depth cues and their parameters (issue 34).
    lighting: lighting::ReferenceLighting,
    // DVR from the classified volume (issue 33 item 1), built on first use (classified.rs).
    classified_on: bool,
    classified: std::sync::OnceLock<Vec<[f64; 4]>>,
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
        // The engine's rule (engine/render.rs): a classified volume except for a cut scene.
        let classified_on = dvr
            && effects.quality.classification == ClassificationLookup::Volume
            && !scene.has_cut();
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

        if scene.clip.check().is_err() {
            return Err(ReferenceError::BadParameter {
                what: "clip (crop or plane)",
                value: f64::NAN,
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
            clip: scene
                .frame_clip(&rays, geometry.world_bounds())
                .to_index(geometry),
            lighting: lighting::ReferenceLighting {
                model: if shading {
                    effects.lighting.model
                } else {
                    crate::scene::LightModel::Headlight
                },
                matcap: (shading && effects.lighting.model == crate::scene::LightModel::Matcap)
                    .then(std::sync::Arc::default),
                camera_axes: [rays.right, rays.up],
                depth_cues: dvr && effects.lighting.depth_cues,
                key_light: crate::scene::lighting::key_light(&rays),
                cues: scene.cues.sanitized(),
            },
            colormap: scene.colormap,
            labels: None,
            layers: Vec::new(),
            vesselness: None,
            vessels_on: dvr && effects.vessels,
            brain_mask: None,
            long_step_setting: {
                let q = effects.quality;
                (dvr && q.empty_space_skipping && q.long_steps.is_on() && !classified_on)
                    .then_some(q.long_steps)
            },
            classified_on,
            classified: std::sync::OnceLock::new(),
            long_steps: None,
            table: (dvr && effects.quality.classification != ClassificationLookup::Exact)
                .then(|| crate::scene::transfer_table::TransferTable::new(&classification)),
        })
    }

    /// The vessel channel (`Effects::vessels`, DVR): `vesselness` is the volume the GPU's
    /// vesselness pass computed (the raymarch's input, as the derived volumes are), sampled
    /// like them and classified by `Classification::classify_with_vessels`.
    pub fn with_vesselness(mut self, vesselness: &'a [f64]) -> Result<Self, ReferenceError> {
        let dims = self.volume.dims;
        check_values("vesselness", dims, vesselness, |v| v.is_finite())?;
        self.vesselness = Some(Grid {
            dims,
            data: vesselness,
        });
        Ok(self)
    }

    /// Draws a label overlay in DVR, as a render target with labels attached does
    /// (`labels.rs`); the labels must be on the volume's grid.
    pub fn with_labels(mut self, labels: ReferenceLabels<'a>) -> Result<Self, ReferenceError> {
        check_values("labels", self.volume.dims, labels.values, |_| true)?;
        self.labels = Some(labels);
        Ok(self)
    }

    /// Draws intensity layers in DVR, as a render target with layers attached does
    /// (`layers.rs`), in order.
    pub fn with_layers(mut self, layers: &[ReferenceLayer<'a>]) -> Self {
        self.layers = layers.to_vec();
        self
    }

    /// The brick bounds the scene's long steps need (`BrickRanges::reference_bounds` on a
    /// `grid` of bricks of `side` voxels); without them, or when the scene's long steps are
    /// off, the twin takes no long steps.
    pub fn with_brick_bounds(
        mut self,
        grid: [u32; 3],
        side: u32,
        bounds: &'a [f64],
    ) -> Result<Self, ReferenceError> {
        let bricks = grid.iter().map(|&g| g as usize).product::<usize>();
        if bounds.len() != bricks || side == 0 {
            return Err(ReferenceError::BadParameter {
                what: "brick bounds (one per brick of the grid)",
                value: bounds.len() as f64,
            });
        }
        self.long_steps = self.long_step_setting.map(|s| ReferenceLongSteps {
            grid,
            side,
            bounds,
            factor: s.factor,
            threshold: s.threshold(),
        });
        Ok(self)
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
            intersect_clipped(origin, direction, self.volume.dims, &self.clip)
        } else {
            None
        };
        let t_near = hit.map_or(0.0, |(t_near, _)| t_near);
        let start = t_near + offset * dt;
        // As the shader: a cap only where a cut moved the entry beyond the volume box's.
        let box_near = crate::scene::geometry::intersect_box(origin, direction, self.volume.dims)
            .map_or(0.0, |b| b.0);
        let cap_end = if hit.is_some() && t_near > box_near + 1e-4 {
            t_near + crate::scene::lighting::CAP_MM
        } else {
            -1.0
        };
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
            cap_end,
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

    /// DVR (else a projection).
    fn is_dvr(&self) -> bool {
        self.mode == RenderMode::Dvr
    }

    /// MIP (else MinIP or DVR).
    fn is_mip(&self) -> bool {
        self.mode == RenderMode::Mip
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

    fn dvr(&self, plan: &RayPlan) -> [f64; 4] {
        self.dvr_picking(plan, None).0
    }

    /// The DVR pixel and, with `pick` (an opacity threshold), the ray parameter of the first
    /// sample at which the accumulated opacity reaches it (the shader's PICK).
    fn dvr_picking(&self, plan: &RayPlan, pick: Option<f64>) -> ([f64; 4], Option<f64>) {
        let mut acc = [0.0; 4];
        let mut picked = None;
        // Where the depth cues are evaluated: the sample at which acc.a first reaches 0.5.
        let mut surface: Option<(DVec3, DVec3)> = None;
        let mut next = 0;
        while next < plan.count {
            let i = next;
            let span = self.long_steps.map_or(1, |l| l.span(plan, i));
            next = i + span;
            let r = self.opacity_exponent * f64::from(span);
            let p = plan.position(i);
            let solid = plan.parameter(i) < plan.cap_end;
            let tissue = if self.classified_on {
                self.classified_sample(p, plan.view_direction)
            } else {
                self.dvr_sample_with(p, plan.view_direction, r, solid)
            };
            let label = self.labels.and_then(|labels| {
                let m = self.geometry.gradient_to_world;
                labels.sample(self.volume.dims.map(|d| d as usize), p, m, self.shading, r)
            });
            let layers: Vec<_> = self
                .layers
                .iter()
                .map(|layer| {
                    let m = self.geometry.gradient_to_world;
                    layer.sample(p, m, self.shading, r)
                })
                .collect();
            if tissue.is_none() && label.is_none() && layers.iter().all(Option::is_none) {
                continue;
            }
            let mut normal = DVec3::ZERO;
            // The layers' media first at this position, as in the shader.
            self.composite_layers(&mut acc, &mut normal, &layers, (solid, plan.view_direction));
            if let Some(sample) = &tissue {
                composite(&mut acc, sample.shaded, sample.corrected);
                normal = sample.normal;
            }
            // The label's medium after the tissue at the same position, as in the shader.
            if let Some((colour, opacity, label_normal)) = label {
                let colour = if self.shading {
                    self.lit(colour, label_normal, plan.view_direction)
                } else {
                    colour
                };
                if tissue.is_none() {
                    normal = label_normal;
                }
                composite(&mut acc, colour, opacity);
            }
            if self.lighting.depth_cues
                && surface.is_none()
                && acc[3] >= lighting::CUE_SURFACE_ALPHA
            {
                surface = Some((p, normal));
            }
            if let Some(threshold) = pick
                && picked.is_none()
                && acc[3] >= threshold
            {
                picked = Some(plan.parameter(i));
            }
            // After compositing, like the shader: the sample that crosses the threshold counts.
            if acc[3] > self.early_termination {
                break;
            }
        }
        if let Some((p, normal)) = surface {
            let factor = self.surface_cues(p, normal, plan.view_direction);
            for c in &mut acc[..3] {
                *c *= factor;
            }
        }
        (self.with_background(acc), picked)
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
