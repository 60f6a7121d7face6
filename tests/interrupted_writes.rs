//! Interrupted writes leave no temporary file (issue 30 item 6): a writer stopped by SIGTERM
//! or SIGINT removes its `.NAME.PID.N.tmp` files, and one killed with SIGKILL leaves one that the
//! next write to the same folder removes.
//!
//! The test runs itself as the writer (`MORPHRAY_TEST_WRITER=DIR`): it installs the interrupt
//! cleanup as the command line does, starts an atomic write in DIR, says "ready" and waits to be
//! killed. Its own `main` (harness = false), because the cleanup must be installed before any
//! other thread exists.

use morphray::files::unfinished::install_interrupt_cleanup;
use morphray::files::write::{AtomicFile, write_file};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

const WRITER: &str = "MORPHRAY_TEST_WRITER";

fn writer(dir: &Path) -> ! {
    install_interrupt_cleanup();
    let mut file = AtomicFile::create(&dir.join("big.nii")).expect("temporary file");
    file.write_all(&[7u8; 1 << 20]).expect("write");
    file.flush().expect("flush");
    println!("ready");
    std::io::stdout().flush().ok();
    std::thread::sleep(std::time::Duration::from_secs(60));
    std::process::exit(0);
}

fn temps(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') && n.ends_with(".tmp"))
        .collect();
    names.sort();
    names
}

fn start(dir: &Path) -> Child {
    let mut child = Command::new(std::env::current_exe().unwrap())
        .env(WRITER, dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the test binary runs as the writer");
    let mut line = String::new();
    BufReader::new(child.stdout.as_mut().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert_eq!(line.trim(), "ready");
    child
}

fn fresh(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("morphray-interrupt-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn signalled_writer_removes_its_temporary_file(signal: i32, name: &str) {
    let dir = fresh(name);
    let mut child = start(&dir);
    assert_eq!(temps(&dir).len(), 1, "the write is under way");
    // SAFETY: sending a signal to the child this test started.
    assert_eq!(unsafe { libc::kill(child.id() as i32, signal) }, 0);
    let status = child.wait().unwrap();
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(
        status.signal(),
        Some(signal),
        "ends by the signal: {status:?}"
    );
    let mut stderr = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    assert!(
        stderr.contains(&format!(
            "interrupted ({name}); removed 1 unfinished output file"
        )),
        "{stderr}"
    );
    assert_eq!(temps(&dir), Vec::<String>::new());
    assert!(!dir.join("big.nii").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

fn killed_writer_is_cleaned_by_the_next_write() {
    let dir = fresh("kill9");
    let mut child = start(&dir);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let left = temps(&dir);
    assert_eq!(left.len(), 1, "kill -9 cannot be caught: {left:?}");
    assert!(left[0].starts_with(".big.nii.") && left[0].contains(&child.id().to_string()));
    // An unrelated hidden file and a live process's temporary file stay.
    std::fs::write(dir.join(".keep.tmp"), b"x").unwrap();
    let live = format!(".other.png.{}.0.tmp", std::process::id());
    std::fs::write(dir.join(&live), b"x").unwrap();
    write_file(&dir.join("next.json"), b"{}").unwrap();
    assert_eq!(temps(&dir), vec![".keep.tmp".to_string(), live]);
    assert!(dir.join("next.json").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

fn main() {
    if let Some(dir) = std::env::var_os(WRITER) {
        writer(Path::new(&dir));
    }
    let tests: [(&str, fn()); 3] = [
        ("sigterm_removes_the_temporary_file", || {
            signalled_writer_removes_its_temporary_file(libc::SIGTERM, "SIGTERM")
        }),
        ("sigint_removes_the_temporary_file", || {
            signalled_writer_removes_its_temporary_file(libc::SIGINT, "SIGINT")
        }),
        (
            "kill_9_leftover_is_removed_by_the_next_write",
            killed_writer_is_cleaned_by_the_next_write,
        ),
    ];
    let filter: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    for (name, test) in tests {
        if filter.iter().all(|f| name.contains(f.as_str())) {
            test();
            println!("test {name} ... ok");
        }
    }
}
