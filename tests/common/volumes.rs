//! Small synthetic volumes for GPU tests (deterministic, no files, no ../shared).
#![allow(dead_code)]

use morphray::volume::{AffineSource, LinearMap, Orientation, Samples, Volume};

/// A deterministic pseudo-random generator (SplitMix64), so failures reproduce.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// A volume with the given samples on a diagonal affine.
pub fn volume(dims: [usize; 3], spacing: [f64; 3], samples: Samples) -> Volume {
    Volume {
        name: "synthetic".into(),
        dims,
        spacing_mm: spacing.map(f64::abs),
        orientation: Orientation::from_spacing(spacing, AffineSource::Synthetic),
        samples,
        to_physical: LinearMap::IDENTITY,
        warnings: vec![],
        facts: Default::default(),
    }
}

/// A volume with a full affine.
pub fn volume_with_affine(dims: [usize; 3], affine: [[f64; 4]; 4], samples: Samples) -> Volume {
    let mut v = volume(dims, [1.0; 3], samples);
    for (axis, spacing) in v.spacing_mm.iter_mut().enumerate() {
        *spacing = affine
            .iter()
            .take(3)
            .map(|row| row[axis] * row[axis])
            .sum::<f64>()
            .sqrt();
    }
    v.orientation = Orientation {
        affine,
        source: AffineSource::Synthetic,
    };
    v
}

/// A smooth random field: a sum of a few random sinusoids, in [lo, hi].
pub fn smooth_field(dims: [usize; 3], rng: &mut Rng, lo: f64, hi: f64) -> Vec<f64> {
    let waves: Vec<([f64; 3], f64)> = (0..4)
        .map(|_| {
            (
                [
                    rng.range(0.05, 0.5),
                    rng.range(0.05, 0.5),
                    rng.range(0.05, 0.5),
                ],
                rng.range(0.0, std::f64::consts::TAU),
            )
        })
        .collect();
    let mut out = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let s: f64 = waves
                    .iter()
                    .map(|(f, phase)| {
                        (f[0] * i as f64 + f[1] * j as f64 + f[2] * k as f64 + phase).sin()
                    })
                    .sum::<f64>()
                    / waves.len() as f64;
                out.push(lo + (hi - lo) * (s * 0.5 + 0.5));
            }
        }
    }
    out
}
