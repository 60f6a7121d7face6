//! Every compiled shader module: valid SPIR-V for Vulkan 1.1 (spirv-val from Debian's
//! spirv-tools, which tools/setup.sh installs), a reflection table that agrees with itself, and
//! a pipeline the device accepts under the validation layer.

mod common;

use morphray::gpu::shaders::{BindingKind, table};
use morphray::gpu::{ComputePipeline, Device, DeviceConfig, DeviceSelector, GpuError, Validation};
use std::process::Command;

#[test]
fn every_module_passes_spirv_val() {
    let dir = std::env::temp_dir().join(format!("morphray-spv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for shader in table::ALL {
        let path = dir.join(format!("{}.spv", shader.name));
        std::fs::write(&path, shader.spirv).unwrap();
        let out = Command::new("spirv-val")
            .args(["--target-env", "vulkan1.1"])
            .arg(&path)
            .output()
            .unwrap_or_else(|e| {
                panic!("spirv-val is needed (apt-get install spirv-tools, or tools/setup.sh): {e}")
            });
        assert!(
            out.status.success(),
            "{}: {}",
            shader.name,
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn reflection_tables_are_consistent() {
    assert!(
        table::ALL.len() >= 14,
        "five sample kinds x two kernels, plus normalize, derivatives, raymarch, bandwidth"
    );
    for shader in table::ALL {
        assert_eq!(shader.spirv.len() % 4, 0, "{}", shader.name);
        assert_eq!(
            shader.spirv_words()[0],
            0x0723_0203,
            "{}: SPIR-V magic",
            shader.name
        );
        assert!(
            shader.invocations_per_workgroup() >= 64 && shader.invocations_per_workgroup() <= 256,
            "{}",
            shader.name
        );
        assert!(
            shader.push_constant_bytes <= 128,
            "{}: push constants must fit the guaranteed 128 bytes",
            shader.name
        );
        for b in shader.bindings {
            assert!(
                !b.name.is_empty(),
                "{} binding {} has a name",
                shader.name,
                b.binding
            );
            if b.kind == BindingKind::UniformBuffer {
                assert!(
                    b.block_bytes > 0,
                    "{}: uniform block {} has a size",
                    shader.name,
                    b.name
                );
            }
        }
    }
    // The sample-kind variants are resolved per kind and differ.
    assert_ne!(table::MINMAX_U8.spirv, table::MINMAX_F32.spirv);
}

#[test]
fn every_pipeline_is_created_without_validation_errors() {
    let engine = common::engine();
    for shader in table::ALL {
        ComputePipeline::new(engine.device(), shader, &[], ash::vk::PipelineCache::null())
            .unwrap_or_else(|e| panic!("{}: {e}", shader.name));
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn objects_are_named_and_passes_labelled_for_capture_tools_without_validation_errors() {
    // The validation layer brings VK_EXT_debug_utils, so names and labels are on here; the layer
    // checks every name and every begin/end label pair of a whole render.
    let mut engine = common::engine();
    assert!(engine.device().debug_names_enabled());
    let before = engine.device().debug_names_set();
    let volume =
        morphray::volume::phantom::generate(&morphray::volume::phantom::PhantomSpec::cube(24))
            .unwrap()
            .volume;
    let mut opened = engine
        .open_volume(&volume, [16, 12], &morphray::scene::SceneRecipe::default())
        .unwrap();
    let mut target = engine
        .render_target(16, 12, ash::vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    engine
        .render_twin(&mut target, &mut opened.twin, &opened.scene)
        .unwrap();
    // Buffers, images and their views, pipelines and layouts, descriptor sets: dozens.
    let named = engine.device().debug_names_set() - before;
    assert!(named >= 20, "only {named} objects were named");
    common::assert_no_validation_errors(&engine);
}

#[test]
fn every_pipeline_is_created_under_the_gen12_profile_with_its_workgroup_and_subgroup() {
    // Gen12: no float atomics (a module declaring them is refused at creation), 8x8 workgroups
    // for the tunable kernels, and the smallest subgroup size both this device and Xe-LP have.
    let probe = common::engine();
    let range = probe.device().adapter().subgroup_size_range;
    drop(probe);
    let profile = morphray::gpu::DeviceProfile::load("gen12").unwrap();
    let common_size =
        range.and_then(|(lo, hi)| [8, 16, 32].into_iter().find(|s| (lo..=hi).contains(s)));
    let device = Device::new(&DeviceConfig {
        validation: Validation::Required,
        profile: Some(profile),
        tuning: morphray::gpu::KernelTuning {
            subgroup_size: common_size,
            ..Default::default()
        },
        ..Default::default()
    })
    .unwrap();
    assert!(!device.adapter().float_atomics);
    for shader in table::ALL {
        let pipeline = ComputePipeline::new(&device, shader, &[], ash::vk::PipelineCache::null())
            .unwrap_or_else(|e| panic!("{}: {e}", shader.name));
        let expected = if shader.workgroup_spec_ids.is_some() {
            [8, 8, 1]
        } else {
            shader.workgroup_size
        };
        assert_eq!(pipeline.workgroup_size(), expected, "{}", shader.name);
        assert_eq!(pipeline.subgroup_size(), common_size, "{}", shader.name);
    }
    let errors = device.validation_log().errors();
    assert!(errors.is_empty(), "{}", errors.join("\n---\n"));
}

#[test]
fn a_missing_device_is_named_with_the_devices_that_exist() {
    let config = DeviceConfig {
        selector: DeviceSelector::Name("no such gpu 9000".into()),
        validation: Validation::Off,
        ..Default::default()
    };
    match Device::new(&config) {
        Err(GpuError::DeviceNotFound { wanted, available }) => {
            assert_eq!(wanted, "no such gpu 9000");
            assert!(!available.is_empty(), "the error lists the devices");
            let message = GpuError::DeviceNotFound { wanted, available }.to_string();
            assert!(
                message.contains("no such gpu 9000") && message.contains("#0"),
                "{message}"
            );
        }
        Err(e) => panic!("expected DeviceNotFound, got: {e}"),
        Ok(_) => panic!("a device named `no such gpu 9000` should not exist"),
    }
    let by_index = DeviceConfig {
        selector: DeviceSelector::Index(999),
        validation: Validation::Off,
        ..Default::default()
    };
    assert!(matches!(
        Device::new(&by_index),
        Err(GpuError::DeviceNotFound { .. })
    ));
}
