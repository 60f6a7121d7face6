//! Cluster-size thresholding: connected groups of voxels that pass a test, smaller than a size,
//! removed (FSL `cluster`'s minimum extent, AFNI's `-clust`), for statistical-map layers.
//!
//! Decisions: 26-connectivity (faces, edges and corners; FSL's default), found by a breadth-first
//! flood over an explicit queue (no recursion: a 10^7-voxel cluster cannot overflow the stack);
//! memory is one u32 label per voxel plus the queue. The caller says which voxels belong
//! together (`side`: +1, -1 or 0 for "not drawn"), so positive and negative blobs that touch
//! stay separate clusters.

/// Sets to `fill` every voxel of a cluster (same non-zero `side`, 26-connected) with fewer than
/// `min_size` voxels; returns the number of clusters kept and removed. `values` and `side`
/// are on one `dims` grid, x fastest.
pub fn remove_small_clusters(
    values: &mut [f32],
    dims: [usize; 3],
    side: impl Fn(f32) -> i8,
    min_size: usize,
    fill: f32,
) -> (usize, usize) {
    let n = values.len();
    let sides: Vec<i8> = values.iter().map(|&v| side(v)).collect();
    let mut seen = vec![false; n];
    let mut members = Vec::new();
    let mut queue = std::collections::VecDeque::new();
    let (mut kept, mut removed) = (0, 0);
    for start in 0..n {
        if seen[start] || sides[start] == 0 {
            continue;
        }
        members.clear();
        seen[start] = true;
        queue.push_back(start);
        while let Some(at) = queue.pop_front() {
            members.push(at);
            for next in neighbours(at, dims) {
                if !seen[next] && sides[next] == sides[start] {
                    seen[next] = true;
                    queue.push_back(next);
                }
            }
        }
        if members.len() < min_size {
            removed += 1;
            for &m in &members {
                values[m] = fill;
            }
        } else {
            kept += 1;
        }
    }
    (kept, removed)
}

/// The up to 26 voxels around `at` inside the grid.
fn neighbours(at: usize, dims: [usize; 3]) -> impl Iterator<Item = usize> {
    let [nx, ny, nz] = dims;
    let (i, j, k) = (at % nx, (at / nx) % ny, at / (nx * ny));
    (0..27).filter_map(move |o| {
        let d = [o % 3, (o / 3) % 3, o / 9];
        if d == [1, 1, 1] {
            return None;
        }
        let q = [i + d[0], j + d[1], k + d[2]];
        let inside = q[0] >= 1 && q[1] >= 1 && q[2] >= 1 && q[0] <= nx && q[1] <= ny && q[2] <= nz;
        inside.then(|| (q[0] - 1) + nx * ((q[1] - 1) + ny * (q[2] - 1)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sign(v: f32) -> i8 {
        if v >= 1.0 {
            1
        } else if v <= -1.0 {
            -1
        } else {
            0
        }
    }

    #[test]
    fn small_clusters_go_and_diagonal_neighbours_join() {
        let dims = [5, 4, 3];
        let at = |i: usize, j: usize, k: usize| i + 5 * (j + 4 * k);
        let mut v = vec![0.0f32; 60];
        // A 3-voxel chain joined only through a corner and an edge: one cluster.
        v[at(0, 0, 0)] = 2.0;
        v[at(1, 1, 1)] = 2.0;
        v[at(2, 1, 2)] = 2.0;
        // A single voxel far away, and a negative voxel touching the chain.
        v[at(4, 3, 0)] = 5.0;
        v[at(1, 0, 0)] = -3.0;
        let (kept, removed) = remove_small_clusters(&mut v, dims, sign, 2, 0.0);
        assert_eq!((kept, removed), (1, 2));
        assert_eq!(v[at(2, 1, 2)], 2.0, "the chain stays");
        assert_eq!(v[at(4, 3, 0)], 0.0, "the lone voxel goes");
        assert_eq!(v[at(1, 0, 0)], 0.0, "a negative voxel is its own cluster");
    }

    #[test]
    fn a_size_of_one_keeps_everything() {
        let mut v = vec![2.0f32, 0.0, -2.0, 0.0];
        let before = v.clone();
        assert_eq!(
            remove_small_clusters(&mut v, [4, 1, 1], sign, 1, 0.0),
            (2, 0)
        );
        assert_eq!(v, before);
    }
}
