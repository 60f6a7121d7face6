//! The command-line tool as a user runs it: exit codes, one-line errors, JSON keys, the
//! phantom's peaks at its true intensities, PNG provenance. Uses the built binary on lavapipe
//! (or whatever Vulkan device the machine has) with the validation layer on.

use morphray::volume::nifti::write_nifti1;
use morphray::volume::phantom::{NOMINAL, PhantomSpec, generate};
use std::path::PathBuf;
use std::process::{Command, Output};

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A failure is exactly one line on stderr, starts with `morphray:`, and is not a panic.
fn assert_one_line_failure(o: &Output, needle: &str) {
    assert_eq!(o.status.code(), Some(1), "stderr: {}", stderr(o));
    let err = stderr(o);
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one line expected: {err}"
    );
    assert!(err.starts_with("morphray: "), "{err}");
    assert!(
        !err.contains("internal error") && !err.contains("panicked"),
        "{err}"
    );
    assert!(
        err.to_lowercase().contains(&needle.to_lowercase()),
        "`{needle}` not in: {err}"
    );
}

#[test]
fn help_explains_every_command() {
    let o = morphray(&["--help"]);
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    for command in ["info", "peaks", "render", "devices"] {
        assert!(text.contains(command), "{command} missing from --help");
    }
    let o = morphray(&["render", "--help"]);
    let text = String::from_utf8_lossy(&o.stdout);
    for option in [
        "--size",
        "--azimuth",
        "--elevation",
        "--zoom",
        "--mode",
        "--tissues",
        "--windows",
        "--step",
        "--curvature",
        "--shading",
        "--background",
        "--turntable",
    ] {
        assert!(text.contains(option), "{option} missing from render --help");
    }
}

#[test]
fn bad_arguments_exit_with_usage_status() {
    assert_eq!(
        morphray(&["render", "--mode", "sideways"]).status.code(),
        Some(2),
        "an unknown mode"
    );
    assert_eq!(
        morphray(&["render", "-o", "x.png", "--size", "12"])
            .status
            .code(),
        Some(2)
    );
    assert_eq!(morphray(&["frobnicate"]).status.code(), Some(2));
}

#[test]
fn unreadable_and_malformed_files_fail_with_one_readable_line() {
    let missing = temp("does-not-exist.nii");
    assert_one_line_failure(
        &morphray(&["info", missing.to_str().unwrap()]),
        "does-not-exist.nii",
    );
    let junk = temp("junk.nii");
    std::fs::write(&junk, b"this is not a NIfTI file at all, just text").unwrap();
    assert_one_line_failure(&morphray(&["info", junk.to_str().unwrap()]), "junk.nii");
    let truncated_gz = temp("truncated.nii.gz");
    std::fs::write(&truncated_gz, [0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3, 1, 2, 3]).unwrap();
    assert_one_line_failure(
        &morphray(&["peaks", truncated_gz.to_str().unwrap()]),
        "gzip",
    );
}

#[test]
fn info_json_has_the_documented_keys() {
    let phantom = generate(&PhantomSpec::cube(24)).unwrap();
    let path = temp("small.nii.gz");
    write_nifti1(&phantom.volume, &path, true).unwrap();
    let o = morphray(&["info", path.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "dims",
        "datatype",
        "spacing_mm",
        "affine",
        "affine_source",
        "imin",
        "imax",
        "nonfinite_voxels",
        "warnings",
    ] {
        assert!(v.get(key).is_some(), "key {key} missing");
    }
    assert_eq!(v["dims"], serde_json::json!([24, 24, 24]));
    assert_eq!(v["datatype"], "int16");
    assert_eq!(v["nonfinite_voxels"], 0);
}

#[test]
fn peaks_on_the_phantom_find_csf_gm_wm_at_their_true_intensities() {
    let o = morphray(&["peaks", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in [
        "file",
        "dims",
        "total_voxels",
        "used_voxels",
        "nonfinite_voxels",
        "imin",
        "imax",
        "peaks",
        "paper_windows",
        "in_paper_window",
        "windows",
        "device",
        "timings_ms",
    ] {
        assert!(v.get(key).is_some(), "key {key} missing");
    }
    assert_eq!(v["total_voxels"], 256 * 256 * 192);
    let raw = |t: &str| {
        v["peaks"][t]["raw"]
            .as_f64()
            .unwrap_or_else(|| panic!("{t} peak missing: {v}"))
    };
    let (csf, gm, wm) = (raw("csf"), raw("gm"), raw("wm"));
    assert!(csf < gm && gm < wm);
    // Within 5 % of the nominal intensities (bias field +-7 % averages out; noise sigma 20).
    for (found, nominal) in [(csf, NOMINAL.csf), (gm, NOMINAL.gm), (wm, NOMINAL.wm)] {
        assert!(
            (found - nominal).abs() <= 0.05 * nominal,
            "peak {found} vs nominal {nominal}"
        );
    }
}

#[test]
fn render_writes_a_png_with_provenance_and_unmasks_pathology() {
    let phantom = generate(&PhantomSpec::cube(48)).unwrap();
    let input = temp("phantom48.nii.gz");
    write_nifti1(&phantom.volume, &input, true).unwrap();
    let out = temp("all.png");
    let o = morphray(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "48x40",
        "--azimuth",
        "30",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let chunks = morphray::files::png::read_text_chunks(&out).unwrap();
    let get = |k: &str| {
        chunks
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.clone())
            .unwrap_or_default()
    };
    assert_eq!(get("morphray:input"), "phantom48.nii.gz");
    assert_eq!(
        get("morphray:input-sha256"),
        morphray::files::png::sha256_hex(&std::fs::read(&input).unwrap())
    );
    let parameters: serde_json::Value = serde_json::from_str(&get("morphray:parameters")).unwrap();
    assert_eq!(parameters["arguments"]["azimuth"], 30.0);
    assert_eq!(parameters["arguments"]["size"], serde_json::json!([48, 40]));

    let pathology = temp("pathology.png");
    let o = morphray(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        pathology.to_str().unwrap(),
        "--size",
        "48x48",
        "--tissues",
        "pathology",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&pathology).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut pixels).unwrap();
    let red = pixels
        .chunks(4)
        .filter(|p| p[0] > 60 && p[0] as u32 > 2 * p[2] as u32)
        .count();
    assert!(red > 0, "the lesion and vessels show in red");

    let o = morphray(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--tissues",
        "bone",
    ]);
    assert_one_line_failure(&o, "unknown tissue");
}

#[test]
fn turntable_writes_numbered_frames() {
    let phantom = generate(&PhantomSpec::cube(24)).unwrap();
    let input = temp("phantom24.nii");
    write_nifti1(&phantom.volume, &input, false).unwrap();
    let out = temp("spin.png");
    let o = morphray(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "16x16",
        "--turntable",
        "3",
        "--mode",
        "mip",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for i in 0..3 {
        assert!(temp(&format!("spin-{i:03}.png")).exists(), "frame {i}");
    }
}

#[test]
fn a_tiny_bench_reports_every_pass_as_json() {
    let phantom = generate(&PhantomSpec::cube(24)).unwrap();
    let input = temp("bench24.nii.gz");
    write_nifti1(&phantom.volume, &input, true).unwrap();
    let json = temp("bench.json");
    let o = morphray(&[
        "bench",
        input.to_str().unwrap(),
        "--size",
        "16x12",
        "--frames",
        "2",
        "--repeat",
        "2",
        // Time to first pixel has its own test below.
        "--trials",
        "0",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let names: Vec<&str> = v["passes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    for pass in [
        "minmax",
        "normalize",
        "histogram",
        "derivatives |g|",
        "derivatives |g|,k",
        "brick bounds",
        "brick distance",
    ] {
        assert!(names.contains(&pass), "{pass} missing from {names:?}");
    }
    for p in v["passes"].as_array().unwrap() {
        assert!(p["gpu_ms"]["median"].as_f64().unwrap() > 0.0, "{p}");
        assert!(p["xe_lp_model_ms"].as_f64().unwrap() > 0.0, "{p}");
    }
    let rm = &v["raymarch"];
    assert_eq!(rm["gpu_ms"]["n"], 2);
    assert!(
        rm["samples_per_frame"]["median"].as_f64().unwrap() > 0.0,
        "samples were counted"
    );
    assert_eq!(v["image"], serde_json::json!([16, 12]));
    // The bench carries the plan it ran.
    assert!(v["plan"]["allocations"].as_array().unwrap().len() > 3);
    assert!(v["plan"]["total_bytes"].as_u64().unwrap() > 0);
    assert_eq!(v["plan"]["degradations"], serde_json::json!([]));
    // A clean file: an empty list of loader warnings, present all the same (issue 12).
    assert_eq!(v["warnings"], serde_json::json!([]));
}

#[test]
fn a_tiny_bench_times_the_first_pixel_over_fresh_processes() {
    // No file: the bench writes the phantom as .nii.gz and times loading it. Each trial is a
    // fresh process; the warm trials must find the cache the first untimed one saved.
    let json = temp("ttfp.json");
    let cache = temp("ttfp-parent-cache");
    let o = morphray(&[
        "--pipeline-cache",
        cache.to_str().unwrap(),
        "bench",
        "--size",
        "64x64",
        "--frames",
        "2",
        "--repeat",
        "1",
        "--trials",
        "2",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(v["input"], "phantom (written as .nii.gz)");
    let t = &v["ttfp"];
    assert_eq!(t["trials"], 2);
    for side in ["cold", "warm"] {
        let s = &t[side];
        for phase in [
            "read",
            "inflate",
            "convert",
            "instance",
            "device",
            "engine",
            "pipelines",
            "upload",
            "minmax",
            "normalize",
            "histogram",
            "derivatives",
            "raymarch",
            "exec",
        ] {
            let p = &s["phases"][phase];
            assert_eq!(p["n"], 2, "{side} {phase}: {p}");
            for q in ["median", "p5", "p95"] {
                let x = p[q].as_f64().unwrap_or(f64::NAN);
                assert!(x.is_finite() && x > 0.0, "{side} {phase} {q}: {p}");
            }
        }
        for gpu in [
            "minmax",
            "normalize",
            "histogram",
            "derivatives",
            "raymarch",
        ] {
            assert!(
                s["gpu_ms"][gpu]["median"].as_f64().unwrap() > 0.0,
                "{side} {gpu}"
            );
        }
        let total = s["total_ms"]["median"].as_f64().unwrap();
        let in_process = s["in_process_ms"]["median"].as_f64().unwrap();
        assert!(
            total.is_finite() && total >= in_process && in_process > 0.0,
            "{s}"
        );
    }
    // Cold trials start empty and save; warm trials load what the untimed trial saved.
    for bytes in t["cold"]["cache_loaded_bytes"].as_array().unwrap() {
        assert_eq!(bytes, 0);
    }
    for bytes in t["cold"]["cache_written_bytes"].as_array().unwrap() {
        assert!(bytes.as_u64().unwrap() > 0);
    }
    for bytes in t["warm"]["cache_loaded_bytes"].as_array().unwrap() {
        assert!(
            bytes.as_u64().unwrap() > 0,
            "the warm trial found the cache"
        );
    }
    assert_eq!(t["warm"]["cache_rejected"], serde_json::json!([]));
    // The bench's own process used the cache directory it was given.
    assert_eq!(v["pipeline_cache"]["mode"], "directory");
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("time to first pixel"), "{text}");
}

#[test]
fn a_damaged_pipeline_cache_is_a_note_not_a_failure() {
    let dir = temp("damaged-cache");
    std::fs::create_dir_all(&dir).unwrap();
    let cache_dir = |o: &Output| -> Vec<PathBuf> {
        assert!(o.status.success(), "{}", stderr(o));
        std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "bin"))
            .collect()
    };
    let png = temp("damaged-cache.png");
    let args = [
        "--pipeline-cache",
        dir.to_str().unwrap(),
        "render",
        "--size",
        "16x16",
        "-o",
        png.to_str().unwrap(),
    ];
    let phantom = generate(&PhantomSpec::cube(20)).unwrap();
    let input = temp("cache20.nii");
    write_nifti1(&phantom.volume, &input, false).unwrap();
    let mut with_input = args.to_vec();
    with_input.push(input.to_str().unwrap());
    let files = cache_dir(&morphray(&with_input));
    assert_eq!(files.len(), 1, "one cache file per device and driver");
    std::fs::write(&files[0], b"not a pipeline cache").unwrap();
    let o = morphray(&with_input);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("pipeline cache") && err.contains("not used"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    // Rewritten whole after the first frame.
    let files = cache_dir(&o);
    assert!(std::fs::read(&files[0]).unwrap().starts_with(b"MRPCACHE"));
    // `off` needs no directory at all.
    let mut off = with_input.clone();
    off[1] = "off";
    assert!(morphray(&off).status.success());
}

#[test]
fn a_tiny_accuracy_study_reports_every_knob_with_a_frontier() {
    let phantom = generate(&PhantomSpec::cube(24)).unwrap();
    let input = temp("accuracy24.nii.gz");
    write_nifti1(&phantom.volume, &input, true).unwrap();
    let json = temp("accuracy.json");
    let svg = temp("accuracy.svg");
    // Progress asked for (stderr is a pipe here): the timing rounds are counted.
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args([
            "accuracy",
            input.to_str().unwrap(),
            "--size",
            "16x16",
            "--views",
            "1",
            "--frames",
            "2",
            "--json",
            json.to_str().unwrap(),
            "--plot",
            svg.to_str().unwrap(),
        ])
        .env("MORPHRAY_VALIDATION", "required")
        .env("MORPHRAY_PROGRESS", "always")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    for round in ["rounds 1/2", "rounds 2/2"] {
        assert!(stderr(&o).contains(round), "{}", stderr(&o));
    }
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let settings = v["settings"].as_array().unwrap();
    let knobs: std::collections::BTreeSet<&str> = settings
        .iter()
        .map(|s| s["knob"].as_str().unwrap())
        .collect();
    for knob in [
        "step",
        "interpolation",
        "gradient",
        "curvature",
        "opacity correction",
        "early termination",
        "empty-space skipping",
        "storage format",
        "lighting",
    ] {
        assert!(knobs.contains(knob), "knob {knob} missing: {knobs:?}");
    }
    // The lighting settings are compared within their own group (the stills' look as truth),
    // and the frontier is drawn there too.
    let lit: Vec<&serde_json::Value> = settings
        .iter()
        .filter(|s| s["group"] == "studio + cues")
        .collect();
    assert_eq!(lit.len(), 5, "{lit:?}");
    assert!(lit.iter().all(|s| s["knob"] == "lighting"), "{lit:?}");
    assert!(lit.iter().any(|s| s["frontier"] == true), "{lit:?}");
    let measured: Vec<&serde_json::Value> =
        settings.iter().filter(|s| s["skipped"].is_null()).collect();
    assert!(measured.len() >= 18, "most settings run on this device");
    for s in &measured {
        assert!(
            s["gpu_ms"].as_f64().unwrap() > 0.0 && s["error"]["rmse"].as_f64().unwrap().is_finite(),
            "{s}"
        );
    }
    // A finer step is closer to the f64 reference (which itself samples at 0.125).
    let rmse = |name: &str| {
        settings.iter().find(|s| s["name"] == name).unwrap()["error"]["rmse"]
            .as_f64()
            .unwrap()
    };
    assert!(rmse("step 0.125") < rmse("default") && rmse("default") < rmse("step 2"));
    assert!(settings.iter().any(|s| s["frontier"] == true));
    // The naive opacity correction fails the stability grid on the device: never on the frontier.
    let naive = settings
        .iter()
        .find(|s| s["name"] == "naive opacity correction")
        .unwrap();
    assert!(
        naive["unstable"].is_string() && naive["frontier"] == false,
        "{naive}"
    );
    assert!(
        v["opacity_stability"]["exact"]["relative"]
            .as_f64()
            .unwrap()
            < 2e-5
    );
    let plot = std::fs::read_to_string(&svg).unwrap();
    assert!(plot.starts_with("<svg") && plot.contains("Pareto frontier"));
    assert_eq!(v["warnings"], serde_json::json!([]));
}

fn plan_json(input: &str, extra: &[&str]) -> serde_json::Value {
    let mut args = vec!["plan", input, "--json", "--size", "32x24"];
    args.extend_from_slice(extra);
    let o = morphray(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn plan_json_is_minimal_for_each_scene() {
    let phantom = generate(&PhantomSpec::cube(64)).unwrap();
    // 64 voxels a row: lavapipe pads rows to 64 bytes, so smaller 8-bit volumes would take the
    // same memory with and without a curvature channel.
    let input = temp("plan64.nii");
    write_nifti1(&phantom.volume, &input, false).unwrap();
    let input = input.to_str().unwrap();
    let dvr = plan_json(input, &[]);
    for key in [
        "passes",
        "variants",
        "allocations",
        "total_bytes",
        "degradations",
        "held",
    ] {
        assert!(dvr.get(key).is_some(), "{key} missing from plan --json");
    }
    for a in dvr["allocations"].as_array().unwrap() {
        for key in ["name", "bytes", "format", "memory_type"] {
            assert!(a.get(key).is_some(), "{key} missing from {a}");
        }
    }
    let total = |v: &serde_json::Value| v["total_bytes"].as_u64().unwrap();
    let passes = |v: &serde_json::Value| -> Vec<String> {
        v["passes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["name"].as_str().unwrap().to_string())
            .collect()
    };
    let holds = |v: &serde_json::Value, name: &str| {
        v["allocations"]
            .as_array()
            .unwrap()
            .iter()
            .any(|a| a["name"] == name)
    };
    let curvature = plan_json(input, &["--curvature", "on"]);
    let mip = plan_json(input, &["--mode", "mip"]);
    let shading = plan_json(input, &["--shading", "on"]);
    assert!(
        total(&curvature) > total(&dvr),
        "curvature holds a second channel"
    );
    assert!(total(&shading) > total(&dvr), "shading holds normals");
    assert!(total(&mip) < total(&dvr), "MIP holds no derived volume");
    assert!(!passes(&mip).contains(&"derivatives".to_string()));
    assert!(passes(&dvr).contains(&"derivatives".to_string()));
    assert!(holds(&shading, "normals") && !holds(&dvr, "normals"));
    assert!(holds(&dvr, "gradient magnitude") && !holds(&mip, "gradient magnitude"));
    assert!(dvr["degradations"].as_array().unwrap().is_empty());
    // What the engine then held equals the plan (the ledger after set-up has no frame yet,
    // so the per-frame occupancy bits and transfer-function tables are the only planned
    // allocations missing).
    assert!(holds(&dvr, "transfer-function table") && !holds(&mip, "transfer-function table"));
    let planned: u64 = dvr["allocations"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|a| {
            a["transient"] == false
                && a["name"] != "occupancy bits"
                && a["name"] != "transfer-function table"
        })
        .map(|a| a["bytes"].as_u64().unwrap())
        .sum();
    assert_eq!(dvr["held_bytes"].as_u64().unwrap(), planned);
}

#[test]
fn an_impossible_budget_is_one_line_naming_volume_and_budget() {
    let phantom = generate(&PhantomSpec::cube(28)).unwrap();
    let input = temp("budget28.nii");
    write_nifti1(&phantom.volume, &input, false).unwrap();
    let out = temp("budget.png");
    let o = morphray(&[
        "--memory-budget",
        "16K",
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_one_line_failure(&o, "does not fit the memory budget of 16384 bytes");
    assert!(stderr(&o).contains("[28, 28, 28]"), "{}", stderr(&o));
    assert!(!out.exists());
}

#[test]
fn a_render_over_the_budget_bricks_and_says_so() {
    // The phantom in a wide empty field of view, so the visible bricks fit where the volume
    // does not.
    let side = 96;
    let inner = generate(&PhantomSpec::cube(40)).unwrap().volume;
    let values = inner.samples.to_f64_vec();
    let mut padded = vec![0i16; side * side * side];
    let o = (side - 40) / 2;
    for z in 0..40 {
        for y in 0..40 {
            for x in 0..40 {
                padded[((z + o) * side + y + o) * side + x + o] =
                    values[(z * 40 + y) * 40 + x] as i16;
            }
        }
    }
    let mut volume = inner;
    volume.dims = [side; 3];
    volume.samples = morphray::volume::Samples::from_i16(&padded);
    let input = temp("padded96.nii");
    write_nifti1(&volume, &input, false).unwrap();
    let out = temp("bricked.png");
    // 96^3 R16 is 1.7 MiB; a 1 MiB budget fits only by bricking (plus gradients on the fly).
    let o = morphray(&[
        "--memory-budget",
        "1M",
        "render",
        input.to_str().unwrap(),
        "--size",
        "40x32",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("bricked"), "{}", stderr(&o));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&out).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let lit = buf[..info.buffer_size()]
        .chunks_exact(4)
        .filter(|p| p[0] as u32 + p[1] as u32 + p[2] as u32 > 30)
        .count();
    // 47 lit pixels of 1280 on lavapipe with the stills' look (studio lighting and depth cues
    // darken the small cube's faces); an empty or black render has none.
    assert!(
        lit > 30,
        "the bricked render shows the phantom ({lit} lit pixels)"
    );
}

#[test]
fn profiles_and_tuning_apply_or_fail_in_one_line() {
    let phantom = generate(&PhantomSpec::cube(24)).unwrap();
    let input = temp("profile24.nii");
    write_nifti1(&phantom.volume, &input, false).unwrap();
    let input = input.to_str().unwrap();
    let o = morphray(&[
        "--profile",
        "gen12",
        "--wg",
        "raymarch=16x4",
        "plan",
        input,
        "--json",
        "--size",
        "16x16",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["device_profile"]["name"], "gen12");
    assert_eq!(v["device_profile"]["max_image_dimension_3d"], 2048);
    assert_eq!(
        v["tuning"]["workgroups"][0][1],
        serde_json::json!([8, 8, 1]),
        "the profile's default"
    );
    assert_eq!(
        v["tuning"]["workgroups"][1],
        serde_json::json!(["raymarch", [16, 4, 1]])
    );

    let bad = temp("bad-profile.toml");
    std::fs::write(&bad, "name = \"x\"\nmax_image_dimension_3d = \"big\"\n").unwrap();
    let o = morphray(&["--profile", bad.to_str().unwrap(), "peaks", input]);
    assert_one_line_failure(&o, "bad-profile.toml");
    let o = morphray(&["--profile", "xe-hpg", "peaks", input]);
    assert_one_line_failure(&o, "unknown profile");
    let o = morphray(&["--subgroup", "1024", "peaks", input]);
    assert_one_line_failure(&o, "subgroup size 1024");
    let o = morphray(&["--wg", "histogram=64", "peaks", input]);
    assert_one_line_failure(&o, "has no selectable workgroup");
}

#[test]
fn peaks_json_reports_no_range_and_no_peak_for_a_volume_without_finite_voxels() {
    // An all-NaN volume once reported imin = imax = 0 as if 0 had been measured.
    let dir = temp("all-nan");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("nan.nii");
    let volume = morphray::volume::Volume::from_voxels(
        "nan",
        [5, 4, 3],
        morphray::volume::Samples::from_f32(&[f32::NAN; 60]),
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
        morphray::volume::LinearMap::IDENTITY,
    )
    .unwrap();
    write_nifti1(&volume, &path, false).unwrap();
    let o = morphray(&["peaks", path.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(json["imin"].is_null() && json["imax"].is_null(), "{json}");
    assert_eq!(json["nonfinite_voxels"], 60);
    for tissue in ["csf", "gm", "wm"] {
        assert!(json["peaks"][tissue].is_null(), "{tissue}: {json}");
    }
}

/// A float32 NIfTI of `dims` (1 mm, identity affine) with `value(x, y, z)`.
fn float_volume(
    name: &str,
    dims: [usize; 3],
    value: impl Fn(usize, usize, usize) -> f32,
) -> PathBuf {
    let mut values = Vec::with_capacity(dims.iter().product());
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                values.push(value(x, y, z));
            }
        }
    }
    let volume = morphray::volume::Volume::from_voxels(
        name,
        dims,
        morphray::volume::Samples::from_f32(&values),
        [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
        morphray::volume::LinearMap::IDENTITY,
    )
    .unwrap();
    let path = temp(&format!("{name}.nii"));
    write_nifti1(&volume, &path, false).unwrap();
    path
}

fn lit_pixels(png: &std::path::Path) -> usize {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut rgba).unwrap();
    rgba.chunks_exact(4)
        .filter(|p| p[..3].iter().any(|&c| c > 1))
        .count()
}

#[test]
fn an_empty_image_is_never_silent_and_says_what_to_try() {
    let constant = float_volume("constant", [12, 11, 10], |_, _, _| 7.0);
    let ramp = float_volume("ramp", [24, 23, 22], |x, _, _| x as f32);
    let out = temp("empty.png");
    let cases: [(&[&str], &str); 4] = [
        (&[constant.to_str().unwrap()], "the volume is constant"),
        (
            &[ramp.to_str().unwrap()],
            "no histogram peak was found for csf, gm, wm",
        ),
        (
            &["--tissues", "pathology", "--opacity", "pathology=0"],
            "every visible tissue (pathology) has opacity 0",
        ),
        (
            // Eq. 1: nothing of the phantom reaches 0.99 (robust clamps its brightest 0.5 % to 1).
            &[
                "--normalize",
                "minmax",
                "--tissues",
                "wm",
                "--window",
                "wm=0.99:1.0",
            ],
            "no sample along any ray fell inside a visible tissue window",
        ),
    ];
    for (args, reason) in cases {
        let mut all = vec!["render", "-o", out.to_str().unwrap(), "--size", "40x40"];
        all.extend_from_slice(args);
        let o = morphray(&all);
        assert!(o.status.success(), "{all:?}: {}", stderr(&o));
        let err = stderr(&o);
        let line = err
            .lines()
            .find(|l| l.starts_with("morphray: note: the image shows only the background: "))
            .unwrap_or_else(|| panic!("{all:?}: no empty-image line in\n{err}"));
        assert!(
            line.contains(reason) && line.contains("; "),
            "{all:?}: {line}"
        );
        assert_eq!(lit_pixels(&out), 0, "{all:?}");
    }
}

#[test]
fn windows_opacities_and_colours_are_set_by_hand_and_recorded() {
    // The ramp has no tissue peaks: only a window set by hand shows it.
    let ramp = float_volume("ramp-manual", [24, 23, 22], |x, _, _| x as f32);
    let out = temp("manual.png");
    let o = morphray(&[
        "render",
        ramp.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "40x40",
        "--tissues",
        "wm",
        "--window",
        "wm=0.2:0.8",
        "--opacity",
        "wm=1",
        "--color",
        "wm=#ff0000",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        !stderr(&o).contains("only the background"),
        "{}",
        stderr(&o)
    );
    assert!(lit_pixels(&out) > 100, "the manual window shows the ramp");
    let chunks = morphray::files::png::read_text_chunks(&out).unwrap();
    let parameters = &chunks
        .iter()
        .find(|(k, _)| k.contains("parameters"))
        .expect("a parameters chunk")
        .1;
    let json: serde_json::Value = serde_json::from_str(parameters).unwrap();
    let wm = &json["scene"]["classification"]["tissues"][2];
    assert_eq!(wm["window"]["lo"], 0.2, "{wm}");
    assert_eq!(wm["window"]["hi"], 0.8, "{wm}");
    assert_eq!(wm["opacity"], 1.0);
    assert_eq!(wm["colour"][0], 1.0);
    assert_eq!(
        json["arguments"]["window"][0][0], "wm",
        "{}",
        json["arguments"]
    );
    // Bad values are usage errors naming the flag.
    for bad in [
        ["--window", "wm=0.9:0.2"],
        ["--window", "bone=0.1:0.2"],
        ["--opacity", "wm=NaN"],
        ["--color", "gm=#12"],
    ] {
        let o = morphray(&["render", "-o", out.to_str().unwrap(), bad[0], bad[1]]);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(bad[0]), "{bad:?}: {}", stderr(&o));
    }
}

#[test]
fn trace_records_host_phases_and_gpu_passes_as_chrome_trace_json() {
    let phantom = generate(&PhantomSpec::cube(32)).unwrap();
    let input = temp("traced.nii.gz");
    write_nifti1(&phantom.volume, &input, true).unwrap();
    let (out, trace) = (temp("traced.png"), temp("trace.json"));
    let o = morphray(&[
        "--trace",
        trace.to_str().unwrap(),
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "24x20",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(&trace).unwrap()).unwrap();
    let events = doc["traceEvents"].as_array().unwrap();
    let complete: Vec<_> = events.iter().filter(|e| e["ph"] == "X").collect();
    let named = |name: &str| complete.iter().any(|e| e["name"] == name);
    for host in [
        "read",
        "inflate",
        "vulkan instance",
        "encode and write PNG",
        "frame",
    ] {
        assert!(named(host), "no host phase {host} in {doc}");
    }
    for gpu in ["minmax", "normalize", "histogram", "raymarch"] {
        let pass = complete
            .iter()
            .find(|e| e["name"] == gpu && e["cat"] == "gpu")
            .unwrap_or_else(|| panic!("no GPU pass {gpu} in {doc}"));
        assert!(pass["dur"].as_f64().unwrap() > 0.0);
    }
    // Every GPU pass on the GPU track, named as such, and every event has a start and length.
    let gpu_tid = complete.iter().find(|e| e["cat"] == "gpu").unwrap()["tid"].clone();
    assert!(
        events
            .iter()
            .any(|e| e["ph"] == "M" && e["tid"] == gpu_tid && e["args"]["name"] == "GPU queue")
    );
    assert!(
        complete
            .iter()
            .all(|e| e["ts"].as_f64().is_some() && e["dur"].as_f64().is_some())
    );
    // A trace that cannot be written fails before any work.
    let o = morphray(&["--trace", "/nonexistent-dir/t.json", "peaks"]);
    assert_one_line_failure(&o, "t.json");
}
