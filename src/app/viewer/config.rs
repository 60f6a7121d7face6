//! How the viewer was started: the command line's choices as the viewer takes them (split from
//! `mod.rs` by concern).

use crate::engine::EngineConfig;
use crate::scene::SceneRecipe;
use crate::volume::source::VolumeSource;
use crate::volume::source::dicom::SeriesChoice;
use std::path::PathBuf;
use std::time::Instant;

use crate::app::script::Step;

/// How the viewer was started.
pub struct ViewerConfig {
    /// What to open first (a file, several DICOM files, or the phantom).
    pub source: VolumeSource,
    /// The DICOM series to open first (`--series`; None: the largest 3-D series).
    pub series: Option<SeriesChoice>,
    /// How to build each volume's scene (as for `render`); checked by [`Viewer::new`].
    pub recipe: SceneRecipe,
    /// Window or offscreen image size, pixels.
    pub size: [u32; 2],
    /// Wait for vertical sync when presenting.
    pub vsync: bool,
    /// Exit after this many frames showing a volume (scripted mode).
    pub frames: Option<u32>,
    /// Save the last frame here before exiting.
    pub screenshot: Option<PathBuf>,
    /// Script steps.
    pub script: Vec<Step>,
    /// Device choice and validation.
    pub engine: EngineConfig,
    /// Print the per-frame log and summary.
    pub log: bool,
    /// The command line (PNG provenance).
    pub command: String,
    /// When the process started (time to first pixel of the first volume).
    pub started: Instant,
    /// A label map drawn over the slices (resampled onto each volume's grid).
    pub overlay: Option<crate::scene::overlay::Overlay>,
    /// Which frame of a 4-D file to show (0-based), for every file this session opens.
    pub frame: usize,
    /// 4-D playback at start (`view --play --fps F`).
    pub cine: crate::app::cine_panel::CineStart,
    /// Raymarch time budget while interacting, ms (`--frame-budget`; 0: always full quality).
    pub frame_budget_ms: f64,
    /// The first layout (`--layout`; 3D + slices by default).
    pub layout: crate::app::slices_panel::Layout,
    /// The matcap of the matcap lighting model (`--matcap`; None: the built-in `clay`).
    pub matcap: Option<crate::scene::matcap::MatcapImage>,
    /// `--matcap`'s word (a built-in's name or a PNG's path), for scene documents.
    pub matcap_spec: Option<String>,
    /// The overlay's label map, table and opacity as given, for scene documents.
    pub overlay_files: Option<(PathBuf, Option<PathBuf>, f64)>,
    /// Layers to open over the first volume (`--layer`, a scene document's).
    pub layers: Vec<crate::scene::layer::LayerSpec>,
    /// Where the crosshair starts on the first volume (a scene document's), world mm.
    pub crosshair_mm: Option<[f64; 3]>,
    /// The measurements the first volume starts with (a scene document's).
    pub measurements: Vec<crate::scene::measure::Measurement>,
}
