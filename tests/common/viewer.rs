//! `morphray view --offscreen` as the viewer tests run it: a script, validation required, the
//! log returned. Fails (never skips) without a Vulkan device or with a validation error.

use std::path::Path;
use std::process::{Command, Output};

/// Runs `morphray view --offscreen VOLUME --layout 3d --size SIZE --frames 2 --script` with
/// `script` (written into `dir`) and returns the log (stdout).
pub fn offscreen(volume: &Path, dir: &Path, size: &str, script: &str) -> String {
    let script_path = dir.join("script.txt");
    std::fs::write(&script_path, format!("{script}\n")).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .args(["view", "--layout", "3d", "--offscreen"])
        .arg(volume)
        .args(["--size", size, "--frames", "2", "--script"])
        .arg(&script_path)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("morphray runs");
    checked_log(&o)
}

/// The log (stdout) of a finished `morphray view` run, after asserting that it found a Vulkan
/// device (else it names what to install), exited 0 and reported no validation error.
pub fn checked_log(o: &Output) -> String {
    let log = String::from_utf8_lossy(&o.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !stderr.contains("no Vulkan") && !stderr.contains("found no device"),
        "this test needs a Vulkan device (Debian: apt-get install mesa-vulkan-drivers \
         libvulkan1 vulkan-validationlayers): {stderr}"
    );
    assert!(
        o.status.success() && log.contains("validation layer: 0 error(s)"),
        "exit {:?}\nstdout:\n{log}\nstderr:\n{stderr}",
        o.status.code()
    );
    log
}

/// `morphray view` as a command, offscreen (no display) or, with `window`, in a window under
/// Xvfb (fails with what to install when xvfb-run is missing); validation required.
pub fn view_command(window: bool) -> Command {
    let bin = env!("CARGO_BIN_EXE_morphray");
    let mut command = if window {
        let found = Command::new("sh")
            .args(["-c", "command -v xvfb-run"])
            .output()
            .is_ok_and(|o| o.status.success());
        assert!(
            found,
            "this test needs xvfb-run (Debian: apt-get install xvfb xauth)"
        );
        let mut c = Command::new("xvfb-run");
        c.args(["-a", "-s", "-screen 0 1280x1024x24", bin, "view"]);
        c
    } else {
        let mut c = Command::new(bin);
        c.env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY");
        c.args(["view", "--offscreen"]);
        c
    };
    command.env("MORPHRAY_VALIDATION", "required");
    command
}
