//! A small DICOM series writer for the tests (dicom-object builds and writes the objects in
//! memory), so `cargo test` needs no Python for DICOM: native encodings (explicit/implicit
//! little endian, explicit big endian, deflated), RLE Lossless and JPEG Lossless (process 14,
//! first-order prediction) encoded here, enhanced multi-frame objects and a DICOMDIR.
//!
//! Every voxel's value is a known function of (i, j, k) ([`Spec::value`]) and every voxel's RAS
//! position a known function too ([`Spec::ras`]), computed here independently of the reader.
#![allow(dead_code)]

use dicom_core::value::{DataSetSequence, PixelFragmentSequence, Value};
use dicom_core::{DataElement, Length, PrimitiveValue, VR};
use dicom_dictionary_std::tags;
use dicom_object::InMemDicomObject;
use dicom_object::meta::FileMetaTableBuilder;
use std::path::{Path, PathBuf};

pub const EXPLICIT_LE: &str = "1.2.840.10008.1.2.1";
pub const IMPLICIT_LE: &str = "1.2.840.10008.1.2";
pub const EXPLICIT_BE: &str = "1.2.840.10008.1.2.2";
pub const DEFLATED: &str = "1.2.840.10008.1.2.1.99";
pub const RLE: &str = "1.2.840.10008.1.2.5";
pub const JPEG_LOSSLESS: &str = "1.2.840.10008.1.2.4.70";
pub const JPEG_2000: &str = "1.2.840.10008.1.2.4.90";
const MR_IMAGE: &str = "1.2.840.10008.5.1.4.1.1.4";
const ENHANCED_MR: &str = "1.2.840.10008.5.1.4.1.1.4.1";

/// One series to write.
#[derive(Clone, Debug)]
pub struct Spec {
    pub rows: u16,
    pub cols: u16,
    pub slices: usize,
    /// ImageOrientationPatient row direction (LPS, unit).
    pub row_dir: [f64; 3],
    /// Column direction (LPS, unit).
    pub col_dir: [f64; 3],
    /// PixelSpacing: between rows, between columns.
    pub pixel_spacing: [f64; 2],
    /// Distance between slices along the normal, mm.
    pub gap: f64,
    /// Position of slice 0's first pixel, LPS.
    pub origin: [f64; 3],
    /// Sideways offset added per slice (gantry tilt), LPS mm.
    pub shift: [f64; 3],
    pub uid: String,
    pub number: i32,
    pub description: String,
    /// ImageType, backslash-separated.
    pub image_type: String,
    /// Transfer syntax UID.
    pub encoding: &'static str,
    pub signed: bool,
    /// RescaleSlope and RescaleIntercept of slice k.
    pub rescale: fn(usize) -> (f64, f64),
    /// Slices not written (missing).
    pub skip: Vec<usize>,
    /// Slices written twice (a second file at the same position, with other values).
    pub duplicate: Vec<usize>,
    /// One enhanced multi-frame file instead of one file per slice.
    pub multiframe: bool,
    /// Value offset (to tell series apart).
    pub offset: i32,
    /// Voxel values (i fastest, cols x rows x slices) instead of the formula.
    pub data: Option<std::sync::Arc<Vec<i32>>>,
    /// PhotometricInterpretation.
    pub photometric: &'static str,
    /// Modality (MR, CT, ...).
    pub modality: &'static str,
    /// More text elements of every file (RepetitionTime, ProtocolName, ...).
    pub extra: Vec<(dicom_core::Tag, VR, String)>,
    /// A Siemens mosaic: one file whose tiles are the slices.
    pub mosaic: Mosaic,
}

/// How a mosaic is written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mosaic {
    /// Not a mosaic.
    No,
    /// Tiles in slice order along row x column; the CSA SliceNormalVector says so.
    Along,
    /// Tiles stored against row x column (as Siemens stores sagittal R to L); the CSA
    /// SliceNormalVector points against it.
    Against,
}

fn no_rescale(_: usize) -> (f64, f64) {
    (1.0, 0.0)
}

impl Spec {
    /// An axial 24x20x12 series, 0.9 x 1.1 mm pixels, 2.5 mm slices, explicit little endian.
    pub fn axial(uid: &str) -> Spec {
        Spec {
            rows: 20,
            cols: 24,
            slices: 12,
            row_dir: [1.0, 0.0, 0.0],
            col_dir: [0.0, 1.0, 0.0],
            pixel_spacing: [1.1, 0.9],
            gap: 2.5,
            origin: [-10.5, -20.25, 30.0],
            shift: [0.0; 3],
            uid: uid.to_string(),
            number: 3,
            description: "T1 test".into(),
            image_type: "ORIGINAL\\PRIMARY\\M\\ND".into(),
            encoding: EXPLICIT_LE,
            signed: false,
            rescale: no_rescale,
            skip: Vec::new(),
            duplicate: Vec::new(),
            multiframe: false,
            offset: 0,
            data: None,
            photometric: "MONOCHROME2",
            modality: "MR",
            extra: Vec::new(),
            mosaic: Mosaic::No,
        }
    }

    /// Sagittal: rows along anterior-posterior, columns head to foot, slices left to right.
    pub fn sagittal(uid: &str) -> Spec {
        Spec {
            row_dir: [0.0, 1.0, 0.0],
            col_dir: [0.0, 0.0, -1.0],
            ..Spec::axial(uid)
        }
    }

    /// Coronal.
    pub fn coronal(uid: &str) -> Spec {
        Spec {
            row_dir: [1.0, 0.0, 0.0],
            col_dir: [0.0, 0.0, -1.0],
            ..Spec::axial(uid)
        }
    }

    /// Oblique: the axial directions rotated by 20 degrees about x, then 30 about z.
    pub fn oblique(uid: &str) -> Spec {
        let rot = |v: [f64; 3]| {
            let (a, b) = (20f64.to_radians(), 30f64.to_radians());
            let v = [
                v[0],
                v[1] * a.cos() - v[2] * a.sin(),
                v[1] * a.sin() + v[2] * a.cos(),
            ];
            [
                v[0] * b.cos() - v[1] * b.sin(),
                v[0] * b.sin() + v[1] * b.cos(),
                v[2],
            ]
        };
        Spec {
            row_dir: rot([1.0, 0.0, 0.0]),
            col_dir: rot([0.0, 1.0, 0.0]),
            ..Spec::axial(uid)
        }
    }

    /// The normal (row x column).
    pub fn normal(&self) -> [f64; 3] {
        let (a, b) = (self.row_dir, self.col_dir);
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    /// Stored value of pixel (column i, row j) of slice k.
    pub fn value(&self, i: usize, j: usize, k: usize) -> i32 {
        if let Some(data) = &self.data {
            let (c, r) = (self.cols as usize, self.rows as usize);
            return data[i + c * (j + r * k)];
        }
        let v = ((i * 7 + j * 13 + k * 101) % 3000) as i32 + self.offset;
        if self.signed { v - 1000 } else { v + 10 }
    }

    /// ImagePositionPatient of slice k (LPS).
    pub fn position(&self, k: usize) -> [f64; 3] {
        let n = self.normal();
        let k = k as f64;
        [0, 1, 2].map(|a| self.origin[a] + n[a] * self.gap * k + self.shift[a] * k)
    }

    /// RAS position of voxel (i, j, k) (k counts slices as written, skipped ones included).
    pub fn ras(&self, i: f64, j: f64, k: f64) -> [f64; 3] {
        let n = self.normal();
        let lps: [f64; 3] = [0, 1, 2].map(|a| {
            self.origin[a]
                + self.row_dir[a] * self.pixel_spacing[1] * i
                + self.col_dir[a] * self.pixel_spacing[0] * j
                + (n[a] * self.gap + self.shift[a]) * k
        });
        [-lps[0], -lps[1], lps[2]]
    }

    /// The stored values of slice k, row-major.
    pub fn slice_values(&self, k: usize) -> Vec<i32> {
        let mut v = Vec::with_capacity(self.rows as usize * self.cols as usize);
        for j in 0..self.rows as usize {
            for i in 0..self.cols as usize {
                v.push(self.value(i, j, k));
            }
        }
        v
    }
}

fn ds(values: &[f64]) -> PrimitiveValue {
    PrimitiveValue::Strs(
        values
            .iter()
            .map(|v| {
                let s = format!("{:.6}", v + 0.0);
                s.trim_end_matches('0').trim_end_matches('.').to_string()
            })
            .collect::<Vec<_>>()
            .into(),
    )
}

fn text(obj: &mut InMemDicomObject, tag: dicom_core::Tag, vr: VR, value: &str) {
    obj.put(DataElement::new(tag, vr, PrimitiveValue::from(value)));
}

fn strs(obj: &mut InMemDicomObject, tag: dicom_core::Tag, vr: VR, values: &[&str]) {
    let v: Vec<String> = values.iter().map(|s| s.to_string()).collect();
    obj.put(DataElement::new(tag, vr, PrimitiveValue::Strs(v.into())));
}

fn us(obj: &mut InMemDicomObject, tag: dicom_core::Tag, value: u16) {
    obj.put(DataElement::new(tag, VR::US, PrimitiveValue::from(value)));
}

fn sequence(obj: &mut InMemDicomObject, tag: dicom_core::Tag, items: Vec<InMemDicomObject>) {
    obj.put(DataElement::new(
        tag,
        VR::SQ,
        Value::from(DataSetSequence::new(items, Length::UNDEFINED)),
    ));
}

fn item(tag: dicom_core::Tag, value: PrimitiveValue, vr: VR) -> InMemDicomObject {
    let mut o = InMemDicomObject::new_empty();
    o.put(DataElement::new(tag, vr, value));
    o
}

/// Header elements shared by every file of the series.
fn common(spec: &Spec, obj: &mut InMemDicomObject, sop_instance: &str, class: &str) {
    text(obj, tags::SOP_CLASS_UID, VR::UI, class);
    text(obj, tags::SOP_INSTANCE_UID, VR::UI, sop_instance);
    text(
        obj,
        tags::STUDY_INSTANCE_UID,
        VR::UI,
        "1.2.826.0.1.3680043.2.1125.9.1",
    );
    text(obj, tags::SERIES_INSTANCE_UID, VR::UI, &spec.uid);
    text(
        obj,
        tags::FRAME_OF_REFERENCE_UID,
        VR::UI,
        "1.2.826.0.1.3680043.2.1125.9.2",
    );
    text(obj, tags::PATIENT_NAME, VR::PN, "Test^Phantom");
    text(obj, tags::PATIENT_ID, VR::LO, "TEST");
    text(obj, tags::STUDY_DATE, VR::DA, "20260101");
    text(obj, tags::MODALITY, VR::CS, spec.modality);
    for (tag, vr, value) in &spec.extra {
        text(obj, *tag, *vr, value);
    }
    text(obj, tags::SERIES_NUMBER, VR::IS, &spec.number.to_string());
    text(obj, tags::SERIES_DESCRIPTION, VR::LO, &spec.description);
    let types: Vec<&str> = spec.image_type.split('\\').collect();
    strs(obj, tags::IMAGE_TYPE, VR::CS, &types);
    obj.put(DataElement::new(
        tags::SLICE_THICKNESS,
        VR::DS,
        ds(&[spec.gap]),
    ));
    us(obj, tags::ROWS, spec.rows);
    us(obj, tags::COLUMNS, spec.cols);
    us(obj, tags::SAMPLES_PER_PIXEL, 1);
    text(
        obj,
        tags::PHOTOMETRIC_INTERPRETATION,
        VR::CS,
        spec.photometric,
    );
    us(obj, tags::BITS_ALLOCATED, 16);
    us(obj, tags::BITS_STORED, 16);
    us(obj, tags::HIGH_BIT, 15);
    us(obj, tags::PIXEL_REPRESENTATION, spec.signed as u16);
}

/// The pixel data element of `frames` (each row-major) in the spec's encoding.
fn pixel_data(spec: &Spec, frames: &[Vec<i32>]) -> DataElement<InMemDicomObject> {
    let words: Vec<u16> = frames.iter().flatten().map(|&v| v as u16).collect();
    let encapsulated = |encode: &dyn Fn(&[i32]) -> Vec<u8>| {
        let fragments: Vec<Vec<u8>> = frames
            .iter()
            .map(|f| {
                let mut b = encode(f);
                if b.len() % 2 == 1 {
                    b.push(0);
                }
                b
            })
            .collect();
        DataElement::new(
            tags::PIXEL_DATA,
            VR::OB,
            Value::from(PixelFragmentSequence::new(Vec::<u32>::new(), fragments)),
        )
    };
    match spec.encoding {
        RLE => encapsulated(&|f| rle_encode(f, spec.rows as usize, spec.cols as usize)),
        JPEG_LOSSLESS => {
            encapsulated(&|f| jpeg_lossless_encode(f, spec.rows as usize, spec.cols as usize))
        }
        JPEG_2000 => encapsulated(&|_| vec![0xFF, 0x4F, 0xFF, 0x51, 0, 0]),
        _ => DataElement::new(tags::PIXEL_DATA, VR::OW, PrimitiveValue::U16(words.into())),
    }
}

fn write(obj: InMemDicomObject, encoding: &str, path: &Path) {
    let file = obj
        .with_meta(FileMetaTableBuilder::new().transfer_syntax(encoding))
        .unwrap();
    file.write_to_file(path).unwrap();
}

/// A file name that says nothing of the slice order.
fn scrambled_name(spec: &Spec, k: usize, copy: usize) -> String {
    let mut h: u64 = 1469598103934665603;
    for b in spec
        .uid
        .bytes()
        .chain([k as u8, (k >> 8) as u8, copy as u8])
    {
        h = (h ^ b as u64).wrapping_mul(1099511628211);
    }
    format!("{:012x}.dcm", h & 0xffff_ffff_ffff)
}

/// A spec whose voxels are those of `volume` (rounded), in an axial series with the
/// volume's spacing and RAS origin (the volume's affine is taken as diagonal).
pub fn from_volume(uid: &str, volume: &morphray::volume::Volume) -> Spec {
    let [nx, ny, nz] = volume.dims;
    let data: Vec<i32> = (0..nx * ny * nz)
        .map(|i| volume.samples.get(i).round() as i32)
        .collect();
    let signed = data.iter().any(|&v| v < 0);
    let a = &volume.orientation.affine;
    // RAS origin to LPS; the columns of a diagonal RAS affine with positive x and y spacing
    // point to LPS -x and -y: flip them into the directions.
    let (sx, sy) = (a[0][0].signum(), a[1][1].signum());
    Spec {
        rows: ny as u16,
        cols: nx as u16,
        slices: nz,
        row_dir: [-sx, 0.0, 0.0],
        col_dir: [0.0, -sy, 0.0],
        pixel_spacing: [volume.spacing_mm[1], volume.spacing_mm[0]],
        gap: volume.spacing_mm[2] * a[2][2].signum() * sx * sy,
        origin: [-a[0][3], -a[1][3], a[2][3]],
        signed,
        data: Some(std::sync::Arc::new(data)),
        description: volume.name.clone(),
        ..Spec::axial(uid)
    }
}

/// Writes the series into `dir` (created); returns the files written.
pub fn write_series(dir: &Path, spec: &Spec) -> Vec<PathBuf> {
    std::fs::create_dir_all(dir).unwrap();
    if spec.multiframe {
        return vec![write_multiframe(dir, spec)];
    }
    if spec.mosaic != Mosaic::No {
        return vec![write_mosaic(dir, spec)];
    }
    let mut files = Vec::new();
    for k in 0..spec.slices {
        if spec.skip.contains(&k) {
            continue;
        }
        let copies = if spec.duplicate.contains(&k) { 2 } else { 1 };
        for copy in 0..copies {
            let mut obj = InMemDicomObject::new_empty();
            let sop = format!("{}.{}.{}", spec.uid, k + 1, copy + 1);
            common(spec, &mut obj, &sop, MR_IMAGE);
            // Meaningless InstanceNumbers: they must not decide the order. A duplicate's
            // second copy has the larger number, so it is the one left out.
            let instance = ((spec.slices - k) * 7) % 23 + 1 + copy * 100;
            text(
                &mut obj,
                tags::INSTANCE_NUMBER,
                VR::IS,
                &instance.to_string(),
            );
            let d = spec
                .row_dir
                .iter()
                .chain(&spec.col_dir)
                .copied()
                .collect::<Vec<_>>();
            obj.put(DataElement::new(
                tags::IMAGE_ORIENTATION_PATIENT,
                VR::DS,
                ds(&d),
            ));
            obj.put(DataElement::new(
                tags::IMAGE_POSITION_PATIENT,
                VR::DS,
                ds(&spec.position(k)),
            ));
            obj.put(DataElement::new(
                tags::PIXEL_SPACING,
                VR::DS,
                ds(&spec.pixel_spacing),
            ));
            let (slope, intercept) = (spec.rescale)(k);
            obj.put(DataElement::new(tags::RESCALE_SLOPE, VR::DS, ds(&[slope])));
            obj.put(DataElement::new(
                tags::RESCALE_INTERCEPT,
                VR::DS,
                ds(&[intercept]),
            ));
            let mut values = spec.slice_values(k);
            if copy > 0 {
                values.iter_mut().for_each(|v| *v += 500);
            }
            obj.put(pixel_data(spec, &[values]));
            let path = dir.join(scrambled_name(spec, k, copy));
            write(obj, spec.encoding, &path);
            files.push(path);
        }
    }
    files
}

/// One enhanced MR object holding every slice as a frame (geometry in functional groups).
fn write_multiframe(dir: &Path, spec: &Spec) -> PathBuf {
    let mut obj = InMemDicomObject::new_empty();
    common(spec, &mut obj, &format!("{}.1", spec.uid), ENHANCED_MR);
    text(
        &mut obj,
        tags::NUMBER_OF_FRAMES,
        VR::IS,
        &spec.slices.to_string(),
    );
    let d = spec
        .row_dir
        .iter()
        .chain(&spec.col_dir)
        .copied()
        .collect::<Vec<_>>();
    let mut shared = InMemDicomObject::new_empty();
    sequence(
        &mut shared,
        tags::PLANE_ORIENTATION_SEQUENCE,
        vec![item(tags::IMAGE_ORIENTATION_PATIENT, ds(&d), VR::DS)],
    );
    sequence(
        &mut shared,
        tags::PIXEL_MEASURES_SEQUENCE,
        vec![item(tags::PIXEL_SPACING, ds(&spec.pixel_spacing), VR::DS)],
    );
    sequence(
        &mut obj,
        tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE,
        vec![shared],
    );
    // Frames stored in reverse order: only the positions say where they go.
    let order: Vec<usize> = (0..spec.slices).rev().collect();
    let per_frame = order
        .iter()
        .map(|&k| {
            let mut g = InMemDicomObject::new_empty();
            sequence(
                &mut g,
                tags::PLANE_POSITION_SEQUENCE,
                vec![item(
                    tags::IMAGE_POSITION_PATIENT,
                    ds(&spec.position(k)),
                    VR::DS,
                )],
            );
            let (slope, intercept) = (spec.rescale)(k);
            let mut t = item(tags::RESCALE_SLOPE, ds(&[slope]), VR::DS);
            t.put(DataElement::new(
                tags::RESCALE_INTERCEPT,
                VR::DS,
                ds(&[intercept]),
            ));
            sequence(&mut g, tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE, vec![t]);
            g
        })
        .collect();
    sequence(
        &mut obj,
        tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE,
        per_frame,
    );
    let frames: Vec<Vec<i32>> = order.iter().map(|&k| spec.slice_values(k)).collect();
    obj.put(pixel_data(spec, &frames));
    let path = dir.join("enhanced.dcm");
    write(obj, spec.encoding, &path);
    path
}

/// A Siemens CSA image header ("SV10") with string-valued tags.
pub fn csa_header(tags: &[(&str, Vec<String>)]) -> Vec<u8> {
    let mut b = b"SV10\x04\x03\x02\x01".to_vec();
    b.extend_from_slice(&(tags.len() as u32).to_le_bytes());
    b.extend_from_slice(&77u32.to_le_bytes());
    for (name, values) in tags {
        let mut tag = [0u8; 84];
        tag[..name.len()].copy_from_slice(name.as_bytes());
        tag[64..68].copy_from_slice(&(values.len() as u32).to_le_bytes());
        tag[68..70].copy_from_slice(b"DS");
        tag[76..80].copy_from_slice(&(values.len() as u32).to_le_bytes());
        tag[80..84].copy_from_slice(&77u32.to_le_bytes());
        b.extend_from_slice(&tag);
        for v in values {
            let len = v.len() as u32 + 1;
            for word in [len, len, 77, len] {
                b.extend_from_slice(&word.to_le_bytes());
            }
            let mut value = v.as_bytes().to_vec();
            value.push(0);
            while value.len() % 4 != 0 {
                value.push(0);
            }
            b.extend_from_slice(&value);
        }
    }
    b
}

/// One Siemens mosaic file holding the spec's slices as tiles of a ceil(sqrt(n))-square grid
/// (empty tiles zero), with ImageType MOSAIC, NumberOfImagesInMosaic (0019,100A), a CSA header
/// (NumberOfImagesInMosaic, SliceNormalVector) and ImagePositionPatient at the grid's corner,
/// as Siemens writes them. The positions the reader must find are `Spec::position`.
pub fn write_mosaic(dir: &Path, spec: &Spec) -> PathBuf {
    let n = spec.slices;
    let per_side = (n as f64).sqrt().ceil() as usize;
    let (tr, tc) = (spec.rows as usize, spec.cols as usize);
    let (mr, mc) = (tr * per_side, tc * per_side);
    let against = spec.mosaic == Mosaic::Against;
    // Tile m holds slice m along the normal, or slice n-1-m against it.
    let slice_of = |m: usize| if against { n - 1 - m } else { m };
    let mut words = vec![0i32; mr * mc];
    for m in 0..n {
        let values = spec.slice_values(slice_of(m));
        let (gr, gc) = (m / per_side, m % per_side);
        for y in 0..tr {
            for x in 0..tc {
                words[(gr * tr + y) * mc + gc * tc + x] = values[y * tc + x];
            }
        }
    }
    let mut obj = InMemDicomObject::new_empty();
    let mut spec_m = spec.clone();
    spec_m.image_type = format!("{}\\MOSAIC", spec.image_type);
    spec_m.rows = mr as u16;
    spec_m.cols = mc as u16;
    spec_m
        .extra
        .push((tags::MANUFACTURER, VR::LO, "SIEMENS".into()));
    common(&spec_m, &mut obj, &format!("{}.1", spec.uid), MR_IMAGE);
    text(&mut obj, tags::INSTANCE_NUMBER, VR::IS, "1");
    let d: Vec<f64> = spec.row_dir.iter().chain(&spec.col_dir).copied().collect();
    obj.put(DataElement::new(
        tags::IMAGE_ORIENTATION_PATIENT,
        VR::DS,
        ds(&d),
    ));
    // The grid's corner: the first tile's first pixel moved back by half the grid minus a tile.
    let first = spec.position(slice_of(0));
    let across = (mc - tc) as f64 / 2.0 * spec.pixel_spacing[1];
    let down = (mr - tr) as f64 / 2.0 * spec.pixel_spacing[0];
    let corner: Vec<f64> = (0..3)
        .map(|a| first[a] - spec.row_dir[a] * across - spec.col_dir[a] * down)
        .collect();
    obj.put(DataElement::new(
        tags::IMAGE_POSITION_PATIENT,
        VR::DS,
        ds(&corner),
    ));
    obj.put(DataElement::new(
        tags::PIXEL_SPACING,
        VR::DS,
        ds(&spec.pixel_spacing),
    ));
    obj.put(DataElement::new(
        tags::SPACING_BETWEEN_SLICES,
        VR::DS,
        ds(&[spec.gap]),
    ));
    let (slope, intercept) = (spec.rescale)(0);
    obj.put(DataElement::new(tags::RESCALE_SLOPE, VR::DS, ds(&[slope])));
    obj.put(DataElement::new(
        tags::RESCALE_INTERCEPT,
        VR::DS,
        ds(&[intercept]),
    ));
    text(
        &mut obj,
        dicom_core::Tag(0x0019, 0x0010),
        VR::LO,
        "SIEMENS MR HEADER",
    );
    obj.put(DataElement::new(
        dicom_core::Tag(0x0019, 0x100A),
        VR::US,
        PrimitiveValue::from(n as u16),
    ));
    text(
        &mut obj,
        dicom_core::Tag(0x0029, 0x0010),
        VR::LO,
        "SIEMENS CSA HEADER",
    );
    let normal = spec.normal();
    let sign = if against { -1.0 } else { 1.0 };
    let csa = csa_header(&[
        ("NumberOfImagesInMosaic", vec![n.to_string()]),
        (
            "SliceNormalVector",
            normal.iter().map(|v| format!("{:.8}", sign * v)).collect(),
        ),
    ]);
    obj.put(DataElement::new(
        dicom_core::Tag(0x0029, 0x1010),
        VR::OB,
        PrimitiveValue::U8(csa.into()),
    ));
    let words: Vec<u16> = words.iter().map(|&v| v as u16).collect();
    obj.put(DataElement::new(
        tags::PIXEL_DATA,
        VR::OW,
        PrimitiveValue::U16(words.into()),
    ));
    let path = dir.join("mosaic.dcm");
    write(obj, spec.encoding, &path);
    path
}

/// A DICOMDIR in `dir` naming `files` (which must lie under `dir`).
pub fn write_dicomdir(dir: &Path, files: &[PathBuf]) -> PathBuf {
    let records = files
        .iter()
        .map(|f| {
            let rel = f.strip_prefix(dir).unwrap();
            let parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            let mut r = InMemDicomObject::new_empty();
            text(&mut r, tags::DIRECTORY_RECORD_TYPE, VR::CS, "IMAGE");
            r.put(DataElement::new(
                tags::REFERENCED_FILE_ID,
                VR::CS,
                PrimitiveValue::Strs(parts.into()),
            ));
            r
        })
        .collect();
    let mut obj = InMemDicomObject::new_empty();
    text(
        &mut obj,
        tags::SOP_CLASS_UID,
        VR::UI,
        "1.2.840.10008.1.3.10",
    );
    text(
        &mut obj,
        tags::SOP_INSTANCE_UID,
        VR::UI,
        "1.2.826.0.1.3680043.2.1125.9.3",
    );
    sequence(&mut obj, tags::DIRECTORY_RECORD_SEQUENCE, records);
    let path = dir.join("DICOMDIR");
    write(obj, EXPLICIT_LE, &path);
    path
}

/// RLE Lossless (PS3.5 G): one segment per byte plane (most significant first), each row a
/// series of literal runs.
pub fn rle_encode(values: &[i32], rows: usize, cols: usize) -> Vec<u8> {
    let mut segments = Vec::new();
    for plane in [1usize, 0] {
        let mut seg = Vec::new();
        for row in values.chunks(cols).take(rows) {
            let bytes: Vec<u8> = row
                .iter()
                .map(|&v| (v as u16).to_be_bytes()[1 - plane])
                .collect();
            for run in bytes.chunks(128) {
                seg.push((run.len() - 1) as u8);
                seg.extend_from_slice(run);
            }
        }
        if seg.len() % 2 == 1 {
            seg.push(0x80); // a no-op run header pads to even length
        }
        segments.push(seg);
    }
    let mut out = vec![0u8; 64];
    out[0..4].copy_from_slice(&(segments.len() as u32).to_le_bytes());
    let mut offset = 64u32;
    for (s, seg) in segments.iter().enumerate() {
        out[4 + 4 * s..8 + 4 * s].copy_from_slice(&offset.to_le_bytes());
        offset += seg.len() as u32;
    }
    for seg in segments {
        out.extend_from_slice(&seg);
    }
    out
}

/// Bits written most significant first, with 0xFF byte stuffing.
struct BitWriter {
    out: Vec<u8>,
    acc: u32,
    n: u32,
}

impl BitWriter {
    fn put(&mut self, bits: u32, count: u32) {
        for b in (0..count).rev() {
            self.acc = (self.acc << 1) | ((bits >> b) & 1);
            self.n += 1;
            if self.n == 8 {
                let byte = self.acc as u8;
                self.out.push(byte);
                if byte == 0xFF {
                    self.out.push(0);
                }
                self.acc = 0;
                self.n = 0;
            }
        }
    }

    fn finish(mut self) -> Vec<u8> {
        while self.n != 0 {
            self.put(1, 1);
        }
        self.out
    }
}

/// JPEG Lossless, non-hierarchical, first-order prediction (process 14, selection value 1),
/// 16-bit precision, one component: the DICOM transfer syntax 1.2.840.10008.1.2.4.70.
/// Huffman table: the 17 difference categories, all with 5-bit codes.
pub fn jpeg_lossless_encode(values: &[i32], rows: usize, cols: usize) -> Vec<u8> {
    let mut out = vec![0xFF, 0xD8];
    // SOF3: precision 16, rows, cols, one component (id 1, 1x1 sampling, table 0).
    out.extend_from_slice(&[0xFF, 0xC3, 0, 11, 16]);
    out.extend_from_slice(&(rows as u16).to_be_bytes());
    out.extend_from_slice(&(cols as u16).to_be_bytes());
    out.extend_from_slice(&[1, 1, 0x11, 0]);
    // DHT: class 0, id 0; 17 codes of length 5.
    let mut dht = vec![0xFF, 0xC4, 0, 2 + 1 + 16 + 17, 0x00];
    let mut counts = [0u8; 16];
    counts[4] = 17;
    dht.extend_from_slice(&counts);
    dht.extend(0..17u8);
    out.extend_from_slice(&dht);
    // SOS: one component, table 0, predictor 1, Se 0, Ah/Al 0.
    out.extend_from_slice(&[0xFF, 0xDA, 0, 8, 1, 1, 0x00, 1, 0, 0]);
    let mut w = BitWriter {
        out: Vec::new(),
        acc: 0,
        n: 0,
    };
    let px = |r: usize, c: usize| values[r * cols + c] as u16 as i32;
    for r in 0..rows {
        for c in 0..cols {
            let predicted = match (r, c) {
                (0, 0) => 1 << 15,
                (0, _) => px(0, c - 1),
                (_, 0) => px(r - 1, 0),
                _ => px(r, c - 1),
            };
            // Modulo 2^16, as a value in -32767..=32768.
            let mut diff = (px(r, c) - predicted).rem_euclid(65536);
            if diff > 32768 {
                diff -= 65536;
            }
            let ssss = if diff == 0 {
                0
            } else {
                32 - (diff.unsigned_abs()).leading_zeros()
            };
            w.put(ssss, 5);
            if ssss > 0 && ssss < 16 {
                let extra = if diff > 0 {
                    diff
                } else {
                    diff - 1 + (1 << ssss)
                };
                w.put(extra as u32 & ((1 << ssss) - 1), ssss);
            }
        }
    }
    out.extend_from_slice(&w.finish());
    out.extend_from_slice(&[0xFF, 0xD9]);
    out
}
