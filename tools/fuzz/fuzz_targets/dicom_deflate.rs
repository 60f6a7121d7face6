//! The deflated transfer syntax (1.2.840.10008.1.2.1.99): two files in one folder, each a
//! preamble and meta group naming deflate, then a data set from the input. The first byte
//! picks the form: even, the rest of the input is the raw deflate stream itself (corrupt
//! streams, bombs, streams that end early); odd, the rest is an explicit-VR little-endian
//! data set after the target's own image elements (Rows and Columns from bytes 1..5), which
//! the target deflates (so mutations reach the element walk over the inflated bytes and the
//! bound by Rows x Columns x frames x bytes).
//!
//! Checks beyond "no panic": everything `dicom_series` checks (one-line messages, an accepted
//! volume fits its dims and has a usable geometry); run with `-malloc_limit_mb=512`, so an
//! inflation past what a header declares (a 4 KB input cannot honestly need more) is a crash.
#![no_main]

use libfuzzer_sys::fuzz_target;
use morphray_fuzz::dicom_check::{fresh_dir, survey_and_load};
use morphray_fuzz::dicom_file::{deflate, element, image_elements, preamble};

const DEFLATED: &str = "1.2.840.10008.1.2.1.99";

fuzz_target!(|data: &[u8]| {
    let Some((&form, rest)) = data.split_first() else {
        return;
    };
    let dir = fresh_dir("deflate");
    let stream = if form % 2 == 0 {
        rest.to_vec()
    } else {
        let word = |i: usize| {
            u16::from_le_bytes([*rest.get(i).unwrap_or(&8), *rest.get(i + 1).unwrap_or(&0)])
        };
        let (rows, cols) = (word(0) % 512, word(2) % 512);
        let tail = rest.get(4..).unwrap_or(&[]);
        let mut set = image_elements("ORIGINAL\\PRIMARY", rows, cols, [0.0, 0.0, 0.0]);
        set.extend_from_slice(tail);
        if !tail.starts_with(&[0xE0, 0x7F]) {
            let pixels = vec![7u8; rows as usize * cols as usize * 2];
            set.extend_from_slice(&element(0x7FE0, 0x0010, b"OW", &pixels));
        }
        deflate(&set)
    };
    for n in 0..2 {
        let mut file = preamble(DEFLATED);
        file.extend_from_slice(&stream);
        std::fs::write(dir.join(format!("f{n}.dcm")), &file).expect("a temporary file");
    }
    survey_and_load(dir);
});
