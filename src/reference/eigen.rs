//! Twin of `shaders/include/eigen3.glsl`: eigenvalues of a real symmetric 3x3 matrix by cyclic
//! Jacobi rotations, in f64.
//!
//! Decisions (NUMERICS.md row "eigenvalues of a symmetric 3x3", the same as the shader's):
//! - Jacobi, not the closed trigonometric form: a Jacobi rotation is backward stable, so each
//!   eigenvalue is within a few eps |A| of the exact one for every spectrum (repeated, nearly
//!   repeated, rank 1 or 2, zero), where the closed form's acos loses half the digits near a
//!   repeated pair.
//! - The matrix is divided by its largest |entry| first and the eigenvalues scaled back, so
//!   squares never overflow or underflow (entries from 1e-300 to 1e300 in f64, 1e-37 to 1e37 in
//!   f32).
//! - Sweeps stop when the off-diagonal norm is below `STOP` of the Frobenius norm (Weyl: the rest
//!   moves no eigenvalue by more than that), at most `MAX_SWEEPS`.
//! - A non-finite entry gives `[0, 0, 0]` (no shape: vesselness 0), as in the shader.
//! - Ascending order.

use super::derivatives::Sym3;

/// Relative off-diagonal norm at which the sweeps stop (f64: about eps).
const STOP: f64 = 1e-16;
/// Upper bound on sweeps (quadratic convergence needs 3 to 6 in f64).
const MAX_SWEEPS: usize = 16;

/// Eigenvalues of `a` in ascending order (module decisions).
pub fn sym3_eigenvalues(a: &Sym3) -> [f64; 3] {
    let entries = [a.xx, a.yy, a.zz, a.xy, a.xz, a.yz];
    if entries.iter().any(|v| !v.is_finite()) {
        return [0.0; 3];
    }
    let m = entries.iter().fold(0.0f64, |acc, v| acc.max(v.abs()));
    if m == 0.0 {
        return [0.0; 3];
    }
    // d: diagonal; o: (0,1), (0,2), (1,2).
    let mut d = [a.xx / m, a.yy / m, a.zz / m];
    let mut o = [a.xy / m, a.xz / m, a.yz / m];
    for _ in 0..MAX_SWEEPS {
        let off: f64 = o.iter().map(|v| v * v).sum();
        let diag: f64 = d.iter().map(|v| v * v).sum();
        if off <= STOP * STOP * (diag + 2.0 * off) {
            break;
        }
        rotate(&mut d, &mut o, 0, 1);
        rotate(&mut d, &mut o, 0, 2);
        rotate(&mut d, &mut o, 1, 2);
    }
    let mut out = d.map(|v| v * m);
    out.sort_by(f64::total_cmp);
    out
}

/// The off-diagonal slot of the index pair `(i, j)`, `i != j`.
fn slot(i: usize, j: usize) -> usize {
    match (i.min(j), i.max(j)) {
        (0, 1) => 0,
        (0, 2) => 1,
        _ => 2,
    }
}

/// One Jacobi rotation zeroing entry `(p, q)` (Numerical Recipes' `jacobi`, smaller angle).
fn rotate(d: &mut [f64; 3], o: &mut [f64; 3], p: usize, q: usize) {
    let pq = slot(p, q);
    let apq = o[pq];
    if apq == 0.0 {
        return;
    }
    let r = 3 - p - q;
    let (rp, rq) = (slot(r, p), slot(r, q));
    let theta = (d[q] - d[p]) / (2.0 * apq);
    // For huge theta (tiny apq) theta^2 would overflow; t = 1 / (2 theta) is exact there.
    let t = if theta.abs() > 1e150 {
        0.5 / theta
    } else if theta != 0.0 {
        theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
    } else {
        1.0
    };
    let c = 1.0 / (t * t + 1.0).sqrt();
    let s = t * c;
    d[p] -= t * apq;
    d[q] += t * apq;
    o[pq] = 0.0;
    let (arp, arq) = (o[rp], o[rq]);
    o[rp] = c * arp - s * arq;
    o[rq] = s * arp + c * arq;
}

/// The eigenvalues sorted by magnitude, `|l1| <= |l2| <= |l3|` (Frangi's order).
pub fn by_magnitude(mut l: [f64; 3]) -> [f64; 3] {
    l.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    l
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diagonal_and_zero_matrices() {
        let a = Sym3 {
            xx: 3.0,
            yy: -1.0,
            zz: 2.0,
            ..Default::default()
        };
        assert_eq!(sym3_eigenvalues(&a), [-1.0, 2.0, 3.0]);
        assert_eq!(sym3_eigenvalues(&Sym3::default()), [0.0; 3]);
    }

    #[test]
    fn non_finite_entries_give_zeros() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let a = Sym3 {
                xx: 1.0,
                xz: bad,
                ..Default::default()
            };
            assert_eq!(sym3_eigenvalues(&a), [0.0; 3]);
        }
    }
}
