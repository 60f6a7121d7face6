//! Siemens mosaics: one explicit-VR little-endian file with ImageType MOSAIC, whose
//! NumberOfImagesInMosaic (0019,100A), Rows, Columns and a CSA header (0029,1010) come from
//! the input, then pixel data of the remaining bytes (often too short or too long, which the
//! tag checks must refuse). Bytes: 0..2 images, 2..4 rows, 4..6 columns (each mod 512), 6 the
//! CSA header's length, 7 flags (bit 0: the CSA bytes get a valid "SV10" head, so its tag loop
//! is reached), then the CSA bytes, then pixel bytes; when the last byte is odd the pixel data
//! is padded or cut to exactly Rows x Columns x 2.
//!
//! Checks beyond "no panic": everything `dicom_series` checks; an accepted mosaic volume has
//! the tile size of a ceil(sqrt(n)) grid and n slices, and its slice spacing is positive.
#![no_main]

use libfuzzer_sys::fuzz_target;
use morphray_fuzz::dicom_check::{fresh_dir, survey_and_load};
use morphray_fuzz::dicom_file::{element, image_elements, preamble, text};

fuzz_target!(|data: &[u8]| {
    if data.len() < 9 {
        return;
    }
    let word = |i: usize| u16::from_le_bytes([data[i], data[i + 1]]) % 512;
    let (images, rows, cols) = (word(0), word(2), word(4));
    let csa_len = data[6] as usize;
    let rest = &data[8..];
    let cut = csa_len.min(rest.len());
    let mut csa = Vec::new();
    if data[7] & 1 == 1 {
        csa.extend_from_slice(b"SV10\x04\x03\x02\x01");
        csa.extend_from_slice(&2u32.to_le_bytes());
        csa.extend_from_slice(&77u32.to_le_bytes());
    }
    csa.extend_from_slice(&rest[..cut]);
    if csa.len() % 2 == 1 {
        csa.push(0);
    }
    let mut pixels = rest[cut..].to_vec();
    if data[data.len() - 1] % 2 == 1 {
        pixels.resize(rows as usize * cols as usize * 2, 3);
    }
    if pixels.len() % 2 == 1 {
        pixels.push(0);
    }
    let mut file = preamble("1.2.840.10008.1.2.1");
    let mut set = image_elements(
        "ORIGINAL\\PRIMARY\\M\\ND\\MOSAIC",
        rows,
        cols,
        [-100.0, -90.0, 10.0],
    );
    // (0019,xxxx) sorts between groups 0x0008 and 0x0020: inserted there.
    let split = set
        .windows(4)
        .position(|w| w == [0x20, 0x00, 0x0E, 0x00])
        .unwrap_or(set.len());
    let private = [
        element(0x0019, 0x0010, b"LO", &text("SIEMENS MR HEADER")),
        element(0x0019, 0x100A, b"US", &images.to_le_bytes()),
    ]
    .concat();
    set.splice(split..split, private);
    // (0029,xxxx) follows every (0028,xxxx) element: appended.
    set.extend_from_slice(&element(0x0029, 0x0010, b"LO", &text("SIEMENS CSA HEADER")));
    set.extend_from_slice(&element(0x0029, 0x1010, b"OB", &csa));
    file.extend_from_slice(&set);
    file.extend_from_slice(&element(0x7FE0, 0x0010, b"OW", &pixels));
    let dir = fresh_dir("mosaic");
    std::fs::write(dir.join("mosaic.dcm"), &file).expect("a temporary file");
    if let Some(v) = survey_and_load(dir) {
        assert!(v.spacing_mm[2] > 0.0);
        let n = images as usize;
        if n >= 2 && v.dims[2] == n {
            let side = (n as f64).sqrt().ceil() as usize;
            assert_eq!(
                [v.dims[0], v.dims[1]],
                [cols as usize / side, rows as usize / side],
                "tile size of a {side}x{side} grid"
            );
        }
    }
});
