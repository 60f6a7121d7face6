//! The scalp-bridge cut of brain extraction's component step (coarse grid, host; the engine and
//! the f64 twin call the same function, as for `brain_components`).
//!
//! Why: on the clinical T2 head in ../shared/data/real (1x1x2 mm slices, the vertex cut off by
//! the slab) the eroded band's largest component runs through partial-volume bridges across the
//! thin, tangentially cut skull into the scalp, and the "brain" came out as the whole head
//! (2180 cm^3, `derive --maps brain`, this machine). On T2 the scalp's fat is as bright as CSF,
//! so no band excludes it; what does is depth: the brain lies under the scalp and the skull.
//!
//! Decisions:
//! - The head is what the foreground (`S > head_lo`, pooled ANY per cell) encloses
//!   (`enclosed_cells`), so skull, sinuses and ventricles inside it are head. The depth of a
//!   voxel is its distance to the nearest voxel of a cell outside the head, inside the grid; the
//!   space beyond the grid is not a surface (a slab that cuts through the head does not make its
//!   cut face skin). The coarse head is up to a cell larger than the fine one (ANY-pool), so
//!   depths read up to a cell deep.
//! - The cut: smoothed values no deeper than `scalp_mm` become 0 (below every band), and the
//!   chain runs again from the band on that volume: erosion, component, re-growth and closing
//!   all stay out of the scalp, however it is bridged.
//! - The cut is the second try: the chain runs first as without it; when its mask leaves an
//!   ambiguous share of the tissue band outside (`DecisionCells::bridge_suspected`: more than a
//!   skull-stripped brain leaves, less than a head whose mask stopped at the brain), the
//!   component ran into the scalp, and the chain runs again on the cut volume. Always cutting
//!   would cost a skull-stripped brain, whose surface is the head's, its outer `scalp_mm`.
//! - `scalp_mm` 8: a scipy prototype on the fine grid (`tools/figures/brain_depth_prototype.py`,
//!   this machine) that kept the eroded core
//!   11 mm deep (the band 6.5 mm deep, with the 4.5 mm erosion) took T2w's mask from 2314 to
//!   1841 cm^3, inside its skull on every slice looked at; 8 mm allows for the coarse head's
//!   extra depth of up to a cell.

use super::brain::squared_distance;
use super::brain_components::{enclosed_cells, slab_axis};

/// The head's cells (0/1): those the foreground cells enclose (module doc). `cell_mm` is a
/// cell's edge per axis in mm (its largest is the slab axis of the hole test).
pub fn head_cells(foreground: &[u8], dims: [usize; 3], cell_mm: [f64; 3]) -> Vec<u8> {
    enclosed_cells(foreground, dims, slab_axis(cell_mm))
}

/// `smoothed` (voxels of `dims`, `spacing` mm) with every voxel no deeper than `scalp_mm` under
/// the head (`head` cells of `f` voxels) set to 0: `D > scalp_mm^2 ? S : 0`, `D` the squared
/// distance to the voxels of the cells outside the head, as the GPU's DEPTH_CUT step.
pub fn depth_cut(
    smoothed: &[f64],
    head: &[u8],
    dims: [usize; 3],
    spacing: [f64; 3],
    f: usize,
    scalp_mm: f64,
) -> Vec<f64> {
    let f = f.max(1);
    let cdims = dims.map(|n| n.div_ceil(f));
    let outside: Vec<u8> = (0..smoothed.len())
        .map(|i| {
            let p = [
                i % dims[0],
                (i / dims[0]) % dims[1],
                i / (dims[0] * dims[1]),
            ];
            let c = p[0] / f + cdims[0] * (p[1] / f + cdims[1] * (p[2] / f));
            u8::from(head.get(c).is_none_or(|&h| h == 0))
        })
        .collect();
    let depth2 = squared_distance(&outside, dims, spacing, scalp_mm);
    let t = scalp_mm * scalp_mm;
    smoothed
        .iter()
        .zip(&depth2)
        .map(|(&v, &d2)| if d2 > t { v } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn idx(p: [usize; 3], d: [usize; 3]) -> usize {
        p[0] + d[0] * (p[1] + d[1] * p[2])
    }

    #[test]
    fn the_shell_under_the_surface_is_cut_and_the_slab_faces_are_not_skin() {
        // 24x24x6 voxels of 1x1x2 mm in cells of 2: the head's cells are x in 1..11 (voxels
        // 2..22); everything else is outside.
        let d = [24, 24, 6];
        let cd = [12, 12, 3];
        let head: Vec<u8> = (0..12 * 12 * 3)
            .map(|c| u8::from((1..11).contains(&(c % 12))))
            .collect();
        assert_eq!(
            head_cells(&head, cd, [2.0, 2.0, 4.0]),
            head,
            "nothing to enclose"
        );
        let s = vec![1.0; 24 * 24 * 6];
        let cut = depth_cut(&s, &head, d, [1.0, 1.0, 2.0], 2, 3.0);
        // x = 2..4 are within 3 mm of voxel x = 1 (outside): cut; x = 5 is 4 mm deep: kept.
        assert_eq!(cut[idx([4, 12, 3], d)], 0.0);
        assert_eq!(cut[idx([5, 12, 3], d)], 1.0);
        // The first and last slices are as deep as the middle one: beyond the grid is not skin.
        assert_eq!(cut[idx([12, 12, 0], d)], 1.0);
        assert_eq!(cut[idx([12, 12, 5], d)], 1.0);
        // Outside the head: cut.
        assert_eq!(cut[idx([0, 12, 3], d)], 0.0);
    }

    #[test]
    fn a_ring_of_scalp_encloses_the_head() {
        // A ring of foreground cells in every slice: the head is the ring and what it holds.
        let d = [9, 9, 2];
        let fg: Vec<u8> = (0..81 * 2i32)
            .map(|c| {
                let (x, y) = (c % 9 - 4, (c / 9) % 9 - 4);
                u8::from(x.abs().max(y.abs()) == 3)
            })
            .collect();
        let head = head_cells(&fg, d, [2.0, 2.0, 4.0]);
        assert_eq!(head[idx([4, 4, 0], d)], 1);
        assert_eq!(head[idx([0, 4, 1], d)], 0);
    }
}
