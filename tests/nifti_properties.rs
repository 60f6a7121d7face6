//! Property tests of the loader: no input panics, every accepted file describes a volume that
//! fits it, and the orientation function is total.

use morphray::volume::nifti::orientation::{OrientationFields, resolve};
use morphray::volume::nifti::{
    ByteOrder, LoadOptions, RawHeader, Version, inflate_if_gzip, parse, parse_pair,
};
use morphray::volume::{AffineSource, Volume};
use proptest::prelude::*;

/// A small valid single file: header + voxels of the given datatype.
fn valid_file(
    version: Version,
    order: ByteOrder,
    datatype: i16,
    bitpix: i16,
    bytes_per_voxel: usize,
) -> Vec<u8> {
    let mut h = RawHeader {
        dim: [4, 3, 4, 2, 2, 1, 1, 1],
        datatype,
        bitpix,
        pixdim: [1.0, 0.9, 1.1, 2.0, 1.0, 0.0, 0.0, 0.0],
        qform_code: 1,
        sform_code: 1,
        quatern: [0.1, -0.2, 0.3],
        srow: [
            [0.9, 0.0, 0.0, -1.0],
            [0.0, 1.1, 0.0, -2.0],
            [0.0, 0.0, 2.0, -3.0],
        ],
        scl_slope: 1.5,
        ..RawHeader::default()
    };
    if version == Version::Nifti2 {
        h.magic = *b"n+2\0";
        h.vox_offset = 544.0;
    }
    let mut out = h.encode(version, order);
    let voxels = 3 * 4 * 2 * 2;
    out.extend((0..voxels * bytes_per_voxel).map(|i| (i * 37 % 251) as u8));
    out
}

/// Datatypes (code, bitpix, bytes per voxel) the mutations start from.
const TYPES: [(i16, i16, usize); 12] = [
    (2, 8, 1),
    (256, 8, 1),
    (4, 16, 2),
    (512, 16, 2),
    (8, 32, 4),
    (768, 32, 4),
    (16, 32, 4),
    (1024, 64, 8),
    (1280, 64, 8),
    (64, 64, 8),
    (128, 24, 3),
    (2304, 32, 4),
];

/// Byte positions of the fields most likely to matter, per version.
const NIFTI1_FIELDS: [usize; 22] = [
    0, 40, 42, 44, 46, 48, 70, 72, 76, 80, 84, 88, 108, 112, 116, 123, 252, 254, 256, 268, 280, 344,
];
const NIFTI2_FIELDS: [usize; 14] = [0, 4, 8, 12, 14, 16, 24, 104, 112, 168, 176, 344, 352, 400];

/// Interesting 4-byte and 8-byte patterns to write over a field.
fn special_values() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        Just(f32::NAN.to_le_bytes().to_vec()),
        Just(f32::INFINITY.to_le_bytes().to_vec()),
        Just((-1.0f32).to_le_bytes().to_vec()),
        Just(0.0f32.to_le_bytes().to_vec()),
        Just(3.0e38f32.to_le_bytes().to_vec()),
        Just(1e-45f32.to_le_bytes().to_vec()),
        Just(f64::NAN.to_le_bytes().to_vec()),
        Just(i64::MAX.to_le_bytes().to_vec()),
        Just(i64::MIN.to_le_bytes().to_vec()),
        Just((1i64 << 40).to_le_bytes().to_vec()),
        Just(i16::MAX.to_le_bytes().to_vec()),
        Just(i16::MIN.to_le_bytes().to_vec()),
        Just(vec![0xff, 0xff]),
        Just(vec![0, 0]),
        Just(vec![8, 0]),
        prop::collection::vec(any::<u8>(), 1..9),
    ]
}

#[derive(Debug, Clone)]
struct Mutation {
    field: usize,
    value: Vec<u8>,
    random_at: usize,
    random_byte: u8,
}

fn mutation() -> impl Strategy<Value = Mutation> {
    (0usize..64, special_values(), 0usize..700, any::<u8>()).prop_map(
        |(field, value, random_at, random_byte)| Mutation {
            field,
            value,
            random_at,
            random_byte,
        },
    )
}

fn apply(bytes: &mut [u8], version: Version, m: &Mutation) {
    let fields: &[usize] = if version == Version::Nifti2 {
        &NIFTI2_FIELDS
    } else {
        &NIFTI1_FIELDS
    };
    let at = fields[m.field % fields.len()];
    for (i, b) in m.value.iter().enumerate() {
        if let Some(slot) = bytes.get_mut(at + i) {
            *slot = *b;
        }
    }
    let n = bytes.len();
    if n > 0 {
        bytes[m.random_at % n] = m.random_byte;
    }
}

fn bytes_per_voxel(code: i16) -> usize {
    TYPES.iter().find(|t| t.0 == code).map_or(0, |t| t.2)
}

/// The invariants every accepted file must satisfy.
fn check_accepted(
    volume: &Volume,
    dims: &[usize],
    data_offset: usize,
    datatype: i16,
    frames: usize,
    data_len: usize,
) {
    let voxels: usize = volume.dims.iter().product();
    assert_eq!(volume.samples.len(), voxels, "samples must match the dims");
    assert_eq!(volume.voxel_count(), voxels);
    let file_voxels: usize = dims.iter().product();
    assert_eq!(
        voxels * frames,
        file_voxels,
        "frames x voxels per frame = all voxels"
    );
    let needed = data_offset + file_voxels * bytes_per_voxel(datatype);
    assert!(
        needed <= data_len,
        "accepted data ({needed} bytes incl. offset) must fit the file ({data_len})"
    );
    check_geometry(&volume.orientation.affine, volume.spacing_mm);
    assert!(volume.to_physical.slope.is_finite() && volume.to_physical.slope != 0.0);
    assert!(volume.to_physical.intercept.is_finite());
}

fn check_geometry(a: &[[f64; 4]; 4], spacing: [f64; 3]) {
    assert!(
        a.iter().flatten().all(|v| v.is_finite()),
        "affine must be finite: {a:?}"
    );
    assert_eq!(a[3], [0.0, 0.0, 0.0, 1.0]);
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    assert!(
        det.is_finite() && det != 0.0,
        "affine must be invertible: det {det}, {a:?}"
    );
    assert!(
        spacing.iter().all(|s| s.is_finite() && *s > 0.0),
        "spacing {spacing:?}"
    );
}

fn version_strategy() -> impl Strategy<Value = Version> {
    prop_oneof![Just(Version::Nifti1), Just(Version::Nifti2)]
}

fn order_strategy() -> impl Strategy<Value = ByteOrder> {
    prop_oneof![Just(ByteOrder::LittleEndian), Just(ByteOrder::BigEndian)]
}

/// 512 cases per property unless `PROPTEST_CASES` asks for more (longer fuzzing runs).
fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(512)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    /// (a) Arbitrary bytes, with and without a plausible sizeof_hdr, never panic.
    #[test]
    fn random_bytes_never_panic(mut bytes in prop::collection::vec(any::<u8>(), 0..1200), prefix in 0u8..5) {
        match prefix {
            0 => {}
            1 => bytes.splice(0..bytes.len().min(4), 348i32.to_le_bytes()).for_each(drop),
            2 => bytes.splice(0..bytes.len().min(4), 540i32.to_be_bytes()).for_each(drop),
            3 => bytes.splice(0..bytes.len().min(2), [0x1f, 0x8b]).for_each(drop),
            _ => bytes.splice(0..bytes.len().min(12), *b"\x1c\x02\0\0n+2\0\r\n\x1a\n").for_each(drop),
        }
        let _ = parse(bytes.clone(), "random", &LoadOptions::default());
        let _ = parse_pair(&bytes, bytes.clone(), "random", &LoadOptions { frame: 1, mean: false });
        let _ = inflate_if_gzip(bytes);
    }

    /// (a) + (b) Mutated valid headers with random data lengths never panic, and whatever loads
    /// describes a volume that fits the file.
    #[test]
    fn mutated_headers_never_panic_and_accepted_files_fit(
        version in version_strategy(),
        order in order_strategy(),
        type_index in 0usize..TYPES.len(),
        mutations in prop::collection::vec(mutation(), 0..6),
        resize in prop_oneof![Just(None), (0usize..2000).prop_map(Some)],
        frame in 0usize..3,
        gzip_it in any::<bool>(),
    ) {
        let (code, bitpix, bpv) = TYPES[type_index];
        let mut bytes = valid_file(version, order, code, bitpix, bpv);
        for m in &mutations {
            apply(&mut bytes, version, m);
        }
        if let Some(len) = resize {
            bytes.resize(len, 0xa5);
        }
        let data_len = bytes.len();
        let input = if gzip_it { morphray::volume::nifti::gzip::gzip_compress(&bytes).unwrap() } else { bytes };
        // The mean over the frames reads the same bytes: an error or a volume, never a panic.
        if let Ok(l) = parse(input.clone(), "mutated", &LoadOptions { frame, mean: true }) {
            prop_assert_eq!(l.volume.samples.len(), l.volume.voxel_count());
        }
        if let Ok(l) = parse(input, "mutated", &LoadOptions { frame, mean: false }) {
            check_accepted(&l.volume, &l.header.dims, l.header.data_offset, l.header.datatype.code(), l.header.frames, data_len);
            prop_assert!(l.header.frame_loaded < l.header.frames);
            prop_assert_eq!(l.header.gzip, gzip_it);
        }
    }

    /// Corrupting compressed bytes gives an error or a file, never a panic.
    #[test]
    fn corrupted_gzip_never_panics(at in any::<prop::sample::Index>(), byte in any::<u8>(), cut in any::<prop::sample::Index>()) {
        let plain = valid_file(Version::Nifti1, ByteOrder::LittleEndian, 4, 16, 2);
        let mut gz = morphray::volume::nifti::gzip::gzip_compress(&plain).unwrap();
        let i = at.index(gz.len());
        gz[i] = byte;
        let c = cut.index(gz.len() + 1);
        gz.truncate(c.max(1));
        let _ = parse(gz, "corrupt", &LoadOptions::default());
    }

    /// (c) The orientation function is total: any bit patterns give a finite invertible affine
    /// and a positive finite spacing, and the source follows the codes.
    #[test]
    fn orientation_is_total(
        bits in prop::collection::vec(any::<u32>(), 22),
        qform_code in -3i32..4,
        sform_code in -3i32..4,
        xyzt_units in any::<u8>(),
        use_specials in any::<bool>(),
    ) {
        let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, -0.0, 1.0, -1.0, 3.4e38, 1e-45, 1.000_000_1];
        let f: Vec<f64> = bits.iter().map(|&b| {
            let v = if use_specials && b % 3 == 0 { specials[(b / 3) as usize % specials.len()] } else { f32::from_bits(b) };
            f64::from(v)
        }).collect();
        let fields = OrientationFields {
            qform_code,
            sform_code,
            quatern: [f[0], f[1], f[2]],
            qoffset: [f[3], f[4], f[5]],
            pixdim: [f[6], f[7], f[8], f[9]],
            srow: [[f[10], f[11], f[12], f[13]], [f[14], f[15], f[16], f[17]], [f[18], f[19], f[20], f[21]]],
            xyzt_units: i32::from(xyzt_units),
        };
        let g = resolve(&fields);
        check_geometry(&g.orientation.affine, g.spacing_mm);
        match g.orientation.source {
            AffineSource::Sform => prop_assert!(sform_code > 0),
            AffineSource::Qform => prop_assert!(qform_code > 0),
            AffineSource::Pixdim => {}
            AffineSource::Synthetic | AffineSource::Dicom => {
                prop_assert!(false, "the NIfTI loader never reports {:?}", g.orientation.source)
            }
        }
        if sform_code <= 0 && qform_code <= 0 {
            prop_assert_eq!(g.orientation.source, AffineSource::Pixdim);
        }
        prop_assert!(g.warnings.iter().all(|w| !w.is_empty() && !w.contains('\n')));
    }
}
