//! `morphray slice FILE --plane axial|coronal|sagittal [--index N | --mm X] -o out.png`: one
//! world-oriented slice of the normalized volume as a greyscale PNG with provenance.
//!
//! Decisions:
//! - Radiological by default (the patient's right on the image's left), as clinical viewers and
//!   PACS show axial and coronal slices; research viewers (FSLeyes, MRIcroGL, NiiVue) default to
//!   neurological, so the convention used is ALWAYS printed, and `--letters` burns R/L/A/P/S/I
//!   into the picture so it cannot be misread once it leaves the terminal.
//! - The slice is a plane of the world (RAS mm): `--mm X` is its coordinate along the plane's
//!   normal; `--index N` is the plane through voxel N along the voxel axis closest to that
//!   normal (for an axis-aligned volume both name the same voxel plane); neither: the volume's
//!   centre.
//! - Opened as a MIP scene (no derived volumes: a slice needs only I_norm), through the same
//!   library path as every command, so `--series`, DICOM folders and `--memory-budget` work.
//! - Grey is I_norm through `--window LO:HI` (default 0:1, the normalization's full range);
//!   outside the volume is opaque black.
//! - `--overlay LABELS` is resampled onto the volume's grid on the CPU (`scene::overlay`: nearest
//!   neighbour through the affines, in f64, once) and blended over the slice on the host.

use super::output::{ms, print_line, print_warnings};
use crate::engine::slice::{Slicer, geometry_of};
use crate::engine::{OpenOptions, Session};
use crate::error::Error;
use crate::files::png::{Provenance, write_rgba8};
use crate::files::write::{OutputKind, check_output};
use crate::scene::overlay::{blend_slice, resample};
use crate::scene::slice::{
    Convention, Plane, SliceGrid, centre_position, edge_letters, index_axis, position_of_index,
    position_of_mm,
};
use crate::scene::{Effects, RenderMode, SceneRecipe};
use crate::volume::source::VolumeSource;
use clap::{Args, ValueEnum};
use std::path::PathBuf;

/// The plane on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
pub enum PlaneArg {
    /// z = const, anterior at the top.
    Axial,
    /// y = const, superior at the top.
    Coronal,
    /// x = const, superior at the top, anterior on the left.
    Sagittal,
}

/// The convention on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum, serde::Serialize)]
pub enum ConventionArg {
    /// The patient's right on the image's left (clinical default).
    Radiological,
    /// The patient's right on the image's right.
    Neurological,
}

/// Options of `slice`.
#[derive(Debug, Args, serde::Serialize)]
pub struct SliceArgs {
    /// NIfTI-1/2 file or DICOM input (a folder, DICOMDIR, .dcm, or several files of one
    /// series); without one, the built-in digital phantom.
    #[arg(value_name = "FILE")]
    pub file: Vec<PathBuf>,
    /// Output PNG.
    #[arg(short, long, value_name = "PNG")]
    pub output: PathBuf,
    /// Which world plane.
    #[arg(long, value_enum)]
    pub plane: PlaneArg,
    /// Voxel index along the volume axis closest to the plane's normal (0-based).
    #[arg(long, conflicts_with = "mm", allow_negative_numbers = true)]
    pub index: Option<i64>,
    /// World coordinate of the plane along its normal (mm, RAS: x for sagittal, y for coronal,
    /// z for axial).
    #[arg(long, allow_negative_numbers = true)]
    pub mm: Option<f64>,
    /// Which side the patient's right is drawn on (printed either way).
    #[arg(long, value_enum, default_value_t = ConventionArg::Radiological)]
    pub convention: ConventionArg,
    /// Burn orientation letters (R/L/A/P/S/I) into the picture's edges.
    #[arg(long)]
    pub letters: bool,
    /// Pixel size in mm; default: the volume's finest voxel spacing.
    #[arg(long, value_name = "MM")]
    pub pixel_mm: Option<f64>,
    /// Grey window in I_norm units: LO is black, HI white.
    #[arg(long, value_name = "LO:HI", default_value = "0:1")]
    pub window: String,
    /// Frame of a 4-D file (0-based).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Label overlay.
    #[command(flatten)]
    pub overlay: super::overlay::OverlayArgs,
    /// Intensity layers.
    #[command(flatten)]
    pub layer: super::layer_args::LayerArgs,
}

fn parse_window(text: &str) -> Result<(f64, f64), Error> {
    let bad = || {
        Error::Usage(format!(
            "--window {text}: expected LO:HI in I_norm units with LO < HI, e.g. 0.1:0.9"
        ))
    };
    let (lo, hi) = text.split_once(':').ok_or_else(bad)?;
    let lo: f64 = lo.trim().parse().map_err(|_| bad())?;
    let hi: f64 = hi.trim().parse().map_err(|_| bad())?;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(bad());
    }
    Ok((lo, hi))
}

fn plane_of(arg: PlaneArg) -> Plane {
    match arg {
        PlaneArg::Axial => Plane::Axial,
        PlaneArg::Coronal => Plane::Coronal,
        PlaneArg::Sagittal => Plane::Sagittal,
    }
}

fn convention_of(arg: ConventionArg) -> Convention {
    match arg {
        ConventionArg::Radiological => Convention::Radiological,
        ConventionArg::Neurological => Convention::Neurological,
    }
}

/// Runs the command.
pub fn run(args: &SliceArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let mut inputs: Vec<&std::path::Path> = args.file.iter().map(|p| p.as_path()).collect();
    inputs.extend(args.overlay.inputs());
    let layer_paths = args.layer.inputs();
    inputs.extend(layer_paths.iter().map(|p| p.as_path()));
    check_output(&args.output, OutputKind::Png, &inputs, false)?;
    let window = parse_window(&args.window)?;
    if let Some(p) = args.pixel_mm.filter(|p| !(p.is_finite() && *p > 0.0)) {
        return Err(Error::Usage(format!(
            "--pixel-mm {p}: the pixel size must be a positive number of millimetres"
        )));
    }
    if let Some(mm) = args.mm.filter(|m| !m.is_finite()) {
        return Err(Error::Usage(format!("--mm {mm}: give a finite coordinate")));
    }
    let options = OpenOptions {
        read: super::source::read_options(args.frame, true),
        image: [256, 256],
        recipe: SceneRecipe {
            effects: Effects {
                mode: RenderMode::Mip,
                ..Effects::default()
            },
            ..SceneRecipe::default()
        },
        first_frame: false,
    };
    // The label map and its table before any GPU work: a bad one fails at once.
    let overlay = args.overlay.load()?;
    let layers = super::layer_args::open_all(&args.layer.specs()?, print_line)?;
    let source = VolumeSource::from_paths(&args.file);
    let session = Session::open(&source, global.engine_config(), &options)?;
    print_warnings(&session.source.volume.warnings);
    let overlay = match overlay {
        Some(o) => Some((
            resample(&o.labels, &session.source.volume).map_err(|e| Error::Usage(e.to_string()))?,
            o,
        )),
        None => None,
    };
    let prepared = &session.twin.prepared;
    if let crate::engine::VolumeLayout::Bricked(_) = prepared.layout {
        return Err(Error::Usage(
            "slices need the whole volume on the GPU, and this one was bricked (--bricked, or a \
             --memory-budget too small for it): drop --bricked or raise --memory-budget"
                .into(),
        ));
    }
    let geometry = geometry_of(prepared)?;
    let plane = plane_of(args.plane);
    let convention = convention_of(args.convention);
    let position = match (args.index, args.mm) {
        (Some(index), _) => {
            position_of_index(&geometry, plane, index).map_err(|e| Error::Usage(e.to_string()))?
        }
        (None, Some(mm)) => {
            position_of_mm(&geometry, plane, mm).map_err(|e| Error::Usage(e.to_string()))?
        }
        (None, None) => centre_position(&geometry, plane),
    };
    let pixel_mm = args.pixel_mm.unwrap_or(geometry.voxel_mm);
    let grid = SliceGrid::new(&geometry, plane, convention, position, pixel_mm)
        .map_err(|e| Error::Usage(e.to_string()))?;
    let slicer = Slicer::new(&session.engine)?;
    let mut image = slicer.render(&session.engine, prepared, &grid, window)?;
    for px in image.rgba8.chunks_exact_mut(4) {
        px[3] = 255; // outside the volume: opaque black in a picture
    }
    if let Some((labels, o)) = &overlay {
        let index = grid.in_index_space(&geometry);
        let none = Default::default();
        let drawn = blend_slice(&mut image.rgba8, &index, labels, &o.table, o.opacity, &none);
        print_line(&format!("overlay: {drawn} labelled pixels"));
    }
    if !layers.is_empty() {
        let index = grid.in_index_space(&geometry);
        let drawn =
            super::layer_args::blend_over(&mut image.rgba8, &index, &prepared.affine, &layers);
        for (layer, count) in layers.iter().zip(drawn) {
            print_line(&format!("layer {}: {count} pixels drawn", layer.grid.name));
        }
    }
    let letters = edge_letters(plane, convention);
    if args.letters
        && !super::glyphs::burn_edge_letters(&mut image.rgba8, grid.width, grid.height, letters)
    {
        eprintln!(
            "morphray: note: the {}x{} picture is too small for orientation letters; use a \
             smaller --pixel-mm",
            grid.width, grid.height
        );
    }
    let parameters = serde_json::json!({
        "engine": format!("morphray {}", env!("CARGO_PKG_VERSION")),
        "input": session.source.label,
        "arguments": args,
        "plane": plane,
        "convention": convention,
        "position_mm": position,
        "index_axis": index_axis(&geometry, plane),
        "pixel_mm": pixel_mm,
        "window_inorm": [window.0, window.1],
        "edge_letters": letters.iter().collect::<String>(),
        "normalization": session.report.table1(),
        "device": session.engine.device().adapter().name,
    });
    let provenance = Provenance {
        scene: None,
        input: session.source.label.clone(),
        input_sha256: session.source.sha256.clone().unwrap_or_default(),
        command: std::env::args().collect::<Vec<_>>().join(" "),
        parameters: parameters.to_string(),
        warnings: session.source.volume.warnings.clone(),
    };
    write_rgba8(
        &args.output,
        grid.width,
        grid.height,
        &image.rgba8,
        &provenance,
    )?;
    let axis = ["x", "y", "z"][plane.normal_axis()];
    print_line(&format!(
        "wrote {} ({} {axis} = {position:.3} mm, {}x{} px at {pixel_mm:.3} mm, slice {:.3} ms GPU)",
        args.output.display(),
        plane.name(),
        grid.width,
        grid.height,
        ms(image.gpu_ms)
    ));
    print_line(&format!("convention: {}", convention.describe()));
    if global.validation {
        super::session::check_validation(&session.engine)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_parse_and_bad_ones_are_usage_errors() {
        assert_eq!(parse_window("0.1:0.9").unwrap(), (0.1, 0.9));
        assert_eq!(parse_window(" 0 : 1 ").unwrap(), (0.0, 1.0));
        for bad in ["0.5", "0.9:0.1", "a:b", "0:inf", "NaN:1", "0.5:0.5"] {
            assert!(matches!(parse_window(bad), Err(Error::Usage(_))), "{bad}");
        }
    }
}
