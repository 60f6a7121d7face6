//! The window: winit's event loop, egui-winit input, redraw scheduling, resize and close.
//!
//! Decisions:
//! - winit 0.30's `ApplicationHandler`: the window (and with it the Vulkan surface, device and
//!   swapchain) is created in `resumed`, as winit requires on every platform.
//! - Input goes through egui-winit into egui, and the viewer reads the camera gestures from
//!   egui's responses, so a drag that starts on a slider never orbits the volume.
//! - Redraws: continuously in scripted runs, with --no-vsync, and while a load or a derived
//!   volume is in progress; otherwise only on input or when egui asks for one (animations),
//!   so an idle viewer uses no CPU (this matters on a CPU Vulkan device).
//! - Closing the window stops the loader thread first (it may be mid-load) and waits for the
//!   frames in flight; then everything is dropped in order (GPU objects before the window).

use super::AppError;
use super::viewer::Viewer;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::window::{Window, WindowId};

struct App {
    // Dropped first: GPU objects (surface) before the window they draw into.
    viewer: Viewer,
    egui: Option<egui_winit::State>,
    window: Option<Window>,
    size: [u32; 2],
    error: Option<AppError>,
    repaint_at: Option<Instant>,
}

/// Runs the viewer in a window until it is closed or the script ends.
pub fn run(viewer: Viewer, size: [u32; 2]) -> Result<Viewer, AppError> {
    let event_loop = EventLoop::new().map_err(|e| AppError::Window(e.to_string()))?;
    let mut app = App {
        viewer,
        egui: None,
        window: None,
        size,
        error: None,
        repaint_at: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| AppError::Window(e.to_string()))?;
    let App {
        mut viewer, error, ..
    } = app;
    let closed = viewer.shutdown();
    match error {
        Some(e) => Err(e),
        None => closed.map(|()| viewer),
    }
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, error: AppError) {
        if self.error.is_none() {
            self.error = Some(error);
        }
        event_loop.exit();
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let (Some(window), Some(state)) = (&self.window, &mut self.egui) else {
            return;
        };
        let input = state.take_egui_input(window);
        match self.viewer.frame(input, Some(window)) {
            Ok(result) => {
                if let Some(platform) = result.platform {
                    state.handle_platform_output(window, platform);
                }
                if let Some([w, h]) = result.resize {
                    let _ = window.request_inner_size(PhysicalSize::new(w, h));
                }
                self.repaint_at = result
                    .repaint_after
                    .filter(|s| s.is_finite() && *s < 60.0)
                    .map(|s| Instant::now() + Duration::from_secs_f64(s));
                if result.exit {
                    event_loop.exit();
                }
            }
            Err(e) => self.fail(event_loop, e),
        }
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let attributes = Window::default_attributes()
            .with_title("morphray")
            .with_inner_size(PhysicalSize::new(self.size[0], self.size[1]));
        let window = match event_loop.create_window(attributes) {
            Ok(w) => w,
            Err(e) => return self.fail(event_loop, AppError::Window(e.to_string())),
        };
        let state = egui_winit::State::new(
            self.viewer.egui().clone(),
            egui::ViewportId::ROOT,
            &window,
            Some(window.scale_factor() as f32),
            window.theme(),
            // Vulkan guarantees 4096-texel 2D images on every device.
            Some(4096),
        );
        let inner = window.inner_size();
        self.viewer.resized([inner.width, inner.height]);
        if let Err(e) = self.viewer.attach(Some(&window)) {
            return self.fail(event_loop, e);
        }
        window.request_redraw();
        self.egui = Some(state);
        self.window = Some(window);
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let (Some(window), Some(state)) = (&self.window, &mut self.egui) else {
            return;
        };
        let response = state.on_window_event(window, &event);
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                self.viewer.resized([size.width, size.height]);
                window.request_redraw();
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            _ => {
                if response.repaint {
                    window.request_redraw();
                }
            }
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let Some(window) = &self.window else { return };
        if self.viewer.continuous() {
            event_loop.set_control_flow(ControlFlow::Poll);
            window.request_redraw();
        } else if let Some(at) = self.repaint_at {
            if at <= Instant::now() {
                self.repaint_at = None;
                window.request_redraw();
            } else {
                event_loop.set_control_flow(ControlFlow::WaitUntil(at));
            }
        } else {
            event_loop.set_control_flow(ControlFlow::Wait);
        }
    }
}
