//! The phantom's contrasts (issue 27 item 5, issue 28): one nominal intensity table per
//! contrast (T1, T2, PD, FLAIR, CT) and its noise model, so brain extraction and contrast
//! detection can be tested on a phantom whose truth is known.
//!
//! Decisions:
//! - One row per contrast, indexed by the tissue label ([`Tissue`] value), raw int16 units
//!   before bias, partial volume and noise. The T1 row's first eight entries are the plain
//!   phantom's [`super::phantom::NOMINAL`] and edema values unchanged (the plain T1 phantom is
//!   byte-identical to the one before contrasts existed; tests/phantom.rs pins its checksum).
//! - MR rows are relative signal on the T1 row's scale (WM 600-850, brightest tissue about
//!   1500, noise sigma 20), with the orders of clinical spin-echo images. The reasoning, from
//!   relaxation times and proton densities (e.g. Stanisz et al. 2005, MRM 54:507, for WM, GM
//!   and muscle; CSF and vitreous: very long T1 and T2, proton density ~1; fat: short T1, and
//!   bright on fast-spin-echo T2 through J-coupling; cortical bone: almost no MR signal):
//!   - T1: fat (1150) > diploe marrow (1050) > WM (850) > GM (600) ~ skin (620) ~ muscle
//!     (560) > CSF (250) ~ vitreous (240) > cortical bone (60). Fat brighter than WM is what
//!     makes the scalp a bright ring that brain extraction must cut away.
//!   - T2: CSF (1500) ~ vitreous (1450) brightest; lesion (1200) and edema (1050) hyperintense;
//!     fat (950) and marrow (850) bright-ish; GM (750) > WM (600); muscle (320) dark (T2 ~ 40 ms
//!     vs WM ~ 70 ms); bone (60) dark; vessels are flow voids (120).
//!   - PD: CSF (1100) > GM (950) > WM (820), low contrast (water content ~1.0 / 0.8 / 0.7);
//!     fat (1000) and marrow (950) bright; muscle (720); bone (60); vessels flow voids (200).
//!   - FLAIR: CSF and vitreous nulled (100); lesion (1400) > edema (1150) > GM (800) > WM
//!     (620); fat not nulled (900); muscle (350); bone (60); vessels flow voids (150).
//!   - Cord (spinal cord, below the foramen magnum): WM's value in every contrast, so the
//!     brainstem-cord bridge has no edge a brain extractor could follow.
//! - CT in Hounsfield units (textbook ranges): air -1000, fat -100, CSF 8, vitreous 10, edema
//!   18 (hypodense, below WM), WM 30, GM 40, skin 50, muscle 50, lesion 70 (hyperdense, like an
//!   acute haematoma), contrast-filled vessels 300 (CT angiography), diploe 300, cortical bone
//!   1200. The plain phantom's skull/scalp shell is 500 (a bone and fat mix).
//! - Noise: MR is Rician magnitude with sigma 20 on both channels (the plain phantom's model; a
//!   positive Rayleigh floor in the air). CT is additive, with sigma 4 HU (head CT soft-tissue
//!   noise is a few HU), Irwin-Hall approximately Gaussian, no floor: air stays near -1000 and
//!   values may be negative. CT has no multiplicative bias field (it is quantitative); MR keeps
//!   the plain phantom's +-7 % field.

use super::phantom::Tissue;

/// Number of tissue labels (the length of each contrast's table).
pub const TISSUE_COUNT: usize = Tissue::ALL.len();

/// The image contrast the phantom imitates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Contrast {
    /// T1-weighted MR (the default; the plain phantom's historical contrast).
    #[default]
    T1,
    /// T2-weighted MR (fast spin echo): CSF brightest, GM > WM.
    T2,
    /// Proton-density-weighted MR: CSF > GM > WM, low contrast.
    Pd,
    /// T2-FLAIR MR: CSF nulled, lesion and edema bright.
    Flair,
    /// CT in Hounsfield units (air -1000, bone > 1000).
    Ct,
}

/// Nominal values per label: Background, SkullFat, Csf, Gm, Wm, Lesion, Vessel, Edema, Skin,
/// Fat, Muscle, Bone, Marrow, Eye, Cord (module doc).
type Row = [f64; TISSUE_COUNT];

const T1: Row = [
    0.0, 80.0, 250.0, 600.0, 850.0, 1350.0, 1450.0, 720.0, 620.0, 1150.0, 560.0, 60.0, 1050.0,
    240.0, 850.0,
];
const T2: Row = [
    0.0, 80.0, 1500.0, 750.0, 600.0, 1200.0, 120.0, 1050.0, 600.0, 950.0, 320.0, 60.0, 850.0,
    1450.0, 600.0,
];
const PD: Row = [
    0.0, 80.0, 1100.0, 950.0, 820.0, 1050.0, 200.0, 1000.0, 800.0, 1000.0, 720.0, 60.0, 950.0,
    1100.0, 820.0,
];
const FLAIR: Row = [
    0.0, 80.0, 100.0, 800.0, 620.0, 1400.0, 150.0, 1150.0, 600.0, 900.0, 350.0, 60.0, 800.0, 100.0,
    620.0,
];
const CT: Row = [
    -1000.0, 500.0, 8.0, 40.0, 30.0, 70.0, 300.0, 18.0, 50.0, -100.0, 50.0, 1200.0, 300.0, 10.0,
    30.0,
];

/// MR noise: standard deviation of each Rician channel, raw units (2.4 % of T1 WM).
pub const MR_NOISE_SIGMA: f64 = 20.0;

/// CT noise: standard deviation of the additive noise, HU.
pub const CT_NOISE_SIGMA: f64 = 4.0;

impl Contrast {
    /// Every contrast, in the order of the command line's choices.
    pub const ALL: [Contrast; 5] = [
        Contrast::T1,
        Contrast::T2,
        Contrast::Pd,
        Contrast::Flair,
        Contrast::Ct,
    ];

    /// Nominal raw intensity of `tissue` in this contrast (module doc).
    pub fn nominal(self, tissue: Tissue) -> f64 {
        self.row()[tissue as usize]
    }

    fn row(self) -> &'static Row {
        match self {
            Contrast::T1 => &T1,
            Contrast::T2 => &T2,
            Contrast::Pd => &PD,
            Contrast::Flair => &FLAIR,
            Contrast::Ct => &CT,
        }
    }

    /// Whether this is an MR contrast (Rician noise and a bias field) rather than CT.
    pub fn is_mr(self) -> bool {
        self != Contrast::Ct
    }

    /// Standard deviation of the noise, raw units.
    pub fn noise_sigma(self) -> f64 {
        if self.is_mr() {
            MR_NOISE_SIGMA
        } else {
            CT_NOISE_SIGMA
        }
    }

    /// Short name (`t1`, `t2`, `pd`, `flair`, `ct`).
    pub fn name(self) -> &'static str {
        match self {
            Contrast::T1 => "t1",
            Contrast::T2 => "t2",
            Contrast::Pd => "pd",
            Contrast::Flair => "flair",
            Contrast::Ct => "ct",
        }
    }

    /// The BIDS suffix a file of this contrast would carry (`T1w`, `T2w`, `PDw`, `FLAIR`, `ct`).
    pub fn bids_suffix(self) -> &'static str {
        match self {
            Contrast::T1 => "T1w",
            Contrast::T2 => "T2w",
            Contrast::Pd => "PDw",
            Contrast::Flair => "FLAIR",
            Contrast::Ct => "ct",
        }
    }

    /// The stored value for noise-free `signal` and two standard-normal deviates: Rician
    /// magnitude for MR, additive for CT (module doc).
    pub(super) fn with_noise(self, signal: f64, n1: f64, n2: f64) -> f64 {
        let sigma = self.noise_sigma();
        if self.is_mr() {
            let re = signal + sigma * n1;
            let im = sigma * n2;
            (re * re + im * im).sqrt()
        } else {
            signal + sigma * n1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::phantom::NOMINAL;

    #[test]
    fn t1_row_keeps_the_plain_phantoms_values() {
        for t in &Tissue::ALL[..8] {
            assert_eq!(Contrast::T1.nominal(*t), NOMINAL.of(*t), "{}", t.name());
        }
    }

    #[test]
    fn each_contrast_keeps_its_promised_order() {
        use Tissue::*;
        let n = |c: Contrast, t: Tissue| c.nominal(t);
        let t1 = Contrast::T1;
        assert!(n(t1, Fat) > n(t1, Wm) && n(t1, Marrow) > n(t1, Wm));
        assert!(n(t1, Wm) > n(t1, Gm) && n(t1, Gm) > n(t1, Csf) && n(t1, Csf) > n(t1, Bone));
        assert!((n(t1, Muscle) - n(t1, Gm)).abs() < 0.1 * n(t1, Gm));
        let t2 = Contrast::T2;
        assert!(
            [Gm, Wm, Fat, Muscle, Bone, Lesion]
                .iter()
                .all(|&t| n(t2, Csf) > n(t2, t))
        );
        assert!(n(t2, Gm) > n(t2, Wm) && n(t2, Wm) > n(t2, Muscle) && n(t2, Fat) > n(t2, Gm));
        let pd = Contrast::Pd;
        assert!(n(pd, Csf) > n(pd, Gm) && n(pd, Gm) > n(pd, Wm));
        assert!(n(pd, Csf) - n(pd, Wm) < 0.3 * n(pd, Csf));
        let fl = Contrast::Flair;
        assert!(n(fl, Lesion) > n(fl, Edema) && n(fl, Edema) > n(fl, Gm));
        assert!(n(fl, Gm) > n(fl, Wm) && n(fl, Csf) < n(fl, Wm) / 3.0);
        let ct = Contrast::Ct;
        assert_eq!(n(ct, Background), -1000.0);
        assert!(n(ct, Fat) < n(ct, Csf) && n(ct, Csf) < n(ct, Wm) && n(ct, Wm) < n(ct, Gm));
        assert!(n(ct, Bone) > n(ct, Marrow) && n(ct, Marrow) > n(ct, Lesion));
        for c in Contrast::ALL {
            assert_eq!(n(c, Cord), n(c, Wm), "{}", c.name());
        }
    }

    #[test]
    fn ct_noise_is_additive_and_mr_noise_is_rician() {
        assert_eq!(Contrast::Ct.with_noise(-1000.0, 1.0, 3.0), -996.0);
        assert_eq!(Contrast::T2.with_noise(0.0, 0.75, 1.0), 25.0);
    }
}
