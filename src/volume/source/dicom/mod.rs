//! The DICOM reader: a folder of an exam (recursively), a DICOMDIR, a multi-frame (enhanced)
//! object, or one slice of a series, assembled into one volume.
//!
//! Decisions:
//! - `claims` is the one reader that looks at the disk: a folder, a file named DICOMDIR or
//!   `*.dcm`/`*.dicom`/`*.ima`, or any other file (not NIfTI-named, those are asked first) whose
//!   bytes 128..132 are `DICM` (one stat and a 132-byte read).
//! - Reading is three steps, each in its own file: headers without pixel data, in parallel
//!   (`headers`); stacks grouped, sorted and checked (`series`, geometry in `geometry`); the
//!   chosen stack's pixels decoded in parallel (`pixels`). [`survey`] stops after the second
//!   step: `morphray info` lists series from it without decoding a pixel.
//! - One slice given alone stands for its series: the files of its folder (not sub-folders)
//!   with its SeriesInstanceUID are read too, and a note says so. A file named on the command
//!   line is never replaced by another at its position: it wins the tie, and the others are
//!   listed in a warning (issue 30).
//! - Siemens mosaics are cut into their tiles where headers are read (`mosaic`); every tag is
//!   checked against the pixel data it describes before use (`consistency`); a deflated data
//!   set is inflated only as far as its header declares (`lengths`), and a stack whose pixels
//!   need more memory than the host has available is refused before anything is allocated
//!   (`pixels`, with `host_memory`).
//! - The series commands use by default is the largest 3-D image stack (most voxels; ties: the
//!   first listed); localizers, derived images and single slices are never picked by default
//!   but can be chosen with [`SeriesChoice`]. When none qualifies, one line says why (one
//!   slice; every file its own series; else counts of each kind of stack) and what to do.
//! - Corrupt files are listed (`Survey::skipped`, and as warnings on the volume) and left out;
//!   one whose pixels fail to decode is dropped and the stack laid out again (a dropped slice
//!   becomes a gap, which the layout resamples with a warning).
//! - The hash for provenance is of the assembled samples and the series UID (the files
//!   themselves are not read a second time).

mod choice;
mod consistency;
mod contain;
mod geometry;
mod headers;
mod lengths;
mod mosaic;
mod photometric;
mod pixels;
mod series;

pub use contain::panic_is_contained;
pub use headers::{Skipped, parse_header};
pub use series::Role;

use super::{InputError, LoadTimings, ReadOptions, SourceVolume, VolumeReader};
use crate::volume::{AffineSource, Orientation, Volume};
use choice::{best, why_no_default};
use headers::Scan;
use series::Stack;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Reads DICOM series.
pub struct DicomReader;

/// Which series of a DICOM input to open.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SeriesChoice {
    /// A SeriesInstanceUID (its largest stack when it has several).
    Uid(String),
    /// The position in the listing of `morphray info` (0-based).
    Index(usize),
}

impl SeriesChoice {
    /// Digits are an index, anything else a UID.
    pub fn parse(text: &str) -> Result<SeriesChoice, String> {
        let text = text.trim();
        if text.is_empty() {
            return Err("a series is a SeriesInstanceUID or an index from `morphray info`".into());
        }
        Ok(match text.parse::<usize>() {
            Ok(i) => SeriesChoice::Index(i),
            Err(_) => SeriesChoice::Uid(text.to_string()),
        })
    }
}

impl fmt::Display for SeriesChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SeriesChoice::Uid(uid) => f.write_str(uid),
            SeriesChoice::Index(i) => write!(f, "{i}"),
        }
    }
}

/// Why a DICOM input gives no volume.
#[derive(Debug, thiserror::Error)]
pub enum DicomError {
    /// The path could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The path.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Nothing under the path is a DICOM image.
    #[error(
        "{}: no DICOM image series found ({detail}); give the folder of one exam, a DICOMDIR \
         or a .dcm file",
        path.display()
    )]
    NoImages {
        /// The path.
        path: PathBuf,
        /// What was found instead.
        detail: String,
    },
    /// `--series` names nothing in the input.
    #[error("--series {choice}: {} has no such series; `morphray info {}` lists them", path.display(), path.display())]
    NoSuchSeries {
        /// The input.
        path: PathBuf,
        /// What was asked for.
        choice: SeriesChoice,
    },
    /// No stack qualifies as the default (`detail` says why and what to do).
    #[error("{}: {detail}", path.display())]
    NoDefault {
        /// The input.
        path: PathBuf,
        /// What the stacks are.
        detail: String,
    },
    /// The chosen series cannot be made a volume.
    #[error("series {series}: {reason}")]
    Unusable {
        /// Number and description.
        series: String,
        /// One line.
        reason: String,
    },
    /// `--frame` on DICOM input.
    #[error("--frame {0} applies to 4-D NIfTI files; a DICOM series is chosen with --series")]
    Frame(usize),
}

/// One stack as `morphray info --json` lists it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SeriesInfo {
    /// Position in the listing (what `--series INDEX` takes).
    pub index: usize,
    /// SeriesInstanceUID.
    pub uid: String,
    /// SeriesDescription.
    pub description: String,
    /// SeriesNumber.
    pub number: Option<i64>,
    /// Modality.
    pub modality: String,
    /// Image, localizer or derived.
    pub role: Role,
    /// Which stack of its UID (1-based) and how many it has.
    pub stack: [usize; 2],
    /// Voxels along i, j, k (None when the stack forms no volume).
    pub dims: Option<[usize; 3]>,
    /// Spacing, mm.
    pub spacing: Option<[f64; 3]>,
    /// Voxel index to RAS mm, row-major (the NIfTI sform convention).
    pub affine: Option<[[f64; 4]; 4]>,
    /// Files holding its frames.
    pub count: usize,
    /// Frames (slices) before duplicates are removed.
    pub frames: usize,
    /// FrameOfReferenceUID: the patient frame of the positions.
    pub frame_of_reference: String,
    /// Transfer syntax UID of its first file.
    pub transfer_syntax: String,
    /// What the layout repaired or found.
    pub warnings: Vec<String>,
    /// Why it forms no volume, when it does not.
    pub problem: Option<String>,
}

/// The series of a DICOM input, from headers only.
pub struct Survey {
    /// The input.
    pub path: PathBuf,
    scan: Scan,
    stacks: Vec<Stack>,
    /// The stack commands use without `--series`, and why (or why none).
    pub default: Result<usize, String>,
}

impl Survey {
    /// Every stack, in listing order.
    pub fn series(&self) -> Vec<SeriesInfo> {
        self.stacks
            .iter()
            .enumerate()
            .map(|(index, s)| {
                let layout = s.layout.as_ref().ok();
                SeriesInfo {
                    index,
                    uid: s.uid.clone(),
                    description: s.description.clone(),
                    number: s.number,
                    modality: s.modality.clone(),
                    role: s.role,
                    stack: [s.stack.0, s.stack.1],
                    dims: layout.map(|l| l.dims),
                    spacing: layout.map(|l| l.spacing),
                    affine: layout.map(|l| l.affine),
                    count: s.files,
                    frames: s.slices.len(),
                    frame_of_reference: s.frame_of_reference.clone(),
                    transfer_syntax: self.scan.images[s.first_file].transfer_syntax.clone(),
                    warnings: layout.map(|l| l.warnings.clone()).unwrap_or_default(),
                    problem: s.layout.as_ref().err().cloned(),
                }
            })
            .collect()
    }

    /// Corrupt or unreadable DICOM files, left out.
    pub fn skipped(&self) -> &[Skipped] {
        &self.scan.skipped
    }

    /// Notes about the input form.
    pub fn notes(&self) -> &[String] {
        &self.scan.notes
    }

    /// Files that are not DICOM, and DICOM files without pixel data.
    pub fn ignored(&self) -> (usize, usize) {
        (self.scan.not_dicom, self.scan.no_pixels)
    }

    /// Why the default is what it is.
    pub fn default_reason(&self) -> String {
        match &self.default {
            Ok(i) => {
                let s = &self.stacks[*i];
                let dims = s.layout.as_ref().map(|l| l.dims).unwrap_or_default();
                let others = self.stacks.len() - 1;
                format!(
                    "the largest 3-D image series ({}x{}x{} voxels){}",
                    dims[0],
                    dims[1],
                    dims[2],
                    if others > 0 {
                        format!(
                            "; {others} other stack(s): localizers, derived images and single \
                             slices are never the default"
                        )
                    } else {
                        String::new()
                    }
                )
            }
            Err(why) => why.clone(),
        }
    }

    /// The stack `choice` names, or the default.
    pub fn pick(&self, choice: Option<&SeriesChoice>) -> Result<usize, DicomError> {
        let no_such = || DicomError::NoSuchSeries {
            path: self.path.clone(),
            choice: choice.cloned().unwrap_or(SeriesChoice::Index(0)),
        };
        match choice {
            None => self
                .default
                .clone()
                .map_err(|detail| DicomError::NoDefault {
                    path: self.path.clone(),
                    detail,
                }),
            Some(SeriesChoice::Index(i)) if *i < self.stacks.len() => Ok(*i),
            Some(SeriesChoice::Index(_)) => Err(no_such()),
            Some(SeriesChoice::Uid(uid)) => {
                let of_uid = || (0..self.stacks.len()).filter(|&i| self.stacks[i].uid == *uid);
                // A UID whose stacks form no volume is still picked: opening it says why.
                best(&self.stacks, of_uid(), false)
                    .or_else(|| of_uid().next())
                    .ok_or_else(no_such)
            }
        }
    }

    /// `exam: series 3 "T1 MPRAGE"` (with the stack when its UID has several).
    pub fn label(&self, index: usize) -> String {
        let s = &self.stacks[index];
        let mut label = format!("{}: series", super::file_name(&self.path));
        if let Some(n) = s.number {
            label.push_str(&format!(" {n}"));
        }
        if !s.description.is_empty() {
            label.push_str(&format!(" \"{}\"", s.description));
        }
        if s.stack.1 > 1 {
            label.push_str(&format!(" stack {}/{}", s.stack.0, s.stack.1));
        }
        label
    }
}

/// Reads the headers under `path` and groups them into stacks.
pub fn survey(path: &Path) -> Result<Survey, DicomError> {
    survey_scan(path.to_path_buf(), scan(path)?)
}

/// [`survey`] of several paths given as one input (files of a series, as a shell glob gives
/// them; a folder among them is read recursively). Named by their common folder.
pub fn survey_files(paths: &[PathBuf]) -> Result<Survey, DicomError> {
    if let [one] = paths {
        return survey(one);
    }
    let mut files = Vec::new();
    for path in paths {
        let io = |source| DicomError::Io {
            path: path.clone(),
            source,
        };
        if std::fs::metadata(path).map_err(io)?.is_dir() {
            files.extend(headers::walk(path).map_err(io)?);
        } else {
            files.push(path.clone());
        }
    }
    files.sort();
    files.dedup();
    files.truncate(headers::MAX_FILES);
    let mut scan = headers::read_all(&files);
    // Files named on the command line (not found in a named folder) win ties of position.
    for h in &mut scan.images {
        h.named = paths.contains(&h.path);
    }
    scan.notes.push(format!(
        "{} paths were given as one input ({} file(s))",
        paths.len(),
        files.len()
    ));
    survey_scan(common_folder(paths), scan)
}

/// The folder every path is in, else the first path (what a several-file input is called).
fn common_folder(paths: &[PathBuf]) -> PathBuf {
    let parent = |p: &PathBuf| p.parent().map(Path::to_path_buf).unwrap_or_default();
    match paths.first() {
        Some(first) if paths.iter().all(|p| parent(p) == parent(first)) => {
            let folder = parent(first);
            if folder.as_os_str().is_empty() {
                PathBuf::from(".")
            } else {
                folder
            }
        }
        Some(first) => first.clone(),
        None => PathBuf::from("."),
    }
}

/// Groups a scan's headers into stacks and picks the default.
fn survey_scan(path: PathBuf, scan: Scan) -> Result<Survey, DicomError> {
    if scan.images.is_empty() {
        let mut detail = format!(
            "{} file(s) not DICOM, {} DICOM file(s) without pixel data, {} unreadable",
            scan.not_dicom,
            scan.no_pixels,
            scan.skipped.len()
        );
        if let Some(first) = scan.skipped.first() {
            detail.push_str(&format!(
                "; first: {}: {}",
                first.path.display(),
                first.reason
            ));
        }
        return Err(DicomError::NoImages { path, detail });
    }
    let stacks = series::stacks(&scan);
    let default =
        best(&stacks, 0..stacks.len(), true).ok_or_else(|| why_no_default(&stacks, &path));
    Ok(Survey {
        path,
        scan,
        stacks,
        default,
    })
}

/// The headers of the files `path` names (see the module's decisions).
fn scan(path: &Path) -> Result<Scan, DicomError> {
    let io = |source| DicomError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if meta.is_dir() {
        return Ok(headers::read_all(&headers::walk(path).map_err(io)?));
    }
    let name = super::file_name(path).to_ascii_uppercase();
    if name == "DICOMDIR" {
        let files = headers::dicomdir_files(path).unwrap_or_default();
        let mut scan = headers::read_all(&files);
        scan.notes
            .push(format!("the DICOMDIR references {} file(s)", files.len()));
        return Ok(scan);
    }
    let single = headers::read_all(&[path.to_path_buf()]);
    let one_slice = single.images.len() == 1 && single.images[0].frames.len() == 1;
    let Some(folder) = path.parent().filter(|_| one_slice) else {
        return Ok(single);
    };
    let uid = single.images[0].series_uid.clone();
    let siblings: Vec<PathBuf> = std::fs::read_dir(if folder.as_os_str().is_empty() {
        Path::new(".")
    } else {
        folder
    })
    .map_err(io)?
    .flatten()
    .map(|e| e.path())
    .filter(|p| p.is_file())
    .take(headers::MAX_FILES)
    .collect();
    let mut scan = headers::read_all(&siblings);
    scan.images.retain(|h| h.series_uid == uid);
    // The file named wins a tie of positions over its siblings (issue 30: it was replaced).
    for h in &mut scan.images {
        h.named = same_file(&h.path, path);
    }
    scan.images.sort_by(|a, b| a.path.cmp(&b.path));
    scan.notes.push(format!(
        "one slice was given: its series' {} file(s) in {} were read with it",
        scan.images.len(),
        folder.display()
    ));
    Ok(scan)
}

/// True when `a` and `b` name the same file (device and inode; else equal paths).
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => a == b,
    }
}

/// The volume of the chosen stack, with the survey it came from.
pub fn load(path: &Path, choice: Option<&SeriesChoice>) -> Result<(Volume, Survey), DicomError> {
    load_survey(survey(path)?, choice)
}

/// The volume of the chosen stack of `survey`.
pub fn load_survey(
    survey: Survey,
    choice: Option<&SeriesChoice>,
) -> Result<(Volume, Survey), DicomError> {
    let index = survey.pick(choice)?;
    let stack = &survey.stacks[index];
    let label = survey.label(index);
    let unusable = |reason: String| DicomError::Unusable {
        series: label.clone(),
        reason,
    };
    let mut layout = stack.layout.clone().map_err(&unusable)?;
    let mut dropped: Vec<String> = Vec::new();
    let decoded = loop {
        match pixels::decode(&layout, &survey.scan) {
            Ok(d) => break d,
            Err(pixels::PixelError::Unsupported(reason)) => return Err(unusable(reason)),
            Err(pixels::PixelError::Files(failed)) => {
                if dropped.len() + failed.len() >= stack.files {
                    let (file, why) = &failed[0];
                    return Err(unusable(format!(
                        "no file decoded; {}: {why}",
                        survey.scan.images[*file].path.display()
                    )));
                }
                for (file, why) in &failed {
                    dropped.push(format!(
                        "{} was left out: {why}",
                        survey.scan.images[*file].path.display()
                    ));
                }
                let keep: Vec<series::Slice> = layout
                    .order
                    .iter()
                    .filter(|s| failed.iter().all(|(f, _)| *f != s.file))
                    .cloned()
                    .collect();
                layout = series::layout(&keep, &survey.scan).map_err(&unusable)?;
            }
        }
    };
    let mut warnings: Vec<String> = survey.scan.notes.clone();
    warnings.extend(
        survey
            .scan
            .skipped
            .iter()
            .map(|s| format!("{} was skipped: {}", s.path.display(), s.reason)),
    );
    warnings.extend(dropped);
    warnings.extend(layout.warnings.iter().cloned());
    warnings.extend(decoded.warnings);
    // The first slice's tags speak for the series (they are the same in every slice of it).
    let facts = layout
        .order
        .first()
        .and_then(|s| survey.scan.images.get(s.file))
        .map(|h| h.facts.clone())
        .unwrap_or_default();
    let volume = Volume {
        name: label,
        dims: layout.dims,
        spacing_mm: layout.spacing,
        orientation: Orientation {
            affine: layout.affine,
            source: AffineSource::Dicom,
        },
        samples: decoded.samples,
        to_physical: decoded.to_physical,
        warnings,
        facts,
    };
    Ok((volume, survey))
}

impl VolumeReader for DicomReader {
    fn name(&self) -> &'static str {
        "DICOM"
    }

    fn claims(&self, path: &Path) -> bool {
        if path.is_dir() {
            return true;
        }
        let name = super::file_name(path).to_ascii_lowercase();
        name == "dicomdir"
            || [".dcm", ".dicom", ".ima"].iter().any(|e| name.ends_with(e))
            || headers::has_magic(path)
    }

    fn read(&self, path: &Path, options: &ReadOptions) -> Result<SourceVolume, InputError> {
        read_files(&[path.to_path_buf()], options)
    }
}

/// Reads several paths as one DICOM input (see [`survey_files`]).
pub fn read_files(paths: &[PathBuf], options: &ReadOptions) -> Result<SourceVolume, InputError> {
    if options.frame != 0 {
        return Err(InputError::Path(Box::new(DicomError::Frame(options.frame))));
    }
    let start = Instant::now();
    let (volume, survey) = survey_files(paths)
        .and_then(|survey| load_survey(survey, options.series.as_ref()))
        .map_err(|e| InputError::Path(Box::new(e)))?;
    let read_ms = start.elapsed().as_secs_f64() * 1e3;
    let index = survey.pick(options.series.as_ref()).unwrap_or(0);
    let sha256 = options.hash.then(|| {
        use sha2::Digest;
        let mut hasher = sha2::Sha256::new();
        hasher.update(survey.stacks[index].uid.as_bytes());
        hasher.update(volume.samples.as_bytes());
        hasher
            .finalize()
            .iter()
            .map(|b| format!("{b:02x}"))
            .collect()
    });
    Ok(SourceVolume {
        label: volume.name.clone(),
        volume,
        header: None,
        sha256,
        timings: LoadTimings {
            read_ms,
            ..LoadTimings::default()
        },
        series: Some(super::SeriesListing {
            chosen: index,
            all: survey.series(),
        }),
    })
}
