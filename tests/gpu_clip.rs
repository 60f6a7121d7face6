//! Crop box and clip planes (issue 16 item 2) on the GPU, against the f64 reference and against
//! geometry: a clipped scene renders like the reference (DVR with empty-space skipping, MIP, a
//! colour map), a clip plane removes exactly its side and rays start exactly on it, and a clipped
//! volume renders the same bricked and whole.

mod common;

use ash::vk;
use common::volumes::volume;
use glam::DVec3;
use morphray::analysis::analyze;
use morphray::engine::readback::read_image;
use morphray::engine::{Derived, Engine, EngineConfig, PreparedVolume};
use morphray::gpu::{Access, DeviceConfig, Validation};
use morphray::reference::raymarch::{ReferenceDerived, ReferenceRaymarch, ReferenceVolume};
use morphray::scene::uniforms::GradientStats;
use morphray::scene::{
    Classification, Clip, ClipPlane, Colormap, Projection, RenderMode, Scene, SceneRecipe,
    VolumeGeometry,
};
use morphray::volume::Samples;
use morphray::volume::phantom::{PhantomSpec, generate};

struct Prepared {
    prepared: PreparedVolume,
    derived: Option<Derived>,
    scene: Scene,
}

fn prepare(
    engine: &mut Engine,
    volume: &morphray::volume::Volume,
    edit: impl Fn(&mut Scene),
) -> Prepared {
    let prepared = engine.prepare(volume).unwrap();
    let (imin, imax) = (
        prepared.normalization.imin.unwrap(),
        prepared.normalization.imax.unwrap(),
    );
    let report = analyze(
        &prepared.histogram,
        imin,
        imax,
        prepared.voxel_count as usize,
        0,
    );
    let mut scene = Scene::new(Classification::from_tissue_windows(
        &report.adaptive_windows,
    ));
    scene.camera.azimuth_deg = 35.0;
    scene.camera.elevation_deg = 25.0;
    edit(&mut scene);
    let derived = scene
        .effects
        .derivative_outputs()
        .map(|o| engine.derive(&prepared, o).unwrap());
    Prepared {
        prepared,
        derived,
        scene,
    }
}

fn gpu_render(engine: &mut Engine, p: &Prepared, w: u32, h: u32) -> Vec<[f64; 4]> {
    let mut target = engine
        .render_target(w, h, vk::Format::R32G32B32A32_SFLOAT)
        .unwrap();
    let frame = engine
        .render(&mut target, &p.prepared, p.derived.as_ref(), &p.scene)
        .unwrap();
    frame
        .values
        .chunks_exact(4)
        .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
        .collect()
}

/// The reference raymarch on the GPU's own normalized and derived volumes, and the geometry.
fn reference_pixels(
    engine: &Engine,
    p: &Prepared,
    w: u32,
    h: u32,
) -> (Vec<[f64; 4]>, Vec<RayCheck>) {
    let device = engine.device();
    let norm: Vec<f64> = read_image(device, &p.prepared.normalized, Access::ComputeSampled)
        .unwrap()
        .values
        .iter()
        .map(|&v| v as f64)
        .collect();
    let geometry = VolumeGeometry::new(p.prepared.dims, p.prepared.affine).unwrap();
    let volume = ReferenceVolume::new(p.prepared.dims, &norm).unwrap();
    let mut magnitude = Vec::new();
    let mut stats = GradientStats {
        max_magnitude: 0.0,
        tau: 0.0,
    };
    if let Some(d) = &p.derived {
        stats = d.stats;
        if let Some(g) = &d.volumes.gradient {
            let g = read_image(device, g, Access::ComputeSampled).unwrap();
            let sg = d.volumes.store_scale[0] as f64;
            for texel in g.values.chunks_exact(g.channels) {
                magnitude.push(texel[0] as f64 / sg);
            }
        }
    }
    let derived = ReferenceDerived {
        gradient_magnitude: (!magnitude.is_empty()).then_some(magnitude.as_slice()),
        curvature: None,
        normals: None,
    };
    let r = ReferenceRaymarch::new(&p.scene, &geometry, &stats, &volume, &derived, w, h).unwrap();
    let mut rays = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let plan = r.ray(x, y);
            let world = |t: f64| {
                geometry
                    .index_to_world
                    .transform_point3(plan.origin + plan.direction * t)
            };
            rays.push(RayCheck {
                entry: plan.hit.map(|(t0, _)| world(t0)),
                exit: plan.hit.map(|(_, t1)| world(t1)),
                first_sample: (plan.count > 0).then(|| world(plan.parameter(0))),
                start_offset_mm: plan.hit.map(|(t0, _)| plan.start - t0),
                count: plan.count,
            });
        }
    }
    (r.render(), rays)
}

struct RayCheck {
    entry: Option<DVec3>,
    exit: Option<DVec3>,
    first_sample: Option<DVec3>,
    start_offset_mm: Option<f64>,
    count: u32,
}

/// (PSNR over RGB with peak 1, max abs error).
fn compare(a: &[[f64; 4]], b: &[[f64; 4]]) -> (f64, f64) {
    let errors: Vec<f64> = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c].min(1.0)).abs()))
        .collect();
    let mse = errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64;
    let max = errors.iter().copied().fold(0.0, f64::max);
    (10.0 * (1.0 / mse.max(1e-20)).log10(), max)
}

fn plane(normal: [f64; 3], offset_mm: f64) -> ClipPlane {
    ClipPlane { normal, offset_mm }
}

#[test]
fn cropped_and_clipped_scenes_match_the_reference_in_dvr_mip_and_with_a_colour_map() {
    let mut engine = common::engine();
    // 29 voxels: not a multiple of the 8^3 bricks or the 8x8 tiles.
    let volume = generate(&PhantomSpec::cube(29)).unwrap().volume;
    let mut clip = Clip {
        crop: [[0.1, 0.85], [0.0, 0.7], [0.2, 1.0]],
        ..Clip::default()
    };
    // Two oblique planes through the volume (world mm; the phantom's centre is near 14 mm).
    clip.add_plane(plane([1.0, 0.4, -0.2], -10.0)).unwrap();
    clip.add_plane(plane([-0.3, 0.2, -1.0], 20.0)).unwrap();
    let cases: [(&str, RenderMode, Option<Colormap>); 4] = [
        ("dvr", RenderMode::Dvr, None),
        ("dvr+viridis", RenderMode::Dvr, Some(Colormap::Viridis)),
        ("mip", RenderMode::Mip, None),
        ("mip+hot", RenderMode::Mip, Some(Colormap::Hot)),
    ];
    for (label, mode, colormap) in cases {
        let p = prepare(&mut engine, &volume, |s| {
            s.effects.mode = mode;
            s.clip = clip;
            s.colormap = colormap;
        });
        let unclipped = prepare(&mut engine, &volume, |s| {
            s.effects.mode = mode;
            s.colormap = colormap;
        });
        let (w, h) = (64, 48);
        let gpu = gpu_render(&mut engine, &p, w, h);
        let (cpu, rays) = reference_pixels(&engine, &p, w, h);
        let (psnr, max) = compare(&gpu, &cpu);
        eprintln!("{label}: PSNR {psnr:.1} dB, max {max:.4}");
        assert!(
            psnr >= 40.0 && max <= 0.25,
            "{label}: PSNR {psnr:.1}, max {max:.4}"
        );
        // The clip changes the picture (it is not a no-op) and every ray's samples lie in the
        // kept region.
        let full = gpu_render(&mut engine, &unclipped, w, h);
        let (psnr_full, _) = compare(&gpu, &full);
        assert!(
            psnr_full < 30.0,
            "{label}: clipping changed nothing ({psnr_full:.1} dB)"
        );
        for ray in &rays {
            for point in [ray.entry, ray.exit].into_iter().flatten() {
                for pl in clip.planes.iter().flatten() {
                    let side = DVec3::from_array(pl.normal).dot(point) + pl.offset_mm;
                    assert!(
                        side >= -1e-9,
                        "{label}: a ray reaches the removed side ({side})"
                    );
                }
            }
        }
    }
    common::assert_no_validation_errors(&engine);
}

/// 17 x 13 x 11 voxels, anisotropic, I = j (a ramp along world y), so MIP along -y reads the
/// value where each ray starts.
fn ramp_along_y() -> morphray::volume::Volume {
    let dims = [17usize, 13, 11];
    let mut values = Vec::with_capacity(dims.iter().product());
    for _k in 0..dims[2] {
        for j in 0..dims[1] {
            values.extend(std::iter::repeat_n(j as f32, dims[0]));
        }
    }
    volume(dims, [1.0, 1.5, 0.8], Samples::from_f32(&values))
}

#[test]
fn a_clip_plane_removes_exactly_its_side_and_rays_start_on_the_cut() {
    let mut engine = common::engine();
    let volume = ramp_along_y();
    let (w, h) = (64, 48);
    let probe = prepare(&mut engine, &volume, |_| {});
    let geometry = VolumeGeometry::new(probe.prepared.dims, probe.prepared.affine).unwrap();
    let at = |i: f64, j: f64, k: f64| {
        geometry
            .index_to_world
            .transform_point3(DVec3::new(i, j, k))
    };
    // Cut at world y between voxel rows 7 and 8 (keep y <= cut), and at world x through the
    // middle of the volume (keep x <= x_cut): a corner of the picture must go.
    let y_cut = at(0.0, 7.3, 0.0).y;
    let x_cut = at(8.2, 0.0, 0.0).x;
    let p = prepare(&mut engine, &volume, |s| {
        s.effects.mode = RenderMode::Mip;
        s.camera.azimuth_deg = 0.0; // anterior view: rays along -y
        s.camera.elevation_deg = 0.0;
        s.camera.projection = Projection::Orthographic;
        s.jitter = false;
        s.clip.add_plane(plane([0.0, -1.0, 0.0], y_cut)).unwrap();
        s.clip
            .add_plane(plane([-2.0, 0.0, 0.0], 2.0 * x_cut))
            .unwrap();
    });
    let gpu = gpu_render(&mut engine, &p, w, h);
    let (cpu, rays) = reference_pixels(&engine, &p, w, h);
    let step_mm = p.scene.sanitized_step_voxels() * geometry.voxel_mm;
    let (mut kept, mut removed) = (0, 0);
    for (i, ray) in rays.iter().enumerate() {
        // Orthographic along -y: a pixel's world x is constant along its ray.
        let Some(x) = ray.first_sample.map(|q| q.x).or(ray.entry.map(|q| q.x)) else {
            continue;
        };
        if x > x_cut + 1e-6 {
            panic!("pixel {i}: a ray at x = {x} beyond the cut x <= {x_cut} took samples");
        }
        let entry = ray.entry.unwrap();
        // Rays enter through the y cut (the front face of the kept part), exactly on it.
        assert!(
            (entry.y - y_cut).abs() < 1e-9,
            "pixel {i}: entry y {} vs cut {y_cut}",
            entry.y
        );
        assert!((ray.start_offset_mm.unwrap() - 0.5 * step_mm).abs() < 1e-12);
        assert!(ray.count > 0);
        // The first sample, half a step behind the cut, holds the ray's maximum: MIP reads it.
        let first = ray.first_sample.unwrap();
        let expected =
            (first.y - at(0.0, 0.0, 0.0).y) / (at(0.0, 12.0, 0.0).y - at(0.0, 0.0, 0.0).y);
        for c in 0..3 {
            // Hardware trilinear weights carry 8 bits of sub-texel precision: 1/256 of a row step
            // of 1/12 in I_norm.
            assert!(
                (gpu[i][c] - expected).abs() < 2e-3,
                "pixel {i}: GPU {} vs the value at the cut {expected}",
                gpu[i][c]
            );
            // The reference reads the R16 normalized volume: 1/65535 per voxel.
            assert!(
                (cpu[i][c] - expected).abs() < 2e-5,
                "pixel {i}: reference {} vs {expected}",
                cpu[i][c]
            );
        }
        kept += 1;
    }
    // Pixels whose rays fall on the removed side (x > x_cut) are the background, exactly.
    for (i, ray) in rays.iter().enumerate() {
        if ray.count == 0 {
            assert_eq!(
                gpu[i][..3],
                [0.0; 3],
                "pixel {i}: removed side is not background"
            );
            removed += 1;
        }
    }
    assert!(
        kept > 200 && removed > 200,
        "kept {kept}, removed {removed}"
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_cropped_volume_renders_the_same_bricked_and_whole() {
    let dims = [37usize, 35, 33];
    let mut values = Vec::with_capacity(dims.iter().product());
    for _ in 0..dims[1] * dims[2] {
        values.extend((0..dims[0]).map(|x| 1000.0 * x as f32 / 36.0));
    }
    let volume = volume(dims, [1.0; 3], Samples::from_f32(&values));
    let mut recipe = SceneRecipe::default();
    recipe.camera.azimuth_deg = 30.0;
    recipe.camera.elevation_deg = 20.0;
    recipe.effects.mode = RenderMode::Mip;
    recipe.clip.crop = [[0.0, 0.6], [0.2, 1.0], [0.0, 0.9]];
    recipe
        .clip
        .add_plane(plane([0.0, 1.0, 1.0], -30.0))
        .unwrap();
    let mut config = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        ..Default::default()
    };
    config.force_bricking = true;
    config.normalize = morphray::analysis::NormalizeMode::MinMax;
    let mut bricking = Engine::new(config).unwrap();
    let mut whole_engine = common::engine();
    let mut images = Vec::new();
    for engine in [&mut bricking, &mut whole_engine] {
        let mut opened = engine.open_volume(&volume, [40, 36], &recipe).unwrap();
        let mut target = engine
            .render_target(40, 36, vk::Format::R8G8B8A8_UNORM)
            .unwrap();
        images.push(
            engine
                .render_twin(&mut target, &mut opened.twin, &opened.scene)
                .unwrap()
                .rgba8,
        );
    }
    let lit = |rgba: &[u8]| {
        rgba.chunks_exact(4)
            .filter(|p| p[..3].iter().any(|&c| c > 0))
            .count()
    };
    let max = images[0]
        .iter()
        .zip(&images[1])
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    eprintln!(
        "lit bricked {}, whole {}, max difference {max}",
        lit(&images[0]),
        lit(&images[1])
    );
    assert!(lit(&images[1]) > 200);
    assert_eq!(lit(&images[0]), lit(&images[1]));
    assert!(max <= 2, "bricked differs from whole by {max}/255");
    common::assert_no_validation_errors(&bricking);
    common::assert_no_validation_errors(&whole_engine);
}
