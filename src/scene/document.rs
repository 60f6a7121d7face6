//! Scene documents (issue 31 item 6): one versioned JSON file that says what a picture shows, so
//! `render --scene`, `view --scene` and `render --scene-from picture.png` reproduce it.
//!
//! Decisions:
//! - The document holds the [`Scene`] itself (camera, tissue windows, colours, opacities,
//!   visibility, effects, lighting, depth cues, clip planes, crop, cut-away, colour map), not the
//!   command-line options that made it: the viewer's scene is the result of drags and clicks no
//!   option list records, and a scene read back is used as it is (`SceneRecipe::from_scene`:
//!   the windows are not fitted again), so the picture does not move when the analysis changes.
//! - Inputs by path and SHA-256: a relative path is relative to the document's folder (a
//!   document moves with its scans); an input whose hash differs is opened with a warning, not
//!   refused (a re-exported file of the same scan).
//! - Versioned: `format` must be [`FORMAT`] and `version` at most [`VERSION`]; unknown fields
//!   are refused (a typo is a mistake, not an extension). Every field of the format is listed in
//!   README "Scenes", and tests/scene_document.rs holds that list against the serializer, so a
//!   change to [`Scene`] that would break version-1 documents fails a test until the version is
//!   raised.
//! - A document is input like a volume: at most [`MAX_BYTES`], and every number checked
//!   ([`check_scene`]): the recipe's bounds (step, zoom, clip) and finiteness of every float
//!   (a value too large for f32 becomes infinite on reading and is refused by the re-encoding
//!   test), so a hostile file cannot hang or blank a render.
//! - Written atomically (`files::write`): a failed save leaves the previous document.

use super::Scene;
use super::recipe::SceneRecipe;
use std::path::{Path, PathBuf};

/// The `format` string of a scene document.
pub const FORMAT: &str = "morphray-scene";
/// The version this build writes and the newest it reads.
pub const VERSION: u32 = 1;
/// Largest document read, bytes (a scene is about 3 kB).
pub const MAX_BYTES: u64 = 1 << 20;

/// What a scene was made of: the scan (paths and hash) and, for a 4-D file, the frame.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneInput {
    /// The file, or the files of one DICOM series; empty: the built-in phantom. Relative paths
    /// are relative to the document's folder.
    pub paths: Vec<String>,
    /// SHA-256 (hex) of the input's bytes as read (of the phantom's samples); empty: unknown.
    #[serde(default)]
    pub sha256: String,
    /// The frame of a 4-D file (0 when absent).
    #[serde(default)]
    pub frame: usize,
}

/// A label map drawn over the volume: `--overlay`, `--overlay-lut`, `--overlay-opacity`.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OverlayRef {
    /// The label map (relative to the document's folder when relative).
    pub labels: String,
    /// Its lookup table, if one was given.
    #[serde(default)]
    pub lut: Option<String>,
    /// Its opacity, 0 to 1.
    pub opacity: f64,
}

/// An intensity layer drawn over the volume (`--layer`, `scene::layer`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LayerRef {
    /// The layer's file (relative to the document's folder when relative).
    pub path: String,
    /// How it is drawn.
    pub style: super::layer::LayerStyle,
}

/// The viewer's arrangement, when the document came from the viewer.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewerLayout {
    /// `view --layout`'s word (`3d`, `slices`, `3d+slices`).
    pub layout: String,
    /// The crosshair in world millimetres.
    #[serde(default)]
    pub crosshair_mm: Option<[f64; 3]>,
}

/// One scene document (module doc).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDocument {
    /// Always [`FORMAT`].
    pub format: String,
    /// [`VERSION`] when written.
    pub version: u32,
    /// The scan.
    pub input: SceneInput,
    /// The scene.
    pub scene: Scene,
    /// Denoising of I_norm when the volume is opened (`--denoise`; not part of the scene).
    #[serde(default)]
    pub denoise: crate::passes::denoise::Denoise,
    /// The matcap (`clay`, `shiny` or a PNG's path) when the lighting is a matcap.
    #[serde(default)]
    pub matcap: Option<String>,
    /// A label map drawn over the volume (`--overlay`).
    #[serde(default)]
    pub overlay: Option<OverlayRef>,
    /// Intensity layers drawn over the volume, in order (`--layer`).
    #[serde(default)]
    pub layers: Vec<LayerRef>,
    /// The picture's size in pixels (`render --size`; the window's for the viewer).
    #[serde(default)]
    pub size: Option<[u32; 2]>,
    /// The viewer's layout and crosshair.
    #[serde(default)]
    pub viewer: Option<ViewerLayout>,
    /// Distances, angles and regions placed on the scan (`scene::measure`), world mm.
    #[serde(default)]
    pub measurements: Vec<super::measure::Measurement>,
}

/// Why a scene document could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum SceneDocError {
    /// The file could not be read.
    #[error("cannot read the scene {path}: {source}")]
    Read {
        /// The document.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is larger than any scene.
    #[error(
        "{path} is {bytes} bytes: not a scene document (they are a few kB; at most {MAX_BYTES})"
    )]
    TooLarge {
        /// The document.
        path: PathBuf,
        /// Its size.
        bytes: u64,
    },
    /// Not JSON, or JSON that is not a scene document of this version.
    #[error("{path} is not a morphray scene document: {reason}")]
    Invalid {
        /// The document.
        path: PathBuf,
        /// What is wrong, with the line and column where serde_json knows them.
        reason: String,
    },
    /// Written by a newer morphray.
    #[error(
        "{path} is a version-{version} scene document; this morphray reads versions up to \
         {VERSION} (upgrade morphray)"
    )]
    Newer {
        /// The document.
        path: PathBuf,
        /// Its version.
        version: u32,
    },
    /// The document could not be written.
    #[error(transparent)]
    Write(#[from] crate::files::write::OutputError),
}

impl SceneDocument {
    /// A document of `scene` made from `input` (no matcap, overlay, size or viewer state).
    pub fn new(input: SceneInput, scene: Scene) -> Self {
        SceneDocument {
            format: FORMAT.into(),
            version: VERSION,
            input,
            scene,
            denoise: crate::passes::denoise::Denoise::None,
            matcap: None,
            overlay: None,
            layers: Vec::new(),
            size: None,
            viewer: None,
            measurements: Vec::new(),
        }
    }

    /// The document as pretty-printed JSON.
    pub fn to_json(&self) -> String {
        // Serializing plain data into a string cannot fail; an empty object would be refused on
        // reading, never taken for a scene.
        serde_json::to_string_pretty(self).unwrap_or_else(|_| "{}".into())
    }

    /// Parses `text` as the document at `path` (for the messages), checking format, version
    /// and every number (module doc).
    pub fn parse(text: &str, path: &Path) -> Result<Self, SceneDocError> {
        let invalid = |reason: String| SceneDocError::Invalid {
            path: path.to_path_buf(),
            reason,
        };
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| invalid(e.to_string()))?;
        let format = value.get("format").and_then(|f| f.as_str());
        if format != Some(FORMAT) {
            return Err(invalid(format!(
                "its \"format\" is {}, not \"{FORMAT}\"",
                format.map_or("missing".into(), |f| format!("\"{f}\""))
            )));
        }
        match value.get("version").and_then(|v| v.as_u64()) {
            Some(v) if v > u64::from(VERSION) => {
                return Err(SceneDocError::Newer {
                    path: path.to_path_buf(),
                    version: u32::try_from(v).unwrap_or(u32::MAX),
                });
            }
            Some(_) => {}
            None => return Err(invalid("its \"version\" is missing or not a number".into())),
        }
        let doc: SceneDocument =
            serde_json::from_value(value).map_err(|e| invalid(e.to_string()))?;
        check_scene(&doc.scene).map_err(invalid)?;
        check_measurements(&doc.measurements).map_err(invalid)?;
        check_extras(&doc).map_err(invalid)?;
        Ok(doc)
    }

    /// Reads and checks the document at `path`.
    pub fn read(path: &Path) -> Result<Self, SceneDocError> {
        let read_error = |source| SceneDocError::Read {
            path: path.to_path_buf(),
            source,
        };
        let bytes = std::fs::metadata(path).map_err(read_error)?.len();
        if bytes > MAX_BYTES {
            return Err(SceneDocError::TooLarge {
                path: path.to_path_buf(),
                bytes,
            });
        }
        let text = std::fs::read_to_string(path).map_err(read_error)?;
        Self::parse(&text, path)
    }

    /// Writes the document to `path` atomically (a `.json` file; not over an input).
    pub fn write(&self, path: &Path, inputs: &[&Path]) -> Result<(), SceneDocError> {
        use crate::files::write::{OutputKind, check_output, write_file};
        check_output(path, OutputKind::Json, inputs, false)?;
        write_file(path, format!("{}\n", self.to_json()).as_bytes())?;
        Ok(())
    }

    /// The recipe that makes this document's scene again: the scene as it is (its windows are
    /// not fitted again), with the document's denoising.
    pub fn recipe(&self) -> SceneRecipe {
        SceneRecipe {
            denoise: self.denoise,
            ..SceneRecipe::from_scene(&self.scene)
        }
    }

    /// The input's paths resolved against the folder of the document at `document` (absolute
    /// paths stay as they are); empty for the phantom.
    pub fn input_paths(&self, document: &Path) -> Vec<PathBuf> {
        resolve(&self.input.paths, document)
    }

    /// The overlay's label map and table resolved as [`SceneDocument::input_paths`].
    pub fn overlay_paths(&self, document: &Path) -> Option<(PathBuf, Option<PathBuf>)> {
        let overlay = self.overlay.as_ref()?;
        let labels = resolve(std::slice::from_ref(&overlay.labels), document);
        let lut = overlay.lut.as_ref().and_then(|l| {
            resolve(std::slice::from_ref(l), document)
                .into_iter()
                .next()
        });
        Some((labels.into_iter().next()?, lut))
    }

    /// The layers as specs that draw them as recorded, paths resolved as
    /// [`SceneDocument::input_paths`].
    pub fn layer_specs(&self, document: &Path) -> Vec<super::layer::LayerSpec> {
        self.layers
            .iter()
            .filter_map(|l| {
                let path = resolve(std::slice::from_ref(&l.path), document)
                    .into_iter()
                    .next()?;
                Some(super::layer::LayerSpec::from_style(path, &l.style))
            })
            .collect()
    }

    /// The matcap to load: a built-in name as it is, a file resolved as the inputs are.
    pub fn matcap_source(&self, document: &Path) -> Option<String> {
        let matcap = self.matcap.as_ref()?;
        if super::matcap::BUILT_IN.contains(&matcap.as_str()) {
            return Some(matcap.clone());
        }
        let path = resolve(std::slice::from_ref(matcap), document)
            .into_iter()
            .next()?;
        Some(path.to_string_lossy().into_owned())
    }
}

/// `paths` with relative ones joined onto the folder of `document`.
fn resolve(paths: &[String], document: &Path) -> Vec<PathBuf> {
    let folder = document.parent().unwrap_or_else(|| Path::new(""));
    paths
        .iter()
        .map(|p| {
            let p = Path::new(p);
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                folder.join(p)
            }
        })
        .collect()
}

/// `path` as a document in `folder` records it: relative to the folder (`../scans/a.nii.gz`)
/// when the two share a folder below the root, else absolute (made so against the working
/// directory), so a document moves with the tree of its scans.
pub fn recorded_path(path: &Path, folder: &Path) -> String {
    let absolute = |p: &Path| {
        std::fs::canonicalize(p).unwrap_or_else(|_| {
            std::env::current_dir()
                .map(|d| d.join(p))
                .unwrap_or_else(|_| p.to_path_buf())
        })
    };
    let (file, folder) = (absolute(path), absolute(folder));
    let (a, b): (Vec<_>, Vec<_>) = (file.components().collect(), folder.components().collect());
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    // Only the root (and a Windows prefix) in common: the absolute path says more.
    let rooted = a
        .iter()
        .take(common)
        .filter(|c| matches!(c, std::path::Component::Normal(_)))
        .count();
    if rooted == 0 {
        return file.to_string_lossy().into_owned();
    }
    let mut relative = PathBuf::new();
    for _ in common..b.len() {
        relative.push("..");
    }
    for part in &a[common..] {
        relative.push(part);
    }
    relative.to_string_lossy().into_owned()
}

/// Why `scene` cannot be rendered: the recipe's bounds (step, zoom, clip) in the command line's
/// words, and any float that is not finite.
pub fn check_scene(scene: &Scene) -> Result<(), String> {
    SceneRecipe::from_scene(scene)
        .check()
        .map_err(|e| e.to_string())?;
    // Re-encoding writes a non-finite float as null, which no float field reads back.
    let finite = serde_json::to_value(scene)
        .ok()
        .and_then(|v| serde_json::from_value::<Scene>(v).ok())
        .is_some();
    if !finite {
        return Err("a number in its scene is not finite (or too large for 32 bits)".into());
    }
    Ok(())
}

/// Why `measurements` cannot be a document's: too many, or a number that is not finite.
fn check_measurements(measurements: &[super::measure::Measurement]) -> Result<(), String> {
    use super::measure::MAX_MEASUREMENTS;
    if measurements.len() > MAX_MEASUREMENTS {
        return Err(format!(
            "it holds {} measurements; at most {MAX_MEASUREMENTS}",
            measurements.len()
        ));
    }
    match measurements.iter().position(|m| !m.is_finite()) {
        Some(i) => Err(format!(
            "measurement {} has a number that is not finite",
            i + 1
        )),
        None => Ok(()),
    }
}

/// Largest picture side a document may ask for, pixels (as `render --size`).
pub const MAX_SIDE: u32 = 16384;

/// Why the picture size, the crosshair, the overlay's opacity or a layer cannot be a document's.
fn check_extras(doc: &SceneDocument) -> Result<(), String> {
    if let Some([w, h]) = doc.size
        && (w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE)
    {
        return Err(format!(
            "its size {w}x{h} must be 1 to {MAX_SIDE} pixels a side"
        ));
    }
    let crosshair = doc.viewer.as_ref().and_then(|v| v.crosshair_mm);
    if crosshair.is_some_and(|c| !c.iter().all(|v| v.is_finite())) {
        return Err("its viewer crosshair is not a finite position".into());
    }
    if doc.layers.len() > super::layer::MAX_LAYERS {
        return Err(format!(
            "it has {} layers; at most {} are drawn",
            doc.layers.len(),
            super::layer::MAX_LAYERS
        ));
    }
    for layer in &doc.layers {
        layer
            .style
            .check()
            .map_err(|e| format!("its layer {}: {e}", layer.path))?;
    }
    if let Some(o) = &doc.overlay
        && !(0.0..=1.0).contains(&o.opacity)
    {
        return Err(format!(
            "its overlay opacity {} must lie in 0..1",
            o.opacity
        ));
    }
    Ok(())
}
