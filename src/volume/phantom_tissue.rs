//! The phantom's tissue classes ([`Tissue`], the label values) and the plain phantom's nominal
//! T1 intensities ([`NOMINAL`]), re-exported from `volume::phantom` (moved out of phantom.rs to
//! keep it short; every contrast's values are in phantom_contrast.rs).
//!
//! Decisions: label values are stable; new classes are appended (8.. for the head's layers), so
//! label maps written before the head still read the same.

use super::phantom_contrast::Contrast;

/// Tissue classes of the phantom (the values of [`super::phantom::Phantom::labels`]).
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Tissue {
    /// Air outside the head.
    Background = 0,
    /// Skull and scalp shell (dark).
    SkullFat = 1,
    /// Cerebrospinal fluid: ventricles, sulci, fissure, subarachnoid layer.
    Csf = 2,
    /// Cortical grey matter.
    Gm = 3,
    /// White matter.
    Wm = 4,
    /// A bright lesion in the left hemisphere's white matter.
    Lesion = 5,
    /// Bright vessels (contrast-enhanced).
    Vessel = 6,
    /// Perilesional edema: a low-contrast shell around the lesion (src/volume/phantom_edema.rs).
    Edema = 7,
    /// Skin of the head phantom (src/volume/phantom_head.rs; so are the labels below).
    Skin = 8,
    /// Subcutaneous and orbital fat.
    Fat = 9,
    /// Muscle: temporalis-like on the sides and back of the head, the neck, the face.
    Muscle = 10,
    /// Cortical bone: the skull's outer and inner tables, the vertebrae.
    Bone = 11,
    /// Fatty marrow of the skull's diploe.
    Marrow = 12,
    /// Vitreous of the eye globes.
    Eye = 13,
    /// Spinal cord below the foramen magnum (the brainstem above it is labelled WM).
    Cord = 14,
}

impl Tissue {
    /// Every class, in label order.
    pub const ALL: [Tissue; 15] = [
        Tissue::Background,
        Tissue::SkullFat,
        Tissue::Csf,
        Tissue::Gm,
        Tissue::Wm,
        Tissue::Lesion,
        Tissue::Vessel,
        Tissue::Edema,
        Tissue::Skin,
        Tissue::Fat,
        Tissue::Muscle,
        Tissue::Bone,
        Tissue::Marrow,
        Tissue::Eye,
        Tissue::Cord,
    ];

    /// The class with label value `label`.
    pub fn from_label(label: u8) -> Option<Tissue> {
        Tissue::ALL.get(usize::from(label)).copied()
    }

    /// Lowercase name.
    pub fn name(self) -> &'static str {
        match self {
            Tissue::Background => "background",
            Tissue::SkullFat => "skull_fat",
            Tissue::Csf => "csf",
            Tissue::Gm => "gm",
            Tissue::Wm => "wm",
            Tissue::Lesion => "lesion",
            Tissue::Vessel => "vessel",
            Tissue::Edema => "edema",
            Tissue::Skin => "skin",
            Tissue::Fat => "fat",
            Tissue::Muscle => "muscle",
            Tissue::Bone => "bone",
            Tissue::Marrow => "marrow",
            Tissue::Eye => "eye",
            Tissue::Cord => "cord",
        }
    }
}

/// Nominal raw (int16) intensity of the plain phantom's tissues in T1, before bias, partial
/// volume and noise (every contrast and tissue: [`Contrast::nominal`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Nominal {
    /// Air.
    pub background: f64,
    /// Skull and scalp shell.
    pub skull_fat: f64,
    /// Cerebrospinal fluid.
    pub csf: f64,
    /// Grey matter.
    pub gm: f64,
    /// White matter.
    pub wm: f64,
    /// Lesion.
    pub lesion: f64,
    /// Vessels.
    pub vessel: f64,
}

impl Nominal {
    /// Nominal intensity of `tissue`.
    pub fn of(&self, tissue: Tissue) -> f64 {
        match tissue {
            Tissue::Background => self.background,
            Tissue::SkullFat => self.skull_fat,
            Tissue::Csf => self.csf,
            Tissue::Gm => self.gm,
            Tissue::Wm => self.wm,
            Tissue::Lesion => self.lesion,
            Tissue::Vessel => self.vessel,
            Tissue::Edema => super::phantom_edema::EDEMA_NOMINAL,
            other => Contrast::T1.nominal(other),
        }
    }
}

impl Nominal {
    /// The plain phantom's tissues in `contrast`.
    pub fn of_contrast(contrast: Contrast) -> Nominal {
        let n = |t| contrast.nominal(t);
        Nominal {
            background: n(Tissue::Background),
            skull_fat: n(Tissue::SkullFat),
            csf: n(Tissue::Csf),
            gm: n(Tissue::Gm),
            wm: n(Tissue::Wm),
            lesion: n(Tissue::Lesion),
            vessel: n(Tissue::Vessel),
        }
    }
}

/// The plain phantom's nominal T1 intensities (phantom.rs module doc).
pub const NOMINAL: Nominal = Nominal {
    background: 0.0,
    skull_fat: 80.0,
    csf: 250.0,
    gm: 600.0,
    wm: 850.0,
    lesion: 1350.0,
    vessel: 1450.0,
};
