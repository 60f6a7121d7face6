//! Texture fetches as Vulkan does them, in f64: clamp-to-edge nearest, trilinear (exact
//! weights) and the tricubic B-spline built from trilinear fetches, for any number of channels.

use super::inputs::ReferenceVolume;
use crate::scene::Interpolation;
use glam::DVec3;

/// A grid of voxel values of any arity, sampled like a clamp-to-edge linear texture. Only built
/// from validated arrays, so every clamped index is in bounds.
#[derive(Clone, Copy)]
pub(super) struct Grid<'a, T> {
    pub(super) dims: [u32; 3],
    pub(super) data: &'a [T],
}

/// One axis of a linear clamp-to-edge fetch: the two texel indices and the weight of the second.
fn axis_taps(dim: u32, x: f64) -> ([usize; 2], f64) {
    let base = x.floor();
    let t = x - base;
    // `as` saturates (NaN -> 0), and `last >= 0` keeps `clamp` from ever seeing min > max.
    let first = base as i64;
    let last = (i64::from(dim) - 1).max(0);
    let clamp = |i: i64| i.clamp(0, last) as usize;
    ([clamp(first), clamp(first.saturating_add(1))], t)
}

fn lerp<const N: usize>(a: [f64; N], b: [f64; N], t: f64) -> [f64; N] {
    // a + t (b - a): exact when a == b, so a constant volume samples to exactly its constant.
    std::array::from_fn(|c| a[c] + t * (b[c] - a[c]))
}

impl<T: Copy> Grid<'_, T> {
    pub(super) fn sample<const N: usize>(
        &self,
        p: DVec3,
        value: impl Fn(T) -> [f64; N],
    ) -> [f64; N] {
        let (xi, tx) = axis_taps(self.dims[0], p.x);
        let (yi, ty) = axis_taps(self.dims[1], p.y);
        let (zi, tz) = axis_taps(self.dims[2], p.z);
        let nx = self.dims[0] as usize;
        let nxy = nx * self.dims[1] as usize;
        // Indices are clamped into the validated grid; the fallback is unreachable and only
        // keeps library code free of panicking paths.
        let fetch = |i: usize, j: usize, k: usize| {
            self.data
                .get(i + nx * j + nxy * k)
                .map_or([0.0; N], |&v| value(v))
        };
        let plane = |k: usize| {
            let row = |j: usize| lerp(fetch(xi[0], j, k), fetch(xi[1], j, k), tx);
            lerp(row(yi[0]), row(yi[1]), ty)
        };
        lerp(plane(zi[0]), plane(zi[1]), tz)
    }
}

impl<T: Copy> Grid<'_, T> {
    pub(super) fn at<const N: usize>(
        &self,
        i: i64,
        j: i64,
        k: i64,
        value: &impl Fn(T) -> [f64; N],
    ) -> [f64; N] {
        let c = |v: i64, d: u32| v.clamp(0, (i64::from(d) - 1).max(0)) as usize;
        let nx = self.dims[0] as usize;
        let nxy = nx * self.dims[1] as usize;
        self.data
            .get(c(i, self.dims[0]) + nx * c(j, self.dims[1]) + nxy * c(k, self.dims[2]))
            .map_or([0.0; N], |&v| value(v))
    }

    /// A fetch with the scene's interpolation: the nearest voxel (centres at integers, ties
    /// rounding up like `floor(p + 0.5)`), trilinear, or the cubic B-spline as its 64-tap
    /// convolution with clamped indices (the shader computes the same sum with 8 linear
    /// fetches).
    pub(super) fn fetch<const N: usize>(
        &self,
        p: DVec3,
        value: impl Fn(T) -> [f64; N],
        interpolation: Interpolation,
    ) -> [f64; N] {
        match interpolation {
            Interpolation::Trilinear => self.sample(p, value),
            Interpolation::Nearest => {
                let r = (p + DVec3::splat(0.5)).floor();
                self.at(r.x as i64, r.y as i64, r.z as i64, &value)
            }
            Interpolation::Tricubic => {
                let base = p.floor();
                let t = p - base;
                let weights = |t: f64| {
                    let (t2, t3) = (t * t, t * t * t);
                    [
                        (1.0 - 3.0 * t + 3.0 * t2 - t3) / 6.0,
                        (4.0 - 6.0 * t2 + 3.0 * t3) / 6.0,
                        (1.0 + 3.0 * t + 3.0 * t2 - 3.0 * t3) / 6.0,
                        t3 / 6.0,
                    ]
                };
                let (wx, wy, wz) = (weights(t.x), weights(t.y), weights(t.z));
                let (bx, by, bz) = (base.x as i64, base.y as i64, base.z as i64);
                let mut acc = [0.0; N];
                for (dz, wz) in wz.iter().enumerate() {
                    for (dy, wy) in wy.iter().enumerate() {
                        for (dx, wx) in wx.iter().enumerate() {
                            let v = self.at(
                                bx + dx as i64 - 1,
                                by + dy as i64 - 1,
                                bz + dz as i64 - 1,
                                &value,
                            );
                            let w = wx * wy * wz;
                            for c in 0..N {
                                acc[c] += w * v[c];
                            }
                        }
                    }
                }
                acc
            }
        }
    }
}

/// A fetch of I_norm at `p` with `interpolation` (see the shader's `sampling.glsl`).
pub fn fetch(volume: &ReferenceVolume<'_>, p: DVec3, interpolation: Interpolation) -> f64 {
    Grid {
        dims: volume.dims,
        data: volume.norm,
    }
    .fetch(p, |v: f64| [v], interpolation)[0]
}

/// Trilinear, clamp-to-edge sample of I_norm at index-space position `p` (voxel centres at
/// integers), exactly what `textureLod(volume, (p + 0.5) / dims, 0)` computes with a `LINEAR`,
/// `CLAMP_TO_EDGE` sampler, with exact weights.
pub fn trilinear(volume: &ReferenceVolume<'_>, p: DVec3) -> f64 {
    let grid = Grid {
        dims: volume.dims,
        data: volume.norm,
    };
    grid.sample(p, |v: f64| [v])[0]
}

impl<T> std::fmt::Debug for Grid<'_, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Grid({:?}, {} values)", self.dims, self.data.len())
    }
}
