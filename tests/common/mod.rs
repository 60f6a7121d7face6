//! Shared helpers for GPU tests: an engine with validation required, and the validation check.
//!
//! A GPU test that finds no Vulkan device fails with a message naming what to install; it never
//! passes silently.
#![allow(dead_code)]

pub mod bids;
pub mod four_d;
pub mod mni152;
pub mod pictures;
pub mod twin_compare;
pub mod viewer;
pub mod volumes;

use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::{DeviceConfig, Validation};

/// An engine on the default device with the Khronos validation layer required, normalizing by
/// eq. 1 (min/max): these tests check the kernels against eq. 1's f64 twins at exact ranges.
/// The robust range (the default) has its own tests: robust_range.rs, robust_render.rs.
pub fn engine() -> Engine {
    engine_normalizing(morphray::analysis::NormalizeMode::MinMax)
}

/// [`engine`] with the given normalization.
pub fn engine_normalizing(normalize: morphray::analysis::NormalizeMode) -> Engine {
    engine_with(|config| config.normalize = normalize)
}

/// [`engine`] with its configuration edited by `edit` (validation stays required).
pub fn engine_with(edit: impl FnOnce(&mut EngineConfig)) -> Engine {
    let mut config = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        ..Default::default()
    };
    edit(&mut config);
    match Engine::new(config) {
        Ok(engine) => engine,
        Err(e) => panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        ),
    }
}

/// Fails the test if the validation layer reported any error.
pub fn assert_no_validation_errors(engine: &Engine) {
    assert!(
        engine.device().validation_enabled(),
        "validation layer is not active"
    );
    let errors = engine.device().validation_log().errors();
    assert!(
        errors.is_empty(),
        "{} validation error(s):\n{}",
        errors.len(),
        errors.join("\n---\n")
    );
    // Faults in destructors (failed frees or resets) are recorded, not skipped: none allowed.
    let faults = engine.device().internal_faults();
    assert!(faults.is_empty(), "internal fault(s): {faults:?}");
}
