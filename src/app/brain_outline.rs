//! The brain mask's outline on the slice panels (issue 27 item 3): a host copy of the mask,
//! read back once per extraction, and the outline drawn over each slice on the host.
//!
//! Decisions:
//! - No kernel of its own: the slices are already read back and uploaded as egui textures
//!   (`viewer/slices.rs`), a few hundred pixels a side, so testing each pixel against the mask
//!   on the host costs well under a millisecond per slice, and the outline can never disagree
//!   with the picture: the mask is read exactly as the raymarch reads it
//!   (`reference::brain_mask::WorkingMask::at`, trilinear on the working grid), inside where
//!   that value is at least 0.5, as `morphray derive --maps brain` exports it.
//! - The host copy is made on the loader thread right after the extraction (the mask is not on
//!   screen yet, so the readback's layout transitions race with no frame), as f64 on the working
//!   grid: 8 bytes a working voxel, 12.5 MB for a 256x256x190 head at 1 mm (factors 2).
//! - The outline is the inside pixels with an outside 4-neighbour (or on the slice's edge): one
//!   pixel wide in slice pixels whatever the zoom, in one colour no grey slice has.

use crate::engine::BrainMask;
use crate::engine::readback::read_image;
use crate::gpu::{Access, Device, GpuResult};
use crate::reference::brain_mask::WorkingMask;
use crate::scene::slice::IndexGrid;

/// The outline's colour on the slices (RGB).
pub const OUTLINE_COLOUR: [u8; 3] = [255, 0, 200];

/// A host copy of a brain mask on its working grid.
#[derive(Clone, Debug, PartialEq)]
pub struct BrainOutline {
    /// 0..1 per working voxel, x fastest.
    values: Vec<f64>,
    /// Working grid dimensions.
    dims: [usize; 3],
    /// Block edge per axis (volume voxels per working voxel).
    factors: [u32; 3],
}

impl BrainOutline {
    /// A mask of `dims` working voxels of `factors` volume voxels each; None when `values` does
    /// not hold `dims`.
    pub fn new(values: Vec<f64>, dims: [usize; 3], factors: [u32; 3]) -> Option<BrainOutline> {
        let count = dims.iter().try_fold(1usize, |n, &d| n.checked_mul(d))?;
        (values.len() == count && count > 0 && !factors.contains(&0)).then_some(BrainOutline {
            values,
            dims,
            factors,
        })
    }

    /// Reads `mask` back (None when the extraction found no component). Call before the mask
    /// is used by any frame (module decisions).
    pub fn read(device: &Device, mask: &BrainMask) -> GpuResult<Option<BrainOutline>> {
        let Some(image) = &mask.image else {
            return Ok(None);
        };
        let data = read_image(device, image, Access::ComputeSampled)?;
        let values = data.values.iter().map(|&v| f64::from(v)).collect();
        let dims = data.extent.map(|d| d as usize);
        Ok(BrainOutline::new(values, dims, mask.factors))
    }

    fn working(&self) -> WorkingMask<'_> {
        WorkingMask {
            values: &self.values,
            dims: self.dims,
            factors: self.factors,
        }
    }

    /// True when volume index position `p` is inside the volume of `dims` voxels and the brain.
    pub fn inside(&self, p: [f64; 3], dims: [u32; 3]) -> bool {
        let in_box = (0..3).all(|a| p[a] >= -0.5 && p[a] <= f64::from(dims[a]) - 0.5);
        in_box && self.working().at(p, false) >= 0.5
    }

    /// Draws the outline over `rgba` (the slice `grid` of a volume of `dims` voxels, in index
    /// space); returns how many pixels it coloured.
    pub fn draw(&self, rgba: &mut [u8], grid: &IndexGrid, dims: [u32; 3]) -> usize {
        let (w, h) = (grid.width as usize, grid.height as usize);
        if rgba.len() < w * h * 4 {
            return 0;
        }
        let inside: Vec<bool> = (0..w * h)
            .map(|n| {
                let (x, y) = ((n % w) as f64, (n / w) as f64);
                let p = std::array::from_fn(|a| grid.origin[a] + x * grid.du[a] + y * grid.dv[a]);
                self.inside(p, dims)
            })
            .collect();
        let mut drawn = 0;
        for y in 0..h {
            for x in 0..w {
                let n = y * w + x;
                let edge = x == 0
                    || y == 0
                    || x + 1 == w
                    || y + 1 == h
                    || !inside[n - 1]
                    || !inside[n + 1]
                    || !inside[n - w]
                    || !inside[n + w];
                if inside[n] && edge {
                    rgba[4 * n..4 * n + 3].copy_from_slice(&OUTLINE_COLOUR);
                    drawn += 1;
                }
            }
        }
        drawn
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4x4x1 working grid of 2x2x1 blocks with the middle 2x2 working voxels inside: the
    /// volume's voxels 2..5 (trilinear 0.5 level half-way between block centres).
    fn square() -> BrainOutline {
        let mut values = vec![0.0; 16];
        for (j, i) in [(1, 1), (1, 2), (2, 1), (2, 2)] {
            values[i + 4 * j] = 1.0;
        }
        BrainOutline::new(values, [4, 4, 1], [2, 2, 1]).unwrap()
    }

    #[test]
    fn the_outline_rings_the_inside_one_pixel_wide() {
        let mask = square();
        let grid = IndexGrid {
            origin: [0.0, 0.0, 0.0],
            du: [1.0, 0.0, 0.0],
            dv: [0.0, 1.0, 0.0],
            width: 8,
            height: 8,
        };
        let mut rgba = vec![0u8; 8 * 8 * 4];
        let drawn = mask.draw(&mut rgba, &grid, [8, 8, 1]);
        let coloured =
            |x: usize, y: usize| rgba[4 * (y * 8 + x)..4 * (y * 8 + x) + 3] == OUTLINE_COLOUR;
        // Inside: x and y in 2..=5 (the mask's 0.5 level lies at 1.5 and 5.5); the ring is
        // those with an outside neighbour, the 2x2 core (3..=4) stays untouched.
        for y in 0..8 {
            for x in 0..8 {
                let inside = (2..=5).contains(&x) && (2..=5).contains(&y);
                let core = (3..=4).contains(&x) && (3..=4).contains(&y);
                assert_eq!(coloured(x, y), inside && !core, "pixel {x},{y}");
            }
        }
        assert_eq!(drawn, 12);
    }

    #[test]
    fn outside_the_volume_and_bad_shapes_draw_nothing() {
        let mask = square();
        // A row of pixels beyond the volume's box along y: clamp-to-edge would read the mask,
        // the box test must not.
        let grid = IndexGrid {
            origin: [0.0, 9.0, 0.0],
            du: [1.0, 0.0, 0.0],
            dv: [0.0, 1.0, 0.0],
            width: 8,
            height: 2,
        };
        let mut rgba = vec![0u8; 8 * 2 * 4];
        assert_eq!(mask.draw(&mut rgba, &grid, [8, 8, 1]), 0);
        assert!(rgba.iter().all(|&b| b == 0));
        assert!(BrainOutline::new(vec![0.0; 3], [2, 2, 1], [1, 1, 1]).is_none());
        assert!(BrainOutline::new(vec![0.0; 4], [2, 2, 1], [1, 0, 1]).is_none());
        // A buffer too small for the grid is left alone.
        assert_eq!(mask.draw(&mut [0u8; 4], &grid, [8, 8, 1]), 0);
    }
}
