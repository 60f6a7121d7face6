//! Tiny DICOM files for the DICOM targets (explicit VR little endian, or deflated), built from
//! fuzzer bytes so that mutations land on the values the reader judges (Rows, Columns, counts,
//! the CSA header, the deflate stream) rather than on the framing.

/// One explicit-VR little-endian element.
pub fn element(group: u16, elem: u16, vr: &[u8; 2], value: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(12 + value.len());
    out.extend_from_slice(&group.to_le_bytes());
    out.extend_from_slice(&elem.to_le_bytes());
    out.extend_from_slice(vr);
    if matches!(vr, b"OB" | b"OW" | b"SQ" | b"UN" | b"UT") {
        out.extend_from_slice(&[0, 0]);
        out.extend_from_slice(&(value.len() as u32).to_le_bytes());
    } else {
        out.extend_from_slice(&(value.len().min(u16::MAX as usize) as u16).to_le_bytes());
    }
    out.extend_from_slice(value);
    out
}

/// Text padded to an even length.
pub fn text(s: &str) -> Vec<u8> {
    let mut b = s.as_bytes().to_vec();
    if b.len() % 2 == 1 {
        b.push(b' ');
    }
    b
}

/// Preamble, magic and a file meta group naming `syntax`.
pub fn preamble(syntax: &str) -> Vec<u8> {
    let mut uid = syntax.as_bytes().to_vec();
    if uid.len() % 2 == 1 {
        uid.push(0);
    }
    let items = [
        element(0x0002, 0x0001, b"OB", &[0, 1]),
        element(0x0002, 0x0010, b"UI", &uid),
    ]
    .concat();
    let mut out = vec![0u8; 128];
    out.extend_from_slice(b"DICM");
    out.extend_from_slice(&element(
        0x0002,
        0x0000,
        b"UL",
        &(items.len() as u32).to_le_bytes(),
    ));
    out.extend_from_slice(&items);
    out
}

/// The image elements every target file carries, before any group above 0x0028 (sorted).
pub fn image_elements(image_type: &str, rows: u16, cols: u16, position: [f64; 3]) -> Vec<u8> {
    let ds = |v: &[f64]| {
        text(
            &v.iter()
                .map(|x| format!("{x}"))
                .collect::<Vec<_>>()
                .join("\\"),
        )
    };
    [
        element(0x0008, 0x0008, b"CS", &text(image_type)),
        element(0x0008, 0x0016, b"UI", &text("1.2.840.10008.5.1.4.1.1.4")),
        element(0x0008, 0x0060, b"CS", &text("MR")),
        element(0x0020, 0x000E, b"UI", &text("1.2.3.4")),
        element(0x0020, 0x0032, b"DS", &ds(&position)),
        element(0x0020, 0x0037, b"DS", &ds(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0])),
        element(0x0028, 0x0002, b"US", &1u16.to_le_bytes()),
        element(0x0028, 0x0004, b"CS", &text("MONOCHROME2")),
        element(0x0028, 0x0010, b"US", &rows.to_le_bytes()),
        element(0x0028, 0x0011, b"US", &cols.to_le_bytes()),
        element(0x0028, 0x0030, b"DS", &ds(&[1.0, 1.0])),
        element(0x0028, 0x0100, b"US", &16u16.to_le_bytes()),
        element(0x0028, 0x0101, b"US", &16u16.to_le_bytes()),
        element(0x0028, 0x0103, b"US", &0u16.to_le_bytes()),
    ]
    .concat()
}

/// Raw deflate of `bytes` (the deflated transfer syntax's data set).
pub fn deflate(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut z = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::fast());
    // Writing into a Vec cannot fail.
    let _ = z.write_all(bytes);
    z.finish().unwrap_or_default()
}
