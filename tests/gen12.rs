//! Intel's own compiler on every kernel: `morphray kernels` on the stub Tiger Lake that
//! tools/gen12/setup.sh builds (ANV and Mesa's no-op DRM shim; tools/setup.sh runs it, cached
//! under ~/.cache/morphray/gen12). Nothing is dispatched there: the stub compiles and reports
//! limits, it does not execute.
//!
//! A missing stub fails these tests with the command that builds it; they never pass silently.

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::{Command, Output};

/// The environment lines setup.sh wrote (LD_PRELOAD, INTEL_STUB_GPU_PLATFORM, VK_ICD_FILENAMES).
fn stub_env() -> Vec<(String, String)> {
    let dir = std::env::var_os("MORPHRAY_GEN12_DIR")
        .map(PathBuf::from)
        .or_else(|| {
            let cache = std::env::var_os("XDG_CACHE_HOME")
                .map(PathBuf::from)
                .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
            Some(cache.join("morphray/gen12"))
        })
        .expect("HOME or XDG_CACHE_HOME is set");
    let text = std::fs::read_to_string(dir.join("env")).unwrap_or_else(|e| {
        panic!(
            "the stub Tiger Lake is not built ({}: {e}); run tools/gen12/setup.sh (tools/setup.sh \
             runs it)",
            dir.join("env").display()
        )
    });
    text.lines()
        .filter_map(|l| l.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

fn on_stub(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .envs(stub_env())
        // The stub's ICD is the only driver; no validation layer (it would validate a device
        // that never executes, and it is not what is measured here).
        .env("MORPHRAY_VALIDATION", "off")
        .env("MORPHRAY_DEVICE", "0")
        .output()
        .expect("the morphray binary runs")
}

fn kernels_json(extra: &[&str]) -> serde_json::Value {
    let mut args: Vec<&str> = extra.to_vec();
    args.extend(["kernels", "--json", "--size", "256x256"]);
    let o = on_stub(&args);
    assert!(
        o.status.success(),
        "morphray {}: {}",
        args.join(" "),
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("kernels --json prints JSON")
}

/// (variant, statistics) of every kernel, after checking each has Intel's statistics.
fn statistics(report: &serde_json::Value) -> Vec<(String, HashMap<String, f64>)> {
    let device = report["device"].as_str().unwrap();
    assert!(device.contains("TGL"), "not the stub Tiger Lake: {device}");
    let kernels = report["kernels"].as_array().unwrap();
    assert!(kernels.len() >= 6, "{report}");
    kernels
        .iter()
        .map(|k| {
            let variant = k["variant"].as_str().unwrap().to_string();
            let stats: HashMap<String, f64> = k["statistics"]
                .as_object()
                .unwrap_or_else(|| panic!("{variant}: no statistics"))
                .iter()
                .map(|(name, v)| (name.clone(), v.as_f64().unwrap_or(f64::NAN)))
                .collect();
            for name in [
                "Instruction Count",
                "Cycle Count",
                "Spill Count",
                "SEND Count",
            ] {
                assert!(
                    stats.get(name).is_some_and(|v| v.is_finite()),
                    "{variant}: no {name} in {stats:?}"
                );
            }
            assert!(stats["Instruction Count"] > 0.0, "{variant}");
            let simd = k["executables"][0]["subgroup_size"].as_u64().unwrap();
            assert!([8, 16, 32].contains(&simd), "{variant}: SIMD{simd}");
            (variant, stats)
        })
        .collect()
}

#[test]
fn every_kernel_of_the_default_plan_compiles_for_tgl_with_intel_statistics() {
    let report = kernels_json(&[]);
    let kernels = statistics(&report);
    for pass in [
        "minmax",
        "normalize",
        "histogram",
        "derivatives",
        "raymarch",
    ] {
        assert!(
            kernels.iter().any(|(v, _)| v.starts_with(pass)),
            "{pass} missing from {report}"
        );
    }
}

#[test]
fn no_kernel_of_the_gen12_plan_spills_at_the_profiles_defaults() {
    let report = kernels_json(&["--profile", "gen12"]);
    for (variant, stats) in statistics(&report) {
        assert_eq!(stats["Spill Count"], 0.0, "{variant} spills: {stats:?}");
        assert_eq!(stats["Fill Count"], 0.0, "{variant} fills: {stats:?}");
    }
    // The profile's tunable kernels take its 8x8 workgroup.
    let kernels = report["kernels"].as_array().unwrap();
    let raymarch = kernels
        .iter()
        .find(|k| k["name"] == "raymarch")
        .expect("a raymarch kernel");
    assert_eq!(raymarch["workgroup"], serde_json::json!([8, 8, 1]));
}

#[test]
fn the_gen12_profile_matches_the_limits_the_stub_tgl_reports() {
    let report = kernels_json(&[]);
    let limits = &report["limits"];
    let profile = morphray::gpu::DeviceProfile::load("gen12").unwrap();
    assert_eq!(
        limits["max_image_dimension_3d"].as_u64(),
        profile.max_image_dimension_3d.map(u64::from),
        "{limits}"
    );
    let range = limits["subgroup_size_range"].as_array().unwrap();
    let sizes = profile.subgroup_sizes.clone().unwrap();
    assert_eq!(range[0].as_u64(), sizes.first().map(|&s| s as u64));
    assert_eq!(range[1].as_u64(), sizes.last().map(|&s| s as u64));
    assert_eq!(limits["unified_memory"], profile.unified_memory);
    assert_eq!(limits["float_atomics"], profile.float_atomics);
    assert_eq!(
        limits["timestamp_valid_bits"].as_u64(),
        profile.timestamp_valid_bits.map(u64::from)
    );
}

#[test]
fn every_variant_compiles_for_tgl_and_only_bricked_on_the_fly_curvature_spills() {
    // Every variant a scene can select (401 kernels, about two minutes on 2 cores). The spilling
    // family is named with its reason in BENCHMARKS.md: 19 fetches per sample through the brick
    // table keep more addresses live than SIMD8's registers hold. Since issue 34's cut-face cap
    // (one more float live across the march) the heaviest whole-volume variant spills too:
    // on-the-fly curvature with Sobel gradients and tricubic fetches (19 + 24 fetches of 8
    // trilinear each per sample). A spill anywhere else is new.
    let o = on_stub(&["--profile", "gen12", "kernels", "--all", "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let kernels = statistics(&report);
    assert!(kernels.len() > 300, "{}", kernels.len());
    let spilling: Vec<&String> = kernels
        .iter()
        .filter(|(_, s)| s["Spill Count"] > 0.0)
        .map(|(v, _)| v)
        .collect();
    assert!(
        !spilling.is_empty(),
        "the known family no longer spills: update BENCHMARKS.md"
    );
    for variant in spilling {
        assert!(
            variant.starts_with("raymarch")
                && variant.contains("CURVATURE=on-the-fly")
                && (variant.contains("BRICKED=on")
                    || (variant.contains("GRADIENT=sobel")
                        && variant.contains("INTERPOLATION=tricubic"))),
            "a new kernel spills on Gen12: {variant}"
        );
    }
}
