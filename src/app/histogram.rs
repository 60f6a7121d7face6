//! The histogram panel: I_norm histogram (log counts), the detected CSF/GM/WM peaks, the fitted
//! tissue classes as curves (`histogram_fit`), and one draggable band per tissue window.
//!
//! Decisions:
//! - Drawn with egui's painter rather than egui_plot: the bands need their own drag handles
//!   (edges and body), and the layout is a pure function ([`Layout`]) that tests use to find
//!   where to press, so a test drags exactly what a person would.
//! - Counts on a log scale (`ln(1 + n)`): the background spike is 10-100x the tissue modes and
//!   would flatten them on a linear axis.
//! - Each tissue has its own lane under the histogram, so overlapping windows (the paper's WM
//!   and pathology bands overlap) stay separately draggable; the band is also shaded over the
//!   histogram in the tissue's colour. Dragging an edge moves that boundary; dragging the body
//!   moves the window, keeping its width. Windows keep their edge softness and a minimum width.

use crate::analysis::TissueReport;
use crate::scene::{Classification, TissueClass, Window};
use egui::{Color32, Pos2, Rect, Sense, Stroke, Ui, vec2};

/// Smallest window width a drag can make, in I_norm.
pub const MIN_WIDTH: f64 = 0.005;

/// Height of one tissue's lane, points.
pub const LANE_HEIGHT: f32 = 14.0;
/// Height of the histogram plot, points.
pub const PLOT_HEIGHT: f32 = 110.0;
/// Width of an edge's drag handle, points.
pub const HANDLE_WIDTH: f32 = 8.0;

/// Where everything of the widget is, for a given outer rectangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    /// The histogram plot.
    pub plot: Rect,
    /// The whole widget.
    pub outer: Rect,
}

impl Layout {
    /// Total height of the widget, points.
    pub fn height() -> f32 {
        PLOT_HEIGHT + 4.0 * LANE_HEIGHT + 4.0
    }

    /// The layout inside `outer` (its top-left and width are used).
    pub fn new(outer: Rect) -> Layout {
        let plot = Rect::from_min_size(outer.min, vec2(outer.width(), PLOT_HEIGHT));
        Layout { plot, outer }
    }

    /// The lane of one tissue.
    pub fn lane(&self, tissue: TissueClass) -> Rect {
        let top = self.plot.bottom() + 4.0 + tissue as usize as f32 * LANE_HEIGHT;
        Rect::from_min_max(
            Pos2::new(self.plot.left(), top),
            Pos2::new(self.plot.right(), top + LANE_HEIGHT - 2.0),
        )
    }

    /// Screen x of an I_norm value.
    pub fn x_of(&self, value: f64) -> f32 {
        self.plot.left() + value.clamp(0.0, 1.0) as f32 * self.plot.width()
    }

    /// I_norm of a screen x (clamped to [0, 1]).
    pub fn value_of(&self, x: f32) -> f64 {
        (((x - self.plot.left()) / self.plot.width().max(1.0)) as f64).clamp(0.0, 1.0)
    }

    /// The centre of a tissue's edge handle (lo or hi), where a drag starts.
    pub fn handle(&self, tissue: TissueClass, window: &Window, hi: bool) -> Pos2 {
        let lane = self.lane(tissue);
        let v = if hi { window.hi.min(1.0) } else { window.lo };
        Pos2::new(self.x_of(v), lane.center().y)
    }
}

/// Which part of a band a drag holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Grip {
    /// The lower boundary.
    Lo,
    /// The upper boundary.
    Hi,
    /// The whole band.
    Body,
}

/// The window after dragging `grip` to I_norm `value` (for the body: by `delta`).
pub fn dragged(window: &Window, grip: Grip, value: f64, delta: f64) -> Window {
    let mut w = *window;
    match grip {
        Grip::Lo => w.lo = value.clamp(0.0, w.hi - MIN_WIDTH),
        Grip::Hi => {
            // A window open above (hi > 1) stays open unless its edge is pulled below 1.
            w.hi = value.max(w.lo + MIN_WIDTH);
            if value >= 1.0 && window.hi > 1.0 {
                w.hi = window.hi;
            }
        }
        Grip::Body => {
            let width = w.hi - w.lo;
            let lo = (w.lo + delta).clamp(0.0, (1.0 - width).max(0.0));
            w.lo = lo;
            w.hi = lo + width;
            if window.hi > 1.0 {
                // Keep an open-above window open.
                w.hi = window.hi.max(w.lo + MIN_WIDTH);
            }
        }
    }
    w
}

/// Colour of a tissue as egui colour with alpha.
pub fn tissue_colour(c: [f32; 3], alpha: u8) -> Color32 {
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    Color32::from_rgba_unmultiplied(byte(c[0]), byte(c[1]), byte(c[2]), alpha)
}

/// Colour of the histogram bars (also what the scripted test looks for in screenshots).
pub const BAR_COLOUR: Color32 = Color32::from_rgb(150, 170, 200);
/// Plot background.
pub const PLOT_BACKGROUND: Color32 = Color32::from_rgb(24, 28, 34);

/// Shows the widget; returns true when a window changed.
pub fn show(
    ui: &mut Ui,
    histogram: &[u32; 256],
    report: Option<&TissueReport>,
    classification: &mut Classification,
) -> bool {
    let (outer, _) =
        ui.allocate_exact_size(vec2(ui.available_width(), Layout::height()), Sense::hover());
    let layout = Layout::new(outer);
    let painter = ui.painter_at(outer);
    painter.rect_filled(layout.plot, 2.0, PLOT_BACKGROUND);

    // Shaded bands behind the bars.
    for tissue in TissueClass::ALL {
        let style = classification.style(tissue);
        if let (Some(w), true) = (style.window, style.visible) {
            let band =
                Rect::from_x_y_ranges(layout.x_of(w.lo)..=layout.x_of(w.hi), layout.plot.y_range());
            painter.rect_filled(band, 0.0, tissue_colour(style.colour, 48));
        }
    }

    // Bars, log scale.
    let max = histogram.iter().copied().max().unwrap_or(0) as f64;
    let scale = (1.0 + max).ln().max(1e-9);
    let bin_width = layout.plot.width() / histogram.len() as f32;
    for (i, &count) in histogram.iter().enumerate() {
        if count == 0 {
            continue;
        }
        let h = ((1.0 + count as f64).ln() / scale) as f32 * (layout.plot.height() - 4.0);
        let x0 = layout.plot.left() + i as f32 * bin_width;
        let bar = Rect::from_min_max(
            Pos2::new(x0, layout.plot.bottom() - h),
            Pos2::new(x0 + bin_width.max(1.0), layout.plot.bottom()),
        );
        painter.rect_filled(bar, 0.0, BAR_COLOUR);
    }

    // The fitted classes (issue 28), over the bars.
    if let Some(report) = report {
        let fitted = report.fit.as_ref().map(|f| (f, false));
        if let Some((fit, rejected)) = fitted.or(report.rejected_fit.as_ref().map(|f| (f, true))) {
            super::histogram_fit::draw(&painter, &layout, fit, rejected, scale, classification);
        }
    }

    // Peaks.
    if let Some(report) = report {
        let peaks = [
            ("CSF", report.peaks.csf, TissueClass::Csf),
            ("GM", report.peaks.gm, TissueClass::Gm),
            ("WM", report.peaks.wm, TissueClass::Wm),
        ];
        for (name, peak, tissue) in peaks {
            let Some(peak) = peak else { continue };
            let x = layout.x_of(peak.norm);
            let colour = tissue_colour(classification.style(tissue).colour, 255);
            painter.line_segment(
                [
                    Pos2::new(x, layout.plot.top() + 12.0),
                    Pos2::new(x, layout.plot.bottom()),
                ],
                Stroke::new(1.5, colour),
            );
            painter.text(
                Pos2::new(x, layout.plot.top() + 1.0),
                egui::Align2::CENTER_TOP,
                name,
                egui::FontId::proportional(10.0),
                colour,
            );
        }
    }

    // Lanes with draggable bands.
    let mut changed = false;
    for tissue in TissueClass::ALL {
        let lane = layout.lane(tissue);
        painter.rect_filled(lane, 2.0, Color32::from_gray(40));
        let style = *classification.style(tissue);
        let Some(window) = style.window else {
            painter.text(
                lane.left_center() + vec2(4.0, 0.0),
                egui::Align2::LEFT_CENTER,
                format!("{}: no peak found", tissue.name()),
                egui::FontId::proportional(9.0),
                Color32::from_gray(140),
            );
            continue;
        };
        let alpha = if style.visible { 220 } else { 70 };
        let band = Rect::from_x_y_ranges(
            layout.x_of(window.lo)..=layout.x_of(window.hi),
            lane.y_range(),
        );
        painter.rect_filled(band, 2.0, tissue_colour(style.colour, alpha));
        let id = ui.id().with(("band", tissue as usize));
        let grips = [
            (
                Grip::Lo,
                Rect::from_center_size(
                    layout.handle(tissue, &window, false),
                    vec2(HANDLE_WIDTH, lane.height()),
                ),
            ),
            (
                Grip::Hi,
                Rect::from_center_size(
                    layout.handle(tissue, &window, true),
                    vec2(HANDLE_WIDTH, lane.height()),
                ),
            ),
            (Grip::Body, band.shrink2(vec2(HANDLE_WIDTH * 0.5, 0.0))),
        ];
        // Handles are registered after the body, so where they overlap (narrow bands) the
        // edges win.
        for (grip, rect) in grips.into_iter().rev() {
            if rect.width() <= 0.0 {
                continue;
            }
            let response = ui
                .interact(rect, id.with(grip as u8), Sense::drag())
                .on_hover_cursor(match grip {
                    Grip::Body => egui::CursorIcon::Grab,
                    _ => egui::CursorIcon::ResizeHorizontal,
                });
            if response.dragged()
                && let Some(pointer) = response.interact_pointer_pos()
            {
                let delta = response.drag_delta().x as f64 / layout.plot.width().max(1.0) as f64;
                let next = dragged(&window, grip, layout.value_of(pointer.x), delta);
                if next != window {
                    classification.style_mut(tissue).window = Some(next);
                    changed = true;
                }
            }
            if grip != Grip::Body {
                painter.rect_filled(
                    Rect::from_center_size(rect.center(), vec2(3.0, rect.height())),
                    1.0,
                    Color32::WHITE,
                );
            }
        }
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(lo: f64, hi: f64) -> Window {
        Window { lo, hi, edge: 0.01 }
    }

    #[test]
    fn edges_move_their_boundary_and_keep_a_minimum_width() {
        assert_eq!(dragged(&w(0.2, 0.4), Grip::Lo, 0.25, 0.0), w(0.25, 0.4));
        assert_eq!(dragged(&w(0.2, 0.4), Grip::Hi, 0.9, 0.0), w(0.2, 0.9));
        let squeezed = dragged(&w(0.2, 0.4), Grip::Lo, 0.7, 0.0);
        assert!((squeezed.lo - (0.4 - MIN_WIDTH)).abs() < 1e-12);
        let open = Window {
            lo: 0.8,
            hi: 1.02,
            edge: 0.02,
        };
        assert_eq!(
            dragged(&open, Grip::Hi, 1.0, 0.0),
            open,
            "open above stays open"
        );
        assert_eq!(dragged(&open, Grip::Hi, 0.9, 0.0).hi, 0.9);
    }

    #[test]
    fn the_body_moves_the_window_inside_zero_one() {
        let moved = dragged(&w(0.2, 0.4), Grip::Body, 0.0, 0.1);
        assert!((moved.lo - 0.3).abs() < 1e-12 && (moved.hi - 0.5).abs() < 1e-12);
        let clamped = dragged(&w(0.2, 0.4), Grip::Body, 0.0, 0.9);
        assert!((clamped.hi - 1.0).abs() < 1e-12 && (clamped.lo - 0.8).abs() < 1e-12);
    }

    #[test]
    fn layout_maps_values_and_lanes() {
        let layout = Layout::new(Rect::from_min_size(
            Pos2::new(10.0, 20.0),
            vec2(200.0, 300.0),
        ));
        assert_eq!(layout.x_of(0.5), 110.0);
        assert_eq!(layout.value_of(60.0), 0.25);
        assert_eq!(layout.value_of(-5.0), 0.0);
        assert!(layout.lane(TissueClass::Gm).top() > layout.lane(TissueClass::Csf).top());
        assert!(layout.lane(TissueClass::Csf).top() > layout.plot.bottom());
    }

    /// Drags the WM band's upper edge through real egui input events and checks the window.
    #[test]
    fn dragging_a_band_edge_in_egui_updates_the_window() {
        let ctx = egui::Context::default();
        let mut hist = [0u32; 256];
        for (i, h) in hist.iter_mut().enumerate() {
            *h = (i as u32 * 7) % 50 + 1;
        }
        let mut classification = Classification::with_windows([
            Some(w(0.1, 0.2)),
            Some(w(0.3, 0.5)),
            Some(w(0.6, 0.8)),
            None,
        ]);
        let screen = Rect::from_min_size(Pos2::ZERO, vec2(400.0, 400.0));
        let layout = std::cell::Cell::new(None);
        let frame = |events: Vec<egui::Event>, c: &mut Classification| {
            let input = egui::RawInput {
                screen_rect: Some(screen),
                events,
                ..Default::default()
            };
            ctx.run_ui(input, |ui| {
                egui::CentralPanel::no_frame().show(ui, |ui| {
                    layout.set(Some(Layout::new(Rect::from_min_size(
                        ui.cursor().min,
                        vec2(ui.available_width(), Layout::height()),
                    ))));
                    show(ui, &hist, None, c);
                });
            })
            .drop_without_applying_deltas();
        };
        frame(vec![], &mut classification);
        let layout = layout.get().unwrap();
        let start = layout.handle(TissueClass::Wm, &w(0.6, 0.8), true);
        let end = Pos2::new(layout.x_of(0.9), start.y);
        let press = |pos, pressed| egui::Event::PointerButton {
            pos,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: Default::default(),
        };
        frame(vec![egui::Event::PointerMoved(start)], &mut classification);
        frame(vec![press(start, true)], &mut classification);
        frame(
            vec![egui::Event::PointerMoved(Pos2::new(
                start.x + 10.0,
                start.y,
            ))],
            &mut classification,
        );
        frame(vec![egui::Event::PointerMoved(end)], &mut classification);
        frame(vec![press(end, false)], &mut classification);
        let wm = classification.style(TissueClass::Wm).window.unwrap();
        assert!(
            (wm.hi - 0.9).abs() < 0.01,
            "WM upper bound follows the mouse: {wm:?}"
        );
        assert_eq!(wm.lo, 0.6, "the lower bound stays");
        let gm = classification.style(TissueClass::Gm).window.unwrap();
        assert_eq!(gm, w(0.3, 0.5), "other tissues untouched");
    }
}
