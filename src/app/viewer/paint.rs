//! One frame's GPU side: the raymarch recorded into the frame's one submission (when the scene
//! or the view changed), the composition and presentation by the painter, the frame log's
//! bookkeeping, screenshots with provenance, and recovery from a lost device.
//!
//! The raymarch runs at the frame's quality level (`quality.rs`): the level's step, into a
//! target of the level's size, which the composition stretches over the view's rectangle.

use super::*;

impl Viewer {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn render_and_paint(
        &mut self,
        window: Option<&winit::window::Window>,
        size: [u32; 2],
        view_rect: [u32; 4],
        primitives: &[egui::ClippedPrimitive],
        ppp: f32,
        screenshot: bool,
        frame_start: Instant,
    ) -> Result<(), FrameError> {
        let _span = crate::files::trace::span("viewer frame (record, compose, present)", "render");
        let scene = self.rendered_scene();
        let continuous = self.always_raymarch();
        let level = self.frame_level(screenshot);
        let Some(gpu) = &mut self.gpu else {
            return Ok(());
        };
        if size[0] == 0 || size[1] == 0 {
            // Minimized: nothing to draw into; keep the textures for later.
            return Ok(());
        }
        if self.inject_device_lost {
            self.inject_device_lost = false;
            return Err(FrameError::Gpu(GpuError::DeviceLost(
                "a frame (simulated by the script)".into(),
            )));
        }
        // The raymarch, recorded into the frame's one submission (the composition is appended
        // to it by the painter).
        let mut frame_recording: Option<Recording> = None;
        let mut fresh = false;
        if let (Some(current), Some(scene)) = (&self.current, scene)
            && view_rect[2] > 0
            && view_rect[3] > 0
        {
            let size = level.target_size(view_rect[2], view_rect[3]);
            let unchanged = self.last.is_some_and(|l| {
                l.scene == scene
                    && l.rect == view_rect
                    && l.level == level
                    && l.volume == current.loaded.id
                    && l.overlay == self.controls.slices.overlay_revision
            });
            let blocked = self.render_blocked == Some((scene, view_rect));
            if (!unchanged || continuous) && !blocked {
                let index = self
                    .last
                    .map(|l| (l.target + 1) % FRAMES_IN_FLIGHT)
                    .unwrap_or(0);
                gpu.painter.release_target(index)?;
                let fits = gpu.targets[index]
                    .as_ref()
                    .is_some_and(|t| t.width == size[0] && t.height == size[1]);
                if !fits {
                    gpu.targets[index] = None;
                    let mut target =
                        match gpu.engine.render_target(size[0], size[1], COMPOSITE_FORMAT) {
                            Ok(t) => t,
                            Err(e) => {
                                self.render_blocked = Some((scene, view_rect));
                                return Err(FrameError::Gpu(e));
                            }
                        };
                    target.read_back = false;
                    gpu.targets[index] = Some(target);
                }
                let Some(target) = gpu.targets[index].as_mut() else {
                    return Ok(());
                };
                super::slices::attach_labels(gpu.labels_3d.as_ref(), &self.controls.slices, target);
                let twin = &current.loaded.twin;
                let volume = (&*twin.prepared, current.loaded.id);
                let layers = &mut self.controls.layers;
                if let Err(e) =
                    super::layers::attach_layers(layers, &mut gpu.engine, volume, target)
                {
                    self.status.error = Some(e);
                }
                let mut rec = Recording::new(&gpu.device, "frame").map_err(FrameError::Gpu)?;
                match gpu.engine.record_render(
                    &mut rec,
                    target,
                    &twin.prepared,
                    twin.derived(),
                    &level.apply(&scene),
                ) {
                    // Nothing to read after the wait: the viewer keeps no pixels or counts, and
                    // the pass times come back with the composition's.
                    Ok(_recorded) => frame_recording = Some(rec),
                    Err(e) => {
                        // Out of memory, or a scene a bricked volume's resident bricks cannot
                        // show: retrying the same scene every frame would fail the same way.
                        if matches!(
                            e,
                            GpuError::OutOfDeviceMemory { .. } | GpuError::InvalidRequest(_)
                        ) {
                            self.render_blocked = Some((scene, view_rect));
                        }
                        return Err(FrameError::Gpu(e));
                    }
                }
                self.render_blocked = None;
                fresh = true;
                self.last = Some(Rendered {
                    scene,
                    rect: view_rect,
                    level,
                    size,
                    target: index,
                    volume: current.loaded.id,
                    overlay: self.controls.slices.overlay_revision,
                });
            }
        }
        let shown = self.last.filter(|l| {
            self.current
                .as_ref()
                .is_some_and(|c| c.loaded.id == l.volume)
        });
        let target = shown.and_then(|l| {
            gpu.targets[l.target]
                .as_ref()
                .filter(|t| t.width == l.size[0] && t.height == l.size[1])
                .map(|t| (t.image().clone(), l.rect, l.target))
        });

        // Window image.
        let slot = gpu.painter.next_slot();
        gpu.painter.wait_slot(slot)?;
        let mut acquired = None;
        if window.is_some() {
            let Some(swapchain) = gpu.swapchain.as_mut() else {
                // No swapchain yet (the window had no area): try again.
                if let Some(surface) = &gpu.surface {
                    gpu.swapchain =
                        Swapchain::new(&gpu.device, surface.clone(), size, self.config.vsync)?;
                }
                return Ok(());
            };
            if (swapchain.extent.width != size[0] || swapchain.extent.height != size[1])
                && !swapchain.recreate(size)?
            {
                return Ok(());
            }
            match swapchain.acquire(slot)? {
                Some(a) => acquired = Some(a),
                None => {
                    swapchain.recreate(size)?;
                    return Ok(());
                }
            }
        }
        let background = self.controls.scene.background;
        let serial = self.serial + 1;
        let spec = FrameSpec {
            serial,
            size,
            raymarch: target
                .as_ref()
                .map(|(image, rect, _)| (image, fresh, *rect)),
            target_index: target.as_ref().map(|t| t.2),
            clear: [background[0], background[1], background[2], 1.0],
            primitives,
            pixels_per_point: ppp,
            textures: std::mem::take(&mut self.unapplied),
            window: acquired,
            screenshot,
        };
        gpu.painter.paint(spec, frame_recording)?;
        self.serial = serial;
        if fresh {
            self.adaptive.submitted(serial, level);
        }
        if let (Some(swapchain), Some(a)) = (gpu.swapchain.as_mut(), acquired)
            && swapchain.present(&a)?
        {
            swapchain.recreate(size)?;
        }

        // Bookkeeping: log record, first pixel, action latencies.
        self.status.quality = shown.and_then(|l| l.level.status_words());
        if let (Some(current), Some(shown)) = (&mut self.current, shown) {
            self.volume_frames += 1;
            let compute = std::mem::take(&mut self.arrived);
            self.log.submitted(
                serial,
                FrameRecord {
                    number: self.volume_frames,
                    compute,
                    compose: Vec::new(),
                    cpu_ms: frame_start.elapsed().as_secs_f64() * 1e3,
                    complete: false,
                    quality: shown.level.describe(),
                },
            );
            let first = !current.shown;
            let resolves = self.log.would_resolve(&shown.scene, Some(shown.volume));
            if first || resolves {
                // Stamp the moment the GPU finished this frame.
                gpu.painter.wait_slot(slot)?;
                let now = Instant::now();
                if first {
                    current.shown = true;
                    let ms = now
                        .duration_since(current.loaded.requested_at)
                        .as_secs_f64()
                        * 1e3;
                    self.status.ttfp_ms = Some(ms);
                    self.log.say(&format!(
                        "time to first pixel of {}: {ms:.0} ms",
                        current.loaded.label
                    ));
                }
                self.log
                    .resolve(self.volume_frames, &shown.scene, Some(shown.volume), now);
            }
        }
        Ok(())
    }

    /// Logs frames whose composition finished, and adds their times to the status bar.
    pub(super) fn flush_completed(&mut self) {
        let Some(gpu) = &mut self.gpu else { return };
        let mut presented_volume = false;
        for done in gpu.painter.take_completed() {
            // A frame that raymarched reports its own raymarch; one that only recomposed keeps
            // the last raymarch's time on show.
            let raymarch = done.passes.iter().find(|p| p.name == "raymarch");
            self.adaptive
                .completed(done.serial, raymarch.map(|p| p.gpu_ms));
            let raymarched = raymarch.is_some();
            presented_volume |= raymarched;
            let mut passes: Vec<(String, f64)> = self
                .status
                .passes
                .iter()
                .filter(|(n, _)| n == "raymarch" && !raymarched)
                .cloned()
                .collect();
            passes.extend(done.passes.iter().map(|p| (p.name.clone(), p.gpu_ms)));
            self.status.passes = passes;
            self.log.completed(done.serial, done.passes);
        }
        if presented_volume {
            // The status bar's rate counts volume frames the user saw, not interface frames
            // nor frames that finished together (on a slow device several complete between two
            // looks, and only the last is on screen: counting each read 12536 volume FPS
            // beside 6.4 s frames).
            self.status.rate.frame(std::time::Instant::now());
        }
    }

    pub(super) fn write_screenshots(&mut self) -> Result<(), AppError> {
        if self.screenshot_requests.is_empty() {
            return Ok(());
        }
        let Some(gpu) = &mut self.gpu else {
            return Ok(());
        };
        let (w, h, pixels) = match gpu.painter.screenshot() {
            Ok(p) => p,
            Err(e) => {
                self.status.error =
                    Some(format!("Screenshot failed: {}", one_line(&e.to_string())));
                self.screenshot_requests.clear();
                return Ok(());
            }
        };
        self.flush_completed();
        for path in std::mem::take(&mut self.screenshot_requests) {
            let provenance = self.provenance(&folder_of(&path));
            // The same rules as `render -o` (right extension, never over the open file); the
            // write itself is atomic.
            let input = self.current.as_ref().map(|c| c.loaded.source.clone());
            let inputs: Vec<&std::path::Path> =
                input.as_ref().map(|s| s.paths()).unwrap_or_default();
            let written = check_output(&path, OutputKind::Png, &inputs, false)
                .map_err(PngError::from)
                .and_then(|()| write_rgba8(&path, w, h, &pixels, &provenance));
            match written {
                Ok(()) => {
                    self.log.say(&format!("wrote {} ({w}x{h})", path.display()));
                    self.status.note = Some(format!("Saved {}", path.display()));
                }
                Err(e) => {
                    // Also on stderr: a scripted run has no one reading the status bar.
                    let text = one_line(&e.to_string());
                    if self.config.log {
                        eprintln!("morphray: screenshot failed: {text}");
                    }
                    self.status.error = Some(text);
                }
            }
        }
        Ok(())
    }

    pub(super) fn provenance(&self, folder: &std::path::Path) -> Provenance {
        let (input, sha, warnings) = match &self.current {
            Some(c) => (
                c.loaded.label.clone(),
                c.loaded.sha256.clone(),
                c.loaded.warnings.clone(),
            ),
            None => (String::new(), String::new(), Vec::new()),
        };
        let parameters = serde_json::json!({
            "engine": format!("morphray {}", env!("CARGO_PKG_VERSION")),
            "input": input,
            "viewer": true,
            "window_size": self.size,
            "scene": self.rendered_scene(),
            "device": self.status.device,
        });
        Provenance {
            input,
            input_sha256: sha,
            command: self.config.command.clone(),
            parameters: parameters.to_string(),
            warnings,
            scene: self.scene_document(folder).map(|d| d.to_json()),
        }
    }

    /// After a device loss: drop every GPU object, make a new device, reload the volume.
    pub(super) fn device_lost(&mut self, during: &str, window: Option<&winit::window::Window>) {
        let message = format!("The GPU device was lost during {during}");
        self.log.say(&format!("{message}; restarting the GPU"));
        // Stale frames and derived work belong to the old device.
        self.gpu = None;
        // The new painter has no textures: give it every texture egui sent so far.
        self.unapplied.clear();
        self.unapplied = self.mirror.full_upload();
        self.log.abandon_in_flight();
        self.adaptive.abandon_in_flight();
        self.last = None;
        self.pending_derive = None;
        self.status.deriving = None;
        let reload = self.current.take().map(|c| {
            (
                c.loaded.source.clone(),
                super::opening::shown_series(&c.loaded),
            )
        });
        match Gpu::new(&self.config.engine, window, self.size, self.config.vsync) {
            Ok(gpu) => {
                self.loader.provide_device(gpu.device.clone());
                self.gpu = Some(gpu);
                if let Some((source, series)) = reload {
                    self.open(source, series, None);
                }
                self.status.error = Some(format!(
                    "{message}; the GPU was restarted and the volume is being reloaded"
                ));
            }
            Err(e) => {
                self.status.error = Some(format!(
                    "{message}, and it could not be restarted: {}",
                    one_line(&e.to_string())
                ));
                self.log.say(self.status.error.as_deref().unwrap_or(""));
                self.exit = true;
            }
        }
    }
}

/// The folder of a file the viewer writes (the working directory for a bare name).
pub(super) fn folder_of(path: &std::path::Path) -> std::path::PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    }
}
