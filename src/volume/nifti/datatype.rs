//! NIfTI datatype codes: names, sizes, and what morphray stores each one as.
//!
//! Decisions:
//! - Every code the NIfTI-1 standard defines is named (so errors can say "complex64", not "32"),
//!   but only real scalar types and RGB(A) are loadable.
//! - u8, i8, u16, i16 and f32 are kept as they are (the GPU reads them directly). int32, uint32,
//!   int64, uint64 and float64 become f32 after subtracting an offset (convert.rs); RGB24 and
//!   RGBA32 become f32 luminance.
//! - The datatype decides the voxel size; `bitpix` is only cross-checked (a mismatch is a warning).

use crate::volume::SampleKind;

/// A NIfTI datatype (the `datatype` header field).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Datatype {
    /// Code 1, one bit per voxel (not supported).
    Binary,
    /// Code 2.
    Uint8,
    /// Code 4.
    Int16,
    /// Code 8.
    Int32,
    /// Code 16.
    Float32,
    /// Code 32, two float32 (not supported).
    Complex64,
    /// Code 64.
    Float64,
    /// Code 128, three uint8 per voxel.
    Rgb24,
    /// Code 256.
    Int8,
    /// Code 512.
    Uint16,
    /// Code 768.
    Uint32,
    /// Code 1024.
    Int64,
    /// Code 1280.
    Uint64,
    /// Code 1536, 128-bit float (not supported).
    Float128,
    /// Code 1792, two float64 (not supported).
    Complex128,
    /// Code 2048, two float128 (not supported).
    Complex256,
    /// Code 2304, four uint8 per voxel.
    Rgba32,
}

impl Datatype {
    /// The datatype with NIfTI code `code`, if the standard defines it.
    pub fn from_code(code: i16) -> Option<Datatype> {
        use Datatype::*;
        Some(match code {
            1 => Binary,
            2 => Uint8,
            4 => Int16,
            8 => Int32,
            16 => Float32,
            32 => Complex64,
            64 => Float64,
            128 => Rgb24,
            256 => Int8,
            512 => Uint16,
            768 => Uint32,
            1024 => Int64,
            1280 => Uint64,
            1536 => Float128,
            1792 => Complex128,
            2048 => Complex256,
            2304 => Rgba32,
            _ => return None,
        })
    }

    /// The NIfTI code.
    pub fn code(self) -> i16 {
        use Datatype::*;
        match self {
            Binary => 1,
            Uint8 => 2,
            Int16 => 4,
            Int32 => 8,
            Float32 => 16,
            Complex64 => 32,
            Float64 => 64,
            Rgb24 => 128,
            Int8 => 256,
            Uint16 => 512,
            Uint32 => 768,
            Int64 => 1024,
            Uint64 => 1280,
            Float128 => 1536,
            Complex128 => 1792,
            Complex256 => 2048,
            Rgba32 => 2304,
        }
    }

    /// The lowercase NIfTI name, e.g. `int16`.
    pub fn name(self) -> &'static str {
        use Datatype::*;
        match self {
            Binary => "binary",
            Uint8 => "uint8",
            Int16 => "int16",
            Int32 => "int32",
            Float32 => "float32",
            Complex64 => "complex64",
            Float64 => "float64",
            Rgb24 => "rgb24",
            Int8 => "int8",
            Uint16 => "uint16",
            Uint32 => "uint32",
            Int64 => "int64",
            Uint64 => "uint64",
            Float128 => "float128",
            Complex128 => "complex128",
            Complex256 => "complex256",
            Rgba32 => "rgba32",
        }
    }

    /// Bits per voxel the standard prescribes (what `bitpix` should say).
    pub fn bitpix(self) -> i16 {
        use Datatype::*;
        match self {
            Binary => 1,
            Uint8 | Int8 => 8,
            Int16 | Uint16 => 16,
            Rgb24 => 24,
            Int32 | Uint32 | Float32 | Rgba32 => 32,
            Int64 | Uint64 | Float64 | Complex64 => 64,
            Float128 | Complex128 => 128,
            Complex256 => 256,
        }
    }

    /// Bytes per voxel in the file, for the loadable datatypes; `None` for the unsupported ones.
    pub fn bytes_per_voxel(self) -> Option<usize> {
        use Datatype::*;
        match self {
            Uint8 | Int8 => Some(1),
            Int16 | Uint16 => Some(2),
            Rgb24 => Some(3),
            Int32 | Uint32 | Float32 | Rgba32 => Some(4),
            Int64 | Uint64 | Float64 => Some(8),
            Binary | Complex64 | Float128 | Complex128 | Complex256 => None,
        }
    }

    /// How the voxels are stored after loading.
    pub fn sample_kind(self) -> SampleKind {
        use Datatype::*;
        match self {
            Uint8 => SampleKind::U8,
            Int8 => SampleKind::I8,
            Int16 => SampleKind::I16,
            Uint16 => SampleKind::U16,
            _ => SampleKind::F32,
        }
    }

    /// The datatype a [`SampleKind`] is written as.
    pub fn from_sample_kind(kind: SampleKind) -> Datatype {
        match kind {
            SampleKind::U8 => Datatype::Uint8,
            SampleKind::I8 => Datatype::Int8,
            SampleKind::U16 => Datatype::Uint16,
            SampleKind::I16 => Datatype::Int16,
            SampleKind::F32 => Datatype::Float32,
        }
    }

    /// True for RGB24 and RGBA32 (never scaled by scl_slope).
    pub fn is_colour(self) -> bool {
        matches!(self, Datatype::Rgb24 | Datatype::Rgba32)
    }
}

impl serde::Serialize for Datatype {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}
