//! Picture regression tests (issue 34 item 5): small stills of the phantom and the head phantom,
//! rendered with the library defaults of a `morphray render` still, compared with reference PNGs
//! in tests/pictures/ by SSIM (src/study/ssim.rs): the mean over the picture and the worst 8x8
//! block, each against a tolerance.
//!
//! Decisions:
//! - The stills are what `render` makes: the scene options parsed by the command line's own
//!   parser, `SceneArgs::as_still` (shaded, studio lighting, depth cues), the recipe built by
//!   `recipe_from_args`, the volume opened by the library's open path. Only the size (128x128)
//!   and the phantoms (64x64x48 voxels of 4 mm: cohort A's 256x256x192 mm at a 64th of the
//!   voxels, so opacities per mm look as at full size) are made small, to keep renders fast.
//! - One engine for the whole binary (its pipelines are compiled once on lavapipe); the tests
//!   take it in turn.
//! - Tolerances from measurement (this machine, lavapipe; `cargo test --test pictures --
//!   --nocapture` prints them): with the stills' defaults, another jitter seed scores 0.9916
//!   mean / 0.8376 worst block and a step of 0.45 instead of 0.5 0.9933 / 0.8727; with the
//!   depth cues off 0.9932 / 0.8376 and 0.9951 / 0.8724; a step of 0.49999 scores 1.0000 /
//!   0.9977 and the camera turned by 0.01 degrees 0.9999 / 0.9989 (rounding-sized changes, as
//!   another lavapipe or CPU might make). Against the phantom's reference, the previous default
//!   opacities score 0.9178 / 0.3122, shading off 0.8049 / 0.1730, the previous lighting
//!   (headlight, no cues) 0.9404 / 0.5752. The tolerances, 0.97 and 0.60, sit between.
//! - The references are compared at jitter seed 0, where a render is deterministic (the same
//!   bytes on every run here). Before the depth cues' probes were scaled to the voxel (4 mm on
//!   these phantoms), a seed change with the cues on scored 0.91 / 0.11 to 0.21.
//! - `MORPHRAY_UPDATE_PICTURES=1 cargo test --test pictures` rewrites every reference (and says
//!   which); a failure writes the picture and its SSIM map under target/pictures-failed/.

mod common;

use ash::vk;
use morphray::cli::render::recipe_from_args;
use morphray::cli::scene_options::parse_scene_args;
use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::{DeviceConfig, Validation};
use morphray::scene::Scene;
use morphray::study::ssim::{self, Ssim};
use morphray::volume::phantom::{PhantomSpec, generate};
use morphray::volume::phantom_contrast::Contrast;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, OnceLock};

/// Picture side, pixels.
const SIZE: u32 = 128;
/// Lowest mean SSIM that passes.
const TOLERANCE_MEAN: f64 = 0.97;
/// Lowest SSIM of the worst 8x8 block that passes.
const TOLERANCE_BLOCK: f64 = 0.60;

/// The plain phantom (dark shell, cohort-A size in mm) at 64x64x48 voxels.
fn phantom() -> PhantomSpec {
    PhantomSpec {
        dims: [64, 64, 48],
        spacing_mm: [4.0; 3],
        ..PhantomSpec::cohort_a()
    }
}

/// The head phantom (T1, noise) at 64x64x48 voxels of 4 mm.
fn head() -> PhantomSpec {
    PhantomSpec {
        spacing_mm: [4.0; 3],
        ..PhantomSpec::head([64, 64, 48], Contrast::T1, true)
    }
}

/// The engine of this binary: validation required, the library's default normalization (the
/// robust range, as `render`). No device is a failure that says what to install.
fn engine() -> MutexGuard<'static, Engine> {
    static ENGINE: OnceLock<Mutex<Engine>> = OnceLock::new();
    let engine = ENGINE.get_or_init(|| {
        let config = EngineConfig {
            device: DeviceConfig {
                validation: Validation::Required,
                ..Default::default()
            },
            ..Default::default()
        };
        match Engine::new(config) {
            Ok(engine) => Mutex::new(engine),
            Err(e) => panic!(
                "the picture tests need a Vulkan device with the validation layer \
                 (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
            ),
        }
    });
    // A test that failed while holding it leaves the engine usable.
    engine
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The RGBA8 still of `spec` with the `render` options `words`; `tweak` changes the planned
/// scene before the frame (the measurements of the tolerances).
fn render(spec: &PhantomSpec, words: &[&str], tweak: impl FnOnce(&mut Scene)) -> Vec<u8> {
    let words: Vec<String> = words.iter().map(|w| w.to_string()).collect();
    let args = parse_scene_args(&words).unwrap().as_still();
    let recipe = recipe_from_args(&args).unwrap();
    let volume = generate(spec).unwrap().volume;
    let mut engine = engine();
    let mut opened = engine.open_volume(&volume, [SIZE, SIZE], &recipe).unwrap();
    tweak(&mut opened.scene);
    let mut target = engine
        .render_target(SIZE, SIZE, vk::Format::R8G8B8A8_UNORM)
        .unwrap();
    let frame = engine
        .render_twin(&mut target, &mut opened.twin, &opened.scene)
        .unwrap();
    common::assert_no_validation_errors(&engine);
    frame.rgba8
}

fn reference_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/pictures")
        .join(format!("{name}.png"))
}

/// target/pictures-failed/ (beside CARGO_TARGET_TMPDIR, so it follows CARGO_TARGET_DIR).
fn failed_dir() -> PathBuf {
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    tmp.parent().unwrap_or(tmp).join("pictures-failed")
}

/// Writes 8-bit pixels (`color`: RGB or grey) as a PNG.
fn write_png(path: &Path, width: u32, pixels: &[u8], color: png::ColorType) {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    }
    let height = pixels.len() as u32 / width / color.samples() as u32;
    let file = std::fs::File::create(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width, height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(pixels).unwrap();
    writer.finish().unwrap();
}

fn rgb(rgba: &[u8]) -> Vec<u8> {
    rgba.chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect()
}

/// The reference picture `name` as RGBA8 (alpha 255); a missing one says how to make it.
fn reference(name: &str) -> Vec<u8> {
    let path = reference_path(name);
    if !path.exists() {
        panic!(
            "no reference picture {}: run MORPHRAY_UPDATE_PICTURES=1 cargo test --test pictures",
            path.display()
        );
    }
    let picture = common::pictures::Picture::read(&path);
    assert_eq!(
        (picture.width, picture.pixels.len()),
        (SIZE, (SIZE * SIZE) as usize),
        "{}: not a {SIZE}x{SIZE} picture",
        path.display()
    );
    picture
        .pixels
        .iter()
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect()
}

fn score(actual: &[u8], name: &str) -> Ssim {
    let n = SIZE as usize;
    ssim::compare_rgba8(actual, &reference(name), n, n).unwrap()
}

/// MORPHRAY_UPDATE_PICTURES=1: the references are being rewritten.
fn updating() -> bool {
    std::env::var_os("MORPHRAY_UPDATE_PICTURES").is_some_and(|v| v == "1")
}

fn passes(s: &Ssim) -> bool {
    s.mean >= TOLERANCE_MEAN && s.worst_block >= TOLERANCE_BLOCK
}

/// Renders still `name` and checks it against its reference (or rewrites the reference when
/// MORPHRAY_UPDATE_PICTURES=1).
fn check(name: &str, spec: &PhantomSpec, words: &[&str]) {
    let actual = render(spec, words, |_| {});
    let path = reference_path(name);
    if updating() {
        write_png(&path, SIZE, &rgb(&actual), png::ColorType::Rgb);
        // Past the test harness's capture: the list shows without --nocapture.
        let _ = writeln!(
            std::io::stderr(),
            "wrote reference picture {}",
            path.display()
        );
        return;
    }
    let s = score(&actual, name);
    println!(
        "{name}: mean SSIM {:.5}, worst 8x8 block {:.5} at {:?}",
        s.mean, s.worst_block, s.worst_block_at
    );
    if passes(&s) {
        return;
    }
    let dir = failed_dir();
    let (picture, map) = (
        dir.join(format!("{name}.png")),
        dir.join(format!("{name}-ssim.png")),
    );
    write_png(&picture, SIZE, &rgb(&actual), png::ColorType::Rgb);
    write_png(
        &map,
        s.map_width as u32,
        &s.map_gray8(),
        png::ColorType::Grayscale,
    );
    panic!(
        "picture `{name}` regressed: mean SSIM {:.5} (needs >= {TOLERANCE_MEAN}), worst 8x8 \
         block {:.5} at {:?} (needs >= {TOLERANCE_BLOCK}); reference {}, this run {}, SSIM map \
         {} (white = same). If the change is meant, rewrite the references: \
         MORPHRAY_UPDATE_PICTURES=1 cargo test --test pictures",
        s.mean,
        s.worst_block,
        s.worst_block_at,
        path.display(),
        picture.display(),
        map.display()
    );
}

#[test]
fn phantom_still() {
    check("phantom", &phantom(), &[]);
}

#[test]
fn phantom_mip() {
    check("phantom-mip", &phantom(), &["--mode", "mip"]);
}

/// The head with `--brain auto` (the default), which finds the brain: the same picture as
/// `--brain on` (SSIM 1.00000 on this machine).
#[test]
fn head_still() {
    check("head", &head(), &[]);
}

/// The head with the brain extraction off: skin, eyes, nose and neck.
#[test]
fn head_brain_off() {
    check("head-brain-off", &head(), &["--brain", "off"]);
}

/// The scores of `words` with `tweak` against the same scene at jitter seed 0, step as given.
fn perturbed(words: &[&str], more: &[&str], tweak: impl FnOnce(&mut Scene)) -> Ssim {
    let base = render(&phantom(), words, |_| {});
    let changed: Vec<&str> = words.iter().chain(more).copied().collect();
    let other = render(&phantom(), &changed, tweak);
    ssim::compare_rgba8(&other, &base, SIZE as usize, SIZE as usize).unwrap()
}

fn report(what: &str, s: &Ssim) -> String {
    format!(
        "{what}: mean SSIM {:.4}, worst block {:.4} (tolerances {TOLERANCE_MEAN}, {TOLERANCE_BLOCK})",
        s.mean, s.worst_block
    )
}

/// The tolerances are loose enough for what should not count as a change: another jitter seed
/// and a step 10 % shorter with the depth cues off (the test below has them on); and, with the
/// stills' defaults, changes of the size of another device's rounding (a step 0.00002 %
/// shorter, the camera turned by 0.01 degrees).
#[test]
fn harmless_changes_pass() {
    let cues_off = ["--depth-cues", "off"];
    let seed = perturbed(&cues_off, &[], |s| s.frame = 7);
    let step = perturbed(&cues_off, &["--step", "0.45"], |_| {});
    let rounding = perturbed(&[], &["--step", "0.49999"], |_| {});
    let turned = perturbed(&[], &[], |s| s.camera.azimuth_deg += 0.01);
    for (what, s) in [
        ("jitter seed 7, cues off", &seed),
        ("step 0.45, cues off", &step),
        ("step 0.49999", &rounding),
        ("azimuth + 0.01 degrees", &turned),
    ] {
        println!("{}", report(what, s));
        assert!(passes(s), "{} must pass", report(what, s));
    }
}

/// The same with the stills' defaults (depth cues on): another seed and a shorter step pass.
#[test]
fn harmless_changes_pass_with_the_still_defaults() {
    let seed = perturbed(&[], &[], |s| s.frame = 7);
    let step = perturbed(&[], &["--step", "0.45"], |_| {});
    for (what, s) in [("jitter seed 7", &seed), ("step 0.45", &step)] {
        println!("{}", report(what, s));
        assert!(passes(s), "{} must pass", report(what, s));
    }
}

/// The check bites: the stills' previous default opacities (CSF 0.20, GM 0.30, WM 0.90),
/// shading off and the previous lighting (headlight, no cues) each fail against the phantom's
/// reference. The depth cues alone change these 4 mm phantoms too little at 128 px to be seen
/// here (0.9966 / 0.9491); tests/gpu_lighting.rs checks that they darken a groove.
#[test]
fn changed_scenes_fail() {
    if updating() {
        return;
    }
    let old = [
        "--opacity",
        "gm=0.30",
        "--opacity",
        "wm=0.90",
        "--opacity",
        "csf=0.20",
    ];
    for (what, words) in [
        ("old opacities", &old[..]),
        ("shading off", &["--shading", "off"][..]),
        (
            "headlight, no cues",
            &["--lighting", "headlight", "--depth-cues", "off"][..],
        ),
    ] {
        let s = score(&render(&phantom(), words, |_| {}), "phantom");
        println!("{}", report(what, &s));
        assert!(!passes(&s), "{} must fail", report(what, &s));
    }
}
