// Eigenvalues of a real symmetric 3x3 matrix, in f32 (twin: src/reference/eigen.rs, the same
// algorithm in f64). Technique and its tests: NUMERICS.md row "eigenvalues of a symmetric 3x3".
//
// - Cyclic Jacobi rotations, not the closed (trigonometric) form: the closed form's acos loses
//   half the digits when two eigenvalues nearly coincide (error ~ sqrt(eps) |A|, 3e-4 in f32),
//   and its discriminant cancels; a Jacobi rotation is backward stable, so every eigenvalue is
//   within a few eps |A| whatever the spectrum (repeated, nearly repeated, rank 1 or 2).
// - The matrix is divided by its largest |entry| first (and the eigenvalues multiplied back):
//   squares of entries near 1e20 overflow f32 and those near 1e-20 underflow to 0, which would
//   stop the sweeps early or turn them into NaN.
// - Sweeps stop when the off-diagonal norm is below 1e-8 of the Frobenius norm (Weyl: what is
//   left moves the eigenvalues by less than f32 rounding), at most 8 sweeps (3x3 Jacobi
//   converges quadratically: 3 to 5 sweeps in practice).
// - A non-finite entry gives (0, 0, 0): such a matrix has no shape. The test is on the bits,
//   since the GPU may fold isnan()/isinf() away (NUMERICS.md preamble).
// Returns the eigenvalues in ascending order.

bool eigen3_nonfinite(float x) {
    return (floatBitsToUint(x) & 0x7f800000u) == 0x7f800000u;
}

// One Jacobi rotation zeroing a[p][q] of the symmetric matrix held in d (diagonal) and
// o (off-diagonal: o.x = (0,1), o.y = (0,2), o.z = (1,2)).
void eigen3_rotate(inout vec3 d, inout vec3 o, int p, int q) {
    // Off-diagonal slot of (p, q) and the third index r with its slots (r, p), (r, q).
    int pq = (p == 0) ? ((q == 1) ? 0 : 1) : 2;
    float apq = o[pq];
    if (apq == 0.0) {
        return;
    }
    int r = 3 - p - q;
    int rp = (min(r, p) == 0) ? ((max(r, p) == 1) ? 0 : 1) : 2;
    int rq = (min(r, q) == 0) ? ((max(r, q) == 1) ? 0 : 1) : 2;
    float theta = (d[q] - d[p]) / (2.0 * apq);
    // t = tan of the rotation angle, the smaller root; for huge theta (tiny apq) theta^2
    // would overflow, and t = 1 / (2 theta) is exact to f32 there.
    float t = 1.0;
    if (abs(theta) > 1e18) {
        t = 0.5 / theta;
    } else if (theta != 0.0) {
        t = sign(theta) / (abs(theta) + sqrt(theta * theta + 1.0));
    }
    float c = inversesqrt(t * t + 1.0);
    float s = t * c;
    d[p] -= t * apq;
    d[q] += t * apq;
    o[pq] = 0.0;
    float arp = o[rp];
    float arq = o[rq];
    o[rp] = c * arp - s * arq;
    o[rq] = s * arp + c * arq;
}

vec3 sym3_eigenvalues(float a00, float a11, float a22, float a01, float a02, float a12) {
    if (eigen3_nonfinite(a00) || eigen3_nonfinite(a11) || eigen3_nonfinite(a22)
        || eigen3_nonfinite(a01) || eigen3_nonfinite(a02) || eigen3_nonfinite(a12)) {
        return vec3(0.0);
    }
    float m = max(max(max(abs(a00), abs(a11)), abs(a22)), max(max(abs(a01), abs(a02)), abs(a12)));
    if (m == 0.0) {
        return vec3(0.0);
    }
    vec3 d = vec3(a00, a11, a22) / m;
    vec3 o = vec3(a01, a02, a12) / m;
    for (int sweep = 0; sweep < 8; sweep++) {
        float off = dot(o, o);
        if (off <= 1e-16 * (dot(d, d) + 2.0 * off)) {
            break;
        }
        eigen3_rotate(d, o, 0, 1);
        eigen3_rotate(d, o, 0, 2);
        eigen3_rotate(d, o, 1, 2);
    }
    // Ascending order (the median by min/max, exact: a sum minus the extremes would cancel).
    float lo = min(min(d.x, d.y), d.z);
    float hi = max(max(d.x, d.y), d.z);
    float mid = max(min(d.x, d.y), min(max(d.x, d.y), d.z));
    return vec3(lo, mid, hi) * m;
}
