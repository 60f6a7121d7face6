//! 4-D files in the viewer (issue 31 item 5): the frames are held in memory when the file is
//! opened, a frame change re-prepares only the new frame (the file is not read again), `frame N`
//! shows frame N, `play` advances frames by the wall clock, the time course at the crosshair is
//! the written values in the scanner's units (scl_slope 2.5, scl_inter 10), the 3D picture
//! changes between frames and comes back pixel for pixel, and a bad frame rate is refused.
//! Offscreen and in a window under Xvfb, validation layer required; fails (never skips) without
//! a Vulkan device or xvfb-run.

mod common;

use morphray::volume::LinearMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const DIMS: [usize; 3] = [24, 20, 16];
const FRAMES: usize = 6;
/// The blob's centre voxel (world mm too: the affine is the identity).
const BLOB: [usize; 3] = [12, 10, 8];
const MAP: LinearMap = LinearMap {
    slope: 2.5,
    intercept: 10.0,
};

/// Stored value of the blob in frame `t`: brightest in frame 0, darker by 40 a frame (frames
/// after the first stay inside its normalization range).
fn blob_stored(t: usize) -> i16 {
    400 - 40 * t as i16
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-cine-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A box of stored value 100 with a 5x5x5 blob at [`BLOB`] whose value changes by frame.
fn phantom(dir: &Path) -> PathBuf {
    let frames: Vec<Vec<i16>> = (0..FRAMES)
        .map(|t| {
            let mut values = Vec::new();
            for k in 0..DIMS[2] {
                for j in 0..DIMS[1] {
                    for i in 0..DIMS[0] {
                        let p = [i, j, k];
                        let near = (0..3).all(|a| p[a].abs_diff(BLOB[a]) <= 2);
                        let inside = (0..3).all(|a| (3..DIMS[a] - 3).contains(&p[a]));
                        values.push(match (near, inside) {
                            (true, _) => blob_stored(t),
                            (false, true) => 100,
                            _ => 0,
                        });
                    }
                }
            }
            values
        })
        .collect();
    let path = dir.join("cine.nii");
    common::four_d::write_4d(&path, DIMS, &frames, MAP);
    path
}

/// `morphray view` on `volume` with `script` and `extra` arguments, offscreen or in a window
/// under Xvfb; the log after the common checks (device found, exit 0, no validation error).
fn view(volume: &Path, script: &str, window: bool, extra: &[&str]) -> String {
    let dir = volume.parent().unwrap();
    let script_path = dir.join(if window { "window.txt" } else { "script.txt" });
    std::fs::write(&script_path, script).unwrap();
    let mut command = common::viewer::view_command(window);
    let o = command
        .current_dir(dir)
        .arg(volume)
        .args([
            "--layout",
            "slices",
            "--mode",
            "mip",
            "--normalize",
            "minmax",
        ])
        .args(["--size", "900x600", "--frames", "3", "--script"])
        .arg(&script_path)
        .args(extra)
        .output()
        .expect("morphray runs");
    common::viewer::checked_log(&o)
}

/// The numbers after `prefix` on its first line in `log`.
fn numbers_after(log: &str, prefix: &str) -> Vec<f64> {
    let line = log
        .lines()
        .find_map(|l| l.strip_prefix(prefix))
        .unwrap_or_else(|| panic!("no `{prefix}` in\n{log}"));
    line.split(", ").map(|v| v.parse().unwrap()).collect()
}

/// Pixels that differ between two PNGs of the same size.
fn differing(a: &Path, b: &Path) -> usize {
    let (a, b) = (
        common::pictures::Picture::read(a),
        common::pictures::Picture::read(b),
    );
    assert_eq!(a.pixels.len(), b.pixels.len());
    a.pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(p, q)| p != q)
        .count()
}

#[test]
fn frames_are_held_shown_played_and_plotted_without_reading_the_file_again() {
    let dir = temp_dir("held");
    let volume = phantom(&dir);
    let log = view(
        &volume,
        "crosshair 12 10 8\n\
         save-view f0.png 160x120\n\
         frame 3\n\
         save-view f3.png 160x120\n\
         frame 0\n\
         save-view back.png 160x120\n\
         play 20\n\
         sleep 1200\n\
         pause\n",
        false,
        &[],
    );
    assert!(
        log.contains(&format!("4-D: {FRAMES} frames held in memory")),
        "{log}"
    );
    // Opened once: the frame changes came from memory.
    assert_eq!(log.matches("\nloaded ").count(), 1, "{log}");
    assert!(
        log.contains(&format!("frame 3/{FRAMES} shown in "))
            && log.contains("held in memory, no file read"),
        "{log}"
    );
    assert!(
        log.contains("action \"frame 3\" -> first shown by frame"),
        "{log}"
    );
    // Frame 3 is what the crosshair reads after it: 2.5 x 280 + 10.
    let after = log.split("frame 3/6 shown in").nth(1).unwrap_or_default();
    assert!(after.contains("voxel 12, 10, 8  |  value 710"), "{log}");
    // The time course at the blob's voxel: the written values in the scanner's units.
    let course = numbers_after(&log, "time course at voxel (12, 10, 8): ");
    let want: Vec<f64> = (0..FRAMES)
        .map(|t| MAP.slope * f64::from(blob_stored(t)) + MAP.intercept)
        .collect();
    assert_eq!(course, want, "{log}");
    // Playback advanced by itself, then stopped.
    let played = log.split("playing at 20 fps").nth(1).expect("playing");
    assert!(
        played.contains(&format!("/{FRAMES} shown in ")),
        "no frame shown while playing:\n{log}"
    );
    assert!(log.contains("paused at frame "), "{log}");
    // The 3D picture changes with the frame and comes back pixel for pixel.
    let changed = differing(&dir.join("f0.png"), &dir.join("f3.png"));
    assert!(
        changed > 20,
        "frame 3 differs from frame 0 in {changed} pixels"
    );
    assert_eq!(differing(&dir.join("f0.png"), &dir.join("back.png")), 0);
}

#[test]
fn a_frame_chosen_while_playing_is_where_playback_goes_on_from() {
    let dir = temp_dir("jump");
    let volume = phantom(&dir);
    let log = view(&volume, "play 2\nframe 4\nsleep 800\npause\n", false, &[]);
    let shown: Vec<&str> = log
        .lines()
        .filter(|l| l.contains("/6 shown in "))
        .map(|l| l.split(" shown in").next().unwrap_or_default())
        .collect();
    let at = shown
        .iter()
        .position(|&f| f == "frame 4/6")
        .expect("frame 4");
    assert_eq!(shown.get(at + 1), Some(&"frame 5/6"), "{log}");
}

/// The phantom as a `.hdr`/`.img` pair (NIfTI-1 `ni1`): its frames are streamed.
fn pair(dir: &Path) -> PathBuf {
    let single = std::fs::read(phantom(dir)).unwrap();
    let offset = f32::from_le_bytes(single[108..112].try_into().unwrap()) as usize;
    let mut header = single[..348].to_vec();
    header[108..112].copy_from_slice(&0f32.to_le_bytes()); // vox_offset: the .img's start
    header[344..348].copy_from_slice(b"ni1\0");
    let hdr = dir.join("pair.hdr");
    std::fs::write(&hdr, header).unwrap();
    std::fs::write(dir.join("pair.img"), &single[offset..]).unwrap();
    hdr
}

#[test]
fn a_pair_s_frames_are_streamed_one_at_a_time_with_the_same_look() {
    let dir = temp_dir("streamed");
    let volume = pair(&dir);
    let log = view(&volume, "frame 3\nframe 4\n", false, &[]);
    assert!(
        log.contains("4-D: frames streamed from the file: a .hdr/.img pair"),
        "{log}"
    );
    // Read from the file, but prepared like the frame on screen: no second open.
    assert!(log.contains("frame 3/6 shown in "), "{log}");
    assert!(log.contains("read from the file in "), "{log}");
    assert_eq!(log.matches("\nloaded ").count(), 1, "{log}");
    assert!(!log.contains("time course at voxel"), "{log}");
}

#[test]
fn a_window_plays_from_the_command_line_and_draws_the_time_course() {
    let dir = temp_dir("window");
    let volume = phantom(&dir);
    let shot = dir.join("cine-window.png");
    let log = view(
        &volume,
        "crosshair 12 10 8\nsleep 1500\n",
        true,
        &[
            "--play",
            "--fps",
            "8",
            "--screenshot",
            shot.to_str().unwrap(),
        ],
    );
    assert!(log.contains("playing at 8 fps from frame 0"), "{log}");
    assert!(log.contains(&format!("/{FRAMES} shown in ")), "{log}");
    // The plot's line colour (cine_panel.rs) in the side panel.
    let picture = common::pictures::Picture::read(&shot);
    let line = picture
        .find(Some([0, 0, 300, 600]), |p| {
            p[0] < 130 && p[1] > 170 && p[2] > 210
        })
        .len();
    assert!(line > 40, "{line} pixels of the time course's line");
}

#[test]
fn a_frame_rate_out_of_range_is_refused() {
    let dir = temp_dir("fps");
    let volume = phantom(&dir);
    for fps in ["0", "61", "-2", "fast", "NaN"] {
        let o: Output = Command::new(env!("CARGO_BIN_EXE_morphray"))
            .env_remove("DISPLAY")
            .args([
                "view",
                "--offscreen",
                "--frames",
                "2",
                &format!("--fps={fps}"),
            ])
            .arg(&volume)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "--fps {fps} accepted");
        assert!(
            stderr.contains("give 0.1 to 60 frames per second"),
            "--fps {fps}: {stderr}"
        );
    }
    std::fs::write(dir.join("bad.txt"), "play 100\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .env_remove("DISPLAY")
        .args(["view", "--offscreen", "--script"])
        .arg(dir.join("bad.txt"))
        .arg(&volume)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("bad.txt:1: play 100 frames per second"),
        "{stderr}"
    );
}
