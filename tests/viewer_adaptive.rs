//! Adaptive quality (issue 17 item 3) on the machine's Vulkan device, offscreen and scripted with
//! the validation layer required: under a budget no device meets, a drag over the view renders
//! coarser frames and, once the hand stops for longer than the idle delay, one switch back to
//! full quality; with `--frame-budget 0` nothing coarsens; and the opacity correction keeps a
//! coarse step's picture as bright as the fine one (no brightness popping). Fails (never skips)
//! without a Vulkan device.

mod common;

use ash::vk;
use morphray::analysis::analyze;
use morphray::engine::{Engine, EngineConfig};
use morphray::gpu::{DeviceConfig, Validation};
use morphray::scene::{Classification, Scene};
use morphray::volume::nifti::write_nifti1;
use morphray::volume::phantom::{PhantomSpec, generate};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "morphray-viewer-adaptive-{}-{name}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn small_spec() -> PhantomSpec {
    PhantomSpec {
        dims: [40, 40, 32],
        ..PhantomSpec::cohort_a()
    }
}

/// Writes the small phantom and a script: a few frames, a drag over the view, a pause longer
/// than the idle delay, a few frames.
fn session(dir: &Path) -> (PathBuf, PathBuf) {
    let volume = dir.join("small.nii.gz");
    write_nifti1(&generate(&small_spec()).unwrap().volume, &volume, true).unwrap();
    let script = dir.join("drag.txt");
    std::fs::write(
        &script,
        "wait 3\ndrag left 0.3 0.5 0.7 0.5\nsleep 400\nwait 3\n",
    )
    .unwrap();
    (volume, script)
}

fn view(volume: &Path, script: &Path, budget: &str) -> String {
    let o: Output = Command::new("timeout")
        .arg("600")
        .arg(env!("CARGO_BIN_EXE_morphray"))
        .args(["view", "--layout", "3d"])
        .arg(volume)
        .args(["--offscreen", "--size", "480x360", "--frames", "1"])
        .arg("--script")
        .arg(script)
        .args(["--frame-budget", budget])
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("morphray runs");
    common::viewer::checked_log(&o)
}

/// The quality word of each frame line, in order.
fn qualities(log: &str) -> Vec<String> {
    log.lines()
        .filter(|l| l.starts_with("frame "))
        .filter_map(|l| l.split("|  quality ").nth(1))
        .map(|q| q.trim().to_string())
        .collect()
}

#[test]
fn a_drag_over_budget_coarsens_then_one_frame_brings_full_quality_back() {
    let dir = temp_dir("drag");
    let (volume, script) = session(&dir);
    // 0.01 ms: no device raymarches in that, so every interactive frame misses it.
    let log = view(&volume, &script, "0.01");
    let levels = qualities(&log);
    assert!(levels.len() >= 10, "every frame logs its level:\n{log}");
    let mut runs: Vec<(String, usize)> = Vec::new();
    for level in &levels {
        match runs.last_mut() {
            Some((l, n)) if l == level => *n += 1,
            _ => runs.push((level.clone(), 1)),
        }
    }
    let names: Vec<&str> = runs.iter().map(|(l, _)| l.as_str()).collect();
    // Full before the drag, the coarsest level (the coarsest step, then the smallest scale)
    // during it, then a single switch back: no intermediate levels on the way in or out.
    assert_eq!(
        names,
        ["full", "step x4, scale 0.5", "full"],
        "levels by frame: {levels:?}\n{log}"
    );
    assert!(runs[1].1 >= 3, "the drag's frames are coarse: {runs:?}");
    assert!(
        runs[2].1 >= 4,
        "full quality returns before the script ends (not only for the last frame): {runs:?}"
    );
    // During the `sleep` frames run as in an idle window, raymarching only on change: the coarse
    // image is shown again (no raymarch) until the delay ends, then one frame raymarches at full
    // quality although the scene did not change.
    let frames: Vec<&str> = log.lines().filter(|l| l.starts_with("frame ")).collect();
    let first_full = runs[0].1 + runs[1].1;
    assert!(
        frames[first_full - 1].contains("compute: none"),
        "the last coarse frame reused the image: {}",
        frames[first_full - 1]
    );
    assert!(
        frames[first_full].contains("compute: raymarch"),
        "the refinement frame raymarched: {}",
        frames[first_full]
    );
}

/// The RGB pixels of a PNG inside the 3D view's rectangle (from the log's layout line), less the
/// orientation letters' margins: the rest of the window holds the status bar, whose timings
/// differ from run to run, and the letters' antialiasing differs by a level or two.
fn view_pixels(path: &Path, log: &str) -> Vec<u8> {
    let line = log.lines().find(|l| l.starts_with("layout:")).unwrap();
    let words: Vec<&str> = line.split_whitespace().collect();
    let i = words.iter().position(|w| *w == "view").unwrap();
    let r: Vec<usize> = words[i + 1]
        .split(',')
        .map(|n| n.parse().unwrap())
        .collect();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut rgba).unwrap();
    let width = info.width as usize;
    let mut out = Vec::new();
    for y in r[1] + 24..r[1] + r[3] - 24 {
        for x in r[0] + 24..r[0] + r[2] - 24 {
            out.extend_from_slice(&rgba[(y * width + x) * 4..][..3]);
        }
    }
    out
}

#[test]
fn a_screenshot_taken_while_coarse_is_the_full_quality_picture() {
    let dir = temp_dir("shot");
    let (volume, _) = session(&dir);
    let shot = |budget: &str| {
        let png = dir.join(format!("shot-{budget}.png"));
        let script = dir.join(format!("shot-{budget}.txt"));
        std::fs::write(
            &script,
            format!(
                "wait 3\ndrag left 0.3 0.5 0.7 0.5\nscreenshot {}\nwait 1\n",
                png.display()
            ),
        )
        .unwrap();
        let log = view(&volume, &script, budget);
        let pixels = view_pixels(&png, &log);
        (log, pixels)
    };
    let (log, coarse_run) = shot("0.01");
    // The screenshot step came right after the drag's coarse frames (within the idle delay).
    assert!(
        qualities(&log).iter().any(|q| q == "step x4, scale 0.5"),
        "{log}"
    );
    let (_, full_run) = shot("0");
    assert!(
        coarse_run.iter().filter(|&&c| c > 24).count() > 1000,
        "the volume is on screen"
    );
    // Same drag, same camera: the screenshot equals the one of a run that never coarsens.
    assert!(
        coarse_run == full_run,
        "the screenshot is rendered at full quality ({} of {} bytes differ)",
        coarse_run
            .iter()
            .zip(&full_run)
            .filter(|(a, b)| a != b)
            .count(),
        coarse_run.len()
    );
}

#[test]
fn with_a_budget_of_zero_nothing_coarsens() {
    let dir = temp_dir("off");
    let (volume, script) = session(&dir);
    let log = view(&volume, &script, "0");
    let levels = qualities(&log);
    assert!(levels.len() >= 10, "{log}");
    assert!(levels.iter().all(|l| l == "full"), "{levels:?}");
    // The drag did move the camera (so there was something to coarsen).
    assert!(
        log.contains("action \"drag left 0.3 0.5 0.7 0.5\" -> first shown"),
        "{log}"
    );
}

#[test]
fn a_budget_that_is_not_a_time_is_a_usage_error() {
    for budget in [
        "--frame-budget=-2",
        "--frame-budget=inf",
        "--frame-budget=nan",
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
            .args([
                "view",
                "--layout",
                "3d",
                "--offscreen",
                "--frames",
                "1",
                budget,
            ])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{budget}: {stderr}");
        assert!(
            stderr.contains("--frame-budget") && stderr.contains("milliseconds >= 0"),
            "{budget}: {stderr}"
        );
    }
}

/// Mean RGB (premultiplied over black) of a render of the phantom at `step` voxels.
fn mean_brightness(engine: &mut Engine, step: f64) -> f64 {
    let volume = generate(&PhantomSpec {
        dims: [64, 64, 48],
        ..PhantomSpec::cohort_a()
    })
    .unwrap()
    .volume;
    let prepared = engine.prepare(&volume).unwrap();
    let (imin, imax) = (
        prepared.normalization.imin.unwrap(),
        prepared.normalization.imax.unwrap(),
    );
    let report = analyze(
        &prepared.histogram,
        imin,
        imax,
        prepared.voxel_count as usize,
        0,
    );
    let mut scene = Scene::new(Classification::from_tissue_windows(
        &report.adaptive_windows,
    ));
    scene.camera.azimuth_deg = 35.0;
    scene.camera.elevation_deg = 25.0;
    scene.step_voxels = step;
    let mut target = engine
        .render_target(96, 96, vk::Format::R32G32B32A32_SFLOAT)
        .unwrap();
    let derived = scene
        .effects
        .derivative_outputs()
        .map(|o| engine.derive(&prepared, o).unwrap());
    let frame = engine
        .render(&mut target, &prepared, derived.as_ref(), &scene)
        .unwrap();
    let rgb: f64 = frame
        .values
        .chunks_exact(4)
        .map(|c| (c[0] + c[1] + c[2]) as f64)
        .sum();
    rgb / (frame.values.len() / 4) as f64
}

#[test]
fn the_coarsest_step_keeps_the_picture_as_bright_as_the_full_one() {
    let mut engine = Engine::new(EngineConfig {
        device: DeviceConfig {
            validation: Validation::Required,
            ..DeviceConfig::default()
        },
        ..EngineConfig::default()
    })
    .unwrap_or_else(|e| panic!("this test needs a Vulkan device: {e}"));
    // The viewer's default step (0.5 voxel) and its coarsest level (x4).
    let full = mean_brightness(&mut engine, 0.5);
    let coarse = mean_brightness(&mut engine, 2.0);
    assert!(full > 0.05, "the phantom is visible: mean {full}");
    let change = (coarse - full).abs() / full;
    eprintln!(
        "mean brightness: step 0.5 {full:.4}, step 2.0 {coarse:.4} ({:.2} %)",
        change * 100.0
    );
    assert!(
        change < 0.03,
        "step x4 changes the mean brightness by {:.1} % (full {full}, coarse {coarse})",
        change * 100.0
    );
}
