//! f64 twin of `shaders/include/labels.glsl`: a label overlay's samples in the DVR raymarch.
//!
//! Same rules as the shader: the label of the voxel nearest to the sample (`floor(p + 0.5)`,
//! 0 outside the grid), its RGBA8 table entry decoded as `unpackUnorm4x8` does (byte / 255), its
//! opacity per mm corrected for the step, its normal (with shading) the central difference of
//! the label's indicator over the six neighbouring voxels mapped to world by the gradient
//! matrix. The positions are f64 here and f32 on the GPU, so a sample within f32 rounding of a
//! voxel boundary can take the neighbouring label: comparisons allow for a few such pixels.

use super::formulas::opacity_correct;
use glam::{DMat3, DVec3};

/// A label map on the volume's grid and its colour table (`engine::label_colours`).
#[derive(Clone, Copy, Debug)]
pub struct ReferenceLabels<'a> {
    /// One label per voxel, x fastest.
    pub values: &'a [u16],
    /// RGBA8 per label value (alpha: opacity per mm).
    pub colours: &'a [u32],
}

impl ReferenceLabels<'_> {
    fn label_at(&self, dims: [usize; 3], q: [i64; 3]) -> u16 {
        let inside = (0..3).all(|a| q[a] >= 0 && q[a] < dims[a] as i64);
        if !inside {
            return 0;
        }
        let [i, j, k] = q.map(|c| c as usize);
        self.values[i + dims[0] * (j + dims[1] * k)]
    }

    /// The colour (unshaded), step-corrected opacity and world shading normal (zero without
    /// `shading`) the label at index position `p` adds, or None. The caller shades with the
    /// scene's lighting model, as the shader's `lit` does.
    pub fn sample(
        &self,
        dims: [usize; 3],
        p: DVec3,
        gradient_to_world: DMat3,
        shading: bool,
        opacity_exponent: f64,
    ) -> Option<([f64; 3], f64, DVec3)> {
        let q = [p.x, p.y, p.z].map(|c| (c + 0.5).floor() as i64);
        let label = self.label_at(dims, q);
        let word = *self
            .colours
            .get(usize::from(label))
            .filter(|_| label != 0)?;
        let [r, g, b, a] = word.to_le_bytes().map(|byte| f64::from(byte) / 255.0);
        if a <= 0.0 {
            return None;
        }
        let mut normal = DVec3::ZERO;
        if shading {
            let mut d = DVec3::ZERO;
            for axis in 0..3 {
                let (mut up, mut down) = (q, q);
                up[axis] += 1;
                down[axis] -= 1;
                let inside = |n: [i64; 3]| f64::from(u8::from(self.label_at(dims, n) == label));
                d[axis] = inside(up) - inside(down);
            }
            normal = gradient_to_world * (0.5 * d);
        }
        Some(([r, g, b], opacity_correct(a, opacity_exponent), normal))
    }
}
