//! The colour bar of a colour map (issue 31 item 1): drawn at the 3D view's right edge whenever
//! the scene colours by a map (`Scene::colormap`: MIP/MinIP's display window, or DVR's samples),
//! the map from the bottom (the window's low end) to the top, each end labelled in the scanner's
//! units (I_norm `v` is `imin + v (imax - imin)`, HU for a CT in Hounsfield units), as the slices'
//! grey window reads (`slices_panel::in_units`).
//!
//! Decisions: a plain grey MIP without a map draws no bar (its grey levels are the slices' grey
//! window, shown under the slices); the bar is 35 % of the view's height in its upper right
//! quarter, clear of the orientation letters at the edges' middles; 48 bands of the map's own
//! lookup (the shader's 9-point table, `Colormap::lookup`), so the bar is the map the pixels get.

use crate::scene::Scene;
use crate::scene::colormap::Colormap;
use egui::{Color32, Painter, Pos2, Rect, vec2};

/// Bands the bar is drawn in.
const BANDS: usize = 48;

/// Where the bar goes in the view `view`: 14 points wide, 18 in from the right edge, from 10 %
/// to 45 % of the height (the right edge's letter is at its middle).
pub fn bar_rect(view: Rect) -> Rect {
    let top = view.top() + 0.10 * view.height();
    let bottom = view.top() + 0.45 * view.height();
    let right = view.right() - 18.0;
    Rect::from_min_max(Pos2::new(right - 14.0, top), Pos2::new(right, bottom))
}

/// The labels of the bar's low and high ends for the display window `window` (I_norm), in the
/// scanner's units when they are known (`units`: what I_norm 0 and 1 are, and the unit's name, as
/// the slices' window reads them), in I_norm otherwise.
pub fn end_labels(window: [f64; 2], units: Option<(f64, f64, &str)>) -> (String, String) {
    let [lo, hi] = window;
    match units {
        Some((imin, imax, unit)) => {
            let text = |v: f64| {
                let value = super::slices_panel::in_units(v, imin, imax);
                if unit.is_empty() {
                    value
                } else {
                    format!("{value} {unit}")
                }
            };
            (text(lo), text(hi))
        }
        None => (format!("{lo:.2}"), format!("{hi:.2}")),
    }
}

/// Draws the colour bar of `scene`'s map over the view `view`, when it has one.
pub fn draw(painter: &Painter, view: Rect, scene: &Scene, units: Option<(f64, f64, &str)>) {
    let Some(map) = scene.colormap else { return };
    let bar = bar_rect(view);
    if bar.height() < 40.0 {
        return;
    }
    draw_bands(painter, bar, map);
    painter.rect_stroke(
        bar,
        0.0,
        egui::Stroke::new(1.0, Color32::from_gray(200)),
        egui::StrokeKind::Outside,
    );
    let (lo, hi) = end_labels(scene.intensity_window.map(f64::from), units);
    let font = egui::FontId::proportional(12.0);
    for (text, y, align) in [
        (hi, bar.top(), egui::Align2::RIGHT_TOP),
        (lo, bar.bottom(), egui::Align2::RIGHT_BOTTOM),
    ] {
        painter.text(
            Pos2::new(bar.left() - 4.0, y),
            align,
            text,
            font.clone(),
            Color32::WHITE,
        );
    }
}

/// The map from the bottom (0) to the top (1) of `bar`, in [`BANDS`] bands.
fn draw_bands(painter: &Painter, bar: Rect, map: Colormap) {
    let band = bar.height() / BANDS as f32;
    for i in 0..BANDS {
        let x = (i as f64 + 0.5) / BANDS as f64;
        let [r, g, b] = map
            .lookup(x)
            .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8);
        let bottom = bar.bottom() - i as f32 * band;
        let rect = Rect::from_min_size(
            Pos2::new(bar.left(), bottom - band),
            vec2(bar.width(), band + 0.5),
        );
        painter.rect_filled(rect, 0.0, Color32::from_rgb(r, g, b));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bar_sits_in_the_upper_right_clear_of_the_edge_letters() {
        let view = Rect::from_min_size(Pos2::new(100.0, 50.0), vec2(600.0, 400.0));
        let bar = bar_rect(view);
        assert!(view.contains_rect(bar));
        // Right of the centre, and ending above the right edge's letter (at its middle, about
        // 20 points tall).
        assert!(bar.left() > view.center().x);
        assert!(bar.bottom() < view.center().y - 10.0);
    }

    #[test]
    fn the_ends_read_in_the_files_units_or_i_norm() {
        let ends = |w, u| end_labels(w, u);
        assert_eq!(ends([0.1, 0.9], None), ("0.10".into(), "0.90".into()));
        assert_eq!(
            ends([0.25, 0.5], Some((-1000.0, 3000.0, "HU"))),
            ("0 HU".into(), "1000 HU".into())
        );
        assert_eq!(
            ends([0.0, 1.0], Some((12.0, 1497.6, ""))),
            ("12".into(), "1498".into())
        );
        assert_eq!(
            ends([0.0, 0.5], Some((0.0, 4.0, ""))),
            ("0.00".into(), "2.00".into())
        );
    }
}
