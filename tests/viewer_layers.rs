//! Intensity layers from the command line and in the viewer (issue 31 item 4): a two-sided map on
//! its own 2 mm grid (scaled storage, so values are physical) over the phantom, drawn by
//! `render --layer` and `slice --layer`, added by the viewer's script (as Add layer... does),
//! its value read at the crosshair, restyled, saved with the scene and drawn again by
//! `view --scene` and `render --scene`.

mod common;

use morphray::volume::{LinearMap, Samples, Volume};
use std::path::{Path, PathBuf};
use std::process::Command;

fn run(dir: &Path, args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .current_dir(dir)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("morphray runs");
    if args.first() == Some(&"view") {
        return common::viewer::checked_log(&o);
    }
    // Validation required: any validation-layer error fails the command.
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Red-yellow pixels (the positive map) and blue-lightblue ones (the negative) in a picture.
fn map_pixels(path: &Path) -> (usize, usize) {
    let pixels = common::pictures::Picture::read(path).pixels;
    let red = pixels
        .iter()
        .filter(|p| p[0] > 200 && p[2] < 60 && p[1] < p[0])
        .count();
    let blue = pixels.iter().filter(|p| p[2] > 200 && p[0] < 60).count();
    (red, blue)
}

/// The phantom (61x67x53, 1 mm) and a layer on a 2 mm grid over the same box holding a positive
/// ball (peak 6) at world `(-20, -20, 10)` and a negative one (peak -5) at `(20, 20, -10)`,
/// stored as i16 with a slope of 0.001.
fn scans(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-layers-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    run(
        &dir,
        &["phantom", "--dims", "61x67x53", "-o", "small.nii.gz"],
    );
    let base = morphray::volume::source::read(
        &morphray::volume::source::VolumeSource::File(dir.join("small.nii.gz")),
        &Default::default(),
    )
    .unwrap()
    .volume;
    let a = base.orientation.affine;
    let dims = [31, 34, 27];
    // Layer index -> base index: twice the step, same origin.
    let affine: [[f64; 4]; 4] = std::array::from_fn(|r| {
        std::array::from_fn(|c| if c < 3 { 2.0 * a[r][c] } else { a[r][c] })
    });
    let world = |i: usize, j: usize, k: usize| -> [f64; 3] {
        std::array::from_fn(|r| {
            affine[r][0] * i as f64
                + affine[r][1] * j as f64
                + affine[r][2] * k as f64
                + affine[r][3]
        })
    };
    let mut stored = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = world(i, j, k);
                let d2 = |c: [f64; 3]| (0..3).map(|x| (p[x] - c[x]).powi(2)).sum::<f64>();
                let v = 6.0 * (-d2([-20.0, -20.0, 10.0]) / 50.0).exp()
                    - 5.0 * (-d2([20.0, 20.0, -10.0]) / 50.0).exp();
                stored.push((v * 1000.0).round() as i16);
            }
        }
    }
    let layer = Volume::from_voxels(
        "blobs.nii.gz",
        dims,
        Samples::from_i16(&stored),
        affine,
        LinearMap {
            slope: 0.001,
            intercept: 0.0,
        },
    )
    .unwrap();
    morphray::volume::nifti::write_new_nifti1(&layer, &dir.join("blobs.nii.gz"), true).unwrap();
    dir
}

#[test]
fn render_and_slice_draw_a_layer_and_a_threshold_above_it_draws_nothing() {
    let dir = scans("cli");
    // The same still (160x160 from above) with `extra` options, written to `out`.
    let still = |extra: &[&str], out: &str| {
        let mut args = vec![
            "render",
            "small.nii.gz",
            "--size",
            "160x160",
            "--view",
            "superior",
        ];
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-o", out]);
        run(&dir, &args)
    };
    let out = still(&[], "plain.png");
    assert!(out.contains("wrote plain.png"), "{out}");
    let layer = [
        "--layer",
        "blobs.nii.gz:red-yellow:2:6",
        "--save-scene",
        "layer.json",
    ];
    let out = still(&layer, "layer.png");
    assert!(
        out.contains("layer blobs.nii.gz: red-yellow 2..6, |v| >= 2, negative side blue-lightblue"),
        "{out}"
    );
    let (red, blue) = map_pixels(&dir.join("layer.png"));
    assert!(red > 50 && blue > 50, "{red} red, {blue} blue pixels");
    assert_eq!(map_pixels(&dir.join("plain.png")), (0, 0));
    // Above every value: the picture without the layer, byte for byte.
    still(&["--layer", "blobs.nii.gz:red-yellow:7:9"], "none.png");
    let plain = common::pictures::Picture::read(&dir.join("plain.png")).pixels;
    assert_eq!(
        common::pictures::Picture::read(&dir.join("none.png")).pixels,
        plain
    );
    // The scene document holds the layer and draws it again.
    run(
        &dir,
        &["render", "--scene", "layer.json", "-o", "again.png"],
    );
    assert_eq!(
        common::pictures::Picture::read(&dir.join("again.png")).pixels,
        common::pictures::Picture::read(&dir.join("layer.png")).pixels
    );
    // A slice through the positive ball, and bad specs refused in one line.
    let out = run(
        &dir,
        &[
            "slice",
            "small.nii.gz",
            "--plane",
            "axial",
            "--mm",
            "10",
            "--layer",
            "blobs.nii.gz:hot:2:6",
            "-o",
            "slice.png",
        ],
    );
    assert!(
        out.contains("layer blobs.nii.gz: ") && out.contains("pixels drawn"),
        "{out}"
    );
    for bad in [
        "blobs.nii.gz:nomap",
        "blobs.nii.gz:hot:6:2",
        "blobs.nii.gz:thr=x",
        "missing.nii:hot",
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
            .current_dir(&dir)
            .args([
                "render",
                "small.nii.gz",
                "--size",
                "32x32",
                "--layer",
                bad,
                "-o",
                "bad.png",
            ])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.lines().count() == 1,
            "{bad}: {err}"
        );
    }
}

#[test]
fn the_viewer_adds_reads_restyles_and_saves_a_layer() {
    let dir = scans("viewer");
    std::fs::write(
        dir.join("layers.txt"),
        "wait 1\n\
         crosshair -20 -20 10\n\
         wait 1\n\
         screenshot before.png\n\
         layer add blobs.nii.gz:red-yellow:2:6\n\
         wait 2\n\
         screenshot with.png\n\
         layer 1 threshold 7\n\
         wait 2\n\
         screenshot above.png\n\
         layer 1 threshold 2\n\
         layer 1 opacity 0.8\n\
         save-scene viewer.json\n",
    )
    .unwrap();
    let view = |args: &[&str]| {
        let mut all = vec!["view", "--offscreen", "--size", "800x600", "--frames", "3"];
        all.extend_from_slice(args);
        run(&dir, &all)
    };
    let log = view(&["small.nii.gz", "--script", "layers.txt"]);
    assert!(log.contains("layer blobs.nii.gz: red-yellow 2..6"), "{log}");
    // The readout: the layer's physical value at the ball's centre (peak 6 at a voxel centre of
    // the 2 mm grid? the ball is centred between them: within 5 % of 6).
    let value: f64 = log
        .lines()
        .filter_map(|l| l.split("layers: blobs.nii.gz ").nth(1))
        .filter_map(|v| v.split([' ', ',', ';']).next()?.parse().ok())
        .next_back()
        .unwrap_or_else(|| panic!("no layer value in\n{log}"));
    assert!((value - 6.0).abs() < 0.3, "value at the ball {value}");
    // The interface has red of its own (the pathology band): count against the window before.
    let (before, _) = map_pixels(&dir.join("before.png"));
    let (red, blue) = map_pixels(&dir.join("with.png"));
    assert!(
        red > before + 1000 && blue > 1000,
        "{red} red, {blue} blue pixels with the layer, {before} before"
    );
    let (above, _) = map_pixels(&dir.join("above.png"));
    assert!(
        above.abs_diff(before) < 50,
        "threshold 7 still drew: {above} red pixels, {before} before"
    );
    let doc = morphray::scene::document::SceneDocument::read(&dir.join("viewer.json")).unwrap();
    assert_eq!(doc.layers.len(), 1);
    assert_eq!(doc.layers[0].style.opacity, 0.8);
    std::fs::write(dir.join("shot.txt"), "wait 2\nscreenshot restored.png\n").unwrap();
    let log = view(&["--scene", "viewer.json", "--script", "shot.txt"]);
    assert!(log.contains("layer blobs.nii.gz: red-yellow 2..6"), "{log}");
    assert!(map_pixels(&dir.join("restored.png")).0 > before + 1000);
    // A label map added from the viewer (as Add labels... does): set up on the volume's grid.
    run(
        &dir,
        &[
            "phantom",
            "--dims",
            "61x67x53",
            "-o",
            "again.nii.gz",
            "--labels",
            "labels.nii.gz",
        ],
    );
    std::fs::write(
        dir.join("labels.txt"),
        "labels labels.nii.gz\nwait 2\nscreenshot labels.png\n",
    )
    .unwrap();
    let log = view(&["small.nii.gz", "--script", "labels.txt"]);
    assert!(log.contains("labels labels.nii.gz added"), "{log}");
    // The readout names the label under the crosshair once the labels are on the grid.
    assert!(log.contains("|  label 4"), "{log}");
    // A bad step is a logged error, not a panic.
    std::fs::write(
        dir.join("bad.txt"),
        "layer 2 threshold 3\nlayer add nothing.nii\n",
    )
    .unwrap();
    let log = view(&["small.nii.gz", "--script", "bad.txt"]);
    assert!(
        log.contains("layer step failed: there is no layer 2"),
        "{log}"
    );
}
