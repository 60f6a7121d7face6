//! The DICOM targets' shared run: a fresh folder per process (emptied before each input), a
//! panic hook that lets the reader's contained dicom-rs panics unwind, and the invariants on
//! what `dicom::survey` and `dicom::load` return (as in the `dicom_series` target).

use morphray::volume::Volume;
use morphray::volume::source::dicom;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The process's folder, emptied.
pub fn fresh_dir(tag: &str) -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    let dir = DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("morphray-fuzz-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("a temporary directory");
        let abort = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if dicom::panic_is_contained() {
                static SEEN: AtomicUsize = AtomicUsize::new(0);
                if SEEN.fetch_add(1, Ordering::Relaxed) < 5 {
                    eprintln!("contained dicom-rs panic: {info}");
                }
                return;
            }
            abort(info);
        }));
        d
    });
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let _ = std::fs::remove_file(e.path());
    }
    dir
}

fn one_line(text: &str) {
    assert!(
        !text.is_empty() && !text.contains('\n'),
        "not one line: {text:?}"
    );
}

/// Survey and load `dir`; checks every message is one line and an accepted volume is usable.
/// Returns the volume, when one was accepted.
pub fn survey_and_load(dir: &Path) -> Option<Volume> {
    match dicom::survey(dir) {
        Err(e) => one_line(&e.to_string()),
        Ok(survey) => {
            for s in survey.series() {
                if let Some(d) = s.dims {
                    assert!(d.iter().all(|&n| n > 0), "empty dims {d:?}");
                    assert!(s.affine.is_some() && s.spacing.is_some());
                }
                s.warnings.iter().for_each(|w| one_line(w));
            }
            survey.skipped().iter().for_each(|s| one_line(&s.reason));
        }
    }
    match dicom::load(dir, None) {
        Err(e) => {
            one_line(&e.to_string());
            None
        }
        Ok((v, _)) => {
            assert_eq!(v.samples.len(), v.dims.iter().product::<usize>());
            super::check_orientation(&v.orientation);
            super::check_warnings(&v.warnings);
            assert!(v.spacing_mm.iter().all(|s| s.is_finite() && *s > 0.0));
            assert!(v.to_physical.slope.is_finite() && v.to_physical.slope != 0.0);
            assert!(v.to_physical.intercept.is_finite());
            Some(v)
        }
    }
}
