//! `render -h` is short and grouped, `--help` is complete, and help defaults match behaviour
//! (issue 16 item 5).

use std::process::Command;

fn help(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .output()
        .expect("the morphray binary runs");
    assert!(o.status.success());
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn render_short_help_is_grouped_and_the_long_help_has_everything() {
    let short = help(&["render", "-h"]);
    let lines = short.lines().count();
    assert!(lines <= 100, "render -h is {lines} lines");
    let position = |text: &str, needle: &str| {
        text.find(needle)
            .unwrap_or_else(|| panic!("`{needle}` missing from:\n{text}"))
    };
    // Headings in the order a user needs them: what to write, what to show, which device.
    let (output, scene, device) = (
        position(&short, "\nOutput:"),
        position(&short, "\nScene:"),
        position(&short, "\nDevice and profiling:"),
    );
    assert!(output < scene && scene < device, "{short}");
    assert!(position(&short, "--crop") > scene && position(&short, "--movie") < scene);
    // Profiling options only in the long help.
    for option in [
        "--wg",
        "--subgroup",
        "--pipeline-cache",
        "--trace",
        "--bricked",
    ] {
        assert!(!short.contains(option), "{option} in render -h");
    }
    let long = help(&["render", "--help"]);
    for option in [
        "--wg",
        "--subgroup",
        "--pipeline-cache",
        "--trace",
        "--crop",
        "--movie",
    ] {
        assert!(long.contains(option), "{option} missing from render --help");
    }
    // The long help keeps the explanations the short one leaves out.
    assert!(long.contains("VK_EXT_memory_budget"));
}

#[test]
fn the_size_default_in_help_names_each_command_s_default() {
    // view opens a 1280x800 window (src/cli/view.rs); the help used to name only render's and
    // bench's defaults.
    let view = help(&["view", "--help"]);
    assert!(view.contains("1280x800"), "{view}");
    let render = help(&["render", "--help"]);
    assert!(render.contains("1024x1024 for render"), "{render}");
}
