//! `morphray info`: what a NIfTI file holds, without touching the GPU.

use super::args::InfoArgs;
use super::output::{json, print_line};
use super::source;
use crate::error::Error;
use crate::volume::stats::intensity_stats;

/// The JSON document of `info --json`.
#[derive(serde::Serialize)]
struct InfoReport<'a> {
    file: &'a str,
    version: String,
    byte_order: String,
    datatype: &'static str,
    bitpix: i16,
    dims: Vec<usize>,
    frames: usize,
    frame_loaded: usize,
    spacing_mm: [f64; 3],
    affine: [[f64; 4]; 4],
    affine_source: crate::volume::AffineSource,
    scl_slope: f64,
    scl_inter: f64,
    imin: Option<f64>,
    imax: Option<f64>,
    finite_voxels: usize,
    nonfinite_voxels: usize,
    gzip: bool,
    gzip_members: usize,
    description: &'a str,
    warnings: &'a [String],
}

/// Runs the command.
pub fn run(args: &InfoArgs) -> Result<(), Error> {
    let source = source::load(Some(&args.file), args.frame, false)?;
    let Some(header) = &source.header else {
        return Err(Error::Usage("info needs a file".into()));
    };
    let v = &source.volume;
    let stats = intensity_stats(v);
    let report = InfoReport {
        file: &source.label,
        version: format!("{:?}", header.version),
        byte_order: format!("{:?}", header.byte_order),
        datatype: header.datatype.name(),
        bitpix: header.bitpix,
        dims: header.dims.clone(),
        frames: header.frames,
        frame_loaded: header.frame_loaded,
        spacing_mm: v.spacing_mm,
        affine: v.orientation.affine,
        affine_source: v.orientation.source,
        scl_slope: header.scl_slope,
        scl_inter: header.scl_inter,
        imin: stats.imin,
        imax: stats.imax,
        finite_voxels: stats.finite,
        nonfinite_voxels: stats.nonfinite,
        gzip: header.gzip,
        gzip_members: header.gzip_members,
        description: &header.description,
        warnings: &v.warnings,
    };
    if args.json {
        print_line(&json(&report));
        return Ok(());
    }
    let dims: Vec<String> = report.dims.iter().map(|d| d.to_string()).collect();
    let range = match (stats.imin, stats.imax) {
        (Some(lo), Some(hi)) => format!("{lo} .. {hi}"),
        _ => "no finite voxel".to_string(),
    };
    print_line(&format!("file          {}", report.file));
    print_line(&format!(
        "format        {} ({}, {}{})",
        report.version,
        report.byte_order,
        if report.gzip { "gzip" } else { "uncompressed" },
        if report.gzip_members > 1 {
            format!(", {} members", report.gzip_members)
        } else {
            String::new()
        }
    ));
    print_line(&format!(
        "datatype      {} (bitpix {})",
        report.datatype, report.bitpix
    ));
    print_line(&format!(
        "dims          {} ({} frame(s), showing frame {})",
        dims.join(" x "),
        report.frames,
        report.frame_loaded
    ));
    print_line(&format!(
        "spacing       {:.4} x {:.4} x {:.4} mm",
        report.spacing_mm[0], report.spacing_mm[1], report.spacing_mm[2]
    ));
    print_line(&format!("affine        from {:?}", report.affine_source));
    for row in &report.affine {
        print_line(&format!(
            "              [{:>10.4} {:>10.4} {:>10.4} {:>10.4}]",
            row[0], row[1], row[2], row[3]
        ));
    }
    print_line(&format!(
        "scaling       slope {} intercept {}",
        report.scl_slope, report.scl_inter
    ));
    print_line(&format!("intensity     {range} (physical, finite voxels)"));
    print_line(&format!(
        "non-finite    {} of {} voxels",
        report.nonfinite_voxels,
        report.finite_voxels + report.nonfinite_voxels
    ));
    if !report.description.is_empty() {
        print_line(&format!("description   {}", report.description));
    }
    if report.warnings.is_empty() {
        print_line("warnings      none");
    } else {
        for w in report.warnings {
            print_line(&format!("warning       {w}"));
        }
    }
    Ok(())
}
