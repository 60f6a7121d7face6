//! Every frame of a 4-D NIfTI file at once, for a viewer that plays them (`app::viewer::cine`):
//! one read and one inflation of the file instead of one per frame.
//!
//! Decisions:
//! - Single files (`.nii`, `.nii.gz`) only: a `.hdr`/`.img` pair is answered [`AllFrames::NotHeld`]
//!   and its frames are read one at a time as before (rare for 4-D data, and its companion
//!   search belongs to `load.rs`).
//! - Each frame is converted by the single-frame path ([`convert::convert_frame`]), so scaling,
//!   byte order and datatypes are exactly those of `--frame N`; each frame keeps its own
//!   stored-to-physical map (the wide integer and float64 kinds pack every frame with its own
//!   offset and scale).
//! - A memory cap given by the caller: frame 0 is converted first, and when frames x its
//!   converted size exceeds the cap nothing more is converted ([`AllFrames::TooLarge`]); the
//!   file's bytes are dropped before the answer either way.
//! - Header errors are the reader's own (the same validation as a normal read).

use super::convert;
use super::error::NiftiError;
use super::header::{self, Storage, Version};
use super::layout;
use super::{bounded, frame_mean, read_file};
use crate::volume::{LinearMap, Samples};
use std::path::Path;

/// What [`load_all_frames`] found.
pub enum AllFrames {
    /// Every frame's stored samples and stored-to-physical map, in order.
    Held(Vec<(Samples, LinearMap)>),
    /// Converting every frame would take `bytes` (over the cap).
    TooLarge {
        /// Bytes all frames would take.
        bytes: u64,
    },
    /// Not a single NIfTI file (a pair, or ANALYZE): the frames are read one at a time.
    NotHeld,
}

/// Every frame of the single-file NIfTI at `path` when they take at most `cap` bytes.
pub fn load_all_frames(path: &Path, cap: u64) -> Result<AllFrames, NiftiError> {
    let (bytes, _) = bounded::inflate_if_gzip(read_file(path)?)?;
    let decoded = header::decode(&bytes)?;
    if decoded.storage != Storage::SingleFile || decoded.version == Version::Analyze75 {
        return Ok(AllFrames::NotHeld);
    }
    let (datatype, bytes_per_voxel) = layout::datatype_of(&decoded)?;
    let lay = layout::plan(&decoded, datatype, bytes_per_voxel, false, &mut Vec::new())?;
    let (slope, inter) = (decoded.header.scl_slope, decoded.header.scl_inter);
    let order = decoded.byte_order;
    let mut held = Vec::new();
    for frame in 0..lay.frames {
        let start = frame_mean::frame_start(frame, lay.frames, lay.frame_bytes, lay.offset)?;
        let slice = start
            .checked_add(lay.frame_bytes)
            .and_then(|end| bytes.get(start..end))
            .ok_or(NiftiError::TruncatedData {
                file: "file",
                len: bytes.len(),
                needed: lay.frame_bytes,
                offset: start,
            })?;
        let converted = convert::convert_frame(
            slice.to_vec(),
            0,
            lay.frame_bytes,
            datatype,
            order,
            slope,
            inter,
        )?;
        if frame == 0 {
            let need =
                (converted.samples.as_bytes().len() as u64).saturating_mul(lay.frames as u64);
            if need > cap {
                return Ok(AllFrames::TooLarge { bytes: need });
            }
        }
        held.push((converted.samples, converted.to_physical));
    }
    Ok(AllFrames::Held(held))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Volume;

    /// A 2x2x1 int16 file of `frames` frames (scl_slope 2, scl_inter 1): frame t holds t, t+1,
    /// t+2, t+3. Written by the library's writer, made 4-D by patching dim[0] and dim[4].
    fn write(path: &Path, frames: i16) {
        let one = |t: i16| {
            let v = Volume::from_voxels(
                "f",
                [2, 2, 1],
                Samples::from_i16(&[t, t + 1, t + 2, t + 3]),
                [
                    [1.0, 0.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0, 0.0],
                    [0.0, 0.0, 1.0, 0.0],
                    [0.0, 0.0, 0.0, 1.0],
                ],
                LinearMap {
                    slope: 2.0,
                    intercept: 1.0,
                },
            )
            .unwrap();
            let one = path.with_extension(format!("{t}.nii"));
            super::super::write_nifti1(&v, &one, false).unwrap();
            std::fs::read(&one).unwrap()
        };
        let mut file = one(0);
        let offset = f32::from_le_bytes(file[108..112].try_into().unwrap()) as usize;
        file[40..42].copy_from_slice(&4i16.to_le_bytes());
        file[48..50].copy_from_slice(&frames.to_le_bytes());
        for t in 1..frames {
            file.extend_from_slice(&one(t)[offset..]);
        }
        std::fs::write(path, file).unwrap();
    }

    #[test]
    fn every_frame_is_held_with_its_map_or_none_over_the_cap() {
        let dir = std::env::temp_dir().join(format!("morphray-frames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("four.nii");
        write(&path, 3);
        let AllFrames::Held(frames) = load_all_frames(&path, 1 << 20).unwrap() else {
            panic!("not held");
        };
        assert_eq!(frames.len(), 3);
        for (t, (samples, map)) in frames.iter().enumerate() {
            let physical: Vec<f64> = (0..4).map(|i| map.apply(samples.get(i))).collect();
            let want: Vec<f64> = (0..4).map(|i| 2.0 * (t + i) as f64 + 1.0).collect();
            assert_eq!(physical, want, "frame {t}");
        }
        // 3 frames of 8 bytes: 24 bytes, over a 23-byte cap.
        assert!(matches!(
            load_all_frames(&path, 23).unwrap(),
            AllFrames::TooLarge { bytes: 24 }
        ));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
