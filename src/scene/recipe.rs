//! A scene recipe: how to turn a volume's histogram analysis into a [`Scene`], given before the
//! volume is read, so every client (the CLI's commands, the viewer, an integrator) builds its
//! scenes the same way and the engine knows the effects to plan for up front.
//!
//! Decisions:
//! - The recipe is plain data in the library's vocabulary (tissue classes, windows, camera,
//!   effects); the command line only maps its arguments into it, the viewer's panels start
//!   from it.
//! - Everything that can be wrong with a recipe is found by [`SceneRecipe::check`] before any
//!   work; after that, [`SceneRecipe::scene_for`] cannot fail, whatever the analysis found (a
//!   tissue without a peak simply has no window).
//! - The effects are part of the recipe, not of the analysis: opening a volume plans for
//!   `recipe.effects` once, before the file is read, and the scene gets the planned (possibly
//!   degraded) effects afterwards.

use super::classification::{HeadRecipe, HeadStyle};
use super::preset::Preset;
use super::{Camera, Classification, Clip, Colormap, Effects, Scene, TissueClass, VesselStyle};
use crate::analysis::{Identity, TissueReport};

/// Which tissue windows a scene starts from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WindowSet {
    /// Around this volume's histogram peaks.
    #[default]
    Adaptive,
    /// The paper's fixed constants.
    Paper,
}

/// How to build a scene from a histogram analysis.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneRecipe {
    /// Adaptive or paper windows.
    pub windows: WindowSet,
    /// The visible tissues; None keeps the classification's default (all but pathology).
    pub visible: Option<Vec<TissueClass>>,
    /// Windows set by hand (I_norm), applied in order after `windows`.
    pub window: Vec<(TissueClass, f64, f64)>,
    /// Opacities per mm, in order.
    pub opacity: Vec<(TissueClass, f32)>,
    /// Colours (RGB 0..1), in order.
    pub colour: Vec<(TissueClass, [f32; 3])>,
    /// The vessel channel's style (window on the vesselness, colour, opacity); None keeps the
    /// default. Whether it is drawn is `effects.vessels`.
    pub vessel_style: Option<VesselStyle>,
    /// The head layer around an extracted brain (hidden unless asked for).
    pub head: HeadRecipe,
    /// A classification to use as it is, instead of `windows`, `visible`, `window`, `opacity`
    /// and `colour` (a client opening a volume again for the scene it shows).
    pub classification: Option<Classification>,
    /// Camera.
    pub camera: Camera,
    /// Mode and effects (what the engine plans for).
    pub effects: Effects,
    /// Sampling distance in voxels of the finest axis, in [`STEP_RANGE`].
    pub step_voxels: f64,
    /// Jittered ray starts.
    pub jitter: bool,
    /// Background colour, RGB 0..1.
    pub background: [f32; 3],
    /// Strength of the curvature weight.
    pub curvature_strength: f32,
    /// MIP/MinIP display window in I_norm.
    pub intensity_window: [f32; 2],
    /// Crop box and clip planes.
    pub clip: Clip,
    /// Outline and depth-cue strengths.
    pub cues: super::DepthCues,
    /// The "open the brain" cut.
    pub cutaway: Option<super::Cutaway>,
    /// Colour map (MIP/MinIP; DVR instead of tissue colours).
    pub colormap: Option<Colormap>,
    /// Denoising of I_norm when the volume is opened (before the derivatives and the raymarch);
    /// not part of [`Scene`]: a client opening a volume again keeps its own.
    pub denoise: crate::passes::denoise::Denoise,
    /// The look by modality (`scene::preset`), applied before `visible`, `window`, `opacity`
    /// and `colour`; None chooses it from the analysis (`Preset::auto`).
    pub preset: Option<Preset>,
}

impl Default for SceneRecipe {
    /// [`Scene::new`]'s defaults around adaptive windows.
    fn default() -> Self {
        // Scene::new's defaults; the classification is rebuilt per volume anyway.
        let scene = Scene::new(Classification::from_tissue_windows(
            &crate::analysis::TissueWindows::paper(),
        ));
        SceneRecipe {
            classification: None,
            ..SceneRecipe::from_scene(&scene)
        }
    }
}

/// The sampling steps a scene may have, in voxels of the finest axis. Below 1/64 voxel a ray
/// takes over 64 samples per voxel (`--step 1e-9` ran a minute and then failed with an
/// unrelated message, issue 30), and the accuracy study sees no change below 1/8 (ACCURACY.md).
pub const STEP_RANGE: (f64, f64) = (1.0 / 64.0, 16.0);

/// Why `step` (voxels) cannot be a scene's step, in the command line's words.
pub fn check_step(step: f64) -> Result<(), String> {
    let (lo, hi) = STEP_RANGE;
    if !step.is_finite() || step <= 0.0 || step > hi {
        return Err(format!(
            "--step {step} must be a number of voxels in [{lo}, {hi}] (0.5 is the default, \
             0.125 diagnosis quality)"
        ));
    }
    if step < lo {
        return Err(format!(
            "--step {step} is finer than {lo} voxel: each ray would take over {} samples per \
             voxel and the image would not change; use a step in [{lo}, {hi}] (0.125 is \
             diagnosis quality)",
            (1.0 / lo) as u32
        ));
    }
    Ok(())
}

/// A recipe that cannot make a scene (the message names the setting and its valid range).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct RecipeError(pub String);

impl SceneRecipe {
    /// Fails on settings no scene can have (a step outside [`STEP_RANGE`] voxels, a zoom that
    /// is not positive); the message uses the command line's names, which are the viewer's too.
    pub fn check(&self) -> Result<(), RecipeError> {
        check_step(self.step_voxels).map_err(RecipeError)?;
        let zoom = self.camera.zoom;
        if !(zoom.is_finite() && zoom > 0.0) {
            return Err(RecipeError(format!(
                "--zoom {zoom} must be a positive number"
            )));
        }
        self.clip.check().map_err(|e| RecipeError(e.0))?;
        Ok(())
    }

    /// The recipe that makes `scene` again (its classification as it is).
    pub fn from_scene(scene: &Scene) -> SceneRecipe {
        SceneRecipe {
            windows: WindowSet::Adaptive,
            visible: None,
            window: Vec::new(),
            opacity: Vec::new(),
            colour: Vec::new(),
            vessel_style: None,
            head: HeadRecipe::default(),
            classification: Some(scene.classification),
            camera: scene.camera,
            effects: scene.effects,
            step_voxels: scene.step_voxels,
            jitter: scene.jitter,
            background: scene.background,
            curvature_strength: scene.curvature_strength,
            intensity_window: scene.intensity_window,
            clip: scene.clip,
            cues: scene.cues,
            cutaway: scene.cutaway,
            colormap: scene.colormap,
            denoise: crate::passes::denoise::Denoise::None,
            preset: None,
        }
    }

    /// The scene this recipe makes around `report` (windows from its peaks, MinIP's floor from
    /// its background threshold).
    pub fn scene_for(&self, report: &TissueReport) -> Scene {
        let mut scene = Scene::new(self.classification_for(report));
        scene.camera = self.camera;
        scene.effects = self.effects;
        scene.effects.vessels = self.vessels_for(report);
        scene.step_voxels = self.step_voxels;
        scene.jitter = self.jitter;
        scene.background = self.background;
        scene.curvature_strength = self.curvature_strength;
        scene.intensity_window = self.intensity_window;
        scene.minip_floor = report.background_threshold as f32;
        scene.clip = self.clip;
        scene.cues = self.cues;
        scene.cutaway = self.cutaway;
        scene.colormap = self.colormap;
        scene
    }

    /// The preset this recipe uses on `report`: the one named, or the automatic choice.
    pub fn preset_for(&self, report: &TissueReport) -> Preset {
        self.preset.unwrap_or_else(|| Preset::auto(report))
    }

    /// Whether the scene should draw the vessel channel: asked for, or the preset wants it (in
    /// DVR; a hand-made classification keeps the effects as given).
    pub fn vessels_for(&self, report: &TissueReport) -> bool {
        self.vessels_with(self.preset_for(report))
    }

    /// The effects to plan for a volume of this `identity`: the recipe's, with the vessel
    /// channel when the preset the analysis will choose draws it (the preset rests on the
    /// identity alone, so the plan made before the analysis counts the vesselness volume).
    pub fn effects_for(&self, identity: &Identity) -> Effects {
        let preset = self
            .preset
            .unwrap_or_else(|| Preset::auto_identified(identity));
        Effects {
            vessels: self.vessels_with(preset),
            ..self.effects
        }
    }

    fn vessels_with(&self, preset: Preset) -> bool {
        self.effects.vessels
            || (self.classification.is_none()
                && self.effects.mode == super::RenderMode::Dvr
                && preset.wants_vessels())
    }

    fn classification_for(&self, report: &TissueReport) -> Classification {
        if let Some(classification) = self.classification {
            return classification;
        }
        let windows = match self.windows {
            WindowSet::Adaptive => &report.adaptive_windows,
            WindowSet::Paper => &report.paper_windows,
        };
        let mut classification = Classification::from_tissue_windows(windows);
        self.preset_for(report).apply(&mut classification, report);
        if let Some(visible) = &self.visible {
            classification.show_only(visible);
        }
        // Later settings win over earlier ones, as on the command line.
        for &(tissue, lo, hi) in &self.window {
            classification.set_window(tissue, lo, hi);
        }
        for &(tissue, opacity) in &self.opacity {
            classification.style_mut(tissue).opacity = opacity;
        }
        for &(tissue, colour) in &self.colour {
            classification.style_mut(tissue).colour = colour;
        }
        if let Some(style) = self.vessel_style {
            classification.vessels = style;
        }
        classification.head = self
            .head
            .apply(HeadStyle::above(report.background_threshold));
        classification
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::analyze;

    fn report() -> TissueReport {
        // Three modes, as a T1 brain has: CSF low, GM middle, WM high.
        let mut histogram = [0u32; 256];
        for (centre, height) in [(40usize, 3000u32), (150, 5000), (210, 8000)] {
            for d in 0..12usize {
                let h = height / (1 + d as u32);
                histogram[centre + d] += h;
                histogram[centre - d] += h;
            }
        }
        histogram[0] = 20000;
        let voxels = histogram.iter().sum::<u32>() as usize;
        analyze(&histogram, 0.0, 1000.0, voxels, 0)
    }

    #[test]
    fn the_default_recipe_is_the_default_scene_around_adaptive_windows() {
        let report = report();
        let scene = SceneRecipe::default().scene_for(&report);
        let mut expected = Scene::new(Classification::from_tissue_windows(
            &report.adaptive_windows,
        ));
        expected.minip_floor = report.background_threshold as f32;
        expected.classification.head = HeadStyle::above(report.background_threshold);
        assert_eq!(scene, expected);
    }

    #[test]
    fn settings_apply_in_order_over_the_chosen_windows() {
        let report = report();
        let recipe = SceneRecipe {
            windows: WindowSet::Paper,
            visible: Some(vec![TissueClass::Wm]),
            window: vec![(TissueClass::Wm, 0.7, 0.9), (TissueClass::Wm, 0.6, 0.8)],
            opacity: vec![(TissueClass::Wm, 0.25)],
            ..SceneRecipe::default()
        };
        let scene = recipe.scene_for(&report);
        let wm = scene.classification.style(TissueClass::Wm);
        assert!(wm.visible);
        assert!(!scene.classification.style(TissueClass::Gm).visible);
        let window = wm.window.unwrap();
        assert_eq!((window.lo, window.hi), (0.6, 0.8));
        assert_eq!(wm.opacity, 0.25);
        let paper = Classification::from_tissue_windows(&report.paper_windows);
        assert_eq!(
            scene.classification.style(TissueClass::Csf).window,
            paper.style(TissueClass::Csf).window
        );
    }

    #[test]
    fn a_recipe_from_a_scene_makes_that_scene_again() {
        let report = report();
        let mut scene = SceneRecipe::default().scene_for(&report);
        scene.classification.set_window(TissueClass::Gm, 0.3, 0.45);
        scene.classification.style_mut(TissueClass::Csf).visible = false;
        scene.camera.azimuth_deg = 75.0;
        scene.effects.shading = true;
        assert_eq!(SceneRecipe::from_scene(&scene).scene_for(&report), scene);
    }

    #[test]
    fn check_refuses_steps_and_zooms_no_scene_can_have() {
        assert!(SceneRecipe::default().check().is_ok());
        for step in [0.0, -1.0, 16.5, f64::NAN, 1e-9, 0.015] {
            let recipe = SceneRecipe {
                step_voxels: step,
                ..SceneRecipe::default()
            };
            assert!(recipe.check().unwrap_err().0.starts_with("--step"));
        }
        let fine = SceneRecipe {
            step_voxels: 1e-9,
            ..SceneRecipe::default()
        };
        let e = fine.check().unwrap_err().0;
        assert!(e.contains("finer than 0.015625 voxel"), "{e}");
        for step in [STEP_RANGE.0, 0.125, 16.0] {
            check_step(step).unwrap();
        }
        let mut recipe = SceneRecipe::default();
        recipe.camera.zoom = 0.0;
        assert!(recipe.check().unwrap_err().0.starts_with("--zoom"));
    }
}
