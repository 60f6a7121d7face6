//! Headless use of morphray as a library: a volume from memory, a memory budget, one frame
//! rendered into a buffer the caller owns, and the plan the engine followed.
//!
//! Run: `cargo run --release --example headless [BUDGET_MIB] [OUT.ppm]`
//! (default budget 256 MiB; with OUT.ppm the frame is also written as a binary PPM).
//!
//! An integrator with their own Vulkan instance and device would create the engine with
//! `Engine::with_device(unsafe { Device::adopt(handles) }?, config)` instead of `Engine::new`
//! (see `morphray::gpu::AdoptedHandles` and tests/integrator.rs).
//!
//! A volume in memory opens with `Engine::open_volume(volume, size, &recipe)`; a file (NIfTI,
//! ANALYZE, or any format `morphray::volume::source` registers) opens with
//! `Session::open(&VolumeSource::File(path), config, &OpenOptions { recipe, .. })`, which reads
//! it while the device starts. Both are the path every morphray command and the viewer use.

use ash::vk;
use morphray::engine::plan::Plan;
use morphray::engine::{Engine, EngineConfig};
use morphray::scene::{RenderMode, SceneRecipe};
use morphray::volume::{LinearMap, Samples, Volume};

/// What one headless frame produced.
pub struct Headless {
    /// RGBA8 pixels, rows top to bottom, in the caller's buffer.
    pub pixels: Vec<u8>,
    /// Width and height.
    pub size: [u32; 2],
    /// The plan the engine followed.
    pub plan: Plan,
    /// GPU milliseconds of the frame's raymarch.
    pub gpu_ms: f64,
}

/// A synthetic 96 x 96 x 80 T1-like head in memory: bright scalp, dark skull, cortex (grey
/// matter), white matter and fluid-filled ventricles, with scanner-like noise, as 16-bit
/// intensities (what an integrator would already hold).
pub fn head_in_memory() -> Result<Volume, Box<dyn std::error::Error>> {
    let dims = [96usize, 96, 80];
    let mut voxels = vec![0u16; dims[0] * dims[1] * dims[2]];
    // A small deterministic generator for the noise (sum of four uniforms ~ Gaussian).
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = [
                    (i as f64 - 47.5) / 44.0,
                    (j as f64 - 47.5) / 40.0,
                    (k as f64 - 39.5) / 36.0,
                ];
                let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                let ventricle = ((p[0].abs() - 0.15) / 0.1).powi(2)
                    + (p[1] / 0.35).powi(2)
                    + (p[2] / 0.25).powi(2);
                let tissue: f64 = match r {
                    r if r > 1.0 => 0.0,
                    r if r > 0.96 => 1000.0, // scalp (fat is bright on T1)
                    r if r > 0.90 => 80.0,   // skull
                    _ if ventricle < 1.0 => 250.0, // CSF
                    r if r > 0.76 => 600.0,  // cortex (GM)
                    _ => 850.0,              // white matter
                };
                // Noise inside the head; outside, a faint positive floor (as in magnitude images).
                let noise = (uniform() + uniform() + uniform() + uniform() - 2.0) * 40.0;
                let noise = if tissue > 0.0 {
                    noise
                } else {
                    noise.abs() * 0.2
                };
                voxels[i + dims[0] * (j + dims[1] * k)] =
                    (tissue + noise).clamp(0.0, 4095.0) as u16;
            }
        }
    }
    // 2 mm voxels, centred on the origin (RAS+).
    let affine = [
        [2.0, 0.0, 0.0, -95.0],
        [0.0, 2.0, 0.0, -95.0],
        [0.0, 0.0, 2.0, -79.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    Ok(Volume::from_voxels(
        "head in memory",
        dims,
        Samples::from_u16(&voxels),
        affine,
        LinearMap::IDENTITY,
    )?)
}

/// Opens `volume` within `budget` bytes of GPU memory and renders one DVR frame into a buffer
/// this function owns and returns.
pub fn render_one_frame(
    volume: &Volume,
    budget: u64,
    size: [u32; 2],
) -> Result<Headless, Box<dyn std::error::Error>> {
    let mut engine = Engine::new(EngineConfig {
        memory_budget: Some(budget),
        ..Default::default()
    })?;
    // The scene is built once the histogram analysis has found the tissue peaks.
    // The scene is a recipe: the engine plans its effects once, then builds the scene around
    // the volume's own histogram peaks (adaptive windows).
    let mut recipe = SceneRecipe::default();
    recipe.effects.mode = RenderMode::Dvr;
    recipe.effects.curvature = true;
    recipe.camera.azimuth_deg = 35.0;
    recipe.camera.elevation_deg = 20.0;
    let mut opened = engine.open_volume(volume, size, &recipe)?;
    let mut target = engine.render_target(size[0], size[1], vk::Format::R8G8B8A8_UNORM)?;
    let mut pixels = vec![0u8; (size[0] * size[1] * 4) as usize];
    let frame =
        engine.render_twin_into(&mut target, &mut opened.twin, &opened.scene, &mut pixels)?;
    Ok(Headless {
        pixels,
        size,
        plan: opened.plan,
        gpu_ms: frame.gpu_timings.iter().map(|t| t.gpu_ms).sum(),
    })
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let budget_mib: u64 = match args.next() {
        Some(text) => text
            .parse()
            .map_err(|_| format!("`{text}` is not a budget in MiB"))?,
        None => 256,
    };
    let out = args.next();
    let volume = head_in_memory()?;
    let result = render_one_frame(&volume, budget_mib << 20, [320, 240])?;
    let plan = &result.plan;
    println!(
        "rendered {}x{} in {:.3} ms of GPU time, within a {budget_mib} MiB budget",
        result.size[0], result.size[1], result.gpu_ms
    );
    println!(
        "passes: {:?}",
        plan.passes.iter().map(|p| &p.name).collect::<Vec<_>>()
    );
    println!("variants: {:?}", plan.variants);
    for a in plan.allocations.iter().filter(|a| !a.transient) {
        println!(
            "  {:<34} {:>10} bytes  {:<16} {}",
            a.name,
            a.bytes,
            a.format_label(),
            a.memory_type
        );
    }
    println!(
        "held while rendering: {} bytes (peak while preparing {})",
        plan.total_bytes, plan.peak_bytes
    );
    for d in &plan.degradations {
        println!(
            "degraded: {} (accuracy setting \"{}\")",
            d.what, d.accuracy_setting
        );
    }
    let lit = result.pixels.chunks_exact(4).filter(|p| p[0] > 0).count();
    println!(
        "{lit} of {} pixels show tissue",
        result.size[0] * result.size[1]
    );
    if let Some(path) = out {
        let mut ppm = format!("P6 {} {} 255\n", result.size[0], result.size[1]).into_bytes();
        for p in result.pixels.chunks_exact(4) {
            ppm.extend_from_slice(&p[..3]);
        }
        std::fs::write(&path, ppm)?;
        println!("wrote {path}");
    }
    Ok(())
}
