//! The interactive viewer (`morphray view`): a window with the raymarched volume and an egui
//! interface over it, on the same engine as the command-line tools.
//!
//! One concern per file:
//!
//! ```text
//! window.rs          winit event loop, egui-winit input, redraw scheduling, close
//! ui.rs              panels: tissues, rendering, view, file, status bar; view input/overlays
//! histogram.rs       the I_norm histogram with peaks and draggable tissue windows
//! camera_control.rs  mouse/keys -> camera, orientation letters (views: scene/views.rs)
//! cine_panel.rs     4-D: frame slider, Play/Pause and fps, the time course at the crosshair
//! clip_panel.rs      crop sliders, one clip plane, colour map (edits Scene::clip/colormap)
//! colour_bar.rs      the colour map's bar over the 3D view, its ends in the file's units
//! frames_job.rs      4-D: frames held in memory, a frame prepared like the one on screen
//! loader.rs          worker thread: opens volumes the library's way (plan, whole or bricked,
//!                    analyse, derive), derives later effects (never the UI thread)
//! readout.rs         the crosshair's mm, voxel and value in the scanner's units (HU for CT)
//! identity_panel.rs  modality, contrast and preset menus and script steps (reopen as given)
//! script.rs          scripted actions for tests and demos
//! frame_log.rs       per-frame passes and action -> first-frame latencies
//! adaptive.rs        adaptive quality: coarser step/scale while interacting (--frame-budget)
//! status.rs          status line: file, dims, spacing, device, first pixel, volume FPS, GPU,
//!                    the memory plan (layout, degradations)
//! viewer/mod.rs      the frame loop tying these together, window or offscreen
//! viewer/opening.rs  volumes adopted, the twin's rule, plans made again, volumes reopened
//! ```
//!
//! Decisions:
//! - Continuous interaction fidelity (the paper's claim) is structural: interface changes edit
//!   a `Scene`, and a frame turns the scene into uniforms for one raymarch dispatch. Everything
//!   else (decoding, min/max, normalization, histogram, derived volumes) runs on the loader
//!   thread, once per volume or once per newly needed derived volume, and the scripted log
//!   shows it frame by frame.
//! - No Vulkan calls in this layer: the swapchain is `gpu::swapchain` and the frame composition
//!   (raymarch image + egui through egui-ash-renderer) is the present pass, `passes::present`;
//!   both exist only with the `viewer` feature.
//! - `--offscreen` runs the same frames without a window (no surface or swapchain): the frame
//!   is composed in the same image the window would show, so screenshots match.

pub mod adaptive;
pub mod brain_outline;
pub mod brain_panel;
pub mod camera_control;
pub mod cine_panel;
pub mod clip_panel;
pub mod colour_bar;
pub mod crosshair_3d;
pub mod file_panel;
pub mod frame_log;
pub mod frames_job;
pub mod histogram;
pub mod histogram_fit;
pub mod identity_panel;
pub mod layers_panel;
pub mod loader;
pub mod measure_panel;
pub mod readout;
pub mod script;
pub mod slices_panel;
pub mod status;
mod status_bar;
pub mod ui;
pub mod vessels_panel;
pub mod view_area;
pub mod viewer;
pub mod window;

use crate::gpu::GpuError;
pub use viewer::{Viewer, ViewerConfig};

/// Failures of the viewer.
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    /// No window could be opened (no display, no X server).
    #[error("cannot open a window: {0} (without a display, use --offscreen)")]
    Window(String),
    /// A script that does not parse.
    #[error(transparent)]
    Script(#[from] script::ScriptError),
    /// Vulkan.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// Anything else, one line.
    #[error("{0}")]
    Failed(String),
}

/// Runs the viewer (in a window, or offscreen) until the script ends or the window closes;
/// prints the session summary when logging, and fails on validation errors when asked to.
pub fn run(
    config: ViewerConfig,
    offscreen: bool,
    fail_on_validation: bool,
) -> Result<(), AppError> {
    let size = config.size;
    let log = config.log;
    let viewer = Viewer::new(config)?;
    let mut viewer = if offscreen {
        run_offscreen(viewer)?
    } else {
        window::run(viewer, size)?
    };
    if log {
        crate::files::stdout::print_line(&viewer.layout_line());
        for line in viewer.summary() {
            crate::files::stdout::print_line(&line);
        }
    }
    let errors = viewer.validation_errors();
    if viewer.validation_enabled() {
        crate::files::stdout::print_line(&format!("validation layer: {} error(s)", errors.len()));
    }
    viewer.shutdown()?;
    if let Some(message) = viewer.fatal_error() {
        return Err(AppError::Failed(format!(
            "cannot open the volume: {message}"
        )));
    }
    if fail_on_validation && !errors.is_empty() {
        return Err(AppError::Failed(format!(
            "the Vulkan validation layer reported {} error(s); first: {}",
            errors.len(),
            errors[0].lines().next().unwrap_or("")
        )));
    }
    Ok(())
}

fn run_offscreen(mut viewer: Viewer) -> Result<Viewer, AppError> {
    viewer.attach(None)?;
    loop {
        let result = viewer.frame(egui::RawInput::default(), None)?;
        if result.exit {
            break;
        }
    }
    viewer.shutdown()?;
    Ok(viewer)
}
