//! Reading a brain mask that lives on brain extraction's working grid (`passes::brain`: blocks
//! of `factors` voxels), exactly as the raymarch does (classification.glsl `brain_weight`), and
//! its export on the volume's own grid (`morphray derive --maps brain`).
//!
//! Decisions: a volume position `p` (index space) maps to the working grid's continuous index
//! `u = (p + 0.5) / factors - 0.5` (the texture coordinate `(p + 0.5) / (dims * factors)` the
//! shader uses); trilinear with clamp-to-edge, or the nearest cell with nearest interpolation.
//! The export thresholds the trilinear value at 0.5 at each voxel centre, so the exported mask's
//! boundary is the rendered one's half-way level, not a staircase of blocks.
//! - Empty-space skipping (`BrainCells::bricks_inside`): a brick of the volume may hold brain
//!   when any coarse brain cell (closed or filled: a superset of the mask's working voxels) lies
//!   in the working voxels its samples' trilinear footprints reach (from the brick's halo's
//!   first voxel to one working voxel past its last). Outside those bricks the mask reads 0 everywhere, so the
//!   tissues (which the raymarch weighs by the mask) cannot show there.

/// The mask on its working grid.
#[derive(Clone, Copy, Debug)]
pub struct WorkingMask<'a> {
    /// 0 or 1 per working voxel, x fastest.
    pub values: &'a [f64],
    /// Working grid dimensions.
    pub dims: [usize; 3],
    /// Block edge per axis.
    pub factors: [u32; 3],
}

impl WorkingMask<'_> {
    /// The mask at volume position `p`, trilinear (or nearest when `nearest`).
    pub fn at(&self, p: [f64; 3], nearest: bool) -> f64 {
        let u: [f64; 3] = std::array::from_fn(|a| (p[a] + 0.5) / f64::from(self.factors[a]) - 0.5);
        let d = self.dims;
        if d.contains(&0) || self.values.len() < d[0] * d[1] * d[2] {
            return 0.0;
        }
        let clamp = |v: i64, a: usize| v.clamp(0, d[a] as i64 - 1) as usize;
        let at = |i: [usize; 3]| self.values[i[0] + d[0] * (i[1] + d[1] * i[2])];
        if nearest {
            let i: [usize; 3] = std::array::from_fn(|a| clamp((u[a] + 0.5).floor() as i64, a));
            return at(i);
        }
        let base: [f64; 3] = u.map(f64::floor);
        let t: [f64; 3] = std::array::from_fn(|a| u[a] - base[a]);
        let mut sum = 0.0;
        for corner in 0..8 {
            let mut w = 1.0;
            let mut i = [0usize; 3];
            for a in 0..3 {
                let high = corner >> a & 1 == 1;
                w *= if high { t[a] } else { 1.0 - t[a] };
                i[a] = clamp(base[a] as i64 + i64::from(high), a);
            }
            sum += w * at(i);
        }
        sum
    }

    /// The mask on the volume's grid of `fine` voxels by nearest lookup: each voxel takes its
    /// block's value (`at(p, true)` is the block `p / factors`), one read a voxel with no
    /// arithmetic, for host passes on the first pixel's path (the tissue fit's histogram: 9 M
    /// trilinear reads took 251 ms of chris_t1's, the "tissue fit in the brain mask" span of
    /// `morphray render chris_t1.nii.gz --trace T.json`, release, this machine; 31 ms by
    /// nearest lookup). Differs from [`Self::export`]
    /// only in the half-block rim the trilinear threshold rounds.
    pub fn export_nearest(&self, fine: [usize; 3]) -> Vec<u8> {
        let d = self.dims;
        let total = fine[0] * fine[1] * fine[2];
        if d.contains(&0) || self.values.len() < d[0] * d[1] * d[2] {
            return vec![0; total];
        }
        let block = |p: usize, a: usize| (p / self.factors[a].max(1) as usize).min(d[a] - 1);
        let columns: Vec<usize> = (0..fine[0]).map(|i| block(i, 0)).collect();
        let mut out = Vec::with_capacity(total);
        for k in 0..fine[2] {
            for j in 0..fine[1] {
                let row = d[0] * (block(j, 1) + d[1] * block(k, 2));
                out.extend(
                    columns
                        .iter()
                        .map(|&q| u8::from(self.values[row + q] >= 0.5)),
                );
            }
        }
        out
    }

    /// The mask on the volume's grid of `fine` voxels: 1 where the trilinear value is at least
    /// 0.5 at the voxel centre.
    pub fn export(&self, fine: [usize; 3]) -> Vec<u8> {
        let mut out = Vec::with_capacity(fine[0] * fine[1] * fine[2]);
        for k in 0..fine[2] {
            for j in 0..fine[1] {
                for i in 0..fine[0] {
                    let v = self.at([i as f64, j as f64, k as f64], false);
                    out.push(u8::from(v >= 0.5));
                }
            }
        }
        out
    }
}

/// The brain's coarse cells, as extraction leaves them (`reference::brain` steps 10 and 11).
#[derive(Clone, Debug, PartialEq)]
pub struct BrainCells {
    /// Coarse grid dimensions.
    pub dims: [usize; 3],
    /// Cell edge in working voxels.
    pub cell: usize,
    /// Block edge per axis (volume voxels per working voxel).
    pub factors: [u32; 3],
    /// 1 where the closed mask has a voxel or the hole filling set the cell, x fastest.
    pub set: Vec<u8>,
}

impl BrainCells {
    /// Cells `[first, last]` along `axis` that a brick `index` of `side` voxels with `halo`
    /// voxels each side reaches through the mask's trilinear footprint (module doc).
    fn cell_span(&self, axis: usize, index: u32, side: u32, halo: u32) -> (usize, usize) {
        let f = f64::from(self.factors[axis].max(1));
        let lo = f64::from(index * side) - f64::from(halo);
        let hi = f64::from((index + 1) * side) + f64::from(halo);
        // Working voxel coordinate u = (p + 0.5) / f - 0.5; the footprint is floor(u) and the next.
        let first = ((lo + 0.5) / f - 0.5).floor();
        let last = ((hi + 0.5) / f - 0.5).floor() + 1.0;
        let cell = self.cell.max(1) as f64;
        let clamp = |w: f64| ((w.max(0.0) / cell).floor() as usize).min(self.dims[axis].max(1) - 1);
        (clamp(first), clamp(last))
    }

    /// Whether each brick of a grid of `grid` bricks (`side` voxels, `halo` voxels of sample
    /// footprint) may see the mask above 0, x fastest. All true when the cells do not fill their
    /// dims (nothing is ruled out on bad input).
    pub fn bricks_inside(&self, grid: [u32; 3], side: u32, halo: u32) -> Vec<bool> {
        let bricks = grid.iter().map(|&g| g as usize).product::<usize>();
        let d = self.dims;
        if d.contains(&0) || self.set.len() != d[0] * d[1] * d[2] {
            return vec![true; bricks];
        }
        let spans: [Vec<(usize, usize)>; 3] = std::array::from_fn(|a| {
            (0..grid[a])
                .map(|i| self.cell_span(a, i, side, halo))
                .collect()
        });
        let mut out = Vec::with_capacity(bricks);
        for &(z0, z1) in &spans[2] {
            for &(y0, y1) in &spans[1] {
                for &(x0, x1) in &spans[0] {
                    let any = (z0..=z1).any(|z| {
                        (y0..=y1).any(|y| {
                            let row = d[0] * (y + d[1] * z);
                            self.set[row + x0..=row + x1].iter().any(|&c| c != 0)
                        })
                    });
                    out.push(any);
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_brick_is_inside_when_the_mask_can_reach_its_samples() {
        // 1 x 1 x 1 mm voxels in blocks of 2, cells of 2 working voxels (4 voxels): one brain
        // cell at x = 3 (voxels 12..16) on a 6-cell row.
        let cells = BrainCells {
            dims: [6, 1, 1],
            cell: 2,
            factors: [2, 1, 1],
            set: vec![0, 0, 0, 1, 0, 0],
        };
        // Bricks of 4 voxels with a 2-voxel halo: brick 3 holds the cell, bricks 2 and 4 reach
        // it with their halos; brick 1 (samples below voxel 10, working voxels up to 5) and
        // bricks 0 and 5 cannot see it.
        let inside = cells.bricks_inside([6, 1, 1], 4, 2);
        assert_eq!(inside, [false, false, true, true, true, false]);
        // Every brick whose samples the trilinear mask reaches is inside: check against the
        // mask itself, with the cell's working voxels 6 and 7 set.
        let mut values = [0.0; 12];
        (values[6], values[7]) = (1.0, 1.0);
        let mask = WorkingMask {
            values: &values,
            dims: [12, 1, 1],
            factors: [2, 1, 1],
        };
        for (b, &inside) in inside.iter().enumerate() {
            let seen = (0..=80)
                .map(|t| (b * 4) as f64 - 2.0 + 8.0 * f64::from(t) / 80.0)
                .any(|p| mask.at([p, 0.0, 0.0], false) > 0.0);
            assert!(inside || !seen, "brick {b} sees the mask but is ruled out");
        }
        // Cells that do not fill their dims rule nothing out.
        let bad = BrainCells {
            set: vec![0; 5],
            ..cells
        };
        assert!(bad.bricks_inside([6, 1, 1], 4, 2).iter().all(|&b| b));
    }

    #[test]
    fn block_centres_read_their_block_and_the_export_keeps_a_solid_block() {
        // A 4x1x1 working grid of 2-voxel blocks: 0 1 1 0.
        let values = [0.0, 1.0, 1.0, 0.0];
        let m = WorkingMask {
            values: &values,
            dims: [4, 1, 1],
            factors: [2, 1, 1],
        };
        // Voxels 2 and 3 are block 1; between their centres (2.5) the mask is 1.
        assert_eq!(m.at([2.5, 0.0, 0.0], false), 1.0);
        // Voxel 1's centre is a quarter block from block 1's centre: 0.75 of it.
        assert!((m.at([1.0, 0.0, 0.0], false) - 0.25).abs() < 1e-12);
        assert_eq!(m.at([1.0, 0.0, 0.0], true), 0.0);
        assert_eq!(m.export([8, 1, 1]), [0, 0, 1, 1, 1, 1, 0, 0]);
        // Nearest: each voxel its block, as `at(p, true)`.
        assert_eq!(m.export_nearest([8, 1, 1]), [0, 0, 1, 1, 1, 1, 0, 0]);
        for p in 0..8 {
            let nearest = m.at([p as f64, 0.0, 0.0], true);
            assert_eq!(f64::from(m.export_nearest([8, 1, 1])[p]), nearest);
        }
    }
}
