//! The knob settings `morphray accuracy` renders: each changes one knob from the render/view
//! default (see the study's method in `accuracy.rs`), within one of three groups whose truth is
//! rendered with the group's own definition: the default look, curvature on, and the stills'
//! lighting (studio model with depth cues, issue 34: what the cues cost and what a coarser step
//! does to them).

use crate::scene::lighting::{LightModel, Lighting, still_effects};
use crate::scene::{
    ClassificationLookup, CurvatureSource, DerivedPrecision, GradientFilter, GradientSource,
    Interpolation, OpacityCorrection, Scene,
};
use ash::vk;

pub(super) type Edit = fn(&mut Scene);

/// The scene definition a setting is compared within: its truth is the f64 reference of the
/// group's scene, and the frontier is drawn per group.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Group {
    /// The render/view default.
    Plain,
    /// Curvature modulation on.
    Curvature,
    /// The stills' look (`still_effects`: shaded, studio lighting, depth cues).
    Lit,
}

impl Group {
    pub(super) const ALL: [Group; 3] = [Group::Plain, Group::Curvature, Group::Lit];

    /// The group's name in the table, the JSON and the plot.
    pub(super) fn name(self) -> &'static str {
        match self {
            Group::Plain => "curvature off",
            Group::Curvature => "curvature on",
            Group::Lit => "studio + cues",
        }
    }

    /// The group's definition applied to the study's base scene (the reference and every
    /// setting of the group start from it).
    pub(super) fn define(self, scene: &mut Scene) {
        match self {
            Group::Plain => {}
            Group::Curvature => scene.effects.curvature = true,
            Group::Lit => scene.effects = still_effects(scene.effects),
        }
    }
}

/// One knob setting.
pub(super) struct Setting {
    pub(super) name: &'static str,
    pub(super) knob: &'static str,
    pub(super) group: Group,
    pub(super) format: vk::Format,
    pub(super) edit: Edit,
}

pub(super) fn settings() -> Vec<Setting> {
    let r16 = vk::Format::R16_UNORM;
    let s = |name, knob, edit: Edit| Setting {
        name,
        knob,
        group: Group::Plain,
        format: r16,
        edit,
    };
    let mut v = vec![
        s("default", "default", |_| {}),
        s("step 0.125", "step", |x| x.step_voxels = 0.125),
        s("step 0.25", "step", |x| x.step_voxels = 0.25),
        s("step 1", "step", |x| x.step_voxels = 1.0),
        s("step 2", "step", |x| x.step_voxels = 2.0),
        s("nearest", "interpolation", |x| {
            x.effects.quality.interpolation = Interpolation::Nearest
        }),
        s("tricubic", "interpolation", |x| {
            x.effects.quality.interpolation = Interpolation::Tricubic
        }),
        s("gradient f32", "gradient", |x| {
            x.effects.quality.derived_precision = DerivedPrecision::F32
        }),
        s("gradient f16", "gradient", |x| {
            x.effects.quality.derived_precision = DerivedPrecision::F16
        }),
        s("gradient on the fly", "gradient", |x| {
            x.effects.gradient_source = GradientSource::OnTheFly
        }),
        s("gradient on the fly, Sobel", "gradient", |x| {
            x.effects.gradient_source = GradientSource::OnTheFly;
            x.effects.quality.gradient_filter = GradientFilter::Sobel;
        }),
        s("naive opacity correction", "opacity correction", |x| {
            x.effects.quality.opacity_correction = OpacityCorrection::Naive
        }),
        s("termination 0.95", "early termination", |x| {
            x.early_termination = 0.95
        }),
        s("termination 0.99", "early termination", |x| {
            x.early_termination = 0.99
        }),
        s("termination off", "early termination", |x| {
            x.early_termination = 2.0
        }),
        s("no empty-space skipping", "empty-space skipping", |x| {
            x.effects.quality.empty_space_skipping = false
        }),
        s("exact classification", "classification", |x| {
            x.effects.quality.classification = ClassificationLookup::Exact
        }),
        // The lean sample (issue 33 item 1): one fetch of the classified volume.
        s("classified volume", "classification", |x| {
            x.effects.quality.classification = ClassificationLookup::Volume
        }),
        s("classified volume, step 1", "classification", |x| {
            x.effects.quality.classification = ClassificationLookup::Volume;
            x.step_voxels = 1.0;
        }),
    ];
    // Long steps in bricks of low opacity bound (issue 17 item 2): (factor, threshold in 1e-4).
    // Of the six pairs measured on the 96x112x96 phantom (ACCURACY.md), 2x/4x below 0.02 and
    // 4x/8x below 0.1 took exactly the default's samples (no occupied brick is that faint at
    // the default opacities); these two are the ones that change anything.
    let long = |name, edit: Edit| s(name, "long steps", edit);
    v.extend([
        long("long steps 4x below 0.3", |x| set_long_steps(x, 4, 3000)),
        long("long steps 8x below 1", |x| set_long_steps(x, 8, 10000)),
    ]);
    for (name, format) in [
        ("I_norm R8", vk::Format::R8_UNORM),
        ("I_norm R16F", vk::Format::R16_SFLOAT),
        ("I_norm R32F", vk::Format::R32_SFLOAT),
    ] {
        v.push(Setting {
            name,
            knob: "storage format",
            group: Group::Plain,
            format,
            edit: |_| {},
        });
    }
    // The storage formats again at the stills' step, where the step no longer hides their
    // quantization: what the defaults' R16 and f16 buy for diagnosis-quality images.
    v.push(Setting {
        name: "step 0.125, I_norm R8",
        knob: "storage format at step 0.125",
        group: Group::Plain,
        format: vk::Format::R8_UNORM,
        edit: |x| x.step_voxels = 0.125,
    });
    v.push(s(
        "step 0.125, gradient f16",
        "storage format at step 0.125",
        |x| {
            x.step_voxels = 0.125;
            x.effects.quality.derived_precision = DerivedPrecision::F16;
        },
    ));
    let c = |name, edit: Edit| Setting {
        name,
        knob: "curvature",
        group: Group::Curvature,
        format: r16,
        edit,
    };
    v.push(c("curvature stored", |x| x.effects.curvature = true));
    v.push(c("curvature on the fly", |x| {
        x.effects.curvature = true;
        x.effects.quality.curvature_source = CurvatureSource::OnTheFly;
    }));
    v.push(c("curvature stored, f16", |x| {
        x.effects.curvature = true;
        x.effects.quality.derived_precision = DerivedPrecision::F16;
    }));
    v.push(c("curvature stored, f32", |x| {
        x.effects.curvature = true;
        x.effects.quality.derived_precision = DerivedPrecision::F32;
    }));
    v.extend(lit_settings());
    v
}

/// The stills' lighting (issue 34 item 2): the depth cues are evaluated per frame at each ray's
/// surface (lighting.glsl); these settings give their error against the f64 truth at the fine
/// step, what a coarser step does to them, and what switching them off saves and changes.
fn lit_settings() -> Vec<Setting> {
    let l = |name, edit: Edit| Setting {
        name,
        knob: "lighting",
        group: Group::Lit,
        format: vk::Format::R16_UNORM,
        edit,
    };
    vec![
        l("studio + depth cues", |_| {}),
        l("studio + depth cues, step 0.25", |x| x.step_voxels = 0.25),
        l("studio + depth cues, step 1", |x| x.step_voxels = 1.0),
        l("studio, depth cues off", |x| {
            x.effects.lighting.depth_cues = false
        }),
        l("headlight, depth cues off", |x| {
            x.effects.lighting = Lighting {
                model: LightModel::Headlight,
                depth_cues: false,
            }
        }),
    ]
}

/// Long steps of `factor` lattice steps in bricks whose opacity bound is below `threshold_e4`
/// x 1e-4 per mm.
fn set_long_steps(scene: &mut Scene, factor: u32, threshold_e4: u32) {
    scene.effects.quality.long_steps = crate::scene::occupancy::LongSteps {
        factor,
        threshold_e4,
    };
}
