//! What arrives between frames: the loader's replies (a volume opened, derived volumes computed,
//! errors) and the script's steps (actions, drags), applied to the viewer's state.

use super::*;

impl Viewer {
    pub(super) fn poll_loader(&mut self) {
        for reply in self.loader.poll() {
            match reply {
                Reply::Progress { id, stage } => {
                    if let (Some((pending, ..)), Some(loading)) =
                        (&self.pending_load, &mut self.status.loading)
                        && *pending == id
                    {
                        loading.stage = stage.to_string();
                    }
                }
                Reply::Frames(reply) => self.frame_reply(reply),
                Reply::Loaded(loaded) => {
                    if self.pending_load.as_ref().map(|p| p.0) != Some(loaded.id) {
                        continue;
                    }
                    self.adopt(*loaded);
                }
                Reply::LoadFailed { id, message } => {
                    if self.pending_load.as_ref().map(|p| p.0) != Some(id) {
                        continue;
                    }
                    self.pending_load = None;
                    self.status.loading = None;
                    let kept = if self.current.is_some() {
                        "; the previous volume stays"
                    } else {
                        ""
                    };
                    self.status.error = Some(format!("Cannot open: {message}{kept}"));
                    self.log.say(&format!("load failed: {message}"));
                    // An interactive window keeps running and shows the error (the user can
                    // open another file); a run nobody watches has nothing left to show.
                    if self.current.is_none() && (self.offscreen || self.config.frames.is_some()) {
                        self.fatal = Some(message.clone());
                        self.exit = true;
                    }
                    self.log
                        .pending
                        .retain(|p| p.until != Until::VolumeShown(id));
                }
                Reply::Derived {
                    id,
                    outputs,
                    derived,
                    brain_outline,
                } => {
                    let Some(current) = &mut self.current else {
                        continue;
                    };
                    if current.loaded.id != id {
                        continue;
                    }
                    self.pending_derive = None;
                    self.status.deriving = None;
                    // The twin's rule decides whether this result is still what is wanted.
                    let wanted = self.controls.scene.effects.derivative_outputs();
                    if twin_step(current.loaded.twin.outputs(), wanted)
                        != TwinStep::Recompute(outputs)
                    {
                        continue;
                    }
                    let ms: f64 = derived.gpu_timings.iter().map(|t| t.gpu_ms).sum();
                    let what = describe(outputs);
                    self.status.note = Some(format!(
                        "Computed the {what} once ({ms:.1} ms GPU); toggling it again is free"
                    ));
                    self.arrived.push((
                        format!("derived volume ({what}), computed once"),
                        derived.gpu_timings.clone(),
                    ));
                    current.loaded.twin.install(*derived);
                    current.loaded.brain_outline = brain_outline;
                }
                Reply::DeriveFailed {
                    id,
                    outputs,
                    message,
                    device_lost,
                } => {
                    if self.current.as_ref().map(|c| c.loaded.id) != Some(id) {
                        continue;
                    }
                    self.pending_derive = None;
                    self.status.deriving = None;
                    // Turn the effect back off so the scene stays renderable.
                    self.controls.scene.effects = self.active_effects;
                    self.status.error = Some(format!(
                        "Cannot compute the {}: {message}",
                        describe(outputs)
                    ));
                    if device_lost {
                        self.device_lost(&format!("computing the {}", describe(outputs)), None);
                    }
                }
            }
        }
    }

    pub(super) fn apply(&mut self, step: &Step) -> Option<[u32; 2]> {
        self.log
            .say(&format!("script line {}: {}", step.line, step.text));
        let before = self.rendered_scene();
        let c = &mut self.controls;
        let mut resize = None;
        let mut watch = true;
        match &step.action {
            Action::Toggle(t) => c.toggle(*t),
            Action::Show(t, v) => c.set_visible(*t, *v),
            Action::Vessels(v) => c.scene.effects.vessels = *v,
            Action::Brain(b) => c.scene.effects.brain = *b,
            Action::Head(v) => c.scene.classification.head.visible = *v,
            Action::HeadOpacity(o) => c.scene.classification.head.opacity = *o,
            Action::HeadColour(rgb) => c.scene.classification.head.colour = *rgb,
            Action::SetWindow(t, lo, hi) => c.set_window(*t, *lo, *hi),
            Action::Opacity(t, o) => c.set_opacity(*t, *o),
            Action::Colour(t, rgb) => c.set_colour(*t, *rgb),
            Action::Preset(p) => c.preset(*p),
            Action::Orbit(az, el) => c.orbit_degrees(*az, *el),
            Action::Pan(x, y) => {
                c.scene.camera.pan_mm[0] += x;
                c.scene.camera.pan_mm[1] += y;
            }
            Action::Zoom(f) => c.scene.camera.zoom = (c.scene.camera.zoom * f).clamp(0.1, 50.0),
            Action::View(v) => c.view(*v),
            Action::ResetView => {
                let camera = c.camera;
                camera.reset(&mut c.scene.camera);
            }
            Action::Drag { button, from, to } => {
                self.queue_drag(*button, *from, *to);
                // Timed from the frame whose input first moves the held mouse (below), not
                // from the synthetic press a few frames earlier.
                self.watch_drag = Some(step.text.clone());
                watch = false;
            }
            Action::Mode(m) => c.set_mode(*m),
            Action::Step(s) => c.scene.step_voxels = *s,
            Action::Curvature(on) => c.scene.effects.curvature = *on,
            Action::CurvatureStrength(s) => c.scene.curvature_strength = *s,
            Action::Shading(on) => c.scene.effects.shading = *on,
            Action::Lighting(model) => c.scene.effects.lighting.model = *model,
            Action::DepthCues(on) => c.scene.effects.lighting.depth_cues = *on,
            Action::Cutaway(on) => c.scene.cutaway = on.then(crate::scene::Cutaway::default),
            Action::Background(rgb) => c.scene.background = *rgb,
            Action::Crop(crop) => c.scene.clip.crop = *crop,
            Action::Clip(plane) => c.scene.clip.planes[0] = *plane,
            Action::Colormap(map) => c.scene.colormap = *map,
            Action::Open(source) => {
                self.frame = self.config.frame;
                self.open(source.clone(), None, Some(step.text.clone()));
                watch = false;
            }
            Action::Series(index) => {
                self.open_series(*index, Some(step.text.clone()));
                watch = false;
            }
            Action::Frame(index) => {
                self.open_frame(*index, Some(step.text.clone()));
                watch = false;
            }
            Action::Play(fps) => {
                c.cine.playing = true;
                c.cine.fps = fps.unwrap_or(c.cine.fps);
                watch = false;
            }
            Action::Pause => {
                c.cine.playing = false;
                watch = false;
            }
            Action::Identity(change) => {
                let choice = c.identity.with(*change);
                self.reidentify(choice, Some(step.text.clone()));
                watch = false;
            }
            Action::SaveView(path, size) => {
                self.save_view(path, *size);
                watch = false;
            }
            Action::SaveScene(path) => {
                self.save_scene(path);
                watch = false;
            }
            Action::Measure(step) => {
                self.measure_step(step);
                watch = false;
            }
            Action::Layer(step) => self.layer_step(step),
            Action::Labels(path) => self.add_labels(path),
            Action::Screenshot(path) => {
                self.screenshot_requests.push(path.clone());
                watch = false;
            }
            Action::Wait(_) | Action::Sleep(_) => watch = false,
            Action::Idle(n) => {
                // This frame and the n after it.
                self.idle_frames = n + 1;
                watch = false;
            }
            Action::Resize(w, h) => {
                resize = Some([*w, *h]);
                watch = false;
            }
            Action::Close => {
                self.exit = true;
                watch = false;
            }
            Action::SimulateDeviceLost => {
                self.inject_device_lost = true;
                watch = false;
            }
            // Slice steps change no 3D scene: nothing to time against the raymarch.
            Action::Layout(l) => {
                c.slices.layout = *l;
                watch = false;
            }
            Action::Convention(v) => {
                c.slices.convention = *v;
                watch = false;
            }
            Action::Crosshair(p) => {
                c.slices.crosshair = Some(glam::DVec3::from_array(*p));
                watch = false;
            }
            Action::Pick(at) => {
                c.pick = Some(*at);
                watch = false;
            }
            Action::Label(label, on) => {
                if *on {
                    c.slices.hidden.remove(label);
                } else {
                    c.slices.hidden.insert(*label);
                }
                c.slices.dirty = true;
                c.slices.overlay_revision += 1;
                watch = false;
            }
            Action::SliceWindow(lo, hi) => {
                c.slices.window = (*lo, *hi);
                watch = false;
            }
        }
        if watch && let Some(before) = before {
            self.log.pending.push(Pending {
                label: step.text.clone(),
                since: Instant::now(),
                until: Until::SceneChanges(Box::new(before)),
            });
        }
        resize
    }

    /// Synthetic pointer events of a drag over the 3D view, one batch per frame.
    pub(super) fn queue_drag(
        &mut self,
        button: crate::app::camera_control::Button,
        from: [f32; 2],
        to: [f32; 2],
    ) {
        let rect = self.view_rect_points();
        let at = |f: [f32; 2]| rect.min + egui::vec2(f[0] * rect.width(), f[1] * rect.height());
        let button = match button {
            crate::app::camera_control::Button::Primary => egui::PointerButton::Primary,
            crate::app::camera_control::Button::Secondary => egui::PointerButton::Secondary,
            crate::app::camera_control::Button::Middle => egui::PointerButton::Middle,
        };
        let press = |pos, pressed| egui::Event::PointerButton {
            pos,
            button,
            pressed,
            modifiers: Default::default(),
        };
        let (a, b) = (at(from), at(to));
        self.synthetic.push_back(vec![egui::Event::PointerMoved(a)]);
        self.synthetic.push_back(vec![press(a, true)]);
        for i in 1..=8 {
            let t = i as f32 / 8.0;
            self.synthetic
                .push_back(vec![egui::Event::PointerMoved(a + (b - a) * t)]);
        }
        self.synthetic.push_back(vec![press(b, false)]);
    }
}
