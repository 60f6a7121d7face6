//! `--contrast` and `--modality`: what a scan is, as the user may state it (the analysis decides
//! from the metadata first when they say `auto`: `analysis::modality`). Split from `args.rs` by
//! concern.

use clap::ValueEnum;

/// `--contrast`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ContrastArg {
    /// From the metadata, then the histogram (T1 when nothing tells); `phantom`: T1.
    Auto,
    /// T1-weighted: CSF < GM < WM.
    T1,
    /// T2-weighted: WM < GM < CSF.
    T2,
    /// Proton density: WM < GM < CSF, less contrast than T2.
    Pd,
    /// FLAIR: CSF suppressed, WM < GM.
    Flair,
    /// CT in Hounsfield units (`phantom` only; a CT file is read by `--modality`).
    Ct,
}

impl ContrastArg {
    /// The analysis' choice; ct is refused (only `phantom` makes it; a CT file's modality is
    /// `--modality ct`).
    pub fn analysis(self) -> Result<crate::analysis::ContrastChoice, String> {
        use crate::analysis::ContrastChoice as C;
        match self {
            ContrastArg::Auto => Ok(C::Auto),
            ContrastArg::T1 => Ok(C::T1),
            ContrastArg::T2 => Ok(C::T2),
            ContrastArg::Pd => Ok(C::Pd),
            ContrastArg::Flair => Ok(C::Flair),
            ContrastArg::Ct => Err(
                "--contrast ct is only for `morphray phantom`; for a CT file use --modality ct"
                    .to_string(),
            ),
        }
    }

    /// The phantom's contrast (auto: T1).
    pub fn phantom(self) -> crate::volume::phantom_contrast::Contrast {
        use crate::volume::phantom_contrast::Contrast;
        match self {
            ContrastArg::Auto | ContrastArg::T1 => Contrast::T1,
            ContrastArg::T2 => Contrast::T2,
            ContrastArg::Pd => Contrast::Pd,
            ContrastArg::Flair => Contrast::Flair,
            ContrastArg::Ct => Contrast::Ct,
        }
    }
}

/// `--modality`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModalityArg {
    /// From the metadata, then the values (MR when nothing tells).
    Auto,
    /// Magnetic resonance.
    Mr,
    /// X-ray CT.
    Ct,
    /// PET.
    Pt,
    /// Anything else.
    Other,
}

impl From<ModalityArg> for crate::analysis::ModalityChoice {
    fn from(arg: ModalityArg) -> Self {
        use crate::analysis::{Modality as M, ModalityChoice as C};
        match arg {
            ModalityArg::Auto => C::Auto,
            ModalityArg::Mr => C::Given(M::Mr),
            ModalityArg::Ct => C::Given(M::Ct),
            ModalityArg::Pt => C::Given(M::Pt),
            ModalityArg::Other => C::Given(M::Other),
        }
    }
}
