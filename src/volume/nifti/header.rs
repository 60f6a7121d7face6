//! The fixed-size header: byte order and version detection, field decoding and encoding.
//!
//! Decisions:
//! - NIfTI-1, NIfTI-2 and ANALYZE 7.5 decode into one [`RawHeader`] with the widest field types
//!   (i64 dims, f64 floats), so everything after this module is version-independent.
//! - Byte order comes from `sizeof_hdr` read both ways (348 or 540); `dim[0]` must then be 1..=7
//!   in that order (the NIfTI standard's own cross-check).
//! - The version comes from the magic: `n+1`/`ni1` in a 348-byte header, `n+2`/`ni2` plus the
//!   EOL bytes `\r\n\x1a\n` in a 540-byte one. A 348-byte header with no NIfTI magic is ANALYZE
//!   7.5; its bytes 252..348 are ANALYZE's own fields, so qform/sform are zeroed (never guessed).
//! - Values are stored exactly as read: repairs happen later and are reported there.
//! - Decoding reads through bounds-checked accessors over a slice already checked to be long
//!   enough, so no input can make it index out of range.
//! - [`RawHeader::encode`] is the exact inverse (used by the writer and by tests that craft files
//!   in either byte order and version).

use super::error::NiftiError;

/// Bytes of a NIfTI-1 / ANALYZE 7.5 header.
pub const NIFTI1_HEADER_LEN: usize = 348;
/// Bytes of a NIfTI-2 header.
pub const NIFTI2_HEADER_LEN: usize = 540;
/// The NIfTI-2 magic is followed by these bytes, which text-mode transfers would alter.
pub const NIFTI2_EOL: [u8; 4] = [0x0d, 0x0a, 0x1a, 0x0a];

/// Header format of a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Version {
    /// 348-byte header with magic `n+1` or `ni1`.
    Nifti1,
    /// 540-byte header with magic `n+2` or `ni2`.
    Nifti2,
    /// 348-byte header without a NIfTI magic (always a .hdr/.img pair).
    Analyze75,
}

impl Version {
    /// Human-readable name.
    pub fn label(self) -> &'static str {
        match self {
            Version::Nifti1 => "NIfTI-1",
            Version::Nifti2 => "NIfTI-2",
            Version::Analyze75 => "ANALYZE 7.5",
        }
    }

    /// Bytes of the fixed header.
    pub fn header_len(self) -> usize {
        match self {
            Version::Nifti2 => NIFTI2_HEADER_LEN,
            Version::Nifti1 | Version::Analyze75 => NIFTI1_HEADER_LEN,
        }
    }
}

/// Byte order of the header and voxels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ByteOrder {
    /// Least significant byte first.
    LittleEndian,
    /// Most significant byte first.
    BigEndian,
}

/// Where the voxels live.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Storage {
    /// One `.nii` file: header, extensions, then voxels from `vox_offset`.
    SingleFile,
    /// A `.hdr` with the header and an `.img` with the voxels (magic `ni1`/`ni2`, or ANALYZE).
    Pair,
}

/// Every header field morphray reads or writes, in the widest type of either version.
#[derive(Clone, Debug, PartialEq)]
pub struct RawHeader {
    /// `dim_info` (frequency/phase/slice dimensions, unused here).
    pub dim_info: u8,
    /// `dim[0]` = number of dimensions, `dim[1..=7]` = sizes.
    pub dim: [i64; 8],
    /// `intent_p1..3`.
    pub intent_p: [f64; 3],
    /// `intent_code`.
    pub intent_code: i32,
    /// `datatype` code.
    pub datatype: i16,
    /// `bitpix`.
    pub bitpix: i16,
    /// `slice_start`.
    pub slice_start: i64,
    /// `pixdim[0]` = qfac, `pixdim[1..=3]` = voxel size, `pixdim[4]` = time step, ...
    pub pixdim: [f64; 8],
    /// `vox_offset`: byte position of the voxels.
    pub vox_offset: f64,
    /// `scl_slope` (ANALYZE: `funused1`, never applied).
    pub scl_slope: f64,
    /// `scl_inter` (ANALYZE: `funused2`, never applied).
    pub scl_inter: f64,
    /// `slice_end`.
    pub slice_end: i64,
    /// `slice_code`.
    pub slice_code: i32,
    /// `xyzt_units`: spatial unit in bits 0..3, temporal in bits 3..6.
    pub xyzt_units: i32,
    /// `cal_max`.
    pub cal_max: f64,
    /// `cal_min`.
    pub cal_min: f64,
    /// `slice_duration`.
    pub slice_duration: f64,
    /// `toffset`.
    pub toffset: f64,
    /// `descrip` (80 bytes, NUL-padded).
    pub descrip: [u8; 80],
    /// `aux_file` (24 bytes).
    pub aux_file: [u8; 24],
    /// `qform_code` (0 for ANALYZE).
    pub qform_code: i32,
    /// `sform_code` (0 for ANALYZE).
    pub sform_code: i32,
    /// `quatern_b`, `quatern_c`, `quatern_d`.
    pub quatern: [f64; 3],
    /// `qoffset_x`, `qoffset_y`, `qoffset_z`.
    pub qoffset: [f64; 3],
    /// `srow_x`, `srow_y`, `srow_z`.
    pub srow: [[f64; 4]; 3],
    /// `intent_name` (16 bytes).
    pub intent_name: [u8; 16],
    /// The first four magic bytes: `n+1\0`, `ni1\0`, `n+2\0`, `ni2\0`, or anything for ANALYZE.
    pub magic: [u8; 4],
    /// The four bytes after the fixed header (`extension[0] != 0` means extensions follow).
    pub extender: [u8; 4],
}

impl Default for RawHeader {
    /// A 1x1x1 uint8 NIfTI-1 single-file header with no orientation.
    fn default() -> Self {
        RawHeader {
            dim_info: 0,
            dim: [3, 1, 1, 1, 1, 1, 1, 1],
            intent_p: [0.0; 3],
            intent_code: 0,
            datatype: 2,
            bitpix: 8,
            slice_start: 0,
            pixdim: [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0],
            vox_offset: 352.0,
            scl_slope: 0.0,
            scl_inter: 0.0,
            slice_end: 0,
            slice_code: 0,
            xyzt_units: 2,
            cal_max: 0.0,
            cal_min: 0.0,
            slice_duration: 0.0,
            toffset: 0.0,
            descrip: [0; 80],
            aux_file: [0; 24],
            qform_code: 0,
            sform_code: 0,
            quatern: [0.0; 3],
            qoffset: [0.0; 3],
            srow: [[0.0; 4]; 3],
            intent_name: [0; 16],
            magic: *b"n+1\0",
            extender: [0; 4],
        }
    }
}

/// A decoded header and what the fixed part said about the file.
#[derive(Clone, Debug)]
pub struct Decoded {
    /// The fields, as read.
    pub header: RawHeader,
    /// Header format.
    pub version: Version,
    /// Byte order of header and voxels.
    pub byte_order: ByteOrder,
    /// One file or a pair.
    pub storage: Storage,
    /// Oddities that did not stop decoding.
    pub warnings: Vec<String>,
}

/// Bounds-checked little/big-endian field reader over the header bytes.
struct Reader<'a> {
    bytes: &'a [u8],
    big: bool,
}

impl Reader<'_> {
    /// `N` bytes at `at`, or zeros if out of range (callers check the length first, so the
    /// zero path only guards against mistakes).
    fn raw<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut out = [0u8; N];
        if let Some(src) = at.checked_add(N).and_then(|end| self.bytes.get(at..end)) {
            out.copy_from_slice(src);
        }
        out
    }
    fn u8(&self, at: usize) -> u8 {
        self.raw::<1>(at)[0]
    }
    fn i16(&self, at: usize) -> i16 {
        let b = self.raw(at);
        if self.big {
            i16::from_be_bytes(b)
        } else {
            i16::from_le_bytes(b)
        }
    }
    fn i32(&self, at: usize) -> i32 {
        let b = self.raw(at);
        if self.big {
            i32::from_be_bytes(b)
        } else {
            i32::from_le_bytes(b)
        }
    }
    fn i64(&self, at: usize) -> i64 {
        let b = self.raw(at);
        if self.big {
            i64::from_be_bytes(b)
        } else {
            i64::from_le_bytes(b)
        }
    }
    fn f32(&self, at: usize) -> f64 {
        let b = self.raw(at);
        f64::from(if self.big {
            f32::from_be_bytes(b)
        } else {
            f32::from_le_bytes(b)
        })
    }
    fn f64(&self, at: usize) -> f64 {
        let b = self.raw(at);
        if self.big {
            f64::from_be_bytes(b)
        } else {
            f64::from_le_bytes(b)
        }
    }
}

/// Bounds-checked little/big-endian field writer.
struct Writer {
    bytes: Vec<u8>,
    big: bool,
}

impl Writer {
    fn put(&mut self, at: usize, b: &[u8]) {
        if let Some(dst) = at
            .checked_add(b.len())
            .and_then(|end| self.bytes.get_mut(at..end))
        {
            dst.copy_from_slice(b);
        }
    }
    fn i16(&mut self, at: usize, v: i16) {
        self.put(
            at,
            &if self.big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            },
        );
    }
    fn i32(&mut self, at: usize, v: i32) {
        self.put(
            at,
            &if self.big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            },
        );
    }
    fn i64(&mut self, at: usize, v: i64) {
        self.put(
            at,
            &if self.big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            },
        );
    }
    fn f32(&mut self, at: usize, v: f64) {
        let v = v as f32;
        self.put(
            at,
            &if self.big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            },
        );
    }
    fn f64(&mut self, at: usize, v: f64) {
        self.put(
            at,
            &if self.big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            },
        );
    }
}

/// Narrows to i16, saturating (NIfTI-1 fields are 16-bit).
fn sat_i16(v: i64) -> i16 {
    v.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16
}

/// Detects version and byte order and decodes the fixed header at the start of `bytes`.
pub fn decode(bytes: &[u8]) -> Result<Decoded, NiftiError> {
    let first: [u8; 4] = Reader { bytes, big: false }.raw(0);
    if bytes.len() < 4 {
        return Err(NiftiError::TooShort {
            len: bytes.len(),
            needed: NIFTI1_HEADER_LEN,
            what: "NIfTI-1",
        });
    }
    let little = i32::from_le_bytes(first);
    let big = i32::from_be_bytes(first);
    let (len, is_big) = match (little, big) {
        (348, _) => (NIFTI1_HEADER_LEN, false),
        (_, 348) => (NIFTI1_HEADER_LEN, true),
        (540, _) => (NIFTI2_HEADER_LEN, false),
        (_, 540) => (NIFTI2_HEADER_LEN, true),
        _ => return Err(NiftiError::NotNifti { little, big }),
    };
    if bytes.len() < len {
        let what = if len == NIFTI2_HEADER_LEN {
            "NIfTI-2"
        } else {
            "NIfTI-1"
        };
        return Err(NiftiError::TooShort {
            len: bytes.len(),
            needed: len,
            what,
        });
    }
    let r = Reader { bytes, big: is_big };
    let byte_order = if is_big {
        ByteOrder::BigEndian
    } else {
        ByteOrder::LittleEndian
    };
    let decoded = if len == NIFTI2_HEADER_LEN {
        decode_nifti2(&r)?
    } else {
        decode_nifti1(&r)
    };
    let dim0 = decoded.header.dim[0];
    if !(1..=7).contains(&dim0) {
        return Err(NiftiError::BadDimCount { dim0 });
    }
    Ok(Decoded {
        byte_order,
        ..decoded
    })
}

fn decode_nifti1(r: &Reader) -> Decoded {
    let magic: [u8; 4] = r.raw(344);
    let mut warnings = Vec::new();
    let (version, storage) = match &magic {
        b"n+1\0" => (Version::Nifti1, Storage::SingleFile),
        b"ni1\0" => (Version::Nifti1, Storage::Pair),
        _ => {
            if magic != [0; 4] {
                warnings.push(format!(
                    "the 348-byte header has no NIfTI magic (found {:?}), so it is read as ANALYZE 7.5",
                    String::from_utf8_lossy(&magic)
                ));
            }
            (Version::Analyze75, Storage::Pair)
        }
    };
    let mut h = RawHeader {
        dim_info: r.u8(39),
        dim: std::array::from_fn(|i| i64::from(r.i16(40 + 2 * i))),
        intent_p: [r.f32(56), r.f32(60), r.f32(64)],
        intent_code: i32::from(r.i16(68)),
        datatype: r.i16(70),
        bitpix: r.i16(72),
        slice_start: i64::from(r.i16(74)),
        pixdim: std::array::from_fn(|i| r.f32(76 + 4 * i)),
        vox_offset: r.f32(108),
        scl_slope: r.f32(112),
        scl_inter: r.f32(116),
        slice_end: i64::from(r.i16(120)),
        slice_code: i32::from(r.u8(122)),
        xyzt_units: i32::from(r.u8(123)),
        cal_max: r.f32(124),
        cal_min: r.f32(128),
        slice_duration: r.f32(132),
        toffset: r.f32(136),
        descrip: r.raw(148),
        aux_file: r.raw(228),
        qform_code: i32::from(r.i16(252)),
        sform_code: i32::from(r.i16(254)),
        quatern: [r.f32(256), r.f32(260), r.f32(264)],
        qoffset: [r.f32(268), r.f32(272), r.f32(276)],
        srow: std::array::from_fn(|row| std::array::from_fn(|c| r.f32(280 + 16 * row + 4 * c))),
        intent_name: r.raw(328),
        magic,
        extender: r.raw(348),
    };
    if version == Version::Analyze75 {
        // Bytes 252.. hold ANALYZE's orient/originator fields, not qform/sform: never guess.
        h.qform_code = 0;
        h.sform_code = 0;
        h.quatern = [0.0; 3];
        h.qoffset = [0.0; 3];
        h.srow = [[0.0; 4]; 3];
        h.intent_code = 0;
        h.intent_name = [0; 16];
    }
    Decoded {
        header: h,
        version,
        byte_order: ByteOrder::LittleEndian,
        storage,
        warnings,
    }
}

fn decode_nifti2(r: &Reader) -> Result<Decoded, NiftiError> {
    let magic: [u8; 4] = r.raw(4);
    let storage = match &magic {
        b"n+2\0" => Storage::SingleFile,
        b"ni2\0" => Storage::Pair,
        _ => {
            return Err(NiftiError::BadMagic {
                found: String::from_utf8_lossy(&magic).into_owned(),
            });
        }
    };
    let eol: [u8; 4] = r.raw(8);
    if eol != NIFTI2_EOL {
        return Err(NiftiError::Nifti2Eol { found: eol });
    }
    let h = RawHeader {
        datatype: r.i16(12),
        bitpix: r.i16(14),
        dim: std::array::from_fn(|i| r.i64(16 + 8 * i)),
        intent_p: [r.f64(80), r.f64(88), r.f64(96)],
        pixdim: std::array::from_fn(|i| r.f64(104 + 8 * i)),
        vox_offset: r.i64(168) as f64,
        scl_slope: r.f64(176),
        scl_inter: r.f64(184),
        cal_max: r.f64(192),
        cal_min: r.f64(200),
        slice_duration: r.f64(208),
        toffset: r.f64(216),
        slice_start: r.i64(224),
        slice_end: r.i64(232),
        descrip: r.raw(240),
        aux_file: r.raw(320),
        qform_code: r.i32(344),
        sform_code: r.i32(348),
        quatern: [r.f64(352), r.f64(360), r.f64(368)],
        qoffset: [r.f64(376), r.f64(384), r.f64(392)],
        srow: std::array::from_fn(|row| std::array::from_fn(|c| r.f64(400 + 32 * row + 8 * c))),
        slice_code: r.i32(496),
        xyzt_units: r.i32(500),
        intent_code: r.i32(504),
        intent_name: r.raw(508),
        dim_info: r.u8(524),
        magic,
        extender: r.raw(540),
    };
    Ok(Decoded {
        header: h,
        version: Version::Nifti2,
        byte_order: ByteOrder::LittleEndian,
        storage,
        warnings: Vec::new(),
    })
}

impl RawHeader {
    /// Encodes the header in `version`'s layout and `order`, followed by the four extender
    /// bytes: 352 bytes for NIfTI-1 / ANALYZE, 544 for NIfTI-2. Fields wider than the format
    /// are narrowed (f64 to f32, i64 to i16 saturating). For NIfTI-2 the magic's first four
    /// bytes are `self.magic` and the EOL bytes are written correctly.
    pub fn encode(&self, version: Version, order: ByteOrder) -> Vec<u8> {
        let big = order == ByteOrder::BigEndian;
        let len = version.header_len();
        let mut w = Writer {
            bytes: vec![0u8; len + 4],
            big,
        };
        match version {
            Version::Nifti1 | Version::Analyze75 => self.encode_nifti1(&mut w, version),
            Version::Nifti2 => self.encode_nifti2(&mut w),
        }
        w.put(len, &self.extender);
        w.bytes
    }

    fn encode_nifti1(&self, w: &mut Writer, version: Version) {
        w.i32(0, 348);
        if version == Version::Analyze75 {
            w.put(38, b"r"); // ANALYZE `regular`
        }
        w.put(39, &[self.dim_info]);
        for (i, &d) in self.dim.iter().enumerate() {
            w.i16(40 + 2 * i, sat_i16(d));
        }
        for (i, &p) in self.intent_p.iter().enumerate() {
            w.f32(56 + 4 * i, p);
        }
        w.i16(68, sat_i16(i64::from(self.intent_code)));
        w.i16(70, self.datatype);
        w.i16(72, self.bitpix);
        w.i16(74, sat_i16(self.slice_start));
        for (i, &p) in self.pixdim.iter().enumerate() {
            w.f32(76 + 4 * i, p);
        }
        w.f32(108, self.vox_offset);
        w.f32(112, self.scl_slope);
        w.f32(116, self.scl_inter);
        w.i16(120, sat_i16(self.slice_end));
        w.put(
            122,
            &[
                self.slice_code.clamp(0, 255) as u8,
                self.xyzt_units.clamp(0, 255) as u8,
            ],
        );
        w.f32(124, self.cal_max);
        w.f32(128, self.cal_min);
        w.f32(132, self.slice_duration);
        w.f32(136, self.toffset);
        w.put(148, &self.descrip);
        w.put(228, &self.aux_file);
        w.i16(252, sat_i16(i64::from(self.qform_code)));
        w.i16(254, sat_i16(i64::from(self.sform_code)));
        for i in 0..3 {
            w.f32(256 + 4 * i, self.quatern[i]);
            w.f32(268 + 4 * i, self.qoffset[i]);
        }
        for (row, values) in self.srow.iter().enumerate() {
            for (c, &v) in values.iter().enumerate() {
                w.f32(280 + 16 * row + 4 * c, v);
            }
        }
        w.put(328, &self.intent_name);
        w.put(344, &self.magic);
    }

    fn encode_nifti2(&self, w: &mut Writer) {
        w.i32(0, 540);
        w.put(4, &self.magic);
        w.put(8, &NIFTI2_EOL);
        w.i16(12, self.datatype);
        w.i16(14, self.bitpix);
        for (i, &d) in self.dim.iter().enumerate() {
            w.i64(16 + 8 * i, d);
        }
        for (i, &p) in self.intent_p.iter().enumerate() {
            w.f64(80 + 8 * i, p);
        }
        for (i, &p) in self.pixdim.iter().enumerate() {
            w.f64(104 + 8 * i, p);
        }
        w.i64(168, self.vox_offset as i64);
        w.f64(176, self.scl_slope);
        w.f64(184, self.scl_inter);
        w.f64(192, self.cal_max);
        w.f64(200, self.cal_min);
        w.f64(208, self.slice_duration);
        w.f64(216, self.toffset);
        w.i64(224, self.slice_start);
        w.i64(232, self.slice_end);
        w.put(240, &self.descrip);
        w.put(320, &self.aux_file);
        w.i32(344, self.qform_code);
        w.i32(348, self.sform_code);
        for i in 0..3 {
            w.f64(352 + 8 * i, self.quatern[i]);
            w.f64(376 + 8 * i, self.qoffset[i]);
        }
        for (row, values) in self.srow.iter().enumerate() {
            for (c, &v) in values.iter().enumerate() {
                w.f64(400 + 32 * row + 8 * c, v);
            }
        }
        w.i32(496, self.slice_code);
        w.i32(500, self.xyzt_units);
        w.i32(504, self.intent_code);
        w.put(508, &self.intent_name);
        w.put(524, &[self.dim_info]);
    }

    /// `descrip` as text: up to the first NUL, lossy UTF-8, trimmed.
    pub fn description(&self) -> String {
        let end = self
            .descrip
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(self.descrip.len());
        String::from_utf8_lossy(self.descrip.get(..end).unwrap_or_default())
            .trim()
            .to_string()
    }

    /// Sets `descrip` from text, truncated to 79 bytes (NUL-terminated).
    pub fn set_description(&mut self, text: &str) {
        self.descrip = [0; 80];
        for (dst, src) in self.descrip.iter_mut().take(79).zip(text.bytes()) {
            *dst = src;
        }
    }
}

/// True when `v` fits a NIfTI-1 16-bit field (used by the writer for dims).
pub fn fits_i16(v: i64) -> bool {
    i16::try_from(v).is_ok()
}
