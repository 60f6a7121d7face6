//! Measurements in the viewer (issue 31 items 2 and 3): a distance, an angle, a sphere and a box
//! placed by a script (the same steps as Shift+clicks: `measure point`, and `measure pick` for
//! the depth-picked 3D surface), their values logged and exported as CSV and JSON (the sphere's
//! voxel count equal to `volume::roi`'s on the same file), drawn over the slices and the 3D
//! view, saved in the scene document and restored by `view --scene`.

mod common;

use std::path::Path;
use std::process::Command;

fn morphray(dir: &Path, args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .current_dir(dir)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("morphray runs");
    common::viewer::checked_log(&o)
}

/// Pixels of the finished marks' orange (measure_panel.rs) in a screenshot.
fn orange_pixels(path: &Path) -> usize {
    common::pictures::Picture::read(path)
        .pixels
        .iter()
        .filter(|p| p[0] > 230 && (150..=190).contains(&p[1]) && p[2] < 40)
        .count()
}

#[test]
fn measurements_are_logged_exported_drawn_and_saved_with_the_scene() {
    let dir = std::env::temp_dir().join(format!("morphray-measure-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .current_dir(&dir)
        .args(["phantom", "--dims", "61x67x53", "-o", "small.nii.gz"])
        .output()
        .unwrap();
    assert!(o.status.success());
    std::fs::write(dir.join("before.txt"), "screenshot before.png\n").unwrap();
    let view = |script: &str| {
        morphray(
            &dir,
            &[
                "view",
                "small.nii.gz",
                "--offscreen",
                "--layout",
                "slices",
                "--size",
                "640x480",
                "--frames",
                "3",
                "--script",
                script,
            ],
        )
    };
    view("before.txt");
    std::fs::write(
        dir.join("measure.txt"),
        "measure distance 0 0 0 30 40 0\n\
         measure mode angle\n\
         measure point 10 0 0\n\
         measure point 0 0 0\n\
         measure point 0 10 0\n\
         measure sphere 0 0 0 5\n\
         measure box -3 -3 -3 3 3 3\n\
         measure mode distance\n\
         measure pick 0.5 0.5\n\
         measure pick 0.6 0.5\n\
         measure export m.csv\n\
         measure export m.json\n\
         save-scene m-scene.json\n\
         screenshot after.png\n",
    )
    .unwrap();
    let log = view("measure.txt");
    for line in [
        "measure: 1 distance 50.00 mm",
        "measure: 2 angle 90.00 deg",
        "measure: 3 sphere r 5.00 mm: ",
        "measure: 4 box: 343 voxels, 343.0 mm^3",
        "measure: 5 distance ",
        "wrote m.csv (5 measurements)",
    ] {
        assert!(log.contains(line), "no `{line}` in\n{log}");
    }
    // The CSV: a header and five rows; the sphere's count is the library's.
    let csv = std::fs::read_to_string(dir.join("m.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows.len(), 6, "{csv}");
    let volume = morphray::volume::source::read(
        &morphray::volume::source::VolumeSource::File(dir.join("small.nii.gz")),
        &Default::default(),
    )
    .unwrap()
    .volume;
    let sphere = morphray::volume::roi::roi_stats(
        &volume,
        &morphray::volume::roi::Region::Sphere {
            centre: [0.0; 3],
            radius_mm: 5.0,
        },
    );
    assert!(sphere.voxels > 400, "{sphere:?}");
    assert!(
        rows[3].starts_with(&format!("3,sphere,0 0 0,5,mm,{},", sphere.voxels)),
        "{}",
        rows[3]
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("m.json")).unwrap()).unwrap();
    assert_eq!(json.as_array().map(Vec::len), Some(5));
    assert_eq!(json[1]["value"], 90.0);
    // Drawn: the marks' orange is on the window now and was not before.
    assert_eq!(orange_pixels(&dir.join("before.png")), 0);
    assert!(orange_pixels(&dir.join("after.png")) > 30);
    // Saved with the scene and restored by `view --scene`.
    let doc = morphray::scene::document::SceneDocument::read(&dir.join("m-scene.json")).unwrap();
    assert_eq!(doc.measurements.len(), 5);
    std::fs::write(dir.join("again.txt"), "measure export again.csv\n").unwrap();
    let log = morphray(
        &dir,
        &[
            "view",
            "--scene",
            "m-scene.json",
            "--offscreen",
            "--frames",
            "3",
            "--script",
            "again.txt",
        ],
    );
    assert!(log.contains("wrote again.csv (5 measurements)"), "{log}");
    assert_eq!(std::fs::read_to_string(dir.join("again.csv")).unwrap(), csv);
    let _ = std::fs::remove_dir_all(&dir);
}
