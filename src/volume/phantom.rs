//! The built-in digital phantom: a deterministic, brain-like T1 volume with known tissue labels,
//! used wherever no file is given and as ground truth in tests. [`PhantomSpec::anatomy`] swaps
//! the dark shell for a layered head with eyes and a neck (phantom_head.rs, which also gives
//! the true brain mask) and [`PhantomSpec::contrast`] picks T1, T2, PD, FLAIR or CT
//! (phantom_contrast.rs); the defaults (shell, T1) give the bytes described here, unchanged.
//!
//! Decisions:
//! - Nominal raw intensities (int16, T1 contrast order), see [`NOMINAL`]: background 0,
//!   skull/fat shell 80 (dark, bone-like: between background and CSF so it falls outside every
//!   tissue window and the pathology band and never hides the brain), CSF 250, GM 600, WM 850,
//!   lesion 1350, vessels 1450. Peaks are 350 / 250 raw units apart (>= 12 noise sigmas), so a
//!   histogram shows separate CSF, GM and WM modes; lesion and vessels are the only voxels above
//!   about 1250.
//! - Geometry is defined in coordinates normalised to the volume extent, so any size gives the
//!   same (scaled) head. Brain: an ellipsoid with semi-axes 0.56 / 0.68 / 0.64 of the half-extent
//!   (72 / 87 / 61 mm at cohort A: a 143 x 174 x 123 mm brain). Thin structures have a floor in voxels so small test
//!   phantoms still contain every tissue: GM ribbon max(3 mm, 2 voxels), sulcus half-width
//!   max(0.75 mm, 0.5 voxel), subarachnoid CSF max(3 mm, 1.5 voxels), interhemispheric fissure
//!   half-width max(1.5 mm, 0.75 voxel), vessel radius max(1.25 mm, 1 voxel), lesion radius
//!   max(4.5 mm, 2 voxels), skull + scalp max(14 mm, CSF + 2.5 voxels). "mm" here means
//!   "cohort-A voxels", scaled by the smallest brain semi-axis in voxels / 61.44.
//! - Folding: sulci are the zero set of S(n) = sum of four sinusoids of the direction n from the
//!   brain centre (no poles, irregular like real gyri), cut from the hull down to 20 % of the
//!   brain radius (12-17 mm at cohort A), filled with CSF; the distance to them is |S| / |grad S| (first order). The GM
//!   ribbon is everything within the GM thickness of CSF (hull, sulci or fissure), so GM lines
//!   sulcal walls and bottoms with a constant thickness; WM is inside. The sulcal frequency is
//!   min(22, pi * smallest semi-axis / 7 voxels): about 9-12 mm between sulci at cohort A, and
//!   lower on small grids so that gyri keep a WM core.
//! - Other structures: two banana-shaped lateral ventricles (CSF) beside the midline; a
//!   midline fissure (CSF) down to the corpus callosum in the middle and through the whole brain
//!   at the front and back; a lesion sphere in the left hemisphere's WM (world x < 0, RAS);
//!   vessels: the superior sagittal sinus along the top of the fissure in the CSF layer, a
//!   pericallosal artery at the fissure bottom, one Sylvian (MCA-like) artery on each side, and
//!   vessels of radii 3, 2, 1, 0.5 mm in the WM (phantom_vessels.rs); edema (phantom_edema.rs).
//! - Partial volume: each structure has a signed distance in voxels; its weight is a linear ramp
//!   over one voxel centred on the boundary, structures blended in nesting order (head, CSF, GM,
//!   WM, ventricles, edema, lesion, vessels); the label is the last one weighing >= 0.5 at the
//!   voxel centre, which is also the dominant one in the blend.
//! - Bias: smooth multiplicative field 1 + 0.07 f(p), |f| <= 1 (about +-7 %), applied to the
//!   tissue signal. Noise (when `noise`): Rician magnitude sqrt((s + sigma n1)^2 + (sigma n2)^2)
//!   with sigma = 20 (2.4 % of WM), so the background is a positive Rayleigh floor (mean ~25).
//!   n1, n2 are Irwin-Hall sums of four 16-bit uniforms (close to Gaussian, bounded at
//!   +-3.46 sigma) from a SplitMix64 hash of (seed, voxel index).
//! - Deterministic: every voxel is a pure function of (spec, index), and only +, -, *, /, sqrt,
//!   abs, min/max and round are used (sin/cos are a local polynomial, not the platform libm), so the
//!   bytes are identical for any thread count and on any IEEE-754 platform.
//! - Fast: slabs of k-planes in parallel with `std::thread::scope`; voxels outside the head
//!   skip the anatomy; the sulcal field is evaluated only near the cortex.

use super::phantom_contrast::Contrast;
use super::phantom_head::{Anatomy, Frame, HEAD_BRAIN_SEMI, HEAD_COHORT_A_BMIN, HeadGeometry};
use super::phantom_math::{PI, det_cos, det_sin, mix, norm3, normal, ramp};
use crate::volume::{AffineSource, LinearMap, Orientation, Samples, Volume};

pub use super::phantom_tissue::{NOMINAL, Nominal, Tissue};

/// Standard deviation of each noise component, in raw units (2.4 % of WM; MR contrasts).
pub const NOISE_SIGMA: f64 = super::phantom_contrast::MR_NOISE_SIGMA;

/// Amplitude of the multiplicative bias field (+-7 %).
pub const BIAS_AMPLITUDE: f64 = 0.07;

/// What to generate.
#[derive(Clone, Debug, PartialEq)]
pub struct PhantomSpec {
    /// Voxels along i, j, k.
    pub dims: [usize; 3],
    /// Voxel size in mm along i, j, k (used for the affine only; geometry is normalised).
    pub spacing_mm: [f64; 3],
    /// Seed of the noise.
    pub seed: u64,
    /// Add noise: Rician for MR, additive for CT (the bias field is always applied in MR).
    pub noise: bool,
    /// What surrounds the brain: today's dark shell (default) or a layered head.
    pub anatomy: Anatomy,
    /// Intensity table and noise model (T1 by default).
    pub contrast: Contrast,
}

impl PhantomSpec {
    /// The default seed ("morphray" in ASCII).
    pub const DEFAULT_SEED: u64 = 0x6d6f_7270_6872_6179;

    /// The paper's cohort-A size: 256 x 256 x 192 voxels of 1 mm (12,582,912 voxels), with noise.
    pub fn cohort_a() -> Self {
        PhantomSpec {
            dims: [256, 256, 192],
            spacing_mm: [1.0; 3],
            seed: Self::DEFAULT_SEED,
            noise: true,
            anatomy: Anatomy::Shell,
            contrast: Contrast::T1,
        }
    }

    /// A small n x n x n phantom of 1 mm voxels, with noise (for tests).
    pub fn cube(n: usize) -> Self {
        PhantomSpec {
            dims: [n; 3],
            spacing_mm: [1.0; 3],
            seed: Self::DEFAULT_SEED,
            noise: true,
            anatomy: Anatomy::Shell,
            contrast: Contrast::T1,
        }
    }

    /// The head phantom (scalp layers, skull, eyes, neck; src/volume/phantom_head.rs) of
    /// `dims` 1 mm voxels in `contrast`, with or without noise.
    pub fn head(dims: [usize; 3], contrast: Contrast, noise: bool) -> Self {
        PhantomSpec {
            dims,
            spacing_mm: [1.0; 3],
            seed: Self::DEFAULT_SEED,
            noise,
            anatomy: Anatomy::Head,
            contrast,
        }
    }
}

/// Why a phantom could not be generated.
#[derive(Debug, thiserror::Error)]
pub enum PhantomError {
    /// A dimension is 0 or a spacing is not finite and positive.
    #[error(
        "a phantom needs dims of at least 1 and finite positive spacing, but got dims {dims:?} and spacing {spacing:?} mm"
    )]
    BadSpec {
        /// The requested dims.
        dims: [usize; 3],
        /// The requested spacing.
        spacing: [f64; 3],
    },
    /// The volume does not fit in memory (checked before allocating).
    #[error(
        "a {dims:?} phantom needs {} of host memory (2 bytes of sample and 1 of label per voxel){}; use smaller --dims",
        bytes.map_or("more bytes than can be counted".to_string(), |b| format!("{b} bytes")),
        available.map_or(String::new(), |a| format!(", but only {a} bytes are available"))
    )]
    TooLarge {
        /// The requested dims.
        dims: [usize; 3],
        /// Bytes it needs (None when the count overflows).
        bytes: Option<u64>,
        /// Bytes the system said were available (None when unknown).
        available: Option<u64>,
    },
}

/// A generated phantom: the volume, a tissue label per voxel and the nominal intensities.
#[derive(Clone, Debug)]
pub struct Phantom {
    /// i16 samples, name `phantom`, RAS+ affine centred on the volume, identity intensity map.
    pub volume: Volume,
    /// [`Tissue`] value per voxel, in the same order as the samples.
    pub labels: Vec<u8>,
    /// Nominal intensity of the plain phantom's tissues in this contrast (all of them:
    /// [`Phantom::intensity`]).
    pub nominal: Nominal,
    /// What was generated.
    pub spec: PhantomSpec,
}

impl Phantom {
    /// Tissue of voxel `index` (None when out of range).
    pub fn tissue(&self, index: usize) -> Option<Tissue> {
        self.labels.get(index).copied().and_then(Tissue::from_label)
    }

    /// Nominal intensity of `tissue` in this phantom's contrast.
    pub fn intensity(&self, tissue: Tissue) -> f64 {
        self.spec.contrast.nominal(tissue)
    }

    /// The true brain mask, one per voxel in sample order: intracranial CSF, GM, WM, lesion,
    /// vessels and edema, without the spinal canal below the foramen magnum
    /// ([`super::phantom_head::brain_truth`]).
    pub fn brain_mask(&self) -> Vec<bool> {
        super::phantom_head::brain_truth(&self.labels, self.volume.dims, self.spec.anatomy)
    }
}

/// Normalised sulcal directions and phases (fixed anatomy; the seed only drives noise).
const SULCUS_WAVES: [([f64; 3], f64); 4] = [
    ([0.8, 0.3, 0.5], 0.3),
    ([-0.2, 0.9, 0.4], 1.1),
    ([0.5, -0.4, 0.8], 2.0),
    ([0.3, 0.6, -0.7], 2.9),
];

/// Radial depth of the sulci, as a fraction of the brain radius.
const SULCUS_DEPTH: f64 = 0.2;

/// Brain semi-axes as fractions of the volume's half-extent.
const BRAIN_SEMI: [f64; 3] = [0.56, 0.68, 0.64];

/// Smallest brain semi-axis in voxels at cohort A (0.64 * 96): the unit of "mm" scaling.
const COHORT_A_BMIN: f64 = 0.64 * 96.0;

/// Everything about the anatomy that depends only on the spec.
struct Geometry {
    centre: [f64; 3],
    half: [f64; 3],
    brain: [f64; 3],
    head: [f64; 3],
    gm: f64,
    sulcus_half: f64,
    csf_layer: f64,
    fissure_half: f64,
    vessel_radius: f64,
    lesion_radius: f64,
    lesion_centre: [f64; 3],
    edema_thickness: f64,
    vessels: super::phantom_vessels::Vessels,
    waves: [([f64; 3], f64); 4],
    frequency: f64,
    contrast: Contrast,
    /// The layered head around the brain (None: the plain dark shell).
    layered: Option<HeadGeometry>,
}

/// The brain frame of a phantom of `dims` whose brain has semi-axes `semi` (fractions of the
/// half-extent) and whose phantom mm is `cohort_bmin` voxels at cohort A over the smallest one.
fn frame(dims: [usize; 3], semi: [f64; 3], cohort_bmin: f64) -> Frame {
    let d = dims.map(|n| n as f64);
    let brain: [f64; 3] = std::array::from_fn(|a| semi[a] * d[a] / 2.0);
    let bmin = brain.iter().fold(f64::INFINITY, |m, &b| m.min(b));
    let voxels_per_mm = bmin / cohort_bmin;
    Frame {
        brain,
        voxels_per_mm,
        csf_layer: (3.0 * voxels_per_mm).max(1.5),
        centre: d.map(|n| (n - 1.0) / 2.0),
    }
}

/// The brain frame of a layered (head) phantom of `dims`.
pub(super) fn head_frame(dims: [usize; 3]) -> Frame {
    frame(dims, HEAD_BRAIN_SEMI, HEAD_COHORT_A_BMIN)
}

impl Geometry {
    fn new(dims: [usize; 3], anatomy: Anatomy, contrast: Contrast) -> Geometry {
        let f = if anatomy.is_layered() {
            head_frame(dims)
        } else {
            frame(dims, BRAIN_SEMI, COHORT_A_BMIN)
        };
        let (brain, s, csf_layer) = (f.brain, f.voxels_per_mm, f.csf_layer);
        let bmin = brain.iter().fold(f64::INFINITY, |m, &b| m.min(b));
        let len = |mm: f64, floor: f64| (mm * s).max(floor);
        let head_t = len(14.0, csf_layer + 2.5);
        let waves = SULCUS_WAVES.map(|(u, phase)| {
            let n = norm3(u);
            ([u[0] / n, u[1] / n, u[2] / n], phase)
        });
        Geometry {
            centre: f.centre,
            half: dims.map(|n| n as f64 / 2.0),
            brain,
            head: brain.map(|b| b + head_t),
            gm: len(3.0, 2.0),
            sulcus_half: len(0.75, 0.5),
            csf_layer,
            fissure_half: len(1.5, 0.75),
            vessel_radius: len(1.25, 1.0),
            lesion_radius: len(4.5, 2.0),
            lesion_centre: [-0.42 * brain[0], -0.08 * brain[1], 0.30 * brain[2]],
            edema_thickness: super::phantom_edema::thickness(s),
            vessels: super::phantom_vessels::Vessels::new(brain, s),
            waves,
            frequency: (PI * bmin / 7.0).min(22.0),
            contrast,
            layered: anatomy.is_layered().then(|| HeadGeometry::new(&f, anatomy)),
        }
    }

    /// Height (q units) of the fissure bottom at anterior-posterior position `qy`.
    fn fissure_bottom(qy: f64) -> f64 {
        let a = qy.abs();
        if a <= 0.45 {
            0.42
        } else {
            0.42 - (a - 0.45) / 0.25 * 1.6
        }
    }

    /// Signed distance (voxels, positive inside) to one lateral ventricle.
    fn ventricle(&self, q: [f64; 3], side: f64) -> f64 {
        let zc = 0.10 * (1.0 - (q[1] + 0.05) * (q[1] + 0.05) / 0.16).max(0.0);
        let semi = [0.085, 0.40, 0.15];
        let c = [side * 0.15, -0.05, zc];
        let u: [f64; 3] = std::array::from_fn(|a| (q[a] - c[a]) / semi[a]);
        let r = norm3(u);
        let grad: [f64; 3] = std::array::from_fn(|a| u[a] / (semi[a] * self.brain[a]));
        let g = norm3(grad) / r.max(1e-12);
        (1.0 - r) / g.max(1e-12)
    }

    /// Signed distance to the CSF boundary of the cortex (voxels; > 0 inside tissue): the
    /// nearest of the brain hull, a sulcus and the fissure.
    fn cortex_distance(&self, v: [f64; 3], q: [f64; 3], r: f64, g_r: f64, hull: f64) -> f64 {
        let mut dist = hull;
        // Sulci reach from the hull down to radius 1 - depth; evaluate them only where the
        // sheet could be within the GM thickness (plus the ramp) of this voxel.
        let below = (1.0 - SULCUS_DEPTH - r) / g_r;
        if below < self.gm + self.sulcus_half + 1.0 && r > 1e-9 {
            let n = [q[0] / r, q[1] / r, q[2] / r];
            let mut s = 0.0;
            let mut ds = [0.0; 3];
            for (u, phase) in &self.waves {
                let arg = self.frequency * (n[0] * u[0] + n[1] * u[1] + n[2] * u[2]) + phase;
                s += det_sin(arg);
                let c = self.frequency * det_cos(arg);
                for a in 0..3 {
                    ds[a] += c * u[a];
                }
            }
            // Tangential part of dS/dn, then chain rule to voxel coordinates.
            let radial = ds[0] * n[0] + ds[1] * n[1] + ds[2] * n[2];
            let grad: [f64; 3] =
                std::array::from_fn(|a| (ds[a] - radial * n[a]) / (r * self.brain[a]));
            let lateral = s.abs() / norm3(grad).max(1e-12);
            let depth = below.max(0.0);
            dist = dist.min((lateral * lateral + depth * depth).sqrt() - self.sulcus_half);
        }
        let below_f = ((Self::fissure_bottom(q[1]) - q[2]) * self.brain[2]).max(0.0);
        dist.min((v[0] * v[0] + below_f * below_f).sqrt() - self.fissure_half)
    }

    /// Distance (voxels) to the nearest vessel centre line.
    fn vessel_distance(&self, v: [f64; 3], q: [f64; 3], hull: f64) -> f64 {
        // Depth of the vessel lines in the subarachnoid layer: its middle.
        let layer = -hull - self.csf_layer / 2.0;
        let mut best = f64::INFINITY;
        // Superior sagittal sinus: midline, upper part of the hull.
        if q[2] > -0.2 {
            best = best.min((v[0] * v[0] + layer * layer).sqrt());
        }
        // Sylvian arteries, both sides, on the lateral hull.
        if q[0].abs() > 0.3 && (-0.35..=0.45).contains(&q[1]) {
            let dz = (q[2] - 0.05) * self.brain[2];
            best = best.min((dz * dz + layer * layer).sqrt());
        }
        // Pericallosal artery: midline, just above the fissure bottom.
        if q[1].abs() <= 0.45 {
            let z = Self::fissure_bottom(q[1]) + (self.vessel_radius + 0.5) / self.brain[2];
            let dz = (q[2] - z) * self.brain[2];
            best = best.min((v[0] * v[0] + dz * dz).sqrt());
        }
        best
    }

    /// Multiplicative bias at normalised position `p`.
    fn bias(p: [f64; 3]) -> f64 {
        let f = 0.55 * p[0] + 0.45 * p[1] - 0.35 * p[2] + 0.25 * det_sin(2.2 * p[1] + 1.3 * p[2]);
        1.0 + BIAS_AMPLITUDE * f.clamp(-1.0, 1.0)
    }

    /// Noise-free signal and label of the voxel at index (i, j, k).
    fn voxel(&self, ijk: [f64; 3]) -> (f64, Tissue) {
        let v: [f64; 3] = std::array::from_fn(|a| ijk[a] - self.centre[a]);
        let mut b = Blend::new(self.contrast);

        // Brain hull: q brain-normalised, hull the signed distance to it (> 0 inside).
        let q: [f64; 3] = std::array::from_fn(|a| v[a] / self.brain[a]);
        let r = norm3(q);
        let g_r = (norm3(std::array::from_fn(|a| q[a] / self.brain[a])) / r.max(1e-12)).max(1e-12);
        let hull = if r > 1e-9 {
            (1.0 - r) / g_r
        } else {
            f64::INFINITY
        };

        match &self.layered {
            None => {
                // Head (skull and scalp): ellipsoid.
                let qh: [f64; 3] = std::array::from_fn(|a| v[a] / self.head[a]);
                let rh = norm3(qh);
                let gh = norm3(std::array::from_fn(|a| qh[a] / self.head[a])) / rh.max(1e-12);
                let head = (1.0 - rh) / gh.max(1e-12);
                if head < -0.5 {
                    return (b.signal, b.label);
                }
                b.add(head, Tissue::SkullFat);
            }
            Some(layered) => {
                if !layered.outer(v, q, r, -hull, &mut b) {
                    return (b.signal, b.label);
                }
            }
        }
        self.brain(v, q, r, g_r, hull, &mut b);
        if let Some(layered) = &self.layered {
            layered.canal(v, hull, &mut b);
        }
        (self.biased(b.signal, v), b.label)
    }

    /// Blends the subarachnoid CSF and everything inside it (nothing when outside the CSF).
    fn brain(&self, v: [f64; 3], q: [f64; 3], r: f64, g_r: f64, hull: f64, b: &mut Blend) {
        if hull + self.csf_layer < -0.5 {
            return;
        }
        b.add(hull + self.csf_layer, Tissue::Csf);

        let cortex = self.cortex_distance(v, q, r, g_r, hull);
        b.add(cortex, Tissue::Gm);
        b.add(cortex - self.gm, Tissue::Wm);

        let ventricles = self.ventricle(q, -1.0).max(self.ventricle(q, 1.0));
        b.add(ventricles, Tissue::Csf);

        let dl = norm3(std::array::from_fn(|a| v[a] - self.lesion_centre[a]));
        let edema = super::phantom_edema::inside(dl, self.lesion_radius, self.edema_thickness);
        b.add(edema, Tissue::Edema);
        b.add(self.lesion_radius - dl, Tissue::Lesion);

        // The older vessels (radius floored) and the known radii, as one structure.
        let vessel =
            (self.vessel_radius - self.vessel_distance(v, q, hull)).max(self.vessels.inside(v));
        // Inside a layered head, the vessels in the CSF layer (radius floored in voxels) stay
        // intracranial on small grids instead of cutting the inner table.
        let vessel = match self.layered {
            Some(_) => vessel.min(hull + self.csf_layer),
            None => vessel,
        };
        b.add(vessel, Tissue::Vessel);
    }

    /// `signal` times the bias field at offset `v` (MR only; CT is quantitative).
    fn biased(&self, signal: f64, v: [f64; 3]) -> f64 {
        if self.contrast.is_mr() {
            signal * Self::bias(self.normalised(v))
        } else {
            signal
        }
    }

    fn normalised(&self, v: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|a| v[a] / self.half[a])
    }
}

/// Partial-volume blending of nested structures at one voxel (module doc): each structure
/// replaces the signal by its weight, and labels the voxel where it weighs >= 0.5.
pub(super) struct Blend {
    pub(super) signal: f64,
    pub(super) label: Tissue,
    contrast: Contrast,
}

impl Blend {
    fn new(contrast: Contrast) -> Blend {
        Blend {
            signal: contrast.nominal(Tissue::Background),
            label: Tissue::Background,
            contrast,
        }
    }

    /// Blends `tissue` whose signed distance (voxels, > 0 inside) is `sd`.
    pub(super) fn add(&mut self, sd: f64, tissue: Tissue) {
        let w = ramp(sd);
        self.signal += w * (self.contrast.nominal(tissue) - self.signal);
        if w >= 0.5 {
            self.label = tissue;
        }
    }
}

/// Generates the phantom described by `spec` (module doc) on all available cores. Identical
/// bytes for the same spec on any thread count.
pub fn generate(spec: &PhantomSpec) -> Result<Phantom, PhantomError> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    generate_with_threads(spec, threads)
}

/// [`generate`] on at most `threads` threads (at least one; at most one per k-plane), for
/// benchmarks and for tests that check the output does not depend on the thread count.
pub fn generate_with_threads(spec: &PhantomSpec, threads: usize) -> Result<Phantom, PhantomError> {
    let dims = spec.dims;
    if dims.contains(&0) || !spec.spacing_mm.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(PhantomError::BadSpec {
            dims,
            spacing: spec.spacing_mm,
        });
    }
    let available = crate::volume::host_memory::available_bytes();
    let needed = dims.iter().try_fold(3u64, |a, &d| a.checked_mul(d as u64));
    let too_large = || PhantomError::TooLarge {
        dims,
        bytes: needed,
        available,
    };
    // Checked before allocating: with overcommit, reserving more than the machine has succeeds
    // and the process is killed later while the pages are filled (2048^3 was, with no message).
    if needed.is_none_or(|n| available.is_some_and(|a| n > a)) {
        return Err(too_large());
    }
    let count = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(too_large)?;
    let bytes = count.checked_mul(2).ok_or_else(too_large)?;
    let mut samples = Vec::new();
    let mut labels = Vec::new();
    samples.try_reserve_exact(bytes).map_err(|_| too_large())?;
    labels.try_reserve_exact(count).map_err(|_| too_large())?;
    samples.resize(bytes, 0u8);
    labels.resize(count, 0u8);

    let geometry = Geometry::new(dims, spec.anatomy, spec.contrast);
    let plane = dims[0] * dims[1];
    let threads = threads.clamp(1, dims[2]);
    let slab = dims[2].div_ceil(threads);
    std::thread::scope(|scope| {
        for (s, (sample_slab, label_slab)) in samples
            .chunks_mut(slab * plane * 2)
            .zip(labels.chunks_mut(slab * plane))
            .enumerate()
        {
            let geometry = &geometry;
            scope.spawn(move || fill(geometry, spec, s * slab * plane, sample_slab, label_slab));
        }
    });

    let orientation = Orientation {
        affine: {
            let mut a = [[0.0; 4]; 4];
            for (axis, row) in a.iter_mut().take(3).enumerate() {
                row[axis] = spec.spacing_mm[axis];
                row[3] = -geometry.centre[axis] * spec.spacing_mm[axis];
            }
            a[3][3] = 1.0;
            a
        },
        source: AffineSource::Synthetic,
    };
    let samples =
        Samples::from_le_bytes(crate::volume::SampleKind::I16, samples).map_err(|_| too_large())?;
    let volume = Volume {
        name: "phantom".to_string(),
        dims,
        spacing_mm: spec.spacing_mm,
        orientation,
        samples,
        to_physical: LinearMap::IDENTITY,
        warnings: Vec::new(),
        facts: Default::default(),
    };
    Ok(Phantom {
        volume,
        labels,
        nominal: Nominal::of_contrast(spec.contrast),
        spec: spec.clone(),
    })
}

/// Fills one slab: `samples` (i16 LE) and `labels` for voxels starting at linear index `first`.
fn fill(
    geometry: &Geometry,
    spec: &PhantomSpec,
    first: usize,
    samples: &mut [u8],
    labels: &mut [u8],
) {
    let [nx, ny, _] = spec.dims;
    for (offset, (out, label)) in samples
        .chunks_exact_mut(2)
        .zip(labels.iter_mut())
        .enumerate()
    {
        let index = first + offset;
        let i = index % nx;
        let j = (index / nx) % ny;
        let k = index / (nx * ny);
        let (signal, tissue) = geometry.voxel([i as f64, j as f64, k as f64]);
        let value = if spec.noise {
            let stream = spec.seed ^ (index as u64).wrapping_mul(0xd1b5_4a32_d192_ed03);
            let n1 = normal(mix(stream));
            let n2 = normal(mix(stream ^ 0x5851_f42d_4c95_7f2d));
            spec.contrast.with_noise(signal, n1, n2)
        } else {
            signal
        };
        let stored = value
            .round()
            .clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16;
        out.copy_from_slice(&stored.to_le_bytes());
        *label = tissue as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bias_field_stays_within_its_amplitude() {
        for i in -10..=10 {
            for j in -10..=10 {
                for k in -10..=10 {
                    let b = Geometry::bias([
                        f64::from(i) / 10.0,
                        f64::from(j) / 10.0,
                        f64::from(k) / 10.0,
                    ]);
                    assert!((b - 1.0).abs() <= BIAS_AMPLITUDE + 1e-12, "{b}");
                }
            }
        }
    }
}
