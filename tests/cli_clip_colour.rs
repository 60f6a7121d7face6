//! `render` with a crop box, clip planes and colour maps (issue 16 items 2 and 4), as a user runs
//! it, with the pictures checked numerically: a greyscale MIP is exactly grey, a colour map is
//! not, a crop removes its part of the picture, bad values are usage errors naming the option;
//! and the turntable movie (item 7) decoded frame by frame.

use morphray::volume::nifti::write_nifti1;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-cli-clip-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A float volume with identity affine: world x, y, z are the voxel indices i, j, k (mm).
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

/// (width, height, RGBA8) of a PNG.
fn read_png(path: &Path) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut rgba).unwrap();
    rgba.truncate(info.buffer_size());
    (info.width, info.height, rgba)
}

fn lit(rgba: &[u8]) -> impl Iterator<Item = &[u8]> {
    rgba.chunks_exact(4)
        .filter(|p| p[..3].iter().any(|&c| c > 1))
}

/// A bright ball in a dimmer ramp: MIP shows grey levels across the whole picture.
fn ball() -> PathBuf {
    float_volume("ball", [23, 21, 19], |x, y, z| {
        let d = ((x as f32 - 11.0).powi(2) + (y as f32 - 10.0).powi(2) + (z as f32 - 9.0).powi(2))
            .sqrt();
        if d < 6.0 { 1000.0 } else { 20.0 * x as f32 }
    })
}

fn render(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "48x40",
        "--no-jitter",
    ];
    args.extend_from_slice(extra);
    morphray(&args)
}

#[test]
fn a_greyscale_mip_is_exactly_grey_and_a_colour_map_is_not() {
    let input = ball();
    let grey = temp("mip-gray.png");
    let o = render(&input, &grey, &["--mode", "mip", "--colormap", "gray"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, rgba) = read_png(&grey);
    assert!(lit(&rgba).count() > 500, "the MIP shows the volume");
    for p in rgba.chunks_exact(4) {
        assert!(p[0] == p[1] && p[1] == p[2], "not grey: {p:?}");
    }
    // Several grey levels, not a binary mask.
    let levels: std::collections::BTreeSet<u8> = rgba.chunks_exact(4).map(|p| p[0]).collect();
    assert!(levels.len() > 10, "{} grey levels", levels.len());

    let hot = temp("mip-hot.png");
    let o = render(&input, &hot, &["--mode", "mip", "--colormap", "hot"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, rgba) = read_png(&hot);
    // hot: red leads green leads blue at every level.
    let coloured = lit(&rgba)
        .filter(|p| i32::from(p[0]) > i32::from(p[1]) + 20)
        .count();
    assert!(coloured > 200, "{coloured} reddish pixels");
    assert!(
        lit(&rgba).all(|p| p[0] >= p[1] && p[1] >= p[2]),
        "hot orders R >= G >= B"
    );

    // DVR with a colour map instead of the tissue colours: a window by hand shows the ball.
    let dvr = temp("dvr-viridis.png");
    let o = render(
        &input,
        &dvr,
        &[
            "--tissues",
            "wm",
            "--window",
            "wm=0.5:1.2",
            "--tissue-opacity",
            "wm=1",
            "--colormap",
            "viridis",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, _, rgba) = read_png(&dvr);
    // viridis' bright end is yellow: green and red above blue.
    let yellowish = lit(&rgba).filter(|p| p[1] > p[2] && p[0] > p[2]).count();
    assert!(yellowish > 50, "{yellowish} yellowish pixels");
}

#[test]
fn crop_and_clip_plane_remove_their_part_of_the_picture() {
    let input = ball();
    let (full, cropped, clipped) = (temp("full.png"), temp("cropped.png"), temp("clipped.png"));
    // Anterior orthographic view: image right = patient's left = -x, image up = +z.
    let view = ["--mode", "mip", "--projection", "orthographic"];
    let o = render(&input, &full, &view);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut args = view.to_vec();
    args.extend(["--crop", "0:1,0:1,0.5:1"]);
    let o = render(&input, &cropped, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut args = view.to_vec();
    // Keep x <= 11 (world mm = index here; RAS: +x is the patient's right): the patient's left
    // half, which the anterior view shows on the image's right.
    args.extend(["--clip-plane", "-1,0,0,11"]);
    let o = render(&input, &clipped, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, full) = read_png(&full);
    let (_, _, cropped) = read_png(&cropped);
    let (_, _, clipped) = read_png(&clipped);
    let lit_in = |rgba: &[u8], rows: std::ops::Range<u32>, cols: std::ops::Range<u32>| {
        let mut n = 0;
        for y in rows {
            for x in cols.clone() {
                let i = 4 * (y * w + x) as usize;
                n += rgba[i..i + 3].iter().any(|&c| c > 1) as usize;
            }
        }
        n
    };
    let (top, bottom) = (0..h / 2 - 2, h / 2 + 2..h);
    let (left, right) = (0..w / 2 - 2, w / 2 + 2..w);
    // The full MIP is lit in every quadrant.
    for (rows, cols) in [(top.clone(), left.clone()), (bottom.clone(), right.clone())] {
        assert!(lit_in(&full, rows, cols) > 50);
    }
    // Cropping k to its upper half (superior: the top of the anterior view) empties the bottom.
    assert_eq!(
        lit_in(&cropped, bottom.clone(), 0..w),
        0,
        "crop keeps the bottom"
    );
    assert!(lit_in(&cropped, top.clone(), 0..w) > 100);
    // The plane keeps x <= 11: the patient's left half, on the image's right.
    assert_eq!(
        lit_in(&clipped, 0..h, left.clone()),
        0,
        "clip keeps the image's left"
    );
    assert!(lit_in(&clipped, 0..h, right.clone()) > 100);
    // The provenance records the clip.
    let chunks = morphray::files::png::read_text_chunks(&temp("clipped.png")).unwrap();
    let parameters = &chunks
        .iter()
        .find(|(k, _)| k.contains("parameters"))
        .unwrap()
        .1;
    let json: serde_json::Value = serde_json::from_str(parameters).unwrap();
    assert_eq!(
        json["scene"]["clip"]["planes"][0]["normal"][0], -1.0,
        "{}",
        json["scene"]
    );
}

#[test]
fn bad_crops_planes_and_colour_maps_are_usage_errors_naming_the_option() {
    let out = temp("bad.png");
    for bad in [
        ["--crop", "0:1,0.8:0.2,0:1"],
        ["--crop", "0:1,0:1"],
        ["--crop", "0:1,0:1,0:1.5"],
        ["--clip-plane", "0,0,0,1"],
        ["--clip-plane", "1,0,nan,1"],
        ["--colormap", "jet"],
    ] {
        let o = morphray(&["render", "-o", out.to_str().unwrap(), bad[0], bad[1]]);
        assert_eq!(o.status.code(), Some(2), "{bad:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(bad[0]), "{bad:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    }
    let five: Vec<&str> = (0..5).flat_map(|_| ["--clip-plane", "1,0,0,0"]).collect();
    let mut args = vec!["render", "-o", out.to_str().unwrap()];
    args.extend(five);
    // Counted after parsing: a one-line error (exit 1, like the other scene checks).
    let o = morphray(&args);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(stderr(&o).trim_end().lines().count(), 1, "{}", stderr(&o));
    assert!(stderr(&o).starts_with("morphray: "), "{}", stderr(&o));
    assert!(stderr(&o).contains("at most 4"), "{}", stderr(&o));
}

#[test]
fn a_turntable_movie_is_an_animated_png_of_the_frames_and_never_replaces_the_input() {
    let input = ball();
    let out = temp("spin.png");
    let movie = temp("spin-movie.png");
    let o = morphray(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "32x24",
        "--mode",
        "mip",
        "--turntable",
        "4",
        "--movie",
        movie.to_str().unwrap(),
        "--fps",
        "10",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("4 frames at 10 fps"));
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&movie).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let control = reader.info().animation_control.expect("an animated PNG");
    assert_eq!(control.num_frames, 4);
    assert_eq!(control.num_plays, 0, "loops forever");
    let mut frames = Vec::new();
    for i in 0..4 {
        let mut rgba = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut rgba).unwrap();
        assert_eq!((info.width, info.height), (32, 24));
        let fc = reader
            .info()
            .frame_control
            .expect("a frame control per frame");
        assert_eq!((fc.delay_num, fc.delay_den), (1, 10));
        // Frame i of the movie is the turntable's still i, byte for byte.
        let (_, _, still) = read_png(&temp(&format!("spin-{i:03}.png")));
        assert_eq!(rgba, still, "frame {i}");
        frames.push(rgba);
    }
    for i in 0..4 {
        for j in i + 1..4 {
            assert_ne!(frames[i], frames[j], "frames {i} and {j} are the same");
        }
    }
    // The input is never the movie: refused before any work, the input untouched.
    let before = std::fs::read(&input).unwrap();
    let o = morphray(&[
        "render",
        input.to_str().unwrap(),
        "-o",
        temp("again.png").to_str().unwrap(),
        "--turntable",
        "2",
        "--movie",
        input.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("input"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&input).unwrap(), before);
    // Without --turntable, --movie is a usage error.
    let o = morphray(&[
        "render",
        "-o",
        out.to_str().unwrap(),
        "--movie",
        movie.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    // A GIF name is refused with the extension to use.
    let o = morphray(&[
        "render",
        "-o",
        out.to_str().unwrap(),
        "--turntable",
        "2",
        "--movie",
        temp("spin.gif").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains(".png"), "{}", stderr(&o));
}

/// Centre of mass (x, y) of the lit pixels, as fractions of the width and height.
fn centre_of_lit(path: &Path) -> (f64, f64) {
    let (w, h, rgba) = read_png(path);
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for (i, p) in rgba.chunks_exact(4).enumerate() {
        if p[..3].iter().any(|&c| c > 1) {
            sx += (i as u32 % w) as f64;
            sy += (i as u32 / w) as f64;
            n += 1.0;
        }
    }
    assert!(n > 10.0, "{}: nothing lit", path.display());
    (sx / n / w as f64, sy / n / h as f64)
}

#[test]
fn superior_and_inferior_views_put_anterior_at_the_top() {
    // Identity affine (RAS mm = voxel index): a blob at the patient's left (low x), anterior
    // (high y), mid-height.
    let input = float_volume("anterior-left-blob", [21, 19, 17], |x, y, z| {
        let d2 = (x as f32 - 5.0).powi(2) + (y as f32 - 14.0).powi(2) + (z as f32 - 8.0).powi(2);
        if d2 < 9.0 { 1000.0 } else { 0.0 }
    });
    let view = |name: &str| {
        let out = temp(&format!("view-{name}.png"));
        let o = render(
            &input,
            &out,
            &[
                "--mode",
                "mip",
                "--projection",
                "orthographic",
                "--view",
                name,
            ],
        );
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        centre_of_lit(&out)
    };
    // Superior: anterior up, the patient's left on the image's left (seen from above).
    let (x, y) = view("superior");
    assert!(
        y < 0.4,
        "superior: anterior blob at y {y}, expected the top"
    );
    assert!(
        x < 0.4,
        "superior: left blob at x {x}, expected the image's left"
    );
    // Inferior: anterior up, the patient's left on the image's right (seen from below).
    let (x, y) = view("inferior");
    assert!(
        y < 0.4,
        "inferior: anterior blob at y {y}, expected the top"
    );
    assert!(
        x > 0.6,
        "inferior: left blob at x {x}, expected the image's right"
    );
    // Anterior: the patient's left on the image's right, mid-height.
    let (x, y) = view("a");
    assert!(
        x > 0.6 && (0.35..0.65).contains(&y),
        "anterior: blob at ({x}, {y})"
    );
    // --view and --elevation together are a usage error.
    let o = morphray(&[
        "render",
        "-o",
        "x.png",
        "--view",
        "superior",
        "--elevation",
        "10",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

#[test]
fn turntable_progress_is_shown_when_asked_and_silent_in_a_pipe() {
    let input = ball();
    let out = temp("progress.png");
    let args = [
        "render",
        input.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--size",
        "16x16",
        "--turntable",
        "3",
    ];
    // stderr is a pipe here: no progress unless asked.
    let quiet = morphray(&args);
    assert!(quiet.status.success(), "{}", stderr(&quiet));
    assert!(!stderr(&quiet).contains("frames 1/3"), "{}", stderr(&quiet));
    let asked = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_PROGRESS", "always")
        .output()
        .unwrap();
    assert!(asked.status.success(), "{}", stderr(&asked));
    let err = stderr(&asked);
    for i in 1..=3 {
        assert!(err.contains(&format!("morphray: frames {i}/3")), "{err}");
    }
    assert!(err.contains("rendering 16x16"), "{err}");
    // stdout keeps exactly the `wrote` lines.
    let out = String::from_utf8_lossy(&asked.stdout);
    assert_eq!(
        out.lines().filter(|l| l.starts_with("wrote")).count(),
        3,
        "{out}"
    );
}

#[test]
fn bench_says_its_phases_when_progress_is_asked_and_nothing_in_a_pipe() {
    let input = ball();
    let args = [
        "bench",
        input.to_str().unwrap(),
        "--trials",
        "0",
        "--frames",
        "2",
        "--repeat",
        "1",
        "--size",
        "16x16",
    ];
    let quiet = morphray(&args);
    assert!(quiet.status.success(), "{}", stderr(&quiet));
    assert!(!stderr(&quiet).contains("bench: "), "{}", stderr(&quiet));
    let asked = Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_PROGRESS", "always")
        .output()
        .unwrap();
    assert!(asked.status.success(), "{}", stderr(&asked));
    let err = stderr(&asked);
    for phase in [
        "morphray: bench: analysis and derivative passes, 1 repeats each",
        "morphray: bench: orbit of 2 frames at 16x16",
    ] {
        assert!(err.contains(phase), "{err}");
    }
}
