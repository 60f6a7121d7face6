//! The viewer's frame loop, independent of how frames reach the screen (a window's swapchain or
//! an offscreen image): loader replies, script actions, the interface, the raymarch,
//! composition, screenshots, status and the session log.
//!
//! Decisions:
//! - Every volume is opened the library's way (the loader calls `Engine::open_with`): one plan
//!   within `--memory-budget` and `--profile`, whole or bricked (`--bricked`), exactly as
//!   `render` does; the status bar shows the layout and the plan's degradations, and the
//!   session log names them (`plan: ...`).
//! - The plan is made again only when the scene's needs change: an effect that needs other
//!   derived volumes is planned within the same budget (`Engine::replan`) and degraded as
//!   `render` would degrade it; a plan that needs another layout or I_norm format, or a bricked
//!   volume whose scene now sees bricks it does not hold (MIP, a tissue switched on), opens the
//!   volume again for the scene on screen, keeping the controls. Once per scene: the same
//!   failure twice is an error in the status line, never a loop. While a recomputation runs
//!   the previous derived volumes stay on screen, so the viewer briefly holds both sets (the
//!   engine's own `update_twin` frees first); the plan covers the larger set only.
//! - The volume on screen is an `engine::Twin`, and derived volumes follow the twin's update
//!   rule (`engine::twin_step`): a step that needs no GPU work (drop the normals, free all for
//!   MIP) is applied at once (the frame that used them has been waited for); a
//!   recomputation runs on the loader thread while the previous effects stay on screen (the
//!   held volumes serve them: `Twin::serves`) and the status line says what is being computed.
//!   A result that arrives after the effects changed again is dropped.
//! - Interaction cost: a slider, toggle or camera move changes [`Controls::scene`]; the frame
//!   records it with `Engine::record_render` (the uniform buffer, the host-written occupancy
//!   bits, the raymarch) into the frame's one submission, to which the painter appends the
//!   composition (`paint.rs`).
//! - One raymarch target per frame in flight, so frame N+1's raymarch never writes the image
//!   frame N's composition may still be copying; a target is reused only after every frame that read it
//!   has finished. The 3D view is rendered at its own pixel size (the central rectangle), so
//!   panels never hide part of the volume.
//! - Without a script or --no-vsync, the raymarch runs only when the scene or the view size
//!   changed (the last image is reused), so an idle window costs no GPU time.
//! - A lost device or exhausted memory never ends the session: memory errors become a
//!   one-line message in the window (the volume stays); a lost device drops every GPU object,
//!   creates a new device (and surface, swapchain) and reloads the current file, with a message.
//!
//! Files: this one (state, the frame loop), `steps.rs` (loader replies, script steps),
//! `paint.rs` (the frame's GPU side, screenshots, device loss), `pick.rs` (depth picking),
//! `opening.rs` (opening files), `cine.rs` (4-D frames and playback),
//! `brain.rs` (brain extraction's panel state, log lines and slice outline),
//! `quality.rs` (adaptive quality while interacting: `app/adaptive.rs`), `config.rs` (how the
//! viewer was started).

mod brain;
mod cine;
mod config;
mod layers;
mod measures;
mod opening;
mod paint;
mod pick;
mod quality;
mod save_scene;
mod save_view;
mod slices;
mod steps;
mod text;

pub use save_view::MAX_SIDE as MAX_VIEW_SIDE;

pub use config::ViewerConfig;
pub use text::px_rect;
use text::{describe, peak_text};

use super::AppError;
use super::frame_log::{FrameLog, FrameRecord, Pending, Until};
use super::loader::{LoadedVolume, Loader, Reply, one_line};
use super::script::{Action, Runner, Step};
use super::status::{Loading, Status};
use super::ui::{self, Controls, Request};
use crate::engine::{Engine, EngineConfig, RenderTarget, TwinStep, twin_step};
use crate::files::png::{PngError, Provenance, write_rgba8};
use crate::files::write::{OutputKind, check_output};
use crate::gpu::swapchain::{Surface, Swapchain};
use crate::gpu::{Device, FRAMES_IN_FLIGHT, GpuError, PassTiming, Presentation, Recording};
use crate::passes::derivatives::DerivativeOutputs;
use crate::passes::present::{COMPOSITE_FORMAT, FrameSpec, Painter};
use crate::scene::layer::LayerSpec;
use crate::scene::{Effects, Scene, SceneRecipe, WindowSet};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// One device's GPU objects; dropped and rebuilt after a device loss.
struct Gpu {
    painter: Painter,
    /// One raymarch target per frame in flight: a new frame renders into one while the
    /// composition of the previous may still read the other.
    targets: [Option<RenderTarget>; FRAMES_IN_FLIGHT],
    engine: Engine,
    /// The slice panels' pipeline, created when a slice is first shown.
    slicer: Option<crate::engine::slice::Slicer>,
    /// The label overlay on the current volume's grid, for the 3D view.
    labels_3d: Option<Arc<crate::engine::LabelVolume>>,
    swapchain: Option<Swapchain>,
    surface: Option<Arc<Surface>>,
    device: Device,
}

impl Gpu {
    fn new(
        config: &EngineConfig,
        window: Option<&winit::window::Window>,
        size: [u32; 2],
        vsync: bool,
    ) -> Result<Gpu, AppError> {
        let mut presentation = Presentation::default();
        if let Some(window) = window {
            use raw_window_handle::HasDisplayHandle;
            let display = window
                .display_handle()
                .map_err(|e| AppError::Window(e.to_string()))?;
            let names =
                ash_window::enumerate_required_extensions(display.as_raw()).map_err(|e| {
                    AppError::Window(format!("no Vulkan surface for this display: {e}"))
                })?;
            for &name in names {
                // SAFETY: ash-window returns pointers to 'static NUL-terminated extension names.
                presentation
                    .surface_extensions
                    .push(unsafe { std::ffi::CStr::from_ptr(name) });
            }
            presentation.swapchain = true;
        }
        let device = Device::with_presentation(&config.device, &presentation)?;
        let engine = Engine::with_device(device.clone(), config.clone())?;
        let (surface, swapchain) = match window {
            Some(window) => {
                let surface = Arc::new(Surface::new(&device, window)?);
                let swapchain = Swapchain::new(&device, surface.clone(), size, vsync)?;
                (Some(surface), swapchain)
            }
            None => (None, None),
        };
        let painter = Painter::new(&device)?;
        Ok(Gpu {
            painter,
            targets: std::array::from_fn(|_| None),
            engine,
            slicer: None,
            labels_3d: None,
            swapchain,
            surface,
            device,
        })
    }
}

/// The volume on screen.
struct Current {
    /// The twin, report, plan and provenance of the volume.
    loaded: LoadedVolume,
    /// First frame of this volume done (time to first pixel measured).
    shown: bool,
}

/// What a frame asks of its host (the window loop).
#[derive(Default)]
pub struct FrameResult {
    /// egui's platform output (cursor, clipboard...), for the window.
    pub platform: Option<egui::PlatformOutput>,
    /// Seconds until egui wants another frame (animations), if any.
    pub repaint_after: Option<f64>,
    /// The session is over (script done, `close`, or --frames reached).
    pub exit: bool,
    /// Ask the window to take this inner size.
    pub resize: Option<[u32; 2]>,
}

/// The viewer.
pub struct Viewer {
    config: ViewerConfig,
    gpu: Option<Gpu>,
    loader: Loader,
    ctx: egui::Context,
    controls: Controls,
    status: Status,
    current: Option<Current>,
    pending_load: Option<(u64, String)>,
    pending_derive: Option<DerivativeOutputs>,
    /// Loader GPU work delivered since the last frame, shown first by the next one.
    arrived: Vec<(String, Vec<PassTiming>)>,
    next_id: u64,
    active_effects: Effects,
    last: Option<Rendered>,
    serial: u64,
    volume_frames: u64,
    /// Frames drawn with a volume loaded but no room for it (the panels fill a tiny window):
    /// they count towards `--frames`, or a scripted run at such a size would never end.
    empty_view_frames: u64,
    log: FrameLog,
    runner: Runner,
    synthetic: std::collections::VecDeque<Vec<egui::Event>>,
    screenshot_requests: Vec<PathBuf>,
    size: [u32; 2],
    exit: bool,
    /// Why the session cannot go on: the first volume failed to load in a run nobody watches
    /// (offscreen, or scripted with --frames), which would otherwise wait forever for a volume.
    fatal: Option<String>,
    /// No window: frames go to an offscreen image.
    offscreen: bool,
    /// The "nothing to show" message over the view, if any (logged when it changes).
    empty_message: Option<String>,
    inject_device_lost: bool,
    /// Frames left of a scripted `idle` (raymarch only on change, as interactively).
    idle_frames: u32,
    /// A scripted drag waiting for its first motion (its latency starts there).
    watch_drag: Option<String>,
    /// egui texture changes not yet applied (a skipped frame keeps them for the next).
    unapplied: egui::TexturesDelta,
    /// Host copies of egui's textures (re-sent to a new painter after a device loss).
    mirror: crate::passes::present::TextureMirror,
    /// Why the last raymarch was refused (out of memory, or bricks of another scene), so it is
    /// not retried every frame.
    render_blocked: Option<(Scene, [u32; 4])>,
    /// A load that opens the volume on screen again for its scene: its adoption keeps the
    /// controls as they are.
    keep_scene: Option<u64>,
    /// The look by modality of the volume on screen (`opening.rs`, `adopt_preset_look`).
    shown_preset: Option<crate::scene::Preset>,
    /// The scene the bricked volume was last opened again for.
    reopened_for: Option<SceneRecipe>,
    /// The frame of 4-D files shown now (`--frame`, then the 4-D panel's, playback's).
    frame: usize,
    /// Adaptive quality: the level of each frame's raymarch (`quality.rs`).
    adaptive: super::adaptive::Controller,
    /// 4-D: held frames, the frame change in progress, playback (`cine.rs`).
    cine: cine::CineState,
}

/// What the last raymarch rendered.
#[derive(Clone, Copy, Debug)]
struct Rendered {
    /// The scene as requested (the level's coarser step is not part of it).
    scene: Scene,
    rect: [u32; 4],
    /// The quality level it was rendered at, and the raymarch target's size at that level.
    level: super::adaptive::Level,
    size: [u32; 2],
    target: usize,
    volume: u64,
    overlay: u64,
}

impl Viewer {
    /// Starts the loader on the first file; the GPU comes with [`Viewer::attach`]. Fails on
    /// scene options that make no sense (same checks as `render`).
    pub fn new(config: ViewerConfig) -> Result<Viewer, AppError> {
        // The scene before any volume: options from the command line, no windows yet (they
        // come from each volume's histogram).
        config
            .recipe
            .check()
            .map_err(|e| AppError::Failed(e.to_string()))?;
        let empty = crate::analysis::analyze(&[0; 256], 0.0, 0.0, 0, 0);
        let scene = config.recipe.scene_for(&empty);
        let mut controls = Controls::new(scene);
        // The menus start from the command line's --modality, --contrast and --preset.
        controls.identity = crate::app::identity_panel::IdentityChoice {
            modality: config.engine.analysis.modality,
            contrast: config.engine.analysis.contrast,
            preset: config.recipe.preset,
        };
        controls.slices.layout = config.layout;
        controls.windows = match config.recipe.windows {
            WindowSet::Adaptive => ui::WindowSource::Adaptive,
            WindowSet::Paper => ui::WindowSource::Paper,
        };
        let loader = Loader::spawn(config.engine.clone());
        if !loader.is_running() {
            return Err(AppError::Failed("cannot start the loader thread".into()));
        }
        let mut status = Status::default();
        let label = config.source.label();
        status.loading = Some(Loading {
            label: label.clone(),
            stage: "starting".into(),
            since: config.started,
        });
        let mut recipe = config.recipe.clone();
        recipe.effects = scene.effects;
        loader.load(
            1,
            config.source.clone(),
            config.started,
            opening::open_options(recipe, config.size, config.series.clone(), config.frame),
        );
        let log = FrameLog::new(config.log);
        let runner = Runner::new(config.script.clone());
        let size = config.size;
        Ok(Viewer {
            gpu: None,
            loader,
            ctx: egui::Context::default(),
            active_effects: scene.effects,
            controls,
            status,
            current: None,
            pending_load: Some((1, label)),
            pending_derive: None,
            arrived: Vec::new(),
            next_id: 2,
            last: None,
            serial: 0,
            volume_frames: 0,
            empty_view_frames: 0,
            log,
            runner,
            synthetic: Default::default(),
            screenshot_requests: Vec::new(),
            size,
            exit: false,
            fatal: None,
            offscreen: false,
            empty_message: None,
            inject_device_lost: false,
            unapplied: Default::default(),
            watch_drag: None,
            idle_frames: 0,
            mirror: Default::default(),
            render_blocked: None,
            keep_scene: None,
            shown_preset: None,
            reopened_for: None,
            frame: config.frame,
            adaptive: super::adaptive::Controller::new(config.frame_budget_ms),
            cine: Default::default(),
            config,
        })
    }

    /// The egui context (the window integration feeds it).
    pub fn egui(&self) -> &egui::Context {
        &self.ctx
    }

    /// True when frames should follow each other without waiting for input (scripted runs,
    /// --no-vsync measurements, loads or derived volumes in progress).
    pub fn continuous(&self) -> bool {
        self.config.frames.is_some()
            || !self.config.vsync
            || !self.config.script.is_empty()
            || self.busy()
    }

    /// True when every frame runs the raymarch even if nothing changed: scripted runs and
    /// --no-vsync measure frames; otherwise an unchanged scene reuses the last image (a load
    /// in progress keeps the window redrawing its spinner without re-raymarching, which on a
    /// CPU device would take cores from the loader). A script's `idle` and `sleep` frames
    /// behave as an interactive window's.
    fn always_raymarch(&self) -> bool {
        (self.config.frames.is_some() || !self.config.vsync || !self.config.script.is_empty())
            && self.idle_frames == 0
            && !self.runner.sleeping()
    }

    fn busy(&self) -> bool {
        self.pending_load.is_some() || self.pending_derive.is_some() || self.cine.busy()
    }

    /// Creates the GPU objects (for `window`, or offscreen) and hands the device to the loader.
    pub fn attach(&mut self, window: Option<&winit::window::Window>) -> Result<(), AppError> {
        let mut gpu = Gpu::new(&self.config.engine, window, self.size, self.config.vsync)?;
        if let Some(matcap) = self.config.matcap.clone() {
            gpu.engine.set_matcap(matcap);
        }
        self.offscreen = window.is_none();
        self.status.device = gpu.device.adapter().name.clone();
        self.loader.provide_device(gpu.device.clone());
        self.log.say(&format!(
            "device: {}{}",
            self.status.device,
            match &gpu.swapchain {
                Some(s) => format!(
                    " (window {}x{}, {:?}, {:?})",
                    s.extent.width, s.extent.height, s.format, s.present_mode
                ),
                None => format!(" (offscreen {}x{})", self.size[0], self.size[1]),
            }
        ));
        self.gpu = Some(gpu);
        Ok(())
    }

    /// Handles a window resize (the swapchain follows on the next frame).
    pub fn resized(&mut self, size: [u32; 2]) {
        self.size = size;
    }

    /// Ends the session (window closed): stops the loader first, which may be mid-load.
    pub fn shutdown(&mut self) -> Result<(), AppError> {
        if self.pending_load.take().is_some() {
            self.log
                .say("closed during a load: the loader stops at its next phase boundary");
        }
        self.loader.shutdown();
        let waited = match &mut self.gpu {
            Some(gpu) => gpu.painter.wait_all().map_err(AppError::from),
            None => Ok(()),
        };
        // The last frames' composition times, for the log.
        self.flush_completed();
        waited
    }

    /// The session log's summary lines.
    pub fn summary(&self) -> Vec<String> {
        self.log.summary()
    }

    /// Why an unattended session ended early (its first volume failed to load), if it did.
    pub fn fatal_error(&self) -> Option<&str> {
        self.fatal.as_deref()
    }

    /// Validation errors reported on the current device.
    pub fn validation_errors(&self) -> Vec<String> {
        match &self.gpu {
            Some(gpu) => gpu.device.validation_log().errors(),
            None => Vec::new(),
        }
    }

    /// True when the validation layer is active on the device.
    pub fn validation_enabled(&self) -> bool {
        self.gpu
            .as_ref()
            .is_some_and(|g| g.device.validation_enabled())
    }

    fn view_rect_points(&self) -> egui::Rect {
        self.ctx.memory(|m| {
            m.data
                .get_temp::<egui::Rect>(egui::Id::new("morphray view rect"))
                .unwrap_or(egui::Rect::from_min_size(
                    egui::pos2(ui::PANEL_WIDTH, 0.0),
                    egui::vec2(300.0, 300.0),
                ))
        })
    }

    /// The scene the raymarch renders now: the requested one with the effects that can be
    /// shown (derived volumes present); None without a volume.
    fn rendered_scene(&self) -> Option<Scene> {
        self.current.as_ref()?;
        let mut scene = self.controls.scene;
        scene.effects = self.active_effects;
        // The cut-away goes through the crosshair (the volume's centre before there is one).
        if let Some(cut) = &mut scene.cutaway {
            cut.point_mm = self.controls.slices.crosshair.map(|c| c.to_array());
        }
        Some(scene)
    }

    /// Runs one frame: `input` from the window (or synthetic offscreen input), `window` when
    /// presenting to one.
    pub fn frame(
        &mut self,
        mut input: egui::RawInput,
        window: Option<&winit::window::Window>,
    ) -> Result<FrameResult, AppError> {
        let frame_start = Instant::now();
        let mut result = FrameResult::default();
        let error_before = self.status.error.clone();
        self.poll_loader();

        // Script: at most one step per frame, never while loading or deriving or dragging.
        if self.synthetic.is_empty()
            && !self.controls.dragging
            && let Some(step) = self.runner.next_step(self.busy())
        {
            result.resize = self.apply(&step);
            if let Some(size) = result.resize
                && window.is_none()
            {
                self.size = size;
            }
        }
        if let Some(events) = self.synthetic.pop_front() {
            input.events.extend(events);
        }
        if window.is_none() {
            input.screen_rect = Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(self.size[0] as f32, self.size[1] as f32),
            ));
            input.time = Some(self.config.started.elapsed().as_secs_f64());
        }

        self.tick_cine();
        self.sync_brain();
        self.update_layers();
        self.update_slices();
        // The interface.
        let before_ui = self.rendered_scene();
        let constant_volume = self
            .current
            .as_ref()
            .is_some_and(|c| c.loaded.twin.prepared.normalization.constant);
        let shown = ui::Shown {
            status: &self.status,
            has_volume: self.current.is_some(),
            constant_volume,
        };
        // The empty-view message, logged when it changes (scripted runs and tests read it).
        let empty = self
            .current
            .as_ref()
            .and_then(|_| ui::empty_view_message(&self.controls.scene, constant_volume));
        if empty != self.empty_message {
            if let Some(message) = &empty {
                self.log.say(&format!("empty view: {message}"));
            }
            self.empty_message = empty;
        }
        let mut outcome: Option<ui::Outcome> = None;
        let controls = &mut self.controls;
        let full = self.ctx.run_ui(input, |ui| {
            // egui may run the interface twice in a frame (a discarded sizing pass); requests
            // (a click, a dropped file) come from whichever pass saw the input.
            let mut next = ui::draw(ui, controls, &shown);
            if let Some(previous) = outcome.take() {
                let mut requests = previous.requests;
                requests.append(&mut next.requests);
                requests.dedup();
                next.requests = requests;
            }
            outcome = Some(next);
        });
        let Some(outcome) = outcome else {
            return Err(AppError::Failed("the interface produced no frame".into()));
        };
        self.ctx.memory_mut(|m| {
            m.data
                .insert_temp(egui::Id::new("morphray view rect"), outcome.view);
            if let Some(h) = outcome.histogram {
                m.data
                    .insert_temp(egui::Id::new("morphray histogram rect"), h);
            }
        });
        self.note_input(before_ui, frame_start);
        if self.controls.dragging
            && let (Some(label), Some(before)) = (self.watch_drag.take(), before_ui)
        {
            self.log.pending.push(Pending {
                label,
                since: frame_start,
                until: Until::SceneChanges(Box::new(before)),
            });
        }
        for request in outcome.requests.clone() {
            match request {
                Request::Open(source) => {
                    // Another file starts at the command line's frame, not the slider's.
                    self.frame = self.config.frame;
                    self.open(source, None, None)
                }
                Request::Series(index) => self.open_series(index, None),
                Request::Screenshot(path) => self.screenshot_requests.push(path),
                Request::SaveView(path, size) => self.save_view(&path, size),
                Request::SaveScene(path) => self.save_scene(&path),
                Request::ExportMeasures(path) => self.export_measures(&path),
                Request::Frame(index) => self.open_frame(index, None),
                Request::Identity(choice) => self.reidentify(choice, None),
                Request::AddLayer(path) => self.add_layer(&LayerSpec {
                    path,
                    ..LayerSpec::default()
                }),
                Request::AddLabels(path) => self.add_labels(&path),
            }
        }
        self.request_derived();
        self.run_pick();
        self.update_measures();

        let ppp = full.pixels_per_point;
        if let Some(delay) = full
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .map(|v| v.repaint_delay.as_secs_f64())
        {
            result.repaint_after = Some(delay);
        }
        let size = match window {
            Some(w) => {
                let s = w.inner_size();
                [s.width, s.height]
            }
            None => self.size,
        };
        self.size = size;
        let view_rect = px_rect(outcome.view, ppp, size);
        if self.current.is_some() && (view_rect[2] == 0 || view_rect[3] == 0) {
            if self.empty_view_frames == 0 {
                self.log.say(&format!(
                    "the window ({}x{}) leaves no room for the volume beside the panels: \
                     nothing to raymarch until it is larger",
                    size[0], size[1]
                ));
            }
            self.empty_view_frames += 1;
        }

        // Exit decision before painting, so the last frame carries the screenshot copy.
        // Offscreen without --frames, the end of the script is the end (there is no window to
        // close); in a window, only --frames or the user ends it.
        let frames_done = match self.config.frames {
            Some(n) => self.volume_frames + self.empty_view_frames + 1 >= n as u64,
            None => window.is_none(),
        };
        let script_done = self.runner.finished() && self.synthetic.is_empty();
        let last =
            self.exit || (frames_done && script_done && !self.busy() && self.current.is_some());

        let primitives = self.ctx.tessellate(full.shapes, ppp);
        let mut textures = full.textures_delta;
        self.mirror.record(&textures);
        self.unapplied.append(std::mem::take(&mut textures));
        textures.clear();
        let frame = self.render_and_paint(
            window,
            size,
            view_rect,
            &primitives,
            ppp,
            last || !self.screenshot_requests.is_empty(),
            frame_start,
        );
        match frame {
            Ok(()) => {}
            Err(FrameError::Gpu(GpuError::DeviceLost(during))) => {
                self.device_lost(&during, window);
            }
            Err(FrameError::Gpu(e @ GpuError::OutOfDeviceMemory { .. })) => {
                self.status.error = Some(format!(
                    "{}; showing the last image (make the window smaller, or use a larger step)",
                    one_line(&e.to_string())
                ));
            }
            Err(FrameError::Gpu(GpuError::InvalidRequest(_))) if self.bricked_now() => {
                self.reopen_for_scene("the bricked volume holds the bricks of another scene");
            }
            Err(FrameError::Gpu(e)) => {
                self.status.error = Some(one_line(&e.to_string()));
            }
            Err(FrameError::App(e)) => return Err(e),
        }
        if self.status.error != error_before
            && let Some(error) = &self.status.error
        {
            self.log.say(&format!("error shown: {error}"));
        }
        self.flush_completed();
        self.refine_later(&mut result);
        self.cine_repaint(&mut result);
        self.idle_frames = self.idle_frames.saturating_sub(1);
        result.platform = Some(full.platform_output);
        if last {
            let path = self.config.screenshot.clone();
            if let Some(path) = path {
                self.screenshot_requests.push(path);
            }
            self.exit = true;
        }
        self.write_screenshots()?;
        result.exit = self.exit;
        Ok(result)
    }

    /// True once a frame showed a volume (tests).
    pub fn frames_shown(&self) -> u64 {
        self.volume_frames
    }

    /// The status line's error, if any.
    pub fn error(&self) -> Option<&str> {
        self.status.error.as_deref()
    }
}

/// Why a frame failed.
enum FrameError {
    Gpu(GpuError),
    App(AppError),
}

impl From<GpuError> for FrameError {
    fn from(e: GpuError) -> Self {
        FrameError::Gpu(e)
    }
}

impl From<AppError> for FrameError {
    fn from(e: AppError) -> Self {
        FrameError::App(e)
    }
}
