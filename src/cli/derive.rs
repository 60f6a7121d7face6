//! `morphray derive FILE -o DIR`: the derived maps the scene computes, as NIfTI-1 files beside
//! each other in DIR, named `<name>_normalized.nii.gz`, `<name>_gradient.nii.gz`,
//! `<name>_curvature.nii.gz`, `<name>_vesselness.nii.gz`, `<name>_brain.nii.gz` (uint8 0/1,
//! with `--maps brain`) and (with `--denoise`) `<name>_denoised.nii.gz`, for use in other tools.
//!
//! Decisions:
//! - The maps come from the engine's one function (`Engine::derived_maps`), in world units
//!   (I_norm, per mm, per mm^2, vesselness in [0, 1]), as float32 with the input's affine (the
//!   volume's RAS orientation, as `convert` writes it).
//! - DIR is created when it is missing (with its parents), as `mkdir -p` would.
//! - Every output is checked before anything is read (`check_output`: never the input, the
//!   folder takes files), and an existing file is replaced only with `--force`: without
//!   it the command refuses to start, and each write refuses a file that appeared meanwhile.
//! - `<name>` is the input's file name without `.nii`/`.nii.gz`/`.hdr`/`.img` (DICOM: the folder's
//!   name); `phantom` without a file.

use super::output::{print_line, print_warnings};
use super::session;
use crate::engine::MapRequest;
use crate::error::Error;
use crate::files::write::{OutputKind, check_output};
use crate::passes::denoise::Denoise;
use crate::volume::{LinearMap, Samples, Volume};
use clap::Args;
use std::path::{Path, PathBuf};

/// Options of `derive`.
#[derive(Debug, Args)]
pub struct DeriveArgs {
    /// NIfTI-1/2, ANALYZE or DICOM input (a folder, DICOMDIR, .dcm, or several files of one
    /// series); without one, the built-in digital phantom.
    #[arg(value_name = "FILE")]
    pub file: Vec<PathBuf>,
    /// Folder the maps are written into (created when missing).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Maps to write, comma-separated: normalized, gradient, curvature, vesselness, brain
    ///
    /// brain is the extracted brain mask (uint8 0/1 on the input's grid; `--brain`'s extraction
    /// with any brain found used), for FSL, ANTs or nibabel.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "normalized,gradient,curvature,vesselness"
    )]
    pub maps: Vec<String>,
    /// Denoising before the derivatives: none, gaussian:SIGMA_MM, median or
    /// bilateral:SIGMA_MM,RANGE; anything but none also writes `<name>_denoised.nii.gz`.
    #[arg(long, default_value = "none", value_parser = parse_denoise)]
    pub denoise: Denoise,
    /// Vesselness scales in mm, comma-separated (default 0.6,1.026,1.754,3).
    #[arg(long, value_delimiter = ',')]
    pub vessel_scales: Vec<f32>,
    /// Replace existing map files (atomically); the input is never replaced.
    #[arg(long)]
    pub force: bool,
    /// Frame of a 4-D file (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
}

fn parse_denoise(text: &str) -> Result<Denoise, String> {
    text.parse()
}

/// `<name>` of the outputs (module decisions).
pub fn base_name(file: Option<&Path>) -> String {
    let Some(file) = file else {
        return "phantom".into();
    };
    // `.` or `..` (a DICOM folder opened from inside it) has no file name of its own: the
    // folder it resolves to names the output, not a generic "volume.png".
    let resolved = || {
        std::fs::canonicalize(file)
            .ok()?
            .file_name()
            .map(ToOwned::to_owned)
    };
    let name = file
        .file_name()
        .map(ToOwned::to_owned)
        .or_else(resolved)
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "volume".into());
    let lower = name.to_ascii_lowercase();
    for ext in [".nii.gz", ".nii", ".hdr", ".img", ".dcm"] {
        if lower.ends_with(ext) && name.len() > ext.len() {
            return name[..name.len() - ext.len()].to_string();
        }
    }
    name
}

/// Runs the command.
pub fn run(args: &DeriveArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let (request, wanted) = MapRequest::named(&args.maps, args.denoise, &args.vessel_scales)
        .map_err(|e| match e {
            crate::gpu::GpuError::InvalidRequest(message) => Error::Usage(message),
            other => Error::from(other),
        })?;
    let stem = base_name(args.file.first().map(PathBuf::as_path));
    let paths: Vec<(&str, PathBuf)> = wanted
        .iter()
        .map(|m| (*m, args.output.join(format!("{stem}_{m}.nii.gz"))))
        .collect();
    if !args.output.is_dir() {
        std::fs::create_dir_all(&args.output).map_err(|e| {
            Error::Usage(format!(
                "cannot create the output folder {}: {e}",
                args.output.display()
            ))
        })?;
    }
    // Before any work: every target is new, none is the input, the folder takes files.
    let inputs: Vec<&Path> = args.file.iter().map(PathBuf::as_path).collect();
    for (_, path) in &paths {
        check_output(path, OutputKind::Nifti, &inputs, args.force)?;
    }
    let mut opened = session::open(
        &args.file,
        args.frame,
        false,
        global.engine_config(),
        None,
        false,
    )?;
    // As every command does: maps of a repaired file must not look like a clean one's.
    print_warnings(&opened.source.volume.warnings);
    let prepared = opened.twin.prepared.clone();
    let maps = opened.engine.derived_maps(&prepared, &request)?;
    let source = &opened.source.volume;
    if let Some(report) = &maps.brain_report {
        print_line(&report.summary());
    }
    for (name, path) in &paths {
        if *name == "brain" {
            let Some(mask) = &maps.brain else {
                print_line("no brain-like region was found: no brain mask written");
                continue;
            };
            let map = Volume {
                name: format!("{stem}_brain"),
                dims: source.dims,
                spacing_mm: source.spacing_mm,
                orientation: source.orientation.clone(),
                samples: Samples::from_u8(mask.clone()),
                to_physical: LinearMap::IDENTITY,
                warnings: vec![],
                facts: Default::default(),
            };
            write_map(&map, path, args.force)?;
            print_line(&format!("wrote {}", path.display()));
            continue;
        }
        let values = match *name {
            "normalized" => Some(&maps.normalized),
            "gradient" => maps.gradient.as_ref(),
            "curvature" => maps.curvature.as_ref(),
            "vesselness" => maps.vesselness.as_ref(),
            _ => maps.denoised.as_ref(),
        };
        let Some(values) = values else { continue };
        let map = Volume {
            name: format!("{stem}_{name}"),
            dims: source.dims,
            spacing_mm: source.spacing_mm,
            orientation: source.orientation.clone(),
            samples: Samples::from_f32(values),
            to_physical: LinearMap::IDENTITY,
            warnings: vec![],
            facts: Default::default(),
        };
        write_map(&map, path, args.force)?;
        print_line(&format!("wrote {}", path.display()));
    }
    if global.validation {
        session::check_validation(&opened.engine)?;
    }
    session::persist_pipeline_cache(&opened.engine);
    Ok(())
}

fn write_map(map: &Volume, path: &Path, force: bool) -> Result<(), Error> {
    if force {
        crate::volume::nifti::write_nifti1(map, path, true)?;
    } else {
        // No clobbering even of a file that appeared while the maps were computed.
        crate::volume::nifti::write_new_nifti1(map, path, true)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base_names_drop_the_volume_extensions() {
        assert_eq!(
            base_name(Some(Path::new("/d/sub-01_T1w.nii.gz"))),
            "sub-01_T1w"
        );
        assert_eq!(base_name(Some(Path::new("a.NII"))), "a");
        assert_eq!(base_name(Some(Path::new("scan.hdr"))), "scan");
        assert_eq!(base_name(Some(Path::new("dicom_folder"))), "dicom_folder");
        assert_eq!(base_name(None), "phantom");
    }

    #[test]
    fn a_folder_named_by_dots_gives_its_own_name() -> std::io::Result<()> {
        let dir = std::env::temp_dir().join(format!("morphray-base-{}", std::process::id()));
        let series = dir.join("head_series");
        std::fs::create_dir_all(series.join("sub"))?;
        let named = base_name(Some(&series.join("sub").join("..")));
        std::fs::remove_dir_all(&dir)?;
        assert_eq!(named, "head_series");
        // The root has no name at all: the generic one, not an empty ".png".
        assert_eq!(base_name(Some(Path::new("/"))), "volume");
        Ok(())
    }
}
