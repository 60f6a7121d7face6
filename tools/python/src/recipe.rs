//! `render()`'s keyword arguments as the library's scene recipe. The names and defaults are
//! the command line's (`morphray render --mode ... --tissues ...`), so a notebook and a shell
//! script describe a frame the same way.

use crate::errors;
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

fn tissues(names: &[String]) -> PyResult<Vec<TissueClass>> {
    names
        .iter()
        .filter(|n| !n.trim().is_empty())
        .map(|name| {
            TissueClass::parse(name).ok_or_else(|| {
                errors::usage(format!(
                    "unknown tissue `{name}`; use \"csf\", \"gm\", \"wm\", \"pathology\""
                ))
            })
        })
        .collect()
}

/// The recipe `settings` describe; fails (ValueError) on an unknown name or a setting the
/// library's recipe check refuses.
pub fn recipe(settings: &SceneSettings) -> PyResult<SceneRecipe> {
    let default_tissues = ["csf", "gm", "wm"].map(String::from).to_vec();
    let visible = tissues(settings.tissues.as_ref().unwrap_or(&default_tissues))?;
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
        ..SceneRecipe::default()
    };
    recipe.check().map_err(|e| errors::usage(e.0))?;
    Ok(recipe)
}
