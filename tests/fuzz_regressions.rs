//! The fuzz targets' seed corpora, and inputs the fuzzers found, run through the same invariants
//! the targets check (tools/fuzz/src/lib.rs, included below), on every `cargo test`.
//!
//! Seeds: crafted valid headers (NIfTI-1/-2, both byte orders, several datatypes, qform/sform,
//! extensions, 4-D, ANALYZE pairs), gzip streams (one and several members, empty members, zero
//! padding, optional header fields, truncated and corrupted ones) and orientation fields. Each is
//! asserted to do what it was made for, so a seed that silently stops loading is noticed.
//!
//! To (re)build the corpora for the fuzzers (tools/fuzz/README.md):
//! `MORPHRAY_FUZZ_SEEDS=tools/fuzz/corpus cargo test --test fuzz_regressions`
//! writes `tools/fuzz/corpus/{nifti_header,gzip,orientation}/seed-*`.

#[path = "../tools/fuzz/src/lib.rs"]
mod invariants;

use morphray::volume::nifti::gzip::inflate_within;
use morphray::volume::nifti::orientation::{OrientationFields, resolve};
use morphray::volume::nifti::{
    ByteOrder, LoadOptions, NiftiError, RawHeader, Version, parse, parse_pair,
};
use std::path::PathBuf;

// ---------------------------------------------------------------------------------------------
// Seeds

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut c = libdeflater::Compressor::new(libdeflater::CompressionLvl::default());
    let mut out = vec![0; c.gzip_compress_bound(bytes.len())];
    let n = c.gzip_compress(bytes, &mut out).unwrap();
    out.truncate(n);
    out
}

/// One member with the optional header fields (FEXTRA, FNAME, FCOMMENT, FHCRC) that libdeflate's
/// writer never sets, so the fuzzer starts with them present.
fn gzip_with_header_fields(bytes: &[u8]) -> Vec<u8> {
    let plain = gzip(bytes);
    let mut head = plain[..10].to_vec();
    head[3] = 0x04 | 0x08 | 0x10 | 0x02; // FEXTRA | FNAME | FCOMMENT | FHCRC
    head.extend([4, 0, b'm', b'r', 0, 0]); // XLEN = 4: one empty subfield "mr"
    head.extend(b"scan.nii\0");
    head.extend(b"fuzz seed\0");
    let crc = libdeflater::crc32(&head);
    head.extend(&(crc as u16).to_le_bytes());
    head.extend(&plain[10..]);
    head
}

/// A small single-file volume of `datatype` with dims 3x4x2(xframes), deterministic bytes.
fn nifti(version: Version, order: ByteOrder, datatype: i16, bitpix: i16, frames: i64) -> Vec<u8> {
    let bytes_per_voxel = (bitpix as usize).div_ceil(8);
    let mut h = RawHeader {
        dim: [if frames > 1 { 4 } else { 3 }, 3, 4, 2, frames, 1, 1, 1],
        datatype,
        bitpix,
        pixdim: [-1.0, 0.9, 1.1, 2.5, 1.0, 0.0, 0.0, 0.0],
        scl_slope: 1.5,
        scl_inter: -3.0,
        qform_code: 1,
        quatern: [0.1, -0.2, 0.3],
        qoffset: [-10.0, 12.0, 3.0],
        sform_code: 2,
        srow: [
            [0.9, 0.1, 0.0, -10.0],
            [0.0, 1.1, 0.0, 12.0],
            [0.0, 0.2, 2.5, 3.0],
        ],
        xyzt_units: 2 | 8,
        ..RawHeader::default()
    };
    if version == Version::Nifti2 {
        h.magic = *b"n+2\0";
        h.vox_offset = 544.0;
    }
    let mut out = h.encode(version, order);
    let n = 3 * 4 * 2 * frames as usize * bytes_per_voxel;
    out.extend((0..n).map(|i| (i * 37 % 251) as u8));
    out
}

/// One header extension (esize, ecode, payload) in the file's byte order.
fn extension(order: ByteOrder, code: i32, payload: usize) -> Vec<u8> {
    let esize = (8 + payload).div_ceil(16) as i32 * 16;
    let mut v = match order {
        ByteOrder::LittleEndian => [esize.to_le_bytes(), code.to_le_bytes()].concat(),
        ByteOrder::BigEndian => [esize.to_be_bytes(), code.to_be_bytes()].concat(),
    };
    v.resize(esize as usize, b'e');
    v
}

/// A NIfTI-1 file with two extensions before the voxels.
fn nifti_with_extensions(order: ByteOrder) -> Vec<u8> {
    let exts = [extension(order, 6, 20), extension(order, 4, 8)].concat();
    let h = RawHeader {
        dim: [3, 2, 2, 2, 1, 1, 1, 1],
        datatype: 4,
        bitpix: 16,
        vox_offset: (352 + exts.len()) as f64,
        extender: [1, 0, 0, 0],
        ..RawHeader::default()
    };
    let mut out = h.encode(Version::Nifti1, order);
    out.extend(exts);
    out.extend((0..16u8).map(|i| i * 11));
    out
}

/// An ANALYZE 7.5 header followed by its image, for the fuzz target's pair path.
fn analyze_pair() -> Vec<u8> {
    let h = RawHeader {
        dim: [3, 4, 3, 2, 1, 1, 1, 1],
        datatype: 4,
        bitpix: 16,
        vox_offset: 0.0,
        pixdim: [0.0, 1.0, 1.0, 3.0, 0.0, 0.0, 0.0, 0.0],
        magic: [0; 4],
        ..RawHeader::default()
    };
    let mut out = h.encode(Version::Analyze75, ByteOrder::BigEndian);
    out.extend((0..48u8).map(|i| i.wrapping_mul(5)));
    // A last byte of 0 makes the fuzz target split right after the header and load frame 0
    // (`split_point`); an image longer than the voxels is allowed.
    out.push(0);
    out
}

/// An `ni1` header whose image starts at byte 16 of the `.img`.
fn ni1_pair() -> Vec<u8> {
    let h = RawHeader {
        dim: [3, 2, 3, 2, 1, 1, 1, 1],
        datatype: 16,
        bitpix: 32,
        vox_offset: 16.0,
        magic: *b"ni1\0",
        ..RawHeader::default()
    };
    let mut out = h.encode(Version::Nifti1, ByteOrder::LittleEndian);
    out.extend([0u8; 16]);
    out.extend((0..12).flat_map(|i| (i as f32 * 0.5 - 1.0).to_le_bytes()));
    out.push(0); // see analyze_pair
    out
}

/// Seeds for `nifti_header`, each with whether `parse` must load it.
fn header_seeds() -> Vec<(&'static str, Vec<u8>, bool)> {
    use ByteOrder::{BigEndian as Be, LittleEndian as Le};
    use Version::{Nifti1 as N1, Nifti2 as N2};
    vec![
        ("n1-le-u8", nifti(N1, Le, 2, 8, 1), true),
        ("n1-be-i16", nifti(N1, Be, 4, 16, 1), true),
        ("n1-le-f32-4d", nifti(N1, Le, 16, 32, 3), true),
        ("n1-be-f64", nifti(N1, Be, 64, 64, 1), true),
        ("n1-le-i64", nifti(N1, Le, 1024, 64, 1), true),
        ("n1-le-rgb24", nifti(N1, Le, 128, 24, 1), true),
        ("n2-le-u16", nifti(N2, Le, 512, 16, 1), true),
        ("n2-be-i32", nifti(N2, Be, 8, 32, 1), true),
        ("n2-le-rgba32-4d", nifti(N2, Le, 2304, 32, 2), true),
        ("n1-le-ext", nifti_with_extensions(Le), true),
        ("n1-be-ext", nifti_with_extensions(Be), true),
        ("n1-gz", gzip(&nifti(N1, Le, 4, 16, 1)), true),
        (
            "n2-gz-fields",
            gzip_with_header_fields(&nifti(N2, Be, 16, 32, 1)),
            true,
        ),
        ("analyze-pair", analyze_pair(), false),
        ("ni1-pair", ni1_pair(), false),
    ]
}

/// Seeds for `gzip`, each with whether `inflate_within` (with the target's limit) must accept it.
fn gzip_seeds() -> Vec<(&'static str, Vec<u8>, bool)> {
    let file = nifti(Version::Nifti1, ByteOrder::LittleEndian, 4, 16, 2);
    let one = gzip(&file);
    let three: Vec<u8> = file.chunks(file.len().div_ceil(3)).flat_map(gzip).collect();
    let with_empty = [gzip(&file[..100]), gzip(&[]), gzip(&file[100..])].concat();
    let padded = [one.clone(), vec![0; 32]].concat();
    let mut corrupt = one.clone();
    let mid = corrupt.len() / 2;
    corrupt[mid] ^= 0x5a;
    let mut bad_crc = one.clone();
    let crc_at = bad_crc.len() - 8;
    bad_crc[crc_at] ^= 1;
    vec![
        ("one-member", one.clone(), true),
        ("three-members", three.clone(), true),
        ("empty-member-between", with_empty, true),
        ("zero-padded", padded, true),
        ("header-fields", gzip_with_header_fields(&file), true),
        ("run-of-zeros", gzip(&[0u8; 4096]), true),
        ("truncated", one[..one.len() - 5].to_vec(), false),
        (
            "truncated-second-member",
            three[..three.len() - 20].to_vec(),
            false,
        ),
        ("corrupt-byte", corrupt, false),
        ("bad-crc", bad_crc, false),
        ("trailing-garbage", [one, b"junk".to_vec()].concat(), false),
    ]
}

/// Orientation fields encoded as the `orientation` target reads them
/// (`invariants::orientation_fields`): a mode byte (odd = f64
/// fields, even = f32), then qform_code, sform_code, xyzt_units (i32 LE), then quatern, qoffset,
/// pixdim, srow.
fn orientation_bytes(f: &OrientationFields, wide: bool) -> Vec<u8> {
    let mut out = vec![u8::from(wide)];
    for v in [f.qform_code, f.sform_code, f.xyzt_units] {
        out.extend(v.to_le_bytes());
    }
    let floats = f
        .quatern
        .iter()
        .chain(&f.qoffset)
        .chain(&f.pixdim)
        .chain(f.srow.iter().flatten());
    for &v in floats {
        if wide {
            out.extend(v.to_le_bytes());
        } else {
            out.extend((v as f32).to_le_bytes());
        }
    }
    out
}

fn orientation_seeds() -> Vec<(&'static str, Vec<u8>)> {
    let base = OrientationFields {
        qform_code: 0,
        sform_code: 0,
        quatern: [0.0; 3],
        qoffset: [0.0; 3],
        pixdim: [1.0, 1.0, 1.0, 1.0],
        srow: [[0.0; 4]; 3],
        xyzt_units: 2,
    };
    let qform = OrientationFields {
        qform_code: 1,
        quatern: [0.1, -0.2, 0.3],
        qoffset: [-90.0, 126.0, -72.0],
        pixdim: [-1.0, 0.9, 1.1, 2.5],
        ..base
    };
    let sform = OrientationFields {
        sform_code: 4,
        srow: [
            [-0.9, 0.1, 0.0, 90.0],
            [0.0, 1.1, 0.3, -126.0],
            [0.05, 0.0, 2.5, -72.0],
        ],
        ..qform
    };
    let metres = OrientationFields {
        xyzt_units: 1,
        pixdim: [1.0, 0.001, 0.001, 0.002],
        ..qform
    };
    vec![
        ("pixdim-f32", orientation_bytes(&base, false)),
        ("qform-f32", orientation_bytes(&qform, false)),
        ("sform-f32", orientation_bytes(&sform, false)),
        ("sform-f64", orientation_bytes(&sform, true)),
        ("qform-metres-f64", orientation_bytes(&metres, true)),
    ]
}

/// Writes `seeds` to `$MORPHRAY_FUZZ_SEEDS/<target>/seed-<name>` when the variable is set.
fn write_seeds<'a>(target: &str, seeds: impl IntoIterator<Item = (&'a str, &'a [u8])>) {
    let Some(root) = std::env::var_os("MORPHRAY_FUZZ_SEEDS") else {
        return;
    };
    let dir = PathBuf::from(root).join(target);
    std::fs::create_dir_all(&dir).unwrap();
    for (name, bytes) in seeds {
        std::fs::write(dir.join(format!("seed-{name}")), bytes).unwrap();
    }
}

// ---------------------------------------------------------------------------------------------
// The targets' bodies, for seeds and regressions

/// What the `nifti_header` target does with one input (without the pair split, which depends on
/// the target's own rule; pairs are run by the seed test directly).
fn run_header(data: &[u8]) -> Result<(), NiftiError> {
    match parse(data.to_vec(), "fuzz.nii", &LoadOptions::default()) {
        Ok(loaded) => {
            invariants::check_loaded(&loaded);
            Ok(())
        }
        Err(e) => {
            invariants::check_error(&e);
            Err(e)
        }
    }
}

#[test]
fn header_seeds_load_or_fail_as_crafted() {
    let seeds = header_seeds();
    for (name, bytes, loads) in &seeds {
        let result = run_header(bytes);
        assert_eq!(result.is_ok(), *loads, "{name}: {result:?}");
        if !loads {
            // The pair seeds: header then image, split where the fuzz target splits them.
            let (hdr, img) = bytes.split_at(invariants::split_point(bytes));
            let l = parse_pair(hdr, img.to_vec(), "seed.hdr", &LoadOptions::default())
                .unwrap_or_else(|e| panic!("{name} as a pair: {e}"));
            invariants::check_loaded(&l);
        }
    }
    write_seeds(
        "nifti_header",
        seeds.iter().map(|(n, b, _)| (*n, b.as_slice())),
    );
}

#[test]
fn gzip_seeds_inflate_or_fail_as_crafted() {
    let seeds = gzip_seeds();
    for (name, bytes, inflates) in &seeds {
        match inflate_within(bytes.clone(), invariants::gzip_limit(bytes)) {
            Ok((out, members)) => {
                assert!(*inflates, "{name} inflated to {} bytes", out.len());
                assert!(members >= 1, "{name}");
            }
            Err(e) => {
                assert!(!inflates, "{name}: {e}");
                invariants::check_error(&e);
            }
        }
    }
    write_seeds("gzip", seeds.iter().map(|(n, b, _)| (*n, b.as_slice())));
}

/// Seeds for `input_path`: every header seed with a last byte appended that picks each layout
/// (`.nii`, `.nii.gz`, pair by `.hdr`, pair by `.IMG`; `invariants::input_files`), run through
/// the target's body. Single files load as single files, pairs as pairs.
#[test]
fn input_path_seeds_load_as_crafted() {
    let dir = std::env::temp_dir().join(format!("morphray-fuzz-seeds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut seeds = Vec::new();
    for (name, bytes, single) in header_seeds() {
        for (layout, last) in [("nii", 0u8), ("niigz", 4), ("hdr", 8), ("img", 12)] {
            let mut data = bytes.clone();
            data.push(last);
            let gz = bytes.starts_with(&[0x1f, 0x8b]);
            let result = invariants::run_input_path(&dir, &data);
            // A pair split of a gzip'd single file, or a single file holding a pair, cannot
            // load; the gzip seeds with a non-zero byte appended have trailing garbage.
            let pair = last >= 8;
            let expect = if gz {
                last == 0 && !pair
            } else {
                single != pair
            };
            assert_eq!(
                result.is_ok(),
                expect,
                "{name}/{layout}: {:?}",
                result.err()
            );
            seeds.push((format!("{name}-{layout}"), data));
        }
    }
    // A small bomb: a whole file, then 70,000 zeros (past the 64 KiB slack), as `.nii.gz`.
    let mut file = nifti(Version::Nifti1, ByteOrder::LittleEndian, 4, 16, 1);
    file.extend(vec![0u8; 70_000]);
    let mut bomb = gzip(&file);
    bomb.push(0);
    let e = invariants::run_input_path(&dir, &bomb).unwrap_err();
    assert!(matches!(e, NiftiError::GzipTooLarge { .. }), "{e}");
    seeds.push(("bomb-niigz".into(), bomb));
    std::fs::remove_dir_all(&dir).unwrap();
    write_seeds(
        "input_path",
        seeds.iter().map(|(n, b)| (n.as_str(), b.as_slice())),
    );
}

#[test]
fn orientation_seeds_round_trip_and_resolve() {
    let seeds = orientation_seeds();
    for (name, bytes) in &seeds {
        let wide = bytes[0] & 1 == 1;
        let f = invariants::orientation_fields(bytes);
        assert_eq!(orientation_bytes(&f, wide), *bytes, "{name}");
        invariants::check_geometry(&resolve(&f));
    }
    write_seeds("orientation", seeds.iter().map(|(n, b)| (*n, b.as_slice())));
}

// ---------------------------------------------------------------------------------------------
// Inputs the fuzzers found (tools/fuzz/README.md), kept under tests/data/fuzz/

/// nifti_header: a NIfTI-2 file with pixdim (1.4e-309, 1, 8e-320): positive and finite, but
/// the pixdim diagonal's determinant underflowed to 0, so the loader returned a singular affine
/// (its totality promise broken; the derivative path could not invert it). Now sizes outside
/// [1e-30, 1e30] mm are repaired to 1 mm with a warning.
#[test]
fn subnormal_nifti2_pixdim_is_repaired_not_kept() {
    let bytes = include_bytes!("data/fuzz/nifti_header-subnormal-pixdim.nii");
    let l = parse(bytes.to_vec(), "fuzz.nii", &LoadOptions::default()).unwrap();
    invariants::check_loaded(&l);
    assert_eq!(l.header.version, Version::Nifti2);
    assert!(
        l.volume
            .warnings
            .iter()
            .any(|w| w.contains("outside the usable range")),
        "{:?}",
        l.volume.warnings
    );
    assert!(
        l.volume
            .spacing_mm
            .iter()
            .all(|s| (1e-30..=1e30).contains(s))
    );
}

/// orientation: f64 pixdim (5.5e-315, 3.8e-7, 2.1e-302) with qform and sform codes set but
/// neither usable: the pixdim fallback was singular in f64, as above.
#[test]
fn tiny_f64_pixdim_gives_an_invertible_fallback() {
    let bytes = include_bytes!("data/fuzz/orientation-tiny-pixdim.bin");
    let f = invariants::orientation_fields(bytes);
    let g = resolve(&f);
    invariants::check_geometry(&g);
    // The usable size (3.8e-7 mm) is kept; the two outside the range become 1 mm.
    assert_eq!(g.spacing_mm[1], f.pixdim[2]);
    assert_eq!((g.spacing_mm[0], g.spacing_mm[2]), (1.0, 1.0));
}

/// gzip: not a loader bug but a policy the differential oracle had to learn. A member with
/// FHCRC set whose header CRC16 does not match its header: libdeflate (and so the loader) skips
/// the header CRC, flate2's gzip reader rejects it. The data CRC-32 and ISIZE still protect the
/// voxels, so the loader accepts it; this pins that choice.
#[test]
fn gzip_member_with_a_wrong_header_crc16_is_accepted() {
    let bytes = include_bytes!("data/fuzz/gzip-bad-header-crc16.gz").to_vec();
    assert_eq!(bytes[3] & 0x02, 0x02, "FHCRC is set");
    let (out, members) = inflate_within(bytes.clone(), invariants::gzip_limit(&bytes)).unwrap();
    assert_eq!(members, 1);
    assert!(!out.is_empty());
}

/// nifti_header: a NIfTI-2 sform whose third row is subnormal (2e-317): the 3x3 part passed the
/// loader's relative determinant test, but 1/det overflows, so the affine had no f64 inverse.
/// Now a form with a column length outside [1e-30, 1e30] mm is skipped with a warning (here
/// the qform is used instead).
#[test]
fn subnormal_sform_row_is_skipped() {
    let bytes = include_bytes!("data/fuzz/nifti_header-subnormal-sform.nii");
    let l = parse(bytes.to_vec(), "fuzz.nii", &LoadOptions::default()).unwrap();
    invariants::check_loaded(&l);
    assert!(l.header.sform_code > 0);
    assert_ne!(
        l.volume.orientation.source,
        morphray::volume::AffineSource::Sform
    );
    assert!(
        l.volume.warnings.iter().any(|w| w.contains("sform")),
        "{:?}",
        l.volume.warnings
    );
}

/// nifti_header (pair path): an ANALYZE float64 image with a voxel at -1.797e308, within half an
/// f32 ulp of f64's range. convert.rs stores f64 data as f32 times a power-of-two scale; the
/// f32 rounding moved the stored value past the voxel, and its physical value (stored * scale)
/// became -inf. Now such a value is stored one f32 step toward zero, and the reach handed to
/// the scaling check is measured on the f32 values actually stored.
#[test]
fn float64_voxel_at_the_edge_of_f64_stays_finite() {
    let data = include_bytes!("data/fuzz/nifti_header-float64-near-max-pair.bin");
    let (hdr, img) = data.split_at(invariants::split_point(data));
    let frame = usize::from(data[data.len() - 1] >> 6);
    let l = parse_pair(
        hdr,
        img.to_vec(),
        "fuzz.hdr",
        &LoadOptions { frame, mean: false },
    )
    .unwrap();
    invariants::check_loaded(&l);
    let physical: Vec<f64> = (0..l.volume.samples.len())
        .map(|i| l.volume.to_physical.apply(l.volume.samples.get(i)))
        .filter(|p| !p.is_nan())
        .collect();
    assert!(
        physical.iter().any(|&p| p < -1.7e308) && physical.iter().all(|p| p.is_finite()),
        "{physical:?}"
    );
}
