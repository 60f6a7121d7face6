//! Words and numbers the viewer shows: what a set of derived volumes is, a peak, a file's
//! label, the 3D view's rectangle in pixels, and the scripted log's layout line.

use crate::passes::derivatives::DerivativeOutputs;

/// What a set of derived volumes is, for the status line.
pub(super) fn describe(outputs: DerivativeOutputs) -> String {
    let mut parts = Vec::new();
    if outputs.magnitude {
        parts.push("gradient magnitude");
    }
    if outputs.curvature {
        parts.push("curvature");
    }
    if outputs.normal {
        parts.push("normals");
    }
    if parts.is_empty() {
        parts.push("gradient maximum");
    }
    let mut text = format!("{} volume", parts.join(" + "));
    if outputs.vesselness {
        text += " + vesselness";
    }
    if outputs.brain != crate::passes::brain::BrainSwitch::Off {
        text += " + brain mask";
    }
    text
}

pub(super) fn peak_text(peak: Option<crate::analysis::Peak>) -> String {
    peak.map(|p| format!("{:.3}", p.norm))
        .unwrap_or_else(|| "-".into())
}

/// A rectangle in points as whole pixels (x, y, w, h) inside a frame of `size` pixels.
pub fn px_rect(rect: egui::Rect, ppp: f32, size: [u32; 2]) -> [u32; 4] {
    let x0 = (rect.left() * ppp).round().clamp(0.0, size[0] as f32) as u32;
    let y0 = (rect.top() * ppp).round().clamp(0.0, size[1] as f32) as u32;
    let x1 = (rect.right() * ppp).round().clamp(0.0, size[0] as f32) as u32;
    let y1 = (rect.bottom() * ppp).round().clamp(0.0, size[1] as f32) as u32;
    [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)]
}

impl super::Viewer {
    /// Layout facts for the scripted log: the view and histogram rectangles in pixels, and the
    /// orientation letters with their positions.
    pub fn layout_line(&self) -> String {
        let ppp = self.ctx.pixels_per_point();
        let view = px_rect(self.view_rect_points(), ppp, self.size);
        let hist = self
            .ctx
            .memory(|m| {
                m.data
                    .get_temp::<egui::Rect>(egui::Id::new("morphray histogram rect"))
            })
            .map(|r| px_rect(r, ppp, self.size))
            .unwrap_or([0; 4]);
        let letters = crate::app::camera_control::edge_labels(&self.controls.scene.camera);
        format!(
            "layout: view {},{},{},{} histogram {},{},{},{} letters left {} right {} top {} bottom {}",
            view[0],
            view[1],
            view[2],
            view[3],
            hist[0],
            hist[1],
            hist[2],
            hist[3],
            letters.left,
            letters.right,
            letters.top,
            letters.bottom
        ) + &self.slices_layout(ppp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_volumes_are_described_for_the_status_line() {
        let o = |magnitude, curvature, normal| DerivativeOutputs {
            magnitude,
            curvature,
            normal,
            precision: Default::default(),
            vesselness: false,
            brain: crate::passes::brain::BrainSwitch::Off,
        };
        assert_eq!(
            describe(o(true, true, false)),
            "gradient magnitude + curvature volume"
        );
        let brain = DerivativeOutputs {
            brain: crate::passes::brain::BrainSwitch::Auto,
            ..o(true, false, false)
        };
        assert_eq!(describe(brain), "gradient magnitude volume + brain mask");
    }

    #[test]
    fn view_rectangles_become_pixels_inside_the_frame() {
        let r = egui::Rect::from_min_max(egui::pos2(300.0, 0.0), egui::pos2(640.0, 420.5));
        assert_eq!(px_rect(r, 1.0, [640, 480]), [300, 0, 340, 421]);
        assert_eq!(px_rect(r, 2.0, [1280, 960]), [600, 0, 680, 841]);
        assert_eq!(px_rect(r, 1.0, [500, 400]), [300, 0, 200, 400]);
    }
}
