//! The layer option shared by `render`, `slice` and `view`: `--layer FILE[:MAP[:LO:HI]]...`,
//! repeatable (issue 31 item 4), read into `scene::layer_open::OpenedLayer`s, and drawn: in
//! `render`'s 3D raymarch ([`attach_to_render`]) and over `slice`'s picture ([`blend_over`]).
//!
//! Decision: the layers are read before any GPU work, so a bad spec or file fails at once, and
//! each is told in one line (window, threshold, sides, clusters) so the picture can be read.

use crate::engine::plan::Plan;
use crate::engine::{Engine, PreparedVolume, RenderTarget};
use crate::error::Error;
use crate::scene::layer::{LayerSpec, MAX_LAYERS};
use crate::scene::layer_grid::blend_layer_slice;
use crate::scene::layer_open::OpenedLayer;
use crate::scene::slice::IndexGrid;
use clap::Args;
use std::sync::Arc;

/// Layer options.
#[derive(Clone, Debug, Default, Args, serde::Serialize)]
pub struct LayerArgs {
    /// Intensity layer over the volume, on its own grid: FILE[:MAP[:LO:HI]][:KEY=VALUE...]
    ///
    /// FILE[:MAP[:LO:HI]][:thr=T][:neg=MAP|off][:cluster=N][:opacity=A]; give it twice for two
    /// layers. A second volume (a statistical map, PET, FLAIR) on its own grid, resampled through both
    /// affines. Values >= thr (default LO) take MAP (default red-yellow) from LO to HI; with
    /// neg=, values <= -thr take the negative map (default blue-lightblue when the file has
    /// values at or below -LO). Without LO:HI: the 95th and 99.5th percentiles of |value|.
    /// cluster=N drops 26-connected clusters under N voxels. opacity: over the slice's grey,
    /// per mm in 3D (default 1). Maps: red-yellow, blue-lightblue, hot, gray, viridis, inferno,
    /// green. Example: --layer zstat.nii.gz:red-yellow:3.1:8:cluster=20
    #[arg(long = "layer", value_name = "SPEC")]
    pub layers: Vec<String>,
}

impl LayerArgs {
    /// The specs, parsed (at most [`MAX_LAYERS`]).
    pub fn specs(&self) -> Result<Vec<LayerSpec>, Error> {
        if self.layers.len() > MAX_LAYERS {
            return Err(Error::Usage(format!(
                "--layer given {} times: at most {MAX_LAYERS} layers are drawn over a volume",
                self.layers.len()
            )));
        }
        self.layers
            .iter()
            .map(|text| LayerSpec::parse(text).map_err(|e| Error::Usage(format!("--layer {e}"))))
            .collect()
    }

    /// The files these options read (never to be written).
    pub fn inputs(&self) -> Vec<std::path::PathBuf> {
        self.specs()
            .map(|specs| specs.into_iter().map(|s| s.path).collect())
            .unwrap_or_default()
    }
}

/// Reads and styles every spec, saying each in one line (`say`).
pub fn open_all(specs: &[LayerSpec], say: impl Fn(&str)) -> Result<Vec<OpenedLayer>, Error> {
    if specs.len() > MAX_LAYERS {
        return Err(Error::Usage(format!(
            "{} layers: at most {MAX_LAYERS} are drawn over a volume",
            specs.len()
        )));
    }
    let mut opened = Vec::new();
    for spec in specs {
        let layer = OpenedLayer::open(spec).map_err(|e| Error::Usage(e.to_string()))?;
        say(&layer.describe());
        opened.push(layer);
    }
    Ok(opened)
}

/// Uploads `layers` for `prepared` and draws them in `target`'s DVR frames; their 2 bytes a
/// voxel must fit in what the plan leaves of the memory budget.
pub fn attach_to_render(
    layers: &[OpenedLayer],
    engine: &mut Engine,
    (prepared, plan): (&PreparedVolume, &Plan),
    target: &mut RenderTarget,
) -> Result<(), Error> {
    let bytes: u64 = layers.iter().map(|l| 2 * l.drawn.values.len() as u64).sum();
    if plan.peak_bytes.saturating_add(bytes) > plan.budget {
        let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
        return Err(Error::Usage(format!(
            "--layer needs {:.1} MiB of GPU memory, and the plan already uses {:.1} of the {:.1} \
             MiB budget: raise --memory-budget",
            mib(bytes),
            mib(plan.peak_bytes),
            mib(plan.budget)
        )));
    }
    let mut attached = Vec::new();
    for layer in layers {
        let uploaded = engine.upload_layer(prepared, (*layer.drawn).clone())?;
        attached.push((Arc::new(uploaded), layer.style));
    }
    target.set_layers(attached)?;
    Ok(())
}

/// Blends `layers` over the RGBA slice `rgba` whose pixels lie at base index positions `slice`
/// of a volume with index-to-world `affine`; returns the pixels each layer drew.
pub fn blend_over(
    rgba: &mut [u8],
    slice: &IndexGrid,
    affine: &[[f64; 4]; 4],
    layers: &[OpenedLayer],
) -> Vec<usize> {
    layers
        .iter()
        .map(|layer| {
            let codes = layer.drawn.codes();
            let map = layer.drawn.index_map(affine);
            let tables = layer.style.tables();
            blend_layer_slice(
                rgba,
                slice,
                (&layer.drawn, &codes, map),
                &layer.style,
                &tables,
            )
        })
        .collect()
}
