//! Brain extraction as a scene asks for it: which band the chain of `engine/brain.rs` runs with,
//! and, for contrasts whose CSF is bright, the second run with a band closed above.
//!
//! Decisions:
//! - The band comes from the histogram and the analysed contrast (`analysis::brain_band`); MR
//!   heads only (not CT, PET, angiography or EPI series).
//! - T2 and PD run the chain twice: first with the band open above (CSF belongs to the brain),
//!   then with its upper end halfway between GM and CSF of the tissue fit inside the first mask
//!   (`analysis::brain_band_csf` says why: the scalp fat and the eyes are as bright as CSF).
//!   The second mask replaces the first when it is a plausible brain; a first run that saw a
//!   head keeps the volume a head (the narrower band leaves less scalp in the band, which is what
//!   the skull-stripped test counts). "Plausible": not refused, and at least [`MIN_KEPT`] of
//!   the first mask's volume (a second band that cuts the brain itself is a fit gone wrong).
//!   The cost is a second extraction for those contrasts only.
//! - The tissue fit (`engine/brain_fit.rs`) reads the first mask, the brain with its CSF (as
//!   ROBEX's masks are), kept on the host (`BrainMask::fit_mask`); the raymarch the second, the
//!   brain's surface.

use super::Engine;
use super::brain::BrainMask;
use super::prepare::{PreparedVolume, VolumeLayout};
use super::readback::read_image;
use crate::analysis::Contrast;
use crate::analysis::brain_band::band_for;
use crate::analysis::brain_band_csf::bright_csf_upper;
use crate::gpu::{Access, GpuResult};
use crate::passes::brain::BrainSwitch;
use crate::reference::brain_params::BrainParams;
use crate::reference::brain_report::{BrainDecision, BrainReport};

/// The second mask replaces the first only when it keeps at least this share of its volume (a
/// second band that breaks the brain into pieces keeps one of them). Measured (`derive --maps
/// brain`, this machine): the clinical T2w head keeps 72 % (1953 -> 1406 cm^3: the scalp and
/// orbits leave), the synthetic T2 head of tests/brain_extraction.rs 75 % (827 -> 624); the PD head
/// phantom's wrongly labelled fit (`brain_band_csf::MIN_CLASS_WEIGHT` now refuses it) would
/// have kept 20 %.
pub const MIN_KEPT: f64 = 0.3;

impl Engine {
    /// Brain extraction as a scene's `switch` asks for it (not `Off`): the band from the
    /// histogram and the analysed contrast, then the chain (module doc); `used` set by the switch.
    pub fn extract_brain(
        &mut self,
        prepared: &PreparedVolume,
        switch: BrainSwitch,
    ) -> GpuResult<BrainMask> {
        if matches!(prepared.layout, VolumeLayout::Bricked(_)) {
            // The plan turns extraction off for bricked volumes; a caller asking anyway gets
            // nothing masked rather than an error.
            return Ok(BrainMask::none(&BrainParams::default(), Vec::new()));
        }
        let identity = &prepared.identity;
        // Brain extraction is for MR heads: not CT, PET, angiography or the EPI series.
        let not_a_head_scan =
            identity.modality.modality != crate::analysis::Modality::Mr || identity.kind.is_some();
        let contrast = self
            .analyze_identified(prepared, identity)
            .contrast
            .contrast;
        if not_a_head_scan {
            let mut none = BrainMask::none(&BrainParams::default(), Vec::new());
            none.report = BrainReport::not_a_head_scan();
            return Ok(none);
        }
        let Some(band) = band_for(&prepared.histogram, contrast) else {
            return Ok(BrainMask::none(&BrainParams::default(), Vec::new()));
        };
        let mut mask = self.banded_mask(prepared, band, contrast)?;
        mask.used = mask.use_for(switch);
        Ok(mask)
    }

    /// The chain with `band`, and for a bright-CSF contrast the second run (module doc).
    fn banded_mask(
        &mut self,
        prepared: &PreparedVolume,
        (lo, hi): (f64, f64),
        contrast: Contrast,
    ) -> GpuResult<BrainMask> {
        let bright_csf = matches!(contrast, Contrast::T2 | Contrast::Pd);
        let params = BrainParams::for_band(lo, hi);
        let (first, inside) = self.brain_chain(prepared, &params, bright_csf)?;
        let Some(upper) = inside.and_then(|h| bright_csf_upper(&h, (lo, hi), contrast)) else {
            return Ok(first);
        };
        let mut second = self.brain_mask(prepared, &BrainParams::for_band(lo, upper))?;
        let kept = second.report.brain_cm3 / first.report.brain_cm3.max(1e-9);
        if second.image.is_none()
            || second.report.decision == BrainDecision::NotFound
            || kept < MIN_KEPT
        {
            return Ok(first);
        }
        if first.report.decision == BrainDecision::Head {
            second.report.decision = BrainDecision::Head;
        }
        // The tissue fit keeps reading the first mask: inside the second, without the outer
        // CSF, T2w's GM and WM classes merged (GM 0.227 +- 0.060, WM 0.191 +- 0.021: not sound,
        // the windows fell back to one foreground class), inside the first they are three.
        if let Some(image) = &first.image {
            let values = read_image(self.device(), image, Access::ComputeSampled)?.values;
            second.fit_mask = Some(values.iter().map(|&v| u8::from(v >= 0.5)).collect());
        }
        second.report.band_from_fit = true;
        second.report.total_ms += first.report.total_ms;
        second.report.host_ms += first.report.host_ms;
        let mut timings = first.gpu_timings;
        timings.append(&mut second.gpu_timings);
        second.gpu_timings = timings;
        Ok(second)
    }
}
