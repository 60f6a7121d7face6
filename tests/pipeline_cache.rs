//! The on-disk pipeline cache on a real device: saved after use, found by the next engine, and
//! a truncated, garbage or foreign-device file is rejected with a reason (never a panic or a
//! failed run) while the engine still renders. Validation layer on.

mod common;

use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::pipeline_cache::{CacheKey, decode_file, encode_file, file_name};
use morphray::gpu::{DeviceConfig, PersistOutcome, PipelineCacheConfig, Validation};
use morphray::volume::phantom::{PhantomSpec, generate};
use std::path::{Path, PathBuf};

fn engine(cache: PipelineCacheConfig) -> Engine {
    Engine::new(EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..Default::default()
        },
        pipeline_cache: cache,
        ..Default::default()
    })
    .unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        )
    })
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "morphray-pipeline-cache-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Opens a small phantom and renders one frame (creating every pipeline a first frame needs).
fn render_once(engine: &mut Engine) {
    let volume = generate(&PhantomSpec::cube(20)).unwrap().volume;
    let recipe = morphray::scene::SceneRecipe::default();
    let mut opened = engine.open_volume(&volume, [16, 16], &recipe).unwrap();
    let mut target = engine
        .render_target(16, 16, ash::vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    engine
        .render_twin(&mut target, &mut opened.twin, &opened.scene)
        .unwrap();
    common::assert_no_validation_errors(engine);
}

fn cache_file(engine: &Engine, dir: &Path) -> PathBuf {
    dir.join(file_name(&CacheKey::of(engine.device().adapter())))
}

#[test]
fn a_saved_cache_is_found_by_the_next_engine_and_saved_only_when_changed() {
    let dir = temp_dir("roundtrip");
    let config = PipelineCacheConfig::Directory(dir.clone());
    let mut first = engine(config.clone());
    let load = first.pipeline_cache().load().clone();
    assert_eq!(
        (load.loaded_bytes, &load.rejected),
        (0, &None),
        "no file yet"
    );
    assert_eq!(
        load.path.as_deref(),
        Some(cache_file(&first, &dir).as_path())
    );
    render_once(&mut first);
    let saved = first.persist_pipeline_cache().unwrap();
    assert!(
        matches!(saved, PersistOutcome::Written { bytes, .. } if bytes >= 32),
        "{saved:?}"
    );
    assert!(cache_file(&first, &dir).exists());
    // No temporary files are left beside it.
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
    assert_eq!(names.len(), 1, "{names:?}");
    drop(first);

    let mut second = engine(config);
    let load = second.pipeline_cache().load().clone();
    assert!(load.loaded_bytes >= 32, "{load:?}");
    assert_eq!(load.rejected, None);
    render_once(&mut second);
    // The same pipelines again: nothing new to save.
    assert!(matches!(
        second.persist_pipeline_cache().unwrap(),
        PersistOutcome::Unchanged { .. }
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn truncated_garbage_and_foreign_cache_files_are_rejected_and_the_engine_still_renders() {
    let dir = temp_dir("bad");
    let config = PipelineCacheConfig::Directory(dir.clone());
    let mut maker = engine(config.clone());
    render_once(&mut maker);
    maker.persist_pipeline_cache().unwrap();
    let path = cache_file(&maker, &dir);
    let key = CacheKey::of(maker.device().adapter());
    drop(maker);
    let good = std::fs::read(&path).unwrap();
    let payload = decode_file(&good, &key).unwrap().to_vec();
    let mut foreign_payload = payload.clone();
    // vendorID of VkPipelineCacheHeaderVersionOne (bytes 8..12).
    foreign_payload[8..12].copy_from_slice(&(key.vendor_id ^ 0xffff).to_le_bytes());
    let garbage: Vec<u8> = (0..3000u32).map(|i| (i * 7919 % 251) as u8).collect();
    let cases: [(&str, Vec<u8>); 4] = [
        ("truncated", good[..good.len() - 5].to_vec()),
        ("empty", Vec::new()),
        ("garbage", garbage),
        ("foreign device", encode_file(&foreign_payload)),
    ];
    for (what, bytes) in cases {
        std::fs::write(&path, &bytes).unwrap();
        let mut engine = engine(config.clone());
        let load = engine.pipeline_cache().load().clone();
        assert_eq!(load.loaded_bytes, 0, "{what}: {load:?}");
        let reason = load.rejected.unwrap_or_default();
        assert!(!reason.is_empty(), "{what} was not rejected");
        if what == "foreign device" {
            assert!(reason.contains("another device"), "{what}: {reason}");
        }
        // The run goes on with an empty cache, and the next save replaces the bad file.
        render_once(&mut engine);
        assert!(matches!(
            engine.persist_pipeline_cache().unwrap(),
            PersistOutcome::Written { .. }
        ));
        let rewritten = std::fs::read(&path).unwrap();
        assert!(decode_file(&rewritten, &key).is_ok(), "{what}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_cache_that_cannot_be_written_is_an_error_value_not_a_failed_engine() {
    let dir = temp_dir("unwritable");
    // A file where the cache directory should be: creating the directory fails.
    let blocked = dir.join("not-a-directory");
    std::fs::write(&blocked, b"x").unwrap();
    let mut engine = engine(PipelineCacheConfig::Directory(blocked.join("cache")));
    // Even looking for the file fails (not a directory): a reason, an empty cache, no error.
    let load = engine.pipeline_cache().load().clone();
    assert_eq!(load.loaded_bytes, 0);
    assert!(load.rejected.is_some(), "{load:?}");
    render_once(&mut engine);
    let error = engine.persist_pipeline_cache().unwrap_err();
    assert!(error.to_string().contains("cannot write"), "{error}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn in_memory_and_off_caches_touch_no_disk() {
    for config in [PipelineCacheConfig::InMemory, PipelineCacheConfig::Off] {
        let mut engine = engine(config.clone());
        assert_eq!(engine.pipeline_cache().load().path, None);
        assert_eq!(
            engine.pipeline_cache().raw() == ash::vk::PipelineCache::null(),
            config == PipelineCacheConfig::Off
        );
        render_once(&mut engine);
        assert_eq!(
            engine.persist_pipeline_cache().unwrap(),
            PersistOutcome::NotPersistent
        );
    }
    // The library's default is in memory.
    assert_eq!(
        EngineConfig::default().pipeline_cache,
        PipelineCacheConfig::InMemory
    );
}

/// Before: the cache file was read with `std::fs::read` after a metadata length check, so a FIFO
/// in its place blocked every engine forever and a link to `/dev/zero` (length 0) was read until
/// memory ran out. Now both are rejected with a note at once, the run renders, and the next
/// save replaces the link or FIFO itself (never writing through it).
#[test]
fn a_fifo_or_a_device_link_in_place_of_the_cache_is_ignored_at_once() {
    let dir = temp_dir("special");
    let config = PipelineCacheConfig::Directory(dir.clone());
    let path = cache_file(&engine(PipelineCacheConfig::Off), &dir);
    for what in ["fifo", "link to /dev/zero"] {
        let _ = std::fs::remove_file(&path);
        if what == "fifo" {
            let made = std::process::Command::new("mkfifo")
                .arg(&path)
                .status()
                .unwrap();
            assert!(made.success());
            // If opening blocked (the old behaviour), a writer arriving after 5 s unblocks it,
            // so the test fails on the time below instead of hanging.
            let late = path.clone();
            std::thread::spawn(move || {
                std::thread::sleep(std::time::Duration::from_secs(5));
                let _ = std::fs::OpenOptions::new().write(true).open(late);
            });
        } else {
            std::os::unix::fs::symlink("/dev/zero", &path).unwrap();
        }
        let start = std::time::Instant::now();
        let mut engine = engine(config.clone());
        let load = engine.pipeline_cache().load().clone();
        assert!(
            load.ms < 1000.0 && start.elapsed().as_secs() < 5,
            "{what}: {load:?}"
        );
        assert_eq!(load.loaded_bytes, 0, "{what}");
        let reason = load.rejected.unwrap_or_default();
        assert!(reason.contains("not a regular file"), "{what}: {reason}");
        render_once(&mut engine);
        assert!(matches!(
            engine.persist_pipeline_cache().unwrap(),
            PersistOutcome::Written { .. }
        ));
        assert!(
            std::fs::symlink_metadata(&path).unwrap().is_file(),
            "{what}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
