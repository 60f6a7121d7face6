//! The GPU side of the slice panels: renders the slices the layout shows when what they show
//! changed (crosshair, convention, window, layout, volume) and hands them to egui as textures.
//!
//! Decisions: one submission per change, read back and uploaded as an egui texture (the
//! slices are small: a 256^2 slice is 256 KiB), rather than a composition pass of their own;
//! an unchanged crosshair costs nothing per frame. A failure is the status line's error, the
//! session goes on. A label overlay (`view --overlay`) is resampled onto each volume's grid
//! when it arrives and blended over the slices on the host, as `morphray slice` does; it is
//! also uploaded for the 3D view (`engine::LabelVolume`), where the same switches apply. The
//! brain mask in use is outlined over both (`app/brain_outline.rs`).

use super::Viewer;
use crate::app::slices_panel::SliceOverlay;
use crate::engine::RenderTarget;
use crate::engine::slice::{Slicer, geometry_of};
use crate::scene::overlay::{blend_slice, resample_onto};
use std::sync::Arc;

/// Draws the label overlay in `target` as the controls say (every frame: the target rewrites
/// its colour table only when it changed).
pub(super) fn attach_labels(
    labels: Option<&Arc<crate::engine::LabelVolume>>,
    slices: &crate::app::slices_panel::SliceControls,
    target: &mut RenderTarget,
) {
    let shown = labels.zip(slices.label_colours_3d());
    target.show_labels(shown);
}

impl Viewer {
    /// Brings the slice textures up to date with the controls (called before the interface).
    pub(super) fn update_slices(&mut self) {
        let (Some(current), Some(gpu)) = (&self.current, &mut self.gpu) else {
            return;
        };
        let prepared = &current.loaded.twin.prepared;
        // Each layer's value at the crosshair, after the volume's (as FSLeyes lists overlays).
        let layer_values = (self.controls.slices.crosshair)
            .map(|world| self.controls.layers.readout(world).join(", "))
            .filter(|text| !text.is_empty());
        let slices = &mut self.controls.slices;
        let overlay = slices.overlay.as_ref();
        let readout = slices
            .crosshair
            .map(|world| {
                // HU only for values in Hounsfield units (a rescaled CT's are not), as the windows.
                let hu = crate::scene::preset::values_are_hu(&current.loaded.report);
                let r = crate::app::readout::readout(&current.loaded.host, world, hu);
                match overlay {
                    // The labels are on this volume's grid once the overlay is set up below.
                    Some(o) if o.labels.dims == current.loaded.host.dims => {
                        r.with_label(&o.labels, &o.table)
                    }
                    _ => r,
                }
                .text()
            })
            .map(|text| match &layer_values {
                Some(values) => format!("{text}; layers: {values}"),
                None => text,
            });
        if readout != self.status.readout {
            if let Some(line) = &readout {
                // Scripted runs and tests read where the crosshair went and what is there.
                self.log.say(line);
            }
            slices.readout.clone_from(&readout);
            self.status.readout = readout;
        }
        if slices.volume != current.loaded.id {
            match geometry_of(prepared) {
                Ok(geometry) => {
                    slices.set_volume(current.loaded.id, geometry);
                    // A scene document's crosshair, on the first volume only.
                    if let Some(mm) = self.config.crosshair_mm.take() {
                        slices.crosshair = Some(glam::DVec3::from_array(mm));
                    }
                }
                Err(e) => {
                    self.status.error = Some(format!("slices: {e}"));
                    return;
                }
            }
            slices.overlay = None;
            gpu.labels_3d = None;
            if let Some(overlay) = &self.config.overlay {
                let dims = prepared.dims.map(|d| d as usize);
                match resample_onto(&overlay.labels, dims, &prepared.affine) {
                    Ok(labels) => {
                        // The same labels in the 3D view (whole volumes only: a bricked one
                        // shows them on the slices and says why not in 3D).
                        match gpu.engine.upload_labels(prepared, &labels) {
                            Ok(uploaded) => gpu.labels_3d = Some(Arc::new(uploaded)),
                            Err(e) => self.status.error = Some(format!("overlay in 3D: {e}")),
                        }
                        slices.overlay = Some(SliceOverlay {
                            present: labels.present(),
                            labels,
                            table: overlay.table.clone(),
                            opacity: overlay.opacity,
                        })
                    }
                    Err(e) => self.status.error = Some(format!("overlay: {e}")),
                }
            }
        }
        let wanted = slices.wanted();
        if wanted.is_empty() || !slices.stale(&wanted) {
            return;
        }
        if gpu.slicer.is_none() {
            match Slicer::new(&gpu.engine) {
                Ok(s) => gpu.slicer = Some(s),
                Err(e) => {
                    self.status.error = Some(format!("slices: {e}"));
                    return;
                }
            }
        }
        let Some(slicer) = &gpu.slicer else {
            return;
        };
        let window = slices.window;
        for grid in wanted {
            let image = match slicer.render(&gpu.engine, prepared, &grid, window) {
                Ok(image) => image,
                Err(e) => {
                    self.status.error = Some(format!("slices: {e}"));
                    return;
                }
            };
            let mut rgba = image.rgba8;
            for px in rgba.chunks_exact_mut(4) {
                px[3] = 255;
            }
            if let Some(geometry) = &slices.geometry {
                let index = grid.in_index_space(geometry);
                if let Some(o) = &slices.overlay {
                    blend_slice(
                        &mut rgba,
                        &index,
                        &o.labels,
                        &o.table,
                        o.opacity,
                        &slices.hidden,
                    );
                }
                // Layers over the labels (as in 3D, where their medium comes first).
                self.controls
                    .layers
                    .blend(&mut rgba, &index, &prepared.affine);
                // Over the labels: the mask's edge stays visible through them.
                if let Some(brain) = &slices.brain {
                    brain.draw(&mut rgba, &index, prepared.dims);
                }
            }
            let size = [grid.width as usize, grid.height as usize];
            let texture = self.ctx.load_texture(
                format!("slice {}", grid.plane.name()),
                egui::ColorImage::from_rgba_unmultiplied(size, &rgba),
                egui::TextureOptions::NEAREST,
            );
            slices.install(grid, texture);
        }
        slices.rendered_window = window;
        slices.dirty = false;
    }
}

impl Viewer {
    /// The slices' part of the scripted log's layout line: the layout, the convention, and each
    /// plane's image rectangle in pixels (0,0,0,0 when not shown).
    pub(super) fn slices_layout(&self, ppp: f32) -> String {
        let s = &self.controls.slices;
        let mut line = format!(
            " slices {} convention {}",
            s.layout.name(),
            s.convention.name()
        );
        for (plane, rect) in crate::scene::slice::Plane::ALL.iter().zip(s.rects) {
            let r = rect.map_or([0; 4], |r| super::px_rect(r, ppp, self.size));
            line += &format!(" {} {},{},{},{}", plane.name(), r[0], r[1], r[2], r[3]);
        }
        line
    }
}
