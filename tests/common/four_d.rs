//! A 4-D NIfTI-1 file for the viewer's 4-D tests: each frame encoded by the library's writer
//! (`write_nifti1`, so its header, affine and scl_slope/scl_inter are the writer's), then the
//! first frame's header made 4-D (`dim[0]` 4, `dim[4]` the frame count) and the other frames'
//! voxels appended, as a scanner's file lays them out.

use morphray::volume::nifti::write_nifti1;
use morphray::volume::{LinearMap, Samples, Volume};
use std::path::Path;

/// Writes `frames` (int16 stored values, x fastest, each `dims` voxels) as one 4-D file at
/// `path` with the identity affine (voxel (i, j, k) at world (i, j, k) mm) and `map` as
/// scl_slope/scl_inter.
pub fn write_4d(path: &Path, dims: [usize; 3], frames: &[Vec<i16>], map: LinearMap) {
    let identity = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let encoded: Vec<Vec<u8>> = frames
        .iter()
        .enumerate()
        .map(|(t, values)| {
            let volume =
                Volume::from_voxels("frame", dims, Samples::from_i16(values), identity, map)
                    .unwrap();
            let one = path.with_extension(format!("frame{t}.nii"));
            write_nifti1(&volume, &one, false).unwrap();
            let bytes = std::fs::read(&one).unwrap();
            std::fs::remove_file(&one).unwrap();
            bytes
        })
        .collect();
    let mut file = encoded[0].clone();
    let offset = f32::from_le_bytes(file[108..112].try_into().unwrap()) as usize;
    file[40..42].copy_from_slice(&4i16.to_le_bytes()); // dim[0]: 4 dimensions
    file[48..50].copy_from_slice(&(frames.len() as i16).to_le_bytes()); // dim[4]: frames
    for frame in &encoded[1..] {
        file.extend_from_slice(&frame[offset..]);
    }
    std::fs::write(path, file).unwrap();
}
