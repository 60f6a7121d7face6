//! Adaptive quality (`view --frame-budget MS`): while the user drags the camera, a slider or a
//! window edge, or scrolls, the raymarch runs coarser when the full-quality frame would miss the
//! budget; a fraction of a second after the last input one full-quality frame replaces it.
//!
//! Decisions:
//! - Measured, not guessed: the input is the raymarch pass's GPU time from timestamp queries
//!   (the same numbers the status bar and the session log show), never CPU time, which on a
//!   real GPU is mostly waiting. Each frame's time is divided by the relative cost of the level
//!   it was rendered at, giving an estimate of the full-quality time; the estimate is an
//!   exponential moving average (newest weight [`SMOOTHING`]) so one slow frame does not
//!   coarsen the next ten. No measurement yet (or a device without timestamps): full quality.
//! - The cost model: raymarch time scales with the samples taken, `scale^2 / step` (rays times
//!   samples per ray). Levels form one ladder, [`LADDER`]: the step grows first (x1.5, x2, x3,
//!   x4: the picture keeps its sharpness, only depth sampling coarsens), the image scale
//!   shrinks only once the coarsest step still misses (0.75, then 0.5 of the view's pixels per
//!   side, stretched back with linear filtering by the composition). While interacting the
//!   controller picks the finest level whose predicted time fits the budget. The samples follow
//!   the model exactly (`morphray bench --step S --size N`, 96x96x72 phantom, this machine:
//!   2-core Debian 12, lavapipe: 2.8, 1.4, 0.7 M samples per frame at step 0.5, 1, 2 voxel and
//!   256 px, 0.4 and 0.2 M at step 2 and 192, 128 px); time only roughly (131, 162, 83, 42,
//!   6.6 ms there, with two other builds sharing the cores), which is why the time is measured
//!   and the model only ranks the levels.
//! - Hysteresis: a coarser level is taken as soon as the current one is predicted to miss
//!   the budget (a late frame is what the user feels), but a finer one only when its
//!   prediction fits within [`REFINE_MARGIN`] of the budget. A time series that hovers at a
//!   threshold therefore settles on the coarser level instead of alternating (tested). And a
//!   level that missed is not taken again until the interaction ends: the cost model is only
//!   roughly right (lavapipe's time falls faster than its samples at small images), and where
//!   time falls faster than the model across two levels the margin alone does not stop an
//!   alternation (a simulated time ~ cost^1.5 alternated 78 times in 200 frames); with the rule
//!   a gesture sees at most as many switches as the ladder has levels (tested).
//! - Return to full quality: [`IDLE_DELAY`] = 0.25 s after the last input, in one step. 0.25 s
//!   is longer than the gap between two mouse-move events of a slow drag (so a drag is not
//!   interrupted by full-quality frames that would miss the budget) and short enough to read
//!   as "at once" when the hand stops. One refinement frame: the user sees one switch from
//!   coarse to fine, never a sequence of intermediate levels (progressive refinement would be
//!   a visible series of pops).
//! - No brightness popping: the raymarch's opacity is defined per millimetre of ray (the
//!   correction exponent r = step mm / 1 mm, `Scene::opacity_exponent`, `march.x` in the
//!   shader), so a coarser step composites fewer, proportionally more opaque samples and the
//!   accumulated opacity and colour stay the same; only sampling detail changes
//!   (tests/viewer_adaptive.rs measures the mean brightness of a step-x4 render against the
//!   full one). The image scale is stretched with linear filtering, so a coarse frame is softer,
//!   not blockier or shifted. Jitter stays on (the seed is unchanged), so a coarse step shows
//!   noise, not wood-grain bands.
//! - Only the raymarch coarsens: the slices, the interface and "Save 3D view" are unchanged, and
//!   a frame that writes a screenshot is always rendered at full quality.
//! - Budget 0 switches the controller off (always full quality); the default, 16.7 ms, is one
//!   frame at 60 Hz.

use crate::scene::Scene;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// How much coarser than requested the raymarch runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    /// Multiplier of the ray step (>= 1).
    pub step: f64,
    /// Image scale per side (<= 1): the raymarch target is this fraction of the view.
    pub scale: f64,
}

impl Level {
    /// The scene as requested.
    pub const FULL: Level = Level {
        step: 1.0,
        scale: 1.0,
    };

    /// True at full quality.
    pub fn is_full(&self) -> bool {
        *self == Level::FULL
    }

    /// Relative raymarch cost: rays (scale^2) times samples per ray (1 / step).
    pub fn cost(&self) -> f64 {
        self.scale * self.scale / self.step
    }

    /// `full`, or `step x2, scale 0.75` (the log's and the status bar's words).
    pub fn describe(&self) -> String {
        if self.is_full() {
            return "full".into();
        }
        let mut text = format!("step x{}", self.step);
        if self.scale < 1.0 {
            text.push_str(&format!(", scale {}", self.scale));
        }
        text
    }

    /// The status bar's words while coarse (`interactive: step x2, scale 0.75`); None at full
    /// quality.
    pub fn status_words(&self) -> Option<String> {
        (!self.is_full()).then(|| format!("interactive: {}", self.describe()))
    }

    /// The scene to raymarch at this level: the requested step times the multiplier.
    pub fn apply(&self, scene: &Scene) -> Scene {
        let mut coarse = *scene;
        coarse.step_voxels = scene.sanitized_step_voxels() * self.step;
        coarse
    }

    /// The raymarch target's size for a view of `width` x `height` pixels (at least 1x1).
    pub fn target_size(&self, width: u32, height: u32) -> [u32; 2] {
        let side = |n: u32| ((n as f64 * self.scale).round() as u32).clamp(1, n.max(1));
        [side(width), side(height)]
    }
}

/// Levels from finest to coarsest: the step first, then the image scale.
pub const LADDER: [Level; 7] = [
    Level::FULL,
    Level {
        step: 1.5,
        scale: 1.0,
    },
    Level {
        step: 2.0,
        scale: 1.0,
    },
    Level {
        step: 3.0,
        scale: 1.0,
    },
    Level {
        step: 4.0,
        scale: 1.0,
    },
    Level {
        step: 4.0,
        scale: 0.75,
    },
    Level {
        step: 4.0,
        scale: 0.5,
    },
];

/// Time after the last input when full quality returns.
pub const IDLE_DELAY: Duration = Duration::from_millis(250);

/// The default budget: one frame at 60 Hz, ms.
pub const DEFAULT_BUDGET_MS: f64 = 16.7;

/// A finer level is taken only when predicted within this fraction of the budget.
pub const REFINE_MARGIN: f64 = 0.8;

/// Weight of the newest measurement in the moving average of the full-quality time.
pub const SMOOTHING: f64 = 0.5;

/// Frames whose level is remembered until their GPU time arrives (a frame whose time never
/// comes, after a device loss, is forgotten once this many newer ones were submitted).
const IN_FLIGHT: usize = 16;

/// The controller: measurements in, a level per frame out.
#[derive(Debug)]
pub struct Controller {
    budget_ms: f64,
    /// Moving average of the full-quality raymarch time, ms.
    estimate_ms: Option<f64>,
    /// Index into [`LADDER`] of the level chosen last.
    current: usize,
    /// The finest level this interaction may still take (the levels above it missed).
    floor: usize,
    last_input: Option<Instant>,
    /// Submitted frames that raymarched: (serial, level), oldest first.
    in_flight: VecDeque<(u64, Level)>,
}

impl Controller {
    /// A controller for a budget in ms; 0 (or anything not a finite positive number) is off.
    pub fn new(budget_ms: f64) -> Controller {
        Controller {
            budget_ms: if budget_ms.is_finite() && budget_ms > 0.0 {
                budget_ms
            } else {
                0.0
            },
            estimate_ms: None,
            current: 0,
            floor: 0,
            last_input: None,
            in_flight: VecDeque::new(),
        }
    }

    /// True unless the budget is 0.
    pub fn enabled(&self) -> bool {
        self.budget_ms > 0.0
    }

    /// The estimate of the full-quality raymarch time, ms, once measured.
    pub fn estimate_ms(&self) -> Option<f64> {
        self.estimate_ms
    }

    /// A raymarch rendered at `level` took `gpu_ms` on the GPU.
    pub fn observe(&mut self, level: Level, gpu_ms: f64) {
        if !(gpu_ms.is_finite() && gpu_ms >= 0.0) || level.cost() <= 0.0 {
            return;
        }
        let full = gpu_ms / level.cost();
        self.estimate_ms = Some(match self.estimate_ms {
            Some(e) => e + SMOOTHING * (full - e),
            None => full,
        });
    }

    /// The user changed the picture by a continuous gesture at `now`.
    pub fn input(&mut self, now: Instant) {
        self.last_input = Some(now);
    }

    /// True while within [`IDLE_DELAY`] of the last input.
    fn interacting(&self, now: Instant) -> bool {
        self.last_input
            .is_some_and(|t| now.saturating_duration_since(t) < IDLE_DELAY)
    }

    /// The level of a frame rendered at `now`.
    pub fn level(&mut self, now: Instant) -> Level {
        if !(self.enabled() && self.interacting(now)) {
            // Idle (or off): full quality, and the next interaction starts afresh.
            self.floor = 0;
            self.current = 0;
        } else if let Some(estimate) = self.estimate_ms {
            let next = self.choose(estimate);
            if next > self.current {
                self.floor = self.floor.max(self.current + 1);
            }
            self.current = next;
        }
        LADDER[self.current]
    }

    /// The ladder index for an estimate, with hysteresis around the current level.
    fn choose(&self, estimate: f64) -> usize {
        let fits = |i: usize, within: f64| estimate * LADDER[i].cost() <= within;
        let finest_within = |within: f64| {
            (0..LADDER.len())
                .find(|&i| fits(i, within))
                .unwrap_or(LADDER.len() - 1)
        };
        if !fits(self.current, self.budget_ms) {
            // Missing the budget: coarsen at once, to the finest level that fits.
            return finest_within(self.budget_ms).max(self.current);
        }
        // Fitting: refine only with a margin, never back to a level that missed, or stay.
        finest_within(self.budget_ms * REFINE_MARGIN)
            .max(self.floor)
            .min(self.current)
    }

    /// How long until the full-quality frame is due, while the level chosen last is coarse
    /// (the window asks for a redraw then, since nothing else may).
    pub fn refine_after(&self, now: Instant) -> Option<Duration> {
        let since = now.saturating_duration_since(self.last_input?);
        (self.current != 0).then(|| IDLE_DELAY.saturating_sub(since))
    }

    /// Frame `serial` raymarched at `level` (its GPU time comes with [`Controller::completed`]).
    pub fn submitted(&mut self, serial: u64, level: Level) {
        self.in_flight.push_back((serial, level));
        while self.in_flight.len() > IN_FLIGHT {
            self.in_flight.pop_front();
        }
    }

    /// Frame `serial` finished; `raymarch_ms` is its raymarch pass's GPU time, if it ran one.
    pub fn completed(&mut self, serial: u64, raymarch_ms: Option<f64>) {
        let mut level = None;
        while let Some(&(s, l)) = self.in_flight.front() {
            if s > serial {
                break;
            }
            self.in_flight.pop_front();
            if s == serial {
                level = Some(l);
            }
        }
        if let (Some(level), Some(ms)) = (level, raymarch_ms) {
            self.observe(level, ms);
        }
    }

    /// Forgets frames in flight (their device is gone).
    pub fn abandon_in_flight(&mut self) {
        self.in_flight.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    /// A controller with an estimate of `full_ms` and the user interacting at `t0`.
    fn interacting(budget: f64, full_ms: f64, t0: Instant) -> Controller {
        let mut c = Controller::new(budget);
        c.observe(Level::FULL, full_ms);
        c.input(t0);
        c
    }

    #[test]
    fn a_met_budget_keeps_full_quality_while_interacting() {
        let t0 = Instant::now();
        let mut c = interacting(16.7, 10.0, t0);
        for i in 0..20u32 {
            c.input(t0 + i * 10 * MS);
            assert_eq!(c.level(t0 + i * 10 * MS), Level::FULL);
        }
        assert_eq!(c.refine_after(t0 + 200 * MS), None);
    }

    #[test]
    fn slow_frames_coarsen_the_step_first_then_the_scale() {
        let t0 = Instant::now();
        // 2.5x the budget: step x3 (cost 1/3) is the finest that fits, scale untouched.
        let mut c = interacting(10.0, 25.0, t0);
        let level = c.level(t0);
        assert_eq!(
            level,
            Level {
                step: 3.0,
                scale: 1.0
            }
        );
        assert_eq!(level.describe(), "step x3");
        // 6x: even step x4 (1/4) misses, so the scale goes to 0.75 (0.5625 / 4 = 0.14).
        let mut c = interacting(10.0, 60.0, t0);
        assert_eq!(
            c.level(t0),
            Level {
                step: 4.0,
                scale: 0.75
            }
        );
        // Far over: the coarsest level, whatever it predicts.
        let mut c = interacting(0.01, 60.0, t0);
        let coarsest = c.level(t0);
        assert_eq!(coarsest, *LADDER.last().unwrap());
        assert_eq!(coarsest.describe(), "step x4, scale 0.5");
        assert_eq!(coarsest.target_size(301, 200), [151, 100]);
    }

    #[test]
    fn full_quality_returns_in_one_step_after_the_idle_delay() {
        let t0 = Instant::now();
        let mut c = interacting(0.01, 60.0, t0);
        assert!(!c.level(t0 + 100 * MS).is_full());
        assert_eq!(c.refine_after(t0 + 100 * MS), Some(150 * MS));
        // Still within the delay: still coarse (the measurement of a coarse frame keeps the
        // estimate where it was).
        c.observe(
            *LADDER.last().unwrap(),
            60.0 * LADDER.last().unwrap().cost(),
        );
        assert!(!c.level(t0 + 249 * MS).is_full());
        // After it: full quality at once, with no intermediate level, and no redraw asked.
        assert_eq!(c.level(t0 + IDLE_DELAY), Level::FULL);
        assert_eq!(c.refine_after(t0 + IDLE_DELAY), None);
    }

    #[test]
    fn without_measurements_or_with_budget_zero_quality_stays_full() {
        let t0 = Instant::now();
        let mut unmeasured = Controller::new(0.01);
        unmeasured.input(t0);
        assert_eq!(unmeasured.level(t0), Level::FULL);
        let mut off = interacting(0.0, 1000.0, t0);
        assert!(!off.enabled());
        assert_eq!(off.level(t0), Level::FULL);
        assert!(!Controller::new(f64::NAN).enabled());
        assert!(!Controller::new(-3.0).enabled());
    }

    #[test]
    fn a_time_series_at_a_threshold_does_not_oscillate() {
        // Full quality takes 20 ms against a 10 ms budget: step x2 predicts exactly 10 ms.
        // The frames measured at whatever level is chosen jitter by +-3 % around that.
        let t0 = Instant::now();
        let mut c = interacting(10.0, 20.0, t0);
        let mut levels = Vec::new();
        for i in 0..200u32 {
            let now = t0 + i * 5 * MS;
            c.input(now);
            let level = c.level(now);
            levels.push(level);
            let jitter = if i % 2 == 0 { 1.03 } else { 0.97 };
            c.observe(level, 20.0 * level.cost() * jitter);
        }
        let switches = levels.windows(2).filter(|w| w[0] != w[1]).count();
        assert!(
            switches <= 1,
            "levels switched {switches} times: {levels:?}"
        );
        // And it settled on a level that meets the budget with the jitter.
        let last = levels.last().unwrap();
        assert!(20.0 * last.cost() * 1.03 <= 10.0, "{last:?}");
    }

    #[test]
    fn a_time_that_falls_faster_than_the_model_does_not_oscillate() {
        // Time ~ cost^1.5 (coarse levels cheaper than the samples predict): measured at the
        // coarser of two levels, the finer one looks affordable; measured there, it misses.
        let time = |level: Level| 196.0 * level.cost().powf(1.5);
        let t0 = Instant::now();
        let mut c = interacting(10.0, time(Level::FULL), t0);
        let mut levels = Vec::new();
        for i in 0..200u32 {
            let now = t0 + i * 5 * MS;
            c.input(now);
            let level = c.level(now);
            levels.push(level);
            c.observe(level, time(level));
        }
        let switches = levels.windows(2).filter(|w| w[0] != w[1]).count();
        assert!(
            switches <= 2,
            "levels switched {switches} times: {levels:?}"
        );
        assert!(time(*levels.last().unwrap()) <= 10.0);
        // The next interaction starts afresh: after the idle delay the floor is gone.
        let later = t0 + 10 * IDLE_DELAY;
        assert_eq!(c.level(later), Level::FULL);
        assert_eq!(c.floor, 0);
    }

    #[test]
    fn a_faster_scene_refines_only_past_the_margin() {
        let t0 = Instant::now();
        let mut c = interacting(10.0, 40.0, t0);
        assert_eq!(c.level(t0).step, 4.0);
        // Full quality now predicted at 30 ms: step x3 would fit exactly (10 ms), but not within
        // the margin (8 ms), so the level stays.
        for _ in 0..30 {
            c.observe(Level::FULL, 30.0);
        }
        assert_eq!(c.level(t0).step, 4.0);
        // At 15 ms, step x2 predicts 7.5 ms: within the margin, refine to it directly.
        for _ in 0..30 {
            c.observe(Level::FULL, 15.0);
        }
        assert_eq!(
            c.level(t0),
            Level {
                step: 2.0,
                scale: 1.0
            }
        );
    }

    #[test]
    fn gpu_times_are_matched_to_the_level_their_frame_was_rendered_at() {
        let mut c = Controller::new(10.0);
        let coarse = Level {
            step: 4.0,
            scale: 0.5,
        };
        c.submitted(1, Level::FULL);
        c.submitted(2, coarse);
        // Frame 1 only recomposed (no raymarch time): nothing learnt, and it is forgotten.
        c.completed(1, None);
        assert_eq!(c.estimate_ms(), None);
        // Frame 2's 1 ms at 1/16 of the cost is 16 ms of full quality.
        c.completed(2, Some(1.0));
        assert_eq!(c.estimate_ms(), Some(16.0));
        c.completed(3, Some(100.0));
        assert_eq!(
            c.estimate_ms(),
            Some(16.0),
            "an unknown frame teaches nothing"
        );
        c.observe(Level::FULL, f64::NAN);
        assert_eq!(c.estimate_ms(), Some(16.0));
    }

    #[test]
    fn a_coarse_level_multiplies_the_requested_step() {
        let scene = Scene::new(crate::scene::Classification::with_windows([None; 4]));
        let level = Level {
            step: 3.0,
            scale: 1.0,
        };
        assert_eq!(level.apply(&scene).step_voxels, 1.5);
        let mut broken = scene;
        broken.step_voxels = f64::NAN;
        assert_eq!(level.apply(&broken).step_voxels, 1.5, "sanitized first");
        assert_eq!(Level::FULL.apply(&scene), scene);
    }
}
