//! The 4-D panel (issue 31 item 5): the frame slider, Play/Pause with a frame rate, and the time
//! course at the crosshair, drawn at the top of the side panel when the file has several frames.
//!
//! Decisions:
//! - Playback follows the wall clock: the frame to show at time t is the frame playback started
//!   from plus floor((t - start) x fps), modulo the frame count (it loops). The viewer asks for
//!   that frame whenever no frame change is in progress, so a change that takes longer than
//!   1/fps skips frames instead of queueing them, and playback never falls behind
//!   ([`FrameClock`], a pure function of time, tested below).
//! - The frame rate is 0.1 to 60 frames per second ([`FPS_RANGE`]; `view --fps`, the script's
//!   `play FPS`): below 0.1 a "playing" session would look stopped, above 60 no display shows
//!   more.
//! - The time course is the value at the crosshair's voxel in every frame, in the scanner's
//!   units (as the readout, `app::readout`), plotted with egui's painter (no plotting crate):
//!   the line, the current frame marked, the minimum and maximum written at the axis, the frame
//!   count under it. A click at frame k asks for frame k. The mapping from frame and value to
//!   the plot's points is [`PlotMap`], pure and tested.
//! - The slider still asks for a frame only when let go (a drag would otherwise ask for every
//!   frame on the way); with the frames held in memory a frame change is cheap, but a streamed
//!   one reads the file.

use super::ui::Request;
use egui::{Color32, Pos2, Rect, RichText, Sense, Stroke, Ui, pos2, vec2};
use std::ops::RangeInclusive;

/// The frame rates playback accepts, frames per second.
pub const FPS_RANGE: RangeInclusive<f64> = 0.1..=60.0;

/// The frame rate playback starts with.
pub const DEFAULT_FPS: f64 = 4.0;

/// How the viewer starts playing (`view --play --fps F`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CineStart {
    /// Start playing as soon as a 4-D file is shown.
    pub play: bool,
    /// Frames per second.
    pub fps: f64,
}

impl Default for CineStart {
    fn default() -> Self {
        CineStart {
            play: false,
            fps: DEFAULT_FPS,
        }
    }
}

/// `fps` if it is a frame rate playback accepts, else the message naming the range.
pub fn check_fps(fps: f64) -> Result<f64, String> {
    if FPS_RANGE.contains(&fps) {
        Ok(fps)
    } else {
        Err(format!(
            "{fps} frames per second: give {} to {}",
            FPS_RANGE.start(),
            FPS_RANGE.end()
        ))
    }
}

/// The script's `play [FPS]`: the rate, if given, checked.
pub fn parse_play(word: Option<&str>) -> Result<Option<f64>, String> {
    let Some(word) = word else {
        return Ok(None);
    };
    let fps = word
        .parse::<f64>()
        .map_err(|_| format!("play {word}: expected frames per second"))?;
    check_fps(fps).map(Some).map_err(|e| format!("play {e}"))
}

/// The time course at the crosshair.
#[derive(Clone, Debug, PartialEq)]
pub struct Course {
    /// The voxel (i, j, k).
    pub voxel: [usize; 3],
    /// Its value in every frame, scanner's units.
    pub values: Vec<f64>,
    /// `HU` or empty.
    pub unit: &'static str,
}

/// The panel's state.
#[derive(Clone, Debug, PartialEq)]
pub struct CinePanel {
    /// The frame on screen and the file's frame count.
    pub frame: (usize, usize),
    /// Playing.
    pub playing: bool,
    /// Frames per second.
    pub fps: f64,
    /// The time course at the crosshair, when the frames are held.
    pub course: Option<Course>,
    /// Why there is no time course (streamed frames, crosshair outside), if there is none.
    pub note: Option<String>,
}

impl Default for CinePanel {
    fn default() -> Self {
        CinePanel {
            frame: (0, 1),
            playing: false,
            fps: DEFAULT_FPS,
            course: None,
            note: None,
        }
    }
}

/// Wall-clock playback (module decisions): where it started, from which frame, at which rate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameClock {
    /// Seconds (any origin) when playback started or last changed rate.
    pub start_s: f64,
    /// The frame shown then.
    pub from: usize,
    /// Frames per second.
    pub fps: f64,
}

impl FrameClock {
    /// The frame to show at `now_s` of `count` frames (loops at the end).
    pub fn frame_at(&self, now_s: f64, count: usize) -> usize {
        if count == 0 {
            return 0;
        }
        let elapsed = (now_s - self.start_s).max(0.0);
        let steps = (elapsed * self.fps).floor();
        // Whole frames advanced, reduced modulo the count in f64 so no cast can overflow.
        let advanced = if steps.is_finite() {
            (steps % count as f64) as usize
        } else {
            0
        };
        (self.from % count + advanced) % count
    }
}

impl FrameClock {
    /// Seconds from `now_s` until the next frame is due (a window sleeps that long).
    pub fn seconds_to_next(&self, now_s: f64) -> f64 {
        let elapsed = (now_s - self.start_s).max(0.0);
        let next = ((elapsed * self.fps).floor() + 1.0) / self.fps;
        let wait = next - elapsed;
        if wait.is_finite() { wait.max(0.0) } else { 0.0 }
    }
}

/// Frames skipped going from `shown` to `next` forwards (0 for the next frame), of `count`.
pub fn skipped(shown: usize, next: usize, count: usize) -> usize {
    if count == 0 {
        return 0;
    }
    (next + count - shown % count - 1) % count
}

/// Where frames and values go in the plot's rectangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlotMap {
    /// The plot area (points).
    pub rect: Rect,
    /// Frames (the x axis runs 0..count-1).
    pub count: usize,
    /// The values' minimum and maximum (the y axis, bottom to top).
    pub lo: f64,
    /// Maximum.
    pub hi: f64,
}

impl PlotMap {
    /// The map for `values` in `rect` (a flat course is drawn across the middle).
    pub fn new(rect: Rect, values: &[f64]) -> PlotMap {
        let finite = values.iter().copied().filter(|v| v.is_finite());
        let lo = finite.clone().fold(f64::INFINITY, f64::min);
        let hi = finite.fold(f64::NEG_INFINITY, f64::max);
        let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) };
        PlotMap {
            rect,
            count: values.len(),
            lo,
            hi,
        }
    }

    /// The point of frame `frame` with value `value`.
    pub fn point(&self, frame: usize, value: f64) -> Pos2 {
        let x = if self.count > 1 {
            frame as f32 / (self.count - 1) as f32
        } else {
            0.5
        };
        let y = if self.hi > self.lo {
            ((value - self.lo) / (self.hi - self.lo)) as f32
        } else {
            0.5
        };
        pos2(
            self.rect.left() + x * self.rect.width(),
            self.rect.bottom() - y.clamp(0.0, 1.0) * self.rect.height(),
        )
    }

    /// The frame nearest to the horizontal position `x`.
    pub fn frame_at(&self, x: f32) -> usize {
        if self.count < 2 || self.rect.width() <= 0.0 {
            return 0;
        }
        let t = ((x - self.rect.left()) / self.rect.width()).clamp(0.0, 1.0);
        ((t * (self.count - 1) as f32).round() as usize).min(self.count - 1)
    }
}

/// Draws the panel when the file has several frames.
pub fn panel(ui: &mut Ui, cine: &mut CinePanel, requests: &mut Vec<Request>) {
    let (shown, count) = cine.frame;
    if count < 2 {
        return;
    }
    ui.label(RichText::new(format!("4-D: frame {shown}/{count}")).strong());
    ui.horizontal(|ui| {
        let label = if cine.playing { "Pause" } else { "Play" };
        if ui
            .button(label)
            .on_hover_text("Plays the frames at the rate beside, looping")
            .clicked()
        {
            cine.playing = !cine.playing;
        }
        ui.add(
            egui::DragValue::new(&mut cine.fps)
                .range(FPS_RANGE)
                .speed(0.1)
                .suffix(" fps"),
        );
    });
    frame_slider(ui, cine, requests);
    match &cine.course {
        Some(course) => plot(ui, course, shown, requests),
        None => {
            if let Some(note) = &cine.note {
                ui.label(RichText::new(note).small().weak());
            }
        }
    }
    ui.separator();
}

/// The slider over the frames; asks for a frame when let go.
fn frame_slider(ui: &mut Ui, cine: &mut CinePanel, requests: &mut Vec<Request>) {
    let (shown, count) = cine.frame;
    let mut wanted = shown;
    let response = ui.add(egui::Slider::new(&mut wanted, 0..=count - 1).text("frame"));
    cine.frame.0 = wanted;
    let settled = response.drag_stopped() || (response.changed() && !response.dragged());
    if settled && wanted != shown {
        requests.push(Request::Frame(wanted));
    }
}

/// The time course: line, current frame, min/max and frame count; a click goes to that frame.
fn plot(ui: &mut Ui, course: &Course, shown: usize, requests: &mut Vec<Request>) {
    let [i, j, k] = course.voxel;
    ui.label(RichText::new(format!("Time course at voxel {i}, {j}, {k}")).small());
    let width = ui.available_width().max(60.0);
    let (outer, response) = ui.allocate_exact_size(vec2(width, 90.0), Sense::click());
    let area = Rect::from_min_max(
        pos2(outer.left() + 48.0, outer.top() + 4.0),
        pos2(outer.right() - 4.0, outer.bottom() - 16.0),
    );
    let map = PlotMap::new(area, &course.values);
    let painter = ui.painter_at(outer);
    let text = ui.visuals().text_color();
    painter.rect_stroke(
        area,
        0.0,
        Stroke::new(1.0, Color32::from_gray(90)),
        egui::StrokeKind::Inside,
    );
    let line: Vec<Pos2> = course
        .values
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .map(|(f, &v)| map.point(f, v))
        .collect();
    painter.add(egui::Shape::line(line, Stroke::new(1.5, COURSE_COLOUR)));
    if let Some(&value) = course.values.get(shown) {
        let at = map.point(shown, value);
        painter.line_segment(
            [pos2(at.x, area.top()), pos2(at.x, area.bottom())],
            Stroke::new(1.0, MARK_COLOUR),
        );
        painter.circle_filled(at, 3.5, MARK_COLOUR);
    }
    let font = egui::FontId::proportional(10.0);
    let unit = course.unit;
    for (value, y, align) in [
        (map.hi, area.top(), egui::Align2::RIGHT_TOP),
        (map.lo, area.bottom(), egui::Align2::RIGHT_BOTTOM),
    ] {
        painter.text(
            pos2(area.left() - 3.0, y),
            align,
            format!("{} {unit}", short(value)),
            font.clone(),
            text,
        );
    }
    painter.text(
        pos2(area.center().x, outer.bottom()),
        egui::Align2::CENTER_BOTTOM,
        format!("frame 0..{}", map.count.saturating_sub(1)),
        font,
        text,
    );
    if response.clicked()
        && let Some(p) = response.interact_pointer_pos()
    {
        let frame = map.frame_at(p.x);
        if frame != shown {
            requests.push(Request::Frame(frame));
        }
    }
}

/// The course's line: the slice crosshair's colour family, readable on the dark panel.
const COURSE_COLOUR: Color32 = Color32::from_rgb(90, 200, 240);
/// The current frame's mark.
const MARK_COLOUR: Color32 = Color32::from_rgb(250, 190, 60);

/// A value for an axis label: 4 significant digits, without trailing zeros.
fn short(value: f64) -> String {
    if value != 0.0 && (value.abs() >= 1e5 || value.abs() < 1e-2) {
        return format!("{value:.2e}");
    }
    let text = format!("{value:.3}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clock(from: usize, fps: f64) -> FrameClock {
        FrameClock {
            start_s: 10.0,
            from,
            fps,
        }
    }

    #[test]
    fn playback_follows_the_wall_clock_and_loops() {
        let c = clock(0, 4.0);
        assert_eq!(c.frame_at(10.0, 6), 0);
        assert_eq!(c.frame_at(10.24, 6), 0);
        assert_eq!(c.frame_at(10.25, 6), 1);
        assert_eq!(c.frame_at(11.0, 6), 4);
        // 6 frames at 4 fps: 1.5 s a loop.
        assert_eq!(c.frame_at(11.5, 6), 0);
        assert_eq!(c.frame_at(11.75, 6), 1);
        // From another frame; a clock before the start stays there.
        assert_eq!(clock(5, 4.0).frame_at(10.25, 6), 0);
        assert_eq!(clock(3, 4.0).frame_at(9.0, 6), 3);
    }

    #[test]
    fn a_window_sleeps_until_the_next_frame_is_due() {
        let c = clock(0, 4.0);
        assert!((c.seconds_to_next(10.0) - 0.25).abs() < 1e-9);
        assert!((c.seconds_to_next(10.3) - 0.2).abs() < 1e-9);
        assert!((c.seconds_to_next(9.0) - 0.25).abs() < 1e-9);
        assert_eq!(c.seconds_to_next(f64::INFINITY), 0.0);
    }

    #[test]
    fn a_slow_frame_change_skips_frames_instead_of_queueing_them() {
        // At 10 fps a change that took 0.35 s lands on the frame due now, 3 ahead.
        let c = clock(0, 10.0);
        let next = c.frame_at(10.35, 20);
        assert_eq!(next, 3);
        assert_eq!(skipped(0, next, 20), 2);
        assert_eq!(skipped(0, 1, 20), 0);
        // Across the loop's end.
        assert_eq!(skipped(18, 1, 20), 2);
    }

    #[test]
    fn hostile_times_and_counts_give_a_frame_in_range() {
        for now in [f64::NAN, f64::INFINITY, 1e300, -1e300] {
            let f = clock(2, 60.0).frame_at(now, 7);
            assert!(f < 7, "{now}: {f}");
        }
        assert_eq!(clock(2, 60.0).frame_at(11.0, 0), 0);
    }

    #[test]
    fn the_frame_rate_is_checked() {
        assert_eq!(check_fps(4.0), Ok(4.0));
        assert_eq!(check_fps(0.1), Ok(0.1));
        assert_eq!(check_fps(60.0), Ok(60.0));
        for bad in [0.0, 0.05, 61.0, f64::NAN, -1.0] {
            let e = check_fps(bad).unwrap_err();
            assert!(e.contains("give 0.1 to 60"), "{e}");
        }
    }

    #[test]
    fn the_plot_maps_frames_across_and_values_up() {
        let rect = Rect::from_min_max(pos2(100.0, 50.0), pos2(200.0, 150.0));
        let map = PlotMap::new(rect, &[10.0, 30.0, 20.0, f64::NAN, 50.0]);
        assert_eq!((map.lo, map.hi, map.count), (10.0, 50.0, 5));
        assert_eq!(map.point(0, 10.0), pos2(100.0, 150.0));
        assert_eq!(map.point(4, 50.0), pos2(200.0, 50.0));
        assert_eq!(map.point(2, 30.0), pos2(150.0, 100.0));
        // Clicks go to the nearest frame, clamped to the axis.
        assert_eq!(map.frame_at(100.0), 0);
        assert_eq!(map.frame_at(137.0), 1);
        assert_eq!(map.frame_at(140.0), 2);
        assert_eq!(map.frame_at(1000.0), 4);
        assert_eq!(map.frame_at(-5.0), 0);
    }

    #[test]
    fn a_flat_or_empty_course_is_drawn_across_the_middle() {
        let rect = Rect::from_min_max(pos2(0.0, 0.0), pos2(10.0, 10.0));
        let flat = PlotMap::new(rect, &[7.0, 7.0]);
        assert_eq!(flat.point(1, 7.0), pos2(10.0, 5.0));
        let empty = PlotMap::new(rect, &[]);
        assert_eq!(empty.frame_at(5.0), 0);
        assert_eq!(empty.point(0, 1.0), pos2(5.0, 5.0));
        assert_eq!(short(2510.0), "2510");
        assert_eq!(short(0.5), "0.5");
    }
}
