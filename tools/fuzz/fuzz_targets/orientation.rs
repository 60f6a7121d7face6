//! Arbitrary bytes as the orientation fields of a header: `orientation::resolve` must be total
//! (no panic, a finite affine whose 3x3 part the derivative twin can invert, a finite positive
//! spacing, one-line warnings) for every bit pattern.
#![no_main]

use libfuzzer_sys::fuzz_target;
use morphray::volume::AffineSource;
use morphray::volume::nifti::orientation::resolve;
use morphray_fuzz::{check_geometry, orientation_fields};

fuzz_target!(|data: &[u8]| {
    let f = orientation_fields(data);
    let g = resolve(&f);
    check_geometry(&g);
    // The priority rule: the source is never one whose code is not set.
    match g.orientation.source {
        AffineSource::Sform => assert!(f.sform_code > 0),
        AffineSource::Qform => assert!(f.qform_code > 0),
        AffineSource::Pixdim => {}
        AffineSource::Synthetic | AffineSource::Dicom => {
            panic!("resolve never builds a synthetic or DICOM affine")
        }
    }
    // Total and deterministic: the same fields give the same answer.
    assert_eq!(resolve(&f), g);
});
