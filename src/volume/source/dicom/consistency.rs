//! DICOM tags checked against the data they describe, before anything is decoded: a file
//! whose tags contradict its pixel data is refused with one line (listed as skipped), never
//! read with the data cut, padded or misread (issue 30).
//!
//! Decisions:
//! - In the native encodings (implicit or explicit VR, little or big endian, deflated), the
//!   PixelData length must be Rows x Columns x frames x SamplesPerPixel x BitsAllocated / 8,
//!   padded to an even length: longer data would be cut silently, shorter data fails later
//!   with a decoder's "Frame #0 is out of range". Encapsulated (compressed) pixel data has no
//!   such length; its decoder checks the frames it gives.
//! - Rows and Columns of 0, BitsAllocated outside 1..64 and BitsStored of 0 or above
//!   BitsAllocated are refused where the header is read (`headers`).

use super::headers::FileHeader;

/// Transfer syntaxes whose pixel data is stored as plain samples.
const NATIVE: [&str; 4] = [
    "1.2.840.10008.1.2",
    "1.2.840.10008.1.2.1",
    "1.2.840.10008.1.2.2",
    "1.2.840.10008.1.2.1.99",
];

/// Bytes of pixel data `h`'s tags declare (None on overflow).
pub fn declared_pixel_bytes(h: &FileHeader) -> Option<u64> {
    let (rows, cols) = h.stored_size();
    let values = (rows as u64)
        .checked_mul(cols as u64)?
        .checked_mul(h.stored_frames() as u64)?
        .checked_mul(h.samples_per_pixel.max(1) as u64)?;
    values
        .checked_mul(h.bits_allocated as u64)
        .map(|bits| bits.div_ceil(8))
}

/// Refuses a file whose PixelData length contradicts its tags (see the module's decisions).
pub fn check(h: &FileHeader) -> Result<(), String> {
    let Some(len) = h.pixel_bytes else {
        return Ok(());
    };
    if !NATIVE.contains(&h.transfer_syntax.as_str()) {
        return Ok(());
    }
    let (rows, cols) = h.stored_size();
    let frames = h.stored_frames();
    let declared = declared_pixel_bytes(h).unwrap_or(u64::MAX);
    let tags = format!(
        "Rows x Columns x frames {rows} x {cols} x {frames}{} at {} bits",
        if h.samples_per_pixel > 1 {
            format!(" x {} samples", h.samples_per_pixel)
        } else {
            String::new()
        },
        h.bits_allocated
    );
    if len < declared {
        return Err(format!(
            "{tags} declare {declared} bytes of pixels but PixelData holds only {len}: the file \
             is truncated or its tags are wrong"
        ));
    }
    if len > declared + declared % 2 {
        return Err(format!(
            "PixelData holds {len} bytes but {tags} declare {declared}: the tags contradict the \
             data (reading it would cut the image)"
        ));
    }
    Ok(())
}
