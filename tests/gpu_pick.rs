//! Depth picking (issue 31 item 2) on the GPU against the f64 twin (`ReferenceRaymarch::pick`):
//! at awkward sizes on an anisotropic grid, the point each pixel's ray first shows (DVR: the
//! accumulated opacity reaches the threshold) is the twin's; background pixels find nothing; a
//! MIP pick lands in the bright blob its pixel shows; bad requests are typed errors.

mod common;
mod hard_support;

use glam::DVec3;
use hard_support::{volume, with_twin};
use morphray::engine::pick::DEFAULT_PICK_THRESHOLD;
use morphray::engine::{Engine, PreparedVolume};
use morphray::gpu::GpuError;
use morphray::scene::geometry::VolumeGeometry;
use morphray::scene::{Classification, RenderMode, Scene, TissueClass, Window};
use morphray::volume::Samples;

const VIEW: [u32; 2] = [41, 31];
const DIMS: [usize; 3] = [29, 25, 21];
const SPACING: [f64; 3] = [1.1, 0.9, 1.3];

/// A tissue slab with a sine-folded top over air, and a bright ball in it: voxel values 20 (air),
/// 600 (tissue), 1000 (ball of radius 3 voxels at (14, 12, 6)).
fn slab_with_ball(engine: &mut Engine) -> PreparedVolume {
    let mut values = Vec::with_capacity(DIMS.iter().product());
    for k in 0..DIMS[2] {
        for j in 0..DIMS[1] {
            for i in 0..DIMS[0] {
                let top = 12.0 + 2.5 * (i as f64 * 0.6).sin();
                let inside = (k as f64) < top && (2..27).contains(&i) && (2..23).contains(&j);
                let d2 = (i as f64 - 14.0).powi(2)
                    + (j as f64 - 12.0).powi(2)
                    + (k as f64 - 6.0).powi(2);
                values.push(if d2 < 9.0 {
                    1000.0
                } else if inside {
                    600.0
                } else {
                    20.0
                });
            }
        }
    }
    let v = volume(DIMS, SPACING, Samples::from_f32(&values));
    engine.prepare(&v).unwrap()
}

fn scene() -> Scene {
    let window = |lo, hi| Some(Window { lo, hi, edge: 0.05 });
    let mut classification =
        Classification::with_windows([window(0.1, 0.4), window(0.4, 0.8), window(0.8, 1.05), None]);
    classification.show_only(&[TissueClass::Gm, TissueClass::Wm]);
    let mut scene = Scene::new(classification);
    scene.effects.shading = true;
    scene.camera.azimuth_deg = 25.0;
    scene.camera.elevation_deg = 50.0;
    scene
}

/// Every third pixel across, every fourth down.
fn pixels() -> Vec<[u32; 2]> {
    (0..VIEW[1])
        .step_by(4)
        .flat_map(|y| (0..VIEW[0]).step_by(3).map(move |x| [x, y]))
        .collect()
}

#[test]
fn a_dvr_pick_is_the_twins_first_visible_sample() {
    let mut engine = common::engine();
    let prepared = slab_with_ball(&mut engine);
    let s = scene();
    let derived = engine
        .derive(&prepared, s.effects.derivative_outputs().unwrap())
        .unwrap();
    let threshold = DEFAULT_PICK_THRESHOLD;
    let gpu: Vec<_> = pixels()
        .into_iter()
        .map(|p| {
            engine
                .pick(&prepared, Some(&derived), &s, VIEW, p, threshold)
                .unwrap()
        })
        .collect();
    let twin: Vec<Option<f64>> = with_twin(&engine, &prepared, Some(&derived), &s, VIEW, |r| {
        pixels()
            .into_iter()
            .map(|[x, y]| r.pick(x, y, f64::from(threshold)))
            .collect()
    });
    let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
    let rays = s.camera.rays(geometry.world_bounds(), VIEW[0], VIEW[1]);
    let (mut hits, mut misses, mut one_step) = (0, 0, 0);
    for ((p, g), t) in pixels().into_iter().zip(&gpu).zip(&twin) {
        match (g, t) {
            (None, None) => misses += 1,
            (Some(g), Some(t)) => {
                hits += 1;
                let (origin, direction) =
                    rays.ray(f64::from(p[0]), f64::from(p[1]), VIEW[0], VIEW[1]);
                let twin_point = origin + direction * *t;
                let error = g.world_mm.distance(twin_point);
                // f32 accumulation may cross the threshold one sample away from f64's.
                if error > 1e-3 {
                    one_step += 1;
                    assert!(
                        error <= 0.5 * 1.3 + 1e-3,
                        "pixel {p:?}: {error} mm from the twin"
                    );
                }
            }
            _ => panic!("pixel {p:?}: GPU {g:?}, twin {t:?}"),
        }
    }
    eprintln!("{hits} hits, {misses} misses, {one_step} a step from the twin's");
    assert!(hits >= 20 && misses >= 10, "{hits} hits, {misses} misses");
    assert!(
        one_step <= 2,
        "{one_step} picks a step away from the twin's"
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_mip_pick_lands_in_the_bright_ball_and_bad_requests_are_refused() {
    let mut engine = common::engine();
    let prepared = slab_with_ball(&mut engine);
    let mut s = scene();
    s.effects.mode = RenderMode::Mip;
    s.effects.shading = false;
    let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
    // The ball's centre, and the pixel whose ray passes closest to it.
    let a = prepared.affine;
    let index = [14.0, 12.0, 6.0];
    let centre = DVec3::from_array(std::array::from_fn(|r| {
        (0..3).map(|c| a[r][c] * index[c]).sum::<f64>() + a[r][3]
    }));
    let rays = s.camera.rays(geometry.world_bounds(), VIEW[0], VIEW[1]);
    let closest = (0..VIEW[1])
        .flat_map(|y| (0..VIEW[0]).map(move |x| [x, y]))
        .min_by(|a, b| {
            let d = |p: &[u32; 2]| {
                let (o, d) = rays.ray(f64::from(p[0]), f64::from(p[1]), VIEW[0], VIEW[1]);
                (centre - o).cross(d).length()
            };
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    let hit = engine
        .pick(&prepared, None, &s, VIEW, closest, DEFAULT_PICK_THRESHOLD)
        .unwrap()
        .expect("the MIP ray finds its maximum");
    let radius_mm = 3.0 * 1.3;
    assert!(
        hit.world_mm.distance(centre) < radius_mm,
        "the pick {:?} is {} mm from the ball's centre {centre:?}",
        hit.world_mm,
        hit.world_mm.distance(centre)
    );
    for (pixel, threshold) in [([VIEW[0], 0], 0.5), ([0, 0], 0.0), ([0, 0], f32::NAN)] {
        let e = engine.pick(&prepared, None, &s, VIEW, pixel, threshold);
        assert!(
            matches!(e, Err(GpuError::InvalidRequest(_))),
            "{pixel:?} {threshold}: {e:?}"
        );
    }
    common::assert_no_validation_errors(&engine);
}
