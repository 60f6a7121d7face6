//! One DVR sample of the f64 twin: classification, derivatives, the opacity of eq. 4 (with the
//! curvature weight and a cut face's cap), opacity correction and lighting, in the shader's
//! order (`tissue_sample` and `classify_at` in raymarch.comp).

use super::ReferenceRaymarch;
use super::formulas::{
    curvature_weight, curvature_with, gradient_central_with, gradient_sobel_with, opacity_correct,
    opacity_correct_naive,
};
use super::sampling::Grid;
use crate::scene::{CurvatureMode, GradientFilter};
use glam::DVec3;

/// The intermediate values of one DVR sample, named as in the shader's loop body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DvrSample {
    /// Trilinear I_norm `v`.
    pub value: f64,
    /// `f(v)`, in (0, 1].
    pub f: f64,
    /// `C_s(v)`, before shading.
    pub colour: [f64; 3],
    /// |grad I| per mm (precomputed and interpolated, or on the fly).
    pub magnitude: f64,
    /// Curvature k per mm^2 (0 unless the curvature effect is on).
    pub curvature: f64,
    /// Shading normal, not normalized (0 unless shading is on, or where |g| <= tau on the fly).
    pub normal: DVec3,
    /// Opacity of eq. 4 for one voxel of step: `clamp(f |g| / |g|max, 0, 1)`, times `w(k)` and
    /// capped at 1 when the curvature effect is on.
    pub opacity: f64,
    /// `opacity` corrected for the step (`opacity_correct(opacity, r)`): what is composited.
    pub corrected: f64,
    /// The colour composited (shaded when shading is on).
    pub shaded: [f64; 3],
}

impl ReferenceRaymarch<'_> {
    /// |g|, k and the shading normal at `p` (k and the normal are 0 when their effect is off).
    pub(super) fn derivatives(&self, p: DVec3, v: f64) -> (f64, f64, DVec3) {
        let m = self.geometry.gradient_to_world;
        let sample = |q: DVec3| self.value(q);
        let (magnitude, mut normal, central) = if self.on_the_fly {
            let g = match self.gradient_filter {
                GradientFilter::Central => gradient_central_with(&sample, m, p),
                GradientFilter::Sobel => gradient_sobel_with(&sample, m, p),
            };
            let magnitude = g.length();
            let normal = if magnitude > self.tau {
                g / magnitude
            } else {
                DVec3::ZERO
            };
            let central = (self.gradient_filter == GradientFilter::Central).then_some(g);
            (magnitude, normal, central)
        } else {
            let scalar = |grid: Option<Grid<'_, f64>>| {
                grid.map_or(0.0, |g| g.fetch(p, |v| [v], self.interpolation)[0])
            };
            let normal = match self.normals {
                Some(grid) => DVec3::from_array(grid.fetch(p, |n| n, self.interpolation)),
                None => DVec3::ZERO,
            };
            (scalar(self.gradient_magnitude), normal, None)
        };
        let k = match self.curvature_mode {
            CurvatureMode::Off => 0.0,
            CurvatureMode::Stored => self
                .curvature
                .map_or(0.0, |g| g.fetch(p, |v| [v], self.interpolation)[0]),
            CurvatureMode::OnTheFly => {
                let g = central.unwrap_or_else(|| gradient_central_with(&sample, m, p));
                curvature_with(&sample, m, self.tau, p, v, g)
            }
        };
        if !self.shading {
            normal = DVec3::ZERO;
        }
        (magnitude, k, normal)
    }

    /// The DVR terms of one sample at index position `p` seen along the unit world direction
    /// `view_direction`, or None where the shader skips it (`f(v) <= 0`). For finding out why a
    /// GPU pixel differs: every intermediate of the shader's loop body.
    pub fn dvr_sample(&self, p: DVec3, view_direction: DVec3) -> Option<DvrSample> {
        self.dvr_sample_with(p, view_direction, self.opacity_exponent, false)
    }

    /// [`ReferenceRaymarch::dvr_sample`] with opacity exponent `r` (a long step's is larger).
    pub(super) fn dvr_sample_with(
        &self,
        p: DVec3,
        view_direction: DVec3,
        r: f64,
        solid: bool,
    ) -> Option<DvrSample> {
        let value = self.value(p);
        let (f, mut colour) = self.classify_at(p, value);
        if f <= 0.0 {
            return None;
        }
        if let Some(map) = self.colormap {
            colour = map.lookup(self.display_position(value));
        }
        let (magnitude, curvature, mut normal) = self.derivatives(p, value);
        let mut opacity = (f * magnitude * self.inv_max_magnitude).clamp(0.0, 1.0);
        if self.curvature_on {
            opacity = (opacity * curvature_weight(curvature, self.curvature_strength, self.k_ref))
                .min(1.0);
        }
        if solid {
            // A cut face's cap, as the shader: the window's opacity, the colour unshaded.
            opacity = opacity.max(f.min(1.0));
            normal = DVec3::ZERO;
        }
        let corrected = if self.naive_opacity {
            opacity_correct_naive(opacity, r)
        } else {
            opacity_correct(opacity, r)
        };
        let shaded = if self.shading {
            self.lit(colour, normal, view_direction)
        } else {
            colour
        };
        Some(DvrSample {
            value,
            f,
            colour,
            magnitude,
            curvature,
            normal,
            opacity,
            corrected,
            shaded,
        })
    }

    /// f(v) and the mean colour of the sample at `p` with I_norm `value`, as the march
    /// classifies it (brain mask, vessel channel, table).
    pub(super) fn classify_at(&self, p: DVec3, value: f64) -> (f64, [f64; 3]) {
        let vessels = self
            .vesselness
            .filter(|_| self.vessels_on)
            .map(|grid| grid.fetch(p, |v| [v], self.interpolation)[0]);
        let nearest = self.interpolation == crate::scene::Interpolation::Nearest;
        let brain = self
            .brain_mask
            .map(|mask| mask.at([p.x, p.y, p.z], nearest));
        match &self.table {
            Some(table) => table.classify_masked(&self.classification, value, vessels, brain),
            None => self.classification.classify_masked(value, vessels, brain),
        }
    }
}
