//! Lighting, depth cues and the cut-away (issue 34 items 2 and 3) on the GPU against the f64 twin
//! (`reference::raymarch`), at awkward sizes on an anisotropic grid: the studio model, the
//! matcap (built in and a user's image), the surface's occlusion and shadow, and the solid cap of a cut face; and what each must do to the
//! picture (cues darken a fold and are free when off, a cut face shows its tissue).

mod common;
mod hard_support;

use common::volumes::{Rng, smooth_field};
use hard_support::{assert_finite_in_range, compare, reference, render, volume};
use morphray::engine::{Engine, PreparedVolume};
use morphray::scene::{
    Classification, Cutaway, LightModel, Lighting, Scene, TissueClass, VolumeGeometry, Window,
};
use morphray::volume::Samples;

const W: u32 = 37;
const H: u32 = 29;

/// A folded surface: a slab of tissue (I_norm ~0.55..0.85) whose top is a sine fold with a deep
/// groove, over air, with a smooth texture; 31 x 27 x 23 voxels of 1 x 1.2 x 0.9 mm.
fn folded(engine: &mut Engine) -> PreparedVolume {
    let dims = [31usize, 27, 23];
    let texture = smooth_field(dims, &mut Rng(7), 0.0, 60.0);
    let mut values = Vec::with_capacity(texture.len());
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let x = i as f64 / dims[0] as f64;
                let top =
                    15.0 + 3.0 * (x * 12.0).sin() - if (12..16).contains(&i) { 8.0 } else { 0.0 };
                let inside = (k as f64) < top && (3..28).contains(&i) && (3..24).contains(&j);
                let t = texture[i + dims[0] * (j + dims[1] * k)];
                values.push(if inside { 600.0 + t as f32 } else { 20.0 });
            }
        }
    }
    values[0] = 0.0;
    values[1] = 1000.0;
    let v = volume(dims, [1.0, 1.2, 0.9], Samples::from_f32(&values));
    engine.prepare(&v).unwrap()
}

fn scene() -> Scene {
    let window = |lo, hi| Some(Window { lo, hi, edge: 0.05 });
    let mut classification = Classification::with_windows([
        window(0.1, 0.45),
        window(0.45, 0.62),
        window(0.62, 1.05),
        None,
    ]);
    classification.show_only(&[TissueClass::Gm, TissueClass::Wm]);
    let mut scene = Scene::new(classification);
    scene.effects.shading = true;
    scene.camera.azimuth_deg = 20.0;
    scene.camera.elevation_deg = 55.0;
    scene.background = [0.1, 0.1, 0.12];
    scene
}

/// GPU and twin of `scene`, compared: PSNR >= 60 dB and the 99th percentile within 1e-3 (on
/// lavapipe they agree to 1e-5, PSNR >= 124 dB; the margin is for a device whose f32 rounding
/// moves a ray's surface sample, the one place a pixel can jump).
fn gpu_matches_twin(
    engine: &mut Engine,
    prepared: &PreparedVolume,
    scene: &Scene,
    label: &str,
) -> Vec<[f64; 4]> {
    let derived = engine
        .derive(prepared, scene.effects.derivative_outputs().unwrap())
        .unwrap();
    let gpu = render(engine, prepared, Some(&derived), scene, W, H);
    assert_finite_in_range(label, &gpu, 1.0 + 1e-6);
    let cpu = reference(engine, prepared, Some(&derived), scene, W, H);
    let (psnr, p99, max) = compare(&gpu, &cpu, None);
    eprintln!("{label}: PSNR {psnr:.1} dB, p99 {p99:.2e}, max {max:.2e}");
    assert!(
        psnr >= 60.0 && p99 <= 1e-3,
        "{label}: PSNR {psnr:.1} dB, p99 {p99:.4}, max {max:.4}"
    );
    gpu
}

fn luminance(image: &[[f64; 4]]) -> f64 {
    image
        .iter()
        .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
        .sum::<f64>()
        / image.len() as f64
}

#[test]
fn studio_lighting_and_depth_cues_match_the_twin() {
    let mut engine = common::engine();
    let prepared = folded(&mut engine);
    let mut studio = scene();
    studio.effects.lighting.model = LightModel::Studio;
    let plain = gpu_matches_twin(&mut engine, &prepared, &studio, "studio");
    studio.effects.lighting = Lighting::STILL;
    let cued = gpu_matches_twin(&mut engine, &prepared, &studio, "studio + cues");
    // The cues only darken, and they do darken the fold.
    for (i, (c, p)) in cued.iter().zip(&plain).enumerate() {
        assert!(
            c[0] <= p[0] + 1e-4,
            "pixel {i}: cues brightened {p:?} -> {c:?}"
        );
    }
    // ... and darken the groove: some pixel by a visible step (measured on lavapipe: mean
    // luminance 0.1841 -> 0.1804, the most darkened pixel by 0.095).
    let darkening = cued
        .iter()
        .zip(&plain)
        .map(|(c, p)| luminance(&[*p]) - luminance(&[*c]))
        .fold(0.0, f64::max);
    assert!(
        luminance(&cued) < luminance(&plain) - 0.002 && darkening > 0.05,
        "cues darkened too little: mean {} -> {}, at most {darkening} at a pixel",
        luminance(&plain),
        luminance(&cued)
    );
    // Cues compiled in with zero strength leave the picture as it was.
    studio.cues.occlusion = 0.0;
    studio.cues.shadow = 0.0;
    let derived = engine
        .derive(&prepared, studio.effects.derivative_outputs().unwrap())
        .unwrap();
    let zero = render(&mut engine, &prepared, Some(&derived), &studio, W, H);
    let (_, _, max) = compare(&zero, &plain, None);
    assert!(max <= 1e-6, "zero-strength cues changed a pixel by {max}");
    common::assert_no_validation_errors(&engine);
}

#[test]
fn the_headlight_model_and_cues_without_shading_match_the_twin() {
    let mut engine = common::engine();
    let prepared = folded(&mut engine);
    let mut s = scene();
    s.effects.lighting.depth_cues = true;
    gpu_matches_twin(&mut engine, &prepared, &s, "headlight + cues");
    s.effects.shading = false;
    gpu_matches_twin(&mut engine, &prepared, &s, "unshaded + cues");
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_cutaway_shows_its_cut_face_solid_and_matches_the_twin() {
    let mut engine = common::engine();
    // A ball of uniform tissue: its interior has no gradient, so eq. 4 makes a cut through it
    // see-through; the cap must make the cut face opaque in the tissue's colour.
    let dims = [33usize, 29, 25];
    let spacing = [1.0, 1.1, 1.3];
    let mut values = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let d = [i, j, k]
                    .iter()
                    .zip(dims)
                    .zip(spacing)
                    .map(|((&c, n), s)| ((c as f64 - (n as f64 - 1.0) / 2.0) * s).powi(2))
                    .sum::<f64>()
                    .sqrt();
                values.push(if d < 13.0 { 800.0 } else { 10.0 });
            }
        }
    }
    values[0] = 0.0;
    values[1] = 1000.0;
    let prepared = engine
        .prepare(&volume(dims, spacing, Samples::from_f32(&values)))
        .unwrap();
    let mut s = scene();
    s.camera.azimuth_deg = 0.0;
    s.camera.elevation_deg = 0.0;
    s.jitter = false;
    let whole = gpu_matches_twin(&mut engine, &prepared, &s, "whole ball");
    s.cutaway = Some(Cutaway::default());
    let cut = gpu_matches_twin(&mut engine, &prepared, &s, "cut ball");
    let centre = ((H / 2) * W + W / 2) as usize;
    let wm = s.classification.tissues[TissueClass::Wm as usize].colour;
    for c in 0..3 {
        assert!(
            (cut[centre][c] - f64::from(wm[c])).abs() < 0.02,
            "cut face at the centre {:?} is not the tissue's colour {wm:?} (whole: {:?})",
            cut[centre],
            whole[centre]
        );
    }
    // The geometry of the cut: the plane goes through the centre facing the camera.
    let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
    let rays = s.camera.rays(geometry.world_bounds(), W, H);
    let clip = s.frame_clip(&rays, geometry.world_bounds());
    assert_eq!(clip.planes.iter().flatten().count(), 1);
    common::assert_no_validation_errors(&engine);
}

/// A 64-pixel matcap (as a user's PNG would be, resampled to 256): redder where the surface faces
/// up, greener where it faces left, in smooth ramps (neighbouring texels differ by under 1/255,
/// so a texel the GPU's f32 picks beside the twin's moves a pixel by less than that).
fn ramp_matcap() -> morphray::scene::matcap::MatcapImage {
    let side = 64u32;
    let rgba: Vec<u8> = (0..side * side)
        .flat_map(|i| {
            let (x, y) = (i % side, i / side);
            let up = 230 - (170 * y / side) as u8;
            let left = 220 - (130 * x / side) as u8;
            [up, left, 160, 255]
        })
        .collect();
    morphray::scene::matcap::MatcapImage::from_rgba("ramps", side, side, &rgba).unwrap()
}

#[test]
fn the_matcap_model_matches_the_twin_with_the_built_in_and_a_users_image() {
    let mut engine = common::engine();
    let prepared = folded(&mut engine);
    let mut s = scene();
    s.effects.lighting.model = LightModel::Matcap;
    let clay = gpu_matches_twin(&mut engine, &prepared, &s, "matcap clay");
    s.effects.lighting.depth_cues = true;
    gpu_matches_twin(&mut engine, &prepared, &s, "matcap clay + cues");
    s.effects.lighting.depth_cues = false;
    engine.set_matcap(ramp_matcap());
    let ramps = gpu_matches_twin(&mut engine, &prepared, &s, "matcap ramps");
    // The image is what lights the picture: the user's matcap changes it.
    let (_, _, max) = compare(&ramps, &clay, None);
    assert!(
        max > 0.1,
        "the user's matcap changed no pixel by more than {max}"
    );
    common::assert_no_validation_errors(&engine);
}
