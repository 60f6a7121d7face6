//! The geometric perturbations of the study (`perturb`): 3 mm slices and LPS storage, each
//! moving the labels with the voxels.
//!
//! Decisions: a thick voxel is the mean of 3 thin ones along k, centred on the middle one (the
//! affine's k column triples and its origin moves one thin slice), a leftover of 1-2 slices is
//! dropped; its label is the class held by at least 2 of the 3, else "head" when any is inside
//! the head. LPS storage reverses i and j and flips the affine with them, so every voxel keeps
//! its world position. Both store f32 with the identity intensity map (means of integers are
//! not integers).

use super::perturb::{Label, PerturbError};
use crate::volume::{LinearMap, Samples, Volume};

/// Mean of 3 consecutive slices along k (a leftover of 1-2 slices is dropped), voxel size
/// tripled along k, labels by the 2-of-3 rule (module doc). Stored as f32, identity map.
#[allow(clippy::type_complexity)]
pub(super) fn thick_slices(
    volume: &Volume,
    values: &[f64],
    labels: &[Label],
) -> Result<(Volume, (Vec<f64>, Vec<Label>)), PerturbError> {
    let [nx, ny, nz] = volume.dims;
    let nz3 = nz / 3;
    if nz3 == 0 {
        return Err(PerturbError::TooThin(volume.name.clone()));
    }
    let plane = nx * ny;
    let mut out = Vec::with_capacity(plane * nz3);
    let mut out_labels = Vec::with_capacity(plane * nz3);
    for k in 0..nz3 {
        for p in 0..plane {
            let thin = [0, 1, 2].map(|d| p + plane * (3 * k + d));
            out.push(thin.iter().map(|&i| values[i]).sum::<f64>() / 3.0);
            out_labels.push(majority(thin.map(|i| labels[i])));
        }
    }
    // The thick voxel's centre is the middle thin slice 3k + 1: the k column triples, the
    // origin moves one thin slice along it.
    let mut affine = volume.orientation.affine;
    for row in affine.iter_mut().take(3) {
        row[3] += row[2];
        row[2] *= 3.0;
    }
    let thick = Volume::from_voxels(
        &volume.name,
        [nx, ny, nz3],
        Samples::from_f32(&out.iter().map(|&v| v as f32).collect::<Vec<_>>()),
        affine,
        LinearMap::IDENTITY,
    )?;
    Ok((thick, (out, out_labels)))
}

fn majority(thin: [Label; 3]) -> Label {
    for class in [Label::Csf, Label::Gm, Label::Wm] {
        if thin.iter().filter(|&&l| l == class).count() >= 2 {
            return class;
        }
    }
    if thin.iter().any(|l| l.in_head()) {
        Label::Head
    } else {
        Label::Outside
    }
}

/// The same volume stored with i and j reversed (RAS storage becomes LPS), the affine flipped
/// with them so that every voxel keeps its world position. `values` are its physical values.
pub fn to_lps(
    volume: &Volume,
    values: &[f64],
    labels: &[Label],
) -> Result<(Volume, Vec<Label>), PerturbError> {
    let [nx, ny, nz] = volume.dims;
    let n = volume.voxel_count();
    if values.len() != n || labels.len() != n {
        return Err(PerturbError::GridMismatch {
            what: "the values or labels".into(),
            got: values.len().min(labels.len()),
            expected: n,
        });
    }
    let mut out = Vec::with_capacity(n);
    let mut out_labels = Vec::with_capacity(n);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let src = (nx - 1 - i) + nx * ((ny - 1 - j) + ny * k);
                out.push(values[src] as f32);
                out_labels.push(labels[src]);
            }
        }
    }
    // index i' = nx-1-i: x = A (nx-1-i', ...) = -A_col0 i' + A_col0 (nx-1) + ...
    let mut affine = volume.orientation.affine;
    for row in affine.iter_mut().take(3) {
        row[3] += row[0] * (nx - 1) as f64 + row[1] * (ny - 1) as f64;
        row[0] = -row[0];
        row[1] = -row[1];
    }
    let lps = Volume::from_voxels(
        &volume.name,
        volume.dims,
        Samples::from_f32(&out),
        affine,
        LinearMap::IDENTITY,
    )?;
    Ok((lps, out_labels))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::perturb::physical;
    use crate::study::perturb::tests::small;

    fn world(v: &Volume, idx: [usize; 3]) -> [f64; 3] {
        let a = &v.orientation.affine;
        let p = [idx[0] as f64, idx[1] as f64, idx[2] as f64];
        [0, 1, 2].map(|r| a[r][0] * p[0] + a[r][1] * p[1] + a[r][2] * p[2] + a[r][3])
    }

    #[test]
    fn lps_storage_keeps_every_voxel_at_its_world_position() {
        let (v, labels) = small();
        let (lps, lps_labels) = to_lps(&v, &physical(&v), &labels).unwrap();
        let (orig, flipped) = (physical(&v), physical(&lps));
        for k in 0..7 {
            for j in 0..3 {
                for i in 0..4 {
                    let src = i + 4 * (j + 3 * k);
                    let (fi, fj) = (3 - i, 2 - j);
                    let dst = fi + 4 * (fj + 3 * k);
                    assert_eq!(world(&v, [i, j, k]), world(&lps, [fi, fj, k]));
                    assert_eq!(orig[src], flipped[dst]);
                    assert_eq!(labels[src], lps_labels[dst]);
                }
            }
        }
        // LPS: the first storage axis now points to -x, the second to -y.
        assert!(lps.orientation.affine[0][0] < 0.0 && lps.orientation.affine[1][1] < 0.0);
    }

    #[test]
    fn thick_slices_average_three_and_sit_at_the_middle_slice() {
        let (v, labels) = small();
        let values = physical(&v);
        let (thick, (tv, tl)) = thick_slices(&v, &values, &labels).unwrap();
        assert_eq!(thick.dims, [4, 3, 2]); // 7 slices: 2 thick, 1 dropped
        assert_eq!(thick.spacing_mm, [2.0, 1.0, 4.5]);
        assert_eq!(world(&thick, [1, 2, 1]), world(&v, [1, 2, 4]));
        let p = 1 + 4 * 2;
        let mean = (values[p + 12 * 3] + values[p + 12 * 4] + values[p + 12 * 5]) / 3.0;
        assert_eq!(tv[p + 12], mean);
        assert_eq!(tl.len(), 24);
        assert_eq!(
            majority([Label::Gm, Label::Csf, Label::Gm]),
            Label::Gm,
            "2 of 3 wins"
        );
        assert_eq!(majority([Label::Gm, Label::Csf, Label::Wm]), Label::Head);
        assert_eq!(
            majority([Label::Outside, Label::Outside, Label::Csf]),
            Label::Head
        );
    }
}
