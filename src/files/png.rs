//! PNG output with provenance: every figure carries what is needed to re-render it exactly; and
//! PNG input as 8-bit RGBA (matcap images).
//!
//! Decisions:
//! - Provenance goes into tEXt chunks (readable by any PNG tool, e.g. `identify -verbose`
//!   or Python's PIL `.text`): `Software` (engine and version), `morphray:input` (file name or
//!   `phantom`), `morphray:input-sha256` (hash of the input file's bytes as read, or of the
//!   phantom's samples), `morphray:command` (the command line), `morphray:parameters` (all
//!   resolved parameters as JSON, including defaults the user did not type), and
//!   `morphray:warnings` (the loader's repairs and warnings about the input, a JSON list of
//!   sentences, `[]` when there were none: an image of a repaired file says so), and from
//!   `render` and the viewer `morphray:scene` (the scene document that reproduces the picture:
//!   `render --scene-from PICTURE.png`).
//! - The file is written through [`AtomicFile`]: a failure (a full disk included) leaves any
//!   previous image intact and no partial file.

use crate::files::write::{AtomicFile, OutputError};
use std::path::Path;

/// Provenance written into a PNG.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Provenance {
    /// File name, or `phantom`.
    pub input: String,
    /// SHA-256 (hex) of the input.
    pub input_sha256: String,
    /// The command line that produced the image.
    pub command: String,
    /// Every resolved parameter, as JSON.
    pub parameters: String,
    /// The loader's repairs and warnings about the input, one sentence each.
    pub warnings: Vec<String>,
    /// The scene document (`scene::document`, JSON) that reproduces the picture, when the
    /// writer has one; written as `morphray:scene`.
    pub scene: Option<String>,
}

impl Provenance {
    /// The tEXt chunks (key, value) in the order they are written (movies use them too).
    pub fn chunks(&self) -> Vec<(String, String)> {
        let software = format!("morphray {}", env!("CARGO_PKG_VERSION"));
        let warnings = serde_json::to_string(&self.warnings).unwrap_or_else(|_| "[]".into());
        [
            ("Software", software),
            ("morphray:input", self.input.clone()),
            ("morphray:input-sha256", self.input_sha256.clone()),
            ("morphray:command", self.command.clone()),
            ("morphray:parameters", self.parameters.clone()),
            ("morphray:warnings", warnings),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .chain(
            self.scene
                .iter()
                .map(|scene| ("morphray:scene".to_string(), scene.clone())),
        )
        .collect()
    }
}

/// A PNG that could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PngError {
    /// The output file could not be created, written or put in place.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The file to read could not be opened.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Cause.
        source: std::io::Error,
    },
    /// The file read is not a PNG this decoder can read.
    #[error("cannot read {path} as a PNG: {message}")]
    Decode {
        /// The file.
        path: String,
        /// Decoder message.
        message: String,
    },
    /// The encoder rejected the data.
    #[error("cannot encode {path} as PNG: {message}")]
    Encode {
        /// Output path.
        path: String,
        /// Encoder message.
        message: String,
    },
}

/// Writes an RGBA8 image with provenance chunks, atomically.
pub fn write_rgba8(
    path: &Path,
    width: u32,
    height: u32,
    rgba: &[u8],
    provenance: &Provenance,
) -> Result<(), PngError> {
    let _span = super::trace::span("encode and write PNG", "io");
    let mut file = AtomicFile::create(path)?;
    encode(&mut file, width, height, rgba, provenance).map_err(|e| match e {
        // The disk's own words ("no space left on device"), not "cannot encode".
        png::EncodingError::IoError(io) => PngError::Output(file.error(io)),
        other => PngError::Encode {
            path: path.display().to_string(),
            message: other.to_string(),
        },
    })?;
    Ok(file.commit()?)
}

/// The PNG stream with its tEXt chunks.
fn encode(
    out: &mut AtomicFile,
    width: u32,
    height: u32,
    rgba: &[u8],
    provenance: &Provenance,
) -> Result<(), png::EncodingError> {
    let mut encoder = png::Encoder::new(out, width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    for (key, value) in provenance.chunks() {
        encoder.add_text_chunk(key, value)?;
    }
    let mut writer = encoder.write_header()?;
    writer.write_image_data(rgba)?;
    writer.finish()
}

/// Reads the tEXt chunks of a PNG (for tests and for `render --from` style reuse).
pub fn read_text_chunks(path: &Path) -> Result<Vec<(String, String)>, PngError> {
    let shown = path.display().to_string();
    // Regular files only, at most 1 GiB (a FIFO must not block, a device must not fill memory).
    let bytes = crate::files::read::read_regular(path, 1 << 30).map_err(|e| PngError::Io {
        path: shown.clone(),
        source: std::io::Error::other(e.to_string()),
    })?;
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let reader = decoder.read_info().map_err(|e| PngError::Decode {
        path: shown.clone(),
        message: e.to_string(),
    })?;
    Ok(reader
        .info()
        .uncompressed_latin1_text
        .iter()
        .map(|c| (c.keyword.clone(), c.text.clone()))
        .collect())
}

/// Reads a PNG as 8-bit RGBA (grey, grey+alpha, RGB, palette and 16-bit images converted):
/// `(width, height, pixels)`, row-major from the top. Images wider or taller than `max_side`
/// are refused from the header, before their pixels are decoded.
pub fn read_rgba8(path: &Path, max_side: u32) -> Result<(u32, u32, Vec<u8>), PngError> {
    let shown = path.display().to_string();
    let bytes = crate::files::read::read_regular(path, 1 << 30).map_err(|e| PngError::Io {
        path: shown.clone(),
        source: std::io::Error::other(e.to_string()),
    })?;
    let bad = |message: String| PngError::Decode {
        path: shown.clone(),
        message,
    };
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(|e| bad(e.to_string()))?;
    let (width, height) = (reader.info().width, reader.info().height);
    if width > max_side || height > max_side {
        return Err(bad(format!(
            "{width}x{height} pixels; at most {max_side} per side are read"
        )));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| bad("the image does not fit in memory".into()))?;
    let mut buffer = vec![0u8; size];
    let frame = reader
        .next_frame(&mut buffer)
        .map_err(|e| bad(e.to_string()))?;
    buffer.truncate(frame.buffer_size());
    let rgba: Vec<u8> = match frame.color_type {
        png::ColorType::Rgba => buffer,
        png::ColorType::Rgb => buffer
            .chunks_exact(3)
            .flat_map(|p| [p[0], p[1], p[2], 255])
            .collect(),
        png::ColorType::GrayscaleAlpha => buffer
            .chunks_exact(2)
            .flat_map(|p| [p[0], p[0], p[0], p[1]])
            .collect(),
        png::ColorType::Grayscale => buffer.iter().flat_map(|&g| [g, g, g, 255]).collect(),
        png::ColorType::Indexed => return Err(bad("a palette image was not expanded".into())),
    };
    Ok((frame.width, frame.height, rgba))
}

/// SHA-256 of bytes, as lowercase hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn provenance_round_trips_through_the_file() {
        let path = std::env::temp_dir().join(format!("morphray-png-{}.png", std::process::id()));
        let provenance = Provenance {
            input: "scan.nii.gz".into(),
            input_sha256: sha256_hex(b"abc"),
            command: "morphray render scan.nii.gz -o x.png".into(),
            parameters: "{\"step\":0.5}".into(),
            warnings: vec!["pixdim[1] was 0; 1 mm used".into()],
            scene: Some("{\"format\":\"morphray-scene\"}".into()),
        };
        write_rgba8(&path, 2, 1, &[255, 0, 0, 255, 0, 255, 0, 255], &provenance).unwrap();
        let chunks = read_text_chunks(&path).unwrap();
        let get = |k: &str| {
            chunks
                .iter()
                .find(|(key, _)| key == k)
                .map(|(_, v)| v.clone())
        };
        assert_eq!(get("morphray:input").as_deref(), Some("scan.nii.gz"));
        assert_eq!(
            get("morphray:scene").as_deref(),
            Some("{\"format\":\"morphray-scene\"}")
        );
        assert_eq!(
            get("morphray:input-sha256").as_deref(),
            Some("ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad")
        );
        assert_eq!(
            get("morphray:parameters").as_deref(),
            Some("{\"step\":0.5}")
        );
        assert!(get("Software").unwrap().starts_with("morphray "));
        assert_eq!(
            get("morphray:warnings").as_deref(),
            Some("[\"pixdim[1] was 0; 1 mm used\"]")
        );
        let _ = std::fs::remove_file(path);
    }
}
