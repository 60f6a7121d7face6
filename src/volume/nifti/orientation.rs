//! Index-to-world geometry from header fields: a total function (any bit pattern in, a finite,
//! invertible affine out, never a panic).
//!
//! Decisions (the loader contract's point 7, `tests/nifti_loader.rs`):
//! - Voxel size: `pixdim[1..=3]`, converted to mm by `xyzt_units` (metres x1000, microns
//!   x0.001; "unknown" (0) is taken as mm silently because most files leave it 0; codes 4..7
//!   are not spatial units: mm, with a warning). A value that is non-finite or <= 0 is repaired
//!   to 1 mm with a warning (the contract's rule: a negative pixdim is not read as a flip), and
//!   so is one outside [1e-30, 1e30] mm (found by fuzzing: NIfTI-2's f64 fields can hold sizes
//!   whose product underflows or overflows, leaving no invertible affine).
//!   The same factor scales the whole affine, so world coordinates are always mm.
//! - Priority: sform if `sform_code > 0`, else qform if `qform_code > 0`, else the pixdim
//!   diagonal (NIfTI "method 1", also used for ANALYZE: no flip, origin at voxel 0, which is what
//!   the NIfTI standard says and avoids guessing ANALYZE's radiological convention).
//! - A method whose fields are non-finite, or whose 3x3 part is singular (columns nearly
//!   coplanar, |det| <= 1e-9 * product of column lengths, or a column length outside
//!   [1e-30, 1e30] mm, where the inverse would leave f64's range), is skipped with a warning and
//!   the next method is used: the renderer needs an invertible affine.
//! - Quaternion: with s = b^2 + c^2 + d^2, a = sqrt(1 - s) when s < 1 - 1e-7; when s is within
//!   (1 - 1e-7, 1 + 1e-5] (rounding of a unit quaternion stored in f32) a = 0 and (b, c, d) is
//!   normalised silently (as nifti_clib does); when s > 1 + 1e-5 the quaternion is normalised
//!   with a warning. qfac = `pixdim[0]`: 0 means 1 (the standard), otherwise its sign; NaN is 1
//!   with a warning.
//! - When both sform and qform are usable and differ by more than 1e-3 of the voxel size in the
//!   3x3 part or 0.01 mm (+1e-6 relative) in the offset, a warning says so; the sform wins.
//! - When the sform is used and its column lengths differ from pixdim by more than 1 %, a
//!   warning says so (spacing comes from pixdim, placement from the sform).
//! - All arithmetic is f64 on f32-or-f64 inputs; oblique affines are kept in full.

use crate::volume::{AffineSource, Orientation};

/// The header fields that decide orientation, exactly as read (f64 holds every f32 exactly).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrientationFields {
    /// `qform_code`.
    pub qform_code: i32,
    /// `sform_code`.
    pub sform_code: i32,
    /// `quatern_b`, `quatern_c`, `quatern_d`.
    pub quatern: [f64; 3],
    /// `qoffset_x`, `qoffset_y`, `qoffset_z`.
    pub qoffset: [f64; 3],
    /// `pixdim[0..=3]`: qfac, then the voxel size along i, j, k.
    pub pixdim: [f64; 4],
    /// `srow_x`, `srow_y`, `srow_z`.
    pub srow: [[f64; 4]; 3],
    /// `xyzt_units` (only the spatial bits 0..3 are used).
    pub xyzt_units: i32,
}

/// Geometry resolved from header fields.
#[derive(Clone, Debug, PartialEq)]
pub struct ResolvedGeometry {
    /// The affine (mm, voxel centres at integer indices) and which method produced it.
    pub orientation: Orientation,
    /// Voxel size in mm along i, j, k (finite and > 0).
    pub spacing_mm: [f64; 3],
    /// Repairs made and disagreements found, one sentence each.
    pub warnings: Vec<String>,
}

const AXES: [&str; 3] = ["i", "j", "k"];

/// Converts the spatial unit code to a factor to mm.
fn unit_factor(xyzt_units: i32, warnings: &mut Vec<String>) -> f64 {
    match xyzt_units & 0x07 {
        1 => 1000.0,
        2 | 0 => 1.0,
        3 => 0.001,
        code => {
            warnings.push(format!(
                "xyzt_units has spatial code {code}, which is not a length unit; millimetres are assumed"
            ));
            1.0
        }
    }
}

/// Smallest and largest voxel size (mm) taken from pixdim. Found by fuzzing: NIfTI-2's f64
/// pixdim can hold 1e-309 or 1e300, which are "positive and finite" but make the pixdim
/// diagonal (or the qform) numerically singular: the determinant, a product of three sizes,
/// underflows to 0 or overflows to infinity, and no inverse exists in f64. Within
/// [1e-30, 1e30] the determinant and the inverse stay far inside f64's normal range; no imaging
/// modality comes within 20 orders of magnitude of either bound.
const MIN_SPACING_MM: f64 = 1e-30;
const MAX_SPACING_MM: f64 = 1e30;

fn repaired_spacing(pixdim: [f64; 3], factor: f64, warnings: &mut Vec<String>) -> [f64; 3] {
    std::array::from_fn(|axis| {
        let p = pixdim[axis];
        let mm = p * factor;
        if p.is_finite() && p > 0.0 && (MIN_SPACING_MM..=MAX_SPACING_MM).contains(&mm) {
            mm
        } else if p.is_finite() && p > 0.0 {
            warnings.push(format!(
                "pixdim[{}] (voxel size along {}) is {p:e} ({mm:e} mm), outside the usable range {MIN_SPACING_MM:e}..{MAX_SPACING_MM:e} mm; 1 mm is used",
                axis + 1,
                AXES[axis]
            ));
            1.0
        } else {
            warnings.push(format!(
                "pixdim[{}] (voxel size along {}) is {p}, which is not a positive finite size; 1 mm is used",
                axis + 1,
                AXES[axis]
            ));
            1.0
        }
    })
}

fn all_finite<const N: usize>(values: &[f64; N]) -> bool {
    values.iter().all(|v| v.is_finite())
}

fn column_norms(m: &[[f64; 4]; 4]) -> [f64; 3] {
    std::array::from_fn(|c| (m[0][c] * m[0][c] + m[1][c] * m[1][c] + m[2][c] * m[2][c]).sqrt())
}

fn det3(m: &[[f64; 4]; 4]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// True when the 3x3 part is finite and clearly invertible, with every column (the voxel size
/// along that index axis) in the usable range: without that bound, found by fuzzing, a sform
/// with subnormal entries passed the relative determinant test yet had an inverse beyond f64
/// (1/det overflowed). With columns in [1e-30, 1e30] and |det| > 1e-9 of their product, det is
/// at least 1e-99 and every inverse entry is finite.
fn invertible(m: &[[f64; 4]; 4]) -> bool {
    let n = column_norms(m);
    let scale = n[0] * n[1] * n[2];
    let det = det3(m);
    m.iter().all(all_finite)
        && n.iter()
            .all(|len| (MIN_SPACING_MM..=MAX_SPACING_MM).contains(len))
        && scale.is_finite()
        && det.is_finite()
        && det.abs() > 1e-9 * scale
}

/// Rotation matrix of the quaternion (b, c, d), repaired as the module doc describes.
/// `None` when a component is non-finite.
pub fn quaternion_rotation(quatern: [f64; 3], warnings: &mut Vec<String>) -> Option<[[f64; 3]; 3]> {
    let [mut b, mut c, mut d] = quatern;
    if !all_finite(&quatern) {
        return None;
    }
    let s = b * b + c * c + d * d;
    if !s.is_finite() {
        return None;
    }
    let a = if s < 1.0 - 1e-7 {
        (1.0 - s).sqrt()
    } else {
        if s > 1.0 + 1e-5 {
            warnings.push(format!(
                "the qform quaternion (b, c, d) = ({b}, {c}, {d}) has b^2 + c^2 + d^2 = {s} > 1; it was normalised (a = 0)"
            ));
        }
        let norm = s.sqrt();
        b /= norm;
        c /= norm;
        d /= norm;
        0.0
    };
    Some([
        [
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
        ],
        [
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
        ],
        [
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        ],
    ])
}

/// qfac from pixdim[0].
fn qfac(pixdim0: f64, warnings: &mut Vec<String>) -> f64 {
    if pixdim0.is_nan() {
        warnings.push("pixdim[0] (qfac) is NaN; 1 is used".to_string());
        1.0
    } else if pixdim0 < 0.0 {
        -1.0
    } else {
        1.0
    }
}

fn qform_affine(
    f: &OrientationFields,
    spacing: [f64; 3],
    factor: f64,
    warnings: &mut Vec<String>,
) -> Option<[[f64; 4]; 4]> {
    if !all_finite(&f.qoffset) {
        warnings.push(format!(
            "the qform offsets ({}, {}, {}) are not all finite, so the qform is not used",
            f.qoffset[0], f.qoffset[1], f.qoffset[2]
        ));
        return None;
    }
    let Some(r) = quaternion_rotation(f.quatern, warnings) else {
        warnings.push(format!(
            "the qform quaternion ({}, {}, {}) is not finite, so the qform is not used",
            f.quatern[0], f.quatern[1], f.quatern[2]
        ));
        return None;
    };
    let q = qfac(f.pixdim[0], warnings);
    let scale = [spacing[0], spacing[1], spacing[2] * q];
    let mut m = [[0.0; 4]; 4];
    for (row, r_row) in r.iter().enumerate() {
        for col in 0..3 {
            m[row][col] = r_row[col] * scale[col];
        }
        m[row][3] = f.qoffset[row] * factor;
    }
    m[3][3] = 1.0;
    if invertible(&m) && m.iter().all(all_finite) {
        Some(m)
    } else {
        warnings.push(
            "the qform does not give a finite invertible affine, so it is not used".to_string(),
        );
        None
    }
}

fn sform_affine(
    f: &OrientationFields,
    factor: f64,
    warnings: &mut Vec<String>,
) -> Option<[[f64; 4]; 4]> {
    if !f.srow.iter().all(all_finite) {
        warnings
            .push("the sform (srow_x/y/z) has non-finite entries, so it is not used".to_string());
        return None;
    }
    let mut m = [[0.0; 4]; 4];
    for (row, values) in f.srow.iter().enumerate() {
        for (col, &v) in values.iter().enumerate() {
            m[row][col] = v * factor;
        }
    }
    m[3][3] = 1.0;
    if invertible(&m) {
        Some(m)
    } else {
        warnings.push("the sform's 3x3 part is singular (or not finite after unit conversion, or a column is outside 1e-30..1e30 mm), so it is not used".to_string());
        None
    }
}

/// Largest differences between two affines: (3x3 part, offsets).
fn differences(a: &[[f64; 4]; 4], b: &[[f64; 4]; 4]) -> (f64, f64) {
    let mut lin = 0.0f64;
    let mut off = 0.0f64;
    for row in 0..3 {
        for col in 0..3 {
            lin = lin.max((a[row][col] - b[row][col]).abs());
        }
        off = off.max((a[row][3] - b[row][3]).abs());
    }
    (lin, off)
}

/// Resolves the affine, its source and the voxel spacing from raw header fields. Total: every
/// input gives a finite affine with an invertible 3x3 part and a finite positive spacing.
pub fn resolve(f: &OrientationFields) -> ResolvedGeometry {
    let mut warnings = Vec::new();
    let factor = unit_factor(f.xyzt_units, &mut warnings);
    let spacing = repaired_spacing(
        [f.pixdim[1], f.pixdim[2], f.pixdim[3]],
        factor,
        &mut warnings,
    );

    let sform = if f.sform_code > 0 {
        sform_affine(f, factor, &mut warnings)
    } else {
        None
    };
    let qform = if f.qform_code > 0 {
        qform_affine(f, spacing, factor, &mut warnings)
    } else {
        None
    };

    let (affine, source) = match (sform, qform) {
        (Some(s), q) => {
            if let Some(q) = q {
                let (lin, off) = differences(&s, &q);
                let voxel = spacing.iter().fold(0.0f64, |m, &v| m.max(v));
                let off_tol = 0.01 + 1e-6 * s.iter().take(3).fold(0.0f64, |m, r| m.max(r[3].abs()));
                if lin > 1e-3 * voxel || off > off_tol {
                    warnings.push(format!(
                        "the qform and sform disagree (largest difference {lin:.4} in the 3x3 part, {off:.4} mm in the offset); the sform is used"
                    ));
                }
            }
            let norms = column_norms(&s);
            let differs = norms
                .iter()
                .zip(spacing.iter())
                .any(|(n, p)| (n - p).abs() > 0.01 * p);
            if differs {
                warnings.push(format!(
                    "the sform's voxel size ({:.4}, {:.4}, {:.4}) mm differs from pixdim ({:.4}, {:.4}, {:.4}) mm; pixdim is used as the spacing",
                    norms[0], norms[1], norms[2], spacing[0], spacing[1], spacing[2]
                ));
            }
            (s, AffineSource::Sform)
        }
        (None, Some(q)) => (q, AffineSource::Qform),
        (None, None) => (
            Orientation::from_spacing(spacing, AffineSource::Pixdim).affine,
            AffineSource::Pixdim,
        ),
    };
    ResolvedGeometry {
        orientation: Orientation { affine, source },
        spacing_mm: spacing,
        warnings,
    }
}
