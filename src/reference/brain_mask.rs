//! Reading a brain mask that lives on brain extraction's working grid (`passes::brain`: blocks
//! of `factors` voxels), exactly as the raymarch does (classification.glsl `brain_weight`), and
//! its export on the volume's own grid (`morphray derive --maps brain`).
//!
//! Decisions: a volume position `p` (index space) maps to the working grid's continuous index
//! `u = (p + 0.5) / factors - 0.5` (the texture coordinate `(p + 0.5) / (dims * factors)` the
//! shader uses); trilinear with clamp-to-edge, or the nearest cell with nearest interpolation.
//! The export thresholds the trilinear value at 0.5 at each voxel centre, so the exported mask's
//! boundary is the rendered one's half-way level, not a staircase of blocks.

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

#[cfg(test)]
mod tests {
    use super::*;

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
    }
}
