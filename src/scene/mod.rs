//! The scene: what to render (camera, classification, mode, effects, quality), independent of
//! the GPU. The raymarch pass turns it into uniforms; the f64 reference reads it directly.
//!
//! Decisions: everything a user changes interactively is here and reaches the GPU as a uniform
//! write only. What decides which passes and shader variants exist (mode, curvature, shading,
//! gradient source) is separated in [`Effects`], so a change there is visible as such.

pub mod camera;
pub mod classification;
pub mod clip;
pub mod colormap;
pub mod document;
pub mod geometry;
pub mod layer;
pub mod layer_grid;
pub mod layer_open;
pub mod lighting;
pub mod matcap;
pub mod measure;
pub mod occupancy;
pub mod overlay;
pub mod preset;
pub mod recipe;
pub mod slice;
pub mod transfer_table;
pub mod uniforms;
pub mod variant;
pub mod views;
pub mod visibility;

pub use camera::{Camera, Projection};
pub use classification::{Classification, TissueClass, TissueStyle, VesselStyle, Window};
pub use clip::{Clip, ClipPlane};
pub use colormap::Colormap;
pub use geometry::VolumeGeometry;
pub use lighting::{Cutaway, DepthCues, LightModel, Lighting};
pub use preset::Preset;
pub use recipe::{RecipeError, SceneRecipe, WindowSet};

/// The path length a tissue's opacity refers to: 1 mm, so opacities mean the same on a 0.5 mm
/// and a 3 mm grid (a per-voxel definition would make finer grids look denser).
pub const REFERENCE_LENGTH_MM: f64 = 1.0;

/// What a ray computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RenderMode {
    /// Emission-absorption compositing of classified samples (the paper).
    Dvr,
    /// Maximum intensity projection.
    Mip,
    /// Minimum intensity projection over samples at or above a floor.
    MinIp,
}

/// Where the gradient-magnitude term of eq. 4 (and normals, curvature) comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GradientSource {
    /// Read from volumes computed once by the derivative pass.
    Precomputed,
    /// Computed per sample from trilinear I_norm fetches (no derived memory).
    OnTheFly,
}

/// How volumes are interpolated at sample positions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// The nearest voxel.
    Nearest,
    /// Trilinear (hardware filtering).
    Trilinear,
    /// Cubic B-spline from 8 trilinear fetches (smooths: an approximating filter).
    Tricubic,
}

/// The finite-difference filter of on-the-fly gradients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GradientFilter {
    /// Central differences (6 fetches).
    Central,
    /// Central differences smoothed across each axis (Sobel-like, 24 fetches).
    Sobel,
}

/// Where the curvature term comes from when curvature weighting is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CurvatureSource {
    /// Stored by the derivative pass (needs precomputed gradients).
    Stored,
    /// Computed per sample from 19 I_norm fetches.
    OnTheFly,
}

pub use crate::passes::derivatives::DerivedPrecision;

/// How opacity is corrected for the step length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OpacityCorrection {
    /// `-expm1(r * log1p(-a))`, accurate for tiny opacities.
    Exact,
    /// `1 - (1 - a)^r` in f32 (loses tiny opacities; for the accuracy study).
    Naive,
}

/// How a sample's tissue windows are evaluated (issue 33 item 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClassificationLookup {
    /// Every window's two smoothsteps per sample (paper eq. 4 as written).
    Exact,
    /// One linear lookup in a 4096-entry table of the window sums (`transfer_table`).
    Table,
    /// Every voxel classified once into an RGBA8 volume (eq. 4's opacity at the voxel, step
    /// corrected, and its colour) when the classification changes; a sample is one trilinear
    /// fetch of it (pre-classification; the lean sample of issue 33 item 1). Scenes with a cut
    /// are drawn with the table (cut faces need f(v) per sample).
    Volume,
}

/// The quality knobs: what accuracy costs in time (the accuracy study varies each).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Quality {
    /// Interpolation of every volume fetch.
    pub interpolation: Interpolation,
    /// Filter of on-the-fly gradients.
    pub gradient_filter: GradientFilter,
    /// Stored or on-the-fly curvature.
    pub curvature_source: CurvatureSource,
    /// Precision of stored derived volumes.
    pub derived_precision: DerivedPrecision,
    /// Opacity correction formula.
    pub opacity_correction: OpacityCorrection,
    /// Skip 8^3 bricks in which no visible tissue can have opacity (lossless).
    pub empty_space_skipping: bool,
    /// Longer steps in bricks of low opacity bound (needs skipping; off by default).
    pub long_steps: occupancy::LongSteps,
    /// Tissue windows per sample or from the transfer-function table.
    pub classification: ClassificationLookup,
}

impl Default for Quality {
    /// Trilinear, central differences, stored curvature, derived volumes in 8-bit SNORM, exact
    /// correction, skipping on. 8-bit derived volumes are the interactive default because the
    /// accuracy study (ACCURACY.md) found them no less accurate than f16 at the default step
    /// (46.37 against 46.42 dB on the phantom, H100) at half the memory and, on lavapipe, 5 %
    /// less time; at the stills' step of 0.125 voxel f16 is worth its bytes (84 against 70 dB),
    /// so `--derived-precision f16` is the stills setting. The classification table is the
    /// default because the accuracy study found its error equal to the exact windows' at the
    /// study's precision (44.18 dB both, 96x112x96 phantom, this machine, lavapipe), below
    /// every other approximation's, at 15 % less unshaded DVR frame time (BENCHMARKS.md).
    fn default() -> Self {
        Quality {
            interpolation: Interpolation::Trilinear,
            gradient_filter: GradientFilter::Central,
            curvature_source: CurvatureSource::Stored,
            derived_precision: DerivedPrecision::Snorm8,
            opacity_correction: OpacityCorrection::Exact,
            empty_space_skipping: true,
            long_steps: occupancy::LongSteps::OFF,
            classification: ClassificationLookup::Table,
        }
    }
}

/// The parts of a scene that select shader variants and derived volumes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub struct Effects {
    /// Composite, MIP or MinIP.
    pub mode: RenderMode,
    /// Multiply opacity by the curvature weight w(k).
    pub curvature: bool,
    /// Phong shading with world-space gradient normals.
    pub shading: bool,
    /// Precomputed or on-the-fly derivatives.
    pub gradient_source: GradientSource,
    /// Quality knobs.
    pub quality: Quality,
    /// Draw the vessel channel (DVR): computes the multi-scale vesselness volume and classifies
    /// it with `Classification::vessels` (issue 15 item 3).
    pub vessels: bool,
    /// Classify tissues inside the extracted brain only (DVR; issue 27): `Auto` masks a head
    /// scan and leaves a skull-stripped one alone.
    pub brain: crate::passes::brain::BrainSwitch,
    /// Lighting model and depth cues (DVR; issue 34).
    pub lighting: Lighting,
}

impl Effects {
    /// The derived volumes the derivative pass must produce for these effects, or None when no
    /// derivative pass runs at all (MIP and MinIP read I_norm only). The on-the-fly path still
    /// runs the pass with no outputs, for max |g|.
    pub fn derivative_outputs(&self) -> Option<crate::passes::derivatives::DerivativeOutputs> {
        if self.mode != RenderMode::Dvr {
            return None;
        }
        let stored = self.gradient_source == GradientSource::Precomputed;
        Some(crate::passes::derivatives::DerivativeOutputs {
            magnitude: stored,
            curvature: stored && self.curvature_mode() == CurvatureMode::Stored,
            normal: stored && self.shading,
            precision: self.quality.derived_precision,
            vesselness: self.vessels,
            // Auto and On extract alike; which one masks is decided per frame (no recompute).
            brain: match self.brain {
                crate::passes::brain::BrainSwitch::Off => crate::passes::brain::BrainSwitch::Off,
                _ => crate::passes::brain::BrainSwitch::Auto,
            },
        })
    }

    /// Where the raymarch gets k from (or nothing): stored only with precomputed gradients.
    pub fn curvature_mode(&self) -> CurvatureMode {
        if !self.curvature || self.mode != RenderMode::Dvr {
            CurvatureMode::Off
        } else if self.gradient_source == GradientSource::OnTheFly
            || self.quality.curvature_source == CurvatureSource::OnTheFly
        {
            CurvatureMode::OnTheFly
        } else {
            CurvatureMode::Stored
        }
    }
}

/// The curvature term as the raymarch computes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CurvatureMode {
    /// No curvature weight.
    Off,
    /// k read from the stored derived volume.
    Stored,
    /// k computed per sample.
    OnTheFly,
}

impl Default for Effects {
    fn default() -> Self {
        Effects {
            mode: RenderMode::Dvr,
            curvature: false,
            shading: false,
            gradient_source: GradientSource::Precomputed,
            quality: Quality::default(),
            vessels: false,
            brain: crate::passes::brain::BrainSwitch::Auto,
            lighting: Lighting::default(),
        }
    }
}

/// Everything that determines one image of one prepared volume.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scene {
    /// Camera.
    pub camera: Camera,
    /// Tissue windows, colours, opacities, switches.
    pub classification: Classification,
    /// Mode and effects.
    pub effects: Effects,
    /// Strength `s` of the curvature weight `w(k) = 1 + s * tanh(|k| / k_ref)`.
    pub curvature_strength: f32,
    /// Sampling distance in voxels (of the finest axis).
    pub step_voxels: f64,
    /// Early ray termination once accumulated opacity exceeds this (>= 1 disables it).
    pub early_termination: f32,
    /// Jittered ray starts against wood-grain banding.
    pub jitter: bool,
    /// Seed of the jitter pattern (a frame counter for animations).
    pub frame: u32,
    /// Background colour, RGB in [0, 1].
    pub background: [f32; 3],
    /// MIP/MinIP display window in I_norm: values map linearly from `lo` (black) to `hi` (white).
    pub intensity_window: [f32; 2],
    /// MinIP ignores samples below this I_norm (the background would otherwise win every ray).
    pub minip_floor: f32,
    // Helper "clip" (issue 16 items 2 and 4): crop box, clip planes, colour map.
    /// Crop box and clip planes: rays sample only the kept region (`clip.rs`).
    pub clip: Clip,
    /// MIP/MinIP: the map of the display window (None: grey). DVR: sample colours from the map
    /// instead of the tissue colours (None: tissue colours).
    pub colormap: Option<Colormap>,
    /// Outline and depth-cue strengths (issue 34; used by the lighting the effects select).
    pub cues: DepthCues,
    /// The "open the brain" cut: a plane through a point facing the camera (issue 34 item 3).
    pub cutaway: Option<Cutaway>,
}

impl Scene {
    /// The crop and planes a frame cuts with: the scene's, plus the cut-away's plane for the
    /// camera `rays` (left out when every plane slot is taken: the command line refuses that
    /// scene before it is built).
    pub fn frame_clip(
        &self,
        rays: &camera::CameraRays,
        bounds: (glam::DVec3, glam::DVec3),
    ) -> Clip {
        match self.cutaway {
            Some(cut) => cut.add_to(&self.clip, rays, bounds).unwrap_or(self.clip),
            None => self.clip,
        }
    }

    /// True when the scene cuts the volume (crop box, clip planes or a cut-away): its cut faces
    /// take the window opacity per sample, so a classified volume cannot draw it.
    pub fn has_cut(&self) -> bool {
        !self.clip.is_full() || self.cutaway.is_some()
    }

    /// The sampling distance the raymarch uses: `step_voxels`, or 0.5 when it is not a finite
    /// positive number (the one rule shared by the GPU uniforms and the f64 reference).
    pub fn sanitized_step_voxels(&self) -> f64 {
        if self.step_voxels.is_finite() && self.step_voxels > 0.0 {
            self.step_voxels
        } else {
            0.5
        }
    }

    /// Opacities are defined per millimetre of ray: the opacity-correction exponent of a step is
    /// its length in mm, so the same world-space object absorbs the same on any voxel grid.
    pub fn opacity_exponent(&self, voxel_mm: f64) -> f64 {
        self.sanitized_step_voxels() * voxel_mm / REFERENCE_LENGTH_MM
    }

    /// The default scene around the given classification: anterior view, DVR, step 0.5 voxel,
    /// early termination at 1 - 1/255, jitter on, black background.
    pub fn new(classification: Classification) -> Self {
        Scene {
            camera: Camera::default(),
            classification,
            effects: Effects::default(),
            curvature_strength: 1.0,
            step_voxels: 0.5,
            early_termination: 1.0 - 1.0 / 255.0,
            jitter: true,
            frame: 0,
            background: [0.0, 0.0, 0.0],
            intensity_window: [0.0, 1.0],
            minip_floor: 0.0,
            clip: Clip::default(),
            colormap: None,
            cues: DepthCues::default(),
            cutaway: None,
        }
    }
}
