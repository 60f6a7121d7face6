//! `morphray.Volume`: a volume opened on the process's engine, with its analysis.
//!
//! Decisions:
//! - The volume keeps its GPU data (the twin: normalized volume, histogram, derived volumes)
//!   until the Python object is collected, so successive renders run the raymarch only.
//! - Every volume keeps its host copy (as a nibabel image keeps its data): `np.asarray(vol)`,
//!   `to_nifti` and the header read it, and a bricked volume (over the memory budget) is opened
//!   again from it when a render's tissues, windows or mode change which bricks are resident,
//!   rather than showing missing bricks.
//! - `open()` takes the scene options too (the recipe the plan is made for: a preset that turns
//!   the vessel channel on is planned with it) and the identity options (`normalize`,
//!   `contrast`, `modality`), set on the shared engine before each open.
//! - A file is read and inflated before the engine is locked, so threads opening several files
//!   overlap their reads with each other's GPU work.
//! - Arrays come in as (i, j, k)-indexed numpy arrays (nibabel's order) and are copied once into
//!   the engine's x-fastest order; maps go out in the same (i, j, k) order.

use crate::errors;
use crate::recipe;
use crate::state::{self, State};
use morphray::analysis::TissueReport;
use morphray::analysis::{ContrastChoice, ModalityChoice, NormalizeMode};
use morphray::cli::args::{ContrastArg, ModalityArg, NormalizeArg};
use morphray::engine::plan::{Layout, Plan};
use morphray::engine::{DerivedMaps, MapRequest, OpenOptions, Twin, VolumeLayout};
use morphray::passes::brain::BrainSwitch;
use morphray::passes::denoise::Denoise;
use morphray::reference::brain_report::{BrainDecision, BrainReport};
use morphray::scene::SceneRecipe;
use morphray::study::batch_summary::ScanSummary;
use morphray::volume::phantom::PhantomSpec;
use morphray::volume::phantom_contrast::Contrast;
use morphray::volume::source::dicom::SeriesChoice;
use morphray::volume::source::{self, ReadOptions, VolumeSource};
use morphray::volume::{LinearMap, Samples, Volume as HostVolume};
use numpy::ndarray::{Array3, ShapeBuilder};
use numpy::{IntoPyArray, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::Mutex;

/// The image size volumes are planned for (the command line's default).
const PLAN_IMAGE: [u32; 2] = [1024, 1024];

struct Inner {
    twin: Twin,
    report: TissueReport,
    plan: Plan,
    /// The recipe the twin was prepared for.
    recipe: SceneRecipe,
    /// The host copy (module doc).
    host: HostVolume,
    /// Whether the volume is bricked (over the memory budget).
    bricked: bool,
    /// The identity options it was opened with (set again when it is reopened).
    identity: (NormalizeMode, ContrastChoice, ModalityChoice),
    generation: u64,
    /// Intensity layers drawn over it (`layers.rs`).
    layers: crate::layers::Layers,
}

/// A volume on the GPU with its tissue analysis.
#[pyclass(frozen, module = "morphray")]
pub struct Volume {
    label: String,
    /// The file it was read from (never replaced by `to_nifti`).
    path: Option<PathBuf>,
    /// The frame of a 4-D file it holds.
    frame: usize,
    dims: [u32; 3],
    warnings: Vec<String>,
    inner: Mutex<Inner>,
}

fn open_options(recipe: &SceneRecipe, frame: usize) -> OpenOptions {
    OpenOptions {
        read: ReadOptions {
            frame,
            ..ReadOptions::default()
        },
        image: PLAN_IMAGE,
        recipe: recipe.clone(),
        first_frame: false,
    }
}

/// How a volume is opened: the scene recipe its plan is made for and the identity options.
pub struct OpenChoice {
    /// The recipe (from `open()`'s scene options).
    pub recipe: SceneRecipe,
    /// `normalize`, `contrast`, `modality`.
    pub identity: (NormalizeMode, ContrastChoice, ModalityChoice),
}

impl OpenChoice {
    /// The choice `scene` (command-line words) and the identity names describe.
    fn parse(scene: &[String], identity: &Identity) -> PyResult<OpenChoice> {
        Ok(OpenChoice {
            recipe: recipe::scene_choice(scene)?.recipe,
            identity: identity.parse()?,
        })
    }
}

/// `open()`'s identity options as the names the command line takes.
#[derive(Clone, Debug, FromPyObject)]
#[pyo3(from_item_all)]
pub struct Identity {
    normalize: String,
    contrast: String,
    modality: String,
}

fn value_enum<T: clap::ValueEnum>(option: &str, text: &str) -> PyResult<T> {
    T::from_str(text, true).map_err(|_| {
        let names: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value().map(|p| p.get_name().to_string()))
            .collect();
        errors::usage(format!(
            "unknown {option} `{text}`; use {}",
            names.join(", ")
        ))
    })
}

impl Identity {
    fn parse(&self) -> PyResult<(NormalizeMode, ContrastChoice, ModalityChoice)> {
        let normalize: NormalizeArg = value_enum("normalize", &self.normalize)?;
        let contrast: ContrastArg = value_enum("contrast", &self.contrast)?;
        let modality: ModalityArg = value_enum("modality", &self.modality)?;
        Ok((
            normalize.into(),
            contrast.analysis().map_err(errors::usage)?,
            modality.into(),
        ))
    }
}

/// Opens `volume` (already read) on the process's engine.
fn open_host(
    state: &mut State,
    volume: HostVolume,
    label: String,
    choice: OpenChoice,
) -> PyResult<Volume> {
    let (engine, generation) = state.engine()?;
    let (normalize, contrast, modality) = choice.identity;
    engine.set_identity(normalize, contrast, modality);
    let opened = engine
        .open_with(&volume, &open_options(&choice.recipe, 0))
        .map_err(errors::open)?;
    let bricked = matches!(opened.plan.layout, Layout::Bricked { .. });
    let dims = opened.twin.prepared.dims;
    Ok(Volume {
        label,
        path: None,
        frame: 0,
        dims,
        warnings: volume.warnings.clone(),
        inner: Mutex::new(Inner {
            twin: opened.twin,
            report: opened.report,
            plan: opened.plan,
            recipe: choice.recipe,
            host: volume,
            bricked,
            identity: choice.identity,
            generation,
            layers: Default::default(),
        }),
    })
}

fn open_source(
    py: Python<'_>,
    source: VolumeSource,
    read: ReadOptions,
    choice: OpenChoice,
) -> PyResult<Volume> {
    py.detach(|| {
        // Read and inflate before taking the engine: other threads' GPU work goes on meanwhile.
        let read =
            source::read(&source, &read).map_err(|e| errors::InputError::new_err(e.to_string()))?;
        open_host(&mut state::lock(), read.volume, read.label, choice)
    })
}

/// Opens a NIfTI/ANALYZE file or a DICOM series (`frame`: which volume of a 4D file;
/// `series`: a DICOM SeriesInstanceUID or the index `morphray info` lists, None for the largest
/// 3-D series).
#[pyfunction]
#[pyo3(signature = (path, scene, identity, frame=0, series=None))]
pub fn open_file(
    py: Python<'_>,
    path: PathBuf,
    scene: Vec<String>,
    identity: Identity,
    frame: usize,
    series: Option<String>,
) -> PyResult<Volume> {
    let choice = OpenChoice::parse(&scene, &identity)?;
    let series = series
        .map(|s| SeriesChoice::parse(&s))
        .transpose()
        .map_err(pyo3::exceptions::PyValueError::new_err)?;
    let read = ReadOptions {
        frame,
        series,
        ..ReadOptions::default()
    };
    let mut volume = open_source(py, VolumeSource::File(path.clone()), read, choice)?;
    volume.path = Some(path);
    volume.frame = frame;
    Ok(volume)
}

/// Opens the synthetic phantom of `dims` voxels of `spacing` mm (the paper's cohort-A size at
/// 1 mm by default): the brain in a dark shell, or with `head` a whole T1 head (scalp, skull,
/// eyes, face, neck: `morphray phantom --head`) whose brain extraction can find.
#[pyfunction]
#[pyo3(signature = (scene, identity, dims=(256, 256, 192), seed=None, noise=true, head=false, spacing=1.0))]
#[allow(clippy::too_many_arguments)]
pub fn open_phantom(
    py: Python<'_>,
    scene: Vec<String>,
    identity: Identity,
    dims: (usize, usize, usize),
    seed: Option<u64>,
    noise: bool,
    head: bool,
    spacing: f64,
) -> PyResult<Volume> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(errors::usage(format!(
            "spacing {spacing} must be a positive number of mm"
        )));
    }
    let base = if head {
        PhantomSpec::head([dims.0, dims.1, dims.2], Contrast::T1, noise)
    } else {
        PhantomSpec::cube(1)
    };
    let spec = PhantomSpec {
        dims: [dims.0, dims.1, dims.2],
        spacing_mm: [spacing; 3],
        seed: seed.unwrap_or(PhantomSpec::DEFAULT_SEED),
        noise,
        ..base
    };
    let choice = OpenChoice::parse(&scene, &identity)?;
    open_source(
        py,
        VolumeSource::Phantom(spec),
        ReadOptions::default(),
        choice,
    )
}

/// The voxels of an (i, j, k)-indexed array in x-fastest order.
fn x_fastest<T: Copy + numpy::Element>(array: &PyReadonlyArray3<'_, T>) -> Vec<T> {
    array.as_array().t().iter().copied().collect()
}

fn samples_of(array: &Bound<'_, PyAny>) -> PyResult<(Samples, [usize; 3])> {
    macro_rules! try_kind {
        ($t:ty, $make:expr) => {
            if let Ok(a) = array.extract::<PyReadonlyArray3<'_, $t>>() {
                let shape = a.shape();
                let dims = [shape[0], shape[1], shape[2]];
                let values = x_fastest(&a);
                #[allow(clippy::redundant_closure_call)]
                return Ok(($make(values), dims));
            }
        };
    }
    try_kind!(u8, Samples::from_u8);
    try_kind!(i8, |v: Vec<i8>| Samples::from_i8(&v));
    try_kind!(u16, |v: Vec<u16>| Samples::from_u16(&v));
    try_kind!(i16, |v: Vec<i16>| Samples::from_i16(&v));
    try_kind!(f32, |v: Vec<f32>| Samples::from_f32(&v));
    Err(errors::InputError::new_err(
        "the array must be 3D of uint8, int8, uint16, int16 or float32 (morphray.open converts \
         other dtypes to float32)",
    ))
}

/// Opens a 3D array indexed (i, j, k) with its 4x4 index-to-world affine (RAS+ mm, as nibabel's
/// `img.affine`).
#[pyfunction]
#[pyo3(signature = (array, affine, scene, identity, name="array"))]
pub fn open_array(
    py: Python<'_>,
    array: &Bound<'_, PyAny>,
    affine: PyReadonlyArray2<'_, f64>,
    scene: Vec<String>,
    identity: Identity,
    name: &str,
) -> PyResult<Volume> {
    let choice = OpenChoice::parse(&scene, &identity)?;
    let a = affine.as_array();
    if a.shape() != [4, 4] {
        return Err(errors::InputError::new_err(format!(
            "the affine must be 4x4, not {:?}",
            a.shape()
        )));
    }
    let mut rows = [[0.0f64; 4]; 4];
    for (r, row) in rows.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = a[[r, c]];
        }
    }
    let (samples, dims) = samples_of(array)?;
    let volume = HostVolume::from_voxels(name, dims, samples, rows, LinearMap::IDENTITY)
        .map_err(|e| errors::InputError::new_err(e.to_string()))?;
    let label = name.to_string();
    py.detach(|| open_host(&mut state::lock(), volume, label, choice))
}

impl Volume {
    /// Runs `f` on the host copy.
    pub fn with_host<R>(&self, f: impl FnOnce(&HostVolume) -> R) -> R {
        let inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        f(&inner.host)
    }

    /// The file the volume was read from, if any.
    pub fn input_path(&self) -> Option<&std::path::Path> {
        self.path.as_deref()
    }
}

impl Inner {
    /// Refuses a bricked volume (`what` it cannot do) and one opened on a replaced engine.
    fn check_whole(&self, state: &State, what: &str) -> PyResult<()> {
        if matches!(self.twin.prepared.layout, VolumeLayout::Bricked(_)) {
            return Err(errors::MemoryBudgetError::new_err(format!(
                "this volume is bricked (over the memory budget): {what}; raise \
                 morphray.configure(memory_budget=...)"
            )));
        }
        if self.generation != state.generation {
            return Err(errors::Error::new_err(
                "this volume was opened before morphray.configure() changed the device; open it \
                 again",
            ));
        }
        Ok(())
    }

    /// Opens the host copy again for `recipe` when the volume is bricked and the recipe's
    /// windows, tissues or mode differ from what the resident bricks were chosen for.
    fn reopen_if_needed(&mut self, state: &mut State, recipe: &SceneRecipe) -> PyResult<()> {
        if !self.bricked {
            return Ok(());
        }
        let host = &self.host;
        let mut same = recipe.clone();
        same.camera = self.recipe.camera;
        if same == self.recipe {
            return Ok(());
        }
        let (engine, _) = state.engine()?;
        let (normalize, contrast, modality) = self.identity;
        engine.set_identity(normalize, contrast, modality);
        let opened = engine
            .open_with(host, &open_options(recipe, 0))
            .map_err(errors::open)?;
        self.twin = opened.twin;
        self.report = opened.report;
        self.plan = opened.plan;
        self.recipe = recipe.clone();
        Ok(())
    }
}

#[pymethods]
impl Volume {
    /// The input's name (file path, "phantom" or the array's name).
    #[getter]
    fn label(&self) -> &str {
        &self.label
    }

    /// Voxels along i, j, k.
    #[getter]
    fn shape(&self) -> (u32, u32, u32) {
        (self.dims[0], self.dims[1], self.dims[2])
    }

    /// The loader's repairs and warnings about the input.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    /// Whether the volume is held whole on the GPU or bricked (over the memory budget).
    #[getter]
    fn layout(&self) -> &'static str {
        let inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        match inner.plan.layout {
            Layout::Whole => "whole",
            Layout::Bricked { .. } => "bricked",
        }
    }

    /// The scan summary (Table-1 row, peaks, windows, contrast, warnings) as JSON text; the
    /// Python `peaks()` parses it.
    fn summary_json(&self) -> PyResult<String> {
        let inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
        let summary = ScanSummary::new(&self.label, self.dims, &inner.report, &self.warnings);
        serde_json::to_string(&summary).map_err(|e| errors::Error::new_err(e.to_string()))
    }

    /// Renders one frame of the scene the command-line words `scene` describe (`morphray
    /// render`'s scene options; the Python side writes them from its keyword arguments);
    /// returns an (H, W, 4) uint8 array (RGBA, rows top to bottom) and, when the picture shows
    /// only the background, why and what to try.
    /// With `document` (a scene document's path), its scene instead, at the size `scene`
    /// gives (`--size` only) or its own.
    /// `layers`: `--layer` specs (none: a document's layers, or none).
    #[pyo3(signature = (scene, document=None, layers=vec![]))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        scene: Vec<String>,
        document: Option<PathBuf>,
        layers: Vec<String>,
    ) -> PyResult<(Bound<'py, PyArray3<u8>>, Option<String>)> {
        let specs = match (&document, layers.is_empty()) {
            (Some(path), true) => morphray::scene::document::SceneDocument::read(path)
                .map_err(|e| errors::usage(e.to_string()))?
                .layer_specs(path),
            _ => crate::layers::parse(&layers)?,
        };
        let choice = match &document {
            Some(path) => {
                let size = (!scene.is_empty())
                    .then(|| recipe::scene_choice(&scene).map(|c| c.size))
                    .transpose()?;
                recipe::document_choice(path, size)?
            }
            None => recipe::scene_choice(&scene)?,
        };
        let (width, height) = choice.size;
        let recipe = choice.recipe;
        let matcap = choice.matcap;
        let (pixels, note) = py.detach(|| -> PyResult<(Vec<u8>, Option<String>)> {
            let mut state = state::lock();
            let mut inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
            let generation = inner.generation;
            state.engine_and_target(generation, [width, height])?;
            inner.reopen_if_needed(&mut state, &recipe)?;
            let scene = recipe.scene_for(&inner.report);
            let (engine, target) = state.engine_and_target(generation, [width, height])?;
            let prepared = inner.twin.prepared.clone();
            inner.layers.attach(&specs, engine, &prepared, target)?;
            // The engine outlives this render: a render without `matcap=` gets the built-in.
            match matcap {
                Some(matcap) => engine.set_matcap(matcap),
                None if engine.matcap().name != "clay" => engine.set_matcap(Default::default()),
                None => {}
            }
            let mut pixels = vec![0u8; width as usize * height as usize * 4];
            engine
                .render_twin_into(target, &mut inner.twin, &scene, &mut pixels)
                .map_err(errors::gpu)?;
            let constant = inner.twin.prepared.normalization.constant;
            let note = morphray::cli::render::empty_note(&scene, constant, &pixels);
            Ok((pixels, note))
        })?;
        let shape = (height as usize, width as usize, 4);
        let array = Array3::from_shape_vec(shape, pixels)
            .map_err(|e| errors::Error::new_err(e.to_string()))?;
        Ok((array.into_pyarray(py), note))
    }

    /// The derived maps as float32 (i, j, k) arrays, by `morphray derive`'s names: `"normalized"`
    /// (I_norm), `"gradient"` (|grad I_norm| per mm), `"curvature"` (k = g^T H g per mm^2,
    /// I_norm units; the paper's eq. 3-4), `"vesselness"` (multi-scale Frangi at
    /// `vessel_scales` mm, default 0.6-3 mm, in [0, 1]) and, with `denoise` (`"gaussian:1"`,
    /// `"median"`, `"bilateral:1,0.1"`, as `--denoise`), `"denoised"`; `"brain"` is a uint8
    /// mask (1 inside the extracted brain, all 0 when no brain-like region was found:
    /// `brain_report_json` says which) on the input grid, as `--brain on` masks. The engine's
    /// one export function computes them (`Engine::derived_maps`, as `morphray derive` does).
    /// Whole volumes only (a bricked volume has no whole-volume map to export).
    #[pyo3(signature = (maps, denoise="none".to_string(), vessel_scales=vec![]))]
    fn derive<'py>(
        &self,
        py: Python<'py>,
        maps: Vec<String>,
        denoise: String,
        vessel_scales: Vec<f32>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let denoise: Denoise = denoise
            .parse()
            .map_err(|e: String| errors::usage(format!("denoise: {e}")))?;
        let (request, wanted) = MapRequest::named(&maps, denoise, &vessel_scales)
            .map_err(|e| errors::usage(e.to_string()))?;
        let computed = py.detach(|| -> PyResult<DerivedMaps> {
            let mut state = state::lock();
            let inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
            inner.check_whole(&state, "its maps cannot be exported whole")?;
            let (engine, _) = state.engine()?;
            engine
                .derived_maps(&inner.twin.prepared, &request)
                .map_err(errors::gpu)
        })?;
        let [x, y, z] = self.dims.map(|d| d as usize);
        let out = PyDict::new(py);
        let export = |name: &str, map: Option<Vec<f32>>| -> PyResult<()> {
            let Some(map) = map else { return Ok(()) };
            // x fastest in memory: a Fortran-ordered (i, j, k) array.
            let array = Array3::from_shape_vec((x, y, z).f(), map)
                .map_err(|e| errors::Error::new_err(e.to_string()))?;
            out.set_item(name, array.into_pyarray(py))
        };
        let mut computed = computed;
        for name in wanted {
            match name {
                "normalized" => export(name, Some(std::mem::take(&mut computed.normalized)))?,
                "gradient" => export(name, computed.gradient.take())?,
                "curvature" => export(name, computed.curvature.take())?,
                "vesselness" => export(name, computed.vesselness.take())?,
                "denoised" => export(name, computed.denoised.take())?,
                _ => {
                    let mask = computed.brain.take().unwrap_or_else(|| vec![0; x * y * z]);
                    let array = Array3::from_shape_vec((x, y, z).f(), mask)
                        .map_err(|e| errors::Error::new_err(e.to_string()))?;
                    out.set_item("brain", array.into_pyarray(py))?;
                }
            }
        }
        Ok(out)
    }

    /// Writes the scene the command-line words `scene` describe on this volume as a scene
    /// document (`morphray render --scene`, `view --scene` open it). Volumes read from a file
    /// only: the document names its input by path.
    #[pyo3(signature = (path, scene, layers=vec![]))]
    fn save_scene(
        &self,
        py: Python<'_>,
        path: PathBuf,
        scene: Vec<String>,
        layers: Vec<String>,
    ) -> PyResult<()> {
        let specs = crate::layers::parse(&layers)?;
        use morphray::scene::document::{SceneDocument, SceneInput, recorded_path};
        let Some(input) = &self.path else {
            return Err(errors::usage(format!(
                "save_scene: {} was not read from a file, and a scene document names its scan by \
                 path: write it with to_nifti() and open that file",
                self.label
            )));
        };
        let choice = recipe::scene_choice(&scene)?;
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        py.detach(|| -> PyResult<()> {
            let mut inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
            let scene = choice.recipe.scene_for(&inner.report);
            let records = inner.layers.records(&specs, &folder)?;
            let mut doc = SceneDocument::new(
                SceneInput {
                    paths: vec![recorded_path(input, &folder)],
                    sha256: String::new(),
                    frame: self.frame,
                },
                scene,
            );
            doc.denoise = choice.recipe.denoise;
            doc.layers = records;
            doc.size = Some([choice.size.0, choice.size.1]);
            doc.matcap = choice.matcap_word.map(|m| {
                if morphray::scene::matcap::BUILT_IN.contains(&m.as_str()) {
                    m
                } else {
                    recorded_path(std::path::Path::new(&m), &folder)
                }
            });
            doc.write(&path, &[input.as_path()])
                .map_err(|e| errors::usage(e.to_string()))
        })
    }

    /// What brain extraction decides for this volume, as JSON text (the Python
    /// `brain_report()` parses it): the report of the mask the volume holds (extracted by the
    /// last DVR render with brain "auto" or "on", or at opening), or of a new extraction when it
    /// holds none. Whole volumes only.
    fn brain_report_json(&self, py: Python<'_>) -> PyResult<String> {
        let report = py.detach(|| -> PyResult<BrainReport> {
            let mut state = state::lock();
            let inner = self.inner.lock().unwrap_or_else(|p| p.into_inner());
            inner.check_whole(&state, "brain extraction needs the whole volume")?;
            if let Some(mask) = inner.twin.derived().and_then(|d| d.brain.as_ref()) {
                return Ok(mask.report.clone());
            }
            let (engine, _) = state.engine()?;
            let mask = engine
                .extract_brain(&inner.twin.prepared, BrainSwitch::On)
                .map_err(errors::gpu)?;
            Ok(mask.report)
        })?;
        let mut value =
            serde_json::to_value(&report).map_err(|e| errors::Error::new_err(e.to_string()))?;
        value["describe"] = report.decision.describe().into();
        value["masks_with_auto"] = (report.decision == BrainDecision::Head).into();
        Ok(value.to_string())
    }

    fn __repr__(&self) -> String {
        let [x, y, z] = self.dims;
        format!("<morphray.Volume {} {x}x{y}x{z}>", self.label)
    }
}
