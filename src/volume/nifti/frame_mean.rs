//! The mean over the frames of a 4-D file (issue 28: the `epi` preset shows "a foreground
//! window on the mean frame" of a BOLD / ASL series).
//!
//! Decisions:
//! - Streaming: one frame is converted at a time ([`convert::convert_frame`], the single-frame
//!   path, so scaling, byte order and datatypes are read exactly as for `--frame`) and added
//!   into one f64 sum per voxel; the memory beyond the file's bytes is that sum (8 bytes a
//!   voxel), one frame's copy and its conversion, whatever the number of frames.
//! - Sums are in physical units (each frame's own stored-to-physical map applied), in f64 so
//!   that hundreds of frames add without rounding; the mean is stored as f32 with the identity
//!   map (f32 holds a mean of any input datatype to its 24-bit precision).
//! - A voxel that is NaN or infinite in any frame is NaN in the mean (the engine counts it as
//!   non-finite), rather than a mean over fewer frames that would differ from its neighbours.
//! - Conversion warnings are said once (every frame has the same datatype and scaling).

use super::convert;
use super::datatype::Datatype;
use super::error::NiftiError;
use super::header::ByteOrder;
use crate::volume::{LinearMap, Samples};

/// Where the frames lie in the file's bytes and how they are encoded.
pub(crate) struct Frames<'a> {
    /// The file's (inflated) bytes.
    pub data: &'a [u8],
    /// Byte position of frame 0.
    pub offset: usize,
    /// Bytes of one frame.
    pub frame_bytes: usize,
    /// Number of frames.
    pub frames: usize,
    /// Datatype of the voxels.
    pub datatype: Datatype,
    /// Byte order of the voxels.
    pub order: ByteOrder,
    /// `scl_slope`, `scl_inter` as the single-frame path takes them.
    pub scaling: (f64, f64),
}

/// Where frame `frame` of `frames` starts in the data: `offset + frame * frame_bytes`, checked
/// so that no arithmetic on header values can overflow.
pub(crate) fn frame_start(
    frame: usize,
    frames: usize,
    frame_bytes: usize,
    offset: usize,
) -> Result<usize, NiftiError> {
    frame
        .checked_mul(frame_bytes)
        .and_then(|skip| skip.checked_add(offset))
        .ok_or(NiftiError::FrameOutOfRange { frame, frames })
}

/// The mean frame, its (identity) map and the first frame's conversion warnings.
pub(crate) fn mean_frame(f: &Frames) -> Result<(Samples, LinearMap, Vec<String>), NiftiError> {
    let mut sum: Vec<f64> = Vec::new();
    let mut warnings = Vec::new();
    for frame in 0..f.frames {
        let start = frame_start(frame, f.frames, f.frame_bytes, f.offset)?;
        let bytes = start
            .checked_add(f.frame_bytes)
            .and_then(|end| f.data.get(start..end))
            .ok_or(NiftiError::TruncatedData {
                file: "file",
                len: f.data.len(),
                needed: f.frame_bytes,
                offset: start,
            })?;
        let (slope, inter) = f.scaling;
        let converted = convert::convert_frame(
            bytes.to_vec(),
            0,
            f.frame_bytes,
            f.datatype,
            f.order,
            slope,
            inter,
        )?;
        if frame == 0 {
            sum = vec![0.0; converted.samples.len()];
            warnings = converted.warnings;
        }
        let map = converted.to_physical;
        for (s, i) in sum.iter_mut().zip(0..converted.samples.len()) {
            *s += map.apply(converted.samples.get(i));
        }
    }
    let n = f.frames.max(1) as f64;
    let mean: Vec<f32> = sum.iter().map(|s| (s / n) as f32).collect();
    Ok((Samples::from_f32(&mean), LinearMap::IDENTITY, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_is_taken_in_physical_units_over_every_frame() {
        // Three frames of 2x1x1 big-endian int16 behind 4 padding bytes, scaled by 0.5 + 10.
        let frames: [[i16; 2]; 3] = [[2, -7], [4, 100], [9, 3]];
        let mut data = vec![0xee; 4];
        for f in frames {
            for v in f {
                data.extend_from_slice(&v.to_be_bytes());
            }
        }
        let f = Frames {
            data: &data,
            offset: 4,
            frame_bytes: 4,
            frames: 3,
            datatype: Datatype::Int16,
            order: ByteOrder::BigEndian,
            scaling: (0.5, 10.0),
        };
        let (samples, map, _) = mean_frame(&f).unwrap();
        assert_eq!(map, LinearMap::IDENTITY);
        let want = [(2 + 4 + 9) as f64, (-7 + 100 + 3) as f64].map(|s| 0.5 * s / 3.0 + 10.0);
        for (i, w) in want.iter().enumerate() {
            assert!(
                (samples.get(i) - w).abs() < 1e-5,
                "{} vs {w}",
                samples.get(i)
            );
        }
        // Frames past the bytes are an error, not a panic.
        let short = Frames { frames: 4, ..f };
        assert!(mean_frame(&short).is_err());
    }
}
