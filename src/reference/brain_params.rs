//! Parameters of brain extraction (`reference::brain`), shared by the GPU passes and their f64 twin
//! (`reference::brain`), so both read one definition and one validation.
//!
//! Decisions (defaults measured with a scipy prototype of the same chain on a 0.88 mm research
//! T1 against its ROBEX mask: Dice 0.95-0.97 for erosion radii 4-5 mm; 3 mm leaked into the
//! scalp, 6 mm lost thin gyri):
//! - `grow_mm` 2.5 instead of the first specification's 1.5: measured with the twin (`brain_twin`
//!   example, this machine) on chris_t1 against ROBEX, erode 4.5 / close 5: grow 1.5 gave Dice
//!   0.947 (1452 cm^3 against ROBEX's 1573), 2.0 0.951, 2.5 0.953, 3.0 0.952. The band cuts the
//!   brain's partial-volume rim (and the CSF ROBEX includes), which the grow gives back. A
//!   smaller erosion scores higher on this scan (3.5 mm / close 6 / grow 2: 0.971; 4 / 6 / 2:
//!   0.963) and leaks only at 2.5 mm here, but 4.5 mm is kept for the margin the specification asks
//!   for (the prototype leaked at 3 mm, and the thick-slice T2w head leaks into its vertex
//!   scalp at every radius tried).
//! - Radii are in mm, so anisotropic voxels erode and dilate by the same ball.
//! - The band `lo..hi` has no useful default: it comes from the histogram
//!   (`analysis::brain_band::band_for`). [`BrainParams::default`] carries `0..2` (every voxel
//!   brighter than the darkest) only so that `..BrainParams::default()` fills the morphology;
//!   [`BrainParams::for_band`] is the usual way in.
//! - `sigma_mm` may be 0 (no smoothing: a radius-0 kernel copies); the radii must be > 0 except
//!   the grow, which may be 0; `close_mm > grow_mm` because the closing's erosion radius is their
//!   difference.

/// Largest coarse-grid cell edge in voxels.
pub const MAX_COARSE: usize = 8;

/// Parameters of the extraction chain (defaults in the module doc and on the fields).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BrainParams {
    /// Gaussian pre-smoothing in mm (1.0).
    pub sigma_mm: f64,
    /// Tissue band, lower end in I_norm (exclusive).
    pub lo: f64,
    /// Tissue band, upper end in I_norm (exclusive; above 1 means no upper bound).
    pub hi: f64,
    /// Erosion radius in mm (4.5).
    pub erode_mm: f64,
    /// Closing radius in mm (5.0).
    pub close_mm: f64,
    /// Net growth of the closing in mm (2.5; the first specification said 1.5): its erosion is
    /// `close_mm - grow_mm`.
    pub grow_mm: f64,
    /// Coarse-grid cell edge in voxels, 1..=8 (2).
    pub coarse: usize,
    /// Foreground threshold in I_norm whose enclosure is the head (half the band's `lo`:
    /// [`BrainParams::for_band`]); `reference::brain_depth`.
    pub head_lo: f64,
    /// Depth under the head's surface in mm down to which a bridged head's second try drops
    /// the tissue (8; 0 turns the second try off); `reference::brain_depth`.
    pub scalp_mm: f64,
}

/// Voxel lengths in mm of each index axis: the column norms of the index-to-world linear part
/// (exact for rotations, the usual oblique affines; a sheared one is treated as its lengths).
pub fn spacing_mm(linear: [[f64; 3]; 3]) -> [f64; 3] {
    std::array::from_fn(|c| {
        (linear[0][c] * linear[0][c] + linear[1][c] * linear[1][c] + linear[2][c] * linear[2][c])
            .sqrt()
    })
}

/// The squared radius the closing's erosion compares with: `(close_mm - grow_mm)^2`.
pub fn close_threshold(params: &BrainParams) -> f64 {
    let r = params.close_mm - params.grow_mm;
    r * r
}

impl Default for BrainParams {
    fn default() -> Self {
        BrainParams {
            sigma_mm: 1.0,
            lo: 0.0,
            hi: 2.0,
            erode_mm: 4.5,
            close_mm: 5.0,
            grow_mm: 2.5,
            coarse: 2,
            head_lo: 0.0,
            scalp_mm: 8.0,
        }
    }
}

/// Why brain-extraction parameters are unusable.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BrainParamsError {
    /// A parameter is NaN or infinite.
    #[error("brain extraction: {name} = {value} is not a finite number")]
    NotFinite {
        /// The parameter's name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A parameter is out of its range.
    #[error("brain extraction: {name} = {value} must be {rule}")]
    OutOfRange {
        /// The parameter's name.
        name: &'static str,
        /// Its value.
        value: f64,
        /// The rule, as words.
        rule: &'static str,
    },
    /// The band is empty.
    #[error("brain extraction: the tissue band {lo}..{hi} is empty (lo must be below hi)")]
    EmptyBand {
        /// Lower end.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
    /// The closing does not exceed the grow.
    #[error(
        "brain extraction: close_mm = {close} must exceed grow_mm = {grow} (the closing erodes by their difference)"
    )]
    CloseNotAboveGrow {
        /// close_mm.
        close: f64,
        /// grow_mm.
        grow: f64,
    },
    /// The coarse cell edge is outside 1..=8.
    #[error("brain extraction: the coarse cell edge {0} must be 1..=8 voxels")]
    Coarse(usize),
}

impl BrainParams {
    /// The defaults with the band `lo..hi` (from `band_for`) and the head's foreground at half
    /// of `lo` (below the band's darkest tissue, above air and noise: the prototype of
    /// `reference::brain_depth` used 0.3 x Otsu, which is half of a T2 band's `lo`).
    pub fn for_band(lo: f64, hi: f64) -> Self {
        BrainParams {
            lo,
            hi,
            head_lo: 0.5 * lo,
            ..BrainParams::default()
        }
    }

    /// Checks every rule of the module doc.
    pub fn validate(&self) -> Result<(), BrainParamsError> {
        let fields = [
            ("sigma_mm", self.sigma_mm),
            ("lo", self.lo),
            ("hi", self.hi),
            ("erode_mm", self.erode_mm),
            ("close_mm", self.close_mm),
            ("grow_mm", self.grow_mm),
            ("head_lo", self.head_lo),
            ("scalp_mm", self.scalp_mm),
        ];
        if let Some(&(name, value)) = fields.iter().find(|(_, v)| !v.is_finite()) {
            return Err(BrainParamsError::NotFinite { name, value });
        }
        let range = |name, value: f64, ok: bool, rule| {
            if ok {
                Ok(())
            } else {
                Err(BrainParamsError::OutOfRange { name, value, rule })
            }
        };
        range("sigma_mm", self.sigma_mm, self.sigma_mm >= 0.0, "0 or more")?;
        range("erode_mm", self.erode_mm, self.erode_mm > 0.0, "above 0")?;
        range("grow_mm", self.grow_mm, self.grow_mm >= 0.0, "0 or more")?;
        range("scalp_mm", self.scalp_mm, self.scalp_mm >= 0.0, "0 or more")?;
        if self.lo >= self.hi {
            return Err(BrainParamsError::EmptyBand {
                lo: self.lo,
                hi: self.hi,
            });
        }
        if self.close_mm <= self.grow_mm {
            return Err(BrainParamsError::CloseNotAboveGrow {
                close: self.close_mm,
                grow: self.grow_mm,
            });
        }
        if !(1..=MAX_COARSE).contains(&self.coarse) {
            return Err(BrainParamsError::Coarse(self.coarse));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_and_each_rule_is_enforced() {
        assert_eq!(BrainParams::default().validate(), Ok(()));
        assert_eq!(BrainParams::for_band(0.4, 0.9).validate(), Ok(()));
        let bad = |f: fn(&mut BrainParams)| {
            let mut p = BrainParams::default();
            f(&mut p);
            p.validate().unwrap_err()
        };
        assert!(matches!(
            bad(|p| p.sigma_mm = f64::NAN),
            BrainParamsError::NotFinite {
                name: "sigma_mm",
                ..
            }
        ));
        assert!(matches!(
            bad(|p| p.hi = f64::INFINITY),
            BrainParamsError::NotFinite { name: "hi", .. }
        ));
        assert!(matches!(
            bad(|p| p.erode_mm = 0.0),
            BrainParamsError::OutOfRange {
                name: "erode_mm",
                ..
            }
        ));
        assert!(matches!(
            bad(|p| p.grow_mm = -0.1),
            BrainParamsError::OutOfRange {
                name: "grow_mm",
                ..
            }
        ));
        assert!(matches!(
            bad(|p| p.sigma_mm = -1.0),
            BrainParamsError::OutOfRange { .. }
        ));
        assert!(matches!(
            bad(|p| p.lo = 2.0),
            BrainParamsError::EmptyBand { .. }
        ));
        assert!(matches!(
            bad(|p| p.close_mm = 1.5),
            BrainParamsError::CloseNotAboveGrow { .. }
        ));
        assert_eq!(bad(|p| p.coarse = 0), BrainParamsError::Coarse(0));
        assert_eq!(bad(|p| p.coarse = 9), BrainParamsError::Coarse(9));
        let mut ok = BrainParams::default();
        (ok.sigma_mm, ok.grow_mm, ok.coarse) = (0.0, 0.0, 8);
        assert_eq!(ok.validate(), Ok(()));
    }
}
