//! Issue 12's oracle: the quick bad-input probe (`tools/reliability/probe.py --quick`) run on the
//! binary cargo built. It fails when any bad input makes morphray panic, hang, get killed (a
//! signal, an allocation abort), hold more than 1 GiB of memory (an unbounded read that the
//! probe's 4 GiB limit stopped short of the OOM killer) or modify a file it must not touch (its
//! own input, an existing scan, an existing PNG after a failed render, /dev/full); the probe's
//! table and its list of runs that were not clean are printed on failure.
//!
//! Decisions: the probe is the single description of the bad inputs (RELIABILITY.md's numbers
//! come from its full run), so this test only runs it and reads its exit status rather than
//! repeating the cases in Rust. It needs `python3` (standard library only) and a Vulkan device;
//! the probe exits 3 when it finds none, and this test then fails (GPU tests never skip).

use std::path::Path;
use std::process::Command;

#[test]
fn quick_probe_finds_no_panic_hang_kill_memory_blowup_or_destroyed_file() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let output = Command::new("python3")
        .arg(root.join("tools/reliability/probe.py"))
        .arg("--quick")
        .arg("--binary")
        .arg(env!("CARGO_BIN_EXE_morphray"))
        .current_dir(root)
        .output()
        .expect("python3 runs (the probe needs Python 3 and its standard library only)");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_ne!(
        output.status.code(),
        Some(3),
        "the probe could not run the binary or found no usable Vulkan device:\n{stderr}"
    );
    assert!(
        output.status.success(),
        "bad input made morphray panic, hang, get killed, take over 1 GiB or destroy a file \
         (exit {:?}):\n{stdout}\n{stderr}",
        output.status.code()
    );
    // The probe really ran: its table has a row per class and a total.
    assert!(stdout.contains("| **all** |"), "no table in:\n{stdout}");
}
