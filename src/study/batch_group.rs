//! The group level of a cohort batch (`morphray batch BIDS_DIR OUT_DIR group`): a TSV of every
//! scan's Table-1 row and a static HTML report (the table, the peaks' distributions as SVG, the
//! thumbnails, the failures), built from the participant outputs alone (no device, no input
//! scan is read), so it runs anywhere once the shards are done.
//!
//! Decisions:
//! - Inputs are the `desc-peaks` summaries and `desc-error` records under OUT_DIR, found by
//!   walking it (not from the logs, which a rerun appends to): what is on disk is the state.
//! - The TSV's columns are the Table-1 row's fields (sorted by name) after the scan's
//!   identity, so a new field appears without a change here; missing values are `n/a` (BIDS).
//! - The HTML is one self-contained file: inline SVG, the thumbnails embedded as `data:` URIs
//!   (base64 PNG), no script or network, so the file alone can be mailed or archived; the PNGs
//!   stay beside it for other tools.
//! - Each scan's quality flags (`batch_qc`: blank picture, fallback windows, brain not found,
//!   no windows, contrast guessed) are a column of both; a flagged row is marked in the HTML.

use super::batch_outputs::group_dir;
use crate::files::write::{OutputError, write_file};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What the group level found and wrote.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct GroupReport {
    /// Scans with a summary.
    pub scans: usize,
    /// Scans with a failure record.
    pub failures: usize,
    /// The TSV.
    pub tsv: PathBuf,
    /// The HTML report.
    pub html: PathBuf,
}

/// Why the group level could not run.
#[derive(Debug, thiserror::Error)]
pub enum GroupError {
    /// OUT_DIR could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The folder or file.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A summary that is not JSON.
    #[error(
        "{path} is not a summary written by morphray ({message}); remove it and rerun the participant level"
    )]
    BadRecord {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// Nothing to report.
    #[error(
        "{0} has no participant outputs (sub-*/**/*_desc-peaks_*.json): run the participant level first"
    )]
    Empty(String),
    /// The report could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// One participant output read back.
struct Record {
    /// Relative to OUT_DIR, `/`-separated.
    relative_dir: String,
    value: Value,
}

fn walk(dir: &Path, found: &mut Vec<PathBuf>) -> Result<(), GroupError> {
    let io = |source| GroupError::Io {
        path: dir.display().to_string(),
        source,
    };
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            walk(&path, found)?;
        } else {
            found.push(path);
        }
    }
    Ok(())
}

/// The summaries and failure records under `out`'s `sub-*` folders.
fn read_records(out: &Path) -> Result<(Vec<Record>, Vec<Record>), GroupError> {
    let mut files = Vec::new();
    let subjects = std::fs::read_dir(out).map_err(|source| GroupError::Io {
        path: out.display().to_string(),
        source,
    })?;
    let mut dirs: Vec<PathBuf> = subjects
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_dir()
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with("sub-"))
        })
        .collect();
    dirs.sort();
    for dir in dirs {
        walk(&dir, &mut files)?;
    }
    let (mut summaries, mut failures) = (Vec::new(), Vec::new());
    for path in files {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let list = if name.contains("_desc-peaks_") && name.ends_with(".json") {
            &mut summaries
        } else if name.contains("_desc-error_") && name.ends_with(".json") {
            &mut failures
        } else {
            continue;
        };
        let text = std::fs::read_to_string(&path).map_err(|source| GroupError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let value: Value = serde_json::from_str(&text).map_err(|e| GroupError::BadRecord {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let relative_dir = path
            .parent()
            .and_then(|p| p.strip_prefix(out).ok())
            .map(|p| p.to_string_lossy().replace('\\', "/"))
            .unwrap_or_default();
        list.push(Record {
            relative_dir,
            value,
        });
    }
    Ok((summaries, failures))
}

fn cell(value: Option<&Value>) -> String {
    match value {
        None | Some(Value::Null) => "n/a".into(),
        Some(Value::String(s)) => s.replace(['\t', '\n', '\r'], " "),
        Some(v) => v.to_string(),
    }
}

/// The TSV: identity columns, then the Table-1 row's fields, then the contrast and warnings.
fn tsv(summaries: &[Record]) -> String {
    let columns: Vec<String> = summaries
        .first()
        .and_then(|r| r.value.get("table1"))
        .and_then(Value::as_object)
        .map(|m| m.keys().cloned().collect())
        .unwrap_or_default();
    let mut text = String::from("scan\tsubject\tsession\tsuffix");
    for c in &columns {
        text.push('\t');
        text.push_str(c);
    }
    text.push_str("\tcontrast\tcontrast_basis\tqc\twarnings\n");
    for r in summaries {
        let v = &r.value;
        let mut row = vec![
            cell(v.get("file")),
            cell(v.get("subject")),
            cell(v.get("session")),
            cell(v.get("suffix")),
        ];
        for c in &columns {
            row.push(cell(v.get("table1").and_then(|t| t.get(c))));
        }
        row.push(cell(v.get("contrast").and_then(|c| c.get("contrast"))));
        row.push(cell(v.get("contrast").and_then(|c| c.get("basis"))));
        row.push(qc_cell(v));
        let warnings = v
            .get("warnings")
            .and_then(Value::as_array)
            .map_or(0, Vec::len);
        row.push(warnings.to_string());
        text.push_str(&row.join("\t"));
        text.push('\n');
    }
    text
}

/// Escapes text for HTML.
fn esc(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn number(v: Option<&Value>) -> Option<f64> {
    v.and_then(Value::as_f64).filter(|x| x.is_finite())
}

/// An SVG strip plot with a 20-bin histogram of `values` on I_norm 0..1.
fn distribution_svg(title: &str, values: &[f64], colour: &str) -> String {
    let (w, h, left, bottom) = (360.0, 140.0, 30.0, 24.0);
    let plot_w = w - left - 10.0;
    let x = |v: f64| left + v.clamp(0.0, 1.0) * plot_w;
    let mut bins = [0usize; 20];
    for v in values {
        bins[((v.clamp(0.0, 1.0) * 20.0) as usize).min(19)] += 1;
    }
    let top = bins.iter().copied().max().unwrap_or(0).max(1) as f64;
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" role=\"img\">\
         <title>{}</title><text x=\"{left}\" y=\"14\" font-size=\"12\">{} (n = {})</text>",
        esc(title),
        esc(title),
        values.len()
    );
    let base = h - bottom;
    for (i, &count) in bins.iter().enumerate() {
        let bar = (count as f64 / top) * (base - 40.0);
        let _ = write!(
            svg,
            "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"{:.1}\" height=\"{bar:.1}\" fill=\"{colour}\" \
             fill-opacity=\"0.35\"/>",
            x(i as f64 / 20.0),
            base - 12.0 - bar,
            plot_w / 20.0 - 1.0
        );
    }
    for v in values {
        let _ = write!(
            svg,
            "<line x1=\"{0:.1}\" x2=\"{0:.1}\" y1=\"{1:.1}\" y2=\"{2:.1}\" stroke=\"{colour}\"/>",
            x(*v),
            base - 10.0,
            base
        );
    }
    let _ = write!(
        svg,
        "<line x1=\"{left}\" x2=\"{:.1}\" y1=\"{base}\" y2=\"{base}\" stroke=\"black\"/>",
        left + plot_w
    );
    for tick in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let _ = write!(
            svg,
            "<text x=\"{:.1}\" y=\"{:.1}\" font-size=\"10\" text-anchor=\"middle\">{tick}</text>",
            x(tick),
            h - 8.0
        );
    }
    svg.push_str("</svg>");
    svg
}

/// A summary's quality flags as one cell (`ok`; `n/a` for a summary written before them).
fn qc_cell(v: &Value) -> String {
    match v.get("qc").and_then(Value::as_array) {
        Some(flags) => {
            let flags: Vec<String> = flags
                .iter()
                .filter_map(|f| f.as_str().map(str::to_string))
                .collect();
            super::batch_qc::cell(&flags)
        }
        None => "n/a".into(),
    }
}

/// A thumbnail as a `data:` URI, read from `out`; None when it cannot be read (the cell then
/// says so instead of showing a broken image).
fn embedded(out: &Path, relative_dir: &str, name: &str) -> Option<String> {
    let bytes = std::fs::read(out.join(relative_dir).join(name)).ok()?;
    Some(format!(
        "data:image/png;base64,{}",
        crate::files::base64::encode(&bytes)
    ))
}

fn fmt(v: Option<f64>) -> String {
    v.map_or("n/a".into(), |x| format!("{x:.4}"))
}

/// The HTML report.
fn html(out: &Path, summaries: &[Record], failures: &[Record]) -> String {
    let mut page = String::from(
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>morphray group report</title>\
         <style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}\
         td,th{border:1px solid #ccc;padding:2px 6px;font-size:13px}\
         img{width:128px;height:128px;background:#000}.fail{color:#a00}\
         tr.flagged td{background:#fff3cd}</style></head><body>",
    );
    let _ = write!(
        page,
        "<h1>morphray group report</h1><p>{} scans, {} failed. Peaks in I_norm (the \
         rendered normalization); the TSV beside this file has every column.</p>",
        summaries.len(),
        failures.len()
    );
    page.push_str("<h2>Tissue peaks across scans</h2><div>");
    for (tissue, colour) in [("csf", "#1f77b4"), ("gm", "#7f7f7f"), ("wm", "#d62728")] {
        let values: Vec<f64> = summaries
            .iter()
            .filter_map(|r| number(r.value.pointer(&format!("/table1/{tissue}_norm"))))
            .collect();
        page.push_str(&distribution_svg(
            &format!("{} peak, I_norm", tissue.to_uppercase()),
            &values,
            colour,
        ));
    }
    page.push_str(
        "</div><h2>Table 1 across scans</h2><table><tr><th>scan</th><th>Imin</th>\
                   <th>Imax</th><th>CSF</th><th>GM</th><th>WM</th><th>contrast</th>\
                   <th>quality</th><th>anterior</th><th>lateral</th><th>superior</th></tr>",
    );
    for r in summaries {
        let v = &r.value;
        let t = |k: &str| number(v.pointer(&format!("/table1/{k}")));
        let qc = qc_cell(v);
        let flagged = if qc == "ok" { "" } else { " class=\"flagged\"" };
        let _ = write!(
            page,
            "<tr{flagged}><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{} ({})</td><td>{}</td>",
            esc(&cell(v.get("file"))),
            fmt(t("imin")),
            fmt(t("imax")),
            fmt(t("csf_norm")),
            fmt(t("gm_norm")),
            fmt(t("wm_norm")),
            esc(&cell(v.pointer("/contrast/contrast"))),
            esc(&cell(v.pointer("/contrast/basis"))),
            esc(&qc)
        );
        let thumbs = v
            .get("thumbnails")
            .and_then(Value::as_array)
            .cloned()
            .unwrap_or_default();
        for i in 0..3 {
            let name = thumbs.get(i).and_then(Value::as_str);
            match name.map(|n| (n, embedded(out, &r.relative_dir, n))) {
                Some((name, Some(uri))) => {
                    let _ = write!(page, "<td><img src=\"{uri}\" alt=\"{}\"></td>", esc(name));
                }
                Some((name, None)) => {
                    let _ = write!(page, "<td class=\"fail\">{} missing</td>", esc(name));
                }
                None => page.push_str("<td>-</td>"),
            }
        }
        page.push_str("</tr>");
    }
    page.push_str("</table><h2>Failures</h2>");
    if failures.is_empty() {
        page.push_str("<p>None.</p>");
    } else {
        page.push_str("<table><tr><th>scan</th><th>error</th></tr>");
        for f in failures {
            let _ = write!(
                page,
                "<tr class=\"fail\"><td>{}</td><td>{}</td></tr>",
                esc(&cell(f.value.get("scan"))),
                esc(&cell(f.value.get("error")))
            );
        }
        page.push_str("</table>");
    }
    page.push_str("</body></html>\n");
    page
}

/// Runs the group level over `out` (module doc).
pub fn run_group(out: &Path) -> Result<GroupReport, GroupError> {
    let (summaries, failures) = read_records(out)?;
    if summaries.is_empty() && failures.is_empty() {
        return Err(GroupError::Empty(out.display().to_string()));
    }
    let dir = group_dir(out);
    std::fs::create_dir_all(&dir).map_err(|e| OutputError::io(&dir, e))?;
    let report = GroupReport {
        scans: summaries.len(),
        failures: failures.len(),
        tsv: dir.join("morphray_table1.tsv"),
        html: dir.join("morphray_report.html"),
    };
    write_file(&report.tsv, tsv(&summaries).as_bytes())?;
    write_file(&report.html, html(out, &summaries, &failures).as_bytes())?;
    Ok(report)
}
