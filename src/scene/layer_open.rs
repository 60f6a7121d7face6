//! Opening a layer from its spec (issue 31 item 4): the file read as any input, its grid in
//! physical units, the style the spec and the data's defaults make, clusters removed. One
//! function for the command line, the viewer, scene documents and Python, so a layer looks the
//! same in each.
//!
//! Decision: the layer is read at its first frame (a 4-D statistical map's first volume), with
//! the reader every input uses (`volume::source`), so a DICOM folder or a .nii.gz with odd
//! headers is a layer as it is a scan.

use super::layer::{LayerError, LayerSpec, LayerStyle};
use super::layer_grid::LayerGrid;
use crate::volume::source::{VolumeSource, read};
use std::sync::Arc;

/// A layer read and styled, ready to upload.
#[derive(Clone, Debug)]
pub struct OpenedLayer {
    /// What was asked for.
    pub spec: LayerSpec,
    /// The style drawn.
    pub style: LayerStyle,
    /// The voxels as read (physical units).
    pub grid: Arc<LayerGrid>,
    /// The voxels as drawn (clusters below the size set to 0).
    pub drawn: Arc<LayerGrid>,
    /// Clusters kept and removed (0, 0 without a cluster size).
    pub clusters: (usize, usize),
}

impl OpenedLayer {
    /// Reads `spec`'s file and styles it.
    pub fn open(spec: &LayerSpec) -> Result<OpenedLayer, LayerError> {
        let source = VolumeSource::File(spec.path.clone());
        let volume = read(&source, &Default::default())
            .map_err(|e| LayerError::Spec(format!("layer {}: {e}", spec.path.display())))?
            .volume;
        let grid = Arc::new(LayerGrid::from_volume(&volume)?);
        OpenedLayer::styled(spec.clone(), grid)
    }

    /// `grid` styled by `spec` (and the data's defaults), clusters removed.
    pub fn styled(spec: LayerSpec, grid: Arc<LayerGrid>) -> Result<OpenedLayer, LayerError> {
        let style = spec.style_for(&grid.defaults())?;
        OpenedLayer::with_style(spec, grid, style)
    }

    /// `grid` drawn with `style` (a viewer's edit), clusters removed.
    pub fn with_style(
        spec: LayerSpec,
        grid: Arc<LayerGrid>,
        style: LayerStyle,
    ) -> Result<OpenedLayer, LayerError> {
        style.check()?;
        let (drawn, clusters) = grid.clustered(&style);
        let drawn = if clusters == (0, 0) {
            grid.clone()
        } else {
            Arc::new(drawn)
        };
        Ok(OpenedLayer {
            spec,
            style,
            grid,
            drawn,
            clusters,
        })
    }

    /// One line saying what is drawn, for logs and the command line.
    pub fn describe(&self) -> String {
        let s = &self.style;
        let mut text = format!(
            "layer {}: {} {}..{}, |v| >= {}",
            self.grid.name,
            s.colormap.name(),
            short(s.lo),
            short(s.hi),
            short(s.threshold)
        );
        match s.negative {
            Some(map) => text.push_str(&format!(", negative side {}", map.name())),
            None => text.push_str(", positive side only"),
        }
        if s.cluster > 1 {
            let (kept, removed) = self.clusters;
            text.push_str(&format!(
                ", clusters >= {} voxels: {kept} kept, {removed} removed",
                s.cluster
            ));
        }
        text.push_str(&format!(", opacity {}", s.opacity));
        if self.grid.non_finite > 0 {
            text.push_str(&format!(
                " ({} non-finite voxels read as 0)",
                self.grid.non_finite
            ));
        }
        text
    }
}

/// `v` with at most 4 decimals and no trailing zeros (`3.1`, `0.9474`, `8`).
fn short(v: f64) -> String {
    let text = format!("{v:.4}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" {
        "0".into()
    } else {
        text.into()
    }
}

impl LayerSpec {
    /// The spec that draws `path` exactly with `style` (scene documents, the viewer's layers).
    pub fn from_style(path: std::path::PathBuf, style: &LayerStyle) -> LayerSpec {
        LayerSpec {
            path,
            colormap: Some(style.colormap),
            window: Some((style.lo, style.hi)),
            threshold: Some(style.threshold),
            negative: Some(style.negative),
            cluster: Some(style.cluster),
            opacity: Some(style.opacity),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::short;

    #[test]
    fn numbers_are_told_short() {
        assert_eq!(short(3.1), "3.1");
        assert_eq!(short(8.0), "8");
        assert_eq!(short(0.947395384311676), "0.9474");
        assert_eq!(short(-0.00001), "0");
        assert_eq!(short(-2.5), "-2.5");
    }
}
