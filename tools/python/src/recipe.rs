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
    /// `matcap=`'s word (a built-in's name or a PNG's path), for scene documents.
    pub matcap_word: Option<String>,
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
        matcap_word: args.matcap.clone(),
    })
}

/// The scene of the scene document at `path` (`morphray render --scene`'s), at `size` when
/// given, else the document's; its errors are ValueErrors naming the file.
pub fn document_choice(path: &std::path::Path, size: Option<(u32, u32)>) -> PyResult<SceneChoice> {
    use morphray::scene::document::SceneDocument;
    let doc = SceneDocument::read(path).map_err(|e| errors::usage(e.to_string()))?;
    let matcap_word = doc.matcap_source(path);
    let matcap = (matcap_word.as_deref())
        .map(morphray::scene::matcap::MatcapImage::load)
        .transpose()
        .map_err(|e| errors::usage(e.to_string()))?;
    Ok(SceneChoice {
        recipe: doc.recipe(),
        size: size
            .or(doc.size.map(|[w, h]| (w, h)))
            .unwrap_or(DEFAULT_SIZE),
        matcap,
        matcap_word,
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
