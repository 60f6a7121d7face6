//! Brain extraction's f64 twin (`morphray::reference::brain`) on a NIfTI file, normalized as
//! morphray does by default (robust range P0.5..P99.5 of the foreground plus headroom, eq. 1),
//! for measuring its Dice against a reference mask and its time, and for sweeping the
//! morphology's radii.
//!
//! Run: `cargo run --release --example brain_twin -- IN.nii[.gz] [--reference MASK.nii[.gz]]
//! [--out OUT.nii.gz] [--contrast t1|t2] [--band LO,HI] [--erode MM[,MM..]] [--close MM[,..]] [--grow MM[,..]]
//! [--sigma MM] [--coarse F]`
//!
//! Prints the band, the time of each part, the mask's volume in cm^3, the head test and (with
//! `--reference`, any nonzero voxel is brain) the Dice; `--band` replaces `band_for`'s band; with lists of radii, one line per
//! combination. `--out` writes the mask of the first combination as uint8 0/1 NIfTI with the
//! input's affine (never replacing an existing file).

use morphray::analysis::brain_band::band_for;
use morphray::analysis::range::exact_robust_range;
use morphray::analysis::{BrainParams, Contrast, analyze};
use morphray::reference::brain::{extract, is_head};
use morphray::reference::brain_components::{
    hole_fill_cells, largest_component_selection, slab_axis,
};
use morphray::reference::{histogram, normalize};
use morphray::volume::nifti::write_new_nifti1;
use morphray::volume::{LinearMap, Samples, Volume};
use std::path::{Path, PathBuf};
use std::time::Instant;

const USAGE: &str = "usage: brain_twin IN.nii[.gz] [--reference MASK] [--out OUT.nii.gz] \
[--contrast t1|t2] [--band LO,HI] [--erode MM[,MM..]] [--close MM[,..]] [--grow MM[,..]] [--sigma MM] [--coarse F]";

struct Args {
    input: PathBuf,
    reference: Option<PathBuf>,
    out: Option<PathBuf>,
    contrast: Option<Contrast>,
    band: Option<(f64, f64)>,
    erode: Vec<f64>,
    close: Vec<f64>,
    grow: Vec<f64>,
    sigma: f64,
    coarse: usize,
}

fn main() {
    if let Err(e) = run() {
        eprintln!("brain_twin: {e}");
        std::process::exit(1);
    }
}

fn list(text: &str) -> Result<Vec<f64>, String> {
    text.split(',')
        .map(|x| {
            x.parse()
                .map_err(|_| format!("{x:?} is not a number\n{USAGE}"))
        })
        .collect()
}

fn parse() -> Result<Args, String> {
    let d = BrainParams::default();
    let mut a = Args {
        input: PathBuf::new(),
        reference: None,
        out: None,
        contrast: None,
        band: None,
        erode: vec![d.erode_mm],
        close: vec![d.close_mm],
        grow: vec![d.grow_mm],
        sigma: d.sigma_mm,
        coarse: d.coarse,
    };
    let mut it = std::env::args().skip(1);
    let mut input = None;
    while let Some(arg) = it.next() {
        let mut value = || {
            it.next()
                .ok_or_else(|| format!("{arg} needs a value\n{USAGE}"))
        };
        match arg.as_str() {
            "--reference" => a.reference = Some(value()?.into()),
            "--out" => a.out = Some(value()?.into()),
            "--contrast" => {
                a.contrast = Some(match value()?.as_str() {
                    "t1" => Contrast::T1,
                    "t2" => Contrast::T2,
                    other => return Err(format!("unknown contrast {other:?}\n{USAGE}")),
                })
            }
            "--band" => match list(&value()?)?[..] {
                [lo, hi] => a.band = Some((lo, hi)),
                _ => return Err(format!("--band takes LO,HI\n{USAGE}")),
            },
            "--erode" => a.erode = list(&value()?)?,
            "--close" => a.close = list(&value()?)?,
            "--grow" => a.grow = list(&value()?)?,
            "--sigma" => a.sigma = list(&value()?)?[0],
            "--coarse" => a.coarse = value()?.parse().map_err(|_| USAGE.to_string())?,
            _ if input.is_none() && !arg.starts_with("--") => input = Some(PathBuf::from(&arg)),
            _ => return Err(USAGE.to_string()),
        }
    }
    a.input = input.ok_or_else(|| USAGE.to_string())?;
    Ok(a)
}

/// Column norms of the affine's linear part (the spacing brain extraction uses).
fn spacing_of(v: &Volume) -> [f64; 3] {
    let l = v.orientation.linear_part();
    [0, 1, 2].map(|c| (0..3).map(|r| l[r][c].powi(2)).sum::<f64>().sqrt())
}

fn dice(a: &[u8], b: &[bool]) -> f64 {
    let both = a.iter().zip(b).filter(|(x, y)| **x != 0 && **y).count();
    let total = a.iter().filter(|x| **x != 0).count() + b.iter().filter(|x| **x).count();
    2.0 * both as f64 / total as f64
}

fn run() -> Result<(), String> {
    let args = parse()?;
    let load = |p: &Path| Volume::open(p).map_err(|e| format!("cannot load {}: {e}", p.display()));
    let t = Instant::now();
    let volume = load(&args.input)?;
    let reference = match &args.reference {
        Some(p) => {
            let r = load(p)?;
            if r.dims != volume.dims {
                return Err(format!("the reference's dims {:?} differ", r.dims));
            }
            Some(
                (0..r.samples.len())
                    .map(|i| r.samples.get(i) > 0.0)
                    .collect::<Vec<_>>(),
            )
        }
        None => None,
    };
    let load_s = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let range = exact_robust_range(&volume.samples, volume.to_physical)
        .ok_or("the volume has no finite voxel")?;
    let norm = normalize(&volume.samples, volume.to_physical, range.lo, range.hi);
    let f32s: Vec<f32> = norm.iter().map(|&v| v as f32).collect();
    let hist = histogram(&f32s, |i| volume.samples.get(i).is_finite());
    let report = analyze(&hist, range.lo, range.hi, norm.len(), 0);
    let contrast = args.contrast.unwrap_or(report.contrast.contrast);
    let (lo, hi) = match args.band {
        Some(band) => band,
        None => band_for(&hist, contrast).ok_or("the histogram has no split (constant)")?,
    };
    // The twin takes the GPU's f32 values as f64.
    let input: Vec<f64> = f32s.iter().map(|&v| f64::from(v)).collect();
    let prep_s = t.elapsed().as_secs_f64();

    let h = spacing_of(&volume);
    println!(
        "{}: dims {:?}, spacing {:.3?} mm, range {:.2}..{:.2}, contrast {} ({}), band {lo:.4}..{hi:.4} \
         (raw {:.1}..{:.1}), load {load_s:.2} s, normalize+histogram {prep_s:.2} s",
        volume.name,
        volume.dims,
        h,
        range.lo,
        range.hi,
        contrast.name(),
        report.contrast.summary(),
        range.lo + lo * (range.hi - range.lo),
        range.lo + hi * (range.hi - range.lo),
    );
    let voxel_mm3 = h.iter().product::<f64>();
    let mut first = true;
    for &erode_mm in &args.erode {
        for &close_mm in &args.close {
            for &grow_mm in &args.grow {
                let params = BrainParams {
                    sigma_mm: args.sigma,
                    lo,
                    hi,
                    erode_mm,
                    close_mm,
                    grow_mm,
                    coarse: args.coarse,
                    ..BrainParams::for_band(lo, hi)
                };
                let t = Instant::now();
                let out = extract(&input, volume.dims, h, &params).map_err(|e| e.to_string())?;
                let twin_s = t.elapsed().as_secs_f64();
                let head = is_head(&out.smoothed, &out.mask, lo, voxel_mm3);
                let t = Instant::now();
                let _ = largest_component_selection(&out.coarse_core, out.coarse_dims);
                let cc_ms = t.elapsed().as_secs_f64() * 1e3;
                let t = Instant::now();
                let _ = hole_fill_cells(&out.coarse_closed, out.coarse_dims, slab_axis(h));
                let fill_ms = t.elapsed().as_secs_f64() * 1e3;
                let d = reference.as_ref().map_or(String::new(), |r| {
                    format!(", Dice {:.4}", dice(&out.mask, r))
                });
                println!(
                    "erode {erode_mm} close {close_mm} grow {grow_mm}: found {}, mask {:.0} cm3, \
                     head {} (outside {:.3}){d}; twin {twin_s:.2} s, coarse {:?}: components \
                     {cc_ms:.1} ms, hole fill {fill_ms:.1} ms",
                    out.found, head.mask_cm3, head.is_head, head.outside_fraction, out.coarse_dims,
                );
                if first && let Some(path) = &args.out {
                    write_mask(&volume, out.mask, path)?;
                    println!("wrote {}", path.display());
                }
                first = false;
            }
        }
    }
    Ok(())
}

fn write_mask(volume: &Volume, mask: Vec<u8>, path: &Path) -> Result<(), String> {
    let m = Volume::from_voxels(
        "brain",
        volume.dims,
        Samples::from_u8(mask),
        volume.orientation.affine,
        LinearMap::IDENTITY,
    )
    .map_err(|e| e.to_string())?;
    let gz = path.extension().is_some_and(|e| e == "gz");
    write_new_nifti1(&m, path, gz).map_err(|e| format!("cannot write {}: {e}", path.display()))
}
