//! `render()`'s keyword arguments as the library's scene recipe. The names and defaults are
//! the command line's (`morphray render --mode ... --tissues ... --brain ...`), so a notebook
//! and a shell script describe a frame the same way: `brain="auto"` masks a head scan's brain,
//! `"head"` among the tissues draws the head layer around it.

use crate::errors;
use morphray::passes::brain::BrainSwitch;
use morphray::scene::classification::HeadRecipe;
use morphray::scene::{
    Camera, Effects, Projection, RenderMode, SceneRecipe, TissueClass, WindowSet,
};
use pyo3::prelude::*;

/// The scene settings `render()` takes.
#[derive(Clone, Debug)]
pub struct SceneSettings {
    pub mode: String,
    pub tissues: Option<Vec<String>>,
    pub windows: String,
    pub azimuth: f64,
    pub elevation: f64,
    pub zoom: f64,
    pub projection: String,
    pub curvature: bool,
    pub shading: bool,
    pub step: f64,
    pub jitter: bool,
    pub background: [f32; 3],
    /// Brain extraction: "auto", "on" or "off" (`--brain`).
    pub brain: String,
    /// The head layer's opacity per mm and colour, by hand (`--opacity head=X`,
    /// `--color head=#RRGGBB`).
    pub head_opacity: Option<f32>,
    pub head_colour: Option<[f32; 3]>,
}

impl Default for SceneSettings {
    /// The command line's defaults.
    fn default() -> Self {
        SceneSettings {
            mode: "dvr".into(),
            tissues: None,
            windows: "adaptive".into(),
            azimuth: 0.0,
            elevation: 0.0,
            zoom: 1.0,
            projection: "perspective".into(),
            curvature: false,
            shading: false,
            step: 0.5,
            jitter: true,
            background: [0.0; 3],
            brain: "auto".into(),
            head_opacity: None,
            head_colour: None,
        }
    }
}

fn mode(name: &str) -> PyResult<RenderMode> {
    match name.to_ascii_lowercase().as_str() {
        "dvr" => Ok(RenderMode::Dvr),
        "mip" => Ok(RenderMode::Mip),
        "minip" => Ok(RenderMode::MinIp),
        _ => Err(errors::usage(format!(
            "unknown mode `{name}`; use \"dvr\", \"mip\" or \"minip\""
        ))),
    }
}

/// The tissue classes named, and whether the head layer (`"head"`) is among them.
fn tissues(names: &[String]) -> PyResult<(Vec<TissueClass>, bool)> {
    let mut head = false;
    let mut classes = Vec::new();
    for name in names.iter().filter(|n| !n.trim().is_empty()) {
        if name.trim().eq_ignore_ascii_case("head") {
            head = true;
            continue;
        }
        classes.push(TissueClass::parse(name).ok_or_else(|| {
            errors::usage(format!(
                "unknown tissue `{name}`; use \"csf\", \"gm\", \"wm\", \"pathology\" or \"head\""
            ))
        })?);
    }
    Ok((classes, head))
}

/// The head layer `settings` ask for (`visible`: "head" among the tissues).
fn head(settings: &SceneSettings, visible: bool) -> PyResult<HeadRecipe> {
    if let Some(o) = settings.head_opacity
        && !(0.0..=1.0).contains(&o)
    {
        return Err(errors::usage(format!(
            "head_opacity {o} must lie in 0..1 (opacity per mm of ray)"
        )));
    }
    if settings
        .head_colour
        .is_some_and(|c| c.iter().any(|v| !v.is_finite()))
    {
        return Err(errors::usage(
            "head_color must be three finite numbers in 0..1",
        ));
    }
    Ok(HeadRecipe {
        visible,
        window: None,
        opacity: settings.head_opacity,
        colour: settings.head_colour.map(|c| c.map(|v| v.clamp(0.0, 1.0))),
    })
}

/// The recipe `settings` describe; fails (ValueError) on an unknown name or a setting the
/// library's recipe check refuses.
pub fn recipe(settings: &SceneSettings) -> PyResult<SceneRecipe> {
    let default_tissues = ["csf", "gm", "wm"].map(String::from).to_vec();
    let (visible, head_visible) = tissues(settings.tissues.as_ref().unwrap_or(&default_tissues))?;
    let brain = BrainSwitch::parse(&settings.brain).ok_or_else(|| {
        errors::usage(format!(
            "unknown brain `{}`; use \"auto\", \"on\" or \"off\"",
            settings.brain
        ))
    })?;
    let windows = match settings.windows.to_ascii_lowercase().as_str() {
        "adaptive" => WindowSet::Adaptive,
        "paper" => WindowSet::Paper,
        other => {
            return Err(errors::usage(format!(
                "unknown windows `{other}`; use \"adaptive\" or \"paper\""
            )));
        }
    };
    let projection = match settings.projection.to_ascii_lowercase().as_str() {
        "perspective" => Projection::Perspective { fov_y_deg: 30.0 },
        "orthographic" => Projection::Orthographic,
        other => {
            return Err(errors::usage(format!(
                "unknown projection `{other}`; use \"perspective\" or \"orthographic\""
            )));
        }
    };
    for (name, value) in [
        ("azimuth", settings.azimuth),
        ("elevation", settings.elevation),
    ] {
        if !value.is_finite() {
            return Err(errors::usage(format!(
                "{name} must be a finite number of degrees"
            )));
        }
    }
    if settings.background.iter().any(|c| !c.is_finite()) {
        return Err(errors::usage(
            "background must be three finite numbers in 0..1",
        ));
    }
    let effects = Effects {
        mode: mode(&settings.mode)?,
        curvature: settings.curvature,
        shading: settings.shading,
        brain,
        ..Effects::default()
    };
    let recipe = SceneRecipe {
        windows,
        visible: Some(visible),
        camera: Camera {
            azimuth_deg: settings.azimuth,
            elevation_deg: settings.elevation,
            zoom: settings.zoom,
            pan_mm: [0.0, 0.0],
            projection,
        },
        effects,
        step_voxels: settings.step,
        jitter: settings.jitter,
        background: settings.background.map(|c| c.clamp(0.0, 1.0)),
        head: head(settings, head_visible)?,
        ..SceneRecipe::default()
    };
    recipe.check().map_err(|e| errors::usage(e.0))?;
    Ok(recipe)
}
