//! Scripted sessions: a small language of interface actions, replayed one per frame boundary.
//!
//! Decisions:
//! - One action per line, `#` starts a comment (unless it starts a `#RRGGBB` colour); every
//!   action is something a person can do in the window (plus `wait`, `screenshot`, `close` and
//!   a fault injection for tests), and it goes through the same [`super::ui::Controls`] methods as the widgets, or, for `drag`, through
//!   egui's pointer events and the same camera controller as a real mouse.
//! - Errors name the file, line and what was expected, and are found before the window opens.
//! - The runner never starts an action while a load or a derived-volume computation is pending,
//!   so a script is deterministic whatever the machine's speed: "curvature on" followed by
//!   "screenshot" shows the curvature.

use super::camera_control::{Button, StandardView};
use crate::passes::brain::BrainSwitch;
use crate::scene::slice::Convention;
use crate::scene::{RenderMode, TissueClass};
use crate::volume::source::VolumeSource;
use std::path::{Path, PathBuf};

/// Presets of the tissue windows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Preset {
    /// Around this volume's histogram peaks.
    Adaptive,
    /// The paper's fixed constants.
    Paper,
    /// Adaptive windows with default colours, opacities and switches.
    Reset,
}

/// One scripted action.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Switch a tissue on or off.
    Toggle(TissueClass),
    /// Set a tissue's visibility.
    Show(TissueClass, bool),
    /// Show or hide the vessel channel (`show vessels`, `hide vessels`).
    Vessels(bool),
    /// Brain extraction's switch (`brain auto|on|off`): tissues inside the extracted brain only.
    Brain(BrainSwitch),
    /// Show or hide the head layer around an extracted brain (`show head`, `hide head`).
    Head(bool),
    /// The head layer's opacity per mm (`set opacity head 0.3`).
    HeadOpacity(f32),
    /// The head layer's colour (`set colour head #RRGGBB`).
    HeadColour([f32; 3]),
    /// Set a tissue's window to `[lo, hi]` in I_norm (as dragging the band's edges does).
    SetWindow(TissueClass, f64, f64),
    /// Set a tissue's opacity.
    Opacity(TissueClass, f32),
    /// Set a tissue's colour (RGB 0..1).
    Colour(TissueClass, [f32; 3]),
    /// Apply a window preset.
    Preset(Preset),
    /// Orbit by degrees of azimuth and elevation.
    Orbit(f64, f64),
    /// Pan by millimetres (right, up).
    Pan(f64, f64),
    /// Multiply the zoom.
    Zoom(f64),
    /// One of the six standard views.
    View(StandardView),
    /// Back to the default camera.
    ResetView,
    /// A mouse drag over the 3D view, from and to fractions of its width and height.
    Drag {
        /// Which button is held.
        button: Button,
        /// Start (x, y) as fractions of the view.
        from: [f32; 2],
        /// End (x, y) as fractions of the view.
        to: [f32; 2],
    },
    /// Rendering mode.
    Mode(RenderMode),
    /// Ray step in voxels.
    Step(f64),
    /// Curvature weighting on or off.
    Curvature(bool),
    /// Curvature strength.
    CurvatureStrength(f32),
    /// Phong shading on or off.
    Shading(bool),
    /// The lighting model (`lighting studio` / `lighting headlight` / `lighting matcap`).
    Lighting(crate::scene::LightModel),
    /// Depth cues on or off (`cues on`).
    DepthCues(bool),
    /// The cut-away through the crosshair on or off (`cutaway on`).
    Cutaway(bool),
    /// Background colour.
    Background([f32; 3]),
    /// Open a source (`open` alone or `open phantom`: the built-in phantom; several paths
    /// are one DICOM input).
    Open(VolumeSource),
    /// Open the DICOM input on screen again with this series (an index from `morphray info`).
    Series(usize),
    /// Crop box, fractions of the voxel axes (`crop 0:1,0:1,0.5:1`).
    Crop([[f64; 2]; 3]),
    /// The first clip plane, world mm (`clip NX NY NZ D`), or none (`clip off`).
    Clip(Option<crate::scene::ClipPlane>),
    /// Colour map (`colormap hot`), or tissue colours / grey (`colormap off`).
    Colormap(Option<crate::scene::Colormap>),
    /// Save the whole window as PNG.
    Screenshot(PathBuf),
    /// Show this frame of the 4-D file on screen (0-based): `frame 3`.
    Frame(usize),
    /// Play a 4-D file's frames (`play`, or `play FPS`: 0.1 to 60 frames per second).
    Play(Option<f64>),
    /// Stop playing (`pause`).
    Pause,
    /// Save the 3D view alone at a size (`save-view PATH 2048x2048`; default the view's size
    /// in pixels is not known to a script, so 1024x1024).
    SaveView(PathBuf, [u32; 2]),
    /// Save the scene on screen as a scene document (`save-scene PATH.json`).
    SaveScene(PathBuf),
    /// A measurement step (`measure distance ...`, `measure export FILE`; measure_panel.rs).
    Measure(crate::app::measure_panel::MeasureStep),
    /// An intensity layer step (`layer add SPEC`, `layer 1 threshold 3.1`; layers_panel.rs).
    Layer(crate::app::layers_panel::LayerStep),
    /// Draw a label map over the volume (`labels FILE`), as Add labels... does.
    Labels(PathBuf),
    /// Let this many frames pass.
    Wait(u32),
    /// Let this many milliseconds of wall time pass, frames going on as in an interactive
    /// window (the raymarch runs only if the picture changes): `sleep 300`, a hand that stops,
    /// for adaptive quality's return to full quality.
    Sleep(u32),
    /// Let this many frames pass as an interactive window would: the raymarch runs only if
    /// the scene changed (scripted runs otherwise raymarch every frame, to measure).
    Idle(u32),
    /// Resize the window (or the offscreen image) to width x height pixels.
    Resize(u32, u32),
    /// Close the window (as the close button does).
    Close,
    /// Test hook: the next GPU frame fails as if the device had been lost.
    SimulateDeviceLost,
    /// Slice layout: 3d, slices, axial, coronal or sagittal.
    Layout(crate::app::slices_panel::Layout),
    /// Slice convention.
    Convention(crate::scene::slice::Convention),
    /// Move the slices' crosshair to a world point (mm, RAS).
    Crosshair([f64; 3]),
    /// A depth pick at a point of the 3D view, as fractions of its width and height from the
    /// top left (`pick 0.5 0.5`: the centre), as a click there does.
    Pick([f32; 2]),
    /// The slices' grey window in I_norm (black, white).
    SliceWindow(f64, f64),
    /// Show or hide one label of the overlay.
    Label(u16, bool),
    /// What the volume is taken to be: `modality NAME`, `contrast NAME`, `preset NAME` (the
    /// look by modality; each also `auto`). Opens the volume again.
    Identity(super::identity_panel::IdentityStep),
}

/// An action with where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// 1-based line number.
    pub line: usize,
    /// The line as written (for the log).
    pub text: String,
    /// The parsed action.
    pub action: Action,
}

/// A parse error: file, line, what was wrong.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("{file}:{line}: {message}")]
pub struct ScriptError {
    /// Script file.
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// What is wrong and what was expected.
    pub message: String,
}

/// Reads and parses a script file.
pub fn load(path: &Path) -> Result<Vec<Step>, ScriptError> {
    // A regular file of at most 1 MiB: a FIFO or device named as the script must not block or
    // fill memory (files::read).
    let cannot = |message: String| ScriptError {
        file: path.display().to_string(),
        line: 0,
        message,
    };
    let bytes = crate::files::read::read_regular(path, 1 << 20)
        .map_err(|e| cannot(format!("cannot read: {e}")))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| cannot("cannot read: the script is not UTF-8 text".into()))?;
    parse(&text, &path.display().to_string())
}

/// Most frames one `wait` or `idle` step, or `view --frames`, may ask for: 10000 frames are
/// almost 3 minutes at 60 Hz (a number past it is a typo, and a scripted run must end).
pub const MAX_FRAMES: u32 = 10_000;

/// Parses script text; `file` names it in errors.
pub fn parse(text: &str, file: &str) -> Result<Vec<Step>, ScriptError> {
    let mut steps = Vec::new();
    for (index, raw) in text.lines().enumerate() {
        let line = strip_comment(raw).trim();
        if line.is_empty() {
            continue;
        }
        let action = parse_line(line).map_err(|message| ScriptError {
            file: file.to_string(),
            line: index + 1,
            message,
        })?;
        steps.push(Step {
            line: index + 1,
            text: line.to_string(),
            action,
        });
    }
    Ok(steps)
}

/// `raw` without its comment: from the first `#` that starts a word and is not a `#RRGGBB`
/// colour (so `set colour wm #ff8000  # orange` keeps its colour).
fn strip_comment(raw: &str) -> &str {
    let mut at = 0;
    while let Some(found) = raw[at..].find('#') {
        let i = at + found;
        let starts_word = raw[..i].chars().next_back().is_none_or(char::is_whitespace);
        let word = raw[i + 1..].split_whitespace().next().unwrap_or("");
        let colour = raw[i + 1..].starts_with(word)
            && word.len() == 6
            && word.chars().all(|c| c.is_ascii_hexdigit());
        if starts_word && !colour {
            return &raw[..i];
        }
        at = i + 1;
    }
    raw
}

fn tissue(word: Option<&str>) -> Result<TissueClass, String> {
    let word = word.ok_or("expected a tissue: csf, gm, wm or pathology")?;
    TissueClass::parse(word)
        .ok_or_else(|| format!("unknown tissue `{word}`; use csf, gm, wm or pathology"))
}

fn number(word: Option<&str>, what: &str) -> Result<f64, String> {
    let word = word.ok_or_else(|| format!("expected {what}"))?;
    word.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("`{word}` is not a number ({what})"))
}

fn switch(word: Option<&str>) -> Result<bool, String> {
    match word {
        Some("on") => Ok(true),
        Some("off") => Ok(false),
        other => Err(format!("expected on or off, got {other:?}")),
    }
}

fn colour(word: Option<&str>) -> Result<[f32; 3], String> {
    let word = word.ok_or("expected a colour #RRGGBB")?;
    let hex = word
        .strip_prefix('#')
        .filter(|h| h.len() == 6)
        .and_then(|h| u32::from_str_radix(h, 16).ok())
        .ok_or_else(|| format!("`{word}` is not a #RRGGBB colour"))?;
    Ok([
        (hex >> 16) as f32 / 255.0,
        ((hex >> 8) & 0xff) as f32 / 255.0,
        (hex & 0xff) as f32 / 255.0,
    ])
}

fn fraction(word: Option<&str>) -> Result<f32, String> {
    let v = number(word, "a fraction of the view from 0 to 1")?;
    if (0.0..=1.0).contains(&v) {
        Ok(v as f32)
    } else {
        Err(format!("{v} is outside 0..1 (fractions of the view)"))
    }
}

fn parse_line(line: &str) -> Result<Action, String> {
    let mut words = line.split_whitespace();
    let verb = words.next().unwrap_or("").to_lowercase();
    let mut next = || words.next();
    let action = match verb.as_str() {
        "toggle" => Action::Toggle(tissue(next())?),
        "show" | "hide" => {
            let word = next();
            let on = verb == "show";
            if word.is_some_and(|w| w.eq_ignore_ascii_case("vessels")) {
                Action::Vessels(on)
            } else if word.is_some_and(|w| w.eq_ignore_ascii_case("head")) {
                Action::Head(on)
            } else {
                Action::Show(tissue(word)?, on)
            }
        }
        "set" => match next() {
            Some("window") => {
                let t = tissue(next())?;
                let lo = number(next(), "the window's lower bound")?;
                let hi = number(next(), "the window's upper bound")?;
                if lo >= hi {
                    return Err(format!("window {lo}..{hi} must have lo < hi"));
                }
                Action::SetWindow(t, lo, hi)
            }
            Some("opacity") => {
                let word = next();
                if word.is_some_and(|w| w.eq_ignore_ascii_case("head")) {
                    let o = number(next(), "an opacity 0..1")?.clamp(0.0, 1.0);
                    return finish(Action::HeadOpacity(o as f32), next());
                }
                let t = tissue(word)?;
                Action::Opacity(t, number(next(), "an opacity 0..1")?.clamp(0.0, 1.0) as f32)
            }
            Some("colour") | Some("color") => {
                let word = next();
                if word.is_some_and(|w| w.eq_ignore_ascii_case("head")) {
                    return finish(Action::HeadColour(colour(next())?), next());
                }
                let t = tissue(word)?;
                Action::Colour(t, colour(next())?)
            }
            other => {
                return Err(format!(
                    "expected `set window|opacity|colour TISSUE ...`, got {other:?}"
                ));
            }
        },
        "preset" => match next() {
            Some("adaptive") => Action::Preset(Preset::Adaptive),
            Some("paper") => Action::Preset(Preset::Paper),
            Some("reset") => Action::Preset(Preset::Reset),
            // The look by modality (`--preset`): `preset auto|mr|ct|angio|...`.
            other => match super::identity_panel::parse_step("preset", other) {
                Some(Ok(step)) => Action::Identity(step),
                _ => {
                    return Err(format!(
                        "expected adaptive, paper or reset (windows), or auto or {} (the look \
                         by modality), got {other:?}",
                        crate::scene::Preset::names()
                    ));
                }
            },
        },
        "modality" | "contrast" => match super::identity_panel::parse_step(&verb, next()) {
            Some(step) => Action::Identity(step?),
            None => return Err(format!("unknown step `{verb}`")),
        },
        "orbit" => Action::Orbit(
            number(next(), "degrees of azimuth")?,
            number(next(), "degrees of elevation")?,
        ),
        "pan" => Action::Pan(
            number(next(), "millimetres right")?,
            number(next(), "millimetres up")?,
        ),
        "zoom" => {
            let f = number(next(), "a zoom factor")?;
            if f <= 0.0 {
                return Err("the zoom factor must be positive".into());
            }
            Action::Zoom(f)
        }
        "layout" => {
            let word = next().unwrap_or("");
            Action::Layout(
                crate::app::slices_panel::Layout::parse(word).ok_or_else(|| {
                    format!("unknown layout `{word}`; use 3d, slices, axial, coronal or sagittal")
                })?,
            )
        }
        "convention" => match next() {
            Some("radiological") => Action::Convention(Convention::Radiological),
            Some("neurological") => Action::Convention(Convention::Neurological),
            other => {
                return Err(format!(
                    "expected radiological or neurological, got {other:?}"
                ));
            }
        },
        "crosshair" => Action::Crosshair([
            number(next(), "x in mm")?,
            number(next(), "y in mm")?,
            number(next(), "z in mm")?,
        ]),
        "pick" => {
            let x = number(next(), "x as a fraction of the view's width (0..1)")?;
            let y = number(next(), "y as a fraction of the view's height (0..1)")?;
            if !(0.0..=1.0).contains(&x) || !(0.0..=1.0).contains(&y) {
                return Err(format!(
                    "pick {x} {y}: both lie in 0..1 (fractions of the view)"
                ));
            }
            Action::Pick([x as f32, y as f32])
        }
        "label" => {
            let n = number(next(), "a label number")?;
            if !(0.0..=65535.0).contains(&n) || n.fract() != 0.0 {
                return Err(format!("{n} is not a label (0..65535)"));
            }
            Action::Label(n as u16, switch(next())?)
        }
        "slice-window" => {
            let lo = number(next(), "the slices' black level (I_norm)")?;
            let hi = number(next(), "the slices' white level (I_norm)")?;
            if lo >= hi {
                return Err(format!("slice window {lo}..{hi} must have lo < hi"));
            }
            Action::SliceWindow(lo, hi)
        }
        "view" => {
            let word = next().ok_or("expected a view name")?;
            match word {
                "reset" => Action::ResetView,
                _ => Action::View(StandardView::parse(word).ok_or_else(|| {
                    format!(
                        "unknown view `{word}`; use anterior, posterior, left, right, superior, inferior or reset"
                    )
                })?),
            }
        }
        "drag" => {
            let button = match next() {
                Some("left") => Button::Primary,
                Some("right") => Button::Secondary,
                Some("middle") => Button::Middle,
                other => return Err(format!("expected left, right or middle, got {other:?}")),
            };
            let from = [fraction(next())?, fraction(next())?];
            let to = [fraction(next())?, fraction(next())?];
            Action::Drag { button, from, to }
        }
        "mode" => match next() {
            Some("dvr") => Action::Mode(RenderMode::Dvr),
            Some("mip") => Action::Mode(RenderMode::Mip),
            Some("minip") => Action::Mode(RenderMode::MinIp),
            other => return Err(format!("expected dvr, mip or minip, got {other:?}")),
        },
        "step" => {
            let s = number(next(), "a step in voxels")?;
            crate::scene::recipe::check_step(s).map_err(|e| e.replacen("--step", "step", 1))?;
            Action::Step(s)
        }
        "curvature" => match next() {
            Some("strength") => {
                Action::CurvatureStrength(number(next(), "a strength")?.clamp(0.0, 20.0) as f32)
            }
            w => Action::Curvature(switch(w)?),
        },
        "shading" => Action::Shading(switch(next())?),
        "lighting" => match next() {
            Some("studio") => Action::Lighting(crate::scene::LightModel::Studio),
            Some("headlight") => Action::Lighting(crate::scene::LightModel::Headlight),
            Some("matcap") => Action::Lighting(crate::scene::LightModel::Matcap),
            w => {
                return Err(format!(
                    "expected `lighting studio`, `lighting headlight` or `lighting matcap`, got {w:?}"
                ));
            }
        },
        "cues" => Action::DepthCues(switch(next())?),
        "cutaway" => Action::Cutaway(switch(next())?),
        "brain" => {
            let word = next().unwrap_or("");
            Action::Brain(BrainSwitch::parse(word).ok_or_else(|| {
                format!("expected `brain auto`, `brain on` or `brain off`, got `{word}`")
            })?)
        }
        "background" => Action::Background(colour(next())?),
        "open" => {
            let paths: Vec<PathBuf> = std::iter::from_fn(&mut next)
                .filter(|w| *w != "phantom")
                .map(PathBuf::from)
                .collect();
            Action::Open(VolumeSource::from_paths(&paths))
        }
        "series" => {
            let n = number(next(), "a series index (from `morphray info`)")?;
            if n < 0.0 || n.fract() != 0.0 {
                return Err(format!("series {n} must be a whole number from 0"));
            }
            Action::Series(n as usize)
        }
        "crop" => {
            let text = next().ok_or("expected X0:X1,Y0:Y1,Z0:Z1 (fractions 0..1)")?;
            Action::Crop(crate::scene::clip::parse_crop(text).map_err(|e| e.0)?)
        }
        "clip" => match next() {
            Some("off") => Action::Clip(None),
            first => {
                let nx = number(first, "NX of the plane's normal")?;
                let ny = number(next(), "NY")?;
                let nz = number(next(), "NZ")?;
                let d = number(next(), "D in mm")?;
                if nx == 0.0 && ny == 0.0 && nz == 0.0 {
                    return Err("the plane's normal must not be zero".into());
                }
                Action::Clip(Some(crate::scene::ClipPlane {
                    normal: [nx, ny, nz],
                    offset_mm: d,
                }))
            }
        },
        "colormap" => match next() {
            Some("off") => Action::Colormap(None),
            Some(name) => Action::Colormap(Some(crate::scene::Colormap::parse(name).ok_or_else(
                || {
                    format!(
                        "unknown colour map `{name}`; use gray, hot, viridis, inferno, bone or off"
                    )
                },
            )?)),
            None => return Err("expected a colour map name or off".into()),
        },
        "screenshot" => Action::Screenshot(PathBuf::from(next().ok_or("expected a PNG path")?)),
        "frame" => {
            let n = number(next(), "a frame index (0-based)")?;
            if n < 0.0 || n.fract() != 0.0 {
                return Err(format!("frame {n} must be a whole number from 0"));
            }
            Action::Frame(n as usize)
        }
        "play" => Action::Play(crate::app::cine_panel::parse_play(next())?),
        "pause" => Action::Pause,
        "measure" => {
            let rest: Vec<&str> = std::iter::from_fn(&mut next).collect();
            Action::Measure(crate::app::measure_panel::MeasureStep::parse(&rest)?)
        }
        "layer" => {
            let rest: Vec<&str> = std::iter::from_fn(&mut next).collect();
            Action::Layer(crate::app::layers_panel::LayerStep::parse(&rest)?)
        }
        "labels" => Action::Labels(PathBuf::from(next().ok_or("expected a label map's path")?)),
        "save-scene" => Action::SaveScene(PathBuf::from(
            next().ok_or("expected a scene document path (.json)")?,
        )),
        "save-view" => {
            let path = PathBuf::from(next().ok_or("expected a PNG path")?);
            let size = match next() {
                None => [1024, 1024],
                Some(text) => {
                    let (w, h) = text
                        .split_once('x')
                        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got `{text}`"))?;
                    let side = |v: &str| {
                        v.trim()
                            .parse::<u32>()
                            .map_err(|_| format!("`{text}` is not WIDTHxHEIGHT in pixels"))
                    };
                    [side(w)?, side(h)?]
                }
            };
            Action::SaveView(path, size)
        }
        "wait" => {
            let n = number(next(), "a number of frames")?;
            if !(0.0..=MAX_FRAMES as f64).contains(&n) || n.fract() != 0.0 {
                return Err(format!(
                    "wait {n}: expected a whole number of frames, 0..{MAX_FRAMES}"
                ));
            }
            Action::Wait(n as u32)
        }
        "idle" => {
            let n = number(next(), "a number of frames")?;
            if !(0.0..=MAX_FRAMES as f64).contains(&n) || n.fract() != 0.0 {
                return Err(format!(
                    "idle {n}: expected a whole number of frames, 0..{MAX_FRAMES}"
                ));
            }
            Action::Idle(n as u32)
        }
        "resize" => {
            let w = number(next(), "a width in pixels")?;
            let h = number(next(), "a height in pixels")?;
            if !(1.0..=16384.0).contains(&w) || !(1.0..=16384.0).contains(&h) {
                return Err(format!("resize {w} {h}: sides must be 1..16384 pixels"));
            }
            Action::Resize(w as u32, h as u32)
        }
        "sleep" => {
            let ms = number(next(), "milliseconds")?;
            if !(0.0..=60_000.0).contains(&ms) || ms.fract() != 0.0 {
                return Err(format!("sleep {ms}: expected whole milliseconds, 0..60000"));
            }
            Action::Sleep(ms as u32)
        }
        "close" => Action::Close,
        "simulate-device-lost" => Action::SimulateDeviceLost,
        other => return Err(format!("unknown action `{other}`")),
    };
    finish(action, next())
}

/// `action`, unless a word follows it.
fn finish(action: Action, extra: Option<&str>) -> Result<Action, String> {
    match extra {
        Some(extra) => Err(format!("unexpected `{extra}` after the action")),
        None => Ok(action),
    }
}

/// Replays steps: hands out the next one when the viewer is ready for it.
#[derive(Debug, Default)]
pub struct Runner {
    steps: Vec<Step>,
    next: usize,
    waiting: u32,
    /// The end of a `sleep`.
    until: Option<std::time::Instant>,
}

impl Runner {
    /// A runner over parsed steps.
    pub fn new(steps: Vec<Step>) -> Self {
        Runner {
            steps,
            next: 0,
            waiting: 0,
            until: None,
        }
    }

    /// The next step to apply before this frame, if any: none while a `wait` counts down or
    /// while the viewer is `busy` (loading, computing a derived volume, or in a drag), except
    /// `close`.
    pub fn next_step(&mut self, busy: bool) -> Option<Step> {
        if self.waiting > 0 {
            self.waiting -= 1;
            return None;
        }
        if let Some(until) = self.until {
            if std::time::Instant::now() < until {
                return None;
            }
            self.until = None;
        }
        // `close` is what a person may do at any time, also while a load runs.
        let closing = matches!(
            self.steps.get(self.next).map(|s| &s.action),
            Some(Action::Close)
        );
        if busy && !closing {
            return None;
        }
        let step = self.steps.get(self.next)?.clone();
        self.next += 1;
        if let Action::Wait(n) | Action::Idle(n) = step.action {
            self.waiting = n;
        }
        if let Action::Sleep(ms) = step.action {
            self.until =
                Some(std::time::Instant::now() + std::time::Duration::from_millis(ms.into()));
        }
        Some(step)
    }

    /// True during a `sleep`.
    pub fn sleeping(&self) -> bool {
        self.until.is_some_and(|t| std::time::Instant::now() < t)
    }

    /// True when every step has been handed out and the last wait has elapsed.
    pub fn finished(&self) -> bool {
        self.next >= self.steps.len()
            && self.waiting == 0
            && self.until.is_none_or(|t| std::time::Instant::now() >= t)
    }
}

#[cfg(test)]
mod tests;
