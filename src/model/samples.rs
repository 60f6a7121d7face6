//! Stored voxel values in the encodings the GPU kernels read.
//!
//! Decisions: samples are kept as one little-endian byte vector plus a [`SampleKind`], which is
//! exactly what is uploaded (no per-type containers, no copy before upload). Typed views decode
//! on demand for the CPU paths (statistics, reference kernels), which are not on the hot path.

/// Encoding of one stored sample. The numeric values are the shader variant selectors
/// (`SAMPLE_KIND` override in the WGSL kernels): keep them in sync with `shaders/`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleKind {
    /// Unsigned 8-bit integer.
    U8 = 0,
    /// Signed 8-bit integer.
    I8 = 1,
    /// Unsigned 16-bit integer.
    U16 = 2,
    /// Signed 16-bit integer.
    I16 = 3,
    /// IEEE-754 binary32; the only kind that can hold NaN or infinities.
    F32 = 4,
}

impl SampleKind {
    /// Bytes per sample.
    pub fn size_bytes(self) -> usize {
        match self {
            SampleKind::U8 | SampleKind::I8 => 1,
            SampleKind::U16 | SampleKind::I16 => 2,
            SampleKind::F32 => 4,
        }
    }

    /// Short lowercase name (`u8`, `i16`, ...), as used in shader variant names.
    pub fn name(self) -> &'static str {
        match self {
            SampleKind::U8 => "u8",
            SampleKind::I8 => "i8",
            SampleKind::U16 => "u16",
            SampleKind::I16 => "i16",
            SampleKind::F32 => "f32",
        }
    }
}

/// Stored samples: `len * kind.size_bytes()` little-endian bytes, from byte `start` of `bytes`.
#[derive(Clone, Debug)]
pub struct Samples {
    kind: SampleKind,
    bytes: Vec<u8>,
    /// Where the samples begin in `bytes` (a loaded `.nii` keeps its header in front).
    start: usize,
}

impl PartialEq for Samples {
    /// Equal kind and equal sample bytes, wherever they start in their vectors.
    fn eq(&self, other: &Self) -> bool {
        self.kind == other.kind && self.as_bytes() == other.as_bytes()
    }
}

/// The byte vector's length is not a whole number of samples.
#[derive(Debug, thiserror::Error)]
#[error("{len} bytes is not a whole number of {kind:?} samples")]
pub struct RaggedSamples {
    /// Length of the rejected byte vector.
    pub len: usize,
    /// The kind it was meant to hold.
    pub kind: SampleKind,
}

impl Samples {
    /// Wraps little-endian bytes; fails if they are not a whole number of samples.
    pub fn from_le_bytes(kind: SampleKind, bytes: Vec<u8>) -> Result<Self, RaggedSamples> {
        if !bytes.len().is_multiple_of(kind.size_bytes()) {
            return Err(RaggedSamples {
                len: bytes.len(),
                kind,
            });
        }
        Ok(Samples {
            kind,
            bytes,
            start: 0,
        })
    }

    /// Wraps the little-endian bytes of `bytes` from `start` on, keeping the bytes before it
    /// (a file's header) in the same allocation instead of moving every sample down by their
    /// length (a 268 MB move cost 20 ms on the H100 machine, `convert` in bench's first-pixel
    /// phases). Fails if they are not a whole number of samples; `start` past the end is an
    /// empty remainder of 0 bytes, which is whole.
    pub fn from_le_bytes_at(
        kind: SampleKind,
        bytes: Vec<u8>,
        start: usize,
    ) -> Result<Self, RaggedSamples> {
        let start = start.min(bytes.len());
        let len = bytes.len() - start;
        if !len.is_multiple_of(kind.size_bytes()) {
            return Err(RaggedSamples { len, kind });
        }
        Ok(Samples { kind, bytes, start })
    }

    /// Samples from u8 values.
    pub fn from_u8(values: Vec<u8>) -> Self {
        Samples {
            kind: SampleKind::U8,
            bytes: values,
            start: 0,
        }
    }

    /// Samples from i8 values.
    pub fn from_i8(values: &[i8]) -> Self {
        Samples {
            kind: SampleKind::I8,
            bytes: values.iter().map(|v| *v as u8).collect(),
            start: 0,
        }
    }

    /// Samples from u16 values.
    pub fn from_u16(values: &[u16]) -> Self {
        Samples {
            kind: SampleKind::U16,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
            start: 0,
        }
    }

    /// Samples from i16 values.
    pub fn from_i16(values: &[i16]) -> Self {
        Samples {
            kind: SampleKind::I16,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
            start: 0,
        }
    }

    /// Samples from f32 values (NaN and infinities allowed).
    pub fn from_f32(values: &[f32]) -> Self {
        Samples {
            kind: SampleKind::F32,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
            start: 0,
        }
    }

    /// The encoding.
    pub fn kind(&self) -> SampleKind {
        self.kind
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.as_bytes().len() / self.kind.size_bytes()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.as_bytes().is_empty()
    }

    /// The raw little-endian bytes, exactly what is uploaded to the GPU.
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes.get(self.start..).unwrap_or_default()
    }

    /// Stored value of sample `index` as f64 (exact for every kind). Panics only on an index out
    /// of range, which is a caller bug, never a data condition.
    pub fn get(&self, index: usize) -> f64 {
        let b = self.as_bytes();
        match self.kind {
            SampleKind::U8 => b[index] as f64,
            SampleKind::I8 => b[index] as i8 as f64,
            SampleKind::U16 => u16::from_le_bytes([b[2 * index], b[2 * index + 1]]) as f64,
            SampleKind::I16 => i16::from_le_bytes([b[2 * index], b[2 * index + 1]]) as f64,
            SampleKind::F32 => {
                let i = 4 * index;
                f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]) as f64
            }
        }
    }

    /// Every stored value as f64, in order (exact for every kind).
    pub fn to_f64_vec(&self) -> Vec<f64> {
        (0..self.len()).map(|i| self.get(i)).collect()
    }
}
