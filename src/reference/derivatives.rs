//! Twin of the derivative kernels: world-space gradient, Hessian and directional curvature of
//! the normalized volume (the paper's eqs. 2 and 3).
//!
//! Decisions (the GPU kernels use exactly these stencils):
//! - Stencils act in index space, on voxel centres, x fastest (`i + nx * (j + ny * k)`):
//!   - first derivative along axis `a`: `lo = max(p_a - 1, 0)`, `hi = min(p_a + 1, n_a - 1)`,
//!     `d_a = (I[hi] - I[lo]) / (hi - lo)`, and 0 when `n_a == 1`. Central inside, one-sided at
//!     the borders, so a linear ramp has its exact slope everywhere, borders included.
//!   - second derivative along `a`: 0 when `n_a < 3`; else `c = clamp(p_a, 1, n_a - 2)` and
//!     `d_aa = I[c+1] - 2 I[c] + I[c-1]`: the centre is shifted inward at the borders, which keeps
//!     the three-point stencil (exact for quadratics) instead of inventing values outside.
//!   - mixed `a != b`: with `lo`/`hi` of both axes as for the first derivative,
//!     `d_ab = (I[hi_a,hi_b] - I[hi_a,lo_b] - I[lo_a,hi_b] + I[lo_a,lo_b]) / ((hi_a-lo_a)(hi_b-lo_b))`,
//!     and 0 when either axis has one voxel. This four-point formula is exact for every
//!     quadratic, whatever the (one-sided or central) step sizes.
//! - World space: with `A` the 3x3 linear part of the index-to-world affine (columns = world
//!   displacement of one index step), `g_world = A^-T g_idx` and `H_world = A^-T H_idx A^-1`
//!   ([`IndexToWorld`]). A singular or non-finite `A` is a typed error, never a silent fallback.
//!   Units: `I_norm` per mm and per mm².
//! - Curvature `k = ĝᵀ H ĝ` with `ĝ = g / |g|`, set to 0 where `|g| <= tau`: the normalized
//!   gradient is undefined at 0 and pure noise just above it (NUMERICS.md). The default
//!   [`DEFAULT_TAU`] is `1e-6` `I_norm`/mm; the GPU uses the same tau (in f32), so the two agree
//!   except for voxels whose `|g|` lies within rounding of tau.
//! - Only what [`DerivativeOptions`] asks for is computed and stored. Curvature needs the
//!   gradient, which is then computed per voxel but stored only if requested too.
//! - The input is the normalized volume in f64 (finite by construction of eq. 1); non-finite
//!   inputs would propagate into the outputs of their neighbours.
//!
//! Where the stencils are exact (checked in tests/reference.rs): a linear ramp gives the exact
//! gradient and `H = 0` everywhere; a quadratic `c |x - x0|^2` gives `H = 2c I` everywhere
//! (borders included, thanks to the shifted centre), hence `k = 2c` at every voxel whose gradient
//! passes the tau guard, while its gradient is exact only in the interior (the one-sided border
//! difference of a quadratic is off by `c * step`).

use std::fmt;

/// Default gradient-magnitude guard for curvature, in `I_norm` per mm.
///
/// Why 1e-6: the smallest non-zero central difference of a 16-bit volume normalized over its
/// full range is `1 / 65535 / 2 = 7.6e-6` per voxel, so on grids up to about 7 mm no real edge of
/// 16-bit data falls below tau, while exact plateaus (0) and rounding dust (f32 `I_norm` differs
/// by about 1e-7 at most between equal voxels rounded differently) do.
pub const DEFAULT_TAU: f64 = 1e-6;

/// Which derivative outputs to compute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DerivativeOptions {
    /// Compute and store the world gradient and its magnitude.
    pub gradient: bool,
    /// Compute and store the world Hessian and the directional curvature.
    pub hessian: bool,
    /// Curvature is 0 where `|g| <= tau` (`I_norm` per mm).
    pub tau: f64,
}

impl Default for DerivativeOptions {
    /// Everything, with [`DEFAULT_TAU`].
    fn default() -> Self {
        DerivativeOptions {
            gradient: true,
            hessian: true,
            tau: DEFAULT_TAU,
        }
    }
}

/// Why derivatives could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DerivativeError {
    /// The value slice does not hold `dims[0] * dims[1] * dims[2]` values.
    #[error(
        "the volume has {len} values but dimensions {dims:?} need {}; pass the volume's own dimensions",
        ExpectedLen(*.expected)
    )]
    LengthMismatch {
        /// Length of the value slice.
        len: usize,
        /// Dimensions given.
        dims: [usize; 3],
        /// Their product, `None` when it overflows `usize`.
        expected: Option<usize>,
    },
    /// A voxel index outside the volume.
    #[error("voxel {p:?} lies outside a volume of {dims:?} voxels")]
    OutOfRange {
        /// The index asked for.
        p: [usize; 3],
        /// The volume's dimensions.
        dims: [usize; 3],
    },
    /// The index-to-world matrix has no usable inverse.
    #[error(
        "the index-to-world matrix {linear:?} is singular or not finite; repair the volume's affine (sform/qform) or build it from the voxel spacing"
    )]
    SingularAffine {
        /// The rejected 3x3 linear part (row-major).
        linear: [[f64; 3]; 3],
    },
}

/// Formats the expected length of [`DerivativeError::LengthMismatch`].
struct ExpectedLen(Option<usize>);

impl fmt::Display for ExpectedLen {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(n) => write!(f, "{n}"),
            None => write!(f, "more than usize::MAX"),
        }
    }
}

/// A symmetric 3x3 matrix (a Hessian), stored as its six distinct entries.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sym3 {
    /// Entry (0, 0).
    pub xx: f64,
    /// Entry (1, 1).
    pub yy: f64,
    /// Entry (2, 2).
    pub zz: f64,
    /// Entries (0, 1) and (1, 0).
    pub xy: f64,
    /// Entries (0, 2) and (2, 0).
    pub xz: f64,
    /// Entries (1, 2) and (2, 1).
    pub yz: f64,
}

impl Sym3 {
    /// The full row-major matrix.
    pub fn to_matrix(&self) -> [[f64; 3]; 3] {
        [
            [self.xx, self.xy, self.xz],
            [self.xy, self.yy, self.yz],
            [self.xz, self.yz, self.zz],
        ]
    }

    /// The symmetric part of a full matrix.
    pub fn from_matrix(m: &[[f64; 3]; 3]) -> Self {
        Sym3 {
            xx: m[0][0],
            yy: m[1][1],
            zz: m[2][2],
            xy: 0.5 * (m[0][1] + m[1][0]),
            xz: 0.5 * (m[0][2] + m[2][0]),
            yz: 0.5 * (m[1][2] + m[2][1]),
        }
    }

    /// Sum of the diagonal (the Laplacian, for a Hessian).
    pub fn trace(&self) -> f64 {
        self.xx + self.yy + self.zz
    }

    /// The quadratic form `vᵀ M v`.
    pub fn quadratic_form(&self, v: [f64; 3]) -> f64 {
        let [x, y, z] = v;
        self.xx * x * x
            + self.yy * y * y
            + self.zz * z * z
            + 2.0 * (self.xy * x * y + self.xz * x * z + self.yz * y * z)
    }
}

/// The inverse of the index-to-world linear part, which maps index-space derivatives to world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IndexToWorld {
    linear: [[f64; 3]; 3],
    inverse: [[f64; 3]; 3],
}

impl IndexToWorld {
    /// From the row-major 3x3 linear part `A` of the index-to-world affine
    /// ([`crate::volume::Orientation::linear_part`]).
    ///
    /// Rejects non-finite entries and matrices whose determinant is below `1e-12` times the
    /// product of the column lengths (the Hadamard bound), i.e. numerically singular ones.
    pub fn new(linear: [[f64; 3]; 3]) -> Result<Self, DerivativeError> {
        let err = DerivativeError::SingularAffine { linear };
        if linear.iter().flatten().any(|v| !v.is_finite()) {
            return Err(err);
        }
        let a = &linear;
        // Cofactors, arranged so that inverse = cof^T / det.
        let cof = [
            [
                a[1][1] * a[2][2] - a[1][2] * a[2][1],
                a[1][2] * a[2][0] - a[1][0] * a[2][2],
                a[1][0] * a[2][1] - a[1][1] * a[2][0],
            ],
            [
                a[0][2] * a[2][1] - a[0][1] * a[2][2],
                a[0][0] * a[2][2] - a[0][2] * a[2][0],
                a[0][1] * a[2][0] - a[0][0] * a[2][1],
            ],
            [
                a[0][1] * a[1][2] - a[0][2] * a[1][1],
                a[0][2] * a[1][0] - a[0][0] * a[1][2],
                a[0][0] * a[1][1] - a[0][1] * a[1][0],
            ],
        ];
        let det = a[0][0] * cof[0][0] + a[0][1] * cof[0][1] + a[0][2] * cof[0][2];
        let column_len =
            |c: usize| (a[0][c] * a[0][c] + a[1][c] * a[1][c] + a[2][c] * a[2][c]).sqrt();
        let hadamard = column_len(0) * column_len(1) * column_len(2);
        if !det.is_finite() || !hadamard.is_finite() || det.abs() <= 1e-12 * hadamard || det == 0.0
        {
            return Err(err);
        }
        let mut inverse = [[0.0; 3]; 3];
        for (r, row) in inverse.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = cof[c][r] / det;
            }
        }
        if inverse.iter().flatten().any(|v| !v.is_finite()) {
            return Err(err);
        }
        Ok(IndexToWorld { linear, inverse })
    }

    /// A diagonal (axis-aligned) grid with the given spacing in mm.
    pub fn from_spacing(spacing_mm: [f64; 3]) -> Result<Self, DerivativeError> {
        let [x, y, z] = spacing_mm;
        Self::new([[x, 0.0, 0.0], [0.0, y, 0.0], [0.0, 0.0, z]])
    }

    /// The linear part `A` this was built from.
    pub fn linear(&self) -> [[f64; 3]; 3] {
        self.linear
    }

    /// `A^-1`, row-major.
    pub fn inverse(&self) -> [[f64; 3]; 3] {
        self.inverse
    }

    /// `A^-T g`: an index-space gradient in world units.
    pub fn gradient_to_world(&self, g: [f64; 3]) -> [f64; 3] {
        let m = &self.inverse;
        [
            m[0][0] * g[0] + m[1][0] * g[1] + m[2][0] * g[2],
            m[0][1] * g[0] + m[1][1] * g[1] + m[2][1] * g[2],
            m[0][2] * g[0] + m[1][2] * g[1] + m[2][2] * g[2],
        ]
    }

    /// `A^-T H A^-1`: an index-space Hessian in world units.
    pub fn hessian_to_world(&self, h: &Sym3) -> Sym3 {
        let m = &self.inverse;
        let hm = h.to_matrix();
        let mut out = [[0.0; 3]; 3];
        for (i, row) in out.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                let mut s = 0.0;
                for (k, hk) in hm.iter().enumerate() {
                    for (l, hkl) in hk.iter().enumerate() {
                        s += m[k][i] * hkl * m[l][j];
                    }
                }
                *v = s;
            }
        }
        Sym3::from_matrix(&out)
    }
}

/// Derivatives of one voxel, in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelDerivatives {
    /// World gradient (`I_norm` per mm).
    pub gradient: [f64; 3],
    /// `|gradient|`.
    pub gradient_magnitude: f64,
    /// World Hessian (`I_norm` per mm²).
    pub hessian: Sym3,
    /// `ĝᵀ H ĝ`, or 0 where `|g| <= tau`.
    pub curvature: f64,
}

/// Per-voxel outputs of [`derivatives`], x fastest; each is `Some` only if requested.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Derivatives {
    /// World gradients (with [`DerivativeOptions::gradient`]).
    pub gradient: Option<Vec<[f64; 3]>>,
    /// Gradient magnitudes (with [`DerivativeOptions::gradient`]).
    pub gradient_magnitude: Option<Vec<f64>>,
    /// World Hessians (with [`DerivativeOptions::hessian`]).
    pub hessian: Option<Vec<Sym3>>,
    /// Directional curvatures (with [`DerivativeOptions::hessian`]).
    pub curvature: Option<Vec<f64>>,
}

/// A checked view of a volume: values plus dimensions.
#[derive(Clone, Copy, Debug)]
struct Grid<'a> {
    values: &'a [f64],
    dims: [usize; 3],
}

impl<'a> Grid<'a> {
    fn new(values: &'a [f64], dims: [usize; 3]) -> Result<Self, DerivativeError> {
        let expected = dims[0]
            .checked_mul(dims[1])
            .and_then(|n| n.checked_mul(dims[2]));
        if expected != Some(values.len()) {
            return Err(DerivativeError::LengthMismatch {
                len: values.len(),
                dims,
                expected,
            });
        }
        Ok(Grid { values, dims })
    }

    fn at(&self, p: [usize; 3]) -> f64 {
        self.values[p[0] + self.dims[0] * (p[1] + self.dims[1] * p[2])]
    }

    /// `(lo, hi)` of the first-derivative stencil along `axis`, or `None` for a 1-voxel axis.
    fn span(&self, p: [usize; 3], axis: usize) -> Option<(usize, usize)> {
        let n = self.dims[axis];
        (n > 1).then(|| (p[axis].saturating_sub(1), (p[axis] + 1).min(n - 1)))
    }

    fn first(&self, p: [usize; 3], axis: usize) -> f64 {
        let Some((lo, hi)) = self.span(p, axis) else {
            return 0.0;
        };
        let (mut a, mut b) = (p, p);
        a[axis] = hi;
        b[axis] = lo;
        (self.at(a) - self.at(b)) / (hi - lo) as f64
    }

    fn second(&self, p: [usize; 3], axis: usize) -> f64 {
        let n = self.dims[axis];
        if n < 3 {
            return 0.0;
        }
        let c = p[axis].clamp(1, n - 2);
        let (mut m, mut z, mut q) = (p, p, p);
        m[axis] = c - 1;
        z[axis] = c;
        q[axis] = c + 1;
        self.at(q) - 2.0 * self.at(z) + self.at(m)
    }

    fn mixed(&self, p: [usize; 3], a: usize, b: usize) -> f64 {
        let (Some((lo_a, hi_a)), Some((lo_b, hi_b))) = (self.span(p, a), self.span(p, b)) else {
            return 0.0;
        };
        let corner = |ia: usize, ib: usize| {
            let mut q = p;
            q[a] = ia;
            q[b] = ib;
            self.at(q)
        };
        let sum = corner(hi_a, hi_b) - corner(hi_a, lo_b) - corner(lo_a, hi_b) + corner(lo_a, lo_b);
        sum / ((hi_a - lo_a) * (hi_b - lo_b)) as f64
    }

    fn gradient_index(&self, p: [usize; 3]) -> [f64; 3] {
        [self.first(p, 0), self.first(p, 1), self.first(p, 2)]
    }

    fn hessian_index(&self, p: [usize; 3]) -> Sym3 {
        Sym3 {
            xx: self.second(p, 0),
            yy: self.second(p, 1),
            zz: self.second(p, 2),
            xy: self.mixed(p, 0, 1),
            xz: self.mixed(p, 0, 2),
            yz: self.mixed(p, 1, 2),
        }
    }
}

/// Euclidean length, scaled so that huge components (tiny voxel spacings) cannot overflow.
fn length(v: [f64; 3]) -> f64 {
    let m = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m == 0.0 || !m.is_finite() {
        return m;
    }
    let [x, y, z] = v.map(|c| c / m);
    m * (x * x + y * y + z * z).sqrt()
}

/// `ĝᵀ H ĝ`, 0 when `|g| <= tau` (or not a number).
fn directional_curvature(g: [f64; 3], magnitude: f64, h: &Sym3, tau: f64) -> f64 {
    if magnitude > tau && magnitude.is_finite() {
        h.quadratic_form(g.map(|c| c / magnitude))
    } else {
        0.0
    }
}

/// All derivatives of voxel `p` (world units): one probe of the GPU output without computing the
/// whole volume.
pub fn voxel_derivatives(
    values: &[f64],
    dims: [usize; 3],
    to_world: &IndexToWorld,
    p: [usize; 3],
    tau: f64,
) -> Result<VoxelDerivatives, DerivativeError> {
    let grid = Grid::new(values, dims)?;
    if (0..3).any(|a| p[a] >= dims[a]) {
        return Err(DerivativeError::OutOfRange { p, dims });
    }
    let gradient = to_world.gradient_to_world(grid.gradient_index(p));
    let gradient_magnitude = length(gradient);
    let hessian = to_world.hessian_to_world(&grid.hessian_index(p));
    let curvature = directional_curvature(gradient, gradient_magnitude, &hessian, tau);
    Ok(VoxelDerivatives {
        gradient,
        gradient_magnitude,
        hessian,
        curvature,
    })
}

/// Derivatives of every voxel of `values` (x fastest, `dims` voxels), in world units.
pub fn derivatives(
    values: &[f64],
    dims: [usize; 3],
    to_world: &IndexToWorld,
    options: &DerivativeOptions,
) -> Result<Derivatives, DerivativeError> {
    let grid = Grid::new(values, dims)?;
    let n = values.len();
    let mut out = Derivatives::default();
    if !options.gradient && !options.hessian {
        return Ok(out);
    }
    let mut gradient = Vec::with_capacity(if options.gradient { n } else { 0 });
    let mut magnitude = Vec::with_capacity(if options.gradient { n } else { 0 });
    let mut hessian = Vec::with_capacity(if options.hessian { n } else { 0 });
    let mut curvature = Vec::with_capacity(if options.hessian { n } else { 0 });
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = [i, j, k];
                let g = to_world.gradient_to_world(grid.gradient_index(p));
                let m = length(g);
                if options.gradient {
                    gradient.push(g);
                    magnitude.push(m);
                }
                if options.hessian {
                    let h = to_world.hessian_to_world(&grid.hessian_index(p));
                    curvature.push(directional_curvature(g, m, &h, options.tau));
                    hessian.push(h);
                }
            }
        }
    }
    if options.gradient {
        out.gradient = Some(gradient);
        out.gradient_magnitude = Some(magnitude);
    }
    if options.hessian {
        out.hessian = Some(hessian);
        out.curvature = Some(curvature);
    }
    Ok(out)
}
