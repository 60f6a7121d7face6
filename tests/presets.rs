//! Presets by modality through the command line (issue 28 item 3): the head phantom as a CT
//! renders its skull with the automatic `ct` preset; a TOF-like tube phantom named as a BIDS
//! `_angio` picks `angio` and shows its vessels; a CT angiogram (BIDS `_angio` with Hounsfield
//! values, a sidecar's ContrastBolusAgent on a CT) picks `angio` with its Hounsfield vessel band
//! and says why; `--preset list`; an unknown name is a one-line error. `render` and `peaks` need
//! a Vulkan device (lavapipe here).

#[path = "common/pictures.rs"]
#[allow(dead_code)]
mod pictures;

use morphray::volume::nifti::write_nifti1;
use pictures::Picture;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn morphray(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_morphray"))
        .args(args)
        .env("MORPHRAY_VALIDATION", "required")
        .output()
        .expect("the morphray binary runs")
}

fn ok(args: &[&str]) -> String {
    let o = morphray(args);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn folder(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("morphray-presets-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Bright ivory pixels (bone; not the red vessel band, not the dimmer MR look).
fn bright(p: [u8; 3]) -> bool {
    p[0] > 170 && p[1] > 130
}

/// The headlight without depth cues: the bone tests below count bright pixels, which the
/// stills' studio lighting (key light, shadows) moves around without changing what is shown.
const HEADLIGHT: [&str; 4] = ["--lighting", "headlight", "--depth-cues", "off"];

#[test]
fn the_head_phantom_as_ct_shows_its_skull_with_the_automatic_ct_preset() {
    let dir = folder("ct");
    let nii = dir.join("head_ct.nii");
    ok(&[
        "phantom",
        "--head",
        "--contrast",
        "ct",
        "--dims",
        "48x48x48",
        "-o",
        s(&nii),
    ]);
    let png = dir.join("ct.png");
    let out = ok(&[
        &["render", s(&nii), "-o", s(&png), "--size", "96x96"][..],
        &HEADLIGHT,
    ]
    .concat());
    assert!(out.contains("preset: ct (CT in Hounsfield units"), "{out}");
    // Brain extraction is for MR heads: the CT's line says it did not run, and why.
    assert!(
        out.contains("brain: not extracted: brain extraction is for structural MR heads"),
        "{out}"
    );
    let ct = Picture::read(&png);
    // The skull encloses the head: the middle of the picture is bone seen from the front.
    let centre = ct.find(Some([40, 40, 16, 16]), bright).len();
    assert!(centre > 200, "only {centre} of 256 centre pixels show bone");
    // The provenance names the preset.
    let text = std::fs::read(&png).unwrap();
    let text = String::from_utf8_lossy(&text);
    assert!(
        text.contains("\"preset\":\"ct\""),
        "no preset in the provenance"
    );
    // By hand, the MR look of the same file shows no skull in the middle of the picture: the
    // paper's translucent MR tissues (with today's opaque GM and WM, a CT's bone in the WM window
    // is as bright as the CT preset's bone, and this predicate cannot tell them apart).
    let mr_png = dir.join("mr.png");
    let out = ok(&[
        &[
            "render",
            s(&nii),
            "-o",
            s(&mr_png),
            "--size",
            "96x96",
            "--preset",
            "paper",
        ][..],
        &HEADLIGHT,
    ]
    .concat());
    assert!(out.contains("preset: paper"), "{out}");
    let mr = Picture::read(&mr_png)
        .find(Some([40, 40, 16, 16]), bright)
        .len();
    assert!(mr * 2 < centre, "mr {mr} vs ct {centre}");
    // With bone hidden (only the CT preset's skin band) the middle goes dark: it was the bone.
    let skin_png = dir.join("skin.png");
    ok(&[
        &[
            "render",
            s(&nii),
            "-o",
            s(&skin_png),
            "--size",
            "96x96",
            "--tissues",
            "csf",
        ][..],
        &HEADLIGHT,
    ]
    .concat());
    let skin = Picture::read(&skin_png)
        .find(Some([40, 40, 16, 16]), bright)
        .len();
    assert_eq!(skin, 0, "bone hidden, yet {skin} bright centre pixels");
}

#[test]
fn a_bids_angio_tube_phantom_picks_the_angio_preset_and_shows_vessels() {
    let dir = folder("angio");
    let nii = dir.join("sub-01_angio.nii");
    let tubes = morphray::volume::shape_phantoms::tubes();
    write_nifti1(&tubes.volume, &nii, false).unwrap();
    let peaks = ok(&["peaks", s(&nii), "--json"]);
    let peaks: serde_json::Value = serde_json::from_str(&peaks).unwrap();
    assert_eq!(peaks["preset"], "angio", "{peaks}");
    let png = dir.join("angio.png");
    let out = ok(&["render", s(&nii), "-o", s(&png), "--size", "96x96"]);
    assert!(out.contains("preset: angio"), "{out}");
    assert!(out.contains("brain: not extracted"), "{out}");
    let red = Picture::read(&png).find(None, pictures::dominant(0)).len();
    assert!(red > 100, "only {red} red vessel pixels");
}

/// The head phantom as a CT in Hounsfield units, written as `name` in `dir`.
fn head_ct(dir: &Path, name: &str) -> PathBuf {
    let nii = dir.join(name);
    ok(&[
        "phantom",
        "--head",
        "--contrast",
        "ct",
        "--dims",
        "48x48x48",
        "-o",
        s(&nii),
    ]);
    nii
}

/// Pixels whose red outweighs green and blue together (the angio band and the vessel channel).
fn red(p: [u8; 3]) -> bool {
    p[0] > 60 && u16::from(p[0]) > u16::from(p[1]) + u16::from(p[2])
}

#[test]
fn a_ct_angiogram_picks_angio_with_its_hounsfield_band_and_says_why() {
    let dir = folder("cta");
    // BIDS `_angio` names no modality; the Hounsfield values make it a CT angiogram.
    let nii = head_ct(&dir, "sub-01_angio.nii");
    let peaks = ok(&["peaks", s(&nii), "--json"]);
    let peaks: serde_json::Value = serde_json::from_str(&peaks).unwrap();
    assert_eq!(peaks["modality"]["modality"], "ct", "{peaks}");
    assert_eq!(peaks["contrast"]["kind"], "angio", "{peaks}");
    assert_eq!(
        peaks["preset"], "angio (CT: vessels 150..600 HU)",
        "{peaks}"
    );
    let png = dir.join("cta.png");
    let out = ok(&["render", s(&nii), "-o", s(&png), "--size", "96x96"]);
    assert!(
        out.contains("preset: angio (CT: vessels 150..600 HU)")
            && out.contains("a CT angiogram: BIDS suffix _angio"),
        "{out}"
    );
    // Bone (1200 HU) is hidden: no ivory; the lumen band (which holds the skull's
    // partial-volume edge and diploe, 300 HU) is red. The plain CT look shows ivory bone.
    let cta = Picture::read(&png);
    let ivory = cta.find(None, bright).len();
    let reds = cta.find(Some([40, 40, 16, 16]), red).len();
    assert!(ivory == 0 && reds > 200, "ivory {ivory}, red centre {reds}");
    let ct_png = dir.join("ct.png");
    let out = ok(&[
        "render",
        s(&nii),
        "-o",
        s(&ct_png),
        "--size",
        "96x96",
        "--preset",
        "ct",
    ]);
    assert!(
        out.contains("preset: ct (") && !out.contains("a CT angiogram"),
        "{out}"
    );
    assert!(Picture::read(&ct_png).find(None, bright).len() > 200);
}

/// The tube phantom as a CT angiogram in Hounsfield units: brain 40 HU, contrast-filled
/// lumen 350 HU (the partial-volume ramp between), a slab of air (-1000 HU) beside the tubes.
fn tubes_in_hu(path: &Path) {
    let mut volume = morphray::volume::shape_phantoms::tubes().volume;
    let [nx, ny, _] = volume.dims;
    let hu: Vec<i16> = volume
        .samples
        .to_f64_vec()
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let y = i / nx % ny;
            if y >= ny - 2 {
                -1000
            } else {
                (40.0 + v * 310.0).round() as i16
            }
        })
        .collect();
    volume.samples = morphray::volume::Samples::from_i16(&hu);
    write_nifti1(&volume, path, false).unwrap();
}

#[test]
fn a_ct_angiogram_in_hounsfield_units_shows_its_vessels_red() {
    let dir = folder("cta-tubes");
    let nii = dir.join("tubes_angio.nii");
    tubes_in_hu(&nii);
    let png = dir.join("angio.png");
    let out = ok(&["render", s(&nii), "-o", s(&png), "--size", "96x96"]);
    assert!(
        out.contains("preset: angio (CT: vessels 150..600 HU)"),
        "{out}"
    );
    // Saturated red: the lumen band and the vessel channel (bone's ivory mixes in green).
    let saturated = |p: [u8; 3]| p[0] > 60 && 3 * u16::from(p[1]) < u16::from(p[0]);
    let red = Picture::read(&png).find(None, saturated).len();
    // The plain CT look draws the 300 HU and up lumen as bone: pink, not red.
    let ct_png = dir.join("ct.png");
    let args = ["render", s(&nii), "-o", s(&ct_png), "--size", "96x96"];
    ok(&[&args[..], &["--preset", "ct"]].concat());
    let ct_red = Picture::read(&ct_png).find(None, saturated).len();
    assert!(
        red > 500 && red > 2 * ct_red,
        "angio {red} red, ct {ct_red}"
    );
}

#[test]
fn a_contrast_agent_on_a_ct_makes_an_angiogram_and_a_plain_ct_stays_ct() {
    let dir = folder("agent");
    let nii = head_ct(&dir, "head.nii");
    let preset = |nii: &Path| {
        let peaks = ok(&["peaks", s(nii), "--json"]);
        let peaks: serde_json::Value = serde_json::from_str(&peaks).unwrap();
        peaks["preset"].as_str().unwrap_or("").to_string()
    };
    assert_eq!(preset(&nii), "ct");
    std::fs::write(
        dir.join("head.json"),
        r#"{"Modality": "CT", "ContrastBolusAgent": "IOPAMIDOL"}"#,
    )
    .unwrap();
    assert_eq!(preset(&nii), "angio (CT: vessels 150..600 HU)");
    let text = ok(&["peaks", s(&nii)]);
    assert!(
        text.contains("a CT angiogram: ContrastBolusAgent 'IOPAMIDOL' on a CT"),
        "{text}"
    );
    // `--preset ct` by hand wins over the automatic choice.
    let by_hand = ok(&["peaks", s(&nii), "--json", "--preset", "ct"]);
    let by_hand: serde_json::Value = serde_json::from_str(&by_hand).unwrap();
    assert_eq!(by_hand["preset"], "ct", "{by_hand}");
}

#[test]
fn preset_list_names_every_preset_and_an_unknown_name_is_one_line() {
    let out = ok(&["render", "--preset", "list"]);
    let names: Vec<&str> = out
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert_eq!(
        names,
        ["mr", "ct", "angio", "post-contrast", "epi", "paper"],
        "{out}"
    );
    let o = morphray(&["peaks", "--preset", "bone"]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    let first = err.lines().next().unwrap_or("");
    assert!(
        first.contains("unknown preset `bone`; use mr, ct, angio, post-contrast, epi, paper"),
        "{err}"
    );
}

#[test]
fn the_paper_preset_is_the_translucent_headlight_look_of_before() {
    // Issue 34: the stills became opaque and studio-lit; `--preset paper` keeps eq. 4's former
    // look, exactly what the opacities and lighting flags of before give.
    let dir = folder("paper");
    let paper = dir.join("paper.png");
    let by_hand = dir.join("by_hand.png");
    ok(&[
        "render",
        "--preset",
        "paper",
        "--size",
        "48x40",
        "-o",
        s(&paper),
    ]);
    ok(&[
        "render",
        "--size",
        "48x40",
        "-o",
        s(&by_hand),
        "--opacity",
        "csf=0.2",
        "--opacity",
        "gm=0.3",
        "--opacity",
        "wm=0.9",
        "--lighting",
        "headlight",
        "--depth-cues",
        "off",
    ]);
    let (a, b) = (Picture::read(&paper), Picture::read(&by_hand));
    assert_eq!(
        a.pixels, b.pixels,
        "--preset paper differs from the flags it stands for"
    );
    let default = dir.join("default.png");
    ok(&["render", "--size", "48x40", "-o", s(&default)]);
    assert_ne!(
        Picture::read(&default).pixels,
        a.pixels,
        "the default look is not the paper's"
    );
}

/// A `side` x `side2` RGBA PNG: grey, bright in its left half (a matcap lit from the left).
fn matcap_png(path: &Path, side: u32, side2: u32) {
    let rgba: Vec<u8> = (0..side * side2)
        .flat_map(|i| {
            let v = if i % side < side / 2 { 240 } else { 70 };
            [v, v, v, 255]
        })
        .collect();
    let provenance = morphray::files::png::Provenance::default();
    morphray::files::png::write_rgba8(path, side, side2, &rgba, &provenance).unwrap();
}

#[test]
fn a_matcap_png_lights_the_still_and_a_bad_one_is_refused_in_one_line() {
    // Issue 34 item 2: `--matcap FILE.png` (implies `--lighting matcap`) lights a still with a
    // user's image; the built-in `clay` is the default matcap; a missing or non-square image is
    // refused before the volume is read.
    let dir = folder("matcap");
    let png = dir.join("left.png");
    matcap_png(&png, 40, 40);
    let (mine, clay) = (dir.join("mine.png"), dir.join("clay.png"));
    let size = ["--size", "48x40"];
    ok(&[
        "render",
        size[0],
        size[1],
        "--matcap",
        s(&png),
        "-o",
        s(&mine),
    ]);
    ok(&[
        "render",
        size[0],
        size[1],
        "--lighting",
        "matcap",
        "-o",
        s(&clay),
    ]);
    let (a, b) = (Picture::read(&mine), Picture::read(&clay));
    assert_ne!(a.pixels, b.pixels, "the user's matcap changed nothing");
    assert!(
        a.pixels.iter().any(|p| bright(*p)),
        "the matcap still is dark"
    );
    let wide = dir.join("wide.png");
    matcap_png(&wide, 40, 20);
    for (matcap, why) in [
        (s(&wide), "square"),
        ("velvet", "no built-in matcap is named \"velvet\""),
    ] {
        let o = morphray(&["render", "--matcap", matcap, "-o", s(&dir.join("x.png"))]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(why), "{matcap}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
}
