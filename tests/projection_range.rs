//! MIP and MinIP keep the brightest structures graded (issue 32 item 5): a projection scene is
//! normalized with the foreground's 99.99th percentile instead of the 99.5th, so a TOF-like
//! volume's vessels (about 1 % of the foreground, graded 600..1000) are not clipped to white,
//! while DVR keeps its range.

mod common;

use morphray::analysis::NormalizeMode;
use morphray::scene::{RenderMode, SceneRecipe};
use morphray::volume::{LinearMap, Samples, Volume};

/// A 48^3 TOF-like volume: tissue 100..140 in a sphere, and four straight vessels 2 voxels wide
/// whose brightness grades from 600 to 1000 along them.
fn tof_like() -> Volume {
    let n = 48usize;
    let mut values = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let c = |a: usize| a as f64 - 23.5;
                let r = (c(i).powi(2) + c(j).powi(2) + c(k).powi(2)).sqrt();
                let vessel = [(12, 12), (12, 34), (34, 12), (34, 34)]
                    .iter()
                    .any(|&(a, b): &(usize, usize)| i.abs_diff(a) <= 1 && j.abs_diff(b) <= 1);
                let v = if r > 22.0 {
                    0.0
                } else if vessel {
                    600.0 + 400.0 * k as f64 / n as f64
                } else {
                    100.0 + ((i * 7 + j * 13 + k * 3) % 40) as f64
                };
                values.push(v as i16);
            }
        }
    }
    let mut affine = [[0.0; 4]; 4];
    for (a, row) in affine.iter_mut().enumerate() {
        row[a] = 1.0;
    }
    Volume::from_voxels(
        "tof",
        [n; 3],
        Samples::from_i16(&values),
        affine,
        LinearMap::IDENTITY,
    )
    .unwrap()
}

/// The opened volume's I_norm range (physical lo, hi) for `mode`.
fn range(engine: &mut morphray::engine::Engine, volume: &Volume, mode: RenderMode) -> (f64, f64) {
    let mut recipe = SceneRecipe::default();
    recipe.effects.mode = mode;
    let opened = engine.open_volume(volume, [64, 64], &recipe).unwrap();
    let n = &opened.twin.prepared.normalization;
    (n.imin.unwrap(), n.imax.unwrap())
}

#[test]
fn projections_keep_the_brightest_vessels_inside_the_range() {
    let mut engine = common::engine_normalizing(NormalizeMode::Robust);
    let volume = tof_like();
    let (_, dvr_hi) = range(&mut engine, &volume, RenderMode::Dvr);
    let (_, mip_hi) = range(&mut engine, &volume, RenderMode::Mip);
    let (_, minip_hi) = range(&mut engine, &volume, RenderMode::MinIp);
    // The vessels' top (~990) is above DVR's robust end, which clips them, and inside the
    // projections' range.
    assert!(dvr_hi < 990.0, "DVR's range ends at {dvr_hi}");
    assert!(
        mip_hi >= 990.0,
        "MIP's range ends at {mip_hi}: the brightest vessels clip"
    );
    assert_eq!(mip_hi, minip_hi);
    // Still a robust range: not pushed up by one hot voxel.
    let mut hot = tof_like();
    let mut values: Vec<i16> = (0..hot.samples.len())
        .map(|i| hot.samples.get(i) as i16)
        .collect();
    values[48 * 48 * 24 + 48 * 24 + 24] = 30_000;
    hot.samples = Samples::from_i16(&values);
    let (_, hot_hi) = range(&mut engine, &hot, RenderMode::Mip);
    assert!(
        hot_hi < 2000.0,
        "one hot voxel moved MIP's range to {hot_hi}"
    );
    // --normalize minmax stays eq. 1 for every mode.
    let mut minmax = common::engine_normalizing(NormalizeMode::MinMax);
    assert_eq!(range(&mut minmax, &hot, RenderMode::Mip).1, 30_000.0);
    common::assert_no_validation_errors(&engine);
}
