//! `morphray render`: one PNG (or a turntable of PNGs) of a volume, with provenance.
//!
//! Decisions:
//! - Every output path (each turntable frame's too) is checked before the volume is loaded or a
//!   device opened (`files::write::check_output`): a wrong extension, a missing or read-only
//!   directory, a device or the input itself as the output fail in milliseconds, not after the
//!   render.
//! - Notes about tissues without a peak are printed in DVR mode only: they are about the
//!   classification, which MIP and MinIP do not use.
//! - One note line about the contrast when it matters, in DVR only like the tissue notes:
//!   tissues labelled for another order than T1's (T2, PD, FLAIR, CT; from whatever basis), or
//!   T1 only assumed although tissue peaks were found (conflicting evidence). With `--windows
//!   paper` on such a volume the same line warns that those are T1 windows. A T1 from the
//!   metadata, the histogram or `--contrast`, or a volume without tissue peaks, gets no
//!   contrast note.
//! - When no tissue class was found and the foreground is shown instead (`analysis::fallback`),
//!   one note line says so (DVR only); the empty-image note stays for scenes that are empty.
//! - The PNG's provenance records the modality and the contrast with their bases and reasons,
//!   and the fallback when there was one.

use super::args::{
    ClassificationArg, GradientArg, ModeArg, PrecisionArg, ProjectionArg, RenderArgs, SceneArgs,
    Switch, WindowsArg,
};
use super::output::{ms, print_line, print_warnings};
use super::scene_args::{Channel, LightingArg};
use super::scene_file::folder_of;
use super::session;
use crate::analysis::{Contrast, ContrastBasis, TissueReport};
use crate::error::Error;
use crate::files::png::{Provenance, write_rgba8};
use crate::files::write::{OutputKind, check_output};
use crate::scene::visibility::{EmptyScene, pixels_off_background, predict_empty};
use crate::scene::{
    Camera, DerivedPrecision, GradientSource, LightModel, Projection, RenderMode, Scene,
    SceneRecipe, TissueClass, VesselStyle, WindowSet,
};
use ash::vk;
use std::path::{Path, PathBuf};

/// The tissue entries of a `--window`/`--opacity`/`--color` list, in order.
fn tissues_only<'a, T, V: 'a>(
    entries: &'a [T],
    split: impl Fn(&T) -> (Channel, V) + 'a,
) -> impl Iterator<Item = (TissueClass, V)> + 'a {
    entries.iter().filter_map(move |e| match split(e) {
        (Channel::Tissue(t), v) => Some((t, v)),
        (Channel::Vessels | Channel::Head, _) => None,
    })
}

/// The head layer from `--tissues head` and the `head=` entries (later ones win).
fn head_recipe(args: &SceneArgs, visible: bool) -> crate::scene::classification::HeadRecipe {
    let mut head = crate::scene::classification::HeadRecipe {
        visible,
        ..Default::default()
    };
    for &(channel, lo, hi) in &args.window {
        if channel == Channel::Head {
            head.window = Some((lo, hi));
        }
    }
    for &(channel, x) in &args.opacity {
        if channel == Channel::Head {
            head.opacity = Some(x);
        }
    }
    for &(channel, rgb) in &args.color {
        if channel == Channel::Head {
            head.colour = Some(rgb);
        }
    }
    head
}

/// The vessel channel's style from the `vessels=` entries (later ones win), or None.
fn vessel_style(args: &SceneArgs) -> Option<VesselStyle> {
    let mut style = VesselStyle::default();
    let mut set = false;
    for &(channel, lo, hi) in &args.window {
        if channel == Channel::Vessels {
            style.window.lo = lo;
            style.window.hi = hi;
            set = true;
        }
    }
    for &(channel, x) in &args.opacity {
        if channel == Channel::Vessels {
            style.opacity = x;
            set = true;
        }
    }
    for &(channel, rgb) in &args.color {
        if channel == Channel::Vessels {
            style.colour = rgb;
            set = true;
        }
    }
    set.then_some(style)
}

/// The scene recipe the arguments describe (the library builds the scene from it around each
/// volume's analysis). Fails on an unknown tissue name and on what `SceneRecipe::check` refuses.
pub fn recipe_from_args(args: &SceneArgs) -> Result<SceneRecipe, Error> {
    let mut visible = Vec::new();
    let mut vessels = false;
    let mut head = false;
    for name in &args.tissues {
        if name.trim().is_empty() {
            continue;
        }
        if name.trim().eq_ignore_ascii_case("head") {
            head = true;
            continue;
        }
        if name.trim().eq_ignore_ascii_case("vessels") {
            vessels = true;
            continue;
        }
        let tissue = TissueClass::parse(name).ok_or_else(|| {
            Error::Usage(format!(
                "unknown tissue `{name}` in --tissues; use csf, gm, wm, pathology, vessels, head"
            ))
        })?;
        visible.push(tissue);
    }
    let mut effects = crate::scene::Effects {
        mode: match args.mode {
            ModeArg::Dvr => RenderMode::Dvr,
            ModeArg::Mip => RenderMode::Mip,
            ModeArg::Minip => RenderMode::MinIp,
        },
        curvature: args.curvature.on(),
        shading: args.shading.is_some_and(Switch::on),
        gradient_source: match args.gradient {
            GradientArg::Precomputed => GradientSource::Precomputed,
            GradientArg::OnTheFly => GradientSource::OnTheFly,
        },
        vessels: vessels && args.mode == ModeArg::Dvr,
        brain: if args.mode == ModeArg::Dvr {
            args.brain
        } else {
            crate::passes::brain::BrainSwitch::Off
        },
        lighting: crate::scene::Lighting {
            model: args
                .light_model_arg()
                .map_or(LightModel::Headlight, LightingArg::model),
            depth_cues: args.depth_cues.is_some_and(Switch::on),
        },
        ..Default::default()
    };
    effects.quality.derived_precision = match args.derived_precision {
        PrecisionArg::Snorm8 => DerivedPrecision::Snorm8,
        PrecisionArg::F16 => DerivedPrecision::F16,
        PrecisionArg::F32 => DerivedPrecision::F32,
    };
    effects.quality.classification = match args.classification {
        ClassificationArg::Exact => crate::scene::ClassificationLookup::Exact,
        ClassificationArg::Table => crate::scene::ClassificationLookup::Table,
        ClassificationArg::Volume => crate::scene::ClassificationLookup::Volume,
    };
    let recipe = SceneRecipe {
        windows: match args.windows {
            WindowsArg::Adaptive => WindowSet::Adaptive,
            WindowsArg::Paper => WindowSet::Paper,
        },
        // The default list leaves visibility to the preset (a CT shows bone, not "wm").
        visible: (!default_tissues(&args.tissues)).then_some(visible),
        window: tissues_only(&args.window, |&(c, lo, hi)| (c, (lo, hi)))
            .map(|(t, (lo, hi))| (t, lo, hi))
            .collect(),
        opacity: tissues_only(&args.opacity, |&(c, x)| (c, x)).collect(),
        colour: tissues_only(&args.color, |&(c, rgb)| (c, rgb)).collect(),
        vessel_style: vessel_style(args),
        head: head_recipe(args, head),
        camera: Camera {
            azimuth_deg: args.view.angles().map_or(args.azimuth, |a| a.0),
            elevation_deg: args.view.angles().map_or(args.elevation, |a| a.1),
            zoom: args.zoom,
            pan_mm: [args.pan.0, args.pan.1],
            projection: match args.projection {
                ProjectionArg::Perspective => Projection::Perspective { fov_y_deg: 30.0 },
                ProjectionArg::Orthographic => Projection::Orthographic,
            },
        },
        effects,
        cues: args.cues(),
        cutaway: args.clip.cutaway,
        step_voxels: args.step,
        jitter: !args.no_jitter,
        background: args.background,
        clip: args.clip.clip().map_err(Error::Usage)?,
        colormap: args.clip.colormap,
        denoise: args.denoise,
        preset: super::preset_arg::PresetArg::preset(args.preset),
        ..SceneRecipe::default()
    };
    recipe.check().map_err(|e| Error::Usage(e.0))?;
    Ok(recipe)
}

/// Whether `--tissues` is its default (csf,gm,wm), so the preset decides what is visible.
fn default_tissues(tissues: &[String]) -> bool {
    let names: Vec<String> = tissues
        .iter()
        .map(|t| t.trim().to_ascii_lowercase())
        .collect();
    names == ["csf", "gm", "wm"]
}

/// Tissues the user asked to see that this volume has no window for (peak not found).
pub fn missing_tissues(scene: &Scene) -> Vec<&'static str> {
    TissueClass::ALL
        .into_iter()
        .filter(|t| {
            let style = scene.classification.style(*t);
            style.visible && style.window.is_none()
        })
        .map(|t| t.name())
        .collect()
}

/// The one contrast note for `render` (module doc), without the `morphray: note: ` prefix.
pub fn contrast_note(report: &TissueReport, windows: WindowsArg) -> Option<String> {
    let c = &report.contrast;
    match (c.contrast, c.basis) {
        (contrast, _) if !contrast.is_t1_order() => {
            let paper = if windows == WindowsArg::Paper {
                format!(
                    "; --windows paper uses the paper's T1 windows, which select the wrong \
                     tissues on a {} volume: use --windows adaptive",
                    contrast.name()
                )
            } else {
                String::new()
            };
            Some(format!("tissues labelled for {}{paper}", c.summary()))
        }
        (Contrast::T1, ContrastBasis::Assumed) if report.peaks.wm.is_some() => {
            Some(format!("tissues labelled for {}", c.summary()))
        }
        _ => None,
    }
}

/// The line that says a 4-D series is shown as its mean frame.
pub fn epi_mean_line(frames: usize) -> String {
    format!("epi: mean of {frames} frames (`--frame N` shows one frame)")
}

/// Why `rgba8`, a frame of `scene`, shows only the background, and what to try; None when it
/// shows something. `constant`: the volume has one value (its normalization says so).
pub fn empty_note(scene: &Scene, constant: bool, rgba8: &[u8]) -> Option<String> {
    if pixels_off_background(rgba8, scene.background) != 0 {
        return None;
    }
    let why = predict_empty(scene, constant).unwrap_or(EmptyScene::NothingSampled);
    Some(format!(
        "the image shows only the background: {}; {}",
        why.reason(),
        what_to_try(&why, scene)
    ))
}

/// What to try on the command line for an empty image.
fn what_to_try(why: &EmptyScene, scene: &Scene) -> String {
    match why {
        EmptyScene::ConstantVolume => {
            "check the input (`morphray info FILE` shows its intensity range)".into()
        }
        EmptyScene::AllHidden => "show tissues with --tissues csf,gm,wm".into(),
        EmptyScene::NoWindow(_) => "try --windows paper, or set a window by hand with \
             --window TISSUE=LO:HI (I_norm units; `morphray peaks FILE` shows the histogram's \
             modes), or --mode mip"
            .into(),
        EmptyScene::ZeroOpacity(ts) => format!(
            "raise it with --opacity {}=0.5",
            ts.first().map_or("wm", |t| t.name())
        ),
        EmptyScene::NothingSampled if scene.effects.mode == RenderMode::Dvr => {
            "try other windows (--window TISSUE=LO:HI; `morphray peaks FILE` shows where the \
             modes are) or --mode mip"
                .into()
        }
        EmptyScene::NothingSampled => "try --mode dvr, or check the camera (--zoom, --pan)".into(),
    }
}

fn frame_path(output: &Path, index: u32) -> PathBuf {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".into());
    let name = format!("{stem}-{index:03}.png");
    output.with_file_name(name)
}

/// Where the picture goes: `-o`, or the input's name with `.png` in the current directory
/// (`scan.nii.gz` -> `scan.png`, a DICOM folder's name, `phantom.png` without an input). The
/// default never replaces a file without `--force`: it was not named, so it may be another
/// scan's picture.
fn output_path(args: &RenderArgs, files: &[PathBuf]) -> Result<PathBuf, Error> {
    if let Some(path) = &args.output {
        return Ok(path.clone());
    }
    let stem = super::derive::base_name(files.first().map(PathBuf::as_path));
    let path = PathBuf::from(format!("{stem}.png"));
    let taken = if args.turntable.is_some() {
        frame_path(&path, 0).exists()
    } else {
        path.exists()
    };
    if taken && !args.force {
        return Err(Error::Usage(format!(
            "{} exists (the default output, <input>.png): pass --force to replace it, or -o \
             to name another file",
            path.display()
        )));
    }
    Ok(path)
}

/// Runs the command.
pub fn run(args: &RenderArgs, global: &super::GlobalOptions) -> Result<(), Error> {
    let validation = global.validation;
    // A scene document replaces the scene options (src/cli/scene_file.rs).
    let loaded = args.scene_file.load(&args.scene)?;
    let files = loaded
        .as_ref()
        .map_or_else(|| args.file.clone(), |l| l.files(&args.file));
    let overlay_args = loaded
        .as_ref()
        .map_or_else(|| args.overlay.clone(), |l| l.overlay(&args.overlay));
    let layer_specs = match &loaded {
        Some(l) if args.layer.layers.is_empty() => l.doc.layer_specs(&l.origin),
        _ => args.layer.specs()?,
    };
    let output = output_path(args, &files)?;
    // 1..=10000 frames (clap checks): the paths below are held, and checked, all at once.
    let frames = args.turntable.unwrap_or(1);
    let paths: Vec<PathBuf> = match args.turntable {
        Some(_) => (0..frames).map(|i| frame_path(&output, i)).collect(),
        None => vec![output.clone()],
    };
    let mut inputs: Vec<&Path> = files.iter().map(|p| p.as_path()).collect();
    inputs.extend(overlay_args.inputs());
    inputs.extend(layer_specs.iter().map(|s| s.path.as_path()));
    // The label map, its table and the layers before any GPU work: a bad one fails at once.
    let overlay = overlay_args.load()?;
    let layers = super::layer_args::open_all(&layer_specs, print_line)?;
    // A turntable's -o names no file of its own, but `-o orbit.jpg` would still be a mistake.
    if args.turntable.is_some() && !OutputKind::Png.accepts(&output) {
        check_output(&output, OutputKind::Png, &inputs, false)?;
    }
    for path in &paths {
        check_output(path, OutputKind::Png, &inputs, false)?;
    }
    args.movie.check(&paths, &inputs)?;
    if let Some(path) = &args.scene_file.save_scene {
        check_output(path, OutputKind::Json, &inputs, false)?;
    }
    // A still is shaded unless asked otherwise (see --shading).
    let scene_args = args.scene.as_still();
    // On a terminal the spinner shows from the start: reading, extraction and the derived
    // volumes of a large scan take seconds before the first frame.
    let mut progress = super::progress::Progress::new(u64::from(frames), "frames");
    progress.message(&format!(
        "opening {} (read, prepare, analyse, derived volumes)",
        files
            .first()
            .map_or("the phantom".to_string(), |p| p.display().to_string())
    ));
    let mut opened = match &loaded {
        Some(l) => l.open(
            &files,
            (args.frame, args.scene.size),
            global.engine_config(),
        )?,
        None => session::open_frame(
            files.as_slice(),
            args.frame,
            true,
            global.engine_config(),
            Some(&scene_args),
            true,
        )?,
    };
    print_warnings(&opened.source.volume.warnings);
    if let Some(warning) = loaded
        .as_ref()
        .and_then(|l| l.hash_warning(opened.source.sha256.as_deref()))
    {
        eprintln!("morphray: warning: {warning}");
    }
    // The planned scene: the arguments' scene with any degradation the budget required.
    let base = opened.scene;
    let classified = base.effects.mode == RenderMode::Dvr;
    // With the foreground fallback, its one line says that no tissue class was found.
    let fallback = opened.report.fallback.is_some();
    for name in missing_tissues(&base)
        .into_iter()
        .filter(|_| classified && !fallback)
    {
        eprintln!(
            "morphray: note: no {name} peak was found in this volume, so {name} cannot be shown"
        );
    }
    if let Some(note) = contrast_note(&opened.report, args.scene.windows).filter(|_| classified) {
        eprintln!("morphray: note: {note}");
    }
    if let Some(fallback) = opened.report.fallback.as_ref().filter(|_| classified) {
        eprintln!("morphray: note: {}", fallback.reason);
    }
    let chosen = recipe_from_args(&scene_args)?.preset_for(&opened.report);
    let preset = chosen.label(&opened.report);
    match &loaded {
        Some(l) => print_line(&format!(
            "scene: {} (scene document version {})",
            l.origin.display(),
            l.doc.version
        )),
        None => {
            let why = chosen
                .why(&opened.report)
                .filter(|_| scene_args.preset.is_none())
                .map_or(String::new(), |why| format!(": {why}"));
            print_line(&format!("preset: {preset} ({}){why}", chosen.summary()));
        }
    }
    let mean_of_frames = opened.source.header.as_ref().and_then(|h| h.mean_of_frames);
    if let Some(n) = mean_of_frames {
        print_line(&epi_mean_line(n));
    }
    if !classified {
        // What the projection's grey levels span (issue 32 item 5): the robust range of a
        // projection ends at the 99.99th percentile, so the brightest structures stay graded.
        let r = &opened.report;
        print_line(&format!(
            "range: {} {:.4}..{:.4} (I_norm 0..1; `--normalize minmax` for the full range)",
            r.range.mode.name(),
            r.imin,
            r.imax
        ));
    }
    let (width, height) = match &loaded {
        Some(l) => l.size(args.scene.size),
        None => args.scene.size.unwrap_or((1024, 1024)),
    };
    let mut target = opened
        .engine
        .render_target(width, height, vk::Format::R8G8B8A8_UNORM)?;
    if let Some(overlay) = &overlay {
        let volume = &opened.source.volume;
        let prepared = opened.twin.prepared.clone();
        let count = super::overlay::attach_to_render(
            overlay,
            volume,
            &mut opened.engine,
            (&prepared, &opened.plan),
            &mut target,
        )?;
        if classified {
            print_line(&format!("overlay: {count} labels drawn in 3D"));
        } else {
            eprintln!(
                "morphray: note: --overlay is drawn in DVR only; MIP and MinIP show intensities"
            );
        }
    }
    if !layers.is_empty() {
        let prepared = opened.twin.prepared.clone();
        super::layer_args::attach_to_render(
            &layers,
            &mut opened.engine,
            (&prepared, &opened.plan),
            &mut target,
        )?;
        if !classified {
            eprintln!(
                "morphray: note: --layer is drawn in DVR only; MIP and MinIP show intensities"
            );
        }
    }
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    // What the pictures' scene documents record besides the scene.
    let frame_index = args
        .frame
        .or(loaded.as_ref().map(|l| l.doc.input.frame))
        .unwrap_or(0);
    let matcap = match &loaded {
        Some(l) => l.doc.matcap_source(&l.origin),
        None => args.scene.matcap.clone(),
    };
    let mut said_empty = false;
    let mut movie = super::movie::Movie::default();
    progress.message(&format!("rendering {width}x{height}"));
    for (index, path) in (0..frames).zip(&paths) {
        let mut scene = base;
        if args.turntable.is_some() {
            scene.camera.azimuth_deg =
                base.camera.azimuth_deg + 360.0 * index as f64 / frames as f64;
            scene.frame = index;
        }
        let frame = opened
            .engine
            .render_twin(&mut target, &mut opened.twin, &scene)?;
        let brain = opened
            .twin
            .derived()
            .and_then(|d| d.brain.as_ref())
            .filter(|_| classified)
            .map(|b| b.report.clone());
        if index == 0 {
            // After the first frame: its pipelines are all compiled now.
            session::persist_pipeline_cache(&opened.engine);
            if let Some(report) = &brain {
                print_line(&report.summary());
            }
        }
        let parameters = serde_json::json!({
            "engine": format!("morphray {}", env!("CARGO_PKG_VERSION")),
            "input": opened.source.label,
            "frame_of_4d_file": mean_of_frames.map_or_else(
                || serde_json::json!(args.frame.unwrap_or(0)),
                |n| serde_json::json!(format!("mean of {n} frames")),
            ),
            "arguments": scene_args,
            "turntable_index": args.turntable.map(|_| index),
            "scene": scene,
            "device": opened.engine.device().adapter().name,
            "layout": opened.plan.layout,
            "normalized_format": format!("{:?}", opened.plan.normalized_format),
            "normalization": opened.report.table1(),
            "modality": opened.report.modality,
            "contrast": opened.report.contrast,
            "fallback": opened.report.fallback,
            "preset": preset,
            "brain": brain,
            "degradations": opened.plan.degradations,
            "overlay": args.overlay,
            "layers": layers.iter().map(|l| l.describe()).collect::<Vec<_>>(),
        });
        let parts = super::scene_file::PictureParts {
            input: (&files, frame_index, opened.source.sha256.as_deref()),
            matcap: matcap.as_deref(),
            denoise: loaded
                .as_ref()
                .map_or(scene_args.denoise, |l| l.doc.denoise),
            overlay: &overlay_args,
            layers: &layers,
            size: (width, height),
            measurements: loaded.as_ref().map_or(&[], |l| &l.doc.measurements),
        };
        let document = super::scene_file::picture_document(&scene, &parts, &folder_of(path));
        if index == 0
            && let Some(save) = &args.scene_file.save_scene
        {
            let doc = super::scene_file::picture_document(&scene, &parts, &folder_of(save));
            doc.write(save, &inputs)?;
            print_line(&format!("wrote {} (scene document)", save.display()));
        }
        let provenance = Provenance {
            scene: Some(document.to_json()),
            input: opened.source.label.clone(),
            input_sha256: opened.source.sha256.clone().unwrap_or_default(),
            command: command.clone(),
            parameters: parameters.to_string(),
            warnings: opened.source.volume.warnings.clone(),
        };
        write_rgba8(path, frame.width, frame.height, &frame.rgba8, &provenance)?;
        let size = (frame.width, frame.height);
        movie.push(&args.movie, frames, size, &frame.rgba8, &provenance)?;
        progress.step();
        let constant = opened.twin.prepared.normalization.constant;
        if let Some(note) = empty_note(&scene, constant, &frame.rgba8).filter(|_| !said_empty) {
            // Never a silent empty image (the exit status stays 0: the scene may mean it).
            eprintln!("morphray: note: {note}");
            said_empty = true;
        }
        let gpu_ms: f64 = frame.gpu_timings.iter().map(|p| p.gpu_ms).sum();
        print_line(&format!(
            "wrote {} ({}x{}, raymarch {:.3} ms GPU)",
            path.display(),
            width,
            height,
            ms(gpu_ms)
        ));
    }
    progress.finish();
    movie.finish(&args.movie, frames)?;
    if validation {
        session::check_validation(&opened.engine)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::{ContrastReport, Peak, analyze};

    fn report(contrast: Contrast, basis: ContrastBasis, wm: bool) -> TissueReport {
        let mut r = analyze(&[0; crate::reference::BINS], 0.0, 1.0, 0, 0);
        r.contrast = ContrastReport::new(contrast, basis, "because".into());
        r.peaks.wm = wm.then(|| Peak::new(0.5, 0.0, 1.0));
        r
    }

    #[test]
    fn contrast_note_only_when_the_labels_are_t2_or_an_assumption() {
        use crate::analysis::Basis::{Assumed, Given as Forced, Histogram as Detected, Metadata};
        let note = |c, b, wm, w| contrast_note(&report(c, b, wm), w);
        let adaptive = WindowsArg::Adaptive;
        assert_eq!(note(Contrast::T1, Detected, true, adaptive), None);
        assert_eq!(note(Contrast::T1, Forced, true, WindowsArg::Paper), None);
        // No tissue peak: nothing was labelled, the tissue notes already say so.
        assert_eq!(note(Contrast::T1, Assumed, false, adaptive), None);
        let assumed = note(Contrast::T1, Assumed, true, adaptive).unwrap();
        assert_eq!(assumed, "tissues labelled for T1 (assumed): because");
        let t2 = note(Contrast::T2, Forced, true, adaptive).unwrap();
        assert_eq!(t2, "tissues labelled for T2 (given): because");
        let paper = note(Contrast::T2, Detected, true, WindowsArg::Paper).unwrap();
        assert!(
            paper.contains("T2 (histogram)") && paper.contains("T1 windows"),
            "{paper}"
        );
        assert_eq!(note(Contrast::T1, Metadata, true, adaptive), None);
        let flair = note(Contrast::Flair, Metadata, true, WindowsArg::Paper).unwrap();
        assert!(
            flair.contains("FLAIR (metadata)") && flair.contains("on a FLAIR volume"),
            "{flair}"
        );
        assert_eq!(paper.lines().count(), 1);
    }
}
