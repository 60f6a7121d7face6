//! Bricked volumes render like whole ones in every mode (issue 12, defect 1): which bricks are
//! resident follows what the mode reads (tissue windows in DVR, values in MIP and MinIP), so a
//! volume whose histogram has no tissue peaks (no window at all) still renders its MIP and MinIP
//! bricked, pixel for pixel within the host-versus-GPU normalization rounding.

mod common;

use ash::vk;
use morphray::engine::plan::Layout;
use morphray::engine::{Engine, EngineConfig, OpenedVolume};
use morphray::gpu::{DeviceConfig, Validation};
use morphray::scene::{RenderMode, SceneRecipe, TissueClass};
use morphray::volume::Samples;
use morphray::volume::phantom::{PhantomSpec, generate};

const IMAGE: [u32; 2] = [40, 36];

fn bricking_engine() -> Engine {
    let mut config = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        ..Default::default()
    };
    config.force_bricking = true;
    // As `common::engine`, the whole volume's engine: both normalize by min/max (eq. 1), so the
    // comparison is about bricking, not about the range.
    config.normalize = morphray::analysis::NormalizeMode::MinMax;
    Engine::new(config).unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        )
    })
}

/// A float ramp along x: a flat histogram without tissue peaks (so no tissue window at all),
/// 37 x 35 x 33 voxels: two storage bricks per axis.
fn ramp() -> morphray::volume::Volume {
    let dims = [37usize, 35, 33];
    let mut values = Vec::with_capacity(dims.iter().product());
    for _ in 0..dims[1] * dims[2] {
        values.extend((0..dims[0]).map(|x| 1000.0 * x as f32 / 36.0));
    }
    common::volumes::volume(dims, [1.0; 3], Samples::from_f32(&values))
}

fn scene_for(mode: RenderMode, visible: &'static [TissueClass]) -> SceneRecipe {
    let mut recipe = SceneRecipe::default();
    if !visible.is_empty() {
        recipe.visible = Some(visible.to_vec());
    }
    recipe.camera.azimuth_deg = 30.0;
    recipe.camera.elevation_deg = 20.0;
    recipe.effects.mode = mode;
    recipe
}

fn render(engine: &mut Engine, opened: &mut OpenedVolume) -> Vec<u8> {
    let mut target = engine
        .render_target(IMAGE[0], IMAGE[1], vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    engine
        .render_twin(&mut target, &mut opened.twin, &opened.scene)
        .unwrap()
        .rgba8
}

/// Pixels brighter than the (black) background.
fn lit(rgba: &[u8]) -> usize {
    rgba.chunks_exact(4)
        .filter(|p| p[..3].iter().any(|&c| c > 0))
        .count()
}

fn max_difference(a: &[u8], b: &[u8]) -> u8 {
    a.iter()
        .zip(b)
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap_or(0)
}

/// Renders `volume` forced bricked and whole with the tissues `visible` (empty: the defaults)
/// and compares.
fn assert_bricked_matches_whole(
    volume: &morphray::volume::Volume,
    mode: RenderMode,
    visible: &'static [TissueClass],
) {
    let mut bricking = bricking_engine();
    let mut bricked = bricking
        .open_volume(volume, IMAGE, &scene_for(mode, visible))
        .unwrap();
    assert!(matches!(bricked.plan.layout, Layout::Bricked { .. }));
    let mut whole_engine = common::engine();
    let mut whole = whole_engine
        .open_volume(volume, IMAGE, &scene_for(mode, visible))
        .unwrap();
    assert_eq!(whole.plan.layout, Layout::Whole);
    let b = render(&mut bricking, &mut bricked);
    let w = render(&mut whole_engine, &mut whole);
    let (lit_b, lit_w) = (lit(&b), lit(&w));
    let max = max_difference(&b, &w);
    eprintln!("{mode:?}: lit bricked {lit_b}, whole {lit_w}, max difference {max}/255");
    assert!(
        lit_w > (IMAGE[0] * IMAGE[1] / 4) as usize,
        "{mode:?}: the whole render shows the volume ({lit_w} lit pixels)"
    );
    assert_eq!(lit_b, lit_w, "{mode:?}: lit pixels bricked vs whole");
    // The bricked I_norm is normalized in f64 on the host, the whole one in f32 on the GPU: a
    // voxel may land one R16 code apart, nothing more.
    assert!(
        max <= 2,
        "{mode:?}: bricked differs from whole by {max}/255"
    );
    common::assert_no_validation_errors(&bricking);
    common::assert_no_validation_errors(&whole_engine);
}

#[test]
fn a_volume_without_tissue_peaks_renders_its_mip_bricked_like_whole() {
    let volume = ramp();
    assert_bricked_matches_whole(&volume, RenderMode::Mip, &[]);
}

#[test]
fn a_volume_without_tissue_peaks_renders_its_minip_bricked_like_whole() {
    let volume = ramp();
    assert_bricked_matches_whole(&volume, RenderMode::MinIp, &[]);
}

#[test]
fn the_phantom_renders_its_mip_bricked_like_whole_whatever_tissues_are_switched_on() {
    // MIP shows every value: the skull's bricks, which no tissue window reaches, must be
    // resident too, whichever tissues are switched on.
    let volume = generate(&PhantomSpec::cube(96)).unwrap().volume;
    assert_bricked_matches_whole(&volume, RenderMode::Mip, &[]);
    assert_bricked_matches_whole(&volume, RenderMode::Mip, &[TissueClass::Pathology]);
}

#[test]
fn the_phantom_renders_dvr_bricked_like_whole() {
    let volume = generate(&PhantomSpec::cube(48)).unwrap().volume;
    assert_bricked_matches_whole(&volume, RenderMode::Dvr, &[]);
}
