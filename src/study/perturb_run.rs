//! Runs the perturbation study through the real GPU path and formats its table: for each
//! normalization mode, one engine; for each perturbed volume, `prepare` (upload, min/max or
//! robust range, normalization, histogram on the device) and `analyze` (the CPU peak finder),
//! then the peaks scored against the truths (`perturb_score`).
//!
//! Decisions:
//! - One engine per mode (the mode is engine configuration), reused across the six volumes, so
//!   pipelines are created once per sample kind.
//! - Only the whole-volume path is used (`Engine::prepare`): the study is about the analysis,
//!   and the volumes fit any device this runs on (the MNI152 template is 8.7 M voxels).
//! - The table prints physical values with one decimal: the template's range is 0-255 and the
//!   perturbations keep magnitudes between about -500 and 11000.
//! - The tissue fit's means (issue 28) are scored against the same truths as the peaks, in a
//!   second table: a fitted mean is what the windows follow when the fit is sound, so it must
//!   land in the bulk of its tissue just as a peak must. A fit that was not made is a miss.

use super::perturb::Perturbed;
use super::perturb_score::{Score, Totals, Truth, Truths, score, truths};
use crate::analysis::{ModeInfo, NormalizeMode, Peak};
use crate::engine::{Engine, EngineConfig};
use crate::gpu::GpuError;

/// One volume under one normalization mode.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Row {
    /// Perturbation name.
    pub volume: String,
    /// Normalization mode.
    pub mode: NormalizeMode,
    /// Physical range mapped to I_norm 0..1.
    pub imin: f64,
    /// ... its upper end.
    pub imax: f64,
    /// Peaks (I_norm) of CSF, GM, WM as found.
    pub norm_peaks: [Option<f64>; 3],
    /// Scores (physical peaks, truths, inside).
    pub score: Score,
    /// Scores of the tissue fit's means (physical units), against the same truths.
    pub fit_score: Score,
    /// Whether the fit was sound (its windows used) and its goodness, when a fit was made.
    pub fit_sound: Option<(bool, f64)>,
    /// Every significant mode the analysis found, with its role (why a tissue is missing).
    pub modes: Vec<ModeInfo>,
    /// The 256-bin histogram of I_norm the analysis saw.
    pub histogram: Vec<u32>,
}

/// Totals of one mode.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ModeTotals {
    /// Normalization mode.
    pub mode: NormalizeMode,
    /// Counts.
    pub totals: Totals,
    /// Whether the target holds.
    pub target_met: bool,
    /// Counts of the fitted means.
    pub fit_totals: Totals,
}

/// The whole study.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StudyReport {
    /// What the volumes were made from.
    pub input: String,
    /// One row per volume and mode (mode-major).
    pub rows: Vec<Row>,
    /// Totals per mode.
    pub totals: Vec<ModeTotals>,
}

/// Runs every volume through the GPU path under each of `modes`, with `base` for everything
/// else in the engine configuration.
pub fn run_study(
    input: &str,
    volumes: &[Perturbed],
    modes: &[NormalizeMode],
    base: &EngineConfig,
) -> Result<StudyReport, GpuError> {
    let all_truths: Vec<Truths> = volumes.iter().map(truths).collect();
    let mut rows = Vec::new();
    let mut totals = Vec::new();
    for &mode in modes {
        let mut engine = Engine::new(EngineConfig {
            normalize: mode,
            ..base.clone()
        })?;
        let mut scores = Vec::new();
        let mut fit_scores = Vec::new();
        for (p, t) in volumes.iter().zip(&all_truths) {
            let mut prepared = engine.prepare(&p.volume)?;
            // As `Engine::open_planned` does for a structural MR scan.
            prepared.leave_out_mask_edge(&p.volume);
            let report = engine.analyze(&prepared);
            let peaks = [report.peaks.csf, report.peaks.gm, report.peaks.wm];
            let s = score(peaks.map(|p| p.map(|p: Peak| p.raw)), t);
            scores.push(s);
            let fit = report.fit.as_ref();
            let fit_means = fit.map(|f| [f.csf, f.gm, f.wm].map(|c| Some(c.mean_raw)));
            let fit_score = score(fit_means.unwrap_or([None; 3]), t);
            fit_scores.push(fit_score);
            rows.push(Row {
                volume: p.kind.name().to_string(),
                mode,
                imin: report.imin,
                imax: report.imax,
                norm_peaks: peaks.map(|p| p.map(|p| p.norm)),
                score: s,
                fit_score,
                fit_sound: fit.map(|f| (f.sound, f.goodness)),
                modes: report.modes.clone(),
                histogram: prepared.histogram.to_vec(),
            });
        }
        let t = Totals::of(&scores);
        totals.push(ModeTotals {
            mode,
            totals: t,
            target_met: t.target_met(),
            fit_totals: Totals::of(&fit_scores),
        });
    }
    Ok(StudyReport {
        input: input.to_string(),
        rows,
        totals,
    })
}

fn cell(peak: Option<f64>, truth: Option<Truth>, inside: bool) -> String {
    let peak = peak.map_or("none".to_string(), |p| format!("{p:.1}"));
    let truth = truth.map_or("none".to_string(), |t| {
        format!("{:.1} to {:.1}", t.p10, t.p90)
    });
    let mark = if inside { "yes" } else { "**no**" };
    format!("{peak} | {truth} | {mark}")
}

/// The study as two markdown tables (the peaks, then the tissue fit's means; one row per volume
/// and mode) followed by the totals.
pub fn markdown(report: &StudyReport) -> String {
    let mut out = table(report, "peak", |r| &r.score);
    out.push('\n');
    out.push_str(&table(report, "fitted mean", |r| &r.fit_score));
    out.push('\n');
    for t in &report.totals {
        let n = t.totals.volumes;
        out.push_str(&format!(
            "- {}: peaks CSF {}/{n}, GM {}/{n}, WM {}/{n} inside; target (GM and WM on all, CSF on all but one) {}\n",
            t.mode.name(),
            t.totals.csf,
            t.totals.gm,
            t.totals.wm,
            if t.target_met { "met" } else { "NOT met" },
        ));
        let f = t.fit_totals;
        out.push_str(&format!(
            "- {}: fitted means CSF {}/{n}, GM {}/{n}, WM {}/{n} inside\n",
            t.mode.name(),
            f.csf,
            f.gm,
            f.wm,
        ));
    }
    out
}

/// One table of `what` (a peak or a fitted mean) per volume and mode, scored by `pick`.
fn table(report: &StudyReport, what: &str, pick: fn(&Row) -> &Score) -> String {
    let mut out = format!(
        "| volume | mode | CSF {what} | CSF truth (p10-p90) | in | GM {what} | GM truth | in | WM {what} | WM truth | in |\n"
    );
    out.push_str("|---|---|---:|---:|:-:|---:|---:|:-:|---:|---:|:-:|\n");
    for r in &report.rows {
        let s = pick(r);
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} |\n",
            r.volume,
            r.mode.name(),
            cell(s.csf.peak, s.csf.truth, s.csf.inside),
            cell(s.gm.peak, s.gm.truth, s.gm.inside),
            cell(s.wm.peak, s.wm.truth, s.wm.inside),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::perturb_score::TissueScore;

    #[test]
    fn the_table_marks_misses_and_totals() {
        let t = Truth {
            p10: 1.0,
            p90: 2.0,
            voxels: 3,
        };
        let hit = TissueScore {
            peak: Some(1.5),
            truth: Some(t),
            inside: true,
        };
        let miss = TissueScore {
            peak: None,
            truth: Some(t),
            inside: false,
        };
        let score = Score {
            csf: miss,
            gm: hit,
            wm: hit,
        };
        let report = StudyReport {
            input: "x".into(),
            rows: vec![Row {
                volume: "original".into(),
                mode: NormalizeMode::MinMax,
                imin: 0.0,
                imax: 1.0,
                norm_peaks: [None, Some(0.5), Some(0.6)],
                score,
                fit_score: score,
                fit_sound: None,
                modes: Vec::new(),
                histogram: Vec::new(),
            }],
            totals: vec![ModeTotals {
                mode: NormalizeMode::MinMax,
                totals: Totals::of(&[score]),
                target_met: Totals::of(&[score]).target_met(),
                fit_totals: Totals::of(&[score]),
            }],
        };
        let md = markdown(&report);
        assert!(
            md.contains(
                "| original | minmax | none | 1.0 to 2.0 | **no** | 1.5 | 1.0 to 2.0 | yes |"
            ),
            "{md}"
        );
        assert!(md.contains("peaks CSF 0/1, GM 1/1, WM 1/1 inside"), "{md}");
        assert!(
            md.contains("fitted means CSF 0/1, GM 1/1, WM 1/1 inside"),
            "{md}"
        );
        assert!(md.contains("| CSF fitted mean |"), "{md}");
        assert!(md.contains("met"), "{md}");
    }
}
