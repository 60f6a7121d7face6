//! Writing output files so that nothing is lost: every file the program writes (PNG, NIfTI,
//! JSON, SVG, pipeline caches) goes through [`AtomicFile`], and every output a command names is
//! checked by [`check_output`] before any GPU work.
//!
//! Decisions:
//! - Atomic replacement: the bytes go to a temporary file in the target's own directory (same
//!   file system, so the final `rename` is atomic); it is flushed and `fsync`ed, then renamed
//!   over the target, then the directory is `fsync`ed (best effort: some file systems refuse
//!   it). A failure at any point (disk full, file-size limit, a producer that stops halfway)
//!   removes the temporary file and leaves any previous target byte for byte as it was. An
//!   [`AtomicFile`] dropped without [`AtomicFile::commit`] removes its temporary file too; an
//!   interrupt (SIGINT, SIGTERM, SIGHUP) removes it, and one left by a killed process is removed
//!   by the next write to its folder ([`super::unfinished`]).
//! - A target that exists but is not a regular file (a directory, `/dev/full`, a FIFO, a
//!   device) is refused: renaming over it would replace the device node or the FIFO, and
//!   writing into it "in place" is what this module exists to avoid. A symbolic link is
//!   followed, so the file it points to is replaced and the link stays.
//! - A replaced file keeps its permission bits (the temporary file gets them before the rename).
//! - No-clobber commits ([`AtomicFile::commit_new`], for NIfTI volumes: a scan may be
//!   irreplaceable) publish with `hard_link`, which fails atomically when the target appeared in
//!   the meantime; file systems without hard links fall back to check-then-rename.
//! - [`check_output`] runs before the work, so a wrong path costs nothing: the directory must
//!   exist and accept a new file (probed by creating and removing one: permission bits do not
//!   tell, for example for root or a read-only mount), the name must carry the format's
//!   extension (case-insensitive), the target must not be any input (compared by device and
//!   inode, so a hard link or `./x/../scan.nii` is caught; the `.hdr`/`.img` partner of a pair
//!   counts as an input) and an existing NIfTI target needs `force`.
//! - Errors are one sentence naming the path and what to do; a full disk says "no space left on
//!   device" whatever layer noticed it.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, ErrorKind, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

/// The format of an output, which fixes its extension and whether an existing file may be
/// replaced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// A PNG image.
    Png,
    /// A NIfTI-1 volume (`.nii` or `.nii.gz`); never replaced without `force`.
    Nifti,
    /// A JSON report.
    Json,
    /// An SVG plot.
    Svg,
    /// A CSV table.
    Csv,
}

impl OutputKind {
    /// Accepted extensions, lowercase, the preferred one first.
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            OutputKind::Png => &[".png"],
            OutputKind::Nifti => &[".nii.gz", ".nii"],
            OutputKind::Json => &[".json"],
            OutputKind::Svg => &[".svg"],
            OutputKind::Csv => &[".csv"],
        }
    }

    /// What the file is, for messages.
    fn what(self) -> &'static str {
        match self {
            OutputKind::Png => "a PNG image",
            OutputKind::Nifti => "a NIfTI volume",
            OutputKind::Json => "a JSON report",
            OutputKind::Svg => "an SVG plot",
            OutputKind::Csv => "a CSV table",
        }
    }

    /// Whether `path`'s file name ends in one of the accepted extensions (ASCII case ignored).
    pub fn accepts(self, path: &Path) -> bool {
        let Some(name) = path
            .file_name()
            .map(|n| n.to_string_lossy().to_ascii_lowercase())
        else {
            return false;
        };
        self.extensions()
            .iter()
            .any(|ext| name.len() > ext.len() && name.ends_with(ext))
    }
}

/// Why an output cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum OutputProblem {
    /// The directory the file would go in does not exist.
    #[error("the directory {0} does not exist; create it first or choose another output path")]
    NoDirectory(PathBuf),
    /// The path's parent is a file.
    #[error("{0} is not a directory; choose an output path inside a directory")]
    ParentNotDirectory(PathBuf),
    /// A file cannot be created in the directory.
    #[error("no file can be created in {dir} ({reason}); choose a directory you can write to")]
    DirectoryNotWritable {
        /// The directory.
        dir: PathBuf,
        /// What the probe's creation said.
        reason: String,
    },
    /// The target is a directory.
    #[error("it is a directory; name a file inside it, for example {0}")]
    IsDirectory(PathBuf),
    /// The target exists and is a device, FIFO or socket.
    #[error(
        "it is not a regular file (a device, FIFO or socket), and morphray only replaces regular files; choose a file name"
    )]
    NotRegularFile,
    /// The extension does not fit the format.
    #[error("the name must end in {expected} for {what}; use for example {suggestion}")]
    WrongExtension {
        /// What the file is.
        what: &'static str,
        /// The accepted extensions.
        expected: String,
        /// The path with the right extension.
        suggestion: PathBuf,
    },
    /// The target is (a link to) an input of the command.
    #[error("it is the input {0}, which writing would destroy; choose another output name")]
    IsInput(PathBuf),
    /// An existing NIfTI volume without `force`.
    #[error(
        "the file exists and a NIfTI volume may be an irreplaceable scan; pass --force to replace it, or choose another name"
    )]
    Exists,
    /// The operating system refused a write, a flush, a sync or the rename.
    #[error("{}", describe(.0))]
    Io(#[source] std::io::Error),
}

/// An output that cannot be written: the path as the user gave it, and why.
#[derive(Debug, thiserror::Error)]
#[error("cannot write {}: {problem}", path.display())]
pub struct OutputError {
    /// The output path.
    pub path: PathBuf,
    /// Why.
    pub problem: OutputProblem,
}

impl OutputError {
    fn new(path: &Path, problem: OutputProblem) -> Self {
        OutputError {
            path: path.to_path_buf(),
            problem,
        }
    }

    /// An operating-system error while writing `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Self::new(path, OutputProblem::Io(source))
    }

    /// The problem as an `io::Error` of the same kind (for layers whose errors wrap
    /// `io::Error`); its text is the problem's sentence, without the path.
    pub fn into_io_error(self) -> std::io::Error {
        let kind = match &self.problem {
            OutputProblem::Io(e) => e.kind(),
            OutputProblem::Exists => ErrorKind::AlreadyExists,
            OutputProblem::NoDirectory(_) => ErrorKind::NotFound,
            _ => ErrorKind::InvalidInput,
        };
        std::io::Error::new(kind, self.problem.to_string())
    }
}

/// An operating-system error as a sentence that says what to do; a full disk always reads
/// "no space left on device", whichever layer noticed it.
pub fn describe(e: &std::io::Error) -> String {
    const KEPT: &str = "any previous file of that name is unchanged";
    match e.kind() {
        ErrorKind::StorageFull => {
            format!("no space left on device; {KEPT}: free some space or write elsewhere")
        }
        ErrorKind::QuotaExceeded => {
            format!("disk quota exceeded; {KEPT}: free some space or write elsewhere")
        }
        ErrorKind::FileTooLarge => format!(
            "the file is larger than this file system or the process's file-size limit allows; {KEPT}"
        ),
        ErrorKind::ReadOnlyFilesystem => {
            format!("the file system is read-only; {KEPT}: write elsewhere")
        }
        ErrorKind::PermissionDenied => {
            format!("permission denied; {KEPT}: choose a directory you can write to")
        }
        _ => format!("{e}; {KEPT}"),
    }
}

/// Checks, before any work, that `path` can receive a complete file of `kind` (see the module's
/// decisions): an existing target is a regular file and not an input, the extension is right,
/// the directory is present and takes a new file, an existing NIfTI is replaced only with
/// `force`. The most specific problem is reported first (`-o scan.nii.gz` onto the input says
/// "it is the input", not "use .png").
pub fn check_output(
    path: &Path,
    kind: OutputKind,
    inputs: &[&Path],
    force: bool,
) -> Result<(), OutputError> {
    let fail = |problem| Err(OutputError::new(path, problem));
    let existing = std::fs::metadata(path).ok();
    if let Some(meta) = &existing {
        if meta.is_dir() {
            return fail(OutputProblem::IsDirectory(
                path.join(format!("out{}", kind.extensions()[0])),
            ));
        }
        if !meta.is_file() {
            return fail(OutputProblem::NotRegularFile);
        }
        if let Some(input) = inputs
            .iter()
            .flat_map(|i| with_pair_partner(i))
            .find(|i| same_file(meta, i))
        {
            return fail(OutputProblem::IsInput(input));
        }
    }
    if !kind.accepts(path) {
        return fail(OutputProblem::WrongExtension {
            what: kind.what(),
            expected: kind.extensions().join(" or "),
            suggestion: with_extension(path, kind.extensions()[0]),
        });
    }
    let dir = parent_dir(path);
    match std::fs::metadata(dir) {
        Err(_) => return fail(OutputProblem::NoDirectory(dir.to_path_buf())),
        Ok(meta) if !meta.is_dir() => {
            return fail(OutputProblem::ParentNotDirectory(dir.to_path_buf()));
        }
        Ok(_) => {}
    }
    if existing.is_some() && kind == OutputKind::Nifti && !force {
        return fail(OutputProblem::Exists);
    }
    probe_directory(dir).map_err(|e| {
        OutputError::new(
            path,
            OutputProblem::DirectoryNotWritable {
                dir: dir.to_path_buf(),
                reason: describe_short(&e),
            },
        )
    })
}

/// The directory `path` is written in (`.` for a bare name).
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The operating system's words, without the "previous file" reassurance (a probe wrote
/// nothing).
fn describe_short(e: &std::io::Error) -> String {
    match e.kind() {
        ErrorKind::StorageFull => "no space left on device".into(),
        ErrorKind::ReadOnlyFilesystem => "the file system is read-only".into(),
        ErrorKind::PermissionDenied => "permission denied".into(),
        _ => e.to_string(),
    }
}

/// Creates and removes a file in `dir`: the only reliable test that a file can be created there.
fn probe_directory(dir: &Path) -> std::io::Result<()> {
    let (file, probe) = create_temp(dir, "morphray-probe")?;
    drop(file);
    let removed = std::fs::remove_file(&probe);
    super::unfinished::unregister(&probe);
    removed
}

/// `path` with its format extension(s) replaced by `ext` (`scan.jpg` -> `scan.png`).
fn with_extension(path: &Path, ext: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let lower = name.to_ascii_lowercase();
    let stem_len = [".nii.gz", ".hdr.gz", ".img.gz"]
        .iter()
        .find(|e| lower.ends_with(*e))
        .map(|e| name.len() - e.len())
        .or_else(|| name.rfind('.').filter(|&i| i > 0))
        .unwrap_or(name.len());
    path.with_file_name(format!("{}{ext}", &name[..stem_len]))
}

/// `input`, and for one file of an ANALYZE/NIfTI pair (`.hdr`/`.img`, optionally `.gz`, any
/// case) the other files of the pair that exist.
fn with_pair_partner(input: &Path) -> Vec<PathBuf> {
    let mut all = vec![input.to_path_buf()];
    let name = input
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let lower = name.to_ascii_lowercase();
    let gz = lower.ends_with(".gz");
    let core = if gz {
        &lower[..lower.len() - 3]
    } else {
        &lower[..]
    };
    let stem_len = core.len().saturating_sub(4);
    let partner = if core.ends_with(".hdr") {
        "img"
    } else if core.ends_with(".img") {
        "hdr"
    } else {
        return all;
    };
    let stem = &name[..stem_len];
    for ext in [partner, &partner.to_ascii_uppercase()] {
        for tail in ["", ".gz", ".GZ"] {
            let candidate = input.with_file_name(format!("{stem}.{ext}{tail}"));
            if candidate.exists() {
                all.push(candidate);
            }
        }
    }
    all
}

/// Whether `meta` (of an existing target) describes the same file as `other`.
fn same_file(meta: &std::fs::Metadata, other: &Path) -> bool {
    let Ok(theirs) = std::fs::metadata(other) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        meta.dev() == theirs.dev() && meta.ino() == theirs.ino()
    }
    #[cfg(not(unix))]
    {
        // No inode numbers: same size and modification time is the portable approximation.
        meta.len() == theirs.len() && meta.modified().ok() == theirs.modified().ok()
    }
}

/// Creates a new, uniquely named hidden file in `dir` (never an existing one), listed for
/// removal on an interrupt; first removes what dead writers left there (`super::unfinished`).
fn create_temp(dir: &Path, name: &str) -> std::io::Result<(File, PathBuf)> {
    super::unfinished::remove_stale(dir);
    // Unique per process and call, so concurrent writers never share a temporary file.
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let mut last = None;
    for _ in 0..16 {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let temp = dir.join(format!(".{name}.{}.{n}.tmp", std::process::id()));
        match OpenOptions::new().write(true).create_new(true).open(&temp) {
            Ok(file) => {
                super::unfinished::register(&temp, &file);
                return Ok((file, temp));
            }
            Err(e) if e.kind() == ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| std::io::Error::from(ErrorKind::AlreadyExists)))
}

/// A file being written: a temporary file beside the target until [`AtomicFile::commit`]
/// renames it over the target. Dropped uncommitted, it removes the temporary file.
pub struct AtomicFile {
    /// The path as given (for messages).
    shown: PathBuf,
    /// Where the file goes (a symbolic link resolved).
    target: PathBuf,
    /// The temporary file's path.
    temp: PathBuf,
    /// The open temporary file; None once committed.
    file: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `target`: creates the temporary file in its directory. Fails when the
    /// target is a directory or another non-regular file, or the directory takes no new file.
    pub fn create(target: &Path) -> Result<Self, OutputError> {
        let fail = |problem| OutputError::new(target, problem);
        // Follow a symbolic link, so the file it points to is replaced and the link stays.
        let resolved = match std::fs::symlink_metadata(target) {
            Ok(m) if m.file_type().is_symlink() => {
                std::fs::canonicalize(target).unwrap_or_else(|_| target.to_path_buf())
            }
            _ => target.to_path_buf(),
        };
        let existing = std::fs::metadata(&resolved).ok();
        if let Some(meta) = &existing {
            if meta.is_dir() {
                return Err(fail(OutputProblem::IsDirectory(target.join("out"))));
            }
            if !meta.is_file() {
                return Err(fail(OutputProblem::NotRegularFile));
            }
        }
        let name = resolved
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "out".into());
        let (file, temp) =
            create_temp(parent_dir(&resolved), &name).map_err(|e| fail(OutputProblem::Io(e)))?;
        if let Some(meta) = existing {
            // Best effort: a file system without permission bits keeps the default.
            let _ = file.set_permissions(meta.permissions());
        }
        Ok(AtomicFile {
            shown: target.to_path_buf(),
            target: resolved,
            temp,
            file: Some(BufWriter::new(file)),
        })
    }

    /// The path as given to [`AtomicFile::create`].
    pub fn path(&self) -> &Path {
        &self.shown
    }

    /// An [`OutputError`] for this file from an I/O error of a producer writing into it.
    pub fn error(&self, source: std::io::Error) -> OutputError {
        OutputError::io(&self.shown, source)
    }

    /// Flushes and syncs the temporary file, then renames it over the target (replacing an
    /// existing file), then syncs the directory (best effort).
    pub fn commit(mut self) -> Result<(), OutputError> {
        self.finish()?;
        std::fs::rename(&self.temp, &self.target).map_err(|e| self.error(e))?;
        self.file = None;
        super::unfinished::unregister(&self.temp);
        sync_dir(parent_dir(&self.target));
        Ok(())
    }

    /// Like [`AtomicFile::commit`], but fails with [`OutputProblem::Exists`] (leaving it
    /// untouched) when the target exists, even if it appeared while this file was written.
    pub fn commit_new(mut self) -> Result<(), OutputError> {
        self.finish()?;
        match std::fs::hard_link(&self.temp, &self.target) {
            Ok(()) => {
                let _ = std::fs::remove_file(&self.temp);
            }
            Err(e) if e.kind() == ErrorKind::AlreadyExists => {
                return Err(OutputError::new(&self.shown, OutputProblem::Exists));
            }
            // No hard links on this file system: check, then rename (a small race remains).
            Err(_) if self.target.exists() => {
                return Err(OutputError::new(&self.shown, OutputProblem::Exists));
            }
            Err(_) => std::fs::rename(&self.temp, &self.target).map_err(|e| self.error(e))?,
        }
        self.file = None;
        super::unfinished::unregister(&self.temp);
        sync_dir(parent_dir(&self.target));
        Ok(())
    }

    /// Flushes the buffer and puts the data on disk, so a crash after the rename cannot leave
    /// a renamed but empty file.
    fn finish(&mut self) -> Result<(), OutputError> {
        let Some(file) = self.file.as_mut() else {
            return Err(self.error(ErrorKind::BrokenPipe.into()));
        };
        file.flush().map_err(|e| OutputError::io(&self.shown, e))?;
        file.get_ref()
            .sync_all()
            .map_err(|e| OutputError::io(&self.shown, e))
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self.file.as_mut() {
            Some(f) => f.write(buf),
            None => Err(ErrorKind::BrokenPipe.into()),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self.file.as_mut() {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let Some(file) = self.file.take() {
            // Not committed: the target is untouched; the partial data go.
            drop(file);
            let _ = std::fs::remove_file(&self.temp);
            super::unfinished::unregister(&self.temp);
        }
    }
}

/// Makes a rename durable (best effort: not every file system lets a directory be synced).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// Writes `bytes` to `target` atomically, replacing an existing file.
pub fn write_file(target: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut file = AtomicFile::create(target)?;
    file.write_all(bytes).map_err(|e| file.error(e))?;
    file.commit()
}

/// Writes `bytes` to `target` atomically, failing with [`OutputProblem::Exists`] when it exists.
pub fn write_new_file(target: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut file = AtomicFile::create(target)?;
    file.write_all(bytes).map_err(|e| file.error(e))?;
    file.commit_new()
}

#[cfg(test)]
#[path = "write_tests.rs"]
mod tests;
