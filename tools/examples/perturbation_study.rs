//! The perturbation study of the peak finder (issue 11, item 2) on a T1 volume with GM and WM
//! probability maps: the original and five scanner perturbations (src/study/perturb.rs), each
//! run through the real GPU path under the minmax and the robust normalization, each tissue peak
//! scored against the 10th-90th percentile of that tissue's intensities.
//!
//! Run (the maps come from tools/perturbation/fetch-templates.sh):
//! `cargo run --release --example perturbation_study -- T1.nii.gz GM.nii.gz WM.nii.gz OUT_DIR
//! [--write-volumes]`
//!
//! Writes OUT_DIR/perturbation_study.md (the table) and OUT_DIR/perturbation_study.json, and
//! prints the table; with `--write-volumes` also OUT_DIR/<perturbation>.nii.gz (never replacing
//! an existing file), so that `morphray render` can be tried on them.

use morphray::analysis::NormalizeMode;
use morphray::engine::EngineConfig;
use morphray::study::perturb::{build_all, labels_from_maps};
use morphray::study::perturb_run::{markdown, run_study};
use morphray::volume::nifti::{LoadOptions, load_path, write_new_nifti1};
use std::path::{Path, PathBuf};

const USAGE: &str =
    "usage: perturbation_study T1.nii[.gz] GM.nii[.gz] WM.nii[.gz] OUT_DIR [--write-volumes]";

fn main() {
    if let Err(e) = run() {
        eprintln!("morphray: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let write_volumes = match args.iter().position(|a| a == "--write-volumes") {
        Some(i) => {
            args.remove(i);
            true
        }
        None => false,
    };
    let Ok([t1, gm, wm, out]) = <[String; 4]>::try_from(args) else {
        eprintln!("{USAGE}");
        std::process::exit(2);
    };
    let load = |path: &str| {
        load_path(Path::new(path), &LoadOptions::default())
            .map(|l| l.volume)
            .map_err(|e| format!("cannot load {path}: {e}"))
    };
    let (t1v, gmv, wmv) = (load(&t1)?, load(&gm)?, load(&wm)?);
    let labels = labels_from_maps(&t1v, &gmv, &wmv).map_err(|e| e.to_string())?;
    let volumes = build_all(&t1v, &labels).map_err(|e| e.to_string())?;
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out)
        .map_err(|e| format!("cannot create the output directory {}: {e}", out.display()))?;
    if write_volumes {
        for p in &volumes {
            let path = out.join(format!("{}.nii.gz", p.kind.name()));
            write_new_nifti1(&p.volume, &path, true)
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            println!("wrote {}", path.display());
        }
    }
    let report = run_study(
        &t1v.name,
        &volumes,
        &[NormalizeMode::MinMax, NormalizeMode::Robust],
        &EngineConfig::default(),
    )
    .map_err(|e| format!("the GPU path failed: {e}"))?;
    let table = markdown(&report);
    let json = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    for (name, text) in [
        ("perturbation_study.md", &table),
        ("perturbation_study.json", &json),
    ] {
        let path = out.join(name);
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    print!("{table}");
    Ok(())
}
