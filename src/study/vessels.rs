//! The vesselness and denoising knobs of the accuracy study (`morphray accuracy --vessels`): what
//! each setting costs in GPU time next to its error, on the shape phantoms of
//! `volume::shape_phantoms` (tubes of radius 0.5 to 3 mm, plates, balls).
//!
//! Decisions:
//! - Number of scales: 1 to 6 log-spaced scales over 0.6 to 3 mm (1 scale: their geometric mean,
//!   1.34 mm). Error: 1 - ROC AUC of tube centrelines against plate and ball centres, and the
//!   weakest centreline response (a radius the scales miss shows there first); plus the GPU's
//!   largest deviation from the f64 twin.
//! - Denoising: each kind on a noisy copy of the shapes (uniform noise of +-`NOISE` in I_norm,
//!   deterministic), against the clean volume: RMS error of I_norm, and 1 - AUC of the vesselness
//!   computed from the denoised volume (default scales). The noisy values are clamped to [0, 1]
//!   with voxels 0 and 1 pinned to 0 and 1, so noisy and clean share one normalization.
//! - GPU time: the median over `repeats` runs of the passes' timestamps.

use crate::engine::{Engine, readback::read_image};
use crate::gpu::{Access, GpuResult};
use crate::passes::denoise::Denoise;
use crate::passes::vesselness::VesselnessParams;
use crate::reference::IndexToWorld;
use crate::reference::vesselness::{VesselnessOptions, vesselness};
use crate::volume::Samples;
use crate::volume::shape_phantoms::{ShapeKind, ShapeVolume, blobs, plates, roc_auc, tubes};

/// Half-width of the uniform noise of the denoising rows (I_norm units).
pub const NOISE: f64 = 0.15;

/// One row of the scales knob.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ScalesRow {
    /// The scales (mm).
    pub scales_mm: Vec<f32>,
    /// 1 - ROC AUC (tubes vs plates and balls), GPU.
    pub one_minus_auc: f64,
    /// Weakest tube-centreline response, GPU.
    pub weakest_tube: f64,
    /// Largest |GPU - f64| over the three volumes.
    pub max_gpu_error: f64,
    /// Median GPU time for the three volumes together (ms).
    pub gpu_ms: f64,
}

/// One row of the denoising knob.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DenoiseRow {
    /// The filter.
    pub denoise: Denoise,
    /// RMS error of I_norm against the clean volumes.
    pub rms_error: f64,
    /// 1 - ROC AUC of the vesselness of the denoised noisy volumes.
    pub one_minus_auc: f64,
    /// Median GPU time of the filter for the three volumes (ms).
    pub gpu_ms: f64,
}

/// The whole study.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VesselStudy {
    /// Scales knob.
    pub scales: Vec<ScalesRow>,
    /// Denoising knob.
    pub denoise: Vec<DenoiseRow>,
}

/// `n` log-spaced scales over 0.6 .. 3 mm (1: the geometric mean).
pub fn log_scales(n: usize) -> Vec<f32> {
    if n <= 1 {
        return vec![(0.6f64 * 3.0).sqrt() as f32];
    }
    (0..n)
        .map(|i| (0.6f64 * 5f64.powf(i as f64 / (n - 1) as f64)) as f32)
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

fn auc(shapes: &[ShapeVolume], scores: &[Vec<f64>]) -> (f64, f64) {
    let (mut pos, mut neg) = (Vec::new(), Vec::new());
    for (s, sc) in shapes.iter().zip(scores) {
        for l in &s.labelled {
            match l.kind {
                ShapeKind::Tube => pos.push(sc[l.index]),
                _ => neg.push(sc[l.index]),
            }
        }
    }
    let weakest = pos.iter().copied().fold(f64::INFINITY, f64::min);
    (1.0 - roc_auc(&pos, &neg), weakest)
}

fn noisy(shape: &ShapeVolume, seed: u64) -> ShapeVolume {
    let clean = shape.volume.samples.to_f64_vec();
    let mut state = seed;
    let values: Vec<f32> = clean
        .iter()
        .enumerate()
        .map(|(i, c)| {
            // SplitMix64 of (seed, index): deterministic uniform in [-1, 1).
            state = seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            let mut z = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            let u = ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64;
            // Clamped to [0, 1] with both extremes pinned, so the noisy copy normalizes exactly
            // as the clean one does (I_norm = value) and errors compare in the same units.
            match i {
                0 => 0.0,
                1 => 1.0,
                _ => (c + NOISE * (2.0 * u - 1.0)).clamp(0.0, 1.0) as f32,
            }
        })
        .collect();
    let mut volume = shape.volume.clone();
    volume.samples = Samples::from_f32(&values);
    ShapeVolume {
        volume,
        labelled: shape.labelled.clone(),
    }
}

/// Runs the study (module decisions).
pub fn run(engine: &mut Engine, repeats: usize) -> GpuResult<VesselStudy> {
    let shapes = [tubes(), plates(), blobs()];
    let prepared = shapes
        .iter()
        .map(|s| engine.prepare(&s.volume))
        .collect::<GpuResult<Vec<_>>>()?;
    let mut scales = Vec::new();
    for n in [1usize, 2, 3, 4, 6] {
        let params = VesselnessParams {
            scales_mm: log_scales(n),
            ..Default::default()
        };
        let mut times = Vec::new();
        let mut scores = Vec::new();
        let mut max_error = 0.0f64;
        for r in 0..repeats.max(1) {
            let mut total = 0.0;
            for p in prepared.iter() {
                let v = engine.vesselness(p, &params)?;
                total += v.gpu_timings.iter().map(|t| t.gpu_ms).sum::<f64>();
                if r == 0 {
                    let gpu: Vec<f64> =
                        read_image(engine.device(), &v.image, Access::ComputeSampled)?
                            .values
                            .iter()
                            .map(|&x| x as f64)
                            .collect();
                    let norm: Vec<f64> =
                        read_image(engine.device(), &p.normalized, Access::ComputeSampled)?
                            .values
                            .iter()
                            .map(|&x| x as f64)
                            .collect();
                    let options = VesselnessOptions {
                        scales_mm: params.scales_mm.iter().map(|&s| s as f64).collect(),
                        ..Default::default()
                    };
                    let to_world = IndexToWorld::new(p.linear_part)
                        .map_err(|e| crate::gpu::GpuError::InvalidRequest(e.to_string()))?;
                    let dims = p.dims.map(|d| d as usize);
                    let twin = vesselness(&norm, dims, &to_world, &options)
                        .map_err(|e| crate::gpu::GpuError::InvalidRequest(e.to_string()))?;
                    for (g, t) in gpu.iter().zip(&twin) {
                        max_error = max_error.max((g - t).abs());
                    }
                    scores.push(gpu);
                }
            }
            times.push(total);
        }
        let (one_minus_auc, weakest_tube) = auc(&shapes, &scores);
        scales.push(ScalesRow {
            scales_mm: params.scales_mm,
            one_minus_auc,
            weakest_tube,
            max_gpu_error: max_error,
            gpu_ms: median(times),
        });
    }
    let noisy_shapes: Vec<ShapeVolume> = shapes.iter().map(|s| noisy(s, 15)).collect();
    let noisy_prepared = noisy_shapes
        .iter()
        .map(|s| engine.prepare(&s.volume))
        .collect::<GpuResult<Vec<_>>>()?;
    let clean_norm = prepared
        .iter()
        .map(|p| read_image(engine.device(), &p.normalized, Access::ComputeSampled))
        .collect::<GpuResult<Vec<_>>>()?;
    let mut denoise = Vec::new();
    for d in [
        Denoise::None,
        Denoise::Gaussian { sigma_mm: 0.6 },
        Denoise::Gaussian { sigma_mm: 1.2 },
        Denoise::Median,
        Denoise::Bilateral {
            sigma_mm: 1.0,
            range: 0.15,
        },
    ] {
        let mut times = Vec::new();
        let (mut sq, mut count) = (0.0f64, 0usize);
        let mut scores = Vec::new();
        for r in 0..repeats.max(1) {
            let mut total = 0.0;
            for (p, clean) in noisy_prepared.iter().zip(&clean_norm) {
                let out = engine.denoise(p, &d)?;
                let source = out.as_ref().unwrap_or(p);
                if let Some(o) = &out {
                    let own = o.gpu_timings.len() - p.gpu_timings.len();
                    total += o
                        .gpu_timings
                        .iter()
                        .rev()
                        .take(own)
                        .map(|t| t.gpu_ms)
                        .sum::<f64>();
                }
                if r == 0 {
                    let values =
                        read_image(engine.device(), &source.normalized, Access::ComputeSampled)?;
                    // Away from the two pinned voxels.
                    for (v, c) in values.values.iter().zip(&clean.values).skip(2) {
                        sq += ((v - c) as f64).powi(2);
                        count += 1;
                    }
                    let v = engine.vesselness(source, &VesselnessParams::default())?;
                    scores.push(
                        read_image(engine.device(), &v.image, Access::ComputeSampled)?
                            .values
                            .iter()
                            .map(|&x| x as f64)
                            .collect(),
                    );
                }
            }
            times.push(total);
        }
        let (one_minus_auc, _) = auc(&noisy_shapes, &scores);
        denoise.push(DenoiseRow {
            denoise: d,
            rms_error: (sq / count.max(1) as f64).sqrt(),
            one_minus_auc,
            gpu_ms: median(times),
        });
    }
    Ok(VesselStudy { scales, denoise })
}

/// The study as a plain-text table.
pub fn table(study: &VesselStudy) -> String {
    let mut out = String::from(
        "vesselness scales (shape phantoms: tubes r 0.5-3 mm vs plates and balls)\n\
         scales (mm)                      1-AUC    weakest tube  max|GPU-f64|  GPU ms\n",
    );
    for r in &study.scales {
        let s: Vec<String> = r.scales_mm.iter().map(|x| format!("{x:.3}")).collect();
        out += &format!(
            "{:<32} {:<8.4} {:<13.3} {:<13.2e} {:.2}\n",
            s.join(","),
            r.one_minus_auc,
            r.weakest_tube,
            r.max_gpu_error,
            r.gpu_ms
        );
    }
    out += &format!(
        "\ndenoising (noisy copy, uniform +-{NOISE} I_norm, vs clean)\n\
         filter                           RMS err  1-AUC after  GPU ms\n"
    );
    for r in &study.denoise {
        out += &format!(
            "{:<32} {:<8.4} {:<12.4} {:.2}\n",
            format!("{:?}", r.denoise),
            r.rms_error,
            r.one_minus_auc,
            r.gpu_ms
        );
    }
    out
}
