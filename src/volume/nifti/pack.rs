//! Packing int32, uint32, int64, uint64 and float64 voxels into f32 (the engine's one wide
//! sample kind) with an offset and a scale chosen so that what is lost is small and said.
//!
//! Decisions (issue 30, "nothing silently wrong"):
//! - Integers: `stored = x - offset`, exact in f32 while the finite range lies within +-2^24
//!   (no offset). A wider range (an int32 volume with one voxel at -2^31, data at 1e9) gets the
//!   offset that keeps the most voxels exact, judged on a sample of [`OFFSET_SAMPLE`] voxels:
//!   candidates around zero, the median and the midpoint, each also nudged (by less than an
//!   f32 ulp) so that the minimum or the maximum is exact; an inexact extreme weighs as 10 % of
//!   the sample, so the extremes stay exact unless that would round many more voxels, so `info`'s minimum and maximum are values of the data whenever f32 can
//!   hold them with the bulk. Values a span wider than 2^24 still rounds are counted, and a
//!   warning gives the largest rounding error.
//! - float64: a handful of voxels beyond +-[`F32_REACH`] (the 1e300 voxel) would force a scale
//!   that underflows every ordinary voxel to 0: the image goes blank and `convert` writes a
//!   volume of zeros. When at most [`CLAMP_FRACTION`] of the finite voxels lie beyond that
//!   reach, they are clamped to +-`F32_REACH` with a warning naming how many and how far (the
//!   robust intensity range then treats them as the hot voxels they are). When more do, the
//!   whole volume is huge and is scaled by a power of two (exact) instead; data sitting far
//!   from zero relative to its spread (1e30 + tiny) gets its midpoint as the offset.
//! - Distinctions float32 loses (neighbouring voxels with different float64 values stored
//!   equal) are counted and said with the largest value concerned; clamped voxels are counted
//!   by the clamping warning instead.

/// Largest magnitude stored in f32 without a scale (f32::MAX is 3.4e38; the margin keeps
/// products in the engine's statistics finite).
pub const F32_REACH: f64 = 1e36;

/// Most voxels (as a fraction of the finite ones) that are clamped to [`F32_REACH`] rather than
/// scaling the whole volume: the robust range's hot-voxel share (0.5 %).
pub const CLAMP_FRACTION: f64 = 0.005;

/// A packed frame: f32 bytes, `physical = stored * scale + offset`, the largest |stored|.
pub struct Packed {
    /// Little-endian f32 samples.
    pub bytes: Vec<u8>,
    /// Added after scaling.
    pub offset: f64,
    /// Multiplies stored values.
    pub scale: f64,
    /// Largest finite |stored|.
    pub reach: f64,
}

/// Iterates fixed-size chunks of `src` as arrays.
pub fn arrays<const N: usize>(src: &[u8]) -> impl Iterator<Item = [u8; N]> + '_ {
    src.chunks_exact(N).map(|c| {
        let mut a = [0u8; N];
        a.copy_from_slice(c);
        a
    })
}

/// Voxels (spread evenly over the frame) on which candidate integer offsets are scored.
const OFFSET_SAMPLE: usize = 1 << 16;

/// `o` near `base` for which `x - o` is exact in f32.
fn exact_for(x: i128, base: i128) -> i128 {
    x - ((x - base) as f32) as i128
}

/// Whether `x - offset` is exact in f32.
fn exact(x: i128, offset: i128) -> bool {
    ((x - offset) as f32) as i128 == x - offset
}

/// The offset for integers spanning `lo..=hi` (`lo <= hi`), given `sample`, voxels spread over
/// the frame (module doc): no offset within +-2^24; else, of candidates around zero, the
/// sample's median and the range's midpoint (each also nudged so that the minimum or the
/// maximum is exact), the one that rounds the fewest sampled voxels, an inexact extreme
/// counting as 10 % of them.
pub fn integer_offset(lo: i128, hi: i128, sample: &mut [i128]) -> i128 {
    const EXACT: i128 = 1 << 24;
    if lo >= -EXACT && hi <= EXACT {
        return 0;
    }
    let median = if sample.is_empty() {
        lo + (hi - lo) / 2
    } else {
        let middle = sample.len() / 2;
        *sample.select_nth_unstable(middle).1
    };
    let mut candidates = Vec::new();
    for base in [0, median, lo + (hi - lo) / 2] {
        candidates.extend([base, exact_for(lo, base), exact_for(hi, base)]);
    }
    // `hi - lo - a` keeps 24 significant bits and `a` has fewer than 24 (spans under 2^48).
    let bits = 128 - (hi - lo).leading_zeros();
    if bits <= 48 {
        let low = bits.saturating_sub(24);
        candidates.push(lo + ((hi - lo) & ((1i128 << low) - 1)));
    }
    // An inexact extreme counts as 10 % of the sample: where nearly every voxel is rounded
    // whatever the offset, a few more or fewer must not cost `info` its true minimum.
    let score = |o: i128| {
        let rounded = sample.iter().filter(|&&x| !exact(x, o)).count();
        let extremes = usize::from(!exact(lo, o)) + usize::from(!exact(hi, o));
        rounded + extremes * (sample.len() / 10).max(1)
    };
    candidates
        .into_iter()
        .min_by_key(|&o| score(o))
        .unwrap_or(0)
}

/// Integers to f32 (module doc); `name` is the datatype's name for the warning.
pub fn integers<const N: usize>(
    src: &[u8],
    read: impl Fn([u8; N]) -> i128,
    name: &str,
    warnings: &mut Vec<String>,
    alloc: impl Fn(usize) -> Result<Vec<u8>, super::error::NiftiError>,
) -> Result<Packed, super::error::NiftiError> {
    let (mut lo, mut hi) = (i128::MAX, i128::MIN);
    for x in arrays::<N>(src).map(&read) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    let count = src.len() / N;
    let stride = count.div_ceil(OFFSET_SAMPLE).max(1);
    let mut sample: Vec<i128> = arrays::<N>(src).step_by(stride).map(&read).collect();
    let offset = if lo > hi {
        0
    } else {
        integer_offset(lo, hi, &mut sample)
    };
    let mut out = alloc(src.len() / N * 4)?;
    // The reach is measured on the f32 values written, not on the exact integers: rounding to
    // f32 can move a value up by half an ulp, and the map must bound what is stored.
    let mut reach = 0.0f64;
    let (mut rounded, mut worst) = (0usize, 0i128);
    for x in arrays::<N>(src).map(&read) {
        let stored = (x - offset) as f32;
        reach = reach.max(f64::from(stored).abs());
        // An f32 of magnitude >= 2^24 is an integer; below that the difference is exact too.
        let error = (x - offset - f64::from(stored) as i128).abs();
        if error != 0 {
            rounded += 1;
            worst = worst.max(error);
        }
        out.extend_from_slice(&stored.to_le_bytes());
    }
    if rounded > 0 {
        let extremes = if exact(lo, offset) && exact(hi, offset) {
            "the minimum and maximum are exact"
        } else {
            "the minimum or maximum is rounded too"
        };
        warnings.push(format!(
            "{name} voxels are stored as float32: the data spans {lo}..{hi}, wider than \
             float32's 2^24 exact integers, so {rounded} voxels are rounded by up to {worst} \
             ({extremes}; convert writes the rounded values)"
        ));
    }
    Ok(Packed {
        bytes: out,
        offset: offset as f64,
        scale: 1.0,
        reach,
    })
}

/// What the float64 data holds, in one pass over the finite voxels.
struct FloatSurvey {
    lo: f64,
    hi: f64,
    finite: usize,
    /// Voxels with |x| > F32_REACH.
    beyond: usize,
    /// Largest |x|.
    largest: f64,
    /// Range of the voxels within F32_REACH.
    inner: (f64, f64),
}

fn survey(values: impl Iterator<Item = f64>) -> FloatSurvey {
    let mut s = FloatSurvey {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
        finite: 0,
        beyond: 0,
        largest: 0.0,
        inner: (f64::INFINITY, f64::NEG_INFINITY),
    };
    for x in values.filter(|x| x.is_finite()) {
        s.lo = s.lo.min(x);
        s.hi = s.hi.max(x);
        s.finite += 1;
        s.largest = s.largest.max(x.abs());
        if x.abs() > F32_REACH {
            s.beyond += 1;
        } else {
            s.inner = (s.inner.0.min(x), s.inner.1.max(x));
        }
    }
    s
}

/// float64 to f32 with the rule of the module doc.
pub fn floats(
    src: &[u8],
    big: bool,
    warnings: &mut Vec<String>,
    alloc: impl Fn(usize) -> Result<Vec<u8>, super::error::NiftiError>,
) -> Result<Packed, super::error::NiftiError> {
    let read = |b: [u8; 8]| {
        if big {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    };
    let s = survey(arrays::<8>(src).map(read));
    let clamp = s.beyond > 0 && s.beyond as f64 <= CLAMP_FRACTION * s.finite as f64;
    let (lo, hi) = if clamp {
        (s.lo.max(-F32_REACH), s.hi.min(F32_REACH))
    } else {
        (s.lo, s.hi)
    };
    let (offset, scale) = if lo <= hi {
        // Halves first: (lo + hi) could overflow for values near f64::MAX.
        let mid = lo / 2.0 + hi / 2.0;
        let half = hi / 2.0 - lo / 2.0;
        let offset = if mid.abs() > 64.0 * half { mid } else { 0.0 };
        // Finite: with an offset, |x - mid| <= half; without one, |x| <= max(|lo|, |hi|).
        let reach = (hi - offset).abs().max((lo - offset).abs());
        let mut scale = 1.0f64;
        // Powers of two: dividing by them is exact, and the loop runs at most ~60 times.
        while reach.is_finite() && reach / scale > F32_REACH {
            scale *= 65536.0;
        }
        (offset, scale)
    } else {
        (0.0, 1.0)
    };
    let mut out = alloc(src.len() / 8 * 4)?;
    let mut stored_reach = 0.0f64;
    for x in arrays::<8>(src).map(read) {
        let x = if clamp && x.is_finite() {
            x.clamp(-F32_REACH, F32_REACH)
        } else {
            x
        };
        let mut stored = ((x - offset) / scale) as f32;
        // Found by fuzzing: for |x| within half an f32 ulp of f64::MAX, rounding to f32 moves
        // the stored value past x, and `stored * scale + offset` overflows to infinity. One
        // f32 step toward zero (an error no larger than the rounding itself) keeps it finite.
        if x.is_finite() && !(f64::from(stored) * scale + offset).is_finite() {
            stored = f32::from_bits(stored.to_bits().saturating_sub(1));
        }
        if stored.is_finite() {
            stored_reach = stored_reach.max(f64::from(stored).abs());
        }
        out.extend_from_slice(&stored.to_le_bytes());
    }
    if clamp {
        warnings.push(format!(
            "{} of {} float64 voxels lie beyond +-{F32_REACH:e} (the largest {:e}), out of \
             float32's reach with the rest of the data ({}..{}): they are stored clamped to \
             +-{F32_REACH:e}, treated as hot voxels by the robust intensity range, and convert \
             writes them clamped",
            s.beyond, s.finite, s.largest, s.inner.0, s.inner.1
        ));
    }
    precision_warning(src, &out, big, clamp, warnings);
    Ok(Packed {
        bytes: out,
        offset,
        scale,
        reach: stored_reach,
    })
}

/// Says so when storing float64 as f32 lost distinctions the data had: neighbouring voxels (in
/// file order) with different finite float64 values whose f32 values are equal. Either f32's
/// 24-bit rounding at the data's reach, or underflow of small values once data reaching 1e308
/// is scaled into f32's range. Voxels clamped by [`floats`] are left to its own warning.
fn precision_warning(src: &[u8], out: &[u8], big: bool, clamped: bool, warnings: &mut Vec<String>) {
    let read = |b: [u8; 8]| {
        if big {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    };
    let originals = arrays::<8>(src).map(read);
    let stored = arrays::<4>(out).map(f32::from_le_bytes);
    let mut previous: Option<(f64, f32)> = None;
    let (mut merged, mut reach) = (0usize, 0.0f64);
    for (x, y) in originals.zip(stored) {
        if !x.is_finite() || (clamped && x.abs() > F32_REACH) {
            previous = None;
            continue;
        }
        reach = reach.max(x.abs());
        if let Some((px, py)) = previous
            && px != x
            && py == y
        {
            merged += 1;
        }
        previous = Some((x, y));
    }
    if merged > 0 {
        warnings.push(format!(
            "float64 voxels are stored as float32: {merged} pairs of neighbouring voxels with \
             different values became equal (the data reaches {reach:e}, and float32 keeps about \
             7 significant digits of that: smaller differences and values are lost, in the \
             image and in what convert writes)"
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn alloc(n: usize) -> Result<Vec<u8>, super::super::error::NiftiError> {
        Ok(Vec::with_capacity(n))
    }

    fn floats_of(values: &[f64]) -> (Vec<f64>, Vec<String>) {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let mut warnings = Vec::new();
        let p = floats(&bytes, false, &mut warnings, alloc).unwrap();
        let physical = arrays::<4>(&p.bytes)
            .map(|b| f64::from(f32::from_le_bytes(b)) * p.scale + p.offset)
            .collect();
        (physical, warnings)
    }

    #[test]
    fn one_voxel_at_1e300_is_clamped_and_the_rest_is_kept() {
        let mut values: Vec<f64> = (0..400).map(|i| f64::from(i % 97) * 13.5).collect();
        values[7] = 1e300;
        let (physical, warnings) = floats_of(&values);
        assert_eq!(physical[7], F32_REACH as f32 as f64);
        for (i, (&x, &y)) in values.iter().zip(&physical).enumerate() {
            if i != 7 {
                assert_eq!(x, y, "voxel {i}");
            }
        }
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("1 of 400 float64 voxels"),
            "{warnings:?}"
        );
        assert!(warnings[0].contains("the largest 1e300"), "{warnings:?}");
        assert!(
            warnings[0].contains("convert writes them clamped"),
            "{warnings:?}"
        );
    }

    #[test]
    fn a_volume_that_is_huge_throughout_is_scaled_not_clamped() {
        let values = [1.7e308, 1.0, 2.0, 3.0, -1.7e308];
        let (physical, warnings) = floats_of(&values);
        assert!(physical.iter().all(|v| v.is_finite()));
        assert!((physical[0] / 1.7e308 - 1.0).abs() < 1e-6);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("2 pairs"), "{warnings:?}");
        assert!(!warnings[0].contains("do not change"), "{warnings:?}");
        // An ordinary float64 volume keeps every distinction: no warning.
        let (_, warnings) = floats_of(&[1.0, 2.0, 3.5, -7.25, 1e6]);
        assert!(warnings.is_empty(), "{warnings:?}");
    }

    fn integers_of(values: &[i64]) -> (Vec<f64>, Vec<String>) {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let mut warnings = Vec::new();
        let read = |b: [u8; 8]| i128::from(i64::from_le_bytes(b));
        let p = integers(&bytes, read, "int64", &mut warnings, alloc).unwrap();
        let physical = arrays::<4>(&p.bytes)
            .map(|b| f64::from(f32::from_le_bytes(b)) * p.scale + p.offset)
            .collect();
        (physical, warnings)
    }

    #[test]
    fn wide_integers_keep_their_minimum_and_maximum_exactly() {
        // Before: the midpoint offset stored -2147483647 as -2147483645 (`info` showed a
        // minimum that is not in the data).
        for values in [
            vec![-2147483647, 0, 1539, 1542, 77],
            vec![100000001, 100001543, 100000500],
            vec![1099511627777, 1099511629319, 1099511628000],
            vec![i64::from(i32::MIN), i64::from(i32::MAX), 12345],
            vec![-(1 << 46) - 3, (1 << 46) + 5, 1],
        ] {
            let (physical, _) = integers_of(&values);
            let lo = *values.iter().min().unwrap() as f64;
            let hi = *values.iter().max().unwrap() as f64;
            let plo = physical.iter().cloned().fold(f64::INFINITY, f64::min);
            let phi = physical.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            assert_eq!((plo, phi), (lo, hi), "{values:?}");
        }
        // One outlier leaves the bulk exact (before: 0..1542 was rounded to steps of 128).
        let mut values: Vec<i64> = (0..1543).collect();
        values.push(-2147483647);
        let (physical, warnings) = integers_of(&values);
        let bulk: Vec<f64> = (0..1543).map(|v| v as f64).collect();
        assert_eq!(physical[..1543], bulk[..]);
        assert_eq!(physical[1543], -2147483647.0);
        assert!(warnings.is_empty(), "{warnings:?}");
        // A spread that f32 cannot hold whole: rounded, and said.
        let values: Vec<i64> = (0..2000).map(|i| i * 1_000_003 + (i % 7)).collect();
        let (physical, warnings) = integers_of(&values);
        assert_eq!(physical[0], 0.0);
        assert_eq!(physical[1999], values[1999] as f64);
        assert!(warnings[0].contains("rounded by up to"), "{warnings:?}");
        assert!(
            warnings[0].contains("minimum and maximum are exact"),
            "{warnings:?}"
        );
        // Within 2^24: exact, no warning.
        let (physical, warnings) = integers_of(&[-16777216, 16777216, 3]);
        assert_eq!(physical, vec![-16777216.0, 16777216.0, 3.0]);
        assert!(warnings.is_empty());
    }
}
