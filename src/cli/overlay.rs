//! The overlay options shared by `slice` and `view`: `--overlay LABELS`, `--overlay-lut FILE`,
//! `--overlay-opacity A`, and reading them into a `scene::overlay::Overlay` (label map as read,
//! colours, opacity; each client resamples it onto its volume's grid).

use crate::error::Error;
use crate::scene::overlay::{LabelTable, Overlay};
use crate::volume::source::VolumeSource;
use clap::Args;
use std::path::PathBuf;

/// Overlay options.
#[derive(Debug, Args, serde::Serialize)]
pub struct OverlayArgs {
    /// Integer label map (NIfTI; same or another grid, resampled onto the volume's by the
    /// affines, nearest neighbour) drawn in colour over the slices; label 0 is not drawn.
    #[arg(long, value_name = "LABELS")]
    pub overlay: Option<PathBuf>,
    /// FreeSurfer-style lookup table for the labels (`index name R G B A` per line); labels
    /// not in it, or all without it, take a default palette.
    #[arg(long, value_name = "FILE", requires = "overlay")]
    pub overlay_lut: Option<PathBuf>,
    /// Opacity of the label colours over the grey, 0..1.
    #[arg(long, default_value_t = 0.5, requires = "overlay")]
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
        let source = VolumeSource::File(path.clone());
        let labels = crate::volume::source::read(&source, &Default::default())?.volume;
        let table = match &self.overlay_lut {
            None => LabelTable::default(),
            Some(lut) => {
                let bytes = crate::files::read::read_regular(lut, 16 << 20).map_err(|e| {
                    Error::Usage(format!(
                        "cannot read the lookup table {}: {e}",
                        lut.display()
                    ))
                })?;
                let text = String::from_utf8(bytes).map_err(|_| {
                    Error::Usage(format!(
                        "{}: the lookup table is not UTF-8 text",
                        lut.display()
                    ))
                })?;
                LabelTable::parse(&text, &lut.display().to_string())
                    .map_err(|e| Error::Usage(e.to_string()))?
            }
        };
        Ok(Some(Overlay {
            labels,
            table,
            opacity: self.overlay_opacity,
        }))
    }
}
