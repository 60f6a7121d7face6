//! TEMPORARY (replaced at merge by reference::brain and its components): the host steps the
//! engine needs, written plainly so the GPU path compiles and runs before the twin lands.

use std::collections::VecDeque;

/// Parameters of brain extraction (BRAIN_SPEC).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BrainParams {
    /// Gaussian pre-smoothing in mm.
    pub sigma_mm: f64,
    /// Tissue band in I_norm: lo < S < hi.
    pub lo: f64,
    /// Upper end of the band (> 1: none).
    pub hi: f64,
    /// Erosion radius in mm.
    pub erode_mm: f64,
    /// Closing radius in mm.
    pub close_mm: f64,
    /// Growth in mm.
    pub grow_mm: f64,
    /// Coarse cell edge in voxels.
    pub coarse: usize,
}

impl BrainParams {
    /// Defaults with a band.
    pub fn with_band(lo: f64, hi: f64) -> Self {
        BrainParams { sigma_mm: 1.0, lo, hi, erode_mm: 4.5, close_mm: 5.0, grow_mm: 1.5, coarse: 2 }
    }
    /// A reason when no run can use these parameters.
    pub fn validate(&self) -> Result<(), String> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !(ok(self.sigma_mm) && ok(self.erode_mm) && ok(self.close_mm)) || !self.grow_mm.is_finite() || self.grow_mm < 0.0 || self.grow_mm >= self.close_mm || !(self.lo < self.hi) || !(1..=8).contains(&self.coarse) {
            return Err(format!("brain extraction parameters out of range: {self:?}"));
        }
        Ok(())
    }
}

/// Threshold of the closing's erosion.
pub fn close_threshold(p: &BrainParams) -> f64 {
    let r = p.close_mm - p.grow_mm;
    r * r
}

/// Column norms.
pub fn spacing_mm(l: [[f64; 3]; 3]) -> [f64; 3] {
    std::array::from_fn(|c| (l[0][c] * l[0][c] + l[1][c] * l[1][c] + l[2][c] * l[2][c]).sqrt())
}

/// Largest spacing axis, ties last.
pub fn slab_axis(s: [f64; 3]) -> usize {
    let mut best = 0;
    for a in 1..3 { if s[a] >= s[best] { best = a; } }
    best
}

fn idx(d: [usize; 3], x: usize, y: usize, z: usize) -> usize { x + d[0] * (y + d[1] * z) }

/// Largest 6-connected component, dilated by one cell (26).
pub fn largest_component_selection(set: &[u8], d: [usize; 3]) -> Option<Vec<u8>> {
    let mut label = vec![0u32; set.len()];
    let (mut best, mut best_size, mut next) = (0u32, 0usize, 0u32);
    let mut q = VecDeque::new();
    for start in 0..set.len() {
        if set[start] == 0 || label[start] != 0 { continue; }
        next += 1; label[start] = next; q.push_back(start); let mut size = 0;
        while let Some(i) = q.pop_front() {
            size += 1;
            let (x, y, z) = (i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1]));
            let mut visit = |j: usize| if set[j] != 0 && label[j] == 0 { label[j] = next; q.push_back(j); };
            if x > 0 { visit(i - 1) } if x + 1 < d[0] { visit(i + 1) }
            if y > 0 { visit(i - d[0]) } if y + 1 < d[1] { visit(i + d[0]) }
            if z > 0 { visit(i - d[0] * d[1]) } if z + 1 < d[2] { visit(i + d[0] * d[1]) }
        }
        if size > best_size { best_size = size; best = next; }
    }
    if best == 0 { return None; }
    let mut out = vec![0u8; set.len()];
    for z in 0..d[2] { for y in 0..d[1] { for x in 0..d[0] {
        if label[idx(d, x, y, z)] != best { continue; }
        for zz in z.saturating_sub(1)..(z + 2).min(d[2]) { for yy in y.saturating_sub(1)..(y + 2).min(d[1]) { for xx in x.saturating_sub(1)..(x + 2).min(d[0]) {
            out[idx(d, xx, yy, zz)] = 1;
        }}}
    }}}
    Some(out)
}

/// Hole filling (BRAIN_SPEC step 11).
pub fn hole_fill_cells(set: &[u8], d: [usize; 3], slab: usize) -> Vec<u8> {
    let n = set.len();
    let coords = |i: usize| [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
    let flood = |in_plane: Option<usize>| {
        let mut reached = vec![false; n];
        let mut q = VecDeque::new();
        for i in 0..n {
            let c = coords(i);
            let border = (0..3).any(|a| Some(a) != in_plane && (c[a] == 0 || c[a] + 1 == d[a]));
            if border && set[i] == 0 { reached[i] = true; q.push_back(i); }
        }
        while let Some(i) = q.pop_front() {
            let c = coords(i);
            for a in 0..3 {
                if Some(a) == in_plane { continue; }
                for s in [-1i64, 1] {
                    let v = c[a] as i64 + s;
                    if v < 0 || v >= d[a] as i64 { continue; }
                    let mut cc = c; cc[a] = v as usize;
                    let j = idx(d, cc[0], cc[1], cc[2]);
                    if set[j] == 0 && !reached[j] { reached[j] = true; q.push_back(j); }
                }
            }
        }
        reached
    };
    let r3 = flood(None);
    let r2 = flood(Some(slab));
    let outside: Vec<bool> = (0..n).map(|i| r3[i] && r2[i]).collect();
    (0..n).map(|i| {
        if outside[i] { return 0; }
        if set[i] == 0 { return 1; }
        let c = coords(i);
        for dz in -1i64..=1 { for dy in -1i64..=1 { for dx in -1i64..=1 {
            let p = [c[0] as i64 + dx, c[1] as i64 + dy, c[2] as i64 + dz];
            if (0..3).any(|a| p[a] < 0 || p[a] >= d[a] as i64) { return 0; }
            if outside[idx(d, p[0] as usize, p[1] as usize, p[2] as usize)] { return 0; }
        }}}
        1
    }).collect()
}

/// Band (BRAIN_SPEC), `t2_like` for T2/PD.
pub fn band_for(h: &[u32; 256], t2_like: bool) -> Option<(f64, f64)> {
    let c = |i: usize| (i as f64 + 0.5) / 256.0;
    let (mut w, mut m) = (0.0f64, 0.0f64);
    let total: f64 = (1..256).map(|i| h[i] as f64).sum();
    let mean: f64 = (1..256).map(|i| h[i] as f64 * c(i)).sum();
    if total <= 0.0 { return None; }
    let (mut best, mut t) = (-1.0, 0usize);
    for i in 1..255 {
        w += h[i] as f64; m += h[i] as f64 * c(i);
        let w1 = total - w; if w <= 0.0 || w1 <= 0.0 { continue; }
        let b = w * w1 * (m / w - (mean - m) / w1).powi(2);
        if b > best { best = b; t = i; }
    }
    let lo = (t as f64 + 1.0) / 256.0;
    if t2_like { return Some((0.6 * lo, 2.0)); }
    let mut s = [0.0f64; 256];
    for (i, v) in s.iter_mut().enumerate() { for d in -3i64..=3 { let j = (i as i64 + d).clamp(0, 255) as usize; *v += h[j] as f64 * (-(d * d) as f64 / 2.0).exp(); } }
    let wm = (t + 1..256).max_by(|&a, &b| s[a].total_cmp(&s[b]))?;
    let wm = c(wm);
    Some((lo, wm + 0.45 * (wm - lo)))
}
