//! Scene documents on the command line (issue 31 item 6): `render --scene FILE.json`,
//! `render --scene-from PICTURE.png`, `render --save-scene FILE.json` and `view --scene`.
//!
//! Decisions:
//! - A document replaces the scene options (the scene is taken as it is, windows included);
//!   what is not the scene may still be given: the input (a moved or re-exported scan),
//!   `--size`, `--frame`, the output. Scene options given beside a document are refused in one
//!   line, not silently ignored or half merged.
//! - `--scene-from` reads the `morphray:scene` chunk that `render` and the viewer write into
//!   every picture; a PNG without one (another program's, or an older morphray's) is refused
//!   with what to do.
//! - An input whose SHA-256 differs from the document's is opened with a warning: the same scan
//!   re-exported is the common case, and the picture shows whether the scene still fits.

use super::scene_args::SceneArgs;
use crate::error::Error;
use crate::files::png::read_text_chunks;
use crate::scene::Scene;
use crate::scene::document::{OverlayRef, SceneDocument, SceneInput, recorded_path};
use clap::Args;
use std::path::{Path, PathBuf};

/// The scene-document options of `render`.
#[derive(Debug, Default, Args)]
pub struct SceneFileArgs {
    /// Render a saved scene document (--save-scene, or the viewer's Save scene...)
    ///
    /// The whole scene: camera, tissues, windows, colours, opacities, clip and crop, lighting,
    /// cut-away, overlay; its input is opened unless a FILE is given. Scene options may not be given with it; --size, --frame
    /// and -o may. README "Scenes" documents the format.
    #[arg(long = "scene", value_name = "FILE.json", help_heading = "Input")]
    pub scene_file: Option<PathBuf>,
    /// Render the scene recorded in a picture that render or the viewer wrote (its
    /// morphray:scene provenance)
    #[arg(
        long,
        value_name = "PNG",
        conflicts_with = "scene_file",
        help_heading = "Input",
        hide_short_help = true
    )]
    pub scene_from: Option<PathBuf>,
    /// Also write this render's scene document (to re-render it, or open it in the viewer)
    #[arg(long, value_name = "FILE.json", hide_short_help = true)]
    pub save_scene: Option<PathBuf>,
}

/// A scene document and where it was read from (its folder resolves relative input paths).
pub struct LoadedScene {
    /// The document.
    pub doc: SceneDocument,
    /// The document or the picture it came from.
    pub origin: PathBuf,
}

impl LoadedScene {
    /// The files to open: `given` when there are any, else the document's.
    pub fn files(&self, given: &[PathBuf]) -> Vec<PathBuf> {
        if given.is_empty() {
            self.doc.input_paths(&self.origin)
        } else {
            given.to_vec()
        }
    }

    /// A warning when the opened input's hash is not the document's (both known).
    pub fn hash_warning(&self, opened: Option<&str>) -> Option<String> {
        let recorded = &self.doc.input.sha256;
        let opened = opened?;
        (!recorded.is_empty() && recorded != opened).then(|| {
            format!(
                "the input differs from the one the scene {} was made from (SHA-256 {}... \
                 against {}...); the scene's windows and camera may not fit it",
                self.origin.display(),
                &opened[..opened.len().min(12)],
                &recorded[..recorded.len().min(12)]
            )
        })
    }
}

impl LoadedScene {
    /// Opens the document's scene on `files` (frame and size from the command line when given,
    /// else the document's), with its matcap.
    pub fn open(
        &self,
        files: &[PathBuf],
        (frame, size): (Option<usize>, Option<(u32, u32)>),
        config: crate::engine::EngineConfig,
    ) -> Result<super::session::Opened, Error> {
        let doc = &self.doc;
        let matcap = doc
            .matcap_source(&self.origin)
            .map(|m| crate::scene::matcap::MatcapImage::load(&m))
            .transpose()
            .map_err(|e| Error::Usage(e.to_string()))?;
        let how = super::session::OpenHow {
            want_hash: true,
            first_frame: true,
            image: self.size(size),
            matcap,
        };
        let config = crate::engine::EngineConfig {
            epi_mean_frame: false,
            ..config
        };
        let frame = frame.unwrap_or(doc.input.frame);
        super::session::open_recipe_with(files, frame, config, doc.recipe(), how)
    }

    /// The picture's size: `given`, else the document's, else 1024x1024.
    pub fn size(&self, given: Option<(u32, u32)>) -> (u32, u32) {
        given
            .or(self.doc.size.map(|[w, h]| (w, h)))
            .unwrap_or((1024, 1024))
    }

    /// The document's overlay as `--overlay` options (`given` when it names one).
    pub fn overlay(&self, given: &super::overlay::OverlayArgs) -> super::overlay::OverlayArgs {
        match (&given.overlay, self.doc.overlay_paths(&self.origin)) {
            (None, Some((labels, lut))) => super::overlay::OverlayArgs {
                overlay: Some(labels),
                overlay_lut: lut,
                overlay_opacity: self.doc.overlay.as_ref().map_or(0.5, |o| o.opacity),
            },
            _ => given.clone(),
        }
    }
}

/// What a picture's scene document records besides the scene.
pub struct PictureParts<'a> {
    /// The opened files (none: the phantom), the frame, the input's hash.
    pub input: (&'a [PathBuf], usize, Option<&'a str>),
    /// The matcap's name or file, when the lighting is a matcap.
    pub matcap: Option<&'a str>,
    /// Denoising when the volume was opened.
    pub denoise: crate::passes::denoise::Denoise,
    /// The label overlay's options.
    pub overlay: &'a super::overlay::OverlayArgs,
    /// The intensity layers drawn.
    pub layers: &'a [crate::scene::layer_open::OpenedLayer],
    /// The picture's size.
    pub size: (u32, u32),
    /// Measurements carried over from the document the picture was rendered from.
    pub measurements: &'a [crate::scene::measure::Measurement],
}

/// The scene document of one picture, its paths recorded relative to `folder` (where the
/// document will live: the picture's folder for its provenance).
pub fn picture_document(scene: &Scene, parts: &PictureParts<'_>, folder: &Path) -> SceneDocument {
    let (files, frame, sha256) = parts.input;
    let mut doc = document_for(scene, (files, frame, sha256), folder);
    doc.denoise = parts.denoise;
    doc.size = Some([parts.size.0, parts.size.1]);
    doc.measurements = parts.measurements.to_vec();
    doc.matcap = parts.matcap.map(|m| {
        if crate::scene::matcap::BUILT_IN.contains(&m) {
            m.to_string()
        } else {
            recorded_path(Path::new(m), folder)
        }
    });
    doc.overlay = parts.overlay.overlay.as_ref().map(|labels| OverlayRef {
        labels: recorded_path(labels, folder),
        lut: parts
            .overlay
            .overlay_lut
            .as_ref()
            .map(|l| recorded_path(l, folder)),
        opacity: parts.overlay.overlay_opacity,
    });
    doc.layers = parts
        .layers
        .iter()
        .map(|l| crate::scene::document::LayerRef {
            path: recorded_path(&l.spec.path, folder),
            style: l.style,
        })
        .collect();
    doc
}

impl SceneFileArgs {
    /// The document `--scene` or `--scene-from` names, read and checked; None without either.
    /// `scene` is the command line's scene options: any of them given beside a document is a
    /// usage error.
    pub fn load(&self, scene: &SceneArgs) -> Result<Option<LoadedScene>, Error> {
        let loaded = match (&self.scene_file, &self.scene_from) {
            (Some(path), _) => LoadedScene {
                doc: SceneDocument::read(path)?,
                origin: path.clone(),
            },
            (None, Some(png)) => LoadedScene {
                doc: from_picture(png)?,
                origin: png.clone(),
            },
            (None, None) => return Ok(None),
        };
        if let Some(option) = first_scene_option_given(scene) {
            return Err(Error::Usage(format!(
                "--{option} cannot be combined with --scene or --scene-from: the document holds \
                 the whole scene (only FILE, --size, --frame and -o may be given with it)"
            )));
        }
        Ok(Some(loaded))
    }
}

/// The first scene option `scene` sets away from its default (`--size` is not one here: it is
/// the picture's, not the scene's), as the command line spells it.
fn first_scene_option_given(scene: &SceneArgs) -> Option<String> {
    let defaults = super::scene_options::parse_scene_args(&[]).ok()?;
    let as_map = |args: &SceneArgs| match serde_json::to_value(args) {
        Ok(serde_json::Value::Object(map)) => map,
        _ => serde_json::Map::new(),
    };
    let (given, defaults) = (as_map(scene), as_map(&defaults));
    given
        .iter()
        .filter(|(name, _)| name.as_str() != "size")
        .find(|(name, value)| defaults.get(*name) != Some(value))
        .map(|(name, _)| name.replace('_', "-"))
}

/// The scene document in the `morphray:scene` chunk of the PNG at `path`.
pub fn from_picture(path: &Path) -> Result<SceneDocument, Error> {
    let chunks = read_text_chunks(path)?;
    let Some((_, text)) = chunks.iter().find(|(k, _)| k == "morphray:scene") else {
        return Err(Error::Usage(format!(
            "{} has no morphray:scene provenance: it was not written by morphray's render or \
             viewer (or by a version before scene documents); render it again, or pass the \
             scene's options",
            path.display()
        )));
    };
    Ok(SceneDocument::parse(text, path)?)
}

/// The document of one picture: `scene` made from `files` (none: the phantom) whose hash is
/// `sha256`, recorded relative to `folder` (where the document will live).
pub fn document_for(
    scene: &Scene,
    (files, frame, sha256): (&[PathBuf], usize, Option<&str>),
    folder: &Path,
) -> SceneDocument {
    let input = SceneInput {
        paths: files.iter().map(|f| recorded_path(f, folder)).collect(),
        sha256: sha256.unwrap_or_default().to_string(),
        frame,
    };
    SceneDocument::new(input, *scene)
}

/// The folder a document at `path` lives in (the working directory for a bare file name).
pub fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// What `view` opens: the command line's choices, or a scene document's where one is given.
#[cfg(feature = "viewer")]
pub struct ViewDocument {
    /// The files (none: the phantom).
    pub files: Vec<PathBuf>,
    /// The scene recipe (the document's scene as it is, or the options' still look).
    pub recipe: crate::scene::SceneRecipe,
    /// Window size.
    pub size: (u32, u32),
    /// Frame of a 4-D file.
    pub frame: usize,
    /// First layout.
    pub layout: crate::app::slices_panel::Layout,
    /// The matcap image and its word.
    pub matcap: Option<crate::scene::matcap::MatcapImage>,
    /// `--matcap`'s word, or the document's.
    pub matcap_spec: Option<String>,
    /// The overlay's options.
    pub overlay: super::overlay::OverlayArgs,
    /// Where the crosshair starts.
    pub crosshair_mm: Option<[f64; 3]>,
    /// The measurements the first volume starts with.
    pub measurements: Vec<crate::scene::measure::Measurement>,
    /// The layers over the first volume.
    pub layers: Vec<crate::scene::layer::LayerSpec>,
}

#[cfg(feature = "viewer")]
impl ViewDocument {
    /// `view`'s arguments resolved against `--scene` / `--scene-from` when given.
    pub fn load(args: &super::args::ViewArgs) -> Result<ViewDocument, Error> {
        use crate::app::slices_panel::Layout;
        if args.scene_file.save_scene.is_some() {
            return Err(Error::Usage(
                "--save-scene is render's: in the viewer use File > Save scene..., or the \
                 script step `save-scene FILE.json`"
                    .into(),
            ));
        }
        let layout = Layout::parse(&args.layout).unwrap_or(Layout::ThreeDAndSlices);
        let Some(loaded) = args.scene_file.load(&args.scene)? else {
            return Ok(ViewDocument {
                files: args.file.clone(),
                // The first view is a still's look (shaded, studio lighting, depth cues), as
                // `render`'s.
                recipe: super::render::recipe_from_args(&args.scene.as_still())?,
                size: args.scene.size.unwrap_or((1280, 800)),
                frame: args.frame,
                layout,
                matcap: args.scene.matcap_image()?,
                matcap_spec: args.scene.matcap.clone(),
                overlay: args.overlay.clone(),
                crosshair_mm: None,
                measurements: Vec::new(),
                layers: args.layer.specs()?,
            });
        };
        let doc = &loaded.doc;
        let matcap_spec = doc.matcap_source(&loaded.origin);
        let matcap = (matcap_spec.as_deref())
            .map(crate::scene::matcap::MatcapImage::load)
            .transpose()
            .map_err(|e| Error::Usage(e.to_string()))?;
        let viewer = doc.viewer.as_ref();
        Ok(ViewDocument {
            files: loaded.files(&args.file),
            recipe: doc.recipe(),
            size: args
                .scene
                .size
                .or(doc.size.map(|[w, h]| (w, h)))
                .unwrap_or((1280, 800)),
            // `--frame` has a default (0): a document's frame counts unless another is given.
            frame: if args.frame == 0 {
                doc.input.frame
            } else {
                args.frame
            },
            layout: viewer
                .and_then(|v| Layout::parse(&v.layout))
                .unwrap_or(layout),
            matcap,
            matcap_spec,
            overlay: loaded.overlay(&args.overlay),
            crosshair_mm: viewer.and_then(|v| v.crosshair_mm),
            measurements: doc.measurements.clone(),
            layers: if args.layer.layers.is_empty() {
                doc.layer_specs(&loaded.origin)
            } else {
                args.layer.specs()?
            },
        })
    }
}
