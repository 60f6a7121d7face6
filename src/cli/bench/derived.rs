//! `bench`'s rows for the derived volumes: every derivative variant (or only the planned one
//! under a memory budget or bricking, the full study's condition), each repeated, and the vessel
//! channel's vesselness when the scene shows vessels. Split from `bench.rs` by concern.

use super::{PassReport, pass_report, times_of};
use crate::engine::{Engine, PreparedVolume};
use crate::error::Error;
use crate::passes::cost::{self, DeviceModel};
use crate::passes::derivatives::DerivativeOutputs;
use crate::scene::Effects;

/// What turns a pass's times into rates, and how often to repeat it.
pub(super) struct Rates {
    /// The measured device copy rate (bytes/s).
    pub copy: Option<f64>,
    /// The device's documented model, when known.
    pub documented: Option<DeviceModel>,
    /// Bytes per I_norm texel.
    pub normalized_bytes: f64,
    /// Repetitions of each pass.
    pub repeat: u32,
}

/// The derived-volume pass reports of `prepared` for `effects`.
pub(super) fn reports(
    engine: &mut Engine,
    prepared: &PreparedVolume,
    effects: &Effects,
    full_study: bool,
    rates: &Rates,
) -> Result<Vec<PassReport>, Error> {
    let mut passes = Vec::new();
    // Derivative variants, repeated.
    let all_variants = [
        (
            "derivatives |g|",
            DerivativeOutputs {
                magnitude: true,
                curvature: false,
                normal: false,
                ..Default::default()
            },
        ),
        (
            "derivatives |g|,k",
            DerivativeOutputs {
                magnitude: true,
                curvature: true,
                normal: false,
                ..Default::default()
            },
        ),
        (
            "derivatives |g|,k,normals",
            DerivativeOutputs {
                magnitude: true,
                curvature: true,
                normal: true,
                ..Default::default()
            },
        ),
        ("derivatives max only", DerivativeOutputs::default()),
    ];
    let planned: Vec<(String, DerivativeOutputs)> = effects
        .derivative_outputs()
        // The brain mask has its own row below.
        .map(|o| DerivativeOutputs {
            brain: crate::passes::brain::BrainSwitch::Off,
            ..o
        })
        .map(|o| (format!("derivatives (planned, {:?})", o.precision), o))
        .into_iter()
        .collect();
    let variants: Vec<(String, DerivativeOutputs)> = if full_study {
        all_variants
            .iter()
            .map(|(name, o)| (name.to_string(), *o))
            .collect()
    } else {
        planned
    };
    let texels = prepared
        .normalized
        .extent()
        .iter()
        .map(|&d| d as f64)
        .product::<f64>();
    for (name, outputs) in variants {
        let mut times = Vec::new();
        for _ in 0..rates.repeat {
            let derived = engine.derive(prepared, outputs)?;
            times.extend(times_of(&derived.gpu_timings, "derivatives"));
        }
        let gradient_bytes = if outputs.magnitude || outputs.curvature {
            outputs.gradient_texel_bytes() as f64
        } else {
            0.0
        };
        let c = cost::derivatives(
            texels,
            rates.normalized_bytes,
            outputs.curvature,
            outputs.normal,
            gradient_bytes,
        );
        passes.push(pass_report(&name, &times, c, rates.copy, rates.documented));
    }

    // The vessel channel's vesselness (all scales, one timed pass), when the scene shows vessels.
    if effects.vessels {
        let params = crate::passes::vesselness::VesselnessParams::default();
        let mut times = Vec::new();
        for _ in 0..rates.repeat {
            let v = engine.vesselness(prepared, &params)?;
            times.extend(times_of(&v.gpu_timings, "vesselness"));
        }
        let c = cost::vesselness(texels, &params.scales_mm);
        passes.push(pass_report(
            "vesselness",
            &times,
            c,
            rates.copy,
            rates.documented,
        ));
    }
    // Brain extraction (its three submissions' GPU time together), when the scene asks for it.
    if effects.mode == crate::scene::RenderMode::Dvr
        && effects.brain != crate::passes::brain::BrainSwitch::Off
    {
        let mut times = Vec::new();
        for _ in 0..rates.repeat {
            let b = engine.extract_brain(prepared, effects.brain)?;
            times.push(b.gpu_timings.iter().map(|t| t.gpu_ms).sum::<f64>());
        }
        let spacing = crate::reference::brain_params::spacing_mm(prepared.linear_part);
        let factors = crate::passes::brain::working_factors(spacing);
        let c = cost::brain(texels / f64::from(factors.iter().product::<u32>()));
        passes.push(pass_report(
            "brain extraction",
            &times,
            c,
            rates.copy,
            rates.documented,
        ));
    }
    Ok(passes)
}
