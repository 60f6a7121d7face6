//! Intensity range of a volume in physical units, on the CPU.
//!
//! Decisions:
//! - Min and max are taken over stored values, decoded once per kind in a tight loop (no
//!   per-voxel match), then mapped through `to_physical`. The map is affine, so the physical
//!   extremes are the images of the stored extremes; a negative slope swaps them.
//! - Only finite voxels count (NUMERICS.md): NaN and +-Inf (possible only in f32 samples) are
//!   counted in `nonfinite` and excluded from the range. With no finite voxel the range is None.
//! - The Hounsfield-unit bands the modality rule needs ([`value_summary`]) come from a regular
//!   sample of at most a million voxels: fractions, not extremes, are what it reads.

use crate::volume::{SampleKind, Volume};

/// Physical intensity range and finite/non-finite voxel counts.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct IntensityStats {
    /// Smallest finite physical intensity; None when no voxel is finite.
    pub imin: Option<f64>,
    /// Largest finite physical intensity; None when no voxel is finite.
    pub imax: Option<f64>,
    /// Number of finite voxels.
    pub finite: usize,
    /// Number of NaN or infinite voxels.
    pub nonfinite: usize,
}

/// Min and max of decoded values, with no per-element branch on the kind.
fn extremes<T: Copy + PartialOrd + Into<f64>, const N: usize>(
    bytes: &[u8],
    decode: impl Fn([u8; N]) -> T,
) -> Option<(f64, f64)> {
    let mut iter = bytes.chunks_exact(N).map(|c| {
        let mut a = [0u8; N];
        a.copy_from_slice(c);
        decode(a)
    });
    let first = iter.next()?;
    let (lo, hi) = iter.fold((first, first), |(lo, hi), v| {
        (if v < lo { v } else { lo }, if v > hi { v } else { hi })
    });
    Some((lo.into(), hi.into()))
}

/// Most voxels [`value_summary`] looks at: a regular sample of a million voxels estimates the
/// fractions it needs (2 % and more) to well under 0.1 %, in a few ms on the host.
pub const VALUE_SUMMARY_SAMPLES: usize = 1 << 20;

/// The Hounsfield-unit bands of `volume`'s physical values (`analysis::ValueSummary`), over
/// every voxel or a regular sample of [`VALUE_SUMMARY_SAMPLES`] of them.
pub fn value_summary(volume: &Volume) -> crate::analysis::ValueSummary {
    let n = volume.samples.len();
    let stride = n.div_ceil(VALUE_SUMMARY_SAMPLES).max(1);
    let map = volume.to_physical;
    crate::analysis::ValueSummary::of(
        (0..n)
            .step_by(stride)
            .map(|i| map.apply(volume.samples.get(i))),
    )
}

/// Range and counts of `volume`'s physical intensities (see the module doc).
pub fn intensity_stats(volume: &Volume) -> IntensityStats {
    let bytes = volume.samples.as_bytes();
    let n = volume.samples.len();
    let (range, finite) = match volume.samples.kind() {
        SampleKind::U8 => (extremes(bytes, |[b]: [u8; 1]| b), n),
        SampleKind::I8 => (extremes(bytes, |[b]: [u8; 1]| b as i8), n),
        SampleKind::U16 => (extremes(bytes, u16::from_le_bytes), n),
        SampleKind::I16 => (extremes(bytes, i16::from_le_bytes), n),
        SampleKind::F32 => {
            let mut lo = f32::INFINITY;
            let mut hi = f32::NEG_INFINITY;
            let mut finite = 0usize;
            for c in bytes.chunks_exact(4) {
                let v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                if v.is_finite() {
                    finite += 1;
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            (
                (finite > 0).then_some((f64::from(lo), f64::from(hi))),
                finite,
            )
        }
    };
    let map = volume.to_physical;
    let (imin, imax) = match range {
        Some((lo, hi)) => {
            let (a, b) = (map.apply(lo), map.apply(hi));
            (Some(a.min(b)), Some(a.max(b)))
        }
        None => (None, None),
    };
    IntensityStats {
        imin,
        imax,
        finite,
        nonfinite: n - finite,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{AffineSource, LinearMap, Orientation, Samples};

    fn volume(samples: Samples, map: LinearMap) -> Volume {
        Volume {
            name: "t".into(),
            dims: [samples.len(), 1, 1],
            spacing_mm: [1.0; 3],
            orientation: Orientation::from_spacing([1.0; 3], AffineSource::Synthetic),
            samples,
            to_physical: map,
            warnings: Vec::new(),
            facts: Default::default(),
        }
    }

    #[test]
    fn every_kind_decodes_its_extremes() {
        let id = LinearMap::IDENTITY;
        let cases = [
            (Samples::from_u8(vec![7, 0, 255, 3]), 0.0, 255.0),
            (Samples::from_i8(&[-128, 5, 127]), -128.0, 127.0),
            (Samples::from_u16(&[300, 65535, 2]), 2.0, 65535.0),
            (
                Samples::from_i16(&[-32768, 0, 32767, -5]),
                -32768.0,
                32767.0,
            ),
            (
                Samples::from_f32(&[-0.0, 1e-45, -3.4e38, 2.5]),
                -3.4e38f32 as f64,
                2.5,
            ),
        ];
        for (samples, lo, hi) in cases {
            let n = samples.len();
            let s = intensity_stats(&volume(samples, id));
            assert_eq!(
                (s.imin, s.imax, s.finite, s.nonfinite),
                (Some(lo), Some(hi), n, 0)
            );
        }
    }

    #[test]
    fn negative_slope_swaps_the_extremes() {
        let s = intensity_stats(&volume(
            Samples::from_i16(&[-10, 0, 30]),
            LinearMap {
                slope: -2.0,
                intercept: 1.0,
            },
        ));
        assert_eq!((s.imin, s.imax), (Some(-59.0), Some(21.0)));
    }

    #[test]
    fn no_finite_voxel_gives_no_range() {
        let s = intensity_stats(&volume(
            Samples::from_f32(&[f32::NAN, f32::INFINITY]),
            LinearMap::IDENTITY,
        ));
        assert_eq!((s.imin, s.imax, s.finite, s.nonfinite), (None, None, 0, 2));
        let empty = intensity_stats(&volume(Samples::from_u8(Vec::new()), LinearMap::IDENTITY));
        assert_eq!((empty.imin, empty.finite, empty.nonfinite), (None, 0, 0));
    }
}
