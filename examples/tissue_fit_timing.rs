//! Host time of the tissue fit (issue 28: <= 2 ms for 256 bins): reads each NIfTI given, takes
//! the 256-bin histogram of I_norm (min/max) above the first bin, and times
//! `analysis::tissue_fit::fit_tissues` (T1 labels) 200 times; prints the median and the 90th
//! percentile. `cargo run --release --example tissue_fit_timing -- FILE.nii.gz ...`

use morphray::analysis::contrast::Contrast;
use morphray::analysis::tissue_fit::{FitDomain, fit_tissues, occupied_range};
use morphray::volume::source::{ReadOptions, VolumeSource, read};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for path in std::env::args().skip(1) {
        let source = VolumeSource::from_paths(&[path.clone().into()]);
        let v = read(&source, &ReadOptions::default())?.volume;
        let n = v.samples.len();
        let phys: Vec<f64> = (0..n)
            .map(|i| v.to_physical.apply(v.samples.get(i)))
            .filter(|x| x.is_finite())
            .collect();
        let (lo, hi) = phys
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let hist = morphray::reference::histogram_of_samples(&v.samples, v.to_physical, lo, hi)
            .map(f64::from);
        let range = occupied_range(&hist, 1);
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..200 {
            let t = Instant::now();
            last = fit_tissues(&hist, range, Contrast::T1, FitDomain::Foreground, (lo, hi));
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        let iterations = last.map_or(0, |(f, _)| f.iterations);
        println!(
            "{path}: median {:.3} ms, p90 {:.3} ms ({iterations} EM iterations)",
            times[100], times[180]
        );
    }
    Ok(())
}
