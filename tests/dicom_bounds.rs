//! Issue 30, DICOM: tags checked against the data, inputs bounded by what their headers declare
//! and by the host's available memory, named files never replaced, and the messages that
//! replaced the unhelpful ones. Series are written by the tests' writer (tests/common/dicom.rs)
//! and then damaged through dicom-object; memory refusals use `MORPHRAY_MEM_AVAILABLE`
//! (host_memory.rs) in a child process, so they happen on any machine.

#[path = "common/dicom.rs"]
mod writer;

use dicom_core::{DataElement, PrimitiveValue, VR};
use dicom_dictionary_std::tags;
use morphray::volume::Volume;
use morphray::volume::source::{self as source, ReadOptions, VolumeSource};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use writer::Spec;

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-bounds-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read(path: &Path) -> Result<Volume, String> {
    source::read(
        &VolumeSource::File(path.to_path_buf()),
        &ReadOptions::default(),
    )
    .map(|s| s.volume)
    .map_err(|e| e.to_string())
}

/// Rewrites `path` with `change` applied to its data set (its transfer syntax kept).
fn damage(path: &Path, change: impl FnOnce(&mut dicom_object::DefaultDicomObject)) {
    let mut obj = dicom_object::open_file(path).unwrap();
    change(&mut obj);
    obj.write_to_file(path).unwrap();
}

fn us(tag: dicom_core::Tag, v: u16) -> DataElement<dicom_object::InMemDicomObject> {
    DataElement::new(tag, VR::US, PrimitiveValue::from(v))
}

fn morphray(args: &[&str], mem: Option<&str>) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_morphray"));
    c.args(args);
    if let Some(m) = mem {
        c.env("MORPHRAY_MEM_AVAILABLE", m);
    }
    c.output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A small axial series (24 x 20 x `slices`); the files written, in slice order.
fn series(dir: &Path, uid: &str, slices: usize) -> (Spec, Vec<PathBuf>) {
    let spec = Spec {
        slices,
        ..Spec::axial(uid)
    };
    let files = writer::write_series(dir, &spec);
    (spec, files)
}

#[test]
fn bits_stored_zero_or_above_bits_allocated_refuses_that_file_with_its_reason() {
    for (name, stored) in [("bits0", 0u16), ("bits17", 17)] {
        let dir = folder(name);
        let (_, files) = series(&dir, "1.2.826.0.1.3680043.2.1125.30.1", 6);
        damage(&files[2], |o| {
            o.put(us(tags::BITS_STORED, stored));
        });
        let v = read(&dir).unwrap();
        let skipped: Vec<&String> = v
            .warnings
            .iter()
            .filter(|w| w.contains("skipped"))
            .collect();
        assert_eq!(skipped.len(), 1, "{:?}", v.warnings);
        assert!(
            skipped[0].contains(&format!("BitsStored {stored} contradicts BitsAllocated 16")),
            "{skipped:?}"
        );
        // That slice is now a gap the layout fills (5 files of 6 positions).
        assert_eq!(v.dims[2], 6);
        // Named alone, no file is left: the command fails with that reason.
        let e = read(&files[2]).unwrap_err();
        assert!(e.contains("BitsStored") && !e.contains('\n'), "{e}");
    }
}

#[test]
fn pixel_data_longer_or_shorter_than_rows_x_columns_is_refused_not_cut() {
    let dir = folder("pixlen");
    let (_, files) = series(&dir, "1.2.826.0.1.3680043.2.1125.30.2", 5);
    // Longer: Rows says 10 of the 20 rows (the data would be cut in half).
    damage(&files[1], |o| {
        o.put(us(tags::ROWS, 10));
    });
    // Shorter: Rows says 40 (was "Frame #0 is out of range").
    damage(&files[3], |o| {
        o.put(us(tags::ROWS, 40));
    });
    let listing = morphray(&["info", "--json", dir.to_str().unwrap()], None);
    let text = String::from_utf8_lossy(&listing.stdout);
    assert!(
        text.contains("PixelData holds 960 bytes but Rows x Columns x frames 10 x 24 x 1 at 16 bits declare 480"),
        "{text}"
    );
    assert!(
        text.contains("Rows x Columns x frames 40 x 24 x 1 at 16 bits declare 1920 bytes of pixels but PixelData holds only 960"),
        "{text}"
    );
    assert!(!text.contains("out of range"), "{text}");
    // Alone, the shorter one fails with the same reason, one line, not a decoder's.
    let e = read(&files[3]).unwrap_err();
    assert!(
        e.contains("PixelData holds only 960") && !e.contains("Frame #0"),
        "{e}"
    );
}

#[test]
fn a_deflated_file_that_inflates_past_its_declared_size_is_refused() {
    let dir = folder("deflate-bomb");
    let spec = Spec {
        slices: 2,
        encoding: writer::DEFLATED,
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.30.3")
    };
    let files = writer::write_series(&dir, &spec);
    // 8 MB of zeros after the pixel data of each file: a few KB deflated, 8000 times what Rows
    // x Columns declare (960 bytes).
    for f in &files {
        damage(f, |o| {
            o.put(DataElement::new(
                dicom_core::Tag(0x7FE1, 0x0010),
                VR::OB,
                PrimitiveValue::U8(vec![0u8; 8 << 20].into()),
            ));
        });
        let size = std::fs::metadata(f).unwrap().len();
        assert!(size < 64 * 1024, "{size} bytes on disk");
    }
    let e = read(&dir).unwrap_err();
    assert!(
        e.contains("inflates past 1.1 MB, more than its header declares"),
        "{e}"
    );
    assert!(!e.contains('\n'), "{e}");
}

#[test]
fn a_series_larger_than_available_memory_is_refused_up_front_with_both_numbers() {
    let dir = folder("memory");
    series(&dir, "1.2.826.0.1.3680043.2.1125.30.4", 4);
    let o = morphray(&["info", dir.to_str().unwrap()], Some("1000"));
    let e = stderr(&o);
    assert!(!o.status.success());
    assert!(
        e.contains("decoding its 4 file(s) (3.8 KB of pixels declared) needs")
            && e.contains("but only 1.0 KB is available (MemAvailable)"),
        "{e}"
    );
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    // With the memory there, the same folder opens.
    assert!(
        morphray(&["info", dir.to_str().unwrap()], None)
            .status
            .success()
    );
}

#[test]
fn a_nifti_gz_whose_declared_size_exceeds_available_memory_is_refused_before_inflating() {
    let dir = folder("nifti-memory");
    series(&dir.join("dicom"), "1.2.826.0.1.3680043.2.1125.30.5", 4);
    let nii = dir.join("v.nii.gz");
    let o = morphray(
        &[
            "convert",
            dir.join("dicom").to_str().unwrap(),
            "-o",
            nii.to_str().unwrap(),
        ],
        None,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = morphray(&["info", nii.to_str().unwrap()], Some("2000"));
    let e = stderr(&o);
    assert!(!o.status.success());
    assert!(
        e.contains("inflating the") && e.contains("but only 2.0 KB is available (MemAvailable)"),
        "{e}"
    );
    assert!(
        morphray(&["info", nii.to_str().unwrap()], None)
            .status
            .success()
    );
    // Uncompressed: the bytes are read, their conversion is refused the same way.
    let raw = dir.join("v.nii");
    let o = morphray(
        &[
            "convert",
            nii.to_str().unwrap(),
            "-o",
            raw.to_str().unwrap(),
        ],
        None,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = morphray(&["info", raw.to_str().unwrap()], Some("2000"));
    let e = stderr(&o);
    assert!(!o.status.success());
    assert!(
        e.contains("uncompressed image") && e.contains("but only 2.0 KB is available"),
        "{e}"
    );
}

#[test]
fn a_file_named_on_the_command_line_wins_its_position_and_the_duplicate_is_listed() {
    let dir = folder("named");
    let spec = Spec {
        slices: 6,
        duplicate: vec![3],
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.30.6")
    };
    let files = writer::write_series(&dir, &spec);
    // Slices 0..2, then slice 3's two copies (the second: values + 500, larger
    // InstanceNumber), then 4, 5.
    let (first, second) = (&files[3], &files[4]);
    let value_at = |v: &Volume| v.samples.get(v.dims[0] * v.dims[1] * 3);
    let folder_read = read(&dir).unwrap();
    assert_eq!(value_at(&folder_read), spec.value(0, 0, 3) as f64);
    let named = read(second).unwrap();
    assert_eq!(value_at(&named), (spec.value(0, 0, 3) + 500) as f64);
    let name = first.file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        named
            .warnings
            .iter()
            .any(|w| w.contains("named on the command line") && w.contains(&name)),
        "{:?}",
        named.warnings
    );
}

#[test]
fn one_slice_alone_says_so_and_info_still_lists_it() {
    let dir = folder("one-slice");
    series(&dir, "1.2.826.0.1.3680043.2.1125.30.7", 1);
    let e = read(&dir).unwrap_err();
    assert!(
        e.contains("it holds one 2-D slice (24x20), not a 3-D volume") && e.contains("--series 0"),
        "{e}"
    );
    let o = morphray(&["info", dir.to_str().unwrap()], None);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("24x20x1"));
    // And the slice itself opens when asked for.
    let one = source::read(
        &VolumeSource::File(dir.clone()),
        &ReadOptions {
            series: Some(morphray::volume::source::dicom::SeriesChoice::Index(0)),
            ..ReadOptions::default()
        },
    )
    .unwrap();
    assert_eq!(one.volume.dims, [24, 20, 1]);
}

#[test]
fn every_file_its_own_series_is_said_in_one_short_line_with_a_count() {
    let dir = folder("own-series");
    for n in 0..40 {
        let spec = Spec {
            slices: 1,
            origin: [0.0, 0.0, n as f64 * 2.0],
            ..Spec::axial(&format!("1.2.826.0.1.3680043.2.1125.30.8.{n}"))
        };
        writer::write_series(&dir, &spec);
    }
    let e = read(&dir).unwrap_err();
    assert!(
        e.contains("every one of its 40 image files is its own series"),
        "{e}"
    );
    assert!(
        e.len() < 400 && !e.contains("image of 1 slice(s)"),
        "{} chars: {e}",
        e.len()
    );
}

#[test]
fn a_mosaic_without_its_image_count_is_read_as_one_image_with_a_warning() {
    let dir = folder("mosaic-no-count");
    let spec = Spec {
        slices: 4,
        mosaic: writer::Mosaic::Along,
        ..Spec::axial("1.2.826.0.1.3680043.2.1125.30.9")
    };
    let files = writer::write_series(&dir, &spec);
    for f in &files {
        damage(f, |obj| {
            obj.remove_element(dicom_core::Tag(0x0019, 0x100A));
            obj.remove_element(dicom_core::Tag(0x0029, 0x1010));
        });
    }
    // The folder is refused as one slice, and the refusal says why it was not cut.
    let e = read(&dir).unwrap_err();
    assert!(e.contains("one 2-D slice") && e.contains("MOSAIC"), "{e}");
    let options = ReadOptions {
        series: Some(source::dicom::SeriesChoice::Index(0)),
        ..ReadOptions::default()
    };
    let v = source::read(&VolumeSource::File(dir.clone()), &options)
        .map(|s| s.volume)
        .expect("the slice itself");
    assert_eq!(v.dims[2], 1, "not cut: {:?}", v.dims);
    assert!(
        v.warnings
            .iter()
            .any(|w| w.contains("MOSAIC but no NumberOfImagesInMosaic")),
        "{:?}",
        v.warnings
    );
}
