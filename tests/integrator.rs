//! The library as an integrator uses it (issue 7): their own Vulkan instance and device handed in
//! as ash handles, a volume from raw voxels in memory, a budget, one frame rendered into a buffer
//! the caller owns; morphray frees everything it made before the integrator destroys the device,
//! which the integrator's own validation messenger checks.

use ash::vk;
use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::{AdoptedHandles, Device, DeviceConfig, KernelTuning, Validation};
use morphray::scene::SceneRecipe;
use morphray::volume::phantom::{PhantomSpec, generate};
use morphray::volume::{LinearMap, Volume};
use std::ffi::c_void;
use std::sync::Mutex;

/// Messages the integrator's messenger received (errors and warnings).
static MESSAGES: Mutex<Vec<String>> = Mutex::new(Vec::new());

unsafe extern "system" fn collect(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) && !data.is_null() {
        // SAFETY: the layer passes a valid callback-data struct for this call.
        let text = unsafe { (*data).message_as_c_str() }
            .map(|m| m.to_string_lossy().into_owned())
            .unwrap_or_default();
        if let Ok(mut m) = MESSAGES.lock() {
            m.push(text);
        }
    }
    vk::FALSE
}

/// What an integrator's application would have set up before calling morphray.
struct IntegratorVulkan {
    entry: ash::Entry,
    instance: ash::Instance,
    messenger: (ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT),
    physical: vk::PhysicalDevice,
    device: ash::Device,
    family: u32,
}

impl IntegratorVulkan {
    fn new() -> IntegratorVulkan {
        // SAFETY: the system loader; every create call below gets valid, live create infos.
        unsafe {
            let entry = ash::Entry::load().expect(
                "this test needs a Vulkan loader (Debian: apt-get install libvulkan1 mesa-vulkan-drivers vulkan-validationlayers)",
            );
            let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
            let extensions = [ash::ext::debug_utils::NAME.as_ptr()];
            let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
            let instance = entry
                .create_instance(
                    &vk::InstanceCreateInfo::default()
                        .application_info(&app)
                        .enabled_layer_names(&layers)
                        .enabled_extension_names(&extensions),
                    None,
                )
                .expect("an instance with the Khronos validation layer");
            let utils = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let messenger = utils
                .create_debug_utils_messenger(
                    &vk::DebugUtilsMessengerCreateInfoEXT::default()
                        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR)
                        .message_type(
                            vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                                | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL,
                        )
                        .pfn_user_callback(Some(collect)),
                    None,
                )
                .unwrap();
            let physical = instance.enumerate_physical_devices().unwrap()[0];
            let family = instance
                .get_physical_device_queue_family_properties(physical)
                .iter()
                .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
                .unwrap() as u32;
            let priorities = [1.0];
            let queues = [vk::DeviceQueueCreateInfo::default()
                .queue_family_index(family)
                .queue_priorities(&priorities)];
            let features = vk::PhysicalDeviceFeatures::default()
                .shader_storage_image_write_without_format(true);
            let mut features13 =
                vk::PhysicalDeviceVulkan13Features::default().synchronization2(true);
            let device = instance
                .create_device(
                    physical,
                    &vk::DeviceCreateInfo::default()
                        .queue_create_infos(&queues)
                        .enabled_features(&features)
                        .push_next(&mut features13),
                    None,
                )
                .unwrap();
            IntegratorVulkan {
                entry,
                instance,
                messenger: (utils, messenger),
                physical,
                device,
                family,
            }
        }
    }

    fn handles(&self) -> AdoptedHandles {
        AdoptedHandles {
            entry: self.entry.clone(),
            instance: self.instance.clone(),
            physical: self.physical,
            device: self.device.clone(),
            queue_family: self.family,
            queue_index: 0,
            profile: None,
            tuning: KernelTuning::default(),
        }
    }

    fn destroy(self) {
        // SAFETY: morphray dropped everything it made from these handles; nothing else uses them.
        unsafe {
            self.device.destroy_device(None);
            self.messenger
                .0
                .destroy_debug_utils_messenger(self.messenger.1, None);
            self.instance.destroy_instance(None);
        }
    }
}

/// The phantom's voxels as an integrator would hold them: a plain array and an affine.
fn volume_from_memory() -> Volume {
    let phantom = generate(&PhantomSpec::cube(40)).unwrap().volume;
    let voxels: Vec<i16> = phantom
        .samples
        .to_f64_vec()
        .iter()
        .map(|&v| v as i16)
        .collect();
    let affine = [
        [1.2, 0.0, 0.0, -24.0],
        [0.0, 1.2, 0.0, -24.0],
        [0.0, 0.0, 1.2, -24.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    Volume::from_voxels(
        "in-memory",
        [40, 40, 40],
        morphray::volume::Samples::from_i16(&voxels),
        affine,
        LinearMap::IDENTITY,
    )
    .unwrap()
}

fn scene() -> SceneRecipe {
    let mut recipe = SceneRecipe::default();
    recipe.camera.azimuth_deg = 30.0;
    recipe.effects.curvature = true;
    recipe
}

const SIZE: [u32; 2] = [48, 36];

fn render_into_owned_buffer(engine: &mut Engine, volume: &Volume) -> Vec<u8> {
    let mut opened = engine.open_volume(volume, SIZE, &scene()).unwrap();
    let mut target = engine
        .render_target(SIZE[0], SIZE[1], vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    let mut pixels = vec![0u8; (SIZE[0] * SIZE[1] * 4) as usize];
    let frame = engine
        .render_twin_into(&mut target, &mut opened.twin, &opened.scene, &mut pixels)
        .unwrap();
    assert!(
        frame.rgba8.is_empty(),
        "the pixels went to the caller's buffer only"
    );
    // A buffer of the wrong size is refused before any GPU work.
    let mut short = vec![0u8; 10];
    let err = engine
        .render_twin_into(&mut target, &mut opened.twin, &opened.scene, &mut short)
        .unwrap_err()
        .to_string();
    assert!(err.contains("needs 6912"), "{err}");
    pixels
}

#[test]
fn an_integrators_device_renders_like_morphrays_own_and_is_left_clean() {
    let volume = volume_from_memory();
    let vulkan = IntegratorVulkan::new();
    // SAFETY: the handles are valid, created with the features AdoptedHandles lists, and outlive
    // the engine (destroyed below, after the engine is dropped); nothing else uses the queue.
    let device = unsafe { Device::adopt(vulkan.handles()) }.unwrap();
    let ledger = device.ledger().clone();
    let config = EngineConfig {
        memory_budget: Some(64 << 20),
        ..Default::default()
    };
    let mut adopted = Engine::with_device(device, config).unwrap();
    assert_eq!(adopted.memory_budget(), 64 << 20);
    let theirs = render_into_owned_buffer(&mut adopted, &volume);
    drop(adopted);
    assert!(ledger.live().is_empty(), "{:?}", ledger.live());
    // Destroying the device reports any object morphray left alive as a validation error.
    vulkan.destroy();
    let messages = MESSAGES.lock().unwrap().clone();
    assert!(messages.is_empty(), "{}", messages.join("\n---\n"));

    let mut own = Engine::new(EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        ..Default::default()
    })
    .unwrap();
    let ours = render_into_owned_buffer(&mut own, &volume);
    let lit = ours.chunks_exact(4).filter(|p| p[0] > 20).count();
    assert!(lit > 100, "the frame shows the volume ({lit} pixels)");
    assert!(
        theirs == ours,
        "the adopted device rendered a different image"
    );
    assert!(own.device().validation_log().errors().is_empty());
}

#[test]
fn adopting_a_queue_that_cannot_compute_or_does_not_exist_is_refused() {
    let vulkan = IntegratorVulkan::new();
    let mut handles = vulkan.handles();
    handles.queue_index = 99;
    // SAFETY: valid handles; adoption fails before any use of the bad queue.
    let err = unsafe { Device::adopt(handles) }.err().unwrap().to_string();
    assert!(err.contains("queue 99"), "{err}");
    let mut handles = vulkan.handles();
    handles.queue_family = 1000;
    // SAFETY: as above.
    let err = unsafe { Device::adopt(handles) }.err().unwrap().to_string();
    assert!(err.contains("does not exist"), "{err}");
    vulkan.destroy();
}

#[allow(dead_code)]
#[path = "../tools/examples/headless.rs"]
mod headless;

#[test]
fn the_headless_example_renders_within_its_budget() {
    let volume = headless::head_in_memory().unwrap();
    let roomy = headless::render_one_frame(&volume, 256 << 20, [64, 48]).unwrap();
    assert!(roomy.plan.degradations.is_empty());
    let lit = |pixels: &[u8]| pixels.chunks_exact(4).filter(|p| p[0] > 20).count();
    assert!(lit(&roomy.pixels) > 500, "{} lit", lit(&roomy.pixels));
    // Three quarters of the full plan's peak: the plan degrades, and still shows the head.
    let budget = roomy.plan.peak_bytes / 4 * 3;
    let tight = headless::render_one_frame(&volume, budget, [64, 48])
        .unwrap_or_else(|e| panic!("a {budget}-byte budget: {e}"));
    assert!(!tight.plan.degradations.is_empty());
    assert!(tight.plan.peak_bytes <= budget);
    assert!(lit(&tight.pixels) > 500, "{} lit", lit(&tight.pixels));
}

/// Issue 13: the library's open path for a file. `Session::open` reads it (any registered
/// format) while the device starts, plans the recipe's effects, bricks when asked, and returns
/// what renders; a file no reader can read is a format-independent input error naming it.
#[test]
fn a_file_opens_through_the_librarys_session_bricked_when_asked() {
    use morphray::engine::plan::Layout;
    use morphray::engine::{OpenOptions, Session, SessionError};
    use morphray::volume::source::VolumeSource;
    let dir = std::env::temp_dir().join(format!("morphray-session-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("head.nii.gz");
    let spec = PhantomSpec {
        dims: [40, 40, 32],
        ..PhantomSpec::cohort_a()
    };
    let volume = generate(&spec).unwrap().volume;
    morphray::volume::nifti::write_nifti1(&volume, &path, true).unwrap();
    let mut config = EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        ..Default::default()
    };
    config.force_bricking = true;
    let options = OpenOptions {
        image: [48, 40],
        recipe: scene(),
        ..Default::default()
    };
    let mut session = Session::open(&VolumeSource::File(path.clone()), config.clone(), &options)
        .unwrap_or_else(|e| panic!("this test needs a Vulkan device: {e}"));
    assert_eq!(session.source.label, "head.nii.gz");
    assert!(matches!(session.plan.layout, Layout::Bricked { .. }));
    // The recipe's scene around this volume's peaks, with the planned effects.
    assert_eq!(session.scene.effects, session.plan.effects);
    assert!(session.scene.effects.curvature);
    assert!(
        session
            .scene
            .classification
            .style(morphray::scene::TissueClass::Wm)
            .window
            .is_some()
    );
    let mut target = session
        .engine
        .render_target(48, 40, vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    let frame = session
        .engine
        .render_twin(&mut target, &mut session.twin, &session.scene)
        .unwrap();
    let lit = frame.rgba8.chunks_exact(4).filter(|p| p[0] > 20).count();
    assert!(lit > 200, "{lit} lit pixels");

    let missing = dir.join("missing.nii");
    let e = Session::open(&VolumeSource::File(missing), config, &options)
        .err()
        .expect("a missing file cannot open");
    match &e {
        SessionError::Input(input) => assert!(input.nifti().is_some(), "{e}"),
        other => panic!("an input error, not {other}"),
    }
    assert!(e.to_string().contains("missing.nii"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}
