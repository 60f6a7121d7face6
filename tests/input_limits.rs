//! Inputs that must neither exhaust memory nor hang (issue 12): gzip data that inflates past
//! what its header declares, paths that are not regular files, the `.img` of a pair given
//! first, and the messages for damaged headers. Each test fails on the loader before the fix
//! (noted per test). Files are tiny and built in memory; the one "bomb" is 1 MB compressed.

use morphray::files::read::ReadError;
use morphray::volume::nifti::{
    ByteOrder, LoadOptions, NiftiError, RawHeader, Version, inflate_if_gzip, load_path, parse,
    parse_pair,
};
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut c = libdeflater::Compressor::new(libdeflater::CompressionLvl::default());
    let mut out = vec![0; c.gzip_compress_bound(bytes.len())];
    let n = c.gzip_compress(bytes, &mut out).unwrap();
    out.truncate(n);
    out
}

/// A NIfTI-1 uint8 header for `dims` voxels, with the given magic and vox_offset.
fn header(dims: [i64; 3], magic: &[u8; 4], vox_offset: f64) -> RawHeader {
    RawHeader {
        dim: [3, dims[0], dims[1], dims[2], 1, 1, 1, 1],
        magic: *magic,
        vox_offset,
        ..RawHeader::default()
    }
}

/// A single-file NIfTI-1 of 96 uint8 voxels (4x4x6): 352 + 96 bytes.
fn small_nii() -> Vec<u8> {
    let mut bytes =
        header([4, 4, 6], b"n+1\0", 352.0).encode(Version::Nifti1, ByteOrder::LittleEndian);
    bytes.extend((0..96u8).map(|v| v * 2));
    bytes
}

/// A unique empty directory.
fn temp_dir(tag: &str) -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "morphray-limits-{tag}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Peak resident memory of this process so far, bytes (Linux reports KiB).
fn peak_rss() -> u64 {
    // SAFETY: getrusage fills the struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    assert_eq!(unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) }, 0);
    u64::try_from(usage.ru_maxrss).unwrap() * 1024
}

/// Runs `f` on a thread and fails the test if it has not returned within `limit` (a hang would
/// otherwise hang the test run).
fn within<T: Send + 'static>(limit: Duration, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(limit)
        .unwrap_or_else(|_| panic!("did not return within {limit:?}"))
}

fn mkfifo(path: &Path) {
    let status = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .unwrap();
    assert!(status.success());
}

// ---------------------------------------------------------------------------------------------
// Inflation bounded by the header

/// Before: inflation was bounded by 1032x the compressed size only, so this 1 MB stream (a
/// header declaring 96 bytes of voxels, then 128 members of 8 MiB of zeros) inflated to 1 GiB
/// and loaded. Now it stops at the declared size plus the slack, with a typed error, quickly and
/// without the gigabyte.
#[test]
fn gzip_inflating_past_the_declared_size_fails_fast_and_bounded() {
    let zeros = gzip(&vec![0u8; 8 << 20]);
    let mut bomb = gzip(&small_nii());
    for _ in 0..128 {
        bomb.extend_from_slice(&zeros);
    }
    assert!(bomb.len() < 2 << 20, "{} bytes", bomb.len());
    let start = Instant::now();
    let e = inflate_if_gzip(bomb.clone()).unwrap_err();
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "{:?}",
        start.elapsed()
    );
    match &e {
        NiftiError::GzipTooLarge {
            declared, limit, ..
        } => {
            assert_eq!(*declared, 352 + 96);
            assert!(*limit < 1 << 20, "limit {limit}");
        }
        other => panic!("expected GzipTooLarge, got {other}"),
    }
    let text = e.to_string();
    assert!(
        text.contains("inflates past") && text.contains("448 bytes its header declares"),
        "{text}"
    );
    // parse (which inflates itself) gives the same error.
    let e = parse(bomb, "bomb.nii.gz", &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, NiftiError::GzipTooLarge { .. }), "{e}");
    // Never anywhere near the gigabyte (the whole test binary's peak, so a loose bound).
    assert!(peak_rss() < 512 << 20, "peak RSS {} MiB", peak_rss() >> 20);
}

/// The common bomb: one member (header, voxels, then 16 MiB of zeros). Before: loaded, with
/// 16 MiB inflated and kept.
#[test]
fn one_member_with_trailing_megabytes_is_refused() {
    let mut file = small_nii();
    file.extend(vec![0u8; 16 << 20]);
    let e = inflate_if_gzip(gzip(&file)).unwrap_err();
    assert!(
        matches!(e, NiftiError::GzipTooLarge { declared: 448, .. }),
        "{e}"
    );
}

/// Trailing bytes within the documented slack (64 KiB), and several members, still load.
#[test]
fn small_trailing_data_and_members_within_the_declared_size_load() {
    let mut file = small_nii();
    file.extend(vec![0u8; 1000]);
    let half = file.len() / 2;
    let stream = [gzip(&file[..half]), gzip(&file[half..])].concat();
    let (inflated, members) = inflate_if_gzip(stream.clone()).unwrap();
    assert_eq!((inflated, members), (file, 2));
    let l = parse(stream, "ok.nii.gz", &LoadOptions::default()).unwrap();
    assert_eq!(l.volume.dims, [4, 4, 6]);
    assert_eq!(l.header.gzip_members, 2);
}

/// A header that is not valid fails before anything beyond its first bytes is inflated: the
/// header's own error, not an allocation or a gzip error.
#[test]
fn a_bad_header_is_reported_before_the_voxels_are_inflated() {
    let mut h = header([4, 4, 6], b"n+1\0", 352.0);
    h.datatype = 1234;
    let mut file = h.encode(Version::Nifti1, ByteOrder::LittleEndian);
    file.extend(vec![0u8; 4 << 20]);
    let e = inflate_if_gzip(gzip(&file)).unwrap_err();
    assert!(
        matches!(e, NiftiError::UnknownDatatype { code: 1234 }),
        "{e}"
    );
}

/// The `.img` of a pair is bounded by what its `.hdr` declares. Before: bounded by its
/// compressed size only.
#[test]
fn a_pair_image_is_bounded_by_its_header() {
    let hdr = header([4, 4, 6], b"ni1\0", 0.0).encode(Version::Nifti1, ByteOrder::LittleEndian);
    let mut img = vec![7u8; 96];
    let ok = parse_pair(&hdr, gzip(&img), "p.hdr", &LoadOptions::default()).unwrap();
    assert_eq!(ok.volume.dims, [4, 4, 6]);
    img.extend(vec![0u8; 4 << 20]);
    let e = parse_pair(&hdr, gzip(&img), "p.hdr", &LoadOptions::default()).unwrap_err();
    match e {
        NiftiError::GzipTooLarge { declared, what, .. } => {
            assert_eq!(declared, 96);
            assert!(what.contains(".hdr"), "{what}");
        }
        other => panic!("expected GzipTooLarge, got {other}"),
    }
}

// ---------------------------------------------------------------------------------------------
// Paths that are not regular files

/// Before: `std::fs::read` on a FIFO blocked in open() forever (no writer).
#[test]
fn a_fifo_as_input_is_refused_at_once() {
    let dir = temp_dir("fifo");
    let fifo = dir.join("scan.nii");
    mkfifo(&fifo);
    let path = fifo.clone();
    let e = within(Duration::from_secs(1), move || {
        load_path(&path, &LoadOptions::default()).unwrap_err()
    });
    assert!(
        matches!(&e, NiftiError::File(ReadError::NotRegular { kind, .. }) if kind.contains("FIFO")),
        "{e}"
    );
    assert!(e.to_string().contains("scan.nii"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Before: `/dev/zero` was read until memory ran out (OOM-killed); a directory gave an OS error.
#[test]
fn devices_and_directories_as_input_are_refused() {
    let dir = temp_dir("dev");
    let link = dir.join("zero.nii.gz");
    std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
    for (path, kind) in [
        (PathBuf::from("/dev/zero"), "character device"),
        (link, "character device"),
        (dir.clone(), "directory"),
    ] {
        let shown = path.display().to_string();
        let e = within(Duration::from_secs(1), move || {
            load_path(&path, &LoadOptions::default()).unwrap_err()
        });
        assert!(
            matches!(&e, NiftiError::File(ReadError::NotRegular { kind: k, .. }) if k.contains(kind)),
            "{shown}: {e}"
        );
        assert!(e.to_string().contains(&shown), "{e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The command line on a FIFO and on /dev/zero: one `morphray:` line, exit 1, promptly.
#[test]
fn the_cli_refuses_a_fifo_and_dev_zero_with_one_line() {
    let dir = temp_dir("cli");
    let fifo = dir.join("pipe.nii");
    mkfifo(&fifo);
    for path in [fifo.as_path(), Path::new("/dev/zero")] {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_morphray"))
            .arg("info")
            .arg(path)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        let status = loop {
            if let Some(status) = child.try_wait().unwrap() {
                break status;
            }
            if start.elapsed() > Duration::from_secs(20) {
                child.kill().unwrap();
                panic!("morphray info {} hung", path.display());
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert_eq!(status.code(), Some(1), "{err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(
            err.starts_with("morphray: ") && err.contains("not a regular file"),
            "{err}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------------------------
// Pairs given by their image, and messages

/// Before: the command line read `x.img` as a header ("sizeof_hdr reads 0"). Now the image
/// finds its `.hdr` in every spelling: `.img`, `.img.gz`, `.IMG`.
#[test]
fn the_image_of_a_pair_finds_its_header() {
    let dir = temp_dir("pair");
    let hdr = header([4, 4, 6], b"ni1\0", 0.0).encode(Version::Nifti1, ByteOrder::LittleEndian);
    let img: Vec<u8> = (0..96u8).collect();
    std::fs::write(dir.join("a.hdr"), &hdr).unwrap();
    std::fs::write(dir.join("a.img"), &img).unwrap();
    std::fs::write(dir.join("b.hdr"), &hdr).unwrap();
    std::fs::write(dir.join("b.img.gz"), gzip(&img)).unwrap();
    std::fs::write(dir.join("C.HDR"), &hdr).unwrap();
    std::fs::write(dir.join("C.IMG"), &img).unwrap();
    for name in ["a.img", "b.img.gz", "C.IMG"] {
        let source = morphray::cli::source::load(&[dir.join(name)], 0, true)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(source.volume.dims, [4, 4, 6], "{name}");
        assert_eq!(source.volume.samples.get(95), 95.0, "{name}");
        assert_eq!(source.label, name);
        let header = source.header.unwrap();
        assert_eq!(header.gzip, name.ends_with(".gz"), "{name}");
        // The hash is of the file named, as read.
        assert!(source.sha256.is_some());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Before: a damaged magic in a 348-byte single file was read as ANALYZE and reported as
/// "no .img file was found". Now the message is about the magic, and names NIfTI-2's.
#[test]
fn a_bad_magic_without_an_image_is_reported_as_a_bad_magic() {
    let dir = temp_dir("magic");
    for (magic, hint) in [(b"n+2\0", true), (b"x!1\0", false)] {
        let mut bytes =
            header([4, 4, 6], magic, 352.0).encode(Version::Nifti1, ByteOrder::LittleEndian);
        bytes.extend(vec![1u8; 96]);
        let path = dir.join("scan.nii");
        std::fs::write(&path, &bytes).unwrap();
        let source = morphray::volume::source::VolumeSource::File(path.clone());
        let e = morphray::volume::source::read(&source, &Default::default())
            .expect_err("a damaged magic must not load");
        let text = e.to_string();
        assert!(text.contains("magic") && text.contains("damaged"), "{text}");
        assert!(!text.contains("no .img file was found"), "{text}");
        assert_eq!(text.contains("NIfTI-2's magic"), hint, "{text}");
        let e = load_path(&path, &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, NiftiError::BadNifti1Magic { .. }), "{e}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Before: "... starting at byte 18446744073709551615" (a saturated usize).
#[test]
fn a_vox_offset_beyond_any_file_says_so() {
    let mut bytes =
        header([4, 4, 6], b"n+1\0", 1e20).encode(Version::Nifti1, ByteOrder::LittleEndian);
    bytes.extend(vec![1u8; 96]);
    let e = parse(bytes.clone(), "x.nii", &LoadOptions::default()).unwrap_err();
    assert!(
        matches!(e, NiftiError::VoxOffsetBeyondAnyFile { .. }),
        "{e}"
    );
    let text = e.to_string();
    assert!(
        text.contains("vox_offset 1e20 is beyond any file"),
        "{text}"
    );
    assert!(!text.contains("18446744073709551615"), "{text}");
    // Also when compressed (and longer than the first pass inflates): the header's error comes
    // first, before the rest is inflated.
    bytes.extend(vec![1u8; 4096]);
    let e = inflate_if_gzip(gzip(&bytes)).unwrap_err();
    assert!(
        matches!(e, NiftiError::VoxOffsetBeyondAnyFile { .. }),
        "{e}"
    );
}

/// Before: the extension flag with no room for an extension passed silently.
#[test]
fn an_extension_flag_without_room_is_a_warning() {
    let mut h = header([4, 4, 6], b"n+1\0", 352.0);
    h.extender = [1, 0, 0, 0];
    let mut bytes = h.encode(Version::Nifti1, ByteOrder::LittleEndian);
    bytes.extend(vec![1u8; 96]);
    let l = parse(bytes, "x.nii", &LoadOptions::default()).unwrap();
    assert!(l.header.extensions.is_empty());
    assert!(
        l.volume
            .warnings
            .iter()
            .any(|w| w.contains("no room for an extension")),
        "{:?}",
        l.volume.warnings
    );
    // A pair whose .hdr ends at the extender: the same warning.
    let mut h = header([4, 4, 6], b"ni1\0", 0.0);
    h.extender = [1, 0, 0, 0];
    let hdr = h.encode(Version::Nifti1, ByteOrder::LittleEndian);
    let l = parse_pair(&hdr, vec![1u8; 96], "x.hdr", &LoadOptions::default()).unwrap();
    assert!(
        l.volume
            .warnings
            .iter()
            .any(|w| w.contains("no room for an extension")),
        "{:?}",
        l.volume.warnings
    );
}
