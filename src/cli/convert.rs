//! `morphray convert PATH -o out.nii[.gz]`: the volume a command would open from PATH (a DICOM
//! series assembled, or a NIfTI frame) written as NIfTI-1.
//!
//! Decisions: the output is checked before anything is read (`check_output`: never the input,
//! right extension, writable folder, an existing file replaced only with `--force`, and then
//! atomically); without `--force` the write itself refuses a file that appeared meanwhile. The
//! NIfTI writer is the library's (`volume::nifti::writer`): samples in their stored encoding,
//! sform from the volume's RAS affine, scl_slope/scl_inter from the rescale.

use super::args::ConvertArgs;
use super::output::print_line;
use super::source;
use crate::error::Error;
use crate::files::write::{OutputKind, check_output};

/// Runs the command.
pub fn run(args: &ConvertArgs) -> Result<(), Error> {
    let inputs: Vec<&std::path::Path> = args.input.iter().map(|p| p.as_path()).collect();
    check_output(&args.output, OutputKind::Nifti, &inputs, args.force)?;
    let read = source::load(&args.input, args.frame, false)?;
    let v = &read.volume;
    let gzip = args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    if args.force {
        crate::volume::nifti::write_nifti1(v, &args.output, gzip)?;
    } else {
        crate::volume::nifti::write_new_nifti1(v, &args.output, gzip)?;
    }
    for w in &v.warnings {
        eprintln!("morphray: warning: {w}");
    }
    print_line(&format!(
        "wrote {} from {} ({}x{}x{}, {}, {:.3} x {:.3} x {:.3} mm)",
        args.output.display(),
        read.label,
        v.dims[0],
        v.dims[1],
        v.dims[2],
        v.samples.kind().name(),
        v.spacing_mm[0],
        v.spacing_mm[1],
        v.spacing_mm[2]
    ));
    Ok(())
}
