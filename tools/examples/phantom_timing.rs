//! Times the cohort-A phantom's generation (256x256x192) on all cores and on one: five runs each,
//! min / median / max in milliseconds. A measurement, not a test (timings are never asserted).
//!
//! Run: `cargo run --release --example phantom_timing`

use morphray::volume::phantom::{PhantomSpec, generate, generate_with_threads};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let spec = PhantomSpec::cohort_a();
    let _warm = generate(&PhantomSpec::cube(32))?;
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    for threads in [all, 1] {
        let mut times = Vec::new();
        for _ in 0..5 {
            let t = std::time::Instant::now();
            let phantom = generate_with_threads(&spec, threads)?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
            if phantom.labels.len() != 12_582_912 {
                return Err("the phantom has the wrong number of voxels".into());
            }
        }
        times.sort_by(f64::total_cmp);
        println!(
            "cohort A (256x256x192) on {threads} thread(s): min {:.1} ms, median {:.1} ms, max {:.1} ms",
            times[0], times[2], times[4]
        );
    }
    Ok(())
}
