//! The classified volume's f64 twin (raymarch.comp's MODE 3 and its CLASSIFIED sample; issue 33
//! item 1): every voxel classified once as a DVR sample at its centre, stored premultiplied and
//! rounded to 8 bits as the RGBA8 volume stores it; a sample is the interpolated volume, its
//! colour the interpolated sum over the interpolated opacity, lit with the sample's normal.

use super::ReferenceRaymarch;
use super::dvr_sample::DvrSample;
use super::sampling::Grid;
use glam::DVec3;

/// An RGBA8 UNORM texel's value of `x` (round to nearest after the clamp, as Vulkan stores it).
fn unorm8(x: f64) -> f64 {
    (x.clamp(0.0, 1.0) * 255.0).round() / 255.0
}

impl ReferenceRaymarch<'_> {
    /// The classified volume: per voxel (x fastest) the premultiplied unlit colour and the
    /// step-corrected opacity of a DVR sample at the voxel's centre, 0 where it has none.
    fn classified_volume(&self) -> Vec<[f64; 4]> {
        let [nx, ny, nz] = self.volume.dims;
        let mut voxels = Vec::with_capacity(nx as usize * ny as usize * nz as usize);
        // Any direction: the stored colour is unlit.
        let direction = DVec3::Z;
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let p = DVec3::new(f64::from(x), f64::from(y), f64::from(z));
                    let texel = self
                        .dvr_sample_with(p, direction, self.opacity_exponent, false)
                        .map_or([0.0; 4], |s| {
                            let a = s.corrected;
                            [s.colour[0] * a, s.colour[1] * a, s.colour[2] * a, a]
                        });
                    voxels.push(texel.map(unorm8));
                }
            }
        }
        voxels
    }

    /// A CLASSIFIED variant's tissue sample at index position `p`, or None where the
    /// interpolated opacity is 0 (the shader's `classified_sample`).
    pub(super) fn classified_sample(&self, p: DVec3, view_direction: DVec3) -> Option<DvrSample> {
        let data = self.classified.get_or_init(|| self.classified_volume());
        let grid = Grid {
            dims: self.volume.dims,
            data,
        };
        let pre = grid.fetch(p, |t| t, self.interpolation);
        let a = pre[3];
        if a <= 0.0 {
            return None;
        }
        let colour = [0, 1, 2].map(|c| (pre[c] / a).min(1.0));
        let (normal, shaded) = if self.shading {
            let normal = self.derivatives(p, 0.0).2;
            (normal, self.lit(colour, normal, view_direction))
        } else {
            (DVec3::ZERO, colour)
        };
        Some(DvrSample {
            value: 0.0,
            f: a,
            colour,
            magnitude: 0.0,
            curvature: 0.0,
            normal,
            opacity: a,
            corrected: a,
            shaded,
        })
    }
}
