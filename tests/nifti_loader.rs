//! The loader contract (`volume::nifti`), one crafted file per point, each with its documented
//! outcome.
//!
//! Files are built in memory by a small builder on top of `RawHeader::encode`. Because encode
//! and decode share the same field table, `header_field_offsets_match_the_standard` checks the
//! encoder byte-for-byte against the offsets printed in the NIfTI-1/-2 standards, and three files
//! written by nibabel 5.4.2 (embedded as hex) check decoding against an independent writer.

use morphray::volume::nifti::{
    ByteOrder, Datatype, Extension, LoadOptions, LoadedNifti, NiftiError, RawHeader, Storage,
    Version, inflate_if_gzip, load_path, parse, parse_pair, write_nifti1,
};
use morphray::volume::stats::intensity_stats;
use morphray::volume::{AffineSource, SampleKind};
use std::path::PathBuf;

// ---------------------------------------------------------------------------------------------
// Builder

/// Voxel values in their file datatype; encoded in the file's byte order at build time.
#[derive(Clone, Debug)]
enum Data {
    U8(Vec<u8>),
    I8(Vec<i8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
    I64(Vec<i64>),
    U64(Vec<u64>),
    F32(Vec<f32>),
    F64(Vec<f64>),
    Raw(Vec<u8>),
}

impl Data {
    fn datatype(&self) -> Datatype {
        match self {
            Data::U8(_) | Data::Raw(_) => Datatype::Uint8,
            Data::I8(_) => Datatype::Int8,
            Data::I16(_) => Datatype::Int16,
            Data::U16(_) => Datatype::Uint16,
            Data::I32(_) => Datatype::Int32,
            Data::U32(_) => Datatype::Uint32,
            Data::I64(_) => Datatype::Int64,
            Data::U64(_) => Datatype::Uint64,
            Data::F32(_) => Datatype::Float32,
            Data::F64(_) => Datatype::Float64,
        }
    }

    fn encode(&self, order: ByteOrder) -> Vec<u8> {
        let big = order == ByteOrder::BigEndian;
        macro_rules! enc {
            ($v:expr) => {
                $v.iter()
                    .flat_map(|x| {
                        if big {
                            x.to_be_bytes().to_vec()
                        } else {
                            x.to_le_bytes().to_vec()
                        }
                    })
                    .collect()
            };
        }
        match self {
            Data::U8(v) | Data::Raw(v) => v.clone(),
            Data::I8(v) => enc!(v),
            Data::I16(v) => enc!(v),
            Data::U16(v) => enc!(v),
            Data::I32(v) => enc!(v),
            Data::U32(v) => enc!(v),
            Data::I64(v) => enc!(v),
            Data::U64(v) => enc!(v),
            Data::F32(v) => enc!(v),
            Data::F64(v) => enc!(v),
        }
    }
}

/// A crafted file: header fields, version, byte order, extension bytes and voxel data.
#[derive(Clone, Debug)]
struct File {
    h: RawHeader,
    version: Version,
    order: ByteOrder,
    ext: Vec<u8>,
    data: Data,
}

impl File {
    /// A NIfTI-1 single file with the given dims (dim[0] = dims.len()) and data.
    fn new(dims: &[i64], data: Data) -> File {
        let mut dim = [1i64; 8];
        dim[0] = dims.len() as i64;
        dim[1..=dims.len()].copy_from_slice(dims);
        let dt = data.datatype();
        let h = RawHeader {
            dim,
            datatype: dt.code(),
            bitpix: dt.bitpix(),
            ..RawHeader::default()
        };
        File {
            h,
            version: Version::Nifti1,
            order: ByteOrder::LittleEndian,
            ext: Vec::new(),
            data,
        }
    }

    fn nifti2(mut self) -> File {
        self.version = Version::Nifti2;
        self.h.magic = *b"n+2\0";
        self.h.vox_offset = 544.0;
        self
    }

    fn big(mut self) -> File {
        self.order = ByteOrder::BigEndian;
        self
    }

    fn with(mut self, f: impl FnOnce(&mut RawHeader)) -> File {
        f(&mut self.h);
        self
    }

    /// Sets the datatype code (and the matching bitpix when the code is known).
    fn datatype(mut self, code: i16) -> File {
        self.h.datatype = code;
        if let Some(dt) = Datatype::from_code(code) {
            self.h.bitpix = dt.bitpix();
        }
        self
    }

    /// Header, extension bytes, zero padding up to vox_offset, then the voxels.
    fn bytes(&self) -> Vec<u8> {
        let mut out = self.h.encode(self.version, self.order);
        out.extend_from_slice(&self.ext);
        let off = self.h.vox_offset;
        if off.is_finite() && off > out.len() as f64 && off < 1e6 {
            out.resize(off as usize, 0);
        }
        out.extend(self.data.encode(self.order));
        out
    }
}

fn load(bytes: Vec<u8>) -> Result<LoadedNifti, NiftiError> {
    parse(bytes, "case.nii", &LoadOptions::default())
}

fn stored(l: &LoadedNifti) -> Vec<f64> {
    l.volume.samples.to_f64_vec()
}

fn physical(l: &LoadedNifti) -> Vec<f64> {
    stored(l)
        .iter()
        .map(|&s| l.volume.to_physical.apply(s))
        .collect()
}

fn warned(l: &LoadedNifti, needle: &str) -> bool {
    l.volume.warnings.iter().any(|w| w.contains(needle))
}

fn assert_affine(actual: &[[f64; 4]; 4], expected: &[[f64; 4]; 4], tol: f64) {
    for r in 0..4 {
        for c in 0..4 {
            assert!(
                (actual[r][c] - expected[r][c]).abs() <= tol,
                "affine[{r}][{c}] = {} but expected {} (tol {tol})\nactual {actual:?}",
                actual[r][c],
                expected[r][c]
            );
        }
    }
}

fn diag(s: [f64; 3]) -> [[f64; 4]; 4] {
    [
        [s[0], 0.0, 0.0, 0.0],
        [0.0, s[1], 0.0, 0.0],
        [0.0, 0.0, s[2], 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut c = libdeflater::Compressor::new(libdeflater::CompressionLvl::default());
    let mut out = vec![0; c.gzip_compress_bound(bytes.len())];
    let n = c.gzip_compress(bytes, &mut out).unwrap();
    out.truncate(n);
    out
}

fn ramp_i16(n: usize) -> Vec<i16> {
    (0..n as i16).map(|v| v * 3 - 7).collect()
}

/// A unique empty directory under the system temp dir.
fn temp_dir(tag: &str) -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let dir = std::env::temp_dir().join(format!(
        "morphray-nifti-{tag}-{}-{nanos}-{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

// ---------------------------------------------------------------------------------------------
// The table

/// What a crafted file must do.
enum Expect {
    /// Loads; the closure checks values, geometry and warnings.
    Loads(Box<dyn Fn(&LoadedNifti)>),
    /// Fails; the closure checks the error variant and its message.
    Fails(Box<dyn Fn(&NiftiError)>),
}

struct Case {
    name: &'static str,
    bytes: Vec<u8>,
    opts: LoadOptions,
    expect: Expect,
}

fn loads(name: &'static str, file: &File, check: impl Fn(&LoadedNifti) + 'static) -> Case {
    Case {
        name,
        bytes: file.bytes(),
        opts: LoadOptions::default(),
        expect: Expect::Loads(Box::new(check)),
    }
}

fn fails(name: &'static str, bytes: Vec<u8>, check: impl Fn(&NiftiError) + 'static) -> Case {
    Case {
        name,
        bytes,
        opts: LoadOptions::default(),
        expect: Expect::Fails(Box::new(check)),
    }
}

fn base_i16() -> File {
    File::new(&[3, 4, 5], Data::I16(ramp_i16(60)))
        .with(|h| h.pixdim[1..4].copy_from_slice(&[0.5, 1.5, 2.5]))
}

/// Checks the ramp_i16 data, its dims and pixdim geometry, and that nothing was repaired.
fn clean_i16(l: &LoadedNifti) {
    assert_eq!(l.volume.dims, [3, 4, 5]);
    assert_eq!(l.volume.samples.kind(), SampleKind::I16);
    assert_eq!(
        stored(l),
        ramp_i16(60)
            .iter()
            .map(|&v| f64::from(v))
            .collect::<Vec<_>>()
    );
    assert_eq!(l.volume.to_physical.slope, 1.0);
    assert_eq!(l.volume.to_physical.intercept, 0.0);
    assert_eq!(l.volume.spacing_mm, [0.5, 1.5, 2.5]);
    assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
    assert_affine(&l.volume.orientation.affine, &diag([0.5, 1.5, 2.5]), 0.0);
    assert!(
        l.volume.warnings.is_empty(),
        "unexpected warnings {:?}",
        l.volume.warnings
    );
    assert_eq!(l.volume.name, "case.nii");
}

fn multi_member_gzip(bytes: &[u8], parts: usize) -> Vec<u8> {
    let chunk = bytes.len().div_ceil(parts);
    bytes.chunks(chunk).flat_map(gzip).collect()
}

fn cases() -> Vec<Case> {
    let mut t = Vec::new();

    // --- versions and byte orders (points 2) ---
    t.push(loads("nifti1 little-endian int16", &base_i16(), |l| {
        clean_i16(l);
        assert_eq!(l.header.version, Version::Nifti1);
        assert_eq!(l.header.byte_order, ByteOrder::LittleEndian);
        assert_eq!(l.header.datatype.name(), "int16");
        assert_eq!(l.header.dims, vec![3, 4, 5]);
        assert_eq!(
            (l.header.frames, l.header.frame_loaded, l.header.data_offset),
            (1, 0, 352)
        );
        assert!(!l.header.gzip);
    }));
    t.push(loads("nifti1 big-endian int16", &base_i16().big(), |l| {
        clean_i16(l);
        assert_eq!(l.header.byte_order, ByteOrder::BigEndian);
    }));
    t.push(loads(
        "nifti2 little-endian int16",
        &base_i16().nifti2(),
        |l| {
            clean_i16(l);
            assert_eq!(l.header.version, Version::Nifti2);
            assert_eq!(l.header.data_offset, 544);
        },
    ));
    t.push(loads(
        "nifti2 big-endian int16",
        &base_i16().nifti2().big(),
        |l| {
            clean_i16(l);
            assert_eq!(
                (l.header.version, l.header.byte_order),
                (Version::Nifti2, ByteOrder::BigEndian)
            );
        },
    ));
    t.push(fails(
        "ANALYZE header given to parse (voxels are in the .img)",
        base_i16().with(|h| h.magic = [0; 4]).bytes(),
        |e| {
            assert!(matches!(e, NiftiError::SeparateImageFile { .. }), "{e}");
            assert!(e.to_string().contains("ANALYZE 7.5"));
        },
    ));
    t.push(fails(
        "ni1 header given to parse",
        base_i16().with(|h| h.magic = *b"ni1\0").bytes(),
        |e| {
            assert!(matches!(e, NiftiError::SeparateImageFile { .. }), "{e}");
        },
    ));
    t.push(fails(
        "sizeof_hdr neither 348 nor 540",
        {
            let mut b = base_i16().bytes();
            b[0..4].copy_from_slice(&349i32.to_le_bytes());
            b
        },
        |e| {
            assert!(matches!(e, NiftiError::NotNifti { little: 349, .. }), "{e}");
            assert!(e.to_string().contains("348"));
        },
    ));
    t.push(fails(
        "header cut short",
        base_i16().bytes()[..200].to_vec(),
        |e| {
            assert!(
                matches!(
                    e,
                    NiftiError::TooShort {
                        len: 200,
                        needed: 348,
                        ..
                    }
                ),
                "{e}"
            );
        },
    ));
    t.push(fails(
        "nifti2 with a wrong magic",
        base_i16().nifti2().with(|h| h.magic = *b"n+1\0").bytes(),
        |e| {
            assert!(matches!(e, NiftiError::BadMagic { .. }), "{e}");
        },
    ));
    t.push(fails(
        "nifti2 EOL bytes altered by a text-mode transfer",
        {
            let mut b = base_i16().nifti2().bytes();
            b[8] = b'\n';
            b
        },
        |e| {
            assert!(matches!(e, NiftiError::Nifti2Eol { .. }), "{e}");
            assert!(e.to_string().contains("text-mode"));
        },
    ));

    // --- gzip (point 1) ---
    t.push(Case {
        name: "gzip, one member",
        bytes: gzip(&base_i16().bytes()),
        opts: LoadOptions::default(),
        expect: Expect::Loads(Box::new(|l| {
            clean_i16(l);
            assert!(l.header.gzip);
            assert_eq!(l.header.gzip_members, 1);
        })),
    });
    t.push(Case {
        name: "gzip, three members",
        bytes: multi_member_gzip(&base_i16().bytes(), 3),
        opts: LoadOptions::default(),
        expect: Expect::Loads(Box::new(|l| {
            clean_i16(l);
            assert_eq!(l.header.gzip_members, 3);
        })),
    });
    t.push(Case {
        name: "gzip with zero padding after the last member",
        bytes: {
            let mut b = gzip(&base_i16().bytes());
            b.extend([0u8; 100]);
            b
        },
        opts: LoadOptions::default(),
        expect: Expect::Loads(Box::new(clean_i16)),
    });
    t.push(fails(
        "gzip with trailing garbage",
        {
            let mut b = gzip(&base_i16().bytes());
            b.extend(b"garbage");
            b
        },
        |e| {
            assert!(
                matches!(e, NiftiError::GzipTrailingGarbage { len: 7, .. }),
                "{e}"
            )
        },
    ));
    t.push(fails(
        "gzip truncated",
        {
            let b = gzip(&base_i16().bytes());
            b[..b.len() - 10].to_vec()
        },
        |e| {
            assert!(
                matches!(
                    e,
                    NiftiError::GzipCorrupt {
                        member: 1,
                        offset: 0
                    }
                ),
                "{e}"
            );
            assert!(e.to_string().contains("corrupt or truncated"));
        },
    ));
    t.push(fails(
        "gzip truncated inside the second member",
        {
            let b = multi_member_gzip(&base_i16().bytes(), 2);
            b[..b.len() - 3].to_vec()
        },
        |e| {
            assert!(
                matches!(e, NiftiError::GzipCorrupt { member: 2, .. }),
                "{e}"
            )
        },
    ));
    t.push(fails(
        "gzip with a corrupt byte",
        {
            let mut b = gzip(&base_i16().bytes());
            let mid = b.len() / 2;
            b[mid] ^= 0x55;
            b[mid + 1] ^= 0xaa;
            b
        },
        |e| assert!(matches!(e, NiftiError::GzipCorrupt { .. }), "{e}"),
    ));
    t.push(fails("gzip magic only", vec![0x1f, 0x8b, 8], |e| {
        assert!(
            matches!(
                e,
                NiftiError::GzipCorrupt {
                    member: 1,
                    offset: 0
                }
            ),
            "{e}"
        )
    }));

    // --- datatypes (point 3) ---
    t.push(loads(
        "uint8",
        &File::new(&[2, 2], Data::U8(vec![0, 1, 254, 255])),
        |l| {
            assert_eq!(l.volume.samples.kind(), SampleKind::U8);
            assert_eq!(stored(l), [0.0, 1.0, 254.0, 255.0]);
            assert_eq!(l.volume.dims, [2, 2, 1]);
        },
    ));
    t.push(loads(
        "int8",
        &File::new(&[4], Data::I8(vec![-128, -1, 0, 127])),
        |l| {
            assert_eq!(l.volume.samples.kind(), SampleKind::I8);
            assert_eq!(stored(l), [-128.0, -1.0, 0.0, 127.0]);
            assert_eq!(l.volume.dims, [4, 1, 1]);
        },
    ));
    t.push(loads(
        "uint16 big-endian",
        &File::new(&[3], Data::U16(vec![0, 258, 65535])).big(),
        |l| {
            assert_eq!(l.volume.samples.kind(), SampleKind::U16);
            assert_eq!(stored(l), [0.0, 258.0, 65535.0]);
            assert_eq!(
                l.volume.samples.as_bytes(),
                &[0, 0, 2, 1, 255, 255],
                "stored little-endian"
            );
        },
    ));
    t.push(loads(
        "float32 big-endian",
        &File::new(&[3], Data::F32(vec![-1.5, 0.25, 3.0e38])).big(),
        |l| {
            assert_eq!(l.volume.samples.kind(), SampleKind::F32);
            assert_eq!(stored(l), [-1.5, 0.25, f64::from(3.0e38f32)]);
        },
    ));
    t.push(loads(
        "int32 near 2e9: an offset keeps unit steps",
        &File::new(
            &[3],
            Data::I32(vec![2_000_000_000, 2_000_000_001, 2_000_000_003]),
        ),
        |l| {
            assert_eq!(l.volume.samples.kind(), SampleKind::F32);
            assert_eq!(
                physical(l),
                [2_000_000_000.0, 2_000_000_001.0, 2_000_000_003.0]
            );
            // Without the offset, f32 (24-bit mantissa) would store all three as 2e9.
            assert_eq!(l.volume.to_physical.intercept, 2_000_000_001.0);
            assert_eq!(stored(l), [-1.0, 0.0, 2.0]);
        },
    ));
    t.push(loads(
        "int32 small range: no offset needed",
        &File::new(&[3], Data::I32(vec![-5, 0, 16_000_000])).big(),
        |l| {
            assert_eq!(stored(l), [-5.0, 0.0, 16_000_000.0]);
            assert_eq!(l.volume.to_physical, morphray::volume::LinearMap::IDENTITY);
        },
    ));
    t.push(loads(
        "uint32 at the top of its range",
        &File::new(&[2], Data::U32(vec![u32::MAX, u32::MAX - 9])),
        |l| {
            assert_eq!(physical(l), [f64::from(u32::MAX), f64::from(u32::MAX - 9)]);
        },
    ));
    t.push(loads(
        "int64 near 2^62: stored differences exact",
        &File::new(&[3], Data::I64(vec![1 << 62, (1 << 62) + 1, (1 << 62) + 7])).big(),
        |l| {
            let s = stored(l);
            assert_eq!([s[1] - s[0], s[2] - s[0]], [1.0, 7.0]);
            let expected = 2f64.powi(62);
            assert!(
                (l.volume.to_physical.intercept - expected).abs() <= 8.0,
                "{:?}",
                l.volume.to_physical
            );
        },
    ));
    t.push(loads(
        "uint64 at u64::MAX",
        &File::new(&[2], Data::U64(vec![u64::MAX, u64::MAX - 5])),
        |l| {
            let s = stored(l);
            assert_eq!(s[0] - s[1], 5.0);
            assert!((physical(l)[0] - u64::MAX as f64).abs() < 1e5);
        },
    ));
    t.push(loads(
        "float64 1e30 + tiny range stays resolvable",
        &File::new(
            &[12],
            Data::F64((0..12).map(|k| 1e30 + f64::from(k) * 1e15).collect()),
        ),
        |l| {
            assert_eq!(l.volume.samples.kind(), SampleKind::F32);
            let p = physical(l);
            for (k, v) in p.iter().enumerate() {
                let x = 1e30 + k as f64 * 1e15;
                assert!((v - x).abs() < 0.2e15, "voxel {k}: {v} vs {x}");
            }
            let s = stored(l);
            assert!(
                s.windows(2).all(|w| w[1] > w[0]),
                "stored values must stay distinct and ordered: {s:?}"
            );
            // What a plain f32 cast would do: every value collapses.
            assert_eq!((1e30f64 as f32), ((1e30 + 11e15) as f32));
        },
    ));
    t.push(loads(
        "float64 near f64::MAX is scaled into f32 range",
        &File::new(&[3], Data::F64(vec![-1.5e308, 0.0, 1.7e308])),
        |l| {
            let s = stored(l);
            assert!(s.iter().all(|v| v.is_finite()), "{s:?}");
            let p = physical(l);
            assert!(
                (p[0] / -1.5e308 - 1.0).abs() < 1e-6
                    && p[1] == 0.0
                    && (p[2] / 1.7e308 - 1.0).abs() < 1e-6,
                "{p:?}"
            );
        },
    ));
    t.push(loads(
        "RGB24 becomes luminance, never scaled",
        &File::new(
            &[4],
            Data::Raw(vec![255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30]),
        )
        .datatype(128)
        .with(|h| h.scl_slope = 2.0),
        |l| {
            assert_eq!(l.volume.samples.kind(), SampleKind::F32);
            let expected = [
                54.213,
                182.376,
                18.411,
                0.2126 * 10.0 + 0.7152 * 20.0 + 0.0722 * 30.0,
            ];
            for (v, e) in stored(l).iter().zip(expected) {
                assert!((v - e).abs() < 1e-3, "{v} vs {e}");
            }
            assert_eq!(l.volume.to_physical, morphray::volume::LinearMap::IDENTITY);
            assert!(warned(l, "luminance 0.2126 R + 0.7152 G + 0.0722 B"));
            assert!(warned(l, "not applied to rgb24"));
        },
    ));
    t.push(loads(
        "RGBA32 ignores alpha",
        &File::new(&[2], Data::Raw(vec![0, 255, 0, 7, 0, 0, 0, 255])).datatype(2304),
        |l| {
            let s = stored(l);
            assert!((s[0] - 182.376).abs() < 1e-3 && s[1] == 0.0, "{s:?}");
            assert!(warned(l, "rgba32"));
        },
    ));
    for (code, name) in [
        (32, "complex64"),
        (1792, "complex128"),
        (2048, "complex256"),
        (1536, "float128"),
        (1, "binary"),
    ] {
        t.push(fails(
            "unsupported datatype is named",
            File::new(&[2], Data::Raw(vec![0; 64]))
                .datatype(code)
                .bytes(),
            move |e| {
                assert!(matches!(e, NiftiError::UnsupportedDatatype { .. }), "{e}");
                assert!(
                    e.to_string().contains(name) && e.to_string().contains("not supported"),
                    "{e}"
                );
            },
        ));
    }
    t.push(fails(
        "unknown datatype code",
        File::new(&[2], Data::Raw(vec![0; 8])).datatype(3).bytes(),
        |e| assert!(matches!(e, NiftiError::UnknownDatatype { code: 3 }), "{e}"),
    ));
    t.push(loads(
        "bitpix inconsistent with datatype: warn, trust datatype",
        &File::new(&[3], Data::I16(vec![1, 2, 3])).with(|h| h.bitpix = 8),
        |l| {
            assert_eq!(stored(l), [1.0, 2.0, 3.0]);
            assert!(warned(l, "bitpix is 8 but datatype int16 has 16 bits"));
        },
    ));

    // --- scaling (point 5) ---
    t.push(loads(
        "scl_slope 2, scl_inter 10",
        &base_i16().with(|h| (h.scl_slope, h.scl_inter) = (2.0, 10.0)),
        |l| {
            assert_eq!(
                physical(l),
                ramp_i16(60)
                    .iter()
                    .map(|&v| f64::from(v) * 2.0 + 10.0)
                    .collect::<Vec<_>>()
            );
            assert!(l.volume.warnings.is_empty());
            assert_eq!((l.header.scl_slope, l.header.scl_inter), (2.0, 10.0));
        },
    ));
    t.push(loads(
        "scl_slope 0 means no scaling (scl_inter ignored too)",
        &base_i16().with(|h| (h.scl_slope, h.scl_inter) = (0.0, 50.0)),
        clean_i16,
    ));
    t.push(loads(
        "scl_slope NaN: no scaling, with a warning",
        &base_i16().with(|h| (h.scl_slope, h.scl_inter) = (f64::NAN, 5.0)),
        |l| {
            assert_eq!(l.volume.to_physical, morphray::volume::LinearMap::IDENTITY);
            assert!(warned(l, "scl_slope is NaN"));
            assert!(l.header.scl_slope.is_nan());
        },
    ));
    t.push(loads(
        "scl_slope infinite: no scaling",
        &base_i16().with(|h| h.scl_slope = f64::INFINITY),
        |l| {
            assert_eq!(l.volume.to_physical, morphray::volume::LinearMap::IDENTITY);
            assert!(warned(l, "scl_slope is inf"));
        },
    ));
    t.push(loads(
        "scl_inter NaN: ignored with a warning, slope kept",
        &base_i16().with(|h| (h.scl_slope, h.scl_inter) = (-0.5, f64::NAN)),
        |l| {
            assert_eq!(l.volume.to_physical.slope, -0.5);
            assert_eq!(l.volume.to_physical.intercept, 0.0);
            assert!(warned(l, "scl_inter is NaN"));
        },
    ));
    t.push(loads(
        "int32 with scaling composes offset and scl",
        &File::new(&[2], Data::I32(vec![100_000_000, 100_000_004]))
            .with(|h| (h.scl_slope, h.scl_inter) = (0.5, -1.0)),
        |l| {
            assert_eq!(physical(l), [49_999_999.0, 50_000_001.0]);
        },
    ));

    t.push(loads(
        "nifti2 scl_slope 1e306 on int16 would overflow f64: not applied, with a warning",
        &base_i16().nifti2().with(|h| h.scl_slope = 1e306),
        |l| {
            assert_eq!(l.volume.to_physical, morphray::volume::LinearMap::IDENTITY);
            assert!(warned(l, "outside the f64 range"));
        },
    ));
    t.push(loads(
        "nifti2 scl_slope 1e300 on int16 fits f64: applied",
        &base_i16().nifti2().with(|h| h.scl_slope = 1e300),
        |l| {
            assert_eq!(l.volume.to_physical.slope, 1e300);
            assert!(l.volume.warnings.is_empty());
        },
    ));
    t.push(loads(
        "nifti2 int32 offset times a huge scl_slope: scaling dropped, offset kept",
        &File::new(&[2], Data::I32(vec![2_000_000_000, 2_000_000_002]))
            .nifti2()
            .with(|h| h.scl_slope = -1e300),
        |l| {
            assert_eq!(physical(l), [2_000_000_000.0, 2_000_000_002.0]);
            assert!(warned(l, "outside the f64 range"));
        },
    ));

    // --- vox_offset and file length (point 3) ---
    t.push(loads(
        "vox_offset 0 in a .nii means 352",
        &base_i16().with(|h| h.vox_offset = 0.0),
        |l| {
            assert_eq!(
                stored(l),
                ramp_i16(60)
                    .iter()
                    .map(|&v| f64::from(v))
                    .collect::<Vec<_>>()
            );
            assert_eq!(l.header.data_offset, 352);
            assert_eq!(l.header.vox_offset, 0.0);
            assert!(warned(l, "vox_offset 0 is below 352"));
        },
    ));
    t.push(loads(
        "vox_offset 348 (< 352) means 352",
        &base_i16().with(|h| h.vox_offset = 348.0),
        |l| {
            assert_eq!(l.header.data_offset, 352);
            assert_eq!(stored(l)[0], -7.0);
            assert!(warned(l, "below 352"));
        },
    ));
    t.push(loads(
        "vox_offset 400: padding is skipped, not read as data",
        &base_i16().with(|h| h.vox_offset = 400.0),
        |l| {
            clean_i16(l);
            assert_eq!(l.header.data_offset, 400);
        },
    ));
    t.push(loads(
        "nifti2 vox_offset 0 means 544",
        &base_i16().nifti2().with(|h| h.vox_offset = 0.0),
        |l| {
            assert_eq!(l.header.data_offset, 544);
            assert_eq!(stored(l)[1], -4.0);
            assert!(warned(l, "below 544"));
        },
    ));
    t.push(fails(
        "vox_offset huge",
        base_i16().with(|h| h.vox_offset = 1e12).bytes(),
        |e| {
            assert!(
                matches!(
                    e,
                    NiftiError::TruncatedData {
                        offset: 999_999_995_904,
                        needed: 120,
                        ..
                    }
                ),
                "{e}"
            )
        },
    ));
    t.push(fails(
        "vox_offset not a whole number",
        base_i16().with(|h| h.vox_offset = 352.5).bytes(),
        |e| {
            assert!(matches!(e, NiftiError::BadVoxOffset { .. }), "{e}");
            assert!(e.to_string().contains("352.5"));
        },
    ));
    t.push(fails(
        "vox_offset negative",
        base_i16().with(|h| h.vox_offset = -16.0).bytes(),
        |e| assert!(matches!(e, NiftiError::BadVoxOffset { .. }), "{e}"),
    ));
    t.push(fails(
        "vox_offset NaN",
        base_i16().with(|h| h.vox_offset = f64::NAN).bytes(),
        |e| assert!(matches!(e, NiftiError::BadVoxOffset { .. }), "{e}"),
    ));
    t.push(fails("file shorter than its data", {
        let b = base_i16().bytes();
        b[..b.len() - 1].to_vec()
    }, |e| {
        assert!(matches!(e, NiftiError::TruncatedData { len: 471, needed: 120, offset: 352, .. }), "{e}");
        assert_eq!(e.to_string(), "file ends at byte 471, but the header promises 120 bytes of voxels starting at byte 352");
    }));

    // --- dims (point 3) ---
    t.push(fails(
        "dim[0] = 0",
        base_i16().with(|h| h.dim[0] = 0).bytes(),
        |e| {
            assert!(matches!(e, NiftiError::BadDimCount { dim0: 0 }), "{e}");
            assert!(e.to_string().contains("1 to 7"));
        },
    ));
    t.push(fails(
        "dim[0] = 8",
        base_i16().with(|h| h.dim[0] = 8).bytes(),
        |e| assert!(matches!(e, NiftiError::BadDimCount { dim0: 8 }), "{e}"),
    ));
    t.push(fails(
        "negative dim",
        base_i16().with(|h| h.dim[2] = -4).bytes(),
        |e| {
            assert!(
                matches!(e, NiftiError::BadDim { axis: 2, value: -4 }),
                "{e}"
            )
        },
    ));
    t.push(fails(
        "zero dim",
        base_i16().with(|h| h.dim[3] = 0).bytes(),
        |e| assert!(matches!(e, NiftiError::BadDim { axis: 3, value: 0 }), "{e}"),
    ));
    t.push(fails(
        "dims whose product overflows (NIfTI-2, 2^40 per axis)",
        base_i16()
            .nifti2()
            .with(|h| {
                h.dim[1] = 1 << 40;
                h.dim[2] = 1 << 40;
                h.dim[3] = 1 << 40;
            })
            .bytes(),
        |e| assert!(matches!(e, NiftiError::SizeOverflow { .. }), "{e}"),
    ));
    t.push(fails(
        "huge NIfTI-1 dims are checked against the file before any allocation",
        File::new(&[32767, 32767, 32767, 32767], Data::F64(vec![1.0])).bytes(),
        |e| assert!(matches!(e, NiftiError::TruncatedData { .. }), "{e}"),
    ));
    t.push(loads(
        "dims above dim[0] are ignored",
        &base_i16().with(|h| (h.dim[4], h.dim[5]) = (9, 9)),
        |l| {
            clean_i16(l);
            assert_eq!(l.header.frames, 1);
        },
    ));
    t.push(loads(
        "2-D image is a volume with k = 1 (its unused pixdim[3] = 0 is not a repair)",
        &File::new(&[3, 2], Data::U8(vec![1, 2, 3, 4, 5, 6])).with(|h| h.pixdim[3] = 0.0),
        |l| {
            assert!(l.volume.warnings.is_empty(), "{:?}", l.volume.warnings);
            assert_eq!(l.volume.dims, [3, 2, 1]);
            assert_eq!(l.volume.spacing_mm, [1.0, 1.0, 1.0]);
            assert_eq!(l.header.dims, vec![3, 2]);
        },
    ));

    // --- pixdim and units (point 3) ---
    t.push(loads(
        "pixdim 0, NaN and negative are repaired to 1 mm",
        &base_i16().with(|h| h.pixdim[1..4].copy_from_slice(&[0.0, f64::NAN, -2.0])),
        |l| {
            assert_eq!(l.volume.spacing_mm, [1.0, 1.0, 1.0]);
            assert!(warned(l, "pixdim[1] (voxel size along i) is 0"));
            assert!(warned(l, "pixdim[2] (voxel size along j) is NaN"));
            assert!(warned(l, "pixdim[3] (voxel size along k) is -2"));
            assert_affine(&l.volume.orientation.affine, &diag([1.0; 3]), 0.0);
        },
    ));
    t.push(loads(
        "xyzt_units metres: spacing and affine in mm",
        &base_i16().with(|h| {
            h.xyzt_units = 1;
            h.pixdim[1..4].copy_from_slice(&[0.001, 0.002, 0.004]);
        }),
        |l| {
            for (s, e) in l.volume.spacing_mm.iter().zip([1.0, 2.0, 4.0]) {
                assert!((s - e).abs() < 1e-6, "{s} vs {e}");
            }
        },
    ));
    t.push(loads(
        "xyzt_units microns",
        &base_i16().with(|h| {
            h.xyzt_units = 3;
            h.pixdim[1..4].copy_from_slice(&[500.0, 500.0, 1000.0]);
        }),
        |l| assert_eq!(l.volume.spacing_mm, [0.5, 0.5, 1.0]),
    ));
    t.push(loads(
        "xyzt_units unknown (0): mm, silently",
        &base_i16().with(|h| h.xyzt_units = 0),
        clean_i16,
    ));

    // --- orientation (point 7) ---
    let sform = [
        [2.0, 0.0, 0.0, 10.0],
        [0.0, 3.0, 0.0, 20.0],
        [0.0, 0.0, 4.0, 30.0],
    ];
    let oriented = move |f: File| {
        f.with(move |h| {
            h.pixdim[1..4].copy_from_slice(&[2.0, 3.0, 4.0]);
            h.srow = sform;
            h.qoffset = [10.0, 20.0, 30.0];
        })
    };
    let expected_sform = [sform[0], sform[1], sform[2], [0.0, 0.0, 0.0, 1.0]];
    t.push(loads(
        "sform wins over qform; agreeing forms give no warning",
        &oriented(base_i16()).with(|h| (h.sform_code, h.qform_code) = (2, 1)),
        move |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Sform);
            assert_affine(&l.volume.orientation.affine, &expected_sform, 0.0);
            assert!(l.volume.warnings.is_empty(), "{:?}", l.volume.warnings);
            assert_eq!((l.header.qform_code, l.header.sform_code), (1, 2));
        },
    ));
    t.push(loads(
        "qform used when sform_code is 0",
        &oriented(base_i16())
            .with(|h| (h.sform_code, h.qform_code, h.qoffset) = (0, 1, [-1.0, -2.0, -3.0])),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Qform);
            let mut e = diag([2.0, 3.0, 4.0]);
            (e[0][3], e[1][3], e[2][3]) = (-1.0, -2.0, -3.0);
            assert_affine(&l.volume.orientation.affine, &e, 1e-12);
        },
    ));
    t.push(loads(
        "pixdim diagonal when neither code is set",
        &oriented(base_i16()),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
            assert_affine(&l.volume.orientation.affine, &diag([2.0, 3.0, 4.0]), 0.0);
        },
    ));
    t.push(loads(
        "negative codes are not > 0",
        &oriented(base_i16()).with(|h| (h.sform_code, h.qform_code) = (-1, -3)),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
        },
    ));
    t.push(loads(
        "qform and sform disagree: warning, sform used",
        &oriented(base_i16()).with(|h| {
            (h.sform_code, h.qform_code) = (1, 1);
            h.qoffset = [10.0, 20.0, 35.0];
        }),
        move |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Sform);
            assert_affine(&l.volume.orientation.affine, &expected_sform, 0.0);
            assert!(
                warned(l, "qform and sform disagree"),
                "{:?}",
                l.volume.warnings
            );
        },
    ));
    t.push(loads(
        "non-finite sform falls back to the qform",
        &oriented(base_i16()).with(|h| {
            (h.sform_code, h.qform_code) = (1, 1);
            h.srow[1][2] = f64::INFINITY;
        }),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Qform);
            assert!(warned(l, "sform (srow_x/y/z) has non-finite entries"));
        },
    ));
    t.push(loads(
        "singular sform falls back to pixdim",
        &oriented(base_i16()).with(|h| {
            h.sform_code = 1;
            h.srow[2] = [0.0, 0.0, 0.0, 5.0];
        }),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
            assert!(warned(l, "singular"));
        },
    ));
    t.push(loads(
        "sform voxel size differing from pixdim is reported",
        &base_i16().with(|h| {
            h.sform_code = 1;
            h.srow = sform;
        }),
        |l| {
            assert_eq!(l.volume.spacing_mm, [0.5, 1.5, 2.5]);
            assert!(warned(l, "differs from pixdim"));
        },
    ));
    t.push(loads(
        "quaternion slightly beyond unit norm: a = 0, no warning",
        &base_i16().with(|h| {
            h.qform_code = 1;
            h.quatern = [1.000_000_1, 0.0, 0.0];
        }),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Qform);
            assert_affine(&l.volume.orientation.affine, &diag([0.5, -1.5, -2.5]), 1e-6);
            assert!(l.volume.warnings.is_empty(), "{:?}", l.volume.warnings);
        },
    ));
    t.push(loads(
        "quaternion clearly beyond unit norm: normalised with a warning",
        &base_i16().with(|h| {
            h.qform_code = 1;
            h.quatern = [1.0, 1.0, 0.0];
        }),
        |l| {
            // (b, c) = (1, 1) / sqrt 2, a = 0: swaps i and j, flips k.
            let e = [
                [0.0, 1.5, 0.0, 0.0],
                [0.5, 0.0, 0.0, 0.0],
                [0.0, 0.0, -2.5, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            ];
            assert_affine(&l.volume.orientation.affine, &e, 1e-12);
            assert!(warned(l, "normalised"));
        },
    ));
    t.push(loads(
        "non-finite quaternion falls back to pixdim",
        &base_i16().with(|h| {
            h.qform_code = 1;
            h.quatern = [f64::NAN, 0.0, 0.0];
        }),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
            assert!(warned(l, "quaternion"));
        },
    ));
    t.push(loads(
        "qfac 0 means 1",
        &base_i16().with(|h| (h.qform_code, h.pixdim[0]) = (1, 0.0)),
        |l| {
            assert_affine(&l.volume.orientation.affine, &diag([0.5, 1.5, 2.5]), 0.0);
        },
    ));
    t.push(loads(
        "qfac -1 flips k",
        &base_i16().with(|h| (h.qform_code, h.pixdim[0]) = (1, -1.0)),
        |l| {
            assert_affine(&l.volume.orientation.affine, &diag([0.5, 1.5, -2.5]), 0.0);
        },
    ));
    t.push(loads(
        "qfac NaN means 1, with a warning",
        &base_i16().with(|h| (h.qform_code, h.pixdim[0]) = (1, f64::NAN)),
        |l| {
            assert_affine(&l.volume.orientation.affine, &diag([0.5, 1.5, 2.5]), 0.0);
            assert!(warned(l, "qfac"));
        },
    ));

    // --- frames (point 8) ---
    let frames = File::new(
        &[2, 2, 1, 3],
        Data::I16((0..12).map(|v| (v / 4) * 100 + v % 4).collect()),
    );
    t.push(loads(
        "4-D: frame 0 by default, with a warning",
        &frames,
        |l| {
            assert_eq!(stored(l), [0.0, 1.0, 2.0, 3.0]);
            assert_eq!((l.header.frames, l.header.frame_loaded), (3, 0));
            assert!(warned(l, "4-D file with 3 frames: showing frame 0"));
            assert_eq!(l.header.dims, vec![2, 2, 1, 3]);
        },
    ));
    t.push(Case {
        name: "4-D: frame 2 selected",
        bytes: frames.bytes(),
        opts: LoadOptions {
            frame: 2,
            mean: false,
        },
        expect: Expect::Loads(Box::new(|l| {
            assert_eq!(stored(l), [200.0, 201.0, 202.0, 203.0]);
            assert_eq!(l.header.frame_loaded, 2);
            assert!(warned(l, "showing frame 2"));
        })),
    });
    t.push(Case {
        name: "4-D big-endian frame 1",
        bytes: frames.clone().big().bytes(),
        opts: LoadOptions {
            frame: 1,
            mean: false,
        },
        expect: Expect::Loads(Box::new(|l| {
            assert_eq!(stored(l), [100.0, 101.0, 102.0, 103.0])
        })),
    });
    t.push(Case {
        name: "4-D: frame out of range",
        bytes: frames.bytes(),
        opts: LoadOptions {
            frame: 3,
            mean: false,
        },
        expect: Expect::Fails(Box::new(|e| {
            assert!(
                matches!(
                    e,
                    NiftiError::FrameOutOfRange {
                        frame: 3,
                        frames: 3
                    }
                ),
                "{e}"
            )
        })),
    });
    t.push(loads(
        "5-D: frames multiply",
        &File::new(
            &[1, 1, 1, 2, 3],
            Data::F32((0..6).map(|v| v as f32).collect()),
        ),
        |l| {
            assert_eq!(l.header.frames, 6);
            assert!(warned(l, "5-D file with 6 frames"));
        },
    ));
    t.push(fails(
        "4-D file missing its last frame",
        {
            let b = frames.bytes();
            b[..b.len() - 2].to_vec()
        },
        |e| {
            assert!(
                matches!(e, NiftiError::TruncatedData { needed: 24, .. }),
                "{e}"
            )
        },
    ));

    // --- extensions (point 4) ---
    let with_ext = |ext: Vec<u8>, vox_offset: f64| {
        let mut f = base_i16()
            .with(|h| h.extender = [1, 0, 0, 0])
            .with(move |h| h.vox_offset = vox_offset);
        f.ext = ext;
        f
    };
    let ext_bytes = |esize: i32, code: i32, body: usize| {
        let mut v = esize.to_le_bytes().to_vec();
        v.extend(code.to_le_bytes());
        v.extend(vec![b'x'; body]);
        v
    };
    let good: Vec<u8> = [ext_bytes(32, 6, 24), ext_bytes(16, 4, 8)].concat();
    t.push(loads(
        "two valid extensions are listed",
        &with_ext(good, 400.0),
        |l| {
            clean_i16(l);
            assert_eq!(
                l.header.extensions,
                vec![
                    Extension { code: 6, size: 32 },
                    Extension { code: 4, size: 16 }
                ]
            );
        },
    ));
    t.push(loads(
        "extensions followed by zero padding",
        &with_ext(ext_bytes(16, 6, 8), 416.0),
        |l| {
            clean_i16(l);
            assert_eq!(l.header.extensions, vec![Extension { code: 6, size: 16 }]);
        },
    ));
    t.push(loads(
        "esize not a multiple of 16: all ignored with a warning",
        &with_ext([ext_bytes(16, 6, 8), ext_bytes(20, 4, 12)].concat(), 388.0),
        |l| {
            assert!(l.header.extensions.is_empty());
            assert!(warned(l, "header extensions ignored"));
            assert_eq!(stored(l)[0], -7.0);
        },
    ));
    t.push(loads(
        "extension running past vox_offset: ignored with a warning",
        &with_ext(ext_bytes(64, 6, 24), 384.0),
        |l| {
            assert!(l.header.extensions.is_empty());
            assert!(warned(l, "runs past the end"));
            assert_eq!(stored(l)[0], -7.0);
        },
    ));

    // --- non-finite voxels (point 6) ---
    t.push(loads(
        "NaN and infinities are kept and counted",
        &File::new(
            &[6],
            Data::F32(vec![
                1.0,
                f32::NAN,
                -2.0,
                f32::INFINITY,
                f32::NEG_INFINITY,
                4.0,
            ]),
        )
        .with(|h| h.scl_slope = -1.0),
        |l| {
            let s = stored(l);
            assert!(s[1].is_nan() && s[3] == f64::INFINITY && s[4] == f64::NEG_INFINITY);
            let st = intensity_stats(&l.volume);
            assert_eq!((st.finite, st.nonfinite), (3, 3));
            // slope -1: physical range is [-4, 2].
            assert_eq!((st.imin, st.imax), (Some(-4.0), Some(2.0)));
        },
    ));
    t.push(loads(
        "float64 NaN survives conversion",
        &File::new(&[3], Data::F64(vec![f64::NAN, 1e30, 1e30 + 1e16])),
        |l| {
            let s = stored(l);
            assert!(s[0].is_nan() && s[1].is_finite() && s[2] > s[1]);
            let st = intensity_stats(&l.volume);
            assert_eq!((st.finite, st.nonfinite), (2, 1));
        },
    ));

    // --- contract points the table did not yet pin down (coverage audit, issue 6) ---
    t.push(fails("empty input", Vec::new(), |e| {
        assert!(matches!(e, NiftiError::TooShort { len: 0, .. }), "{e}")
    }));
    t.push(fails(
        "nifti2 header cut short",
        base_i16().nifti2().bytes()[..400].to_vec(),
        |e| {
            assert!(
                matches!(
                    e,
                    NiftiError::TooShort {
                        len: 400,
                        needed: 540,
                        what: "NIfTI-2"
                    }
                ),
                "{e}"
            )
        },
    ));
    t.push(fails(
        "byte order cross-check: sizeof_hdr little-endian, dim[0] big-endian",
        {
            let mut b = base_i16().bytes();
            b[40..42].copy_from_slice(&3i16.to_be_bytes());
            b
        },
        |e| assert!(matches!(e, NiftiError::BadDimCount { dim0: 768 }), "{e}"),
    ));
    t.push(fails(
        "unknown 348-byte magic (n+3) is ANALYZE, whose voxels are in the .img",
        base_i16().with(|h| h.magic = *b"n+3\0").bytes(),
        |e| {
            assert!(matches!(e, NiftiError::SeparateImageFile { .. }), "{e}");
            assert!(e.to_string().contains("ANALYZE 7.5"), "{e}");
        },
    ));
    t.push(fails(
        "ni2 header given to parse",
        base_i16().nifti2().with(|h| h.magic = *b"ni2\0").bytes(),
        |e| {
            assert!(
                matches!(
                    e,
                    NiftiError::SeparateImageFile {
                        version: "NIfTI-2 (ni2)"
                    }
                ),
                "{e}"
            )
        },
    ));
    t.push(fails(
        "nifti2 negative vox_offset (an i64 field)",
        base_i16().nifti2().with(|h| h.vox_offset = -8.0).bytes(),
        |e| {
            assert!(
                matches!(e, NiftiError::BadVoxOffset { value } if *value == -8.0),
                "{e}"
            )
        },
    ));
    t.push(loads(
        "xyzt_units with a time code in the spatial bits: mm, with a warning",
        &base_i16().with(|h| h.xyzt_units = 4),
        |l| {
            assert_eq!(l.volume.spacing_mm, [0.5, 1.5, 2.5]);
            assert!(warned(l, "not a length unit"), "{:?}", l.volume.warnings);
        },
    ));
    t.push(loads(
        "non-finite qoffset: the qform is not used, with a warning",
        &base_i16().with(|h| {
            h.qform_code = 1;
            h.qoffset = [f64::NAN, 0.0, 0.0];
        }),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
            assert!(warned(l, "qform offsets"), "{:?}", l.volume.warnings);
        },
    ));
    t.push(loads(
        "esize 0: all extensions ignored with a warning",
        &with_ext(ext_bytes(0, 6, 8), 368.0),
        |l| {
            assert!(l.header.extensions.is_empty());
            assert!(warned(l, "esize 0"), "{:?}", l.volume.warnings);
            assert_eq!(stored(l)[0], -7.0);
        },
    ));
    t.push(loads(
        "extension head cut off by vox_offset: ignored with a warning",
        &with_ext([ext_bytes(16, 6, 8), vec![7, 0, 0, 0]].concat(), 372.0),
        |l| {
            assert!(l.header.extensions.is_empty());
            assert!(warned(l, "cut off"), "{:?}", l.volume.warnings);
            assert_eq!(stored(l)[0], -7.0);
        },
    ));
    t.push(loads(
        "nifti2 pixdim too small or too large for an invertible affine: 1 mm, with a warning",
        &base_i16()
            .nifti2()
            .with(|h| h.pixdim[1..4].copy_from_slice(&[1e-35, 1e35, 2.5])),
        |l| {
            assert_eq!(l.volume.spacing_mm, [1.0, 1.0, 2.5]);
            assert!(warned(l, "pixdim[1] (voxel size along i) is 1e-35"));
            assert!(warned(l, "pixdim[2] (voxel size along j) is 1e35"));
            assert_affine(&l.volume.orientation.affine, &diag([1.0, 1.0, 2.5]), 0.0);
        },
    ));
    t.push(loads(
        "nifti2 sform with a column outside 1e-30..1e30 mm falls back, with a warning",
        &base_i16().nifti2().with(|h| {
            h.sform_code = 1;
            h.srow = [
                [1e-40, 0.0, 0.0, 0.0],
                [0.0, 1.5, 0.0, 0.0],
                [0.0, 0.0, 2.5, 0.0],
            ];
        }),
        |l| {
            assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
            assert!(warned(l, "sform's 3x3 part"), "{:?}", l.volume.warnings);
        },
    ));
    t.push(loads(
        "float64 at -f64::MAX and f64::MAX: every physical value finite",
        &File::new(&[4], Data::F64(vec![-f64::MAX, f64::MAX, 0.0, 1.0])),
        |l| {
            let p = physical(l);
            assert!(p.iter().all(|v| v.is_finite()), "{p:?}");
            assert!((p[0] / -f64::MAX - 1.0).abs() < 1e-6, "{p:?}");
            assert!((p[1] / f64::MAX - 1.0).abs() < 1e-6, "{p:?}");
            let st = intensity_stats(&l.volume);
            assert_eq!(st.finite, 4);
        },
    ));

    // --- header summary ---
    t.push(loads(
        "description is trimmed lossy UTF-8",
        &base_i16().with(|h| h.set_description("  T1 \u{e9}t\u{e9}  ")),
        |l| {
            assert_eq!(l.header.description, "T1 \u{e9}t\u{e9}");
        },
    ));
    t
}

#[test]
fn crafted_files_have_their_documented_outcomes() {
    let cases = cases();
    assert!(cases.len() > 80, "the table has {} cases", cases.len());
    for case in cases {
        eprintln!("case: {}", case.name);
        let result = parse(case.bytes, "case.nii", &case.opts);
        match (case.expect, result) {
            (Expect::Loads(check), Ok(loaded)) => {
                let v = &loaded.volume;
                assert_eq!(v.samples.len(), v.voxel_count(), "{}", case.name);
                check(&loaded);
            }
            (Expect::Fails(check), Err(e)) => {
                let text = e.to_string();
                assert!(
                    !text.is_empty() && !text.contains('\n'),
                    "{}: one-sentence message, got {text:?}",
                    case.name
                );
                check(&e);
            }
            (Expect::Loads(_), Err(e)) => panic!("{}: expected to load, got error: {e}", case.name),
            (Expect::Fails(_), Ok(l)) => panic!(
                "{}: expected an error, loaded {:?} ({:?})",
                case.name, l.volume.dims, l.volume.warnings
            ),
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Independent checks of the byte layout

fn at<const N: usize>(b: &[u8], off: usize) -> [u8; N] {
    b[off..off + N].try_into().unwrap()
}

#[test]
fn header_field_offsets_match_the_standard() {
    let mut h = RawHeader {
        dim: [4, 7, 8, 9, 2, 1, 1, 1],
        datatype: 16,
        bitpix: 32,
        pixdim: [-1.0, 0.5, 0.75, 1.25, 2.0, 0.0, 0.0, 0.0],
        vox_offset: 416.0,
        scl_slope: 3.0,
        scl_inter: -4.0,
        xyzt_units: 10,
        qform_code: 1,
        sform_code: 2,
        quatern: [0.1, 0.2, 0.3],
        qoffset: [5.0, 6.0, 7.0],
        srow: [
            [1.0, 2.0, 3.0, 4.0],
            [5.0, 6.0, 7.0, 8.0],
            [9.0, 10.0, 11.0, 12.0],
        ],
        ..RawHeader::default()
    };
    h.set_description("abc");

    // NIfTI-1 (nifti1.h offsets), big-endian to also pin the byte order.
    let b = h.encode(Version::Nifti1, ByteOrder::BigEndian);
    assert_eq!(b.len(), 352);
    assert_eq!(i32::from_be_bytes(at(&b, 0)), 348);
    assert_eq!(i16::from_be_bytes(at(&b, 40)), 4);
    assert_eq!(i16::from_be_bytes(at(&b, 42)), 7);
    assert_eq!(i16::from_be_bytes(at(&b, 48)), 2);
    assert_eq!(i16::from_be_bytes(at(&b, 70)), 16);
    assert_eq!(i16::from_be_bytes(at(&b, 72)), 32);
    assert_eq!(f32::from_be_bytes(at(&b, 76)), -1.0);
    assert_eq!(f32::from_be_bytes(at(&b, 84)), 0.75);
    assert_eq!(f32::from_be_bytes(at(&b, 108)), 416.0);
    assert_eq!(f32::from_be_bytes(at(&b, 112)), 3.0);
    assert_eq!(f32::from_be_bytes(at(&b, 116)), -4.0);
    assert_eq!(b[123], 10);
    assert_eq!(&b[148..151], b"abc");
    assert_eq!(i16::from_be_bytes(at(&b, 252)), 1);
    assert_eq!(i16::from_be_bytes(at(&b, 254)), 2);
    assert_eq!(f32::from_be_bytes(at(&b, 260)), 0.2);
    assert_eq!(f32::from_be_bytes(at(&b, 276)), 7.0);
    assert_eq!(f32::from_be_bytes(at(&b, 280)), 1.0);
    assert_eq!(f32::from_be_bytes(at(&b, 308)), 8.0);
    assert_eq!(f32::from_be_bytes(at(&b, 324)), 12.0);
    assert_eq!(&b[344..348], b"n+1\0");

    // NIfTI-2 (nifti2.h offsets).
    h.magic = *b"n+2\0";
    let b = h.encode(Version::Nifti2, ByteOrder::LittleEndian);
    assert_eq!(b.len(), 544);
    assert_eq!(i32::from_le_bytes(at(&b, 0)), 540);
    assert_eq!(&b[4..12], b"n+2\0\r\n\x1a\n");
    assert_eq!(i16::from_le_bytes(at(&b, 12)), 16);
    assert_eq!(i16::from_le_bytes(at(&b, 14)), 32);
    assert_eq!(i64::from_le_bytes(at(&b, 16)), 4);
    assert_eq!(i64::from_le_bytes(at(&b, 24)), 7);
    assert_eq!(f64::from_le_bytes(at(&b, 104)), -1.0);
    assert_eq!(f64::from_le_bytes(at(&b, 112)), 0.5);
    assert_eq!(i64::from_le_bytes(at(&b, 168)), 416);
    assert_eq!(f64::from_le_bytes(at(&b, 176)), 3.0);
    assert_eq!(f64::from_le_bytes(at(&b, 184)), -4.0);
    assert_eq!(&b[240..243], b"abc");
    assert_eq!(i32::from_le_bytes(at(&b, 344)), 1);
    assert_eq!(i32::from_le_bytes(at(&b, 348)), 2);
    assert_eq!(f64::from_le_bytes(at(&b, 360)), 0.2);
    assert_eq!(f64::from_le_bytes(at(&b, 392)), 7.0);
    assert_eq!(f64::from_le_bytes(at(&b, 400)), 1.0);
    assert_eq!(f64::from_le_bytes(at(&b, 456)), 8.0);
    assert_eq!(f64::from_le_bytes(at(&b, 488)), 12.0);
    assert_eq!(i32::from_le_bytes(at(&b, 500)), 10);
}

// Files written by nibabel 5.4.2 (numpy 2.4.6); see the expected values in each test.
// q: 3x4x5 int16 (7n - 100, x fastest), oblique qform (code 1) with qfac -1, sform_code 0.
const NIBABEL_QFORM: &str = concat!(
    "5c010000000000000000000000000000000000000000000000000000000000000000000000000000030003000400",
    "050001000100010001000000000000000000000000000000040010000000000080bf6666663fcdcc8c3f00002040",
    "0000803f0000803f0000803f0000803f0000b0430000803f00000000000000000000000000000000000000000000",
    "000000000000000000006e69626162656c2071666f726d206f7261636c6500000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000010000008c69e0bd7c03713d1442103e0000a4c100000542",
    "0000e040000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "000000000000000000000000000000000000000000006e2b3100000000009cffa3ffaaffb1ffb8ffbfffc6ffcdff",
    "d4ffdbffe2ffe9fff0fff7fffeff05000c0013001a00210028002f0036003d0044004b0052005900600067006e00",
    "75007c0083008a00910098009f00a600ad00b400bb00c200c900d000d700de00e500ec00f300fa00010108010f01",
    "16011d0124012b0132013901",
);
// sbe: same voxels, big-endian, sform_code 2 (non-orthogonal), qform_code 0, slope 2, inter -10.
const NIBABEL_SFORM_BE: &str = concat!(
    "0000015c000000000000000000000000000000000000000000000000000000000000000000000000000300030004",
    "0005000100010001000100000000000000000000000000000004001000003f8000003f99999a3f8000003fc00000",
    "3f8000003f8000003f8000003f80000043b0000040000000c1200000000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000020000000000000000000000000000000000000000",
    "0000000000000000bf99999a3dcccccd42b400003f8000003d4ccccd00000000c2fc00003ca3d70a000000003fc0",
    "0000c2900000000000000000000000000000000000006e2b310000000000ff9cffa3ffaaffb1ffb8ffbfffc6ffcd",
    "ffd4ffdbffe2ffe9fff0fff7fffe0005000c0013001a00210028002f0036003d0044004b0052005900600067006e",
    "0075007c0083008a00910098009f00a600ad00b400bb00c200c900d000d700de00e500ec00f300fa01010108010f",
    "0116011d0124012b01320139",
);
// n2: NIfTI-2, 2x3x2 float64 1e30 + n * 1e15 (x fastest), affine diag(2, 3, 4), sform_code 2.
const NIBABEL_NIFTI2: &str = concat!(
    "1c0200006e2b32000d0a1a0a40004000030000000000000002000000000000000300000000000000020000000000",
    "00000100000000000000010000000000000001000000000000000100000000000000000000000000000000000000",
    "000000000000000000000000000000000000f03f0000000000000040000000000000084000000000000010400000",
    "00000000f03f000000000000f03f000000000000f03f000000000000f03f2002000000000000000000000000f03f",
    "00000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000000000000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000000200000000000000000000000000000000000000",
    "00000000000000000000000000000000000000000000000000000000000000000000000000000040000000000000",
    "00000000000000000000000000000000000000000000000000000000000000000840000000000000000000000000",
    "00000000000000000000000000000000000000000000000000001040000000000000000000000000000000000000",
    "0000000000000000000000000000000000000000000000000000000000000000000000000000ea8ca039593e2946",
    "f18ca039593e2946f88ca039593e2946ff8ca039593e2946068da039593e29460e8da039593e2946158da039593e",
    "29461c8da039593e2946238da039593e29462a8da039593e2946318da039593e2946388da039593e2946",
);

fn unhex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

#[test]
fn nibabel_qform_file_matches_nibabels_affine() {
    let l = load(unhex(NIBABEL_QFORM)).unwrap();
    assert_eq!(l.volume.dims, [3, 4, 5]);
    assert_eq!(l.volume.orientation.source, AffineSource::Qform);
    // nibabel's img.affine for this file.
    let expected = [
        [0.8580444312, -0.3185924189, -0.2117803908, -20.5],
        [0.2374551406, 1.0299227248, -0.5795671204, 33.25],
        [-0.131813381, -0.2185362761, -2.4226537142, 7.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    assert_affine(&l.volume.orientation.affine, &expected, 1e-6);
    assert_eq!(
        stored(&l),
        (0..60).map(|n| f64::from(7 * n - 100)).collect::<Vec<_>>()
    );
    assert_eq!(l.header.description, "nibabel qform oracle");
    let s = l.volume.spacing_mm;
    assert!(
        (s[0] - 0.9).abs() < 1e-6 && (s[1] - 1.1).abs() < 1e-6 && (s[2] - 2.5).abs() < 1e-6,
        "{s:?}"
    );
    assert!(l.volume.warnings.is_empty(), "{:?}", l.volume.warnings);
}

#[test]
fn nibabel_big_endian_sform_file_matches_nibabel() {
    let l = load(unhex(NIBABEL_SFORM_BE)).unwrap();
    assert_eq!(l.header.byte_order, ByteOrder::BigEndian);
    assert_eq!(l.volume.orientation.source, AffineSource::Sform);
    let expected = [
        [0.0, -1.2000000477, 0.1000000015, 90.0],
        [1.0, 0.0500000007, 0.0, -126.0],
        [0.0199999996, 0.0, 1.5, -72.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    assert_affine(&l.volume.orientation.affine, &expected, 1e-9);
    // nibabel's scaled data: 2 * (7n - 100) - 10.
    assert_eq!(
        physical(&l),
        (0..60).map(|n| f64::from(14 * n - 210)).collect::<Vec<_>>()
    );
    assert_eq!(l.volume.spacing_mm, [f64::from(1.2f32), 1.0, 1.5]);
}

#[test]
fn nibabel_nifti2_float64_file_keeps_its_tiny_range() {
    let l = load(unhex(NIBABEL_NIFTI2)).unwrap();
    assert_eq!(l.header.version, Version::Nifti2);
    assert_eq!(l.volume.dims, [2, 3, 2]);
    assert_eq!(l.header.datatype, Datatype::Float64);
    assert_affine(&l.volume.orientation.affine, &diag([2.0, 3.0, 4.0]), 0.0);
    for (n, v) in physical(&l).iter().enumerate() {
        let x = 1e30 + n as f64 * 1e15;
        assert!((v - x).abs() < 0.2e15, "voxel {n}: {v} vs {x}");
    }
}

// ---------------------------------------------------------------------------------------------
// Files on disk: pairs, gzip by content, errors naming paths

fn pair_parts(file: &File) -> (Vec<u8>, Vec<u8>) {
    let bytes = file.bytes();
    let header_len = file.version.header_len() + 4;
    let mut header = bytes[..header_len].to_vec();
    header.extend_from_slice(&file.ext);
    (header, file.data.encode(file.order))
}

#[test]
fn analyze_pair_loads_from_either_file() {
    let dir = temp_dir("analyze");
    let file = base_i16().big().with(|h| {
        h.magic = [0; 4];
        h.vox_offset = 0.0;
        h.scl_slope = 2.0; // SPM's funused1: reported, not applied
        h.qform_code = 1; // bytes that ANALYZE uses for other fields: must be ignored
    });
    let (hdr, img) = pair_parts(&file);
    std::fs::write(dir.join("scan.hdr"), &hdr).unwrap();
    std::fs::write(dir.join("scan.img"), &img).unwrap();
    for name in ["scan.hdr", "scan.img"] {
        let l = load_path(&dir.join(name), &LoadOptions::default()).unwrap();
        assert_eq!(l.header.version, Version::Analyze75);
        assert_eq!(l.header.storage, Storage::Pair);
        assert_eq!(l.volume.name, name);
        assert_eq!(
            stored(&l),
            ramp_i16(60)
                .iter()
                .map(|&v| f64::from(v))
                .collect::<Vec<_>>()
        );
        assert_eq!(l.volume.to_physical, morphray::volume::LinearMap::IDENTITY);
        assert_eq!(l.volume.orientation.source, AffineSource::Pixdim);
        assert_eq!(l.header.qform_code, 0);
        assert!(warned(&l, "funused1 is 2"), "{:?}", l.volume.warnings);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn nifti_pairs_with_gzip_and_offsets() {
    let dir = temp_dir("pairs");
    // ni1 with the image gzip-compressed and voxels at byte 16 of the .img.
    let file = base_i16().with(|h| {
        h.magic = *b"ni1\0";
        h.vox_offset = 16.0;
    });
    let (hdr, img) = pair_parts(&file);
    let mut padded = vec![0u8; 16];
    padded.extend(img);
    std::fs::write(dir.join("a.hdr"), &hdr).unwrap();
    std::fs::write(dir.join("a.img.gz"), gzip(&padded)).unwrap();
    let l = load_path(&dir.join("a.hdr"), &LoadOptions::default()).unwrap();
    clean_i16_named(&l, "a.hdr");
    assert_eq!((l.header.gzip, l.header.gzip_members), (true, 1));
    assert_eq!(l.header.data_offset, 16);

    // ni2, upper-case names, both files compressed.
    let file = base_i16().nifti2().with(|h| {
        h.magic = *b"ni2\0";
        h.vox_offset = 0.0;
    });
    let (hdr, img) = pair_parts(&file);
    std::fs::write(dir.join("B.HDR.gz"), gzip(&hdr)).unwrap();
    std::fs::write(dir.join("B.IMG"), &img).unwrap();
    let l = load_path(&dir.join("B.HDR.gz"), &LoadOptions::default()).unwrap();
    clean_i16_named(&l, "B.HDR.gz");
    assert_eq!(l.header.gzip_members, 1);
    assert_eq!(l.header.version, Version::Nifti2);

    // parse_pair from memory.
    let l = parse_pair(&hdr, img.clone(), "mem", &LoadOptions::default()).unwrap();
    clean_i16_named(&l, "mem");

    // Image shorter than the header promises.
    let e = parse_pair(&hdr, img[..100].to_vec(), "mem", &LoadOptions::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "image file ends at byte 100, but the header promises 120 bytes of voxels starting at byte 0"
    );

    // A header without its image.
    std::fs::write(dir.join("lonely.hdr"), &hdr).unwrap();
    let e = load_path(&dir.join("lonely.hdr"), &LoadOptions::default()).unwrap_err();
    assert!(
        matches!(e, NiftiError::MissingCompanion { wanted: ".img", .. }),
        "{e}"
    );
    assert!(e.to_string().contains("lonely.hdr"));
    std::fs::remove_dir_all(&dir).unwrap();
}

fn clean_i16_named(l: &LoadedNifti, name: &str) {
    assert_eq!(l.volume.name, name);
    assert_eq!(l.volume.dims, [3, 4, 5]);
    assert_eq!(
        stored(l),
        ramp_i16(60)
            .iter()
            .map(|&v| f64::from(v))
            .collect::<Vec<_>>()
    );
    assert_eq!(l.volume.spacing_mm, [0.5, 1.5, 2.5]);
    assert!(l.volume.warnings.is_empty(), "{:?}", l.volume.warnings);
}

#[test]
fn gzip_is_detected_by_content_not_by_name() {
    let dir = temp_dir("sniff");
    let plain = base_i16().bytes();
    std::fs::write(dir.join("looks_compressed.nii.gz"), &plain).unwrap();
    std::fs::write(dir.join("looks_plain.nii"), gzip(&plain)).unwrap();
    let a = load_path(
        &dir.join("looks_compressed.nii.gz"),
        &LoadOptions::default(),
    )
    .unwrap();
    let b = load_path(&dir.join("looks_plain.nii"), &LoadOptions::default()).unwrap();
    assert_eq!((a.header.gzip, b.header.gzip), (false, true));
    assert_eq!(a.volume.samples, b.volume.samples);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn missing_file_error_names_the_path() {
    let path = std::env::temp_dir().join("morphray-definitely-missing-file.nii");
    let e = load_path(&path, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e, NiftiError::Io { action: "read", .. }), "{e}");
    assert!(
        e.to_string()
            .contains("morphray-definitely-missing-file.nii"),
        "{e}"
    );
}

#[test]
fn inflate_phase_is_separate_and_counts_members() {
    let plain = base_i16().bytes();
    let (same, members) = inflate_if_gzip(plain.clone()).unwrap();
    assert_eq!((same == plain, members), (true, 0));
    let (inflated, members) = inflate_if_gzip(multi_member_gzip(&plain, 4)).unwrap();
    assert_eq!((inflated == plain, members), (true, 4));
    // A second member after a whole file (a wrong ISIZE hint for the first): still inflates,
    // since the 10 extra bytes are within the slack after the size the header declares.
    let big = File::new(
        &[64, 64, 16],
        Data::I16((0..65536).map(|v| (v % 1000) as i16).collect()),
    )
    .bytes();
    let mut two = gzip(&big);
    two.extend(gzip(&big[..10]));
    let (inflated, members) = inflate_if_gzip(two).unwrap();
    assert_eq!(members, 2);
    assert_eq!(inflated.len(), big.len() + 10);
    // The engine's path: inflate, then parse, then record the member count.
    let mut l = parse(inflated[..big.len()].to_vec(), "x", &LoadOptions::default()).unwrap();
    l.header.set_gzip_members(2);
    assert!(l.header.gzip);
}

// ---------------------------------------------------------------------------------------------
// Writer round trips

fn round_trip(volume: &morphray::volume::Volume, gz: bool) -> LoadedNifti {
    let dir = temp_dir("writer");
    let path = dir.join(if gz { "rt.nii.gz" } else { "rt.nii" });
    write_nifti1(volume, &path, gz).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(bytes.starts_with(&[0x1f, 0x8b]), gz);
    let l = load_path(&path, &LoadOptions::default()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    l
}

#[test]
fn writer_round_trip_phantom() {
    let phantom =
        morphray::volume::phantom::generate(&morphray::volume::phantom::PhantomSpec::cube(20))
            .unwrap();
    let v = &phantom.volume;
    for gz in [false, true] {
        let l = round_trip(v, gz);
        assert_eq!(l.volume.dims, v.dims);
        assert_eq!(l.volume.samples, v.samples);
        assert_eq!(l.volume.spacing_mm, v.spacing_mm);
        assert_eq!(l.volume.to_physical, v.to_physical);
        assert_affine(&l.volume.orientation.affine, &v.orientation.affine, 0.0);
        assert_eq!(l.volume.orientation.source, AffineSource::Sform);
        assert_eq!((l.header.sform_code, l.header.qform_code), (2, 2));
        assert_eq!(l.header.gzip, gz);
        assert!(l.volume.warnings.is_empty(), "{:?}", l.volume.warnings);
        assert_eq!(l.header.description, "morphray: phantom");
    }
}

fn oblique_volume(affine: [[f64; 4]; 4], spacing: [f64; 3]) -> morphray::volume::Volume {
    morphray::volume::Volume {
        name: "oblique".into(),
        dims: [3, 2, 2],
        spacing_mm: spacing,
        orientation: morphray::volume::Orientation {
            affine,
            source: AffineSource::Synthetic,
        },
        samples: morphray::volume::Samples::from_f32(&[
            0.5,
            f32::NAN,
            -1.0,
            2.0,
            f32::INFINITY,
            3.0,
            4.0,
            5.0,
            6.0,
            7.0,
            8.0,
            9.0,
        ]),
        to_physical: morphray::volume::LinearMap {
            slope: 2.0,
            intercept: -5.0,
        },
        warnings: vec![],
        facts: Default::default(),
    }
}

#[test]
fn writer_round_trip_oblique_with_flip_derives_an_exact_qform() {
    // Rotation of 30 degrees about z, voxel sizes 0.8 x 1.2 x 2, k flipped (qfac -1).
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let affine = [
        [0.8 * c, -1.2 * s, 0.0, 12.5],
        [0.8 * s, 1.2 * c, 0.0, -3.0],
        [0.0, 0.0, -2.0, 40.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let v = oblique_volume(affine, [0.8, 1.2, 2.0]);
    for gz in [false, true] {
        let l = round_trip(&v, gz);
        assert_eq!(l.header.qform_code, 2, "an orthogonal affine gets a qform");
        assert!(
            l.volume.warnings.is_empty(),
            "qform must agree with sform: {:?}",
            l.volume.warnings
        );
        assert_affine(&l.volume.orientation.affine, &affine, 1e-6);
        assert_eq!(
            l.volume.samples.as_bytes(),
            v.samples.as_bytes(),
            "NaN and Inf written bit-exactly"
        );
        assert_eq!(l.volume.to_physical, v.to_physical);
        let st = intensity_stats(&l.volume);
        assert_eq!((st.finite, st.nonfinite), (10, 2));
        assert_eq!((st.imin, st.imax), (Some(-7.0), Some(13.0)));
    }
    // The qform alone reproduces the affine: drop the sform and reload.
    let dir = temp_dir("qform-only");
    let path = dir.join("q.nii");
    write_nifti1(&v, &path, false).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[254..256].copy_from_slice(&0i16.to_le_bytes());
    let l = parse(bytes, "q.nii", &LoadOptions::default()).unwrap();
    assert_eq!(l.volume.orientation.source, AffineSource::Qform);
    assert_affine(&l.volume.orientation.affine, &affine, 1e-6);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn writer_skips_the_qform_for_a_sheared_affine_and_rejects_what_nifti1_cannot_hold() {
    let affine = [
        [1.0, 0.3, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let v = oblique_volume(affine, [1.0, 1.0, 1.0]);
    let l = round_trip(&v, false);
    assert_eq!((l.header.qform_code, l.header.sform_code), (0, 2));
    assert_affine(&l.volume.orientation.affine, &affine, 1e-7);

    let mut too_big = v.clone();
    too_big.dims = [40000, 1, 1];
    let e = write_nifti1(
        &too_big,
        &std::env::temp_dir().join("morphray-never-written.nii"),
        false,
    )
    .unwrap_err();
    assert!(matches!(e, NiftiError::Unwritable { .. }), "{e}");
    assert!(e.to_string().contains("32767"), "{e}");
}

#[test]
fn header_summary_serialises_to_json() {
    let l = load(gzip(
        &base_i16().big().with(|h| h.scl_slope = f64::NAN).bytes(),
    ))
    .unwrap();
    let json: serde_json::Value = serde_json::to_value(&l.header).unwrap();
    assert_eq!(json["version"], "nifti1");
    assert_eq!(json["byte_order"], "big_endian");
    assert_eq!(json["storage"], "single_file");
    assert_eq!(json["datatype"], "int16");
    assert_eq!(json["dims"], serde_json::json!([3, 4, 5]));
    assert_eq!(json["frames"], 1);
    assert_eq!(json["vox_offset"], 352.0);
    assert_eq!(
        json["scl_slope"],
        serde_json::Value::Null,
        "NaN has no JSON number"
    );
    assert_eq!(
        (json["gzip"].clone(), json["gzip_members"].clone()),
        (true.into(), 1.into())
    );
}
