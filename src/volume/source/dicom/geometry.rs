//! DICOM patient geometry to the volume's affine.
//!
//! Decisions:
//! - DICOM positions are LPS (x to the patient's left, y to posterior, z to head); the volume's
//!   affine is RAS like NIfTI's sform, so the first two rows are negated.
//! - Voxel index i runs along a row (ImageOrientationPatient's first vector, spaced by
//!   PixelSpacing[1], the column spacing), j down the columns (second vector, PixelSpacing[0]),
//!   k from slice to slice. The pixel data is row-major, so i is also the fastest index of the
//!   samples, as the volume wants: no reordering.
//! - The slice step is a vector, not a length along the normal: with gantry tilt the slices are
//!   offset sideways, and a sheared affine keeps every voxel where it was scanned (no
//!   resampling).

/// 3-vector helpers.
pub type V3 = [f64; 3];

/// a . b
pub fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// a x b
pub fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// |a|
pub fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}

/// a - b
pub fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// a * s
pub fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// The row and column directions of ImageOrientationPatient, normalized, and their normal;
/// None when they are not two usable (non-zero, non-parallel) directions.
pub fn directions(iop: &[f64; 6]) -> Option<(V3, V3, V3)> {
    let row = [iop[0], iop[1], iop[2]];
    let col = [iop[3], iop[4], iop[5]];
    let (rn, cn) = (norm(row), norm(col));
    if !(rn > 1e-6 && cn > 1e-6) {
        return None;
    }
    let (row, col) = (scale(row, 1.0 / rn), scale(col, 1.0 / cn));
    let normal = cross(row, col);
    let nn = norm(normal);
    // Nearly parallel rows and columns make no plane.
    if nn < 0.5 {
        return None;
    }
    Some((row, col, scale(normal, 1.0 / nn)))
}

/// The RAS index-to-world affine: `origin` (LPS position of voxel (0,0,0)), the row and column
/// directions with their spacings (`pixel_spacing` as in DICOM: between rows, between columns),
/// and the LPS step from one slice to the next.
pub fn affine_ras(
    origin: V3,
    row: V3,
    col: V3,
    pixel_spacing: [f64; 2],
    step: V3,
) -> [[f64; 4]; 4] {
    let columns = [
        scale(row, pixel_spacing[1]),
        scale(col, pixel_spacing[0]),
        step,
        origin,
    ];
    let mut a = [[0.0; 4]; 4];
    for (c, v) in columns.iter().enumerate() {
        for r in 0..3 {
            // LPS -> RAS: x and y change sign.
            // (+ 0.0 turns a negated zero into 0, for tidy listings.)
            a[r][c] = if r < 2 { -v[r] + 0.0 } else { v[r] };
        }
    }
    a[3][3] = 1.0;
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_axial_stack_maps_to_ras_with_x_and_y_negated() {
        let (row, col, normal) = directions(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]).unwrap();
        assert_eq!(normal, [0.0, 0.0, 1.0]);
        let a = affine_ras([10.0, 20.0, 30.0], row, col, [0.5, 0.8], [0.0, 0.0, 2.0]);
        // i along the row (LPS +x = RAS -x) spaced by the column spacing 0.8.
        assert_eq!(a[0], [-0.8, 0.0, 0.0, -10.0]);
        assert_eq!(a[1], [0.0, -0.5, 0.0, -20.0]);
        assert_eq!(a[2], [0.0, 0.0, 2.0, 30.0]);
        assert_eq!(a[3], [0.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn parallel_or_zero_directions_are_refused() {
        assert!(directions(&[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]).is_none());
        assert!(directions(&[0.0; 6]).is_none());
    }
}
