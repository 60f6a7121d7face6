//! DICOM input (issue 14): series written by the tests' own writer (tests/common/dicom.rs) are
//! read through the library's source registry and compared voxel by voxel, and position by
//! position, with what the writer put in them.

#[path = "common/dicom.rs"]
mod writer;

use morphray::volume::source::dicom::{self, SeriesChoice};
use morphray::volume::source::{self as source, ReadOptions, VolumeSource};
use morphray::volume::{AffineSource, SampleKind, Volume};
use std::path::{Path, PathBuf};
use writer::Spec;

/// A fresh folder for one test.
fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-dicom-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read(path: &Path, series: Option<SeriesChoice>) -> Result<Volume, String> {
    let options = ReadOptions {
        series,
        ..ReadOptions::default()
    };
    source::read(&VolumeSource::File(path.to_path_buf()), &options)
        .map(|s| s.volume)
        .map_err(|e| e.to_string())
}

/// The affine applied to (i, j, k).
fn world(v: &Volume, i: f64, j: f64, k: f64) -> [f64; 3] {
    let a = &v.orientation.affine;
    [0, 1, 2].map(|r| a[r][0] * i + a[r][1] * j + a[r][2] * k + a[r][3])
}

/// Every voxel's position (the volume's corners and a few inside) and physical value match the
/// spec; `k_of` maps the volume's slice index to the spec's.
fn assert_matches(v: &Volume, spec: &Spec, physical: impl Fn(usize, usize, usize) -> f64) {
    assert_eq!(
        v.dims,
        [spec.cols as usize, spec.rows as usize, spec.slices]
    );
    assert_eq!(v.orientation.source, AffineSource::Dicom);
    let last = [v.dims[0] - 1, v.dims[1] - 1, v.dims[2] - 1].map(|d| d as f64);
    for (i, j, k) in [
        (0.0, 0.0, 0.0),
        (last[0], 0.0, 0.0),
        (0.0, last[1], 0.0),
        (0.0, 0.0, last[2]),
        (last[0], last[1], last[2]),
        (3.0, 5.0, 7.0),
    ] {
        let got = world(v, i, j, k);
        let want = spec.ras(i, j, k);
        for a in 0..3 {
            assert!(
                (got[a] - want[a]).abs() < 1e-3,
                "voxel ({i},{j},{k}): {got:?} != {want:?}"
            );
        }
    }
    let (nx, ny) = (v.dims[0], v.dims[1]);
    for k in 0..v.dims[2] {
        for j in 0..ny {
            for i in 0..nx {
                let stored = v.samples.get(i + nx * (j + ny * k));
                let got = v.to_physical.apply(stored);
                let want = physical(i, j, k);
                assert!(
                    (got - want).abs() < 1e-3,
                    "voxel ({i},{j},{k}): {got} != {want}"
                );
            }
        }
    }
}

fn plain(spec: &Spec) -> impl Fn(usize, usize, usize) -> f64 + '_ {
    move |i, j, k| spec.value(i, j, k) as f64
}

#[test]
fn an_axial_series_has_its_positions_and_values() {
    let dir = folder("axial");
    let spec = Spec::axial("1.2.826.0.1.3680043.2.1125.1.1");
    writer::write_series(&dir, &spec);
    let v = read(&dir, None).unwrap();
    assert_matches(&v, &spec, plain(&spec));
    assert_eq!(v.samples.kind(), SampleKind::U16);
    assert_eq!(v.spacing_mm, [0.9, 1.1, 2.5]);
    assert!(v.warnings.is_empty(), "{:?}", v.warnings);
    assert!(v.name.contains("series 3 \"T1 test\""), "{}", v.name);
}

#[test]
fn oblique_sagittal_and_coronal_stacks_with_shuffled_names_and_bogus_instance_numbers() {
    for (name, spec) in [
        ("oblique", Spec::oblique("1.2.826.0.1.3680043.2.1125.1.2")),
        ("sagittal", Spec::sagittal("1.2.826.0.1.3680043.2.1125.1.3")),
        ("coronal", Spec::coronal("1.2.826.0.1.3680043.2.1125.1.4")),
    ] {
        let dir = folder(name);
        writer::write_series(&dir, &spec);
        let v = read(&dir, None).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_matches(&v, &spec, plain(&spec));
    }
}

#[test]
fn encodings_decode_to_the_same_values() {
    for (name, encoding, signed) in [
        ("implicit", writer::IMPLICIT_LE, true),
        ("big-endian", writer::EXPLICIT_BE, false),
        ("deflated", writer::DEFLATED, false),
        ("rle", writer::RLE, true),
        ("jpeg-lossless", writer::JPEG_LOSSLESS, false),
    ] {
        let dir = folder(name);
        let spec = Spec {
            encoding,
            signed,
            ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.5")
        };
        writer::write_series(&dir, &spec);
        let v = read(&dir, None).unwrap_or_else(|e| panic!("{name}: {e}"));
        let kind = if signed {
            SampleKind::I16
        } else {
            SampleKind::U16
        };
        assert_eq!(v.samples.kind(), kind, "{name}");
        assert_matches(&v, &spec, plain(&spec));
    }
}

#[test]
fn jpeg_2000_is_refused_naming_the_transfer_syntax_and_dcm2niix() {
    let dir = folder("j2k");
    let spec = Spec {
        encoding: writer::JPEG_2000,
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.6")
    };
    writer::write_series(&dir, &spec);
    let e = read(&dir, None).unwrap_err();
    assert!(e.contains("JPEG 2000") && e.contains("dcm2niix"), "{e}");
    assert!(!e.contains('\n'), "{e}");
}

#[test]
fn one_rescale_is_the_intensity_map_and_per_slice_rescale_becomes_float() {
    let dir = folder("rescale");
    let spec = Spec {
        rescale: |_| (2.5, -100.0),
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.7")
    };
    writer::write_series(&dir, &spec);
    let v = read(&dir, None).unwrap();
    assert_eq!(v.samples.kind(), SampleKind::U16);
    assert_eq!(
        (v.to_physical.slope, v.to_physical.intercept),
        (2.5, -100.0)
    );
    assert_matches(&v, &spec, |i, j, k| {
        spec.value(i, j, k) as f64 * 2.5 - 100.0
    });

    let dir = folder("rescale-per-slice");
    let spec = Spec {
        rescale: |k| (1.0 + k as f64 * 0.25, k as f64 * 10.0),
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.8")
    };
    writer::write_series(&dir, &spec);
    let v = read(&dir, None).unwrap();
    assert_eq!(v.samples.kind(), SampleKind::F32);
    assert!(v.warnings.iter().any(|w| w.contains("vary between slices")));
    assert_matches(&v, &spec, |i, j, k| {
        spec.value(i, j, k) as f64 * (1.0 + k as f64 * 0.25) + k as f64 * 10.0
    });
}

#[test]
fn monochrome1_is_inverted_within_its_range_so_bright_means_high_signal() {
    let plain_dir = folder("mono2");
    let spec = Spec::axial("1.2.826.0.1.3680043.2.1125.1.40");
    writer::write_series(&plain_dir, &spec);
    let inverted_dir = folder("mono1");
    let spec1 = Spec {
        photometric: "MONOCHROME1",
        ..spec.clone()
    };
    writer::write_series(&inverted_dir, &spec1);
    let plain = read(&plain_dir, None).unwrap();
    let inverted = read(&inverted_dir, None).unwrap();
    let a = plain.samples.to_f64_vec();
    let b = inverted.samples.to_f64_vec();
    let lo = a.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = a.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    assert!(hi > lo, "the test series must not be constant");
    assert_eq!(inverted.samples.kind(), plain.samples.kind());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(
            *y,
            lo + hi - x,
            "MONOCHROME1 sample not inverted in its range"
        );
    }
    assert!(
        inverted.warnings.iter().any(|w| w.contains("MONOCHROME1")),
        "{:?}",
        inverted.warnings
    );
    assert!(plain.warnings.is_empty(), "{:?}", plain.warnings);
    assert_eq!(inverted.orientation.affine, plain.orientation.affine);
}

#[test]
fn an_enhanced_multiframe_object_is_one_volume_with_per_frame_geometry_and_rescale() {
    let dir = folder("enhanced");
    let spec = Spec {
        multiframe: true,
        rescale: |k| (1.0, k as f64),
        ..Spec::oblique("1.2.826.0.1.3680043.2.1125.1.9")
    };
    let files = writer::write_series(&dir, &spec);
    // The file itself (not its folder) is the input.
    let v = read(&files[0], None).unwrap();
    assert_matches(&v, &spec, |i, j, k| spec.value(i, j, k) as f64 + k as f64);
}

#[test]
fn a_localizer_and_a_second_series_are_listed_but_the_largest_3d_series_is_the_default() {
    let dir = folder("exam");
    let main = Spec::axial("1.2.826.0.1.3680043.2.1125.1.10");
    writer::write_series(&dir.join("t1"), &main);
    let small = Spec {
        slices: 6,
        number: 5,
        description: "small".into(),
        offset: 5000,
        ..Spec::coronal("1.2.826.0.1.3680043.2.1125.1.11")
    };
    writer::write_series(&dir.join("t2"), &small);
    // A 3-slice localizer in a third series, larger in-plane than the main series.
    let localizer = Spec {
        rows: 64,
        cols: 64,
        slices: 3,
        number: 1,
        image_type: "ORIGINAL\\PRIMARY\\LOCALIZER".into(),
        ..Spec::sagittal("1.2.826.0.1.3680043.2.1125.1.12")
    };
    writer::write_series(&dir.join("loc"), &localizer);

    let survey = dicom::survey(&dir).unwrap();
    let series = survey.series();
    assert_eq!(series.len(), 3);
    let roles: Vec<_> = series.iter().map(|s| (s.number, s.role)).collect();
    assert_eq!(
        roles,
        [
            (Some(1), dicom::Role::Localizer),
            (Some(3), dicom::Role::Image),
            (Some(5), dicom::Role::Image)
        ]
    );
    assert_eq!(survey.default, Ok(1));
    assert_eq!(series[1].count, 12);
    assert!(survey.default_reason().contains("largest 3-D"));

    assert_matches(&read(&dir, None).unwrap(), &main, plain(&main));
    let by_index = read(&dir, Some(SeriesChoice::Index(2))).unwrap();
    assert_matches(&by_index, &small, plain(&small));
    let by_uid = read(&dir, Some(SeriesChoice::parse(&small.uid).unwrap())).unwrap();
    assert_eq!(by_uid.samples, by_index.samples);
    let e = read(&dir, Some(SeriesChoice::Uid("1.2.3".into()))).unwrap_err();
    assert!(
        e.contains("--series 1.2.3") && e.contains("no such series"),
        "{e}"
    );
}

#[test]
fn a_missing_slice_is_interpolated_with_a_warning() {
    let dir = folder("missing");
    let spec = Spec {
        skip: vec![5],
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.13")
    };
    writer::write_series(&dir, &spec);
    let v = read(&dir, None).unwrap();
    assert!(
        v.warnings.iter().any(|w| w.contains("1 slice(s) missing")),
        "{:?}",
        v.warnings
    );
    // Four slices with the second missing: gaps 2g and g, so the spacing is the smaller one
    // (an upper median took 2g and gave 3 slices).
    let short = folder("missing-short");
    let four = Spec {
        slices: 4,
        skip: vec![1],
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.19")
    };
    writer::write_series(&short, &four);
    assert_eq!(read(&short, None).unwrap().dims, [24, 20, 4]);
    // Slice 5 is the mean of slices 4 and 6 (rounded); every other slice as written.
    assert_matches(&v, &spec, |i, j, k| {
        if k == 5 {
            ((spec.value(i, j, 4) + spec.value(i, j, 6)) as f64 / 2.0).round()
        } else {
            spec.value(i, j, k) as f64
        }
    });
}

#[test]
fn duplicate_positions_keep_the_first_instance_with_a_warning() {
    let dir = folder("duplicate");
    let spec = Spec {
        duplicate: vec![2, 7],
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.14")
    };
    writer::write_series(&dir, &spec);
    let v = read(&dir, None).unwrap();
    assert!(
        v.warnings.iter().any(|w| w.contains("2 frames repeat")),
        "{:?}",
        v.warnings
    );
    assert_matches(&v, &spec, plain(&spec));
}

#[test]
fn gantry_tilt_gives_a_sheared_affine_with_a_warning() {
    let dir = folder("tilt");
    let spec = Spec {
        shift: [0.0, 0.4, 0.0],
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.1.15")
    };
    writer::write_series(&dir, &spec);
    let v = read(&dir, None).unwrap();
    assert!(
        v.warnings.iter().any(|w| w.contains("gantry tilt")),
        "{:?}",
        v.warnings
    );
    assert_matches(&v, &spec, plain(&spec));
}

#[test]
fn a_corrupt_file_is_listed_and_skipped_and_the_series_still_opens() {
    let dir = folder("corrupt");
    let spec = Spec::axial("1.2.826.0.1.3680043.2.1125.1.16");
    let files = writer::write_series(&dir, &spec);
    // A file with the DICM magic and garbage after it, and one cut in its pixel data.
    let mut garbage = vec![0u8; 128];
    garbage.extend_from_slice(b"DICM\x02\x00\x10\x00UI\xff\xff");
    garbage.extend_from_slice(&[0xAB; 300]);
    std::fs::write(dir.join("garbage.dcm"), &garbage).unwrap();
    std::fs::write(dir.join("README.txt"), "not DICOM").unwrap();
    let survey = dicom::survey(&dir).unwrap();
    assert_eq!(survey.skipped().len(), 1, "{:?}", survey.skipped());
    assert!(survey.skipped()[0].path.ends_with("garbage.dcm"));
    assert_eq!(survey.ignored().0, 1);
    let v = read(&dir, None).unwrap();
    assert!(
        v.warnings
            .iter()
            .any(|w| w.contains("garbage.dcm was skipped"))
    );
    assert_matches(&v, &spec, plain(&spec));

    // A slice whose pixel data is cut short: left out, and its gap interpolated.
    let victim = files
        .iter()
        .find(|f| {
            let h = dicom::parse_header(
                std::io::Cursor::new(std::fs::read(f).unwrap()[128..].to_vec()),
                f,
            );
            matches!(h, Ok(Some(h)) if h.frames[0].position == Some(spec.position(4)))
        })
        .unwrap();
    let bytes = std::fs::read(victim).unwrap();
    std::fs::write(victim, &bytes[..bytes.len() - 200]).unwrap();
    let v = read(&dir, None).unwrap();
    assert_eq!(v.dims, [24, 20, 12]);
    assert!(
        v.warnings
            .iter()
            .any(|w| w.contains("was left out") || w.contains("was skipped")),
        "{:?}",
        v.warnings
    );
}

#[test]
fn an_empty_folder_or_one_without_images_is_a_clear_error() {
    let dir = folder("empty");
    let e = read(&dir, None).unwrap_err();
    assert!(e.contains("no DICOM image series found"), "{e}");
    std::fs::write(dir.join("notes.txt"), "hello").unwrap();
    let e = read(&dir, None).unwrap_err();
    assert!(e.contains("1 file(s) not DICOM"), "{e}");
}

#[test]
fn a_dicomdir_and_a_single_slice_open_their_series() {
    let dir = folder("dicomdir");
    let spec = Spec::sagittal("1.2.826.0.1.3680043.2.1125.1.17");
    let files = writer::write_series(&dir.join("DATA"), &spec);
    let dicomdir = writer::write_dicomdir(&dir, &files);
    assert_matches(&read(&dicomdir, None).unwrap(), &spec, plain(&spec));
    // One slice stands for its series (the files of its folder with its UID).
    let v = read(&files[3], None).unwrap();
    assert_matches(&v, &spec, plain(&spec));
    assert!(v.warnings.iter().any(|w| w.contains("one slice was given")));
}

#[test]
fn a_file_without_a_dicom_name_is_claimed_by_its_magic() {
    let dir = folder("magic");
    let spec = Spec::axial("1.2.826.0.1.3680043.2.1125.1.18");
    let files = writer::write_series(&dir, &spec);
    let plain_name = dir.join("IM0001");
    std::fs::rename(&files[0], &plain_name).unwrap();
    assert_eq!(source::reader_for(&plain_name).name(), "DICOM");
    assert_eq!(source::reader_for(&dir).name(), "DICOM");
}

/// Seeds of the `dicom_series` fuzz target (tools/fuzz/README.md): small series in each
/// encoding, each seed the concatenation of its files from the `DICM` magic on (the target
/// splits there). Written under `$MORPHRAY_FUZZ_SEEDS/dicom_series/` when that is set; always
/// checked to read back as the series they were made from.
#[test]
fn fuzz_seeds_are_series_that_read_back() {
    let out =
        std::env::var_os("MORPHRAY_FUZZ_SEEDS").map(|d| PathBuf::from(d).join("dicom_series"));
    let small = |uid: &str| Spec {
        rows: 3,
        cols: 4,
        slices: 3,
        ..Spec::oblique(uid)
    };
    let seeds = [
        ("native", small("1.2.826.0.1.3680043.2.1125.4.1")),
        (
            "implicit",
            Spec {
                encoding: writer::IMPLICIT_LE,
                ..small("1.2.826.0.1.3680043.2.1125.4.2")
            },
        ),
        (
            "rle",
            Spec {
                encoding: writer::RLE,
                ..small("1.2.826.0.1.3680043.2.1125.4.3")
            },
        ),
        (
            "jpeg",
            Spec {
                encoding: writer::JPEG_LOSSLESS,
                ..small("1.2.826.0.1.3680043.2.1125.4.4")
            },
        ),
        (
            "enhanced",
            Spec {
                multiframe: true,
                rescale: |k| (1.0, k as f64),
                ..small("1.2.826.0.1.3680043.2.1125.4.5")
            },
        ),
        (
            "gap",
            Spec {
                slices: 4,
                skip: vec![1],
                rescale: |k| (2.0, k as f64),
                ..small("1.2.826.0.1.3680043.2.1125.4.6")
            },
        ),
    ];
    for (name, spec) in seeds {
        let dir = folder(&format!("seed-{name}"));
        let files = writer::write_series(&dir, &spec);
        let seed: Vec<u8> = files
            .iter()
            .flat_map(|f| std::fs::read(f).unwrap()[128..].to_vec())
            .collect();
        let v = read(&dir, None).unwrap();
        assert_eq!(v.dims, [4, 3, spec.slices], "{name}");
        if let Some(out) = &out {
            std::fs::create_dir_all(out).unwrap();
            std::fs::write(out.join(name), &seed).unwrap();
        }
    }
}

/// The `dicom_series` fuzz target's first finding (tests/data/fuzz/): a 2.4 KB input whose
/// element declared 1.4 GB, which dicom-rs reserved and zero-filled before reading. Split at
/// `DICM` into files as the target does; the files must be skipped naming the length, without
/// the allocation (lengths.rs checks every declared length against the file first).
///
/// The second: an element with an unknown VR, which dicom-rs reads as UN with a 32-bit length
/// (the first length walk read a 16-bit one, as for short VRs, and missed it).
#[test]
fn fuzz_finding_a_huge_declared_length_is_a_skipped_file_not_an_allocation() {
    for (name, data) in [
        (
            "declared-length",
            &include_bytes!("data/fuzz/dicom_series-oom-declared-length.bin")[..],
        ),
        (
            "unknown-vr",
            &include_bytes!("data/fuzz/dicom_series-oom-unknown-vr.bin")[..],
        ),
    ] {
        fuzz_input_is_refused(name, data, "bytes but only");
    }
    // The third: (0028,0011) as SL with 2 bytes; dicom-rs reads no value and consumes nothing,
    // so its parse went on 2 bytes early and met a 775 MB length the walk never saw.
    fuzz_input_is_refused(
        "short-numeric",
        include_bytes!("data/fuzz/dicom_series-oom-short-numeric.bin"),
        "not a whole number of 4-byte values",
    );
}

fn fuzz_input_is_refused(name: &str, data: &[u8], needle: &str) {
    let dir = folder(&format!("fuzz-{name}"));
    let mut starts: Vec<usize> = (0..data.len().saturating_sub(3))
        .filter(|&i| &data[i..i + 4] == b"DICM")
        .collect();
    if starts.first() != Some(&0) {
        starts.insert(0, 0);
    }
    for (n, &s) in starts.iter().enumerate() {
        let end = starts.get(n + 1).copied().unwrap_or(data.len());
        let mut file = vec![0u8; 128];
        file.extend_from_slice(&data[s..end]);
        std::fs::write(dir.join(format!("f{n:02}.dcm")), file).unwrap();
    }
    let e = match dicom::survey(&dir) {
        Ok(s) => s
            .skipped()
            .iter()
            .map(|s| s.reason.clone())
            .collect::<Vec<_>>()
            .join("; "),
        Err(e) => e.to_string(),
    };
    assert!(e.contains(needle), "{name}: {e}");
}

/// A FIFO given as a DICOM input (by its name, or inside a folder) must not block the open
/// waiting for a writer: it is refused (or left out of the folder) at once.
#[test]
fn a_fifo_never_blocks_the_dicom_reader() {
    let dir = folder("fifo");
    let fifo = dir.join("slice.dcm");
    let name = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: mkfifo with a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(name.as_ptr(), 0o600) }, 0);
    let (tx, rx) = std::sync::mpsc::channel();
    let (f, d) = (fifo.clone(), dir.clone());
    std::thread::spawn(move || {
        let by_name = read(&f, None);
        let in_folder = read(&d, None);
        tx.send((by_name, in_folder)).unwrap();
    });
    let (by_name, in_folder) = rx
        .recv_timeout(std::time::Duration::from_secs(10))
        .expect("the reader returned instead of blocking on the FIFO");
    assert!(by_name.unwrap_err().contains("no DICOM image series"));
    assert!(in_folder.unwrap_err().contains("no DICOM image series"));
}

/// The fourth fuzz finding: an RLE fragment whose header declares about 1.2 billion segments;
/// dicom-rs allocated 4.9 GB of offsets (and panicked on other counts). The series' files are
/// left out with the reason, without the allocation.
#[test]
fn fuzz_finding_an_rle_header_with_too_many_segments_is_refused() {
    let data = include_bytes!("data/fuzz/dicom_series-oom-rle-segments.bin");
    let dir = folder("fuzz-rle");
    let mut starts: Vec<usize> = (0..data.len().saturating_sub(3))
        .filter(|&i| &data[i..i + 4] == b"DICM")
        .collect();
    if starts.first() != Some(&0) {
        starts.insert(0, 0);
    }
    for (n, &s) in starts.iter().enumerate() {
        let end = starts.get(n + 1).copied().unwrap_or(data.len());
        let mut file = vec![0u8; 128];
        file.extend_from_slice(&data[s..end]);
        std::fs::write(dir.join(format!("f{n:02}.dcm")), file).unwrap();
    }
    let e = read(&dir, None).unwrap_err();
    assert!(e.contains("segments (1 to 15"), "{e}");
}

#[test]
fn a_siemens_mosaic_is_cut_into_its_slices_with_their_positions() {
    for (name, spec) in [
        (
            "mosaic-along",
            Spec {
                slices: 5,
                mosaic: writer::Mosaic::Along,
                ..Spec::oblique("1.2.826.0.1.3680043.2.1125.1.40")
            },
        ),
        (
            "mosaic-against",
            Spec {
                slices: 9,
                mosaic: writer::Mosaic::Against,
                ..Spec::sagittal("1.2.826.0.1.3680043.2.1125.1.41")
            },
        ),
    ] {
        let dir = folder(name);
        writer::write_series(&dir, &spec);
        let v = read(&dir, None).unwrap_or_else(|e| panic!("{name}: {e}"));
        // Before issue 30 this was one 2-D image of the whole grid (e.g. 72x60x1).
        assert_matches(&v, &spec, plain(&spec));
        assert!(v.warnings.is_empty(), "{name}: {:?}", v.warnings);
    }
}
