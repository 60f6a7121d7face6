//! Twin of the empty-space distance map (shaders/brick_distance.comp): per brick, the Chebyshev
//! distance in bricks to the nearest occupied brick, written as its definition (the minimum over
//! every occupied brick, no separable scans), so the GPU's three scans are checked against the
//! quantity they claim to compute.
//!
//! Decisions: integers throughout (the map is exact, so the GPU must equal it); the same cap of
//! [`FAR`] as the shader, which is also the answer where no brick is occupied.

/// The largest distance stored (and the distance when nothing is occupied).
pub const FAR: u8 = 255;

/// Whether brick `b` is set in `bits` (32 bricks a word, brick `b` at bit `b % 32` of word
/// `b / 32`, as the brick-bounds pass writes them).
pub fn bit_set(bits: &[u32], b: usize) -> bool {
    bits.get(b / 32).is_some_and(|w| (w >> (b % 32)) & 1 == 1)
}

/// Per brick of a `grid` (x fastest), min over occupied bricks q of max(|dx|, |dy|, |dz|),
/// capped at [`FAR`].
pub fn chebyshev_distances(bits: &[u32], grid: [u32; 3]) -> Vec<u8> {
    let [nx, ny, nz] = grid.map(|g| g as i64);
    let position = |b: i64| [b % nx, (b / nx) % ny, b / (nx * ny)];
    let count = nx * ny * nz;
    let occupied: Vec<[i64; 3]> = (0..count)
        .filter(|&b| bit_set(bits, b as usize))
        .map(position)
        .collect();
    (0..count)
        .map(|b| {
            let p = position(b);
            let nearest = occupied
                .iter()
                .map(|q| (0..3).map(|a| (p[a] - q[a]).abs()).max().unwrap_or(0))
                .min()
                .unwrap_or(i64::from(FAR));
            nearest.min(i64::from(FAR)) as u8
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_occupied_brick_gives_concentric_cubes() {
        let grid = [5, 4, 3];
        let mut bits = vec![0u32; 2];
        let centre = 2 + 5 * (1 + 4);
        bits[centre / 32] |= 1 << (centre % 32);
        let d = chebyshev_distances(&bits, grid);
        assert_eq!(d[centre], 0);
        assert_eq!(d[0], 2); // (0,0,0) to (2,1,1)
        assert_eq!(d[4 + 5 * (3 + 4 * 2)], 2); // (4,3,2)
        assert_eq!(d[3 + 5 * (2 + 4 * 2)], 1); // (3,2,2): a corner neighbour
    }

    #[test]
    fn nothing_occupied_is_far_and_long_lines_are_capped() {
        assert!(
            chebyshev_distances(&[0], [3, 2, 1])
                .iter()
                .all(|&d| d == FAR)
        );
        let d = chebyshev_distances(&[1, 0, 0, 0, 0, 0, 0, 0, 0, 0], [300, 1, 1]);
        assert_eq!((d[0], d[1], d[254], d[255], d[299]), (0, 1, 254, 255, 255));
    }
}
