//! Issue 11's "done when": a scan with a handful of hot voxels renders like the clean scan under
//! the default (robust) normalization, while eq. 1 (`--normalize minmax`) loses the tissue. The
//! built-in phantom with six voxels at 20x its maximum, rendered with the default scene.

mod common;

use ash::vk;
use morphray::analysis::NormalizeMode;
use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::{DeviceConfig, Validation};
use morphray::scene::SceneRecipe;
use morphray::volume::phantom::{PhantomSpec, Tissue, generate};
use morphray::volume::{Samples, Volume};

const IMAGE: [u32; 2] = [64, 64];

fn engine(normalize: NormalizeMode) -> Engine {
    let config = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        normalize,
        ..Default::default()
    };
    Engine::new(config).unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        )
    })
}

fn render(engine: &mut Engine, volume: &Volume) -> Vec<u8> {
    let mut opened = engine
        // The default scene of `morphray render`: adaptive windows, default tissues and camera.
        .open_volume(volume, IMAGE, &SceneRecipe::default())
        .expect("open");
    let mut target = engine
        .render_target(IMAGE[0], IMAGE[1], vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    engine
        .render_twin(&mut target, &mut opened.twin, &opened.scene)
        .unwrap()
        .rgba8
}

/// The phantom, and a copy with six white-matter voxels at 20x its maximum.
fn clean_and_hot() -> (Volume, Volume) {
    let phantom = generate(&PhantomSpec::cube(48)).expect("phantom");
    let clean = phantom.volume.clone();
    let n = phantom.labels.len();
    let mut values: Vec<i16> = (0..n).map(|i| clean.samples.get(i) as i16).collect();
    let max = *values.iter().max().unwrap();
    let wm: Vec<usize> = (0..n)
        .filter(|&i| phantom.labels[i] == Tissue::Wm as u8)
        .collect();
    for k in 0..6 {
        values[wm[k * wm.len() / 6]] = max * 20;
    }
    let mut hot = clean.clone();
    hot.samples = Samples::from_i16(&values);
    (clean, hot)
}

/// Mean absolute difference per channel, and the share of pixels differing by more than 32.
fn difference(a: &[u8], b: &[u8]) -> (f64, f64) {
    let sum: u64 = a.iter().zip(b).map(|(x, y)| x.abs_diff(*y) as u64).sum();
    let pixels = a.len() / 4;
    let changed = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > 32))
        .count();
    (sum as f64 / a.len() as f64, changed as f64 / pixels as f64)
}

fn lit(rgba: &[u8]) -> usize {
    rgba.chunks_exact(4)
        .filter(|p| p[..3].iter().any(|&c| c > 8))
        .count()
}

#[test]
fn hot_voxels_leave_the_default_rendering_as_the_clean_scan_has_it() {
    let (clean, hot) = clean_and_hot();
    let mut robust = engine(NormalizeMode::Robust);
    let (a, b) = (render(&mut robust, &clean), render(&mut robust, &hot));
    let (mean, changed) = difference(&a, &b);
    assert!(
        lit(&a) > 1000,
        "the clean phantom renders ({} lit)",
        lit(&a)
    );
    assert!(
        mean < 2.0 && changed < 0.01,
        "robust: mean difference {mean:.3}, {:.2} % of pixels changed",
        changed * 100.0
    );
    common::assert_no_validation_errors(&robust);

    // Eq. 1 squeezes the tissue into the darkest bins: the same volumes render very differently
    // (which is why robust is the default).
    let mut minmax = engine(NormalizeMode::MinMax);
    let (c, d) = (render(&mut minmax, &clean), render(&mut minmax, &hot));
    let (mean, changed) = difference(&c, &d);
    assert!(
        mean > 5.0 && changed > 0.1,
        "minmax: mean difference {mean:.3}, {:.2} % changed",
        changed * 100.0
    );
    common::assert_no_validation_errors(&minmax);
}
