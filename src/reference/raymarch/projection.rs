//! The f64 twin of the raymarch's MIP and MinIP (the extreme along each ray in the display
//! window, `raymarch.comp`'s projection branch) and of its PICK variant (`pick`): the sample at
//! which a DVR ray's accumulated opacity reaches a threshold, or the first sample holding a
//! projection's extreme.

use super::{RayPlan, ReferenceRaymarch};

impl ReferenceRaymarch<'_> {
    pub(super) fn projection(&self, plan: &RayPlan) -> [f64; 4] {
        self.projection_picking(plan).0
    }

    /// The MIP/MinIP pixel and the ray parameter of the first sample holding the extreme (the
    /// shader's PICK).
    fn projection_picking(&self, plan: &RayPlan) -> ([f64; 4], Option<f64>) {
        let mip = self.is_mip();
        let mut found = false;
        let mut extreme: f64 = if mip { 0.0 } else { 1.0 };
        let mut at = None;
        for i in 0..plan.count {
            let v = self.value(plan.position(i));
            if mip {
                if v > extreme {
                    at = Some(plan.parameter(i));
                }
                extreme = extreme.max(v);
                found = true;
            } else if v >= self.minip_floor {
                if v < extreme {
                    at = Some(plan.parameter(i));
                }
                extreme = extreme.min(v);
                found = true;
            }
        }
        if !found {
            return (self.with_background([0.0; 4]), at);
        }
        let grey = self.display_position(extreme);
        let colour = match self.colormap {
            Some(map) => {
                let [r, g, b] = map.lookup(grey);
                [r, g, b, 1.0]
            }
            None => [grey, grey, grey, 1.0],
        };
        (colour, at)
    }

    /// Twin of the raymarch's PICK variant at pixel (x, y): the ray parameter (mm from the ray's
    /// origin) of the first sample at which the accumulated opacity reaches `threshold` (DVR),
    /// or of the first sample holding the ray's extreme (MIP/MinIP); None where the shader
    /// writes -1.
    pub fn pick(&self, x: u32, y: u32, threshold: f64) -> Option<f64> {
        let plan = self.ray(x, y);
        if self.is_dvr() {
            self.dvr_picking(&plan, Some(threshold)).1
        } else {
            self.projection_picking(&plan).1
        }
    }

    /// Where I_norm `v` falls in the display window, in [0, 1]: the grey level of MIP/MinIP and
    /// the colour map's input (`display_position` in `colormap.glsl`).
    pub(super) fn display_position(&self, v: f64) -> f64 {
        let [lo, hi] = self.intensity_window;
        ((v - lo) / (hi - lo).max(1e-6)).clamp(0.0, 1.0)
    }
}
