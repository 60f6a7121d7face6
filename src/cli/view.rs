//! `morphray view`: the interactive viewer (src/app), and its scripted mode for tests.

use super::args::ViewArgs;
use crate::app::{ViewerConfig, script};
use crate::error::Error;
use crate::gpu::Validation;
use std::time::Instant;

/// Runs the command.
pub fn run(args: &ViewArgs, global: &super::GlobalOptions) -> Result<(), super::CommandError> {
    let started = Instant::now();
    let steps = match &args.script {
        Some(path) => script::load(path).map_err(crate::app::AppError::from)?,
        None => Vec::new(),
    };
    if args.offscreen && args.frames.is_none() && steps.is_empty() {
        return Err(Error::Usage(
            "--offscreen has no window to close: give --frames N or --script FILE".into(),
        )
        .into());
    }
    if let Some(n) = args
        .frames
        .filter(|n| !(1..=script::MAX_FRAMES).contains(n))
    {
        return Err(Error::Usage(format!(
            "--frames {n}: give 1 to {} frames (a scripted run must end)",
            script::MAX_FRAMES
        ))
        .into());
    }
    // Before the window and the GPU: a script's screenshot that cannot be written fails now,
    // not silently in the status bar after the run.
    let mut inputs: Vec<&std::path::Path> = args.file.iter().map(|p| p.as_path()).collect();
    inputs.extend(args.overlay.inputs());
    let layer_paths = args.layer.inputs();
    inputs.extend(layer_paths.iter().map(|p| p.as_path()));
    for step in &steps {
        let (path, kind) = match &step.action {
            script::Action::Screenshot(path) | script::Action::SaveView(path, _) => {
                (path, crate::files::write::OutputKind::Png)
            }
            script::Action::SaveScene(path) => (path, crate::files::write::OutputKind::Json),
            script::Action::Measure(crate::app::measure_panel::MeasureStep::Export(path)) => {
                let csv = crate::files::write::OutputKind::Csv;
                let json = crate::files::write::OutputKind::Json;
                (path, if csv.accepts(path) { csv } else { json })
            }
            _ => continue,
        };
        {
            crate::files::write::check_output(path, kind, &inputs, false).map_err(|e| {
                let script = args
                    .script
                    .as_deref()
                    .unwrap_or(std::path::Path::new("script"));
                Error::Usage(format!(
                    "{}:{}: `{}`: {e}",
                    script.display(),
                    step.line,
                    step.text
                ))
            })?;
        }
    }
    if let Some(path) = &args.screenshot {
        // Before the window and the GPU: a screenshot that cannot be written fails now.
        let mut inputs: Vec<&std::path::Path> = args.file.iter().map(|p| p.as_path()).collect();
        inputs.extend(args.overlay.inputs());
        crate::files::write::check_output(
            path,
            crate::files::write::OutputKind::Png,
            &inputs,
            false,
        )
        .map_err(Error::from)?;
    }
    let document = super::scene_file::ViewDocument::load(args)?;
    let overlay = document.overlay.load()?;
    let engine = global.engine_config();
    let fail_on_validation = engine.device.validation == Validation::Required;
    let (width, height) = document.size;
    let scripted = args.frames.is_some() || !steps.is_empty();
    let config = ViewerConfig {
        source: crate::volume::source::VolumeSource::from_paths(&document.files),
        series: super::source::read_options(0, false).series,
        recipe: document.recipe,
        size: [width, height],
        vsync: !args.no_vsync,
        frames: args.frames,
        screenshot: args.screenshot.clone(),
        script: steps,
        engine,
        log: scripted,
        command: std::env::args().collect::<Vec<_>>().join(" "),
        started,
        overlay,
        frame: document.frame,
        frame_budget_ms: args.frame_budget,
        cine: crate::app::cine_panel::CineStart {
            play: args.play,
            fps: args.fps,
        },
        layout: document.layout,
        matcap: document.matcap,
        matcap_spec: document.matcap_spec,
        overlay_files: (document.overlay.overlay.clone()).map(|labels| {
            let o = &document.overlay;
            (labels, o.overlay_lut.clone(), o.overlay_opacity)
        }),
        crosshair_mm: document.crosshair_mm,
        measurements: document.measurements,
        layers: document.layers,
    };
    crate::app::run(config, args.offscreen, fail_on_validation)?;
    Ok(())
}
