//! The viewer as a person (or CI) runs it: `morphray view` in a real window under Xvfb on the
//! machine's Vulkan device (lavapipe here), scripted, with the validation layer required.
//! Screenshots are checked where the interface draws things: the histogram panel has its bar
//! colour, the 3D view has the volume, toggling WM changes the view, and the lesion (left
//! hemisphere) appears on the side the orientation letter `L` marks.
//!
//! These tests fail (never skip) when xvfb-run or a Vulkan device is missing.

use morphray::app::histogram::BAR_COLOUR;
use morphray::volume::nifti::write_nifti1;
use morphray::volume::phantom::{PhantomSpec, generate};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-viewer-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A small phantom (48x48x40, 1 mm) with CSF, GM, WM and the left-hemisphere lesion.
fn small_phantom(dir: &Path) -> PathBuf {
    let spec = PhantomSpec {
        dims: [48, 48, 40],
        ..PhantomSpec::cohort_a()
    };
    let phantom = generate(&spec).unwrap();
    let path = dir.join("small.nii.gz");
    write_nifti1(&phantom.volume, &path, true).unwrap();
    path
}

fn xvfb_run() -> &'static str {
    let found = Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        found,
        "this test needs xvfb-run (Debian: apt-get install xvfb xauth; tools/setup.sh installs it)"
    );
    "xvfb-run"
}

/// Runs `morphray view ARGS` under Xvfb (or offscreen without DISPLAY) with validation required,
/// killed as hung after 10 minutes.
fn view(args: &[&str], window: bool) -> Output {
    let output = view_within(args, window, std::time::Duration::from_secs(600));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        !stderr.contains("no Vulkan") && !stderr.contains("found no device"),
        "this test needs a Vulkan device (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {stderr}"
    );
    output
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn assert_ok(o: &Output) {
    assert!(
        o.status.success(),
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        stdout(o),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout(o).contains("validation layer: 0 error(s)"),
        "validation must be on and clean:\n{}",
        stdout(o)
    );
}

struct Png {
    width: u32,
    height: u32,
    rgba: Vec<u8>,
}

impl Png {
    fn read(path: &Path) -> Png {
        let decoder = png::Decoder::new(std::io::BufReader::new(
            std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
        ));
        let mut reader = decoder.read_info().unwrap();
        let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut rgba).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgba);
        Png {
            width: info.width,
            height: info.height,
            rgba,
        }
    }

    fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = ((y * self.width + x) * 4) as usize;
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2]]
    }

    fn pixels_in(&self, r: [u32; 4]) -> impl Iterator<Item = (u32, u32, [u8; 3])> + '_ {
        (r[1]..r[1] + r[3])
            .flat_map(move |y| (r[0]..r[0] + r[2]).map(move |x| (x, y, self.pixel(x, y))))
    }
}

/// `name x,y,w,h` from the layout line of the log.
fn layout_rect(log: &str, name: &str) -> [u32; 4] {
    let line = log
        .lines()
        .find(|l| l.starts_with("layout:"))
        .unwrap_or_else(|| panic!("no layout line in:\n{log}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    let i = words.iter().position(|w| *w == name).unwrap();
    let v: Vec<u32> = words[i + 1]
        .split(',')
        .map(|n| n.parse().unwrap())
        .collect();
    [v[0], v[1], v[2], v[3]]
}

fn layout_word(log: &str, name: &str) -> String {
    let line = log.lines().find(|l| l.starts_with("layout:")).unwrap();
    let words: Vec<&str> = line.split_whitespace().collect();
    let i = words.iter().position(|w| *w == name).unwrap();
    words[i + 1].to_string()
}

/// Pixels of the 3D view that differ from the background (black).
fn lit(png: &Png, view: [u32; 4]) -> usize {
    // Skip the letters' margins (yellow text at the edges).
    let inner = [view[0] + 24, view[1] + 24, view[2] - 48, view[3] - 48];
    png.pixels_in(inner)
        .filter(|(_, _, p)| p.iter().any(|&c| c > 24))
        .count()
}

#[test]
fn scripted_window_session_shows_histogram_volume_and_reacts_to_a_toggle() {
    let dir = temp_dir("window");
    let volume = small_phantom(&dir);
    let script = dir.join("actions.txt");
    let (a, b, last) = (dir.join("a.png"), dir.join("b.png"), dir.join("last.png"));
    std::fs::write(
        &script,
        format!(
            "wait 1\nscreenshot {}\ntoggle wm\nwait 1\nscreenshot {}\ntoggle wm\norbit 30 0\nset window gm 0.3 0.6\nidle 3\nresize 600 440\nwait 2\n",
            a.display(),
            b.display()
        ),
    )
    .unwrap();
    let o = view(
        &[
            volume.to_str().unwrap(),
            "--size",
            "640x480",
            "--frames",
            "6",
            "--script",
            script.to_str().unwrap(),
            "--screenshot",
            last.to_str().unwrap(),
        ],
        true,
    );
    assert_ok(&o);
    let log = stdout(&o);
    assert!(
        log.contains("(window 640x480"),
        "a real window and swapchain:\n{log}"
    );

    let view_rect = layout_rect(&log, "view");
    let hist = layout_rect(&log, "histogram");
    let a = Png::read(&a);
    assert_eq!((a.width, a.height), (640, 480));
    // The histogram panel: its bars' colour is there.
    let bars = a
        .pixels_in(hist)
        .filter(|(_, _, p)| *p == [BAR_COLOUR.r(), BAR_COLOUR.g(), BAR_COLOUR.b()])
        .count();
    assert!(bars > 100, "histogram bars in {hist:?}: {bars} pixels");
    // The volume: not blank.
    let lit_a = lit(&a, view_rect);
    assert!(
        lit_a > 2000,
        "the 3D view shows the volume: {lit_a} lit pixels"
    );
    // After `toggle wm` the rendered region changed.
    let b = Png::read(&b);
    let changed = a
        .pixels_in(view_rect)
        .zip(b.pixels_in(view_rect))
        .filter(|((_, _, p), (_, _, q))| p != q)
        .count();
    assert!(
        changed > 1000,
        "toggling WM changed {changed} pixels of the view"
    );
    assert!(
        Png::read(&last).rgba != a.rgba,
        "orbit and window edit changed the frame"
    );

    // Provenance as `morphray render` writes it.
    let chunks = morphray::files::png::read_text_chunks(&last).unwrap();
    let input = chunks.iter().find(|(k, _)| k == "morphray:input").unwrap();
    assert_eq!(input.1, "small.nii.gz");
    assert!(
        chunks
            .iter()
            .any(|(k, v)| k == "morphray:parameters" && v.contains("\"scene\""))
    );

    // Only the raymarch ran after the first frame; every action was seen and timed.
    assert!(
        log.contains("other compute passes after the first frame: none"),
        "{log}"
    );
    // `idle`: as in an interactive window, an unchanged scene reuses the last image.
    assert!(
        log.lines()
            .any(|l| l.starts_with("frame") && l.contains("compute: none")),
        "idle frames without a raymarch:\n{log}"
    );
    for action in ["toggle wm", "orbit 30 0", "set window gm 0.3 0.6"] {
        assert!(
            log.lines()
                .any(|l| l.starts_with(&format!("action \"{action}\" -> first shown by frame"))),
            "latency of `{action}` missing:\n{log}"
        );
    }
}

#[test]
fn orientation_letters_match_the_picture_for_the_lesion() {
    // The phantom's lesion is in the left hemisphere (world x < 0). In the anterior view the
    // letter on the image's right must be L, and the lesion must be on that side; from behind,
    // R on the right and the lesion on the left.
    let dir = temp_dir("letters");
    let volume = small_phantom(&dir);
    for (view_name, right_letter, lesion_right) in
        [("anterior", "L", true), ("posterior", "R", false)]
    {
        let shot = dir.join(format!("{view_name}.png"));
        let script = dir.join(format!("{view_name}.txt"));
        std::fs::write(
            &script,
            format!("hide csf\nhide gm\nhide wm\nshow pathology\nview {view_name}\n"),
        )
        .unwrap();
        let o = view(
            &[
                volume.to_str().unwrap(),
                "--size",
                "640x480",
                "--frames",
                "2",
                "--script",
                script.to_str().unwrap(),
                "--screenshot",
                shot.to_str().unwrap(),
                "--offscreen",
                // The headlight: under the studio key light a shadowed orange GM pixel passes
                // the red test below.
                "--lighting",
                "headlight",
                "--depth-cues",
                "off",
            ],
            false,
        );
        assert_ok(&o);
        let log = stdout(&o);
        assert_eq!(layout_word(&log, "right"), right_letter, "{log}");
        let view_rect = layout_rect(&log, "view");
        let png = Png::read(&shot);
        let red: Vec<u32> = png
            .pixels_in(view_rect)
            .filter(|(_, _, p)| p[0] > 120 && p[1] < 80 && p[2] < 80)
            .map(|(x, _, _)| x)
            .collect();
        assert!(
            red.len() > 20,
            "{view_name}: the lesion is visible ({} red pixels)",
            red.len()
        );
        let mean = red.iter().map(|&x| x as f64).sum::<f64>() / red.len() as f64;
        let centre = view_rect[0] as f64 + view_rect[2] as f64 / 2.0;
        assert_eq!(
            mean > centre,
            lesion_right,
            "{view_name}: lesion at x {mean:.0}, view centre {centre:.0}"
        );
    }
}

#[test]
fn a_bad_file_keeps_the_volume_and_a_lost_device_recovers() {
    let dir = temp_dir("robust");
    let volume = small_phantom(&dir);
    let bad = dir.join("broken.nii");
    std::fs::write(&bad, b"not a nifti file").unwrap();
    let script = dir.join("robust.txt");
    std::fs::write(
        &script,
        format!(
            "open {}\nwait 1\nsimulate-device-lost\nwait 2\n",
            bad.display()
        ),
    )
    .unwrap();
    let shot = dir.join("after.png");
    let o = view(
        &[
            volume.to_str().unwrap(),
            "--size",
            "480x360",
            "--frames",
            "3",
            "--script",
            script.to_str().unwrap(),
            "--screenshot",
            shot.to_str().unwrap(),
            "--offscreen",
        ],
        false,
    );
    assert_ok(&o);
    let log = stdout(&o);
    assert!(log.contains("load failed: broken.nii"), "{log}");
    assert!(log.contains("The GPU device was lost"), "{log}");
    assert_eq!(
        log.matches("loaded small.nii.gz").count(),
        2,
        "the volume is reloaded on the new device:\n{log}"
    );
    let png = Png::read(&shot);
    assert!(
        lit(&png, layout_rect(&log, "view")) > 2000,
        "the volume is back"
    );
}

#[test]
fn closing_the_window_during_a_load_exits_cleanly() {
    let dir = temp_dir("close");
    let volume = small_phantom(&dir);
    let script = dir.join("close.txt");
    // The built-in phantom is 256x256x192: its load is still running at `close`.
    std::fs::write(&script, "open phantom\nclose\n").unwrap();
    let started = std::time::Instant::now();
    let o = view(
        &[
            volume.to_str().unwrap(),
            "--size",
            "480x360",
            "--script",
            script.to_str().unwrap(),
        ],
        true,
    );
    assert_ok(&o);
    let log = stdout(&o);
    assert!(log.contains("closed during a load"), "{log}");
    assert!(
        started.elapsed().as_secs() < 120,
        "closing does not wait for the whole load"
    );
}

/// A window smaller than the interface panels leaves no room for the volume: the scripted run
/// still ends after its frames (it used to wait forever for a volume frame) and says why.
#[test]
fn a_window_too_small_for_the_volume_ends_and_says_why() {
    let dir = temp_dir("tiny");
    let volume = small_phantom(&dir);
    let o = view(
        &[
            volume.to_str().unwrap(),
            "--size",
            "320x200",
            "--frames",
            "3",
            "--offscreen",
        ],
        false,
    );
    assert_ok(&o);
    let log = stdout(&o);
    assert!(
        log.contains("leaves no room for the volume beside the panels"),
        "{log}"
    );
}

#[test]
fn an_offscreen_script_ends_with_its_last_line_and_times_each_opened_file() {
    // Offscreen, the script's end is the session's end: without `close` or --frames the viewer
    // used to run forever. Each opened file's first pixel is logged (issue 17's second-file
    // measurement reads these lines).
    let dir = temp_dir("script-end");
    let volume = small_phantom(&dir);
    let script = dir.join("open-again.txt");
    std::fs::write(&script, format!("open {}\n", volume.display())).unwrap();
    let o = view_within(
        &[
            volume.to_str().unwrap(),
            "--offscreen",
            "--size",
            "640x480",
            "--script",
            script.to_str().unwrap(),
        ],
        false,
        std::time::Duration::from_secs(240),
    );
    assert_ok(&o);
    let log = stdout(&o);
    let firsts = log
        .lines()
        .filter(|l| l.starts_with("time to first pixel of "))
        .count();
    assert_eq!(firsts, 2, "one line per opened file:\n{log}");
}

/// Runs `morphray view ARGS` (offscreen, or under Xvfb) and kills it after `limit`: a run that
/// does not end by then is reported as hung (the viewer used to wait forever for a volume that
/// failed to load).
fn view_within(args: &[&str], window: bool, limit: std::time::Duration) -> Output {
    let bin = env!("CARGO_BIN_EXE_morphray");
    let mut command = if window {
        let mut c = Command::new(xvfb_run());
        c.args([
            "-a",
            "-s",
            "-screen 0 1280x1024x24",
            bin,
            "view",
            "--layout",
            "3d",
        ]);
        c
    } else {
        let mut c = Command::new(bin);
        c.env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY");
        c.args(["view", "--layout", "3d"]);
        c
    };
    let mut child = command
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("morphray runs");
    // Drained on threads while the child runs: a long log must not fill the pipe and stall it.
    let drain = |pipe: Option<Box<dyn std::io::Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut pipe) = pipe {
                let _ = pipe.read_to_end(&mut bytes);
            }
            bytes
        })
    };
    let out = drain(child.stdout.take().map(|p| Box::new(p) as _));
    let err = drain(child.stderr.take().map(|p| Box::new(p) as _));
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("waits") {
            break status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            let log = String::from_utf8_lossy(&out.join().unwrap_or_default()).into_owned();
            panic!(
                "`view {}` still ran after {limit:?}\nstdout:\n{log}",
                args.join(" ")
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    };
    Output {
        status,
        stdout: out.join().expect("stdout drained"),
        stderr: err.join().expect("stderr drained"),
    }
}

#[test]
fn an_unattended_viewer_whose_volume_fails_to_load_exits_with_the_error() {
    let dir = temp_dir("unattended");
    let limit = std::time::Duration::from_secs(60);
    let missing = dir.join("missing.nii.gz");
    let cases: [(&str, bool, &[&str]); 3] = [
        (
            missing.to_str().unwrap(),
            false,
            &["--offscreen", "--frames", "3"],
        ),
        (
            dir.to_str().unwrap(),
            false,
            &["--offscreen", "--frames", "3"],
        ),
        // Scripted in a window: --frames would never be reached without a volume.
        (missing.to_str().unwrap(), true, &["--frames", "3"]),
    ];
    for (file, window, flags) in cases {
        let mut args = vec![file, "--size", "320x240"];
        args.extend_from_slice(flags);
        let o = view_within(&args, window, limit);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(
            stderr.contains("morphray: cannot open the volume: "),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn an_interactive_window_shows_a_load_error_and_keeps_running() {
    // No --frames: a person is watching. The window shows the error and stays open until it is
    // closed (here by the script, after a screenshot of the error state).
    let dir = temp_dir("interactive-error");
    let missing = dir.join("missing.nii.gz");
    let shot = dir.join("error.png");
    let script = dir.join("close.txt");
    std::fs::write(
        &script,
        format!("wait 5\nscreenshot {}\nwait 2\nclose\n", shot.display()),
    )
    .unwrap();
    let o = view_within(
        &[
            missing.to_str().unwrap(),
            "--size",
            "480x360",
            "--script",
            script.to_str().unwrap(),
        ],
        true,
        std::time::Duration::from_secs(120),
    );
    assert_ok(&o);
    let log = stdout(&o);
    assert!(log.contains("error shown: Cannot open"), "{log}");
    let png = Png::read(&shot);
    assert_eq!((png.width, png.height), (480, 360));
}

#[test]
fn a_view_that_can_only_show_the_background_says_why_over_the_image() {
    // A float ramp has no tissue peaks, hence no window: the view says so (and the log with
    // it); a window set by hand makes the message go away.
    let dir = temp_dir("empty-view");
    let values: Vec<f32> = (0..24 * 23 * 22).map(|i| (i % 24) as f32).collect();
    let volume = morphray::volume::Volume::from_voxels(
        "ramp",
        [24, 23, 22],
        morphray::volume::Samples::from_f32(&values),
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
        morphray::volume::LinearMap::IDENTITY,
    )
    .unwrap();
    let path = dir.join("ramp.nii");
    write_nifti1(&volume, &path, false).unwrap();
    let script = dir.join("window.txt");
    std::fs::write(&script, "wait 2\nset window wm 0.2 0.8\nwait 2\n").unwrap();
    let o = view_within(
        &[
            path.to_str().unwrap(),
            "--size",
            "480x360",
            "--frames",
            "6",
            "--script",
            script.to_str().unwrap(),
            "--offscreen",
        ],
        false,
        std::time::Duration::from_secs(120),
    );
    assert_ok(&o);
    let log = stdout(&o);
    let said: Vec<&str> = log.lines().filter(|l| l.contains("empty view:")).collect();
    assert_eq!(said.len(), 1, "said once, when it appeared:\n{log}");
    assert!(
        said[0].contains("Nothing to show: no histogram peak was found for csf, gm, wm"),
        "{log}"
    );
}

#[test]
fn a_fifo_named_as_the_script_is_refused_at_once() {
    let dir = temp_dir("script-fifo");
    let fifo = dir.join("script.fifo");
    let made = Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("mkfifo runs");
    assert!(made.success());
    let o = view_within(
        &[
            "--offscreen",
            "--frames",
            "1",
            "--script",
            fifo.to_str().unwrap(),
        ],
        false,
        std::time::Duration::from_secs(30),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("is a FIFO"), "{stderr}");
}

/// A 96x96x80 phantom (1 mm): large enough that a 4 MiB budget degrades its plan.
fn mid_phantom(dir: &Path) -> PathBuf {
    let spec = PhantomSpec {
        dims: [96, 96, 80],
        ..PhantomSpec::cohort_a()
    };
    let phantom = generate(&spec).unwrap();
    let path = dir.join("mid.nii.gz");
    write_nifti1(&phantom.volume, &path, true).unwrap();
    path
}

/// Issue 13: the viewer used to open volumes its own way (no plan, no budget, no bricking).
/// Now it opens them through the library's path, so `--memory-budget` and `--bricked` mean
/// exactly what they mean to `render`: the same layout, the same degradations in the same
/// order (the viewer's log line is what its status bar shows), and a volume on screen.
#[test]
fn the_viewer_bricks_and_degrades_within_the_budget_exactly_as_render_does() {
    let dir = temp_dir("budget");
    let volume = mid_phantom(&dir);
    let shot = dir.join("bricked.png");
    // 4 MiB, plus the two 128 KiB transfer-function tables every DVR plan holds (issue 33).
    let common = ["--bricked", "--memory-budget", "4.25M", "--size", "640x480"];
    let mut args = vec![volume.to_str().unwrap(), "--offscreen", "--frames", "2"];
    args.extend(["--shading", "on", "--screenshot", shot.to_str().unwrap()]);
    args.extend(common);
    let o = view(&args, false);
    assert_ok(&o);
    let log = stdout(&o);
    let plan = log
        .lines()
        .find_map(|l| l.strip_prefix("plan: "))
        .unwrap_or_else(|| panic!("no plan line:\n{log}"));
    assert!(plan.starts_with("bricked ("), "{plan}");
    // What `render` says, note by note, with the same options.
    let png = dir.join("render.png");
    let render = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(["render", volume.to_str().unwrap(), "--shading", "on", "-o"])
        .arg(&png)
        .args(common)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&render.stderr);
    assert!(render.status.success(), "{stderr}");
    let render_degradations: Vec<&str> = stderr
        .lines()
        .filter_map(|l| l.strip_prefix("morphray: note: to fit 4 MiB of GPU memory: "))
        .filter_map(|l| l.split(" (saves ").next())
        .collect();
    assert!(render_degradations.len() >= 2, "render degrades: {stderr}");
    let viewer_degradations: Vec<&str> = plan
        .split_once("degraded: ")
        .map(|(_, list)| list.split("; ").collect())
        .unwrap_or_default();
    assert_eq!(viewer_degradations, render_degradations, "{log}");
    // The bricked volume is on screen.
    let view_rect = layout_rect(&log, "view");
    let lit = lit(&Png::read(&shot), view_rect);
    assert!(lit > 2000, "the bricked volume is shown: {lit} lit pixels");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 13: a bricked volume holds the bricks its scene can see. Switching to MIP (which sees
/// every brick above 0) used to be an error in the viewer ("open it again with this scene");
/// now the viewer opens it again for the scene on screen, keeps the controls, and shows it.
#[test]
fn a_bricked_volume_is_opened_again_when_the_scene_needs_other_bricks() {
    let dir = temp_dir("rebrick");
    let volume = mid_phantom(&dir);
    let script = dir.join("mip.txt");
    let shot = dir.join("mip.png");
    std::fs::write(
        &script,
        format!("wait 1\nmode mip\nwait 2\nscreenshot {}\n", shot.display()),
    )
    .unwrap();
    let o = view(
        &[
            volume.to_str().unwrap(),
            "--bricked",
            "--offscreen",
            "--size",
            "640x480",
            "--frames",
            "4",
            "--script",
            script.to_str().unwrap(),
        ],
        false,
    );
    assert_ok(&o);
    let log = stdout(&o);
    let plans: Vec<&str> = log.lines().filter(|l| l.starts_with("plan: ")).collect();
    assert_eq!(plans.len(), 2, "opened once, then again for MIP:\n{log}");
    assert!(plans.iter().all(|p| p.contains("bricked (")), "{plans:?}");
    assert_ne!(plans[0], plans[1], "MIP keeps other bricks:\n{log}");
    assert!(
        log.contains("opening the volume again for this scene"),
        "{log}"
    );
    assert!(!log.contains("error shown"), "{log}");
    let lit = lit(&Png::read(&shot), layout_rect(&log, "view"));
    assert!(
        lit > 2000,
        "the MIP of the bricked volume is shown: {lit} lit pixels"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Issue 13: an effect switched on in the viewer is planned within the budget as `render`
/// plans it. Before, `shading on` under an 8 MiB budget computed stored gradients and normals
/// beyond it; now the plan degrades the effect the way `render --shading on` does.
#[test]
fn an_effect_switched_on_is_planned_within_the_budget_as_render_plans_it() {
    let dir = temp_dir("replan");
    let volume = mid_phantom(&dir);
    let script = dir.join("shading.txt");
    std::fs::write(&script, "wait 1\nshading on\nwait 2\n").unwrap();
    let common = ["--memory-budget", "8M", "--size", "640x480"];
    // The viewer opens shaded (a still's look): start without it, so `shading on` is a change.
    let mut args = vec![volume.to_str().unwrap(), "--offscreen", "--frames", "3"];
    args.extend(["--shading", "off", "--script", script.to_str().unwrap()]);
    args.extend(common);
    let o = view(&args, false);
    assert_ok(&o);
    let log = stdout(&o);
    let plans: Vec<&str> = log
        .lines()
        .filter_map(|l| l.strip_prefix("plan: "))
        .collect();
    assert_eq!(
        plans.len(),
        2,
        "opened, then planned again for shading:\n{log}"
    );
    assert!(!plans[0].contains("degraded"), "{plans:?}");
    let render = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(["render", volume.to_str().unwrap(), "--shading", "on", "-o"])
        .arg(dir.join("render.png"))
        .args(common)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&render.stderr);
    assert!(render.status.success(), "{stderr}");
    let render_degradations: Vec<&str> = stderr
        .lines()
        .filter_map(|l| l.strip_prefix("morphray: note: to fit 8 MiB of GPU memory: "))
        .filter_map(|l| l.split(" (saves ").next())
        .collect();
    assert!(!render_degradations.is_empty(), "render degrades: {stderr}");
    let viewer_degradations: Vec<&str> = plans[1]
        .split_once("degraded: ")
        .map(|(_, list)| list.split("; ").collect())
        .unwrap_or_default();
    assert_eq!(viewer_degradations, render_degradations, "{log}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_viewer_finds_the_tissues_of_a_scan_with_hot_voxels_by_default_and_not_under_eq_1() {
    // Issue 11: a few hot voxels squeezed every tissue into the darkest bins (no peak, nothing
    // to drag in the histogram); the viewer normalizes like render, robust by default.
    let dir = temp_dir("hot-voxels");
    let phantom = generate(&PhantomSpec::cube(48)).unwrap();
    let mut volume = phantom.volume.clone();
    let mut values: Vec<i16> = (0..volume.samples.len())
        .map(|i| volume.samples.get(i) as i16)
        .collect();
    let max = *values.iter().max().unwrap();
    for k in 0..6 {
        let i = (k * 7919 + values.len() / 2) % values.len();
        values[i] = max * 20;
    }
    volume.samples = morphray::volume::Samples::from_i16(&values);
    let path = dir.join("hot.nii");
    write_nifti1(&volume, &path, false).unwrap();
    let file = path.to_str().unwrap();
    let loaded = |o: &Output| {
        stdout(o)
            .lines()
            .find(|l| l.starts_with("loaded hot.nii"))
            .map(str::to_string)
            .unwrap_or_else(|| panic!("no load line:\n{}", stdout(o)))
    };
    let robust = view(
        &[file, "--size", "320x240", "--frames", "2", "--offscreen"],
        false,
    );
    assert_ok(&robust);
    let line = loaded(&robust);
    assert!(
        !line.contains(" -"),
        "every tissue found by default: {line}"
    );
    let eq1 = view(
        &[
            "--normalize",
            "minmax",
            file,
            "--size",
            "320x240",
            "--frames",
            "2",
            "--offscreen",
        ],
        false,
    );
    assert_ok(&eq1);
    let line = loaded(&eq1);
    assert!(line.ends_with("peaks CSF - GM - WM -"), "{line}");
}
