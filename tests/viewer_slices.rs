//! The viewer's slice layouts as a person (or CI) runs them: scripted sessions (offscreen, and
//! one in a real window under Xvfb) switch layouts, and screenshots show the slices where the
//! layout line says they are, with a left-anterior-superior blob on the correct side of the
//! axial slice in both conventions. Validation layer required. Fails (never skips) without a
//! Vulkan device or xvfb-run.

mod common;

use morphray::volume::nifti::write_nifti1;
use morphray::volume::{LinearMap, Samples, Volume};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-vslices-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const DIMS: [usize; 3] = [40, 36, 32];
/// Left (x < 0), anterior (y > 0), superior (z > 0), world mm.
const BLOB: [f64; 3] = [-8.0, 7.0, 6.0];

/// A 1 mm head: a dim sphere (radius 15 mm) with a bright blob (radius 4 mm) at [`BLOB`],
/// centred on the world origin.
fn head(dir: &Path) -> PathBuf {
    let half = |a: usize| (DIMS[a] as f64 - 1.0) / 2.0;
    let mut voxels = Vec::new();
    for k in 0..DIMS[2] {
        for j in 0..DIMS[1] {
            for i in 0..DIMS[0] {
                let p = [i as f64 - half(0), j as f64 - half(1), k as f64 - half(2)];
                let r2 = |c: [f64; 3]| (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f64>();
                voxels.push(if r2(BLOB) < 16.0 {
                    1000u16
                } else if r2([0.0; 3]) < 225.0 {
                    300
                } else {
                    0
                });
            }
        }
    }
    let affine = [
        [1.0, 0.0, 0.0, -half(0)],
        [0.0, 1.0, 0.0, -half(1)],
        [0.0, 0.0, 1.0, -half(2)],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let v = Volume::from_voxels(
        "head",
        DIMS,
        Samples::from_u16(&voxels),
        affine,
        LinearMap::IDENTITY,
    )
    .unwrap();
    let path = dir.join("head.nii");
    write_nifti1(&v, &path, false).unwrap();
    path
}

/// Runs `morphray view` with a script, offscreen or under Xvfb, validation required.
fn view(volume: &Path, script: &str, shot: &Path, window: bool) -> Output {
    view_with(volume, script, shot, window, &[])
}

/// [`view`] with more arguments.
fn view_with(volume: &Path, script: &str, shot: &Path, window: bool, extra: &[&str]) -> Output {
    let script_path = shot.with_extension("txt");
    std::fs::write(&script_path, script).unwrap();
    let mut command = common::viewer::view_command(window);
    let o = command
        .args(["--layout", "3d", volume.to_str().unwrap()])
        .args(["--normalize", "minmax", "--size", "800x500"])
        .args(["--frames", "3", "--script", script_path.to_str().unwrap()])
        .args(["--screenshot", shot.to_str().unwrap()])
        .args(extra)
        .output()
        .expect("morphray runs");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && out.contains("validation layer: 0 error(s)"),
        "exit {:?}\nstdout:\n{out}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

fn layout_line(o: &Output) -> String {
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    out.lines()
        .find(|l| l.starts_with("layout:"))
        .unwrap_or_else(|| panic!("no layout line:\n{out}"))
        .to_string()
}

/// The word after `name` in the layout line.
fn word(line: &str, name: &str) -> String {
    let words: Vec<&str> = line.split_whitespace().collect();
    let i = words
        .iter()
        .position(|w| *w == name)
        .unwrap_or_else(|| panic!("{name}: {line}"));
    words[i + 1].to_string()
}

/// The rectangle after the LAST `name` (a plane's name may also be the layout's).
fn rect(line: &str, name: &str) -> [u32; 4] {
    let words: Vec<&str> = line.split_whitespace().collect();
    let i = words
        .iter()
        .rposition(|w| *w == name)
        .unwrap_or_else(|| panic!("{name}: {line}"));
    let v: Vec<u32> = words[i + 1]
        .split(',')
        .map(|n| n.parse().unwrap())
        .collect();
    [v[0], v[1], v[2], v[3]]
}

struct Png {
    width: u32,
    rgba: Vec<u8>,
}

impl Png {
    fn read(path: &Path) -> Png {
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut rgba).unwrap();
        Png {
            width: info.width,
            rgba,
        }
    }

    fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = ((y * self.width + x) * 4) as usize;
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2]]
    }

    /// Mean x (as a fraction of the rectangle's width) of pixels in `r` passing `keep`, and
    /// their count.
    fn mean_x(&self, r: [u32; 4], keep: impl Fn([u8; 3]) -> bool) -> (f64, usize) {
        let mut xs = Vec::new();
        for y in r[1]..r[1] + r[3] {
            for x in r[0]..r[0] + r[2] {
                if keep(self.pixel(x, y)) {
                    xs.push((x - r[0]) as f64 / r[2] as f64);
                }
            }
        }
        (xs.iter().sum::<f64>() / xs.len().max(1) as f64, xs.len())
    }
}

fn bright_grey(p: [u8; 3]) -> bool {
    p[0] == p[1] && p[1] == p[2] && p[0] > 200
}

fn mid_grey(p: [u8; 3]) -> bool {
    p[0] == p[1] && p[1] == p[2] && p[0] > 40 && p[0] < 160
}

#[test]
fn layouts_switch_and_the_slices_show_the_blob_on_the_convention_s_side() {
    let dir = temp_dir("layouts");
    let volume = head(&dir);
    // 3D only (the default): no slice rectangles, the view takes the centre.
    let o = view(&volume, "wait 1\n", &dir.join("3d.png"), false);
    let only_3d = layout_line(&o);
    assert_eq!(word(&only_3d, "slices"), "3d", "{only_3d}");
    assert_eq!(rect(&only_3d, "axial"), [0; 4], "{only_3d}");
    let full_view = rect(&only_3d, "view");
    // One slice large: only the axial rectangle, larger than the 3D view beside it.
    let o = view(
        &volume,
        "layout axial\nwait 2\n",
        &dir.join("one.png"),
        false,
    );
    let one = layout_line(&o);
    let (axial, view_one) = (rect(&one, "axial"), rect(&one, "view"));
    assert!(
        axial[2] > view_one[2] && rect(&one, "coronal") == [0; 4],
        "{one}"
    );
    // 3D + slices, crosshair on the blob: three slices right of a narrower 3D view, each
    // showing the head's grey; the blob on the image's right in radiological convention
    // (the patient's left), on its left in neurological.
    let script = |convention: &str| {
        format!(
            "layout slices\nconvention {convention}\ncrosshair {} {} {}\nwait 2\n",
            BLOB[0], BLOB[1], BLOB[2]
        )
    };
    for (convention, blob_on_right) in [("radiological", true), ("neurological", false)] {
        let shot = dir.join(format!("{convention}.png"));
        let o = view(&volume, &script(convention), &shot, false);
        let line = layout_line(&o);
        assert_eq!(word(&line, "convention"), convention, "{line}");
        let view_rect = rect(&line, "view");
        assert!(view_rect[2] < full_view[2], "the 3D view gave room: {line}");
        let png = Png::read(&shot);
        for plane in ["axial", "coronal", "sagittal"] {
            let r = rect(&line, plane);
            assert!(r[2] > 40 && r[3] > 40, "{plane}: {line}");
            // Within the panel separator, which the central rectangle reaches under by a few pixels.
            assert!(
                r[0] + 8 >= view_rect[0] + view_rect[2],
                "{plane} right of the 3D view: {line}"
            );
            let (_, grey) = png.mean_x(r, mid_grey);
            assert!(
                grey > (r[2] * r[3] / 10) as usize,
                "{plane}: the head's grey ({grey} px)"
            );
        }
        let (x, n) = png.mean_x(rect(&line, "axial"), bright_grey);
        assert!(
            n > 10,
            "{convention}: the blob is in the axial slice ({n} px)"
        );
        assert_eq!(
            x > 0.5,
            blob_on_right,
            "{convention}: blob at {x:.2} of the axial width"
        );
        // Sagittal: anterior on the left in both conventions.
        let (x, _) = png.mean_x(rect(&line, "sagittal"), bright_grey);
        assert!(
            x < 0.5,
            "{convention}: sagittal blob at {x:.2}, anterior is on the left"
        );
    }
}

#[test]
fn a_window_under_xvfb_shows_the_slice_layout() {
    let dir = temp_dir("window");
    let volume = head(&dir);
    let shot = dir.join("window.png");
    let o = view(&volume, "layout slices\nwait 2\n", &shot, true);
    let line = layout_line(&o);
    assert_eq!(word(&line, "slices"), "slices", "{line}");
    let png = Png::read(&shot);
    let (_, grey) = png.mean_x(rect(&line, "coronal"), mid_grey);
    assert!(
        grey > 100,
        "the coronal slice shows the head ({grey} px): {line}"
    );
}

/// Label 7 around the blob on a 2 mm grid with x flipped (another grid than the volume's).
fn labels(dir: &Path) -> PathBuf {
    let dims = [21usize, 19, 17];
    let affine = [
        [-2.0, 0.0, 0.0, 20.0],
        [0.0, 2.0, 0.0, -18.0],
        [0.0, 0.0, 2.0, -16.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut values = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let w = [
                    20.0 - 2.0 * i as f64,
                    -18.0 + 2.0 * j as f64,
                    -16.0 + 2.0 * k as f64,
                ];
                let d2: f64 = (0..3).map(|a| (w[a] - BLOB[a]).powi(2)).sum();
                values.push(if d2 < 16.0 { 7u8 } else { 0 });
            }
        }
    }
    let v = Volume::from_voxels(
        "labels",
        dims,
        Samples::from_u8(values),
        affine,
        LinearMap::IDENTITY,
    )
    .unwrap();
    let path = dir.join("labels.nii");
    write_nifti1(&v, &path, false).unwrap();
    path
}

#[test]
fn the_overlay_colours_the_blob_on_the_slices_and_its_switch_hides_it() {
    let dir = temp_dir("overlay");
    let volume = head(&dir);
    let labels = labels(&dir);
    let lut = dir.join("lut.txt");
    std::fs::write(&lut, "7 Blob 255 0 0 0\n").unwrap();
    let extra = [
        "--overlay",
        labels.to_str().unwrap(),
        "--overlay-lut",
        lut.to_str().unwrap(),
        "--overlay-opacity",
        "1",
    ];
    let cross = format!("crosshair {} {} {}\n", BLOB[0], BLOB[1], BLOB[2]);
    let red = |p: [u8; 3]| p == [255, 0, 0];
    let shot = dir.join("on.png");
    let o = view_with(
        &volume,
        &format!("layout slices\n{cross}wait 2\n"),
        &shot,
        false,
        &extra,
    );
    // The readout names the label under the crosshair from the lookup table (issue 31 item 1).
    let log = String::from_utf8_lossy(&o.stdout);
    assert!(log.contains("|  label 7 Blob"), "{log}");
    let axial = rect(&layout_line(&o), "axial");
    let (x, n) = Png::read(&shot).mean_x(axial, red);
    assert!(n > 10, "the label is drawn on the axial slice ({n} px)");
    assert!(x > 0.5, "on the image's right (radiological): {x:.2}");
    let shot = dir.join("off.png");
    let script = format!("layout slices\n{cross}label 7 off\nwait 2\n");
    let o = view_with(&volume, &script, &shot, false, &extra);
    let (_, n) = Png::read(&shot).mean_x(rect(&layout_line(&o), "axial"), red);
    assert_eq!(n, 0, "label 7 switched off");
}

#[test]
fn the_overlay_shows_in_the_3d_view_and_its_switches_hide_it_there_too() {
    let dir = temp_dir("overlay-3d");
    let volume = head(&dir);
    let labels = labels(&dir);
    let lut = dir.join("lut.txt");
    std::fs::write(&lut, "7 Blob 0 255 0 0\n").unwrap();
    let extra = [
        "--overlay",
        labels.to_str().unwrap(),
        "--overlay-lut",
        lut.to_str().unwrap(),
        "--overlay-opacity",
        "1",
    ];
    let green = |p: [u8; 3]| p[1] > 80 && u32::from(p[1]) > 2 * u32::from(p[0].max(p[2]));
    // The default 3D layout, anterior view: the label around the left blob is drawn on the
    // image's right (the patient faces the viewer).
    let shot = dir.join("3d-on.png");
    let o = view_with(&volume, "wait 2\n", &shot, false, &extra);
    let view = rect(&layout_line(&o), "view");
    let (x, n) = Png::read(&shot).mean_x(view, green);
    assert!(n > 30, "the label is drawn in 3D ({n} px)");
    assert!(x > 0.5, "on the image's right: {x:.2}");
    // Its switch hides it in 3D as on the slices.
    let shot = dir.join("3d-off.png");
    let o = view_with(&volume, "label 7 off\nwait 2\n", &shot, false, &extra);
    let (_, n) = Png::read(&shot).mean_x(rect(&layout_line(&o), "view"), green);
    assert_eq!(n, 0, "label 7 switched off in 3D");
}

/// Issue 31 item 1: the crosshair's world mm, voxel and value in the file's units are read out
/// (status bar; the scripted log prints the same line): on the blob, its stored 1000.
#[test]
fn the_crosshair_reads_out_mm_voxel_and_value() {
    let dir = temp_dir("readout");
    let volume = head(&dir);
    let script = format!("crosshair {} {} {}\nwait 1\n", BLOB[0], BLOB[1], BLOB[2]);
    let o = view(&volume, &script, &dir.join("readout.png"), false);
    let out = String::from_utf8_lossy(&o.stdout);
    // The nearest voxel of the blob's centre (half-way cases round away from zero).
    let index = |a: usize| ((DIMS[a] as f64 - 1.0) / 2.0 + BLOB[a]).round();
    let voxel = format!("voxel {}, {}, {}", index(0), index(1), index(2));
    let line = out
        .lines()
        .find(|l| l.contains("crosshair  L 8.0  A 7.0  S 6.0 mm"))
        .unwrap_or_else(|| panic!("no readout of the blob in:\n{out}"));
    assert!(line.contains(&voxel), "{line} (expected {voxel})");
    assert!(line.ends_with("value 1000"), "{line}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 31 item 7: `morphray view` opens on 3D + slices (the readout's crosshair on show);
/// `--layout 3d` asks for the 3D view alone.
#[test]
fn the_viewer_opens_on_3d_and_slices() {
    let dir = temp_dir("first-layout");
    let volume = head(&dir);
    let run = |extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_morphray"))
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY")
            .args([
                "view",
                "--offscreen",
                volume.to_str().unwrap(),
                "--frames",
                "3",
            ])
            .args(["--size", "800x500"])
            .args(extra)
            .output()
            .expect("morphray runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        layout_line(&o)
    };
    let first = run(&[]);
    assert_eq!(word(&first, "slices"), "slices", "{first}");
    let alone = run(&["--layout", "3d"]);
    assert_eq!(word(&alone, "slices"), "3d", "{alone}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Issue 31 item 2: a depth pick (a click on the 3D view; here the script's `pick`) moves the
/// crosshair to the point the picture shows under it: in a MIP (this volume has no tissue
/// classes for DVR to show), at the view's centre the anterior view's ray first holds its
/// maximum where it enters the dim sphere's plateau (radius 15 mm about the origin) on the y
/// axis; at the corner it meets nothing and the crosshair stays.
#[test]
fn a_pick_moves_the_crosshair_to_the_surface_under_it() {
    let dir = temp_dir("pick");
    let volume = head(&dir);
    let script = "mode mip\nwait 1\npick 0.02 0.02\nwait 1\npick 0.5 0.5\nwait 2\n";
    let o = view(&volume, script, &dir.join("pick.png"), false);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        out.contains("pick: 0.020,0.020 of the view: nothing visible there"),
        "{out}"
    );
    let line = out
        .lines()
        .find(|l| l.starts_with("pick: 0.500,0.500 of the view -> "))
        .unwrap_or_else(|| panic!("no pick at the centre in:\n{out}"));
    let point: Vec<f64> = line
        .split("-> ")
        .nth(1)
        .and_then(|s| s.strip_suffix(" mm (world)"))
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        point[0].abs() < 1.5 && point[2].abs() < 1.5 && (12.0..16.0).contains(&point[1]),
        "{line}: not the sphere's front on the y axis"
    );
    // The slices follow: the readout is at the picked point.
    let readout = format!("A {:.1}", point[1]);
    assert!(
        out.lines()
            .any(|l| l.starts_with("crosshair") && l.contains(&readout)),
        "no readout at {readout} in:\n{out}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
