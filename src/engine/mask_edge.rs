//! The tissue histogram of a masked volume: the histogram the tissue analysis reads (peaks,
//! Table-1 row, fit, windows) leaves out the voxels on the edge of a mask (issue 28, item 6).
//!
//! A skull-stripped or otherwise masked scan stores one exact value (its minimum, usually 0)
//! outside the mask. Every voxel on the mask's edge is a partial-volume mix of tissue and that
//! value, a ramp that belongs to no tissue; on thick slices it is a dark mode of its own that the
//! peak finder took for CSF (the MNI152 perturbation study's `thick_lps`: CSF at 38.5 where its
//! truth is 57-101; without the edge 65.4, and every other row unchanged, ACCURACY.md "Peaks
//! under scanner perturbations").
//!
//! Decisions:
//! - Masked = the stored minimum holds at least [`MASKED_SHARE`] of the finite voxels exactly.
//!   Scanners' air is noise, never one exact value over a fifth of the volume; masks are.
//! - Edge = a finite voxel above the minimum with at least one of its six face neighbours at the
//!   minimum. Its histogram is subtracted from the full one, so the background's bin keeps its
//!   count (the analysis finds the background as before) and no other voxel moves.
//! - A host pass, and only where the GPU histogram's first bin could be a mask
//!   ([`may_be_masked`]); an unmasked scan with a quiet background pays for one read of each
//!   sample. The pass reads each sample once into a bit set of minimum voxels, then bins only
//!   the edge voxels (a few percent), both on every core.
//! - The display histogram (the viewer's) and the brain band keep the full histogram: they show
//!   and bound what is in the volume.

use super::prepare::PreparedVolume;
use crate::analysis::{Identity, fits_tissues_for};
use crate::passes::histogram::BINS;
use crate::volume::Volume;

/// Whether the tissue analysis of a volume with `identity` leaves a mask's edge out: structural
/// MR only. An angiogram's or a masked CT's foreground is thin vessels, mostly edge.
pub fn wanted_for(identity: &Identity) -> bool {
    fits_tissues_for(&identity.modality, identity.kind)
}

impl PreparedVolume {
    /// Leaves a mask's edge out of `tissue_histogram` when `volume` (what this was prepared
    /// from) is masked; the caller decides that the modality wants it ([`wanted_for`]). Each
    /// edge voxel binned as the histogram kernel bins it (eq. 1 in f64, then f32).
    pub fn leave_out_mask_edge(&mut self, volume: &Volume) {
        let norm = &self.normalization;
        let (Some((stored_min, _)), Some(imin), Some(imax)) =
            (self.stored_range, norm.imin, norm.imax)
        else {
            return;
        };
        if norm.constant || !may_be_masked(&self.histogram) {
            return;
        }
        let _span = crate::files::trace::span("mask edge out of the tissue histogram", "prepare");
        let map = volume.to_physical;
        let bin = |i: usize| {
            let physical = map.apply(volume.samples.get(i));
            let v = crate::reference::normalize::normalize_value(physical, imin, imax);
            crate::reference::histogram::bin_of(v as f32)
        };
        if let Some(edge) = mask_edge(volume, stored_min, bin) {
            self.tissue_histogram = without_edge(&self.histogram, &edge);
            self.mask_edge_voxels = edge.voxels;
        }
    }
}

/// Share of the finite voxels the minimum must hold exactly for a volume to count as masked.
pub const MASKED_SHARE: f64 = 0.2;

/// Whether `histogram`'s first bin holds enough voxels for the volume to be masked (a cheap
/// test before the host pass; the pass decides with the exact minimum).
pub fn may_be_masked(histogram: &[u32; BINS]) -> bool {
    let finite: u64 = histogram.iter().map(|&c| u64::from(c)).sum();
    finite > 0 && f64::from(histogram[0]) >= MASKED_SHARE * finite as f64
}

/// The edge of a masked volume: how many voxels it holds and their histogram.
#[derive(Clone, Debug, PartialEq)]
pub struct MaskEdge {
    /// Edge voxels (finite, above the minimum, a face neighbour at the minimum).
    pub voxels: u64,
    /// Their histogram, binned by the caller's rule.
    pub histogram: [u32; BINS],
}

/// The edge of `volume` when it is masked at `stored_min` (None when it is not), each edge
/// voxel binned by `bin_of_voxel(index)`. Slabs of slices run on the machine's cores.
pub fn mask_edge(
    volume: &Volume,
    stored_min: f64,
    bin_of_voxel: impl Fn(usize) -> usize + Sync,
) -> Option<MaskEdge> {
    let [nx, ny, nz] = volume.dims;
    let n = nx * ny * nz;
    if n == 0 || volume.samples.len() < n || !stored_min.is_finite() {
        return None;
    }
    let (at_min, finite) = minimum_voxels(volume, n, stored_min);
    let at_min_count: u64 = at_min.iter().map(|w| u64::from(w.count_ones())).sum();
    if finite == 0 || (at_min_count as f64) < MASKED_SHARE * finite as f64 {
        return None;
    }
    let slabs = nz.div_ceil(threads()).max(1);
    let parts: Vec<MaskEdge> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..nz)
            .step_by(slabs)
            .map(|k0| {
                let (at_min, bin_of_voxel) = (&at_min, &bin_of_voxel);
                let slices = k0..(k0 + slabs).min(nz);
                scope.spawn(move || edge_of_slices(volume, at_min, slices, bin_of_voxel))
            })
            .collect();
        workers.into_iter().filter_map(|w| w.join().ok()).collect()
    });
    let mut edge = MaskEdge {
        voxels: 0,
        histogram: [0; BINS],
    };
    for part in parts {
        edge.voxels += part.voxels;
        for (total, count) in edge.histogram.iter_mut().zip(part.histogram) {
            *total = total.saturating_add(count);
        }
    }
    Some(edge)
}

fn threads() -> usize {
    std::thread::available_parallelism().map_or(1, |t| t.get())
}

/// The edge voxels of slices `slices` (`at_min`: a bit per voxel of the whole volume).
fn edge_of_slices(
    volume: &Volume,
    at_min: &[u64],
    slices: std::ops::Range<usize>,
    bin_of_voxel: &impl Fn(usize) -> usize,
) -> MaskEdge {
    let [nx, ny, nz] = volume.dims;
    let is_min = |i: usize| at_min[i / 64] >> (i % 64) & 1 == 1;
    let (sy, sz) = (nx, nx * ny);
    let mut edge = MaskEdge {
        voxels: 0,
        histogram: [0; BINS],
    };
    for k in slices {
        for j in 0..ny {
            for i in 0..nx {
                let at = i + nx * (j + ny * k);
                if is_min(at) || !volume.samples.get(at).is_finite() {
                    continue;
                }
                let touches = (i > 0 && is_min(at - 1))
                    || (i + 1 < nx && is_min(at + 1))
                    || (j > 0 && is_min(at - sy))
                    || (j + 1 < ny && is_min(at + sy))
                    || (k > 0 && is_min(at - sz))
                    || (k + 1 < nz && is_min(at + sz));
                if touches {
                    let b = bin_of_voxel(at).min(BINS - 1);
                    edge.histogram[b] = edge.histogram[b].saturating_add(1);
                    edge.voxels += 1;
                }
            }
        }
    }
    edge
}

/// A bit per voxel, set where the stored sample equals `stored_min`; and the finite voxels.
/// Runs of 64-voxel words on the machine's cores.
fn minimum_voxels(volume: &Volume, n: usize, stored_min: f64) -> (Vec<u64>, u64) {
    let mut bits = vec![0u64; n.div_ceil(64)];
    let words_per_thread = bits.len().div_ceil(threads()).max(1);
    let finite = std::thread::scope(|scope| {
        let workers: Vec<_> = bits
            .chunks_mut(words_per_thread)
            .enumerate()
            .map(|(c, words)| {
                scope.spawn(move || {
                    let mut finite = 0u64;
                    for (w, word) in words.iter_mut().enumerate() {
                        let first = (c * words_per_thread + w) * 64;
                        for b in 0..64.min(n - first) {
                            let s = volume.samples.get(first + b);
                            finite += u64::from(s.is_finite());
                            if s == stored_min {
                                *word |= 1 << b;
                            }
                        }
                    }
                    finite
                })
            })
            .collect();
        workers.into_iter().filter_map(|w| w.join().ok()).sum()
    });
    (bits, finite)
}

/// `histogram` less `edge`'s voxels, bin by bin (never below zero).
pub fn without_edge(histogram: &[u32; BINS], edge: &MaskEdge) -> [u32; BINS] {
    std::array::from_fn(|b| histogram[b].saturating_sub(edge.histogram[b]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{LinearMap, Samples};

    fn volume(dims: [usize; 3], values: Vec<f32>) -> Volume {
        let mut affine = [[0.0; 4]; 4];
        (0..4).for_each(|i| affine[i][i] = 1.0);
        Volume::from_voxels(
            "t",
            dims,
            Samples::from_f32(&values),
            affine,
            LinearMap::IDENTITY,
        )
        .unwrap()
    }

    /// A 6x5x4 volume, 0 outside a 2x2x2 cube of 10 (its 8 voxels all on the edge) with one
    /// voxel of 7 outside the cube touching it.
    fn cube() -> Volume {
        let dims = [6, 5, 4];
        let mut v = vec![0.0f32; 6 * 5 * 4];
        for k in 1..3 {
            for j in 1..3 {
                for i in 1..3 {
                    v[i + 6 * (j + 5 * k)] = 10.0;
                }
            }
        }
        v[3 + 6 * (1 + 5)] = 7.0;
        volume(dims, v)
    }

    #[test]
    fn every_voxel_touching_the_minimum_is_edge_and_keeps_its_bin() {
        let edge = mask_edge(&cube(), 0.0, |i| if i == 3 + 6 * 6 { 7 } else { 10 }).unwrap();
        assert_eq!(edge.voxels, 9);
        assert_eq!(edge.histogram[10], 8);
        assert_eq!(edge.histogram[7], 1);
        let mut full = [0u32; BINS];
        full[0] = 111;
        full[10] = 8;
        full[7] = 1;
        let rest = without_edge(&full, &edge);
        assert_eq!(rest[0], 111, "the background keeps its bin");
        assert_eq!(rest.iter().sum::<u32>(), 111);
    }

    #[test]
    fn interior_voxels_stay_and_an_unmasked_volume_has_no_edge() {
        // A 5x5x5 block of 10 inside a 7x7x7 zero box: its 27 inner voxels are not edge.
        let mut v = vec![0.0f32; 343];
        for k in 1..6 {
            for j in 1..6 {
                for i in 1..6 {
                    v[i + 7 * (j + 7 * k)] = 10.0;
                }
            }
        }
        let edge = mask_edge(&volume([7, 7, 7], v), 0.0, |_| 10).unwrap();
        assert_eq!(edge.voxels, 125 - 27);
        // Noise everywhere: the minimum is one voxel, not a mask.
        let noisy: Vec<f32> = (0..343).map(|i| (i % 17) as f32 + 1.0).collect();
        let min = noisy.iter().copied().fold(f32::INFINITY, f32::min);
        assert!(mask_edge(&volume([7, 7, 7], noisy), f64::from(min), |_| 1).is_none());
    }

    #[test]
    fn the_first_bin_gate_needs_a_fifth_of_the_voxels() {
        let mut h = [0u32; BINS];
        h[0] = 20;
        h[100] = 80;
        assert!(may_be_masked(&h));
        h[0] = 19;
        h[100] = 81;
        assert!(!may_be_masked(&h));
        assert!(!may_be_masked(&[0; BINS]));
    }
}
