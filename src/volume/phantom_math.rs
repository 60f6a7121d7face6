//! Deterministic arithmetic of the phantom (moved out of phantom.rs): a platform-independent
//! sine, the SplitMix64 hash, an approximately normal deviate, the partial-volume ramp.
//!
//! Decisions: only +, -, *, /, sqrt, abs, min/max and round are used, so every phantom voxel is
//! bit-identical on any IEEE-754 platform and thread count (phantom.rs module doc).

pub(super) const PI: f64 = std::f64::consts::PI;

/// sin(x) from basic IEEE operations only (bit-identical on every platform). Accurate to about
/// 1e-9 for |x| up to a few thousand, far below what the int16 rounding can see.
pub(super) fn det_sin(x: f64) -> f64 {
    // Reduce to [-pi, pi], then fold to [-pi/2, pi/2].
    let turns = (x / (2.0 * PI)).round();
    let mut y = x - turns * (2.0 * PI);
    if y > PI / 2.0 {
        y = PI - y;
    } else if y < -PI / 2.0 {
        y = -PI - y;
    }
    let y2 = y * y;
    // Taylor series to y^15 in Horner form (error < 1e-10 on [-pi/2, pi/2]); the coefficients
    // are exact-rounded compile-time constants, so the result is the same everywhere.
    const C: [f64; 7] = [
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
        -1.0 / 1_307_674_368_000.0,
    ];
    let mut p = C[6];
    for &c in C[..6].iter().rev() {
        p = c + y2 * p;
    }
    y + y * y2 * p
}

pub(super) fn det_cos(x: f64) -> f64 {
    det_sin(x + PI / 2.0)
}

/// SplitMix64 finaliser.
pub(super) fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Approximately standard normal value from 64 random bits (Irwin-Hall, n = 4).
pub(super) fn normal(bits: u64) -> f64 {
    let mut sum = 0.0;
    for shift in [0, 16, 32, 48] {
        sum += (((bits >> shift) & 0xffff) as f64 + 0.5) / 65536.0;
    }
    (sum - 2.0) * 3.0f64.sqrt()
}

/// Weight of a structure whose signed distance (voxels, positive inside) is `d`: a linear ramp
/// over one voxel centred on the boundary.
pub(super) fn ramp(d: f64) -> f64 {
    (d + 0.5).clamp(0.0, 1.0)
}

pub(super) fn norm3(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// First-order signed distance (voxels, > 0 inside) to the ellipsoid with semi-axes `semi`
/// (voxels; an infinite one makes a cylinder) centred at the origin, at offset `v`: exact on the
/// axes, (1 - r) / |grad r| elsewhere.
pub(super) fn ellipsoid_inside(v: [f64; 3], semi: [f64; 3]) -> f64 {
    let q: [f64; 3] = std::array::from_fn(|a| v[a] / semi[a]);
    let r = norm3(q);
    if r <= 1e-12 {
        return semi.iter().fold(f64::INFINITY, |m, &s| m.min(s));
    }
    let g = norm3(std::array::from_fn(|a| q[a] / semi[a])) / r;
    (1.0 - r) / g.max(1e-12)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_sine_matches_libm() {
        let mut worst = 0.0f64;
        for i in -20_000..=20_000 {
            let x = f64::from(i) * 0.003_7;
            worst = worst
                .max((det_sin(x) - x.sin()).abs())
                .max((det_cos(x) - x.cos()).abs());
        }
        assert!(worst < 1e-9, "worst error {worst}");
    }

    #[test]
    fn irwin_hall_noise_is_close_to_standard_normal() {
        let n = 200_000u64;
        let xs: Vec<f64> = (0..n).map(|i| normal(mix(i))).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.02, "variance {var}");
        assert!(xs.iter().all(|x| x.abs() <= 2.0 * 3.0f64.sqrt()));
    }

    #[test]
    fn ellipsoid_distance_is_exact_on_the_axes() {
        let semi = [10.0, 20.0, f64::INFINITY];
        assert!((ellipsoid_inside([12.0, 0.0, 0.0], semi) + 2.0).abs() < 1e-12);
        assert!((ellipsoid_inside([0.0, 15.0, 99.0], semi) - 5.0).abs() < 1e-12);
        assert_eq!(ellipsoid_inside([0.0; 3], semi), 10.0);
    }

    #[test]
    fn ramp_is_a_one_voxel_linear_blend() {
        assert_eq!(ramp(-0.5), 0.0);
        assert_eq!(ramp(0.0), 0.5);
        assert_eq!(ramp(0.25), 0.75);
        assert_eq!(ramp(0.5), 1.0);
        assert_eq!(ramp(f64::INFINITY), 1.0);
        assert_eq!(ramp(f64::NEG_INFINITY), 0.0);
    }
}
