//! The Python package (tools/python) as CI tests it: the wheel is built with maturin in the dev
//! profile into its own target dir (target/python: `cargo test` holds the lock of target/, so
//! a nested cargo on it would wait forever), installed into a directory under target/python
//! (never into the cached venv itself, which other runs share), and the pytest suite runs on
//! lavapipe from the cached venv of tools/pyenv.sh.
//!
//! Fails, never skips, when the venv is missing: the message says to run tools/setup.sh.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The cached venv of tools/pyenv.sh.
fn pyenv() -> PathBuf {
    if let Some(dir) = std::env::var_os("MORPHRAY_PYENV") {
        return PathBuf::from(dir);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .expect("neither XDG_CACHE_HOME nor HOME is set");
    cache.join("morphray/pyenv")
}

fn run(what: &str, command: &mut Command) -> String {
    let output = command
        .output()
        .unwrap_or_else(|e| panic!("{what} could not start: {e}"));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(output.status.success(), "{what} failed:\n{text}");
    text
}

fn newest_wheel(dir: &Path) -> PathBuf {
    std::fs::read_dir(dir)
        .expect("maturin wrote no wheel directory")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "whl"))
        .max_by_key(|p| p.metadata().and_then(|m| m.modified()).ok())
        .expect("maturin wrote no wheel")
}

#[test]
fn the_python_package_builds_as_an_abi3_wheel_and_its_pytest_suite_passes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let env = pyenv();
    let bin = env.join("bin");
    assert!(
        bin.join("maturin").is_file() && bin.join("pytest").is_file(),
        "the Python test environment {} lacks maturin or pytest: run tools/setup.sh (or \
         tools/pyenv.sh) first",
        env.display()
    );
    let out = root.join("target/python");
    let wheels = out.join("wheels");
    let _ = std::fs::remove_dir_all(&wheels);
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let build = Command::new(bin.join("maturin"))
        .args(["build", "--profile", "dev", "-m"])
        .arg(root.join("tools/python/Cargo.toml"))
        .arg("--target-dir")
        .arg(&out)
        .arg("-o")
        .arg(&wheels)
        .arg("-i")
        .arg(bin.join("python"))
        .env("CARGO", &cargo)
        // No debug info in the test wheel: a faster compile and link, a smaller wheel (the
        // tests need none; a failure is reported by Python, not a debugger).
        .env("CARGO_PROFILE_DEV_DEBUG", "0")
        .output()
        .expect("maturin could not start");
    assert!(
        build.status.success(),
        "maturin build failed:\n{}",
        String::from_utf8_lossy(&build.stderr)
    );
    let wheel = newest_wheel(&wheels);
    let name = wheel.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.contains("abi3"), "not an abi3 wheel: {name}");
    let site = out.join("site");
    let _ = std::fs::remove_dir_all(&site);
    run(
        "pip install of the wheel",
        Command::new(bin.join("python"))
            .args(["-m", "pip", "install", "-q", "--no-deps", "--target"])
            .arg(&site)
            .arg(&wheel),
    );
    let report = run(
        "the pytest suite (tools/python/tests)",
        Command::new(bin.join("python"))
            .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
            .arg(root.join("tools/python/tests"))
            .env("PYTHONPATH", &site)
            // For the tests that check a document Python wrote with the command line.
            .env("MORPHRAY_BIN", env!("CARGO_BIN_EXE_morphray"))
            .current_dir(&out),
    );
    // pytest exits 0 with nothing collected only with options we do not pass; still, say it.
    assert!(report.contains(" passed"), "pytest ran no test:\n{report}");
    println!("{report}");
}
