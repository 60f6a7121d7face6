//! Comparing a GPU frame with its f64 twin, as the overlay tests (labels, layers) do: the case
//! (volume, scene, derived volumes), the frame as f64 RGBA, I_norm read back for the twin, PSNR
//! and the share of pixels off by more than 0.1.
#![allow(dead_code)]

use morphray::engine::readback::read_image;
use morphray::engine::{Derived, Engine, Frame, PreparedVolume, RenderTarget};
use morphray::gpu::Access;
use morphray::reference::raymarch::ReferenceVolume;
use morphray::scene::uniforms::GradientStats;
use morphray::scene::{GradientSource, Scene, VolumeGeometry};

/// A volume prepared for a twin comparison, with its scene and derived volumes.
pub struct Case {
    pub prepared: PreparedVolume,
    pub derived: Option<Derived>,
    pub scene: Scene,
}

/// `volume` prepared with the adaptive scene, gradients on the fly (the twin then needs only
/// I_norm, also with shading), edited by `edit`, and the derived volumes that scene reads.
pub fn prepare(
    engine: &mut Engine,
    volume: &morphray::volume::Volume,
    edit: impl Fn(&mut Scene),
) -> Case {
    let (prepared, mut scene) = super::pictures::prepared_scene(engine, volume);
    scene.effects.gradient_source = GradientSource::OnTheFly;
    edit(&mut scene);
    let derived = scene
        .effects
        .derivative_outputs()
        .map(|o| engine.derive(&prepared, o).unwrap());
    Case {
        prepared,
        derived,
        scene,
    }
}

/// What every twin of a case starts from: I_norm read back, the geometry and the gradient
/// statistics (zero without derived volumes).
pub struct TwinInputs {
    pub norm: Vec<f64>,
    pub geometry: VolumeGeometry,
    pub stats: GradientStats,
}

impl TwinInputs {
    pub fn of(engine: &Engine, case: &Case) -> Self {
        TwinInputs {
            norm: norm(engine, &case.prepared),
            geometry: VolumeGeometry::new(case.prepared.dims, case.prepared.affine).unwrap(),
            stats: case.derived.as_ref().map_or(
                GradientStats {
                    max_magnitude: 0.0,
                    tau: 0.0,
                },
                |d| d.stats,
            ),
        }
    }

    /// I_norm as the twin's volume.
    pub fn volume(&self) -> ReferenceVolume<'_> {
        ReferenceVolume::new(self.geometry.dims, &self.norm).unwrap()
    }
}

/// `scene` over `case`'s volumes rendered into a fresh `w` x `h` RGBA32F target that `attach`
/// has set up (labels, layers; or nothing).
pub fn render_float(
    engine: &mut Engine,
    case: &Case,
    scene: &Scene,
    (w, h): (u32, u32),
    attach: impl FnOnce(&mut RenderTarget),
) -> Frame {
    let mut target = engine
        .render_target(w, h, ash::vk::Format::R32G32B32A32_SFLOAT)
        .unwrap();
    attach(&mut target);
    engine
        .render(&mut target, &case.prepared, case.derived.as_ref(), scene)
        .unwrap()
}

/// A float frame's pixels as f64 RGBA.
pub fn rgba(frame: &Frame) -> Vec<[f64; 4]> {
    frame
        .values
        .chunks_exact(4)
        .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
        .collect()
}

/// The prepared volume's I_norm, read back as f64 (the twin's input).
pub fn norm(engine: &Engine, prepared: &PreparedVolume) -> Vec<f64> {
    read_image(
        engine.device(),
        &prepared.normalized,
        Access::ComputeSampled,
    )
    .unwrap()
    .values
    .iter()
    .map(|&v| v as f64)
    .collect()
}

/// (PSNR over RGB with peak 1, fraction of pixels off by more than 0.1 in a channel).
pub fn compare(a: &[[f64; 4]], b: &[[f64; 4]]) -> (f64, f64) {
    let mut sum = 0.0;
    let mut off = 0usize;
    for (x, y) in a.iter().zip(b) {
        let errors: Vec<f64> = (0..3).map(|c| (x[c] - y[c].min(1.0)).abs()).collect();
        sum += errors.iter().map(|e| e * e).sum::<f64>();
        off += usize::from(errors.iter().any(|&e| e > 0.1));
    }
    let mse = sum / (3 * a.len()) as f64;
    (
        10.0 * (1.0 / mse.max(1e-20)).log10(),
        off as f64 / a.len() as f64,
    )
}

/// Asserts the GPU matches the twin: a sample within f32 rounding of a voxel boundary or a
/// threshold may fall on the other side, so a few pixels may differ, no more.
pub fn assert_matches(what: &str, gpu: &[[f64; 4]], cpu: &[[f64; 4]]) {
    let (psnr, off) = compare(gpu, cpu);
    eprintln!(
        "{what}: PSNR {psnr:.1} dB, {:.2} % of pixels off by > 0.1",
        100.0 * off
    );
    assert!(
        psnr >= 40.0 && off <= 0.01,
        "{what}: PSNR {psnr:.1} dB, {off:.4} off"
    );
}
