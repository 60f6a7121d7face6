//! Twin of the slice kernel (shaders/slice.comp): a plane of I_norm sampled trilinearly and
//! mapped through a window to grey.
//!
//! Decisions (the kernel's, stated once here):
//! - The plane is given in index space (`scene::slice::IndexGrid`: pixel (x, y) at
//!   `origin + x du + y dv`), so the twin, like the kernel, knows nothing of affines: the f64
//!   world-to-index mapping happens once on the CPU (`SliceGrid::in_index_space`).
//! - A sample inside the closed box `[-0.5, dim - 0.5]` is trilinear between voxel centres with
//!   clamp-to-edge at the half-voxel border (what the raymarch's sampler does); outside it the
//!   pixel is black. Grey = `clamp((v - lo) / (hi - lo), 0, 1)`.
//! - Trilinear weights are computed in full precision (the kernel fetches the eight voxels and
//!   weights them in f32 instead of using the sampler's filter, whose weights are 8-bit on many
//!   GPUs), so the two agree to f32 rounding before the RGBA8 store.

/// Grey levels (0..1, row-major, `width * height`) of the slice `origin + x du + y dv` through
/// `values` (I_norm, x fastest, `dims`), window `[lo, hi]`; None for mismatched sizes or an
/// empty window.
#[allow(clippy::too_many_arguments)]
pub fn slice(
    values: &[f64],
    dims: [usize; 3],
    origin: [f64; 3],
    du: [f64; 3],
    dv: [f64; 3],
    width: usize,
    height: usize,
    window: (f64, f64),
) -> Option<Vec<f64>> {
    let count = dims.iter().product::<usize>();
    if values.len() != count
        || count == 0
        || window.1.partial_cmp(&window.0) != Some(std::cmp::Ordering::Greater)
    {
        return None;
    }
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        for x in 0..width {
            let p: [f64; 3] =
                std::array::from_fn(|a| origin[a] + x as f64 * du[a] + y as f64 * dv[a]);
            out.push(match sample(values, dims, p) {
                Some(v) => ((v - window.0) / (window.1 - window.0)).clamp(0.0, 1.0),
                None => 0.0,
            });
        }
    }
    Some(out)
}

/// Trilinear I_norm at index position `p`, None outside the box `[-0.5, dim - 0.5]`.
pub fn sample(values: &[f64], dims: [usize; 3], p: [f64; 3]) -> Option<f64> {
    let inside = (0..3).all(|a| p[a] >= -0.5 && p[a] <= dims[a] as f64 - 0.5);
    if !inside {
        return None;
    }
    let base = p.map(f64::floor);
    let t: [f64; 3] = std::array::from_fn(|a| p[a] - base[a]);
    let at =
        |a: usize, offset: i64| (base[a] as i64 + offset).clamp(0, dims[a] as i64 - 1) as usize;
    let mut v = 0.0;
    for corner in 0..8 {
        let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
        let w: f64 = (0..3)
            .map(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] })
            .product();
        let (i, j, k) = (at(0, o[0] as i64), at(1, o[1] as i64), at(2, o[2] as i64));
        v += w * values[i + dims[0] * (j + dims[1] * k)];
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_is_reproduced_between_voxels_and_clamped_at_the_border() {
        // I = i / 4 along x on a 5x2x3 grid.
        let dims = [5, 2, 3];
        let values: Vec<f64> = (0..30).map(|n| (n % 5) as f64 / 4.0).collect();
        assert_eq!(sample(&values, dims, [1.5, 0.3, 1.7]), Some(0.375));
        // Half-voxel border: clamp to the edge voxel; beyond it: outside.
        assert_eq!(sample(&values, dims, [-0.5, 0.0, 0.0]), Some(0.0));
        assert_eq!(sample(&values, dims, [4.4, 1.5, 2.5]), Some(1.0));
        assert_eq!(sample(&values, dims, [4.6, 0.0, 0.0]), None);
        let row = slice(
            &values,
            dims,
            [0.0, 0.0, 1.0],
            [0.5, 0.0, 0.0],
            [0.0; 3],
            11,
            1,
            (0.25, 0.75),
        )
        .unwrap();
        let want = [0.0, 0.0, 0.0, 0.25, 0.5, 0.75, 1.0, 1.0, 1.0, 1.0, 0.0];
        for (g, w) in row.iter().zip(want) {
            assert!((g - w).abs() < 1e-12, "{row:?}");
        }
        assert!(
            slice(
                &values,
                dims,
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [0.0; 3],
                1,
                1,
                (0.5, 0.5)
            )
            .is_none()
        );
        assert!(
            slice(
                &values[1..],
                dims,
                [0.0; 3],
                [1.0, 0.0, 0.0],
                [0.0; 3],
                1,
                1,
                (0.0, 1.0)
            )
            .is_none()
        );
    }
}
