//! Arbitrary bytes as a single-file NIfTI (`parse`) and, split in two, as a `.hdr`/`.img` pair
//! (`parse_pair`). Bytes that are not gzip go straight to the header decoder; gzip ones are
//! inflated first (the `gzip` target explores that part in depth).
#![no_main]

use libfuzzer_sys::fuzz_target;
use morphray::volume::nifti::{LoadOptions, parse, parse_pair};
use morphray_fuzz::{check_error, check_loaded, split_point};

fuzz_target!(|data: &[u8]| {
    match parse(data.to_vec(), "fuzz.nii", &LoadOptions::default()) {
        Ok(loaded) => check_loaded(&loaded),
        Err(e) => check_error(&e),
    }
    let split = split_point(data);
    let (header, image) = data.split_at(split);
    // A frame other than 0 now and then exercises the frame offset arithmetic.
    let frame = usize::from(data.last().copied().unwrap_or(0) >> 6);
    match parse_pair(header, image.to_vec(), "fuzz.hdr", &LoadOptions { frame, mean: false }) {
        Ok(loaded) => {
            check_loaded(&loaded);
            assert_eq!(loaded.header.frame_loaded, frame);
        }
        Err(e) => check_error(&e),
    }
});
