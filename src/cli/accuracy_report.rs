//! What `morphray accuracy` reports: per setting its time, error and frontier membership, the
//! recommendations per device class, and the table it prints.

use super::accuracy::NOISY_TIME_SPREAD;
use super::output::print_line;
use crate::study::metrics::ImageError;
use crate::study::stability::OpacityStability;

/// One setting's result.
#[derive(Clone, Debug, serde::Serialize)]
pub(super) struct SettingResult {
    pub(super) name: &'static str,
    pub(super) knob: &'static str,
    pub(super) group: &'static str,
    /// Median over the timing rounds of the mean frame time over the views.
    pub(super) gpu_ms: f64,
    /// Relative half-width of the rounds' 10th..90th percentile range: the time's resolution.
    pub(super) time_spread: f64,
    pub(super) precompute_ms: f64,
    pub(super) error: ImageError,
    pub(super) samples_per_frame: f64,
    pub(super) xe_lp_model_ms: f64,
    pub(super) frontier: bool,
    pub(super) xe_lp_frontier: bool,
    pub(super) default: bool,
    pub(super) skipped: Option<String>,
    /// Why the setting is kept off the frontier despite its images (a failed stability check).
    pub(super) unstable: Option<String>,
    /// Whether the setting uses the naive f32 opacity correction.
    pub(super) naive_opacity: bool,
}

#[derive(serde::Serialize)]
pub(super) struct Recommendation {
    pub(super) device_class: String,
    pub(super) interaction: Option<&'static str>,
    pub(super) diagnosis: Option<&'static str>,
    pub(super) rule: &'static str,
}

#[derive(serde::Serialize)]
pub(super) struct AccuracyReport<'a> {
    pub(super) engine: String,
    pub(super) device: String,
    pub(super) device_type: &'static str,
    pub(super) input: &'a str,
    pub(super) dims: [u32; 3],
    pub(super) image: [u32; 2],
    /// Size of the timing renders (RGBA8).
    pub(super) time_image: [u32; 2],
    pub(super) views: Vec<(f64, f64)>,
    pub(super) frames: u32,
    pub(super) reference: &'static str,
    pub(super) settings: Vec<SettingResult>,
    pub(super) default_on_frontier: bool,
    /// Median over the settings of each setting's round-to-round time spread (relative
    /// half-width of its 10th..90th percentile range).
    pub(super) typical_time_spread: f64,
    /// Worst relative errors of the exact and the naive opacity correction on this device.
    pub(super) opacity_stability: OpacityStability,
    pub(super) recommendations: Vec<Recommendation>,
    /// The loader's repairs and warnings about the input.
    pub(super) warnings: Vec<String>,
}

pub(super) fn print_table(r: &AccuracyReport<'_>) {
    print_line(&format!(
        "{} on {}: {} {}x{}x{}, error at {}x{} px, time at {}x{} px, {} views, {} frames",
        r.engine,
        r.device,
        r.input,
        r.dims[0],
        r.dims[1],
        r.dims[2],
        r.image[0],
        r.image[1],
        r.time_image[0],
        r.time_image[1],
        r.views.len(),
        r.frames
    ));
    print_line(&format!("reference: {}", r.reference));
    print_line(
        "setting                        group          GPU ms   +-%   precompute  RMSE      PSNR dB  SSIM    max abs  frontier  Xe-LP model ms",
    );
    for s in &r.settings {
        if let Some(why) = &s.skipped {
            print_line(&format!("{:<30} {:<14} skipped: {why}", s.name, s.group));
            continue;
        }
        print_line(&format!(
            "{:<30} {:<14} {:>7.3} {:>5.1}  {:>9.3}  {:>8.5}  {:>7.2}  {:>6.4}  {:>7.4}  {:<8}  {:>8.3}{}",
            s.name,
            s.group,
            s.gpu_ms,
            s.time_spread * 100.0,
            s.precompute_ms,
            s.error.rmse,
            s.error.psnr_db,
            s.error.ssim,
            s.error.max_abs,
            if s.frontier {
                "yes"
            } else if s.unstable.is_some() {
                "unstable"
            } else {
                ""
            },
            s.xe_lp_model_ms,
            if s.default {
                "   <- render/view default"
            } else {
                ""
            }
        ));
    }
    print_line(&format!(
        "default on the measured frontier: {}",
        if r.default_on_frontier { "yes" } else { "NO" }
    ));
    if r.typical_time_spread > NOISY_TIME_SPREAD {
        print_line(&format!(
            "warning: GPU times varied by +-{:.0} % between rounds (median over the settings): \
             the device was busy, time differences under {:.0} % count as ties, so the frontier \
             and the recommendations rest on the errors alone; rerun on an idle device",
            r.typical_time_spread * 100.0,
            r.typical_time_spread * 200.0
        ));
    }
    print_line(&format!(
        "opacity correction on this device, worst relative error over NUMERICS.md's grid: exact {:.2e}, naive {:.2e} (a = {:e}, r = {})",
        r.opacity_stability.exact.relative,
        r.opacity_stability.naive.relative,
        r.opacity_stability.naive.alpha,
        r.opacity_stability.naive.ratio
    ));
    for s in r.settings.iter().filter(|s| s.unstable.is_some()) {
        print_line(&format!(
            "kept off the frontier: {}: {}",
            s.name,
            s.unstable.as_deref().unwrap_or("")
        ));
    }
    for rec in &r.recommendations {
        print_line(&format!(
            "recommended for {}: interaction `{}`, diagnosis `{}`",
            rec.device_class,
            rec.interaction.unwrap_or("-"),
            rec.diagnosis.unwrap_or("-")
        ));
    }
}
