//! Hard geometry on the GPU (NUMERICS.md row "ray-box with zero direction components, rays on
//! faces, grazing rays, camera inside"): the real raymarch against the f64 reference raymarcher
//! (whose `intersect_box` is tested on the CPU in tests/reference_raymarch.rs and
//! src/scene/geometry.rs) for cameras whose rays lie exactly on faces and edges, run through
//! corners, graze faces, or start inside the box; misses must take zero samples and show exactly
//! the background, and the number of samples the GPU takes must match the reference's.
//!
//! The table mapping every NUMERICS.md row to its tests is at the top of tests/hard_cases.rs.

mod common;
mod hard_support;

use common::volumes::{Rng, smooth_field};
use hard_support::{
    ALL_OUTPUTS, assert_finite_in_range, compare, derived_data, normalized, render, volume,
};
use morphray::engine::{Derived, Engine, PreparedVolume};
use morphray::reference::raymarch::{ReferenceDerived, ReferenceRaymarch, ReferenceVolume};
use morphray::scene::uniforms::GradientStats;
use morphray::scene::{
    Camera, Classification, Projection, RenderMode, Scene, TissueClass, VolumeGeometry, Window,
};
use morphray::volume::Samples;

/// 12^3 voxels of a smooth field whose border voxels are as visible as its interior (every
/// I_norm in (0, 1] lies in one of the windows), identity affine: the box is [-0.5, 11.5]^3 mm
/// and its centre 5.5.
const N: usize = 12;

fn setup(engine: &mut Engine) -> (PreparedVolume, Derived, Scene) {
    let dims = [N; 3];
    let mut rng = Rng(4242);
    let values: Vec<f32> = smooth_field(dims, &mut rng, 100.0, 900.0)
        .iter()
        .map(|&x| x as f32)
        .collect();
    let prepared = engine
        .prepare(&volume(dims, [1.0; 3], Samples::from_f32(&values)))
        .unwrap();
    let derived = engine.derive(&prepared, ALL_OUTPUTS).unwrap();
    let window = |lo, hi| Some(Window { lo, hi, edge: 0.02 });
    let mut classification = Classification::with_windows([
        window(0.0, 0.35),
        window(0.35, 0.7),
        window(0.7, 1.05),
        None,
    ]);
    classification.show_only(&[TissueClass::Csf, TissueClass::Gm, TissueClass::Wm]);
    let mut scene = Scene::new(classification);
    scene.background = [0.25, 0.5, 0.75];
    scene.jitter = false;
    // Every sample is taken: the GPU's and the reference's sample counts are comparable.
    scene.early_termination = 2.0;
    scene.effects.shading = true;
    (prepared, derived, scene)
}

struct Case {
    label: &'static str,
    camera: Camera,
    size: u32,
}

fn orthographic(azimuth_deg: f64, elevation_deg: f64, zoom: f64) -> Camera {
    Camera {
        azimuth_deg,
        elevation_deg,
        zoom,
        pan_mm: [0.0, 0.0],
        projection: Projection::Orthographic,
    }
}

fn perspective(azimuth_deg: f64, elevation_deg: f64, zoom: f64) -> Camera {
    Camera {
        azimuth_deg,
        elevation_deg,
        zoom,
        pan_mm: [0.0, 0.0],
        projection: Projection::Perspective { fov_y_deg: 30.0 },
    }
}

fn cases() -> Vec<Case> {
    // Body diagonal: elevation atan(1/sqrt 2) at azimuth 45 looks along (1, 1, 1) / sqrt 3.
    let diagonal = (1.0f64 / 2f64.sqrt()).atan().to_degrees();
    // Perspective zoom that puts the eye at distance R = 6 mm from the centre, i.e. on the face
    // y = 11.5 (zoom 1 puts it at R / sin 15 degrees).
    let on_face = 1.0 / 15f64.to_radians().sin();
    vec![
        // Orthographic along -y (forward (-0, -1, -0): signed zeros), zoom 0.5, 30 x 30: the
        // image spans +-12 mm, so columns 7 and 22 lie exactly on the faces x = 11.5 and
        // x = -0.5 and rows 7 and 22 on z = 11.5 and z = -0.5; pixels (7, 7), (22, 7), (7, 22) and
        // (22, 22) run along the box's edges. Everything is exact in f64 and f32.
        Case {
            label: "axis-aligned, rays on faces and edges",
            camera: orthographic(0.0, 0.0, 0.5),
            size: 30,
        },
        // Along -x, -z and +y: the camera's basis has components of cos(90 deg) = 6e-17 or
        // sin(180 deg) = 1.2e-16, above the 1e-20 threshold, so the slab test divides by them
        // (inverses near 1e16) instead of testing containment. 32 x 32 pixels: no ray lies on a
        // face (on a face these views disagree with the reference, see
        // `views_at_90_degrees_keep_face_rays_on_the_face`).
        Case {
            label: "nearly axis-aligned along x (6e-17 components)",
            camera: orthographic(90.0, 0.0, 0.5),
            size: 32,
        },
        Case {
            label: "nearly axis-aligned along z, from superior",
            camera: orthographic(0.0, 90.0, 0.5),
            size: 32,
        },
        Case {
            label: "nearly axis-aligned, from behind (azimuth 180)",
            camera: orthographic(180.0, 0.0, 0.5),
            size: 32,
        },
        // The centre pixel of an odd image looks along the body diagonal through the box centre,
        // so its ray passes through two opposite corners.
        Case {
            label: "through corners (perspective)",
            camera: perspective(45.0, diagonal, 1.0),
            size: 31,
        },
        Case {
            label: "through corners (orthographic)",
            camera: orthographic(45.0, diagonal, 1.0),
            size: 31,
        },
        // Grazing: a thousandth of a degree off the face planes.
        Case {
            label: "grazing, azimuth 0.001",
            camera: orthographic(0.001, 0.0, 0.5),
            size: 30,
        },
        Case {
            label: "grazing, elevation 89.999",
            camera: orthographic(30.0, 89.999, 0.5),
            size: 30,
        },
        // Eye on the face y = 11.5 (up to rounding), and at the box centre (zoom 1000: the
        // eye is 0.023 mm from the centre; the camera cannot sit exactly on the look-at point).
        Case {
            label: "camera on a face",
            camera: perspective(0.0, 0.0, on_face),
            size: 24,
        },
        Case {
            label: "camera at the centre",
            camera: perspective(20.0, 10.0, 1000.0),
            size: 24,
        },
        Case {
            label: "camera at the centre, axis-aligned",
            camera: perspective(0.0, 0.0, 1000.0),
            size: 24,
        },
    ]
}

#[test]
fn gpu_rays_on_faces_edges_corners_grazing_and_from_inside_match_the_reference() {
    let mut engine = common::engine();
    let (prepared, derived, base) = setup(&mut engine);
    let norm: Vec<f64> = normalized(&engine, &prepared)
        .iter()
        .map(|&v| v as f64)
        .collect();
    let data = derived_data(&engine, &derived);
    let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
    let reference_volume = ReferenceVolume::new(prepared.dims, &norm).unwrap();
    let refs = ReferenceDerived {
        gradient_magnitude: Some(&data.magnitude),
        curvature: data.curvature.as_deref(),
        normals: data.normals.as_deref(),
    };
    let stats: GradientStats = derived.stats;
    for case in cases() {
        for mode in [RenderMode::Dvr, RenderMode::Mip] {
            let mut scene = base;
            scene.camera = case.camera;
            scene.effects.mode = mode;
            let label = format!("{} ({mode:?})", case.label);
            let s = case.size;
            let mut target = engine
                .render_target(s, s, ash::vk::Format::R32G32B32A32_SFLOAT)
                .unwrap();
            target.count_samples = true;
            let d = (mode == RenderMode::Dvr).then_some(&derived);
            let frame = engine.render(&mut target, &prepared, d, &scene).unwrap();
            let gpu: Vec<[f64; 4]> = frame
                .values
                .chunks_exact(4)
                .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
                .collect();
            assert_finite_in_range(&label, &gpu, 1.0 + 1e-6);
            let raymarch =
                ReferenceRaymarch::new(&scene, &geometry, &stats, &reference_volume, &refs, s, s)
                    .unwrap();
            let cpu = raymarch.render();
            let background = scene.background.map(f64::from);
            let (mut reference_samples, mut hits, mut misses) = (0u64, 0, 0);
            for y in 0..s {
                for x in 0..s {
                    let plan = raymarch.ray(x, y);
                    reference_samples += u64::from(plan.count);
                    let px = gpu[(y * s + x) as usize];
                    if plan.hit.is_none() {
                        // A miss takes no sample: exactly the background (the GPU agrees on
                        // hit/miss; a disagreement shows up in the image comparison too).
                        misses += 1;
                        if mode == RenderMode::Dvr {
                            assert!(
                                (0..3).all(|c| (px[c] - background[c]).abs() < 1e-6),
                                "{label}: pixel ({x}, {y}) misses but is {px:?}"
                            );
                        }
                    } else {
                        hits += 1;
                    }
                }
            }
            assert!(hits > 0, "{label}: no ray hits the box");
            // Samples: the GPU computes t_near, t_far and the count in f32, the reference in
            // f64; a count may differ by one where (t_far - start) / dt lands within f32
            // rounding of an integer, and a ray exactly on a face may be a hit in one and a miss
            // in the other only if f32 rounding moved its origin (it does not here: the face
            // positions are exact). So |GPU - reference| <= one sample per pixel that hits.
            let gpu_samples = frame.samples.unwrap().marched;
            let diff = gpu_samples.abs_diff(reference_samples);
            // The image: the comparison bounds of tests/gpu_raymarch.rs (hardware trilinear
            // weights, f16 derived data, window slopes), for the pixels' RGB.
            let (psnr, p99, max) = compare(&gpu, &cpu, None);
            eprintln!(
                "{label}: {hits} hits, {misses} misses; samples GPU {gpu_samples} vs f64 \
                 {reference_samples}; PSNR {psnr:.1} dB, p99 {p99:.4}, max {max:.4}"
            );
            assert!(
                diff <= hits,
                "{label}: {gpu_samples} samples vs {reference_samples}"
            );
            assert!(
                psnr >= 35.0 && p99 <= 0.05 && max <= 0.25,
                "{label}: PSNR {psnr:.1}, p99 {p99:.4}, max {max:.4}"
            );
        }
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn gpu_rays_exactly_on_a_face_see_the_border_voxels_like_rays_just_inside() {
    let mut engine = common::engine();
    let (prepared, derived, mut scene) = setup(&mut engine);
    // Orthographic along -y at zoom 0.5 on 30 x 30 pixels: column 7 lies on the face x = 11.5
    // and column 22 on x = -0.5. Clamp-to-edge: there, and anywhere in the outer half voxel, both
    // trilinear taps along x are the border voxel, so a face ray sees what a ray 1e-3 mm inside
    // sees. Pan moves the look-at point along `right` = -x, so pan +1e-3 moves column 7 inside
    // and pan -1e-3 column 22 (f32 keeps 1e-3 mm at these magnitudes).
    scene.camera = orthographic(0.0, 0.0, 0.5);
    let on_face = render(&mut engine, &prepared, Some(&derived), &scene, 30, 30);
    let background = scene.background.map(f64::from);
    for (x, pan) in [(7u32, 1e-3), (22, -1e-3)] {
        scene.camera.pan_mm = [pan, 0.0];
        let inside = render(&mut engine, &prepared, Some(&derived), &scene, 30, 30);
        scene.camera.pan_mm = [-pan, 0.0];
        let outside = render(&mut engine, &prepared, Some(&derived), &scene, 30, 30);
        for y in 7..23u32 {
            let i = (y * 30 + x) as usize;
            let (a, b) = (on_face[i], inside[i]);
            assert!(
                (0..3).any(|c| (a[c] - background[c]).abs() > 1e-3),
                "face ray ({x}, {y}) shows nothing: {a:?}"
            );
            // Same sample positions along y, the same taps along x: only the f32 rounding of a
            // 1e-3 mm shift in the ray origin remains.
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() <= 1e-4,
                    "({x}, {y}): on the face {a:?}, just inside {b:?}"
                );
            }
            // 1e-3 mm outside: a miss, exactly the background.
            let o = outside[i];
            assert!(
                (0..3).all(|c| (o[c] - background[c]).abs() < 1e-6),
                "({x}, {y}) just outside: {o:?}"
            );
        }
    }
    common::assert_no_validation_errors(&engine);
}

/// KNOWN FAILURE (reported, not fixed here: the fix belongs in src/scene/camera.rs). The views
/// at azimuth 90 and 180 and elevation 90 are meant to be axis-aligned, but `Camera::rays` builds
/// their basis from `sin`/`cos` of radians, so their direction has components of 6e-17 or 1.2e-16
/// instead of 0, and the f64 look-at point picks up a rounding of 2 ulps. A ray meant to lie on
/// a face then drifts out through it (t_far = 0: a miss) or in (a hit), depending on f32 vs f64
/// rounding of its origin: on the GPU one face column of the image is background and the other
/// shows the full chord, in the f64 reference the two columns split the chord at t = 29 mm
/// (PSNR 27 dB, max error 0.46 at azimuth 90). At azimuth 0 (exact signed zeros) both faces are
/// hits in both and agree to 1e-7. Fixed by exact sin/cos of degrees at multiples of 90 degrees
/// in `Camera::rays` (`camera::sin_cos_degrees`); this test keeps it fixed.
#[test]
fn views_at_90_degrees_keep_face_rays_on_the_face() {
    let mut engine = common::engine();
    let (prepared, derived, base) = setup(&mut engine);
    for (azimuth, elevation) in [(90.0, 0.0), (180.0, 0.0), (0.0, 90.0)] {
        let mut scene = base;
        scene.camera = orthographic(azimuth, elevation, 0.5);
        let gpu = render(&mut engine, &prepared, Some(&derived), &scene, 30, 30);
        let cpu = hard_support::reference(&engine, &prepared, Some(&derived), &scene, 30, 30);
        let background = scene.background.map(f64::from);
        // Columns 7 and 22 lie on two opposite faces (exactly, in exact arithmetic): both must
        // be hits, as they are at azimuth 0.
        for y in 7..23usize {
            for x in [7usize, 22] {
                let px = gpu[y * 30 + x];
                assert!(
                    (0..3).any(|c| (px[c] - background[c]).abs() > 1e-3),
                    "azimuth {azimuth}, elevation {elevation}: face ray ({x}, {y}) missed"
                );
            }
        }
        let (psnr, _, max) = compare(&gpu, &cpu, None);
        assert!(
            psnr >= 35.0 && max <= 0.25,
            "azimuth {azimuth}, elevation {elevation}: PSNR {psnr:.1}, max {max:.4}"
        );
    }
    common::assert_no_validation_errors(&engine);
}
