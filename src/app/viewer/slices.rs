//! The GPU side of the slice panels: renders the slices the layout shows when what they show
//! changed (crosshair, convention, window, layout, volume) and hands them to egui as textures.
//!
//! Decisions: one submission per change, read back and uploaded as an egui texture (the
//! slices are small: a 256^2 slice is 256 KiB), rather than a composition pass of their own;
//! an unchanged crosshair costs nothing per frame. A failure is the status line's error, the
//! session goes on.

use super::Viewer;
use crate::engine::slice::{Slicer, geometry_of};

impl Viewer {
    /// Brings the slice textures up to date with the controls (called before the interface).
    pub(super) fn update_slices(&mut self) {
        let (Some(current), Some(gpu)) = (&self.current, &mut self.gpu) else {
            return;
        };
        let prepared = &current.loaded.twin.prepared;
        let slices = &mut self.controls.slices;
        if slices.volume != current.loaded.id {
            match geometry_of(prepared) {
                Ok(geometry) => slices.set_volume(current.loaded.id, geometry),
                Err(e) => {
                    self.status.error = Some(format!("slices: {e}"));
                    return;
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
            let size = [grid.width as usize, grid.height as usize];
            let texture = self.ctx.load_texture(
                format!("slice {}", grid.plane.name()),
                egui::ColorImage::from_rgba_unmultiplied(size, &rgba),
                egui::TextureOptions::NEAREST,
            );
            slices.install(grid, texture);
        }
        slices.rendered_window = window;
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
