//! What the status line says: file, dims, spacing, device, time to first pixel of this load,
//! frame rate, GPU time per pass, the memory plan (layout, degradations), and one-line notes
//! and errors.
//!
//! Decisions: the frame rate counts volume frames, frames whose raymarch ran (issue 16: counting
//! interface frames read 60.8 FPS beside 1852 ms of GPU time per frame on a CPU device), and of
//! those only the ones presented: frames that finish together count once (issue 31: counting
//! each read 12536 volume FPS beside 6.4 s frames), over the last second of wall time (not
//! 1 / last frame time, which jumps); two records at the same instant give no rate. GPU times are the last
//! complete volume frame's timestamp-query results, per pass, so a bar per pass shows where the
//! time goes.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Frames per second over a sliding window of one second.
#[derive(Debug, Default)]
pub struct FrameRate {
    times: VecDeque<Instant>,
}

impl FrameRate {
    /// Records a volume frame (one whose raymarch ran). Frames older than one second are
    /// dropped, except that the last two are kept for up to ten seconds, so a slow device (a
    /// CPU renderer at 0.5 volume frames per second) still gets a rate instead of none.
    pub fn frame(&mut self, at: Instant) {
        self.times.push_back(at);
        while let Some(first) = self.times.front() {
            let age = at.duration_since(*first);
            if age > Duration::from_secs(10)
                || (age > Duration::from_secs(1) && self.times.len() > 2)
            {
                self.times.pop_front();
            } else {
                break;
            }
        }
    }

    /// Frames per second (None until two frames were seen).
    pub fn fps(&self) -> Option<f64> {
        let (first, last) = (self.times.front()?, self.times.back()?);
        let span = last.duration_since(*first).as_secs_f64();
        // Under a millisecond between the first and the last record is no measurement.
        (self.times.len() >= 2 && span >= 1e-3).then(|| (self.times.len() - 1) as f64 / span)
    }
}

/// A load in progress.
#[derive(Clone, Debug)]
pub struct Loading {
    /// What is being opened.
    pub label: String,
    /// The current phase.
    pub stage: String,
    /// When it was requested.
    pub since: Instant,
}

/// The status line's content.
#[derive(Debug, Default)]
pub struct Status {
    /// File name or `phantom`.
    pub file: String,
    /// A 4-D file's frame on screen: `frame 3/10` (from 0).
    pub frame: Option<String>,
    /// Volume dimensions.
    pub dims: [u32; 3],
    /// Voxel spacing, mm.
    pub spacing_mm: [f64; 3],
    /// Vulkan device name.
    pub device: String,
    /// Time to first pixel of the current volume, ms.
    pub ttfp_ms: Option<f64>,
    /// Frame rate.
    pub rate: FrameRate,
    /// GPU ms per pass of the last complete frame.
    pub passes: Vec<(String, f64)>,
    /// A note (e.g. "curvature volume computed once").
    pub note: Option<String>,
    /// The last error, one line (a failed load, out of memory, device lost).
    pub error: Option<String>,
    /// A load in progress.
    pub loading: Option<Loading>,
    /// A derived-volume computation in progress.
    pub deriving: Option<String>,
    /// The current volume's memory plan: layout and degradations (one line).
    pub plan: Option<String>,
    /// The adaptive quality level while the image is coarser than requested
    /// (`interactive: step x2, scale 0.75`).
    pub quality: Option<String>,
    /// What the volume was read as and where its windows come from (issue 28): modality,
    /// contrast, each with its basis, and the windows' source.
    pub identity: Option<String>,
    /// The crosshair's position and the value there (`app::readout`).
    pub readout: Option<String>,
}

/// The status bar's identity line of `report`: `MR (metadata) | T1 (metadata): ... | windows
/// from the fit`.
pub fn identity_text(report: &crate::analysis::TissueReport) -> String {
    let windows = match report.windows_from {
        crate::analysis::WindowsFrom::Fit => "windows from the tissue fit",
        crate::analysis::WindowsFrom::Modes => "windows from the histogram's modes",
        other => other.words(),
    };
    format!(
        "modality {}  |  contrast {}  |  {windows}",
        report.modality.summary(),
        report.contrast.summary()
    )
}

impl Status {
    /// The volume part: `file  256x256x192  1.00x1.00x1.00 mm  device`.
    pub fn volume_text(&self) -> String {
        if self.file.is_empty() {
            return format!("no volume yet  |  {}", self.device);
        }
        let [x, y, z] = self.dims;
        let [sx, sy, sz] = self.spacing_mm;
        format!(
            "{}  |  {x}x{y}x{z}  |  {sx:.2}x{sy:.2}x{sz:.2} mm  |  {}",
            self.file, self.device
        )
    }

    /// The timing part: `first pixel 812 ms  |  24.3 volume FPS  |  GPU 12.10 ms`.
    pub fn timing_text(&self) -> String {
        let mut parts = Vec::new();
        if let Some(t) = self.ttfp_ms {
            parts.push(format!("first pixel {t:.0} ms"));
        }
        match self.rate.fps() {
            Some(fps) => parts.push(format!("{fps:.1} volume FPS")),
            None => parts.push("- volume FPS".into()),
        }
        let gpu: f64 = self.passes.iter().map(|(_, ms)| ms).sum();
        if !self.passes.is_empty() {
            parts.push(format!("GPU {gpu:.2} ms/frame"));
        }
        if let Some(quality) = &self.quality {
            parts.push(quality.clone());
        }
        parts.join("  |  ")
    }

    /// Each pass's share of the frame's GPU time, for the bar (name, ms, fraction of total).
    pub fn pass_shares(&self) -> Vec<(String, f64, f64)> {
        let total: f64 = self.passes.iter().map(|(_, ms)| ms.max(0.0)).sum();
        self.passes
            .iter()
            .map(|(name, ms)| {
                let share = if total > 0.0 {
                    ms.max(0.0) / total
                } else {
                    0.0
                };
                (name.clone(), *ms, share)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_rate_counts_frames_in_the_last_second() {
        let mut rate = FrameRate::default();
        let t0 = Instant::now();
        assert_eq!(rate.fps(), None);
        for i in 0..=30 {
            rate.frame(t0 + Duration::from_millis(i * 20));
        }
        // 31 frames 20 ms apart: 50 FPS.
        assert!((rate.fps().unwrap() - 50.0).abs() < 1e-9);
        // After a pause, old frames leave the window.
        rate.frame(t0 + Duration::from_millis(3000));
        rate.frame(t0 + Duration::from_millis(3100));
        assert!((rate.fps().unwrap() - 10.0).abs() < 1e-9);
    }

    #[test]
    fn frames_recorded_at_one_instant_claim_no_rate() {
        // Two records 0.08 ms apart once read 12536 volume FPS beside 6.4 s frames.
        let mut rate = FrameRate::default();
        let t0 = Instant::now();
        rate.frame(t0);
        rate.frame(t0 + Duration::from_micros(80));
        assert_eq!(rate.fps(), None);
        rate.frame(t0 + Duration::from_millis(6400));
        assert!(rate.fps().unwrap() < 1.0, "{:?}", rate.fps());
    }

    #[test]
    fn a_slow_device_still_gets_a_volume_frame_rate() {
        // 1852 ms per volume frame (the CPU device): 0.54 volume FPS, not "-".
        let mut rate = FrameRate::default();
        let t0 = Instant::now();
        for i in 0..4 {
            rate.frame(t0 + Duration::from_millis(i * 1852));
        }
        assert!((rate.fps().unwrap() - 1000.0 / 1852.0).abs() < 1e-9);
        // Ten seconds without a volume frame: no rate is claimed.
        rate.frame(t0 + Duration::from_millis(30_000));
        assert_eq!(rate.fps(), None);
        let status = Status {
            rate,
            ..Status::default()
        };
        assert!(
            status.timing_text().contains("- volume FPS"),
            "{}",
            status.timing_text()
        );
    }

    #[test]
    fn texts_and_shares() {
        let status = Status {
            file: "t1.nii.gz".into(),
            dims: [48, 48, 40],
            spacing_mm: [1.0, 1.0, 1.2],
            device: "llvmpipe".into(),
            ttfp_ms: Some(812.4),
            passes: vec![("raymarch".into(), 3.0), ("interface".into(), 1.0)],
            ..Status::default()
        };
        assert_eq!(
            status.volume_text(),
            "t1.nii.gz  |  48x48x40  |  1.00x1.00x1.20 mm  |  llvmpipe"
        );
        assert!(status.timing_text().starts_with("first pixel 812 ms"));
        assert!(status.timing_text().ends_with("GPU 4.00 ms/frame"));
        let shares = status.pass_shares();
        assert_eq!(shares[0].2, 0.75);
        assert_eq!(shares[1].2, 0.25);
    }

    #[test]
    fn a_coarse_image_is_named_after_the_gpu_time() {
        use crate::app::adaptive::{LADDER, Level};
        let status = Status {
            passes: vec![("raymarch".into(), 3.0)],
            quality: LADDER[5].status_words(),
            ..Status::default()
        };
        assert!(
            status
                .timing_text()
                .ends_with("GPU 3.00 ms/frame  |  interactive: step x4, scale 0.75"),
            "{}",
            status.timing_text()
        );
        assert_eq!(Level::FULL.status_words(), None);
    }
}
