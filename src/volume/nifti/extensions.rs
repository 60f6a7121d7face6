//! Header extensions: listed best effort, never needed to show the image.
//!
//! Decisions:
//! - Extensions follow the four extender bytes: from byte 352 (NIfTI-1) or 544 (NIfTI-2) up to
//!   `vox_offset` in a single file, or to the end of a `.hdr`. `extender[0] == 0` means none.
//! - Each is `esize` (i32, a multiple of 16 and at least 16, counting its own 8-byte head),
//!   `ecode` (i32), then `esize - 8` bytes. On the first inconsistency (size not a multiple of
//!   16, or running past the region) the whole list is dropped with one warning: partial lists
//!   are more misleading than none, and no extension changes how voxels are read.
//! - All-zero bytes after the last extension are padding (writers round vox_offset up), not
//!   an error.
//! - The flag set with no room for even one extension (fewer than 16 bytes, all zero, between
//!   the extender and the voxels or the end of the `.hdr`) is a warning: the flag says
//!   something the file does not hold.
//! - Only codes and sizes are kept (the summary lists them); the payloads are not interpreted.

use super::header::ByteOrder;

/// One header extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Extension {
    /// `ecode` (for example 4 = AFNI, 6 = comment, 32 = CIFTI).
    pub code: i32,
    /// `esize`: bytes including the 8-byte head.
    pub size: usize,
}

/// Parses the extensions in `region` (the bytes after the extender). Returns the list, or an
/// empty list and a warning when the list is inconsistent.
pub fn parse(region: &[u8], order: ByteOrder) -> (Vec<Extension>, Option<String>) {
    let read = |at: usize| -> Option<i32> {
        let b: [u8; 4] = region.get(at..at.checked_add(4)?)?.try_into().ok()?;
        Some(match order {
            ByteOrder::LittleEndian => i32::from_le_bytes(b),
            ByteOrder::BigEndian => i32::from_be_bytes(b),
        })
    };
    if region.len() < 16 && region.iter().all(|&b| b == 0) {
        return (
            Vec::new(),
            Some(format!(
                "the header's extension flag is set, but there is no room for an extension: {} bytes follow the extender where an extension needs at least 16; the flag is ignored",
                region.len()
            )),
        );
    }
    let mut out = Vec::new();
    let mut at = 0usize;
    while at < region.len() {
        // Zero bytes after the last extension are padding up to vox_offset, not an extension.
        if region
            .get(at..)
            .is_some_and(|rest| rest.iter().all(|&b| b == 0))
        {
            break;
        }
        let bad = |why: String| {
            (
                Vec::new(),
                Some(format!("header extensions ignored: {why}")),
            )
        };
        let (Some(esize), Some(code)) = (read(at), at.checked_add(4).and_then(read)) else {
            return bad(format!(
                "an extension at byte {at} of the extension area is cut off by the end of the area ({} bytes)",
                region.len()
            ));
        };
        let size = match usize::try_from(esize) {
            Ok(s) if s >= 16 && s.is_multiple_of(16) => s,
            _ => {
                return bad(format!(
                    "an extension declares esize {esize}, which is not a positive multiple of 16"
                ));
            }
        };
        let end = match at.checked_add(size) {
            Some(end) if end <= region.len() => end,
            _ => {
                return bad(format!(
                    "an extension of {size} bytes at byte {at} runs past the end of the {}-byte extension area",
                    region.len()
                ));
            }
        };
        out.push(Extension { code, size });
        at = end;
    }
    (out, None)
}
