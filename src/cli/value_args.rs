//! The value types of global options that are not about the scene or the volume's identity
//! (`--normalize`, `--empty-skip`), apart from args.rs so that file stays one screenful of
//! clap structs per command.

use clap::ValueEnum;

/// `--normalize`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum NormalizeArg {
    /// Percentiles of the finite voxels; values outside clamped.
    Robust,
    /// The paper's min/max (eq. 1).
    Minmax,
}

impl From<NormalizeArg> for crate::analysis::NormalizeMode {
    fn from(arg: NormalizeArg) -> Self {
        match arg {
            NormalizeArg::Robust => crate::analysis::NormalizeMode::Robust,
            NormalizeArg::Minmax => crate::analysis::NormalizeMode::MinMax,
        }
    }
}

/// `--empty-skip`: how far one empty-space jump reaches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum EmptySkip {
    /// Across the cube of empty bricks the distance map finds.
    #[default]
    Distance,
    /// One brick at a time (the occupancy bits alone).
    Bricks,
}
