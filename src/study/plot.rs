//! The accuracy study's plot: error vs GPU time per setting (log-log), frontier drawn, as SVG.
//!
//! Decision: the SVG is drawn into a string, then written atomically (`files::write`), so a
//! failed draw or write never leaves a half-written plot over a previous one.

use plotters::prelude::*;

/// One point of the plot.
pub struct PlotPoint {
    /// Short label.
    pub label: String,
    /// GPU milliseconds per frame.
    pub time_ms: f64,
    /// Error (RMSE).
    pub error: f64,
    /// On the Pareto frontier.
    pub frontier: bool,
    /// The render/view default.
    pub default: bool,
}

/// A plot that could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Drawing failed (no plottable point, or the backend failed).
    #[error("cannot draw the accuracy plot {path}: {message}")]
    Draw {
        /// Output path.
        path: String,
        /// What failed.
        message: String,
    },
    /// The drawn plot could not be written.
    #[error(transparent)]
    Write(#[from] crate::files::write::OutputError),
}

/// Writes an SVG of `points` to `path`, atomically.
pub fn write_svg(
    path: &std::path::Path,
    title: &str,
    points: &[PlotPoint],
) -> Result<(), PlotError> {
    let mut svg = String::new();
    draw(&mut svg, title, points).map_err(|message| PlotError::Draw {
        path: path.display().to_string(),
        message,
    })?;
    Ok(crate::files::write::write_file(path, svg.as_bytes())?)
}

/// Draws the plot into `svg`.
fn draw(svg: &mut String, title: &str, points: &[PlotPoint]) -> Result<(), String> {
    let finite: Vec<&PlotPoint> = points
        .iter()
        .filter(|p| {
            p.time_ms > 0.0 && p.error > 0.0 && p.time_ms.is_finite() && p.error.is_finite()
        })
        .collect();
    if finite.is_empty() {
        return Err("no point with positive, finite time and error".into());
    }
    let (tmin, tmax) = finite.iter().fold((f64::MAX, 0.0f64), |(a, b), p| {
        (a.min(p.time_ms), b.max(p.time_ms))
    });
    let (emin, emax) = finite.iter().fold((f64::MAX, 0.0f64), |(a, b), p| {
        (a.min(p.error), b.max(p.error))
    });
    let root = SVGBackend::with_string(svg, (960, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(
            (tmin * 0.8..tmax * 1.25).log_scale(),
            (emin * 0.7..emax * 1.4).log_scale(),
        )
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("GPU time per frame (ms, log)")
        .y_desc("RMSE vs f64 reference (log)")
        .draw()
        .map_err(|e| e.to_string())?;
    let mut front: Vec<(f64, f64)> = finite
        .iter()
        .filter(|p| p.frontier)
        .map(|p| (p.time_ms, p.error))
        .collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    chart
        .draw_series(LineSeries::new(front, RED.stroke_width(2)))
        .map_err(|e| e.to_string())?
        .label("Pareto frontier")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    for p in &finite {
        let colour = if p.default {
            BLUE
        } else if p.frontier {
            RED
        } else {
            BLACK
        };
        let size = if p.default { 6 } else { 4 };
        chart
            .draw_series(std::iter::once(Circle::new(
                (p.time_ms, p.error),
                size,
                colour.filled(),
            )))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(std::iter::once(Text::new(
                p.label.clone(),
                (p.time_ms, p.error),
                ("sans-serif", 11),
            )))
            .map_err(|e| e.to_string())?;
    }
    chart
        .configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE.mix(0.8))
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())
}
