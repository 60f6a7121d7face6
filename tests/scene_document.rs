//! Scene documents (issue 31 item 6): the version-1 format's fields held against the serializer
//! (the schema test), a scene that survives the round trip exactly, hostile documents refused in
//! one line, and on the GPU: `render --save-scene` then `render --scene` and `--scene-from` give
//! the same pixels, and the viewer's `save-scene` gives what its 3D view showed.

mod common;

use morphray::scene::document::{
    FORMAT, OverlayRef, SceneDocError, SceneDocument, SceneInput, VERSION, ViewerLayout,
};
use morphray::scene::measure::Measurement;
use morphray::scene::{ClipPlane, Colormap, Cutaway, Scene};
use morphray::volume::roi::Region;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Every key path of a version-1 document with every optional part present (arrays of objects
/// as `[]`). A change here is a change of the format: raise `scene::document::VERSION` (and
/// read the old version) before updating this list and README "Scenes".
const SCHEMA_V1: &[&str] = &[
    "denoise",
    "format",
    "input",
    "input.frame",
    "input.paths",
    "input.sha256",
    "layers",
    "layers[].path",
    "layers[].style",
    "layers[].style.cluster",
    "layers[].style.colormap",
    "layers[].style.hi",
    "layers[].style.lo",
    "layers[].style.negative",
    "layers[].style.opacity",
    "layers[].style.threshold",
    "matcap",
    "measurements",
    "measurements[].angle",
    "measurements[].angle.points",
    "measurements[].box",
    "measurements[].box.a",
    "measurements[].box.b",
    "measurements[].distance",
    "measurements[].distance.points",
    "measurements[].sphere",
    "measurements[].sphere.centre",
    "measurements[].sphere.radius_mm",
    "overlay",
    "overlay.labels",
    "overlay.lut",
    "overlay.opacity",
    "scene",
    "scene.background",
    "scene.camera",
    "scene.camera.azimuth_deg",
    "scene.camera.elevation_deg",
    "scene.camera.pan_mm",
    "scene.camera.projection",
    "scene.camera.projection.perspective",
    "scene.camera.projection.perspective.fov_y_deg",
    "scene.camera.zoom",
    "scene.classification",
    "scene.classification.head",
    "scene.classification.head.colour",
    "scene.classification.head.opacity",
    "scene.classification.head.visible",
    "scene.classification.head.window",
    "scene.classification.head.window.edge",
    "scene.classification.head.window.hi",
    "scene.classification.head.window.lo",
    "scene.classification.tissues",
    "scene.classification.tissues[].colour",
    "scene.classification.tissues[].opacity",
    "scene.classification.tissues[].visible",
    "scene.classification.tissues[].window",
    "scene.classification.tissues[].window.edge",
    "scene.classification.tissues[].window.hi",
    "scene.classification.tissues[].window.lo",
    "scene.classification.vessels",
    "scene.classification.vessels.colour",
    "scene.classification.vessels.opacity",
    "scene.classification.vessels.window",
    "scene.classification.vessels.window.edge",
    "scene.classification.vessels.window.hi",
    "scene.classification.vessels.window.lo",
    "scene.clip",
    "scene.clip.crop",
    "scene.clip.planes",
    "scene.clip.planes[].normal",
    "scene.clip.planes[].offset_mm",
    "scene.colormap",
    "scene.cues",
    "scene.cues.occlusion",
    "scene.cues.occlusion_reach_mm",
    "scene.cues.shadow",
    "scene.cues.shadow_reach_mm",
    "scene.cues.silhouette",
    "scene.curvature_strength",
    "scene.cutaway",
    "scene.cutaway.point_mm",
    "scene.early_termination",
    "scene.effects",
    "scene.effects.brain",
    "scene.effects.curvature",
    "scene.effects.gradient_source",
    "scene.effects.lighting",
    "scene.effects.lighting.depth_cues",
    "scene.effects.lighting.model",
    "scene.effects.mode",
    "scene.effects.quality",
    "scene.effects.quality.classification",
    "scene.effects.quality.curvature_source",
    "scene.effects.quality.derived_precision",
    "scene.effects.quality.empty_space_skipping",
    "scene.effects.quality.gradient_filter",
    "scene.effects.quality.interpolation",
    "scene.effects.quality.long_steps",
    "scene.effects.quality.long_steps.factor",
    "scene.effects.quality.long_steps.threshold_e4",
    "scene.effects.quality.opacity_correction",
    "scene.effects.shading",
    "scene.effects.vessels",
    "scene.frame",
    "scene.intensity_window",
    "scene.jitter",
    "scene.minip_floor",
    "scene.step_voxels",
    "size",
    "version",
    "viewer",
    "viewer.crosshair_mm",
    "viewer.layout",
];

/// A document with every optional part present and values away from the defaults.
fn full_document() -> SceneDocument {
    let mut scene = Scene::new(morphray::scene::Classification::from_tissue_windows(
        &morphray::analysis::TissueWindows::paper(),
    ));
    scene.camera.azimuth_deg = 37.5;
    scene.camera.pan_mm = [3.25, -1.5];
    scene.step_voxels = 0.25;
    scene.background = [0.1, 0.2, 0.3];
    scene.colormap = Some(Colormap::Hot);
    scene.cutaway = Some(Cutaway {
        point_mm: Some([1.0, 2.0, 3.0]),
    });
    scene.clip.planes[0] = Some(ClipPlane {
        normal: [0.0, 0.0, 1.0],
        offset_mm: -10.0,
    });
    scene
        .classification
        .set_window(morphray::scene::TissueClass::Wm, 0.6, 0.9);
    let mut doc = SceneDocument::new(
        SceneInput {
            paths: vec!["scan.nii.gz".into()],
            sha256: "ab".repeat(32),
            frame: 2,
        },
        scene,
    );
    doc.matcap = Some("clay".into());
    doc.overlay = Some(OverlayRef {
        labels: "labels.nii.gz".into(),
        lut: Some("labels.lut".into()),
        opacity: 0.25,
    });
    doc.layers = vec![morphray::scene::document::LayerRef {
        path: "zstat.nii.gz".into(),
        style: morphray::scene::layer::LayerStyle {
            colormap: morphray::scene::layer::LayerColormap::RedYellow,
            lo: 3.1,
            hi: 8.0,
            threshold: 3.1,
            negative: Some(morphray::scene::layer::LayerColormap::BlueLightblue),
            cluster: 20,
            opacity: 0.9,
        },
    }];
    doc.size = Some([320, 240]);
    doc.measurements = vec![
        Measurement::Distance {
            points: [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]],
        },
        Measurement::Angle {
            points: [[1.0, 0.0, 0.0], [0.0; 3], [0.0, 1.0, 0.0]],
        },
        Measurement::Region(Region::Sphere {
            centre: [1.0, 2.0, 3.0],
            radius_mm: 4.5,
        }),
        Measurement::Region(Region::Box {
            a: [0.0; 3],
            b: [5.0, 6.0, 7.0],
        }),
    ];
    doc.viewer = Some(ViewerLayout {
        layout: "3d".into(),
        crosshair_mm: Some([1.5, -2.0, 3.0]),
    });
    doc
}

/// The key paths of `value` below `prefix` (module doc of [`SCHEMA_V1`]).
fn key_paths(value: &serde_json::Value, prefix: &str, out: &mut Vec<String>) {
    match value {
        serde_json::Value::Object(map) => {
            for (key, v) in map {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                out.push(path.clone());
                key_paths(v, &path, out);
            }
        }
        serde_json::Value::Array(items) => {
            // The union over the items: a list of measurements holds every kind.
            let stem = format!("{prefix}[]");
            for item in items.iter().filter(|i| i.is_object()) {
                key_paths(item, &stem, out);
            }
        }
        _ => {}
    }
}

#[test]
fn the_version_1_format_is_the_documented_one() {
    let doc = full_document();
    let value: serde_json::Value = serde_json::from_str(&doc.to_json()).unwrap();
    let mut paths = Vec::new();
    key_paths(&value, "", &mut paths);
    paths.sort();
    paths.dedup();
    let expected: Vec<String> = SCHEMA_V1.iter().map(|s| s.to_string()).collect();
    assert_eq!(
        paths, expected,
        "the scene document's fields changed: raise scene::document::VERSION, read the old \
         version, then update SCHEMA_V1 and README \"Scenes\""
    );
    assert_eq!((doc.format.as_str(), doc.version), (FORMAT, VERSION));
    // README names every top-level field.
    let readme =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let section = readme
        .split("## Scenes")
        .nth(1)
        .expect("README has a \"Scenes\" section");
    for top in SCHEMA_V1.iter().filter(|p| !p.contains('.')) {
        assert!(
            section.contains(&format!("`{top}`")),
            "README \"Scenes\" does not document `{top}`"
        );
    }
}

#[test]
fn a_scene_survives_the_round_trip_exactly() {
    let doc = full_document();
    let back = SceneDocument::parse(&doc.to_json(), Path::new("x.json")).unwrap();
    assert_eq!(back, doc);
    // Paths resolve against the document's folder; absolute ones stay.
    let paths = back.input_paths(Path::new("/data/scenes/x.json"));
    assert_eq!(paths, vec![PathBuf::from("/data/scenes/scan.nii.gz")]);
    let (labels, lut) = back.overlay_paths(Path::new("/d/x.json")).unwrap();
    assert_eq!(labels, PathBuf::from("/d/labels.nii.gz"));
    assert_eq!(lut, Some(PathBuf::from("/d/labels.lut")));
    assert_eq!(
        back.matcap_source(Path::new("/d/x.json")).as_deref(),
        Some("clay")
    );
}

#[test]
fn hostile_documents_are_refused_in_one_line() {
    let good: serde_json::Value = serde_json::from_str(&full_document().to_json()).unwrap();
    let edit = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v = good.clone();
        f(&mut v);
        v.to_string()
    };
    let cases: Vec<(String, &str)> = vec![
        ("not json".into(), "expected"),
        ("{}".into(), "\"format\" is missing"),
        (
            edit(&|v| v["format"] = "other".into()),
            "not \"morphray-scene\"",
        ),
        (edit(&|v| v["version"] = 99.into()), "version-99"),
        (
            edit(&|v| v["version"] = "one".into()),
            "\"version\" is missing or not a number",
        ),
        (edit(&|v| v["typo"] = 1.into()), "unknown field `typo`"),
        (edit(&|v| v["scene"]["step_voxels"] = 1e-9.into()), "--step"),
        (edit(&|v| v["scene"]["step_voxels"] = 1e6.into()), "--step"),
        (
            edit(&|v| v["scene"]["camera"]["zoom"] = (-1.0).into()),
            "--zoom",
        ),
        (
            edit(&|v| v["scene"]["background"] = serde_json::json!([1e39, 0, 0])),
            "not finite",
        ),
        (
            edit(&|v| v["scene"]["jitter"] = "yes".into()),
            "invalid type",
        ),
        (
            edit(&|v| v["size"] = serde_json::json!([0, 5])),
            "1 to 16384 pixels",
        ),
        (edit(&|v| v["overlay"]["opacity"] = 2.0.into()), "opacity 2"),
        (
            edit(&|v| v["layers"][0]["style"]["lo"] = 9.0.into()),
            "lo < hi",
        ),
        (
            edit(&|v| v["viewer"]["crosshair_mm"] = serde_json::json!([1, 2])),
            "invalid length",
        ),
        (
            edit(&|v| v["scene"]["effects"]["mode"] = "hologram".into()),
            "unknown variant",
        ),
    ];
    for (text, expected) in cases {
        let e = SceneDocument::parse(&text, Path::new("bad.json"))
            .expect_err(&format!("{text:.80} was accepted"));
        let message = e.to_string();
        assert!(
            message.contains(expected) && !message.contains('\n'),
            "{message} (expected `{expected}`)"
        );
        assert!(message.contains("bad.json"), "{message}");
    }
    // Too large to be a scene: refused before it is read.
    let dir = std::env::temp_dir().join(format!("morphray-scene-big-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let big = dir.join("big.json");
    std::fs::write(&big, vec![b' '; 2 << 20]).unwrap();
    assert!(matches!(
        SceneDocument::read(&big),
        Err(SceneDocError::TooLarge { .. })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

fn morphray(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .current_dir(dir)
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("morphray runs")
}

fn ok(dir: &Path, args: &[&str]) -> String {
    let o = morphray(dir, args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !stderr.contains("no Vulkan") && !stderr.contains("found no device"),
        "this test needs a Vulkan device (Debian: apt-get install mesa-vulkan-drivers \
         libvulkan1 vulkan-validationlayers): {stderr}"
    );
    assert!(o.status.success(), "{args:?}: {stderr}");
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn pixels(path: &Path) -> Vec<[u8; 3]> {
    common::pictures::Picture::read(path).pixels
}

#[test]
fn render_writes_a_scene_that_renders_the_same_pixels_again() {
    let dir = std::env::temp_dir().join(format!("morphray-scene-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("scans")).unwrap();
    ok(
        &dir,
        &["phantom", "--dims", "61x67x53", "-o", "scans/small.nii.gz"],
    );
    let render_args = [
        "render",
        "scans/small.nii.gz",
        "--size",
        "64x48",
        "-o",
        "a.png",
        "--azimuth",
        "35",
        "--tissues",
        "gm,wm",
        "--window",
        "wm=0.55:0.95",
        "--save-scene",
        "scenes/a.json",
    ];
    // The scenes folder does not exist: refused before anything is rendered.
    let o = morphray(&dir, &render_args);
    assert!(!o.status.success() && !dir.join("a.png").exists());
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    ok(&dir, &render_args);
    let doc = SceneDocument::read(&dir.join("scenes/a.json")).unwrap();
    // Recorded relative to the document's folder, with the size and the input's hash.
    assert_eq!(doc.input.paths, vec!["../scans/small.nii.gz".to_string()]);
    assert_eq!((doc.size, doc.input.sha256.len()), (Some([64, 48]), 64));
    assert_eq!(doc.scene.camera.azimuth_deg, 35.0);
    let log = ok(&dir, &["render", "--scene", "scenes/a.json", "-o", "b.png"]);
    assert!(
        log.contains("scene: scenes/a.json (scene document version 1)"),
        "{log}"
    );
    ok(&dir, &["render", "--scene-from", "a.png", "-o", "c.png"]);
    let a = pixels(&dir.join("a.png"));
    assert!(
        a.iter().any(|p| p.iter().any(|&c| c > 40)),
        "a.png is blank"
    );
    assert_eq!(a, pixels(&dir.join("b.png")), "--scene");
    assert_eq!(a, pixels(&dir.join("c.png")), "--scene-from");
    // Scene options beside a document, or a picture without one: one line each.
    for (args, expected) in [
        (
            vec![
                "render",
                "--scene",
                "scenes/a.json",
                "--tissues",
                "wm",
                "-o",
                "d.png",
            ],
            "--tissues cannot be combined with --scene",
        ),
        (
            vec![
                "render",
                "--scene-from",
                "scans/small.nii.gz",
                "-o",
                "d.png",
            ],
            "cannot read",
        ),
    ] {
        let o = morphray(&dir, &args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && stderr.contains(expected), "{stderr}");
        assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
    }
    // A different scan under the same name: rendered, with a warning.
    ok(
        &dir,
        &[
            "phantom",
            "--dims",
            "61x67x55",
            "-o",
            "scans/small.nii.gz",
            "--force",
        ],
    );
    let o = morphray(&dir, &["render", "--scene", "scenes/a.json", "-o", "e.png"]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("the input differs"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_viewer_saves_the_scene_its_3d_view_shows() {
    let dir = std::env::temp_dir().join(format!("morphray-scene-view-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    ok(
        &dir,
        &["phantom", "--dims", "61x67x53", "-o", "small.nii.gz"],
    );
    let log = common::viewer::offscreen(
        &dir.join("small.nii.gz"),
        &dir,
        "160x120",
        &format!(
            "orbit 30 10\ntoggle csf\nset window wm 0.5 0.9\nsave-view {} 64x48\nsave-scene {}",
            dir.join("v.png").display(),
            dir.join("v.json").display()
        ),
    );
    assert!(log.contains("(scene document)"), "{log}");
    let doc = SceneDocument::read(&dir.join("v.json")).unwrap();
    let viewer = doc.viewer.as_ref().expect("the viewer's layout");
    assert_eq!(viewer.layout, "3d");
    assert!(viewer.crosshair_mm.is_some());
    assert_eq!(doc.input.paths, vec!["small.nii.gz".to_string()]);
    assert!(
        !doc.scene.classification.tissues[0].visible,
        "csf toggled off"
    );
    ok(
        &dir,
        &[
            "render", "--scene", "v.json", "--size", "64x48", "-o", "r.png",
        ],
    );
    assert_eq!(pixels(&dir.join("v.png")), pixels(&dir.join("r.png")));
    // And `view --scene` opens it again: same camera, window and layout.
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .current_dir(&dir)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .args([
            "view",
            "--offscreen",
            "--scene",
            "v.json",
            "--frames",
            "2",
            "--script",
        ])
        .arg({
            let script = dir.join("again.txt");
            std::fs::write(&script, "save-view again.png 64x48\n").unwrap();
            script
        })
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .unwrap();
    common::viewer::checked_log(&o);
    assert_eq!(pixels(&dir.join("v.png")), pixels(&dir.join("again.png")));
    let _ = std::fs::remove_dir_all(&dir);
}
