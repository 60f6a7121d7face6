//! `morphray phantom`: writes the built-in digital phantom (src/volume/phantom.rs), plain or a
//! whole head (`--head`, src/volume/phantom_head.rs), in the global `--contrast`
//! (src/volume/phantom_contrast.rs), and optionally its tissue labels.
//!
//! Decisions: the contrast is the global `--contrast` (the one tissue analysis reads), so one
//! flag names a scan's contrast everywhere; `auto` makes T1. The output name is the user's; the
//! summary line names the contrast's BIDS suffix so a user can name files accordingly.

use super::args::PhantomArgs;
use super::output;
use crate::error::Error;
use crate::files::write::{OutputKind, check_output};
use crate::volume::Volume;
use crate::volume::phantom::{Phantom, PhantomSpec};
use crate::volume::phantom_contrast::Contrast;
use crate::volume::phantom_head::Anatomy;
use std::path::Path;

/// Runs `phantom` with the phantom contrast `contrast`.
pub fn run(args: &PhantomArgs, contrast: Contrast) -> Result<(), Error> {
    // Before generating: an existing scan is never replaced without --force.
    check_output(&args.output, OutputKind::Nifti, &[], args.force)?;
    if let Some(labels) = &args.labels {
        // Both onto one file: the labels replaced the phantom, and both were reported written.
        if same_destination(labels, &args.output) {
            return Err(Error::Usage(format!(
                "--labels {} names the same file as --output: the labels would replace the \
                 phantom; give the labels another name (e.g. {})",
                labels.display(),
                labels_name(&args.output).display()
            )));
        }
        check_output(labels, OutputKind::Nifti, &[], args.force)?;
    }
    let spec = PhantomSpec {
        dims: args.dims,
        anatomy: if args.head {
            Anatomy::Head
        } else {
            Anatomy::Shell
        },
        contrast,
        ..PhantomSpec::cohort_a()
    };
    let phantom = crate::volume::phantom::generate(&spec)?;
    write(&phantom.volume, &args.output, args.force)?;
    if let Some(path) = &args.labels {
        write_labels(&phantom, path, args.force)?;
    }
    let [x, y, z] = args.dims;
    let head = if args.head { ", head" } else { "" };
    let suffix = match contrast {
        Contrast::T1 => String::new(),
        c => format!(", {}", c.bids_suffix()),
    };
    output::print_line(&format!(
        "wrote {} ({x}x{y}x{z}, int16, 1 mm{head}{suffix})",
        args.output.display()
    ));
    Ok(())
}

/// Whether `a` and `b` name one file: the same inode when both exist, else the same name in
/// the same (resolved) folder, so `./p.nii.gz`, `p.nii.gz` and `d/../p.nii.gz` are one file.
fn same_destination(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    if let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) {
        use std::os::unix::fs::MetadataExt;
        return ma.dev() == mb.dev() && ma.ino() == mb.ino();
    }
    let resolved = |p: &Path| {
        let dir = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        (
            std::fs::canonicalize(dir).ok(),
            p.file_name().map(|n| n.to_owned()),
        )
    };
    let (ra, rb) = (resolved(a), resolved(b));
    (ra.1.is_some() && ra.0.is_some() && ra == rb) || a == b
}

/// A labels name beside `output`: `NAME_labels.nii.gz` for `NAME.nii.gz`.
fn labels_name(output: &Path) -> std::path::PathBuf {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (stem, ext) = match name.find('.') {
        Some(i) => name.split_at(i),
        None => (name.as_str(), ".nii.gz"),
    };
    output.with_file_name(format!("{stem}_labels{ext}"))
}

/// Writes `volume` as NIfTI-1 (gzip for .gz), replacing a file only with `force`.
fn write(volume: &Volume, path: &Path, force: bool) -> Result<(), Error> {
    let gzip = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    if force {
        crate::volume::nifti::write_nifti1(volume, path, gzip)?;
    } else {
        // No clobbering even of a file that appeared while the phantom was generated.
        crate::volume::nifti::write_new_nifti1(volume, path, gzip)?;
    }
    Ok(())
}

/// Writes the phantom's tissue labels (u8, the phantom's grid) as a NIfTI label map.
fn write_labels(phantom: &Phantom, path: &Path, force: bool) -> Result<(), Error> {
    check_output(path, OutputKind::Nifti, &[], force)?;
    let v = &phantom.volume;
    let labels = Volume::from_voxels(
        "phantom labels",
        v.dims,
        crate::volume::Samples::from_u8(phantom.labels.clone()),
        v.orientation.affine,
        crate::volume::LinearMap::IDENTITY,
    )?;
    write(&labels, path, force)?;
    output::print_line(&format!("wrote {} (tissue labels)", path.display()));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_onto_the_output_are_found_however_the_name_is_spelled() {
        let dir = std::env::temp_dir().join(format!("morphray-phantom-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let out = dir.join("p.nii.gz");
        assert!(same_destination(&out, &dir.join("sub/../p.nii.gz")));
        assert!(same_destination(&out, &dir.join("./p.nii.gz")));
        assert!(!same_destination(&out, &dir.join("p_labels.nii.gz")));
        assert!(!same_destination(&out, &dir.join("p.nii")));
        std::fs::write(&out, b"x").unwrap();
        assert!(same_destination(&out, &dir.join("sub/../p.nii.gz")));
        assert_eq!(labels_name(&out), dir.join("p_labels.nii.gz"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
