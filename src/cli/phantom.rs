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
