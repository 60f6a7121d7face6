//! The fitted tissue classes drawn over the histogram panel's bars (issue 28 item 5): each pure
//! class of the tissue fit (`analysis::tissue_fit`) as its Gaussian's expected counts per bin,
//! on the bars' log scale, in the tissue's colour.
//!
//! Decisions:
//! - Expected counts in the fitted histogram (`weight x voxels x` the bin's probability), so a
//!   class fitted inside the brain mask sits under the whole volume's bars by the share of the
//!   volume outside the brain: what the fit saw, not rescaled to look like the bars.
//! - Drawn only for a fit that set the windows or was rejected beside them (a rejected fit is
//!   dashed: the windows did not come from it).
//! - The bin probability is the normal density at the bin centre times the bin width (bins of
//!   1/256 are narrow next to every fitted SD, at least `MIN_SD_BINS`), a pure function tested
//!   against the fit's own weights.

use super::histogram::{Layout, tissue_colour};
use crate::analysis::{Fit, FittedClass};
use crate::scene::{Classification, TissueClass};
use egui::{Pos2, Shape, Stroke};

/// Expected counts per bin of one fitted class over `bins` bins of I_norm `[0, 1)`.
pub fn class_counts(class: &FittedClass, voxels: f64, bins: usize) -> Vec<f64> {
    let width = 1.0 / bins.max(1) as f64;
    let sd = class.sd.max(1e-9);
    (0..bins)
        .map(|b| {
            let x = (b as f64 + 0.5) * width;
            let z = (x - class.mean) / sd;
            let density = (-0.5 * z * z).exp() / (sd * (2.0 * std::f64::consts::PI).sqrt());
            class.weight * voxels * density * width
        })
        .collect()
}

/// Draws `fit`'s three classes over the plot of `layout`, with the bars' log `scale`
/// (`ln(1 + max count)`).
pub fn draw(
    painter: &egui::Painter,
    layout: &Layout,
    fit: &Fit,
    rejected: bool,
    scale: f64,
    classification: &Classification,
) {
    let classes = [
        (&fit.csf, TissueClass::Csf),
        (&fit.gm, TissueClass::Gm),
        (&fit.wm, TissueClass::Wm),
    ];
    let bins = 256;
    let bin_width = layout.plot.width() / bins as f32;
    for (class, tissue) in classes {
        let counts = class_counts(class, fit.voxels, bins);
        let points: Vec<Pos2> = counts
            .iter()
            .enumerate()
            .map(|(b, &n)| {
                let h = ((1.0 + n).ln() / scale.max(1e-9)) as f32 * (layout.plot.height() - 4.0);
                Pos2::new(
                    layout.plot.left() + (b as f32 + 0.5) * bin_width,
                    layout.plot.bottom() - h,
                )
            })
            .collect();
        let stroke = Stroke::new(1.5, tissue_colour(classification.style(tissue).colour, 255));
        if rejected {
            painter.extend(Shape::dashed_line(&points, stroke, 4.0, 3.0));
        } else {
            painter.add(Shape::line(points, stroke));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_class_holds_its_weight_of_the_fitted_voxels_around_its_mean() {
        let class = FittedClass {
            mean: 0.4,
            sd: 0.03,
            weight: 0.3,
            mean_raw: 0.0,
            sd_raw: 0.0,
        };
        let counts = class_counts(&class, 10_000.0, 256);
        let total: f64 = counts.iter().sum();
        assert!((total - 3000.0).abs() < 1.0, "{total}");
        let peak = counts
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(b, _)| b)
            .unwrap_or(0);
        assert_eq!(peak, (0.4 * 256.0) as usize, "the bin holding the mean");
    }
}
