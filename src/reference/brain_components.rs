//! The CPU steps of brain extraction on the coarse grid (the chain of `reference::brain`): the
//! largest 6-connected component of the eroded tissue, and hole filling. The engine runs them on
//! the coarse grid it reads back from the GPU; the f64 twin (`reference::brain`) calls the same
//! functions, so the two cannot disagree here.
//!
//! Decisions:
//! - Cells are `u8` (nonzero = set), x fastest: cell `(i, j, k)` is at `i + mx * (j + my * k)`,
//!   as the GPU's R8 coarse image reads back.
//! - Iterative flood fills with an explicit stack of `u32` cell indices (no recursion: a coarse
//!   grid has 1M+ cells), each cell pushed at most once, so both steps are O(cells) in time and
//!   use 4 bytes a cell for labels plus at most 4 bytes a cell of stack. Grids of more than
//!   `u32::MAX` cells are not coarse grids: they select nothing and fill nothing.
//! - Components are 6-connected (face neighbours): a diagonal contact between two blobs (a
//!   vessel, a thin bridge of partial volume) does not join them. The largest by cell count
//!   wins; on a tie the one holding the lowest linear index (the first one a scan in index
//!   order meets, so "strictly larger replaces" implements the rule). The selection is then
//!   dilated by one cell (26-neighbours) so the fine core taken inside it is not cut by the block
//!   grid.
//! - Hole filling: a cell is outside when it is unset and reachable from the grid border through
//!   unset cells both in 3D (6-connected) and in 2D within its slice across the slab axis
//!   (4-connected). Requiring both means a slab cut through the brain (the ventricles open to
//!   the first or last slice) still fills in 2D, while a cavity closed in 3D but open within a
//!   slice is filled by the 3D test. `fill(c) = !outside(c) && (c unset || no 26-neighbour of c
//!   is outside)`, neighbours beyond the grid counting as outside: a set cell touching the
//!   outside is left to the fine mask, so the fill never makes the surface blocky.
//! - The slab axis is the axis of largest spacing (thick slices); ties go to the last of them
//!   (z for isotropic data).
//!
//! Time (this machine: 2-core Debian 12 dev machine shared with other builds, load average
//! about 6 while measured; release build; `cargo run --release --example brain_twin`): on the
//! coarse grid of chris_t1 at f = 2, 94 x 128 x 95 = 1.14 M cells, the largest component took
//! 15.8 ms and the hole filling 88.2 ms; on the MNI152's 99 x 117 x 95, 17.3 and 76.8 ms. The
//! hole filling does three flood fills and a 26-neighbour pass with a division per visited
//! cell; a faster version (coordinates carried along instead of divided out) is left for when
//! it matters against the GPU's part.

/// The slab axis of a grid with these voxel spacings: the largest spacing, ties to the last.
pub fn slab_axis(spacing: [f64; 3]) -> usize {
    let mut best = 0;
    for a in 1..3 {
        if spacing[a] >= spacing[best] {
            best = a;
        }
    }
    best
}

/// Number of cells of `dims`, when it fits the `u32` indices used here.
fn cell_count(dims: [usize; 3]) -> Option<usize> {
    let n = dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d))?;
    (n <= u32::MAX as usize).then_some(n)
}

/// Coordinates of cell `c`.
fn coords(c: usize, dims: [usize; 3]) -> [usize; 3] {
    [
        c % dims[0],
        (c / dims[0]) % dims[1],
        c / (dims[0] * dims[1]),
    ]
}

/// Linear index of `p`.
fn index(p: [usize; 3], dims: [usize; 3]) -> usize {
    p[0] + dims[0] * (p[1] + dims[1] * p[2])
}

/// The up to six face neighbours of `c` inside the grid.
fn face_neighbours(c: usize, dims: [usize; 3]) -> impl Iterator<Item = usize> {
    let p = coords(c, dims);
    let strides = [1, dims[0], dims[0] * dims[1]];
    (0..3).flat_map(move |a| {
        let down = (p[a] > 0).then(|| c - strides[a]);
        let up = (p[a] + 1 < dims[a]).then(|| c + strides[a]);
        down.into_iter().chain(up)
    })
}

/// Step 6: the largest 6-connected component of the set cells, dilated by one cell
/// (26-neighbours), as 0/1 cells. None when no cell is set (no brain found), and when `set` does
/// not hold exactly `dims`' cells or the grid has more than `u32::MAX` cells.
pub fn largest_component_selection(set: &[u8], dims: [usize; 3]) -> Option<Vec<u8>> {
    largest_component(set, dims).map(|component| dilate_one_cell(&component, dims))
}

/// The largest 6-connected component of the set cells as 0/1 cells (the module doc's rule), not
/// dilated. None as for [`largest_component_selection`].
pub fn largest_component(set: &[u8], dims: [usize; 3]) -> Option<Vec<u8>> {
    let n = cell_count(dims).filter(|&n| n == set.len())?;
    let mut label = vec![0u32; n];
    let mut stack: Vec<u32> = Vec::new();
    let (mut best, mut best_size) = (0u32, 0usize);
    let mut next = 0u32;
    for start in 0..n {
        if set[start] == 0 || label[start] != 0 {
            continue;
        }
        next += 1;
        label[start] = next;
        stack.push(start as u32);
        let mut size = 0usize;
        while let Some(c) = stack.pop() {
            size += 1;
            for q in face_neighbours(c as usize, dims) {
                if set[q] != 0 && label[q] == 0 {
                    label[q] = next;
                    stack.push(q as u32);
                }
            }
        }
        // Strictly larger: on a tie the earlier component (lowest index) stays.
        if size > best_size {
            (best, best_size) = (next, size);
        }
    }
    if best == 0 {
        return None;
    }
    Some(label.iter().map(|&l| u8::from(l == best)).collect())
}

/// `component` dilated by one cell (26-neighbours), so the fine core taken inside it is not cut
/// by the block grid.
pub fn dilate_one_cell(component: &[u8], dims: [usize; 3]) -> Vec<u8> {
    let mut selected = vec![0u8; component.len()];
    for (c, &v) in component.iter().enumerate() {
        if v != 0 {
            mark_block(&mut selected, coords(c, dims), dims);
        }
    }
    selected
}

/// Sets `p` and its 26 neighbours inside the grid.
fn mark_block(out: &mut [u8], p: [usize; 3], dims: [usize; 3]) {
    let range = |a: usize| p[a].saturating_sub(1)..=(p[a] + 1).min(dims[a] - 1);
    for k in range(2) {
        for j in range(1) {
            for i in range(0) {
                out[index([i, j, k], dims)] = 1;
            }
        }
    }
}

/// Unset cells reachable from the grid border through unset cells, 6-connected.
fn outside_3d(set: &[u8], dims: [usize; 3]) -> Vec<bool> {
    let mut out = vec![false; set.len()];
    let mut stack: Vec<u32> = Vec::new();
    for (c, o) in out.iter_mut().enumerate() {
        let p = coords(c, dims);
        let border = (0..3).any(|a| p[a] == 0 || p[a] + 1 == dims[a]);
        if border && set[c] == 0 {
            *o = true;
            stack.push(c as u32);
        }
    }
    while let Some(c) = stack.pop() {
        for q in face_neighbours(c as usize, dims) {
            if set[q] == 0 && !out[q] {
                out[q] = true;
                stack.push(q as u32);
            }
        }
    }
    out
}

/// Unset cells reachable from their slice's border through unset cells 4-connected within the
/// slice, slices taken across axis `s`.
fn outside_2d(set: &[u8], dims: [usize; 3], s: usize) -> Vec<bool> {
    let (u, v) = match s {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let strides = [1, dims[0], dims[0] * dims[1]];
    let mut out = vec![false; set.len()];
    let mut stack: Vec<u32> = Vec::new();
    for (c, o) in out.iter_mut().enumerate() {
        let p = coords(c, dims);
        let border = [u, v].iter().any(|&a| p[a] == 0 || p[a] + 1 == dims[a]);
        if border && set[c] == 0 {
            *o = true;
            stack.push(c as u32);
        }
    }
    while let Some(c) = stack.pop() {
        let c = c as usize;
        let p = coords(c, dims);
        for a in [u, v] {
            let down = (p[a] > 0).then(|| c - strides[a]);
            let up = (p[a] + 1 < dims[a]).then(|| c + strides[a]);
            for q in down.into_iter().chain(up) {
                if set[q] == 0 && !out[q] {
                    out[q] = true;
                    stack.push(q as u32);
                }
            }
        }
    }
    out
}

/// Whether any of the 26 neighbours of `p` is outside (beyond the grid counts as outside).
fn touches_outside(outside: &[bool], p: [usize; 3], dims: [usize; 3]) -> bool {
    if (0..3).any(|a| p[a] == 0 || p[a] + 1 == dims[a]) {
        return true;
    }
    for k in p[2] - 1..=p[2] + 1 {
        for j in p[1] - 1..=p[1] + 1 {
            for i in p[0] - 1..=p[0] + 1 {
                if outside[index([i, j, k], dims)] {
                    return true;
                }
            }
        }
    }
    false
}

/// Cells outside `set` by the module doc's rule: unset and reachable from the border both in 3D
/// and within their slice across `slab_axis`.
fn outside(set: &[u8], dims: [usize; 3], slab_axis: usize) -> Vec<bool> {
    let o3 = outside_3d(set, dims);
    let o2 = outside_2d(set, dims, slab_axis.min(2));
    o3.iter().zip(&o2).map(|(&a, &b)| a && b).collect()
}

/// The cells `set` encloses (0/1): every cell not outside it (the module doc's rule), so the set
/// cells and the holes within them. All zeros when `set` does not hold exactly `dims`' cells or
/// the grid has more than `u32::MAX` cells.
pub fn enclosed_cells(set: &[u8], dims: [usize; 3], slab_axis: usize) -> Vec<u8> {
    if cell_count(dims).filter(|&n| n == set.len()).is_none() {
        return vec![0; set.len()];
    }
    outside(set, dims, slab_axis)
        .iter()
        .map(|&o| u8::from(!o))
        .collect()
}

/// Step 11: the filled cells (0/1) of the coarse mask `set` (module doc), slices across
/// `slab_axis` (0, 1 or 2; larger values mean 2). All zeros when `set` does not hold exactly
/// `dims`' cells or the grid has more than `u32::MAX` cells.
pub fn hole_fill_cells(set: &[u8], dims: [usize; 3], slab_axis: usize) -> Vec<u8> {
    let Some(n) = cell_count(dims).filter(|&n| n == set.len()) else {
        return vec![0; set.len()];
    };
    let outside = outside(set, dims, slab_axis);
    (0..n)
        .map(|c| {
            let fill =
                !outside[c] && (set[c] == 0 || !touches_outside(&outside, coords(c, dims), dims));
            u8::from(fill)
        })
        .collect()
}

#[cfg(test)]
#[path = "brain_components_tests.rs"]
mod tests;
