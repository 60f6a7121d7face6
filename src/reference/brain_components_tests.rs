use super::*;

/// Cells of `dims` for which `f(i, j, k)` holds, as 0/1.
fn grid(dims: [usize; 3], f: impl Fn(f64, f64, f64) -> bool) -> Vec<u8> {
    let mut out = Vec::with_capacity(dims.iter().product());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                out.push(u8::from(f(i as f64, j as f64, k as f64)));
            }
        }
    }
    out
}

fn count(v: &[u8]) -> usize {
    v.iter().filter(|&&x| x != 0).count()
}

#[test]
fn slab_axis_is_the_thickest_axis_ties_to_the_last() {
    assert_eq!(slab_axis([1.0, 1.0, 2.0]), 2);
    assert_eq!(slab_axis([3.0, 1.0, 2.0]), 0);
    assert_eq!(slab_axis([1.0, 3.0, 3.0]), 2);
    assert_eq!(slab_axis([3.0, 3.0, 1.0]), 1);
    assert_eq!(slab_axis([0.9, 0.9, 0.9]), 2);
}

#[test]
fn empty_grid_has_no_component() {
    assert_eq!(largest_component_selection(&[0; 60], [3, 4, 5]), None);
    assert_eq!(largest_component_selection(&[], [0, 4, 5]), None);
    // A length that does not match the dims selects nothing (caller error, no panic).
    assert_eq!(largest_component_selection(&[1; 59], [3, 4, 5]), None);
}

#[test]
fn the_larger_of_two_blobs_is_selected_and_dilated_by_one_cell() {
    let dims = [30, 17, 13];
    // Blob A: a 5x5x5 cube at (3..8, 3..8, 3..8); blob B: a 6x6x6 cube at (18..24, ...).
    let set = grid(dims, |i, j, k| {
        let a = (3.0..8.0).contains(&i) && (3.0..8.0).contains(&j) && (3.0..8.0).contains(&k);
        let b = (18.0..24.0).contains(&i) && (3.0..9.0).contains(&j) && (3.0..9.0).contains(&k);
        a || b
    });
    let sel = largest_component_selection(&set, dims).expect("two blobs");
    // B dilated by one cell: 8x8x8 cells, A untouched.
    assert_eq!(count(&sel), 8 * 8 * 8);
    assert_eq!(sel[index([5, 5, 5], dims)], 0);
    assert_eq!(sel[index([20, 5, 5], dims)], 1);
    assert_eq!(
        sel[index([17, 2, 2], dims)],
        1,
        "26-dilation reaches the corner"
    );
    assert_eq!(sel[index([16, 5, 5], dims)], 0);
}

#[test]
fn a_tie_selects_the_component_with_the_lowest_index() {
    let dims = [20, 6, 6];
    // Two equal 3x3x3 cubes; the one at low i holds the lowest linear index.
    let set = grid(dims, |i, j, k| {
        let inside = |lo: f64| (lo..lo + 3.0).contains(&i);
        (inside(2.0) || inside(12.0)) && (1.0..4.0).contains(&j) && (1.0..4.0).contains(&k)
    });
    let sel = largest_component_selection(&set, dims).expect("two cubes");
    assert_eq!(sel[index([3, 2, 2], dims)], 1);
    assert_eq!(sel[index([13, 2, 2], dims)], 0);
    // The cube at low k but high i holds the lowest linear index when k differs.
    let set = grid(dims, |i, j, k| {
        let a = (12.0..15.0).contains(&i) && (0.0..3.0).contains(&k);
        let b = (2.0..5.0).contains(&i) && (3.0..6.0).contains(&k);
        (a || b) && (1.0..4.0).contains(&j)
    });
    let sel = largest_component_selection(&set, dims).expect("two cubes");
    assert_eq!(sel[index([13, 2, 1], dims)], 1);
    assert_eq!(sel[index([3, 2, 4], dims)], 0);
}

#[test]
fn a_face_bridge_joins_blobs_a_diagonal_contact_does_not() {
    let dims = [24, 9, 9];
    let cube = |i: f64, j: f64, k: f64, lo: f64, side: f64| {
        (lo..lo + side).contains(&i)
            && (2.0..2.0 + side).contains(&j)
            && (2.0..2.0 + side).contains(&k)
    };
    // A 5-cube at i 1..6 and a 4-cube at i 12..16, a one-cell-wide face bridge at j = k = 3.
    let bridged = grid(dims, |i, j, k| {
        cube(i, j, k, 1.0, 5.0)
            || cube(i, j, k, 12.0, 4.0)
            || ((6.0..12.0).contains(&i) && j == 3.0 && k == 3.0)
    });
    let sel = largest_component_selection(&bridged, dims).expect("bridged blobs");
    assert_eq!(
        sel[index([13, 3, 3], dims)],
        1,
        "the bridge joins the small cube"
    );
    // Without the bridge, two cubes meeting only along a diagonal (an edge or a corner).
    let diagonal = grid(dims, |i, j, k| {
        cube(i, j, k, 1.0, 5.0) || (i == 6.0 && j == 7.0 && k == 7.0)
    });
    // Cube A ends at (5, 6, 6); (6, 7, 7) touches it only at a corner, so it is separate.
    let sel = largest_component_selection(&diagonal, dims).expect("cube");
    let own = |p: [usize; 3]| diagonal[index(p, dims)];
    assert_eq!(own([6, 7, 7]), 1);
    // Selected only through the one-cell dilation of A, not as a member: its far neighbour
    // (7, 8, 8) is beyond the dilation.
    assert_eq!(sel[index([6, 7, 7], dims)], 1);
    assert_eq!(sel[index([7, 8, 8], dims)], 0);
    // A corner contact between two blobs of 8 and 27 cells: the selection is the 27-cube's.
    let two = grid(dims, |i, j, k| {
        let a = (1.0..4.0).contains(&i) && (1.0..4.0).contains(&j) && (1.0..4.0).contains(&k);
        let b = (4.0..6.0).contains(&i) && (4.0..6.0).contains(&j) && (4.0..6.0).contains(&k);
        a || b
    });
    let sel = largest_component_selection(&two, dims).expect("cubes");
    assert_eq!(
        count(&sel),
        5 * 5 * 5,
        "the 3-cube dilated; the 2-cube is not a member"
    );
}

#[test]
fn a_hollow_sphere_is_filled() {
    let dims = [21, 22, 23];
    let r = |i: f64, j: f64, k: f64| {
        ((i - 10.0).powi(2) + (j - 10.5).powi(2) + (k - 11.0).powi(2)).sqrt()
    };
    let shell = grid(dims, |i, j, k| (6.0..8.0).contains(&r(i, j, k)));
    let fill = hole_fill_cells(&shell, dims, 2);
    let ball = grid(dims, |i, j, k| r(i, j, k) < 6.0);
    for c in 0..shell.len() {
        if ball[c] != 0 {
            assert_eq!(fill[c], 1, "interior cell {c} filled");
        }
        if shell[c] == 0 && ball[c] == 0 {
            assert_eq!(fill[c], 0, "exterior cell {c} not filled");
        }
    }
    // The shell's outer layer touches the outside and is left to the fine mask; its inner
    // layer is filled.
    let p = [10, 10, 11];
    assert_eq!(fill[index([10 + 7, p[1], p[2]], dims)], 0);
    assert_eq!(fill[index([10 + 6, p[1], p[2]], dims)], 1);
}

#[test]
fn a_slab_cut_cylinder_fills_across_the_slab_axis_only() {
    // A hollow cylinder along z, open at both z faces: every interior cell is reachable from
    // the border in 3D, none within its z slice.
    let dims = [15, 16, 9];
    let r = |i: f64, j: f64| ((i - 7.0).powi(2) + (j - 7.5).powi(2)).sqrt();
    let tube = grid(dims, |i, j, _| (4.0..6.0).contains(&r(i, j)));
    let fill = hole_fill_cells(&tube, dims, 2);
    for k in 0..9 {
        assert_eq!(
            fill[index([7, 7, k], dims)],
            1,
            "interior of slice {k} filled"
        );
        assert_eq!(fill[index([0, 0, k], dims)], 0);
    }
    // Slices across x see the interior open along z: nothing is filled.
    let fill_x = hole_fill_cells(&tube, dims, 0);
    assert_eq!(count(&fill_x), 0);
    // Capped at both ends (closed in 3D): a cell is outside only when reachable in both, so
    // the 3D test alone fills the closed can whatever the slab axis.
    let mut can = tube.clone();
    for k in [0, 8] {
        for j in 0..16 {
            for i in 0..15 {
                if r(i as f64, j as f64) < 6.0 {
                    can[index([i, j, k], dims)] = 1;
                }
            }
        }
    }
    let fill_can = hole_fill_cells(&can, dims, 0);
    assert_eq!(fill_can[index([7, 7, 4], dims)], 1);
}

#[test]
fn the_grid_border_is_outside_and_bad_lengths_fill_nothing() {
    // A fully set grid: every cell touches beyond-grid only if on the border.
    let dims = [5, 5, 5];
    let fill = hole_fill_cells(&[1; 125], dims, 2);
    assert_eq!(count(&fill), 27, "only the 3x3x3 core");
    assert_eq!(hole_fill_cells(&[1; 7], dims, 2), vec![0; 7]);
    assert_eq!(count(&hole_fill_cells(&[0; 125], dims, 9)), 0);
}
