//! `render()`'s and `open()`'s scene options as the library's scene recipe, through the command
//! line's own option model (`morphray::cli::scene_options`): the Python side turns its keyword
//! arguments into the words a shell would pass (`mode="mip"` -> `--mode mip`), and they are
//! parsed and checked here exactly as `morphray render` parses them, so names, units, defaults
//! and errors cannot drift between the two.
//!
//! One difference, stated once: a still from Python is lit as `morphray render`'s are (shading,
//! studio lighting and depth cues unless the options say otherwise: `SceneArgs::as_still`).

use crate::errors;
use morphray::cli::render::recipe_from_args;
use morphray::cli::scene_args::SceneArgs;
use morphray::cli::scene_options::{self as options, SceneOption};
use morphray::error::Error;
use morphray::scene::SceneRecipe;
use pyo3::prelude::*;

/// The image size of a Python render when `size` is not given.
pub const DEFAULT_SIZE: (u32, u32) = (512, 512);

/// The scene the command-line words describe, and its image size.
pub struct SceneChoice {
    /// What the engine builds the scene from.
    pub recipe: SceneRecipe,
    /// Width and height in pixels.
    pub size: (u32, u32),
    /// The matcap `matcap=` names (None: the built-in `clay`).
    pub matcap: Option<morphray::scene::matcap::MatcapImage>,
}

fn usage(error: Error) -> PyErr {
    match error {
        Error::Usage(message) => errors::usage(message),
        other => errors::usage(other.to_string()),
    }
}

/// The scene arguments of `words`, shaded unless they say otherwise (module doc).
fn still_args(words: &[String]) -> PyResult<SceneArgs> {
    let args = options::parse_scene_args(words).map_err(usage)?;
    Ok(args.as_still())
}

/// The recipe and size `words` describe (`["--mode", "mip", ...]`); a ValueError names the
/// option on a bad name or value, as the command line's usage errors do.
pub fn scene_choice(words: &[String]) -> PyResult<SceneChoice> {
    let args = still_args(words)?;
    let recipe = recipe_from_args(&args).map_err(usage)?;
    Ok(SceneChoice {
        recipe,
        size: args.size.unwrap_or(DEFAULT_SIZE),
        matcap: args.matcap_image().map_err(usage)?,
    })
}

/// The scene options as (long name, kind, accepted values, default, help) tuples, for the
/// Python side's keyword conversion and its documentation.
#[pyfunction]
pub fn scene_options() -> Vec<(String, String, Vec<String>, String, String)> {
    options::scene_options()
        .into_iter()
        .map(
            |SceneOption {
                 long,
                 kind,
                 values,
                 default,
                 help,
             }| {
                let kind = serde_json::to_value(kind)
                    .ok()
                    .and_then(|v| v.as_str().map(String::from))
                    .unwrap_or_default();
                (long, kind, values, default, help)
            },
        )
        .collect()
}
