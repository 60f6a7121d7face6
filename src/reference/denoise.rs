//! Twins of the denoising passes (`passes::denoise`, shaders/denoise.comp and the Gaussian of
//! shaders/gaussian_axis.comp), in f64, with the same neighbourhoods: clamp-to-edge at the faces,
//! per-axis voxel lengths for the spatial weights.

use super::vesselness::{gaussian_axis, sigma_voxels};

fn at(values: &[f64], dims: [usize; 3], p: [i64; 3]) -> f64 {
    let q = [0, 1, 2].map(|a| p[a].clamp(0, dims[a] as i64 - 1) as usize);
    values[q[0] + dims[0] * (q[1] + dims[1] * q[2])]
}

fn voxels(dims: [usize; 3]) -> impl Iterator<Item = [i64; 3]> {
    (0..dims[2]).flat_map(move |k| {
        (0..dims[1]).flat_map(move |j| (0..dims[0]).map(move |i| [i as i64, j as i64, k as i64]))
    })
}

/// The separable Gaussian of `sigma_mm` (the vesselness scale space's).
pub fn gaussian(
    values: &[f64],
    dims: [usize; 3],
    linear: [[f64; 3]; 3],
    sigma_mm: f64,
) -> Vec<f64> {
    let s = sigma_voxels(linear, sigma_mm);
    let mut out = values.to_vec();
    for (axis, sigma) in s.iter().enumerate() {
        out = gaussian_axis(&out, dims, axis, *sigma);
    }
    out
}

/// The median of each voxel's 3x3x3 neighbourhood.
pub fn median3(values: &[f64], dims: [usize; 3]) -> Vec<f64> {
    voxels(dims)
        .map(|p| {
            let mut v = Vec::with_capacity(27);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        v.push(at(values, dims, [p[0] + dx, p[1] + dy, p[2] + dz]));
                    }
                }
            }
            v.sort_by(f64::total_cmp);
            v[13]
        })
        .collect()
}

/// The bilateral filter: spatial sigma `s` (mm) with `radius` taps per axis, range sigma `r`.
pub fn bilateral(
    values: &[f64],
    dims: [usize; 3],
    spacing: [f64; 3],
    radius: [u32; 3],
    s: f64,
    r: f64,
) -> Vec<f64> {
    let rad = radius.map(|x| x as i64);
    voxels(dims)
        .map(|p| {
            let centre = at(values, dims, p);
            let (mut acc, mut total) = (0.0, 0.0);
            for dz in -rad[2]..=rad[2] {
                for dy in -rad[1]..=rad[1] {
                    for dx in -rad[0]..=rad[0] {
                        let d = [
                            dx as f64 * spacing[0],
                            dy as f64 * spacing[1],
                            dz as f64 * spacing[2],
                        ];
                        let q = at(values, dims, [p[0] + dx, p[1] + dy, p[2] + dz]);
                        let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                        let w = (-d2 / (2.0 * s * s) - (q - centre).powi(2) / (2.0 * r * r)).exp();
                        acc += w * q;
                        total += w;
                    }
                }
            }
            acc / total
        })
        .collect()
}
