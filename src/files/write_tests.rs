//! Unit tests of the atomic writer and the output checks (kept apart from write.rs so that file
//! stays about the writer).

use super::*;

/// A fresh directory under the system temporary directory, removed by the caller's `cleanup`.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-files-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Names in `dir` (to see that no temporary file was left behind).
fn names(dir: &Path) -> Vec<String> {
    let mut all: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    all.sort();
    all
}

#[test]
fn a_producer_failing_halfway_leaves_the_old_file_intact_and_no_temporary() {
    let dir = scratch("halfway");
    let target = dir.join("out.png");
    std::fs::write(&target, b"the old, complete image").unwrap();
    // A producer that writes part of the new file, then fails (as an encoder on a full disk).
    let produce = || -> Result<(), OutputError> {
        let mut file = AtomicFile::create(&target)?;
        file.write_all(b"half of a new")
            .map_err(|e| file.error(e))?;
        Err(file.error(std::io::Error::from_raw_os_error(28)))
    };
    let e = produce().unwrap_err();
    assert!(
        e.to_string().contains("no space left on device"),
        "message: {e}"
    );
    assert_eq!(std::fs::read(&target).unwrap(), b"the old, complete image");
    assert_eq!(names(&dir), ["out.png"]);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn commit_replaces_with_the_complete_file_and_keeps_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("commit");
    let target = dir.join("r.json");
    std::fs::write(&target, b"old").unwrap();
    std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o640)).unwrap();
    write_file(&target, b"{\"new\": true}").unwrap();
    assert_eq!(std::fs::read(&target).unwrap(), b"{\"new\": true}");
    let mode = std::fs::metadata(&target).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o640);
    assert_eq!(names(&dir), ["r.json"]);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn commit_new_refuses_an_existing_file_and_leaves_it() {
    let dir = scratch("new");
    let target = dir.join("scan.nii");
    write_new_file(&target, b"first").unwrap();
    let e = write_new_file(&target, b"second").unwrap_err();
    assert!(matches!(e.problem, OutputProblem::Exists), "{e}");
    assert!(e.to_string().contains("--force"));
    assert_eq!(std::fs::read(&target).unwrap(), b"first");
    assert_eq!(names(&dir), ["scan.nii"]);
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_symbolic_link_is_followed_and_stays_a_link() {
    let dir = scratch("link");
    let real = dir.join("real.png");
    let link = dir.join("link.png");
    std::fs::write(&real, b"old").unwrap();
    std::os::unix::fs::symlink(&real, &link).unwrap();
    write_file(&link, b"new").unwrap();
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read(&real).unwrap(), b"new");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn devices_and_directories_are_never_written_or_replaced() {
    let dir = scratch("special");
    let e = write_file(Path::new("/dev/full"), b"x").unwrap_err();
    assert!(matches!(e.problem, OutputProblem::NotRegularFile), "{e}");
    let e = write_file(&dir, b"x").unwrap_err();
    assert!(matches!(e.problem, OutputProblem::IsDirectory(_)), "{e}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn check_output_names_the_extension_to_use() {
    let dir = scratch("ext");
    let e = check_output(&dir.join("out.jpg"), OutputKind::Png, &[], false).unwrap_err();
    let text = e.to_string();
    assert!(text.contains(".png") && text.contains("out.jpg"), "{text}");
    assert!(check_output(&dir.join("OUT.PNG"), OutputKind::Png, &[], false).is_ok());
    assert!(check_output(&dir.join("a.NII.GZ"), OutputKind::Nifti, &[], false).is_ok());
    assert!(check_output(&dir.join("a.nii"), OutputKind::Nifti, &[], false).is_ok());
    assert!(check_output(&dir.join("a.gz"), OutputKind::Nifti, &[], false).is_err());
    assert!(check_output(&dir.join(".png"), OutputKind::Png, &[], false).is_err());
    assert!(check_output(&dir.join("r.json"), OutputKind::Json, &[], false).is_ok());
    assert!(check_output(&dir.join("p.svg"), OutputKind::Svg, &[], false).is_ok());
    assert_eq!(
        with_extension(Path::new("d/scan.nii.gz"), ".png"),
        Path::new("d/scan.png")
    );
    // The probe left nothing behind.
    assert!(names(&dir).is_empty());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn check_output_refuses_inputs_links_to_them_and_pair_partners() {
    let dir = scratch("input");
    let scan = dir.join("scan.nii.gz");
    std::fs::write(&scan, b"mri").unwrap();
    std::fs::create_dir_all(dir.join("x")).unwrap();
    let dotted = dir.join("x").join("..").join("scan.nii.gz");
    let linked = dir.join("linked.nii.gz");
    std::fs::hard_link(&scan, &linked).unwrap();
    for target in [&scan, &dotted, &linked] {
        let e = check_output(target, OutputKind::Nifti, &[&scan], true).unwrap_err();
        assert!(matches!(e.problem, OutputProblem::IsInput(_)), "{e}");
    }
    let hdr = dir.join("pair.HDR");
    let img = dir.join("pair.img.gz");
    std::fs::write(&hdr, b"h").unwrap();
    std::fs::write(&img, b"i").unwrap();
    let e = check_output(&img, OutputKind::Png, &[&hdr], false).unwrap_err();
    assert!(matches!(e.problem, OutputProblem::IsInput(_)), "{e}");
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn check_output_refuses_existing_nifti_unless_forced_but_replaces_reports() {
    let dir = scratch("exists");
    let nii = dir.join("a.nii");
    let json = dir.join("a.json");
    std::fs::write(&nii, b"scan").unwrap();
    std::fs::write(&json, b"{}").unwrap();
    let e = check_output(&nii, OutputKind::Nifti, &[], false).unwrap_err();
    assert!(matches!(e.problem, OutputProblem::Exists), "{e}");
    assert!(check_output(&nii, OutputKind::Nifti, &[], true).is_ok());
    assert!(check_output(&json, OutputKind::Json, &[], false).is_ok());
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn check_output_refuses_missing_unwritable_and_special_places() {
    let dir = scratch("places");
    let missing = dir.join("nope").join("out.png");
    let e = check_output(&missing, OutputKind::Png, &[], false).unwrap_err();
    assert!(matches!(e.problem, OutputProblem::NoDirectory(_)), "{e}");
    let e = check_output(&dir, OutputKind::Png, &[], false).unwrap_err();
    assert!(matches!(e.problem, OutputProblem::IsDirectory(_)), "{e}");
    // /proc takes no new file even for root, which read-only permission bits would not stop.
    let e = check_output(Path::new("/proc/out.png"), OutputKind::Png, &[], false).unwrap_err();
    assert!(
        matches!(e.problem, OutputProblem::DirectoryNotWritable { .. }),
        "{e}"
    );
    let e = check_output(Path::new("/dev/full"), OutputKind::Png, &[], false).unwrap_err();
    assert!(matches!(e.problem, OutputProblem::NotRegularFile), "{e}");
    let fifo = dir.join("fifo.png");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    let e = check_output(&fifo, OutputKind::Png, &[], false).unwrap_err();
    assert!(matches!(e.problem, OutputProblem::NotRegularFile), "{e}");
    let file = dir.join("file");
    std::fs::write(&file, b"").unwrap();
    let e = check_output(&file.join("out.png"), OutputKind::Png, &[], false).unwrap_err();
    assert!(
        matches!(e.problem, OutputProblem::ParentNotDirectory(_)),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_full_disk_is_described_as_such() {
    let e = OutputError::io(Path::new("o.png"), std::io::Error::from_raw_os_error(28));
    assert!(
        e.to_string()
            .starts_with("cannot write o.png: no space left on device")
    );
    let io = e.into_io_error();
    assert_eq!(io.kind(), ErrorKind::StorageFull);
    assert!(io.to_string().contains("no space left on device"));
}
