//! The overlay options shared by `render`, `slice` and `view`: `--overlay LABELS`,
//! `--overlay-lut FILE`, `--overlay-opacity A`, and reading them into a
//! `scene::overlay::Overlay` (label map as read, colours, opacity; each client resamples it onto
//! its volume's grid). `render` draws it in the 3D raymarch ([`attach_to_render`]).
//!
//! Decision: one opacity for both uses, read as a blend factor over a slice's grey and as an
//! opacity per millimetre in 3D (like the tissues'), so 0.5 shows a structure as a solid
//! coloured surface that the tissue in front of it can still veil.

use crate::engine::plan::Plan;
use crate::engine::{Engine, PreparedVolume, RenderTarget, label_colours};
use crate::error::Error;
use crate::scene::overlay::{Overlay, resample};
use crate::volume::Volume;
use clap::Args;
use std::path::PathBuf;

/// Overlay options.
#[derive(Clone, Debug, Args, serde::Serialize)]
pub struct OverlayArgs {
    /// Integer label map drawn in colour on slices and in 3D (label 0 is not drawn)
    ///
    /// NIfTI, on the same or another grid: resampled onto the volume's by the affines (nearest
    /// neighbour). In 3D (DVR) each sample takes its nearest voxel's label.
    #[arg(long, value_name = "LABELS")]
    pub overlay: Option<PathBuf>,
    /// FreeSurfer-style colour table for the labels (`index name R G B A` lines)
    ///
    /// Labels not in it, or all without it, take a default palette. A is a transparency, as
    /// FreeSurfer writes it (0 = opaque).
    #[arg(
        long,
        value_name = "FILE",
        requires = "overlay",
        hide_short_help = true
    )]
    pub overlay_lut: Option<PathBuf>,
    /// Label opacity 0..1: over a slice's grey, per mm in 3D
    #[arg(long, value_name = "A", default_value_t = 0.5, requires = "overlay")]
    pub overlay_opacity: f64,
}

impl OverlayArgs {
    /// The files these options read (never to be written).
    pub fn inputs(&self) -> Vec<&std::path::Path> {
        [&self.overlay, &self.overlay_lut]
            .into_iter()
            .filter_map(|p| p.as_deref())
            .collect()
    }

    /// Reads the label map and its table (None without `--overlay`).
    pub fn load(&self) -> Result<Option<Overlay>, Error> {
        if !(0.0..=1.0).contains(&self.overlay_opacity) {
            return Err(Error::Usage(format!(
                "--overlay-opacity {}: give an opacity from 0 to 1",
                self.overlay_opacity
            )));
        }
        let Some(path) = &self.overlay else {
            return Ok(None);
        };
        Overlay::open(path, self.overlay_lut.as_deref(), self.overlay_opacity)
            .map(Some)
            .map_err(Error::Usage)
    }
}

/// Resamples `overlay` onto `volume` (prepared as `prepared` under `plan`), uploads it and
/// draws it in `target`'s DVR frames; returns the number of distinct labels drawn. The labels'
/// 2 bytes a voxel must fit in what the plan leaves of the memory budget.
pub fn attach_to_render(
    overlay: &Overlay,
    volume: &Volume,
    engine: &mut Engine,
    (prepared, plan): (&PreparedVolume, &Plan),
    target: &mut RenderTarget,
) -> Result<usize, Error> {
    let labels = resample(&overlay.labels, volume).map_err(|e| Error::Usage(e.to_string()))?;
    let label_bytes = 2 * labels.values.len() as u64;
    if plan.peak_bytes.saturating_add(label_bytes) > plan.budget {
        let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
        return Err(Error::Usage(format!(
            "--overlay needs {:.1} MiB of GPU memory for its labels, and the plan already uses \
             {:.1} of the {:.1} MiB budget: raise --memory-budget",
            mib(label_bytes),
            mib(plan.peak_bytes),
            mib(plan.budget)
        )));
    }
    if let crate::engine::VolumeLayout::Bricked(_) = prepared.layout {
        return Err(Error::Usage(
            "--overlay is drawn in 3D on whole volumes only, and this one was bricked (--bricked, \
             or a --memory-budget too small for it): drop --bricked or raise --memory-budget"
                .into(),
        ));
    }
    let uploaded = std::sync::Arc::new(engine.upload_labels(prepared, &labels)?);
    let hidden = Default::default();
    let colours = label_colours(&overlay.table, &uploaded.present, overlay.opacity, &hidden);
    let count = uploaded.present.len();
    target.set_labels(Some((uploaded, colours)));
    Ok(count)
}
