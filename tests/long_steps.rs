//! Long steps in bricks of low opacity bound (LONG_STEPS, issue 17 item 2): the GPU raymarch
//! against its f64 twin with them on (PSNR as tests/gpu_raymarch.rs bounds it), and the proof
//! that they do something (fewer samples, a different image) and nothing when off.

mod common;

use ash::vk;
use morphray::engine::readback::read_image;
use morphray::engine::{Derived, Engine, PreparedVolume};
use morphray::gpu::Access;
use morphray::reference::raymarch::{ReferenceDerived, ReferenceRaymarch, ReferenceVolume};
use morphray::scene::occupancy::LongSteps;
use morphray::scene::{Scene, VolumeGeometry};
use morphray::volume::phantom::{PhantomSpec, generate};

struct Prepared {
    prepared: PreparedVolume,
    derived: Option<Derived>,
    scene: Scene,
}

fn prepare(engine: &mut Engine, n: usize) -> Prepared {
    let volume = generate(&PhantomSpec::cube(n)).unwrap().volume;
    let (prepared, mut scene) = common::pictures::prepared_scene(engine, &volume);
    scene.effects.shading = true;
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

/// RGBA f32 pixels and the samples marched.
fn gpu_render(engine: &mut Engine, p: &Prepared, scene: &Scene, size: u32) -> (Vec<[f64; 4]>, u64) {
    let mut target = engine
        .render_target(size, size, vk::Format::R32G32B32A32_SFLOAT)
        .unwrap();
    target.count_samples = true;
    let frame = engine
        .render(&mut target, &p.prepared, p.derived.as_ref(), scene)
        .unwrap();
    assert!(frame.skipped_empty_space);
    let pixels = frame
        .values
        .chunks_exact(4)
        .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
        .collect();
    (pixels, frame.samples.unwrap().marched)
}

fn reference(engine: &mut Engine, p: &Prepared, scene: &Scene, size: u32) -> Vec<[f64; 4]> {
    let device = engine.device();
    let norm: Vec<f64> = read_image(device, &p.prepared.normalized, Access::ComputeSampled)
        .unwrap()
        .values
        .iter()
        .map(|&v| v as f64)
        .collect();
    let d = p.derived.as_ref().unwrap();
    let g = read_image(
        device,
        d.volumes.gradient.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    let sg = d.volumes.store_scale[0] as f64;
    let magnitude: Vec<f64> = g
        .values
        .chunks_exact(g.channels)
        .map(|t| t[0] as f64 / sg)
        .collect();
    let n = read_image(
        device,
        d.volumes.normal.as_ref().unwrap(),
        Access::ComputeSampled,
    )
    .unwrap();
    let normals: Vec<[f64; 3]> = n
        .values
        .chunks_exact(4)
        .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64])
        .collect();
    let geometry = VolumeGeometry::new(p.prepared.dims, p.prepared.affine).unwrap();
    let volume = ReferenceVolume::new(p.prepared.dims, &norm).unwrap();
    let derived = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        curvature: None,
        normals: Some(&normals),
    };
    let ranges = engine.brick_ranges(&p.prepared).unwrap();
    let bounds = ranges.reference_bounds(&scene.classification, None, None);
    ReferenceRaymarch::new(scene, &geometry, &d.stats, &volume, &derived, size, size)
        .unwrap()
        .with_brick_bounds(ranges.grid, ranges.side, &bounds)
        .unwrap()
        .render()
}

/// PSNR over RGB, peak 1.
fn psnr(a: &[[f64; 4]], b: &[[f64; 4]]) -> f64 {
    let mut sum = 0.0;
    for (x, y) in a.iter().zip(b) {
        for c in 0..3 {
            sum += (x[c] - y[c].min(1.0)).powi(2);
        }
    }
    let mse = sum / (3 * a.len()) as f64;
    10.0 * (1.0 / mse.max(1e-20)).log10()
}

#[test]
fn long_steps_match_the_twin_and_take_fewer_samples() {
    let mut engine = common::engine();
    let mut p = prepare(&mut engine, 48);
    // The translucent opacities of before issue 34 (CSF 0.2, GM 0.3, WM 0.9): with today's
    // opaque GM and WM (1.0) every tissue brick's bound is 1 and no threshold below 1 lets a
    // long step into one, so the image could not differ.
    for (tissue, opacity) in [
        (morphray::scene::TissueClass::Csf, 0.2),
        (morphray::scene::TissueClass::Gm, 0.3),
        (morphray::scene::TissueClass::Wm, 0.9),
    ] {
        p.scene.classification.style_mut(tissue).opacity = opacity;
    }
    let size = 48;
    let (plain, plain_samples) = gpu_render(&mut engine, &p, &p.scene, size);
    for (factor, threshold_e4) in [(2, 2500), (4, 3500), (4, 10000)] {
        let mut scene = p.scene;
        scene.effects.quality.long_steps = LongSteps {
            factor,
            threshold_e4,
        };
        let (gpu, samples) = gpu_render(&mut engine, &p, &scene, size);
        let cpu = reference(&mut engine, &p, &scene, size);
        let label = format!("k {factor}, threshold {threshold_e4}e-4");
        let against_twin = psnr(&gpu, &cpu);
        let against_plain = psnr(&gpu, &plain);
        eprintln!(
            "{label}: GPU vs twin {against_twin:.1} dB, vs no long steps {against_plain:.1} dB, \
             samples {samples} of {plain_samples}"
        );
        assert!(against_twin >= 40.0, "{label}: {against_twin:.1} dB");
        // They really ran: fewer samples (and, where every occupied brick qualifies, another
        // image; the phantom's low-bound bricks are flat CSF, where |g| makes opacity ~0).
        assert!(samples < plain_samples, "{label}");
        if threshold_e4 == 10000 {
            assert!(gpu != plain, "{label}");
        }
    }
    // Off (factor 1, or a zero threshold) is the plain image, exactly.
    for off in [
        LongSteps {
            factor: 1,
            threshold_e4: 10000,
        },
        LongSteps {
            factor: 4,
            threshold_e4: 0,
        },
    ] {
        let mut scene = p.scene;
        scene.effects.quality.long_steps = off;
        assert_eq!(gpu_render(&mut engine, &p, &scene, size).0, plain);
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn in_a_faint_scene_the_gpu_follows_the_twins_long_steps_not_the_plain_march() {
    // Opacities of a few per cent per mm: every occupied brick is below the threshold, so the
    // long steps change the image well beyond the GPU-vs-twin error, and the GPU must follow the
    // twin's long steps, not the plain lattice.
    let mut engine = common::engine();
    let mut p = prepare(&mut engine, 48);
    for t in &mut p.scene.classification.tissues {
        t.opacity *= 0.1;
    }
    let size = 48;
    let (plain, _) = gpu_render(&mut engine, &p, &p.scene, size);
    let mut scene = p.scene;
    scene.effects.quality.long_steps = LongSteps {
        factor: 8,
        threshold_e4: 2000,
    };
    let (gpu, _) = gpu_render(&mut engine, &p, &scene, size);
    let cpu = reference(&mut engine, &p, &scene, size);
    let (against_twin, against_plain) = (psnr(&gpu, &cpu), psnr(&gpu, &plain));
    eprintln!(
        "faint, k 8: GPU vs twin {against_twin:.1} dB, vs no long steps {against_plain:.1} dB"
    );
    assert!(against_twin >= 40.0, "{against_twin:.1} dB");
    assert!(
        against_twin >= against_plain + 6.0,
        "{against_twin:.1} vs {against_plain:.1} dB"
    );
    common::assert_no_validation_errors(&engine);
}
