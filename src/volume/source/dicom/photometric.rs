//! MONOCHROME1 pixels (the lowest value is displayed white) turned into MONOCHROME2 ones, so
//! that a bright voxel means a strong signal in every command, as it does for NIfTI.
//!
//! Decisions:
//! - The inversion is `min + max - v` over the whole stack's samples (their own range, not
//!   the 2^BitsStored range): the samples keep their kind and range, integers are inverted
//!   exactly (the result lies in `[min, max]`), and since the stored-to-physical map is
//!   linear the physical values are inverted within their range too. dcm2niix leaves
//!   MONOCHROME1 values as stored (NIfTI has no photometric interpretation); a viewer that
//!   did so would show such a scan as a negative, so morphray inverts and says so.
//! - The stack's interpretation is its first file's; a stack that mixes MONOCHROME1 and
//!   MONOCHROME2 files is inverted as a whole, with a warning naming the mixture.

use super::headers::Scan;
use super::series::Layout;
use crate::volume::{SampleKind, Samples};

/// The samples as MONOCHROME2, and a sentence when they were inverted.
pub fn to_monochrome2(samples: Samples, layout: &Layout, scan: &Scan) -> (Samples, Option<String>) {
    let Some(first) = layout.order.first() else {
        return (samples, None);
    };
    if scan.images[first.file].photometric != "MONOCHROME1" || samples.is_empty() {
        return (samples, None);
    }
    let mixed = layout
        .order
        .iter()
        .any(|s| scan.images[s.file].photometric != "MONOCHROME1");
    let (low, high) = range(&samples);
    let inverted = invert(&samples, low + high);
    let mut note = format!(
        "PhotometricInterpretation MONOCHROME1 (low values shown white): intensities were \
         inverted within their range ({low} + {high} - v), so bright means high signal"
    );
    if mixed {
        note.push_str("; the stack also holds MONOCHROME2 files, inverted with it");
    }
    (inverted, Some(note))
}

/// The smallest and largest finite sample.
fn range(samples: &Samples) -> (f64, f64) {
    (0..samples.len())
        .map(|i| samples.get(i))
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        })
}

/// `sum - v` for every sample, in the samples' own kind (exact for integers: the result stays
/// within the samples' range).
fn invert(samples: &Samples, sum: f64) -> Samples {
    if !sum.is_finite() {
        return samples.clone();
    }
    let flipped = |i: usize| sum - samples.get(i);
    let n = samples.len();
    match samples.kind() {
        SampleKind::U8 => Samples::from_u8((0..n).map(|i| flipped(i) as u8).collect()),
        SampleKind::I8 => Samples::from_i8(&(0..n).map(|i| flipped(i) as i8).collect::<Vec<i8>>()),
        SampleKind::U16 => {
            Samples::from_u16(&(0..n).map(|i| flipped(i) as u16).collect::<Vec<u16>>())
        }
        SampleKind::I16 => {
            Samples::from_i16(&(0..n).map(|i| flipped(i) as i16).collect::<Vec<i16>>())
        }
        SampleKind::F32 => {
            Samples::from_f32(&(0..n).map(|i| flipped(i) as f32).collect::<Vec<f32>>())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_are_inverted_exactly_within_their_own_range() {
        let s = Samples::from_u16(&[100, 250, 4000]);
        let (lo, hi) = range(&s);
        assert_eq!((lo, hi), (100.0, 4000.0));
        assert_eq!(
            invert(&s, lo + hi).to_f64_vec(),
            vec![4000.0, 3850.0, 100.0]
        );
        let s = Samples::from_i16(&[-32768, 0, 32767]);
        let (lo, hi) = range(&s);
        assert_eq!(
            invert(&s, lo + hi).to_f64_vec(),
            vec![32767.0, -1.0, -32768.0]
        );
    }

    #[test]
    fn non_finite_floats_do_not_poison_the_range() {
        let s = Samples::from_f32(&[1.0, f32::NAN, 3.0]);
        assert_eq!(range(&s), (1.0, 3.0));
        let v = invert(&s, 4.0).to_f64_vec();
        assert_eq!((v[0], v[2]), (3.0, 1.0));
        assert!(v[1].is_nan());
    }
}
