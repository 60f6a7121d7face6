use super::*;
use crate::volume::{LinearMap, Samples};

/// A 13x11x7 grid on an oblique affine (30 degrees about z, 1.1 x 0.9 x 2.3 mm) whose values
/// are a ramp through a scaling (slope 2, intercept -1000), one voxel NaN.
fn oblique() -> Volume {
    let dims = [13, 11, 7];
    let (s, c) = (0.5f64, 0.75f64.sqrt());
    let h = [1.1, 0.9, 2.3];
    let affine = [
        [c * h[0], -s * h[1], 0.0, -5.0],
        [s * h[0], c * h[1], 0.0, 3.0],
        [0.0, 0.0, h[2], -7.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut values: Vec<f32> = (0..dims.iter().product::<usize>())
        .map(|i| (i % 97) as f32)
        .collect();
    values[5 + 13 * (4 + 11 * 3)] = f32::NAN;
    let map = LinearMap {
        slope: 2.0,
        intercept: -1000.0,
    };
    Volume::from_voxels("oblique", dims, Samples::from_f32(&values), affine, map).unwrap()
}

/// The statistics by visiting every voxel (no bounding box).
fn brute(volume: &Volume, region: &Region) -> (u64, f64, f64, f64, f64) {
    let m = DMat4::from_cols_array_2d(&volume.orientation.affine).transpose();
    let [nx, ny, nz] = volume.dims;
    let mut v = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = (m * DVec4::new(i as f64, j as f64, k as f64, 1.0)).truncate();
                let x = volume
                    .to_physical
                    .apply(volume.samples.get(i + nx * (j + ny * k)));
                if region.contains(p) && x.is_finite() {
                    v.push(x);
                }
            }
        }
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let min = v.iter().cloned().fold(f64::INFINITY, f64::min);
    let max = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    (v.len() as u64, mean, sd, min, max)
}

#[test]
fn spheres_and_boxes_match_a_visit_of_every_voxel_on_an_oblique_grid() {
    let volume = oblique();
    let voxel = 1.1 * 0.9 * 2.3;
    for region in [
        Region::Sphere {
            centre: [0.0, 6.0, -1.0],
            radius_mm: 4.7,
        },
        Region::Box {
            a: [3.0, 12.0, 4.0],
            b: [-4.0, 2.0, -6.5],
        },
        // Larger than the volume: clipped, every finite voxel.
        Region::Sphere {
            centre: [0.0, 0.0, 0.0],
            radius_mm: 1e6,
        },
    ] {
        let stats = roi_stats(&volume, &region);
        let (n, mean, sd, min, max) = brute(&volume, &region);
        assert!(n > 5, "{region:?} holds {n}");
        assert_eq!(stats.voxels, n, "{region:?}");
        assert!((stats.volume_mm3 - n as f64 * voxel).abs() < 1e-9 * n as f64);
        for (got, want) in [
            (stats.mean, mean),
            (stats.sd, sd),
            (stats.min, min),
            (stats.max, max),
        ] {
            let got = got.expect("a value");
            assert!(
                (got - want).abs() <= 1e-9 * want.abs().max(1.0),
                "{got} vs {want}"
            );
        }
    }
    let all = roi_stats(
        &volume,
        &Region::Sphere {
            centre: [0.0; 3],
            radius_mm: 1e6,
        },
    );
    assert_eq!((all.voxels, all.skipped), (13 * 11 * 7 - 1, 1));
}

#[test]
fn empty_and_hostile_regions_hold_nothing() {
    let volume = oblique();
    for region in [
        Region::Sphere {
            centre: [500.0, 0.0, 0.0],
            radius_mm: 3.0,
        },
        Region::Sphere {
            centre: [0.0, 0.0, 0.0],
            radius_mm: f64::NAN,
        },
        Region::Box {
            a: [f64::INFINITY, 0.0, 0.0],
            b: [0.0; 3],
        },
        Region::Sphere {
            centre: [0.0, 6.0, -1.0],
            radius_mm: 0.0,
        },
    ] {
        let stats = roi_stats(&volume, &region);
        assert!(stats.voxels <= 1, "{region:?}: {stats:?}");
        if stats.voxels == 0 {
            assert_eq!((stats.mean, stats.sd, stats.min), (None, None, None));
        }
    }
}
