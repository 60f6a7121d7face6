//! The loader thread's 4-D work (`app::loader` runs it): holding a file's frames in memory, and
//! preparing another frame like the one on screen (`Engine::prepare_frame`).
//!
//! Decisions:
//! - Memory rule: every frame is held in host memory when all of them together take at most
//!   [`hold_cap`]: a quarter of the engine's memory budget (`--memory-budget`, or what the
//!   device can give), never more than 2 GiB. The frames live in host RAM, not on the GPU, but
//!   the budget is the one memory figure a person sets for a session, and a quarter of it leaves
//!   the rest for the volume and derived volumes it plans (on a CPU device such as lavapipe they
//!   are host RAM too); 2 GiB caps what a large GPU's budget would let a 4-D file take from a
//!   desktop. Over the cap (or for a `.hdr`/`.img` pair, or a DICOM input) each frame change
//!   reads that one frame from the file, as before ("streamed"); the log says which.
//! - Holding is a job of its own, queued after the first load: the first frame is on screen
//!   before the other frames are read, and a frame change meanwhile streams.
//! - A frame change is one job: the frame (held, or read from the file), then
//!   `Engine::prepare_frame` (upload and normalization with the range of the frame on screen) and
//!   `Engine::derive_frame` (the same derived volumes, the brain mask shared), then the brick
//!   ranges the raymarch skips empty space with. Nothing of the open path is repeated: no plan,
//!   no analysis, no histogram, no brain extraction.

use crate::engine::{BrainMask, Engine, PreparedVolume, Twin};
use crate::gpu::PassTiming;
use crate::passes::derivatives::DerivativeOutputs;
use crate::volume::Volume;
use crate::volume::nifti::frames::{AllFrames, load_all_frames};
use crate::volume::source::{self, ReadOptions, VolumeSource};
use std::sync::Arc;
use std::time::Instant;

/// The most host memory a 4-D file's held frames may take, whatever the budget (module doc).
pub const HOLD_CAP_MAX: u64 = 2 << 30;

/// The memory rule for a budget of `budget` bytes (module doc).
pub fn hold_cap(budget: u64) -> u64 {
    (budget / 4).min(HOLD_CAP_MAX)
}

/// Every frame of a 4-D file, each a volume of its own (same grid and metadata; its own
/// samples and stored-to-physical map).
pub struct HeldFrames {
    /// The frames in order.
    pub volumes: Vec<Arc<Volume>>,
    /// Bytes of samples they hold.
    pub bytes: u64,
}

impl HeldFrames {
    /// The value of voxel `index` (x fastest) in the scanner's units, in every frame.
    pub fn time_course(&self, index: usize) -> Vec<f64> {
        self.volumes
            .iter()
            .map(|v| {
                let stored = if index < v.samples.len() {
                    v.samples.get(index)
                } else {
                    f64::NAN
                };
                v.to_physical.apply(stored)
            })
            .collect()
    }
}

/// What holding the frames came to.
pub enum Holding {
    /// Held in memory.
    Held(Arc<HeldFrames>),
    /// Each frame is read when shown; why (one line, for the log).
    Streamed(String),
}

/// Reads every frame of `source` (whose frame `template` is, for its metadata) when they fit
/// `cap` bytes.
pub fn hold_frames(source: &VolumeSource, template: &Volume, cap: u64) -> Holding {
    let path = match source {
        VolumeSource::File(path) if source::reader_for(path).name() == "NIfTI/ANALYZE" => path,
        _ => return Holding::Streamed("only a single NIfTI file's frames are held".into()),
    };
    match load_all_frames(path, cap) {
        Ok(AllFrames::Held(frames)) => {
            let bytes = frames.iter().map(|(s, _)| s.as_bytes().len() as u64).sum();
            let volumes = frames
                .into_iter()
                .enumerate()
                .map(|(t, (samples, to_physical))| {
                    Arc::new(Volume {
                        name: template.name.clone(),
                        dims: template.dims,
                        spacing_mm: template.spacing_mm,
                        orientation: template.orientation.clone(),
                        samples,
                        to_physical,
                        warnings: frame_warnings(&template.warnings, t),
                        facts: template.facts.clone(),
                    })
                })
                .collect();
            Holding::Held(Arc::new(HeldFrames { volumes, bytes }))
        }
        Ok(AllFrames::TooLarge { bytes }) => Holding::Streamed(format!(
            "the frames take {} MiB, over the {} MiB cap (a quarter of the memory budget, at most 2 GiB)",
            bytes >> 20,
            cap >> 20
        )),
        Ok(AllFrames::NotHeld) => {
            Holding::Streamed("a .hdr/.img pair's frames are read one at a time".into())
        }
        Err(e) => Holding::Streamed(format!(
            "reading every frame failed: {}",
            super::loader::one_line(&e.to_string())
        )),
    }
}

/// The reader's warnings about a file as they read for frame `t`: its "showing frame N" line
/// (`volume::nifti`) names `t`, so a screenshot's provenance names the frame it shows.
fn frame_warnings(warnings: &[String], t: usize) -> Vec<String> {
    warnings
        .iter()
        .map(|w| match w.rsplit_once(": showing frame ") {
            Some((file, _)) => format!("{file}: showing frame {t}"),
            None => w.clone(),
        })
        .collect()
}

/// Where a frame comes from.
pub enum FrameInput {
    /// Held in memory.
    Held(Arc<Volume>),
    /// Read from the file (with these options: the frame, the series).
    Read(VolumeSource, ReadOptions),
}

/// What a frame change needs of the frame on screen.
pub struct Like {
    /// Its prepared volume (range, analysis, grid).
    pub prepared: Arc<PreparedVolume>,
    /// The derived volumes it holds.
    pub outputs: Option<DerivativeOutputs>,
    /// Its brain mask, shared by every frame.
    pub brain: Option<Arc<BrainMask>>,
}

/// A frame prepared like the one on screen.
pub struct FrameReady {
    /// The new twin.
    pub twin: Twin,
    /// The frame as read (the readout's values).
    pub host: Arc<Volume>,
    /// GPU passes it ran.
    pub passes: Vec<PassTiming>,
    /// Reading the frame from the file, ms (None: held in memory).
    pub read_ms: Option<f64>,
    /// Host wall times, ms: upload and normalization, derived volumes, brick ranges.
    pub steps_ms: [f64; 3],
}

/// Prepares `input` like `like` on `engine` (module doc); errors are one line.
pub fn prepare_frame(
    engine: &mut Engine,
    input: FrameInput,
    like: &Like,
) -> Result<FrameReady, String> {
    let text = |e: &dyn std::fmt::Display| super::loader::one_line(&e.to_string());
    let before_read = Instant::now();
    let (host, read_ms) = match input {
        FrameInput::Held(volume) => (volume, None),
        FrameInput::Read(source, options) => {
            let read = source::read(&source, &options).map_err(|e| text(&e))?;
            let ms = before_read.elapsed().as_secs_f64() * 1e3;
            (Arc::new(read.volume), Some(ms))
        }
    };
    let ms = |since: Instant| since.elapsed().as_secs_f64() * 1e3;
    let before = Instant::now();
    let prepared = engine
        .prepare_frame(&host, &like.prepared)
        .map_err(|e| text(&e))?;
    let normalize_ms = ms(before);
    let mut passes = prepared.gpu_timings.clone();
    let mut twin = Twin::new(prepared);
    let before_derive = Instant::now();
    if let Some(outputs) = like.outputs {
        let derived = engine
            .derive_frame(&twin.prepared, outputs, like.brain.clone())
            .map_err(|e| text(&e))?;
        passes.extend(derived.gpu_timings.iter().cloned());
        twin.install(derived);
    }
    let derive_ms = ms(before_derive);
    let before_ranges = Instant::now();
    let (_, ranges) = engine
        .brick_ranges_timed(&twin.prepared)
        .map_err(|e| text(&e))?;
    passes.extend(ranges);
    let steps_ms = [normalize_ms, derive_ms, ms(before_ranges)];
    Ok(FrameReady {
        twin,
        host,
        passes,
        read_ms,
        steps_ms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{LinearMap, Samples};

    #[test]
    fn the_cap_is_a_quarter_of_the_budget_and_at_most_2_gib() {
        assert_eq!(hold_cap(400 << 20), 100 << 20);
        assert_eq!(hold_cap(64 << 30), HOLD_CAP_MAX);
        assert_eq!(hold_cap(0), 0);
    }

    #[test]
    fn the_time_course_applies_each_frame_s_own_map() {
        let frame = |values: &[i16], slope: f64, intercept: f64| {
            let mut v = Volume::from_voxels(
                "t",
                [2, 1, 1],
                Samples::from_i16(values),
                [
                    [1.0, 0.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0, 0.0],
                    [0.0, 0.0, 1.0, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                ],
                LinearMap::IDENTITY,
            )
            .unwrap();
            v.to_physical = LinearMap { slope, intercept };
            Arc::new(v)
        };
        let held = HeldFrames {
            volumes: vec![frame(&[1, 5], 2.0, 10.0), frame(&[3, 7], 0.5, 0.0)],
            bytes: 8,
        };
        assert_eq!(held.time_course(1), vec![20.0, 3.5]);
        // A voxel past the end is NaN in every frame, never a panic.
        assert!(held.time_course(9).iter().all(|v| v.is_nan()));
    }

    #[test]
    fn each_held_frame_s_warnings_name_that_frame() {
        let read = vec![
            "4-D file with 6 frames: showing frame 0".to_string(),
            "bitpix is 8".to_string(),
        ];
        assert_eq!(
            frame_warnings(&read, 4),
            ["4-D file with 6 frames: showing frame 4", "bitpix is 8"]
        );
    }
}
