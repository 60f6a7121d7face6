//! `morphray info`: what a NIfTI file or a DICOM input holds, without touching the GPU.
//!
//! Decisions: for DICOM input the report lists every stack of every series (what `--series`
//! can pick), which one commands pick by default and why, the files left out, and then the
//! chosen volume as it would be opened (decoded, so its intensity range is known). When no
//! series qualifies as the default, the listing is still printed (it is what the user needs to
//! choose one) and the command fails after it.
//!
//! What the scan is: the modality and the contrast with their basis and reason (`identity`),
//! decided as the engine decides them (`analysis::modality`, with `--modality` and
//! `--contrast`), and the facts they came from. When only the histogram can tell the contrast,
//! `info` computes it on the CPU (the robust range, or eq. 1 with `--normalize minmax`, and the
//! 256-bin histogram), up to [`HOST_HISTOGRAM_VOXELS`] voxels; above that it says that the
//! histogram decides when the volume is opened (`morphray peaks` shows it).

use super::args::InfoArgs;
use super::output::{json, print_line};
use super::source;
use crate::analysis::{ContrastReport, ModalityReport, ScanFacts};
use crate::error::Error;
use crate::volume::Volume;
use crate::volume::source::InputError;
use crate::volume::stats::intensity_stats;

/// Most voxels whose histogram `info` computes on the CPU (the exact robust range sorts them:
/// 16 M values are 128 MB and about 2 s on this machine's class of CPU).
pub const HOST_HISTOGRAM_VOXELS: usize = 16 << 20;

/// What the scan is, and from what (`info`'s `identity`).
#[derive(serde::Serialize)]
struct Identity<'a> {
    modality: ModalityReport,
    /// None when only the histogram can tell and the volume is too large for the CPU here.
    contrast: Option<ContrastReport>,
    /// The foreground shown when no tissue class is found (`analysis::fallback`).
    fallback: Option<crate::analysis::Fallback>,
    facts: &'a ScanFacts,
}

/// The modality and contrast of `v` as the engine would decide them (module doc).
fn identity<'a>(v: &'a Volume, global: &super::GlobalOptions) -> Identity<'a> {
    let params = crate::analysis::AnalysisParams {
        contrast: global.contrast,
        modality: global.modality,
        ..Default::default()
    };
    let values = crate::volume::stats::value_summary(v);
    let id = crate::analysis::identify(&v.facts, Some(&values), params.modality, params.contrast);
    let modality = id.modality.clone();
    if v.samples.len() > HOST_HISTOGRAM_VOXELS {
        let contrast = id.contrast.clone().map(|c| id.contrast_or_else(|| c));
        return Identity {
            modality,
            contrast,
            fallback: None,
            facts: &v.facts,
        };
    }
    let range = match global.normalize {
        crate::analysis::NormalizeMode::Robust
        | crate::analysis::NormalizeMode::RobustProjection => {
            crate::analysis::range::exact_robust_range(&v.samples, v.to_physical)
                .map(|r| (r.lo, r.hi))
        }
        crate::analysis::NormalizeMode::MinMax => {
            let s = intensity_stats(v);
            s.imin.zip(s.imax)
        }
    };
    let (lo, hi) = range.unwrap_or((0.0, 0.0));
    let hist = crate::reference::histogram_of_samples(&v.samples, v.to_physical, lo, hi);
    let report =
        crate::analysis::analyze_identified(&hist, lo, hi, v.samples.len(), 0, &params, &id);
    Identity {
        modality,
        contrast: Some(report.contrast),
        fallback: report.fallback,
        facts: &v.facts,
    }
}

/// The text lines of [`Identity`].
fn print_identity(id: &Identity) {
    print_line(&format!("modality      {}", id.modality.summary()));
    match &id.contrast {
        Some(c) => print_line(&format!("contrast      {}", c.summary())),
        None => print_line(
            "contrast      decided by the histogram when the volume is opened (`morphray peaks` \
             shows it)",
        ),
    }
    if let Some(f) = &id.fallback {
        print_line(&format!("fallback      {}", f.reason));
    }
    let f = id.facts;
    let ms = |name: &str, v: Option<f64>| v.map(|v| format!("{name} {v} ms"));
    let times: Vec<String> = [
        ms("TR", f.repetition_time_ms),
        ms("TE", f.echo_time_ms),
        ms("TI", f.inversion_time_ms),
    ]
    .into_iter()
    .flatten()
    .collect();
    if !times.is_empty() {
        print_line(&format!("timing        {}", times.join(", ")));
    }
    if !f.sources.is_empty() {
        print_line(&format!("metadata      {}", f.sources.join(", ")));
    }
}

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
    /// A large single-member .gz: inflation cannot be split across threads (a hint is shown).
    #[serde(skip)]
    one_thread_inflate: bool,
    description: &'a str,
    /// What the scan is (modality, contrast), and from what.
    identity: Identity<'a>,
    warnings: &'a [String],
}

/// Samples of a single-member .gz above which `info` suggests a multi-member copy: 64 MiB
/// inflate in about 0.2 s on one thread of the H100 machine (740 ms for 268 MB,
/// benches/results/h100-2026-11-24-streamed) and in a tenth of that on 16.
const SLOW_SINGLE_MEMBER: usize = 64 << 20;

/// Runs the command.
pub fn run(args: &InfoArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let first = args
        .file
        .first()
        .ok_or_else(|| Error::Usage("info needs a file".into()))?;
    if args.file.len() > 1 || crate::volume::source::reader_for(first).name() == "DICOM" {
        return run_dicom(args, global);
    }
    let source = source::load(&args.file, args.frame, false)?;
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
        one_thread_inflate: header.gzip
            && header.gzip_members == 1
            && v.samples.as_bytes().len() >= SLOW_SINGLE_MEMBER,
        description: &header.description,
        identity: identity(v, global),
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
    if report.one_thread_inflate {
        print_line(&format!(
            "note          one gzip member: it inflates on one thread; `morphray convert {} -o COPY.nii.gz` writes a copy of 1 MiB members that inflates on every core",
            report.file
        ));
    }
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
    print_identity(&report.identity);
    if report.warnings.is_empty() {
        print_line("warnings      none");
    } else {
        for w in report.warnings {
            print_line(&format!("warning       {w}"));
        }
    }
    Ok(())
}

/// The chosen DICOM volume in `info --json`.
#[derive(serde::Serialize)]
struct DicomVolume<'a> {
    label: &'a str,
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    affine: [[f64; 4]; 4],
    sample_kind: &'static str,
    scl_slope: f64,
    scl_inter: f64,
    imin: Option<f64>,
    imax: Option<f64>,
    /// What the scan is (modality, contrast), and from what.
    identity: Identity<'a>,
    warnings: &'a [String],
}

/// The DICOM document of `info --json`.
#[derive(serde::Serialize)]
struct DicomReport<'a> {
    file: String,
    format: &'static str,
    series: Vec<dicom::SeriesInfo>,
    /// The index commands pick without --series (None when no series qualifies).
    default: Option<usize>,
    default_reason: String,
    /// The series described under `volume` (--series, else the default).
    chosen: Option<usize>,
    volume: Option<DicomVolume<'a>>,
    skipped: &'a [dicom::Skipped],
    not_dicom_files: usize,
    no_pixel_data_files: usize,
    notes: &'a [String],
}

use crate::volume::source::dicom;

/// `info` on a DICOM folder, DICOMDIR or file.
fn run_dicom(args: &InfoArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let wrap = |e: dicom::DicomError| Error::from(InputError::Path(Box::new(e)));
    let choice = source::read_options(0, false).series;
    crate::volume::source::check_several(&args.file)?;
    let survey = dicom::survey_files(&args.file).map_err(wrap)?;
    let picked = survey.pick(choice.as_ref());
    let (loaded, survey) = match &picked {
        Ok(_) => {
            let (volume, survey) = dicom::load_survey(survey, choice.as_ref()).map_err(wrap)?;
            (Some(volume), survey)
        }
        Err(_) => (None, survey),
    };
    let stats = loaded.as_ref().map(intensity_stats);
    let (not_dicom, no_pixels) = survey.ignored();
    let report = DicomReport {
        file: survey.path.display().to_string(),
        format: "DICOM",
        series: survey.series(),
        default: survey.default.clone().ok(),
        default_reason: survey.default_reason(),
        chosen: picked.as_ref().ok().copied(),
        volume: loaded.as_ref().map(|v| DicomVolume {
            label: &v.name,
            dims: v.dims,
            spacing_mm: v.spacing_mm,
            affine: v.orientation.affine,
            sample_kind: v.samples.kind().name(),
            scl_slope: v.to_physical.slope,
            scl_inter: v.to_physical.intercept,
            imin: stats.as_ref().and_then(|s| s.imin),
            imax: stats.as_ref().and_then(|s| s.imax),
            identity: identity(v, global),
            warnings: &v.warnings,
        }),
        skipped: survey.skipped(),
        not_dicom_files: not_dicom,
        no_pixel_data_files: no_pixels,
        notes: survey.notes(),
    };
    if args.json {
        print_line(&json(&report));
    } else {
        print_dicom(&report);
    }
    // Without --series, a listing with no default is still a listing (issue 30: `info` failed
    // with the same "choose one with --series" it tells the user to run it for).
    match (&choice, picked) {
        (None, Err(dicom::DicomError::NoDefault { .. })) => Ok(()),
        (_, picked) => picked.map(|_| ()).map_err(wrap),
    }
}

/// The text form of [`DicomReport`].
fn print_dicom(r: &DicomReport) {
    print_line(&format!("file          {} (DICOM)", r.file));
    for s in &r.series {
        let dims = s
            .dims
            .map(|d| format!("{}x{}x{}", d[0], d[1], d[2]))
            .unwrap_or_else(|| "no volume".into());
        let mark = if Some(s.index) == r.chosen { "*" } else { " " };
        print_line(&format!(
            "series {mark}{:>3}  #{:<4} {:<10} {:<12} {:>4} file(s)  {}  {}",
            s.index,
            s.number.map(|n| n.to_string()).unwrap_or_default(),
            format!("{:?}", s.role).to_lowercase(),
            dims,
            s.count,
            s.description,
            s.uid
        ));
        if let Some(p) = &s.problem {
            print_line(&format!("                unusable: {p}"));
        }
    }
    print_line(&format!("default       {}", r.default_reason));
    for n in r.notes {
        print_line(&format!("note          {n}"));
    }
    for s in r.skipped {
        print_line(&format!("skipped       {}: {}", s.path.display(), s.reason));
    }
    if let Some(v) = &r.volume {
        print_line(&format!("volume        {}", v.label));
        print_line(&format!(
            "dims          {} x {} x {} ({})",
            v.dims[0], v.dims[1], v.dims[2], v.sample_kind
        ));
        print_line(&format!(
            "spacing       {:.4} x {:.4} x {:.4} mm",
            v.spacing_mm[0], v.spacing_mm[1], v.spacing_mm[2]
        ));
        print_line("affine        voxel index to RAS mm");
        for row in &v.affine {
            print_line(&format!(
                "              [{:>10.4} {:>10.4} {:>10.4} {:>10.4}]",
                row[0], row[1], row[2], row[3]
            ));
        }
        print_line(&format!(
            "scaling       slope {} intercept {}",
            v.scl_slope, v.scl_inter
        ));
        if let (Some(lo), Some(hi)) = (v.imin, v.imax) {
            print_line(&format!("intensity     {lo} .. {hi} (physical)"));
        }
        print_identity(&v.identity);
        for w in v.warnings {
            print_line(&format!("warning       {w}"));
        }
    }
}
