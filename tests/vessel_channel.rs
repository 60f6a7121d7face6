//! The vessel channel (issue 15 item 3) on the GPU: classified on the multi-scale vesselness
//! like a tissue on I_norm, matching the f64 reference raymarch given the same vesselness
//! volume, showing the vessel phantom's tubes with every tissue hidden, and computed only when
//! the scene shows vessels.

mod common;

use ash::vk;
use common::pictures::{Picture, dominant};
use morphray::engine::readback::read_image;
use morphray::engine::{Derived, Engine, PreparedVolume, Twin};
use morphray::gpu::Access;
use morphray::reference::raymarch::{ReferenceDerived, ReferenceRaymarch, ReferenceVolume};
use morphray::scene::classification::render_weight;
use morphray::scene::{Classification, RenderMode, Scene, VolumeGeometry};
use morphray::volume::phantom::{PhantomSpec, Tissue, generate};
use morphray::volume::shape_phantoms::tubes;

fn gpu_render(
    engine: &mut Engine,
    prepared: &PreparedVolume,
    derived: &Derived,
    scene: &Scene,
) -> Vec<[f64; 4]> {
    let mut target = engine
        .render_target(64, 48, vk::Format::R32G32B32A32_SFLOAT)
        .unwrap();
    let frame = engine
        .render(&mut target, prepared, Some(derived), scene)
        .unwrap();
    // Skipping stays on with the vessel channel (lossless: the comparisons below hold).
    assert!(frame.skipped_empty_space || !scene.effects.vessels);
    frame
        .values
        .chunks_exact(4)
        .map(|c| [c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64])
        .collect()
}

fn read(engine: &Engine, image: &std::sync::Arc<morphray::gpu::Image>) -> (Vec<f32>, usize) {
    let data = read_image(engine.device(), image, Access::ComputeSampled).unwrap();
    (data.values, data.channels)
}

fn reference(
    engine: &Engine,
    prepared: &PreparedVolume,
    derived: &Derived,
    scene: &Scene,
) -> Vec<[f64; 4]> {
    let norm: Vec<f64> = read(engine, &prepared.normalized)
        .0
        .iter()
        .map(|&v| v as f64)
        .collect();
    let (g, channels) = read(engine, derived.volumes.gradient.as_ref().unwrap());
    let sg = derived.volumes.store_scale[0] as f64;
    let magnitude: Vec<f64> = g.chunks_exact(channels).map(|t| t[0] as f64 / sg).collect();
    let vesselness: Vec<f64> = read(engine, derived.vesselness.as_ref().unwrap())
        .0
        .iter()
        .map(|&v| v as f64)
        .collect();
    let geometry = VolumeGeometry::new(prepared.dims, prepared.affine).unwrap();
    let volume = ReferenceVolume::new(prepared.dims, &norm).unwrap();
    let d = ReferenceDerived {
        gradient_magnitude: Some(&magnitude),
        curvature: None,
        normals: None,
    };
    ReferenceRaymarch::new(scene, &geometry, &derived.stats, &volume, &d, 64, 48)
        .unwrap()
        .with_vesselness(&vesselness)
        .unwrap()
        .render()
}

fn psnr(a: &[[f64; 4]], b: &[[f64; 4]]) -> f64 {
    let mse = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c].min(1.0)).powi(2)))
        .sum::<f64>()
        / (3 * a.len()) as f64;
    10.0 * (1.0 / mse.max(1e-20)).log10()
}

#[test]
fn vessels_alone_show_the_tubes_and_match_the_reference() {
    let mut engine = common::engine();
    let shapes = tubes();
    let prepared = engine.prepare(&shapes.volume).unwrap();
    // No tissue window at all: whatever is drawn comes from the vessel channel.
    let mut scene = Scene::new(Classification::with_windows([None; 4]));
    scene.camera.azimuth_deg = 30.0;
    scene.camera.elevation_deg = 20.0;
    scene.effects.vessels = true;
    let outputs = scene.effects.derivative_outputs().unwrap();
    assert!(outputs.vesselness);
    let derived = engine.derive(&prepared, outputs).unwrap();
    assert!(derived.vesselness.is_some());
    let gpu = gpu_render(&mut engine, &prepared, &derived, &scene);
    let cpu = reference(&engine, &prepared, &derived, &scene);
    let db = psnr(&gpu, &cpu);
    eprintln!("vessel channel: PSNR {db:.1} dB against the reference");
    assert!(db >= 40.0, "PSNR {db:.1} dB");
    let lit = gpu.iter().filter(|p| p[0] > 0.1).count();
    assert!(lit > 150, "the tubes are drawn ({lit} px)");
    // In the vessel colour (crimson: red well above green and blue).
    let red = gpu
        .iter()
        .filter(|p| p[0] > 0.1 && p[0] > 2.0 * p[1].max(p[2]))
        .count();
    assert!(red * 10 >= lit * 9, "{red} of {lit} lit pixels are crimson");
    // The channel switched off: nothing is drawn.
    scene.effects.vessels = false;
    let off = gpu_render(&mut engine, &prepared, &derived, &scene);
    assert!(
        off.iter().all(|p| p[0] + p[1] + p[2] == 0.0),
        "nothing without the channel"
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn the_vesselness_is_computed_only_while_vessels_are_shown() {
    let mut engine = common::engine();
    let prepared = engine.prepare(&tubes().volume).unwrap();
    let mut twin = Twin::new(prepared);
    let mut effects = Scene::new(Classification::with_windows([None; 4])).effects;
    engine.update_twin(&mut twin, &effects).unwrap();
    assert!(
        twin.derived().unwrap().vesselness.is_none(),
        "not shown: not computed"
    );
    effects.vessels = true;
    let update = engine.update_twin(&mut twin, &effects).unwrap();
    assert!(update.recomputed && twin.derived().unwrap().vesselness.is_some());
    assert!(twin.serves(&effects));
    // MIP needs no derived volume: everything is freed, the vesselness too.
    effects.mode = RenderMode::Mip;
    engine.update_twin(&mut twin, &effects).unwrap();
    assert!(twin.derived().is_none());
    common::assert_no_validation_errors(&engine);
}

#[test]
fn the_default_vessel_window_keeps_the_phantoms_vessels_and_drops_its_parenchyma() {
    // The commands' default normalization (robust), so the numbers are those users get.
    let mut engine = common::engine_normalizing(morphray::analysis::NormalizeMode::Robust);
    let phantom = generate(&PhantomSpec {
        dims: [96, 112, 96],
        ..PhantomSpec::cohort_a()
    })
    .unwrap();
    let prepared = engine.prepare(&phantom.volume).unwrap();
    let params = morphray::passes::vesselness::VesselnessParams::default();
    let vesselness = engine.vesselness(&prepared, &params).unwrap();
    let (values, _) = read(&engine, &vesselness.image);
    let window = Classification::with_windows([None; 4]).vessels.window;
    let shown = |tissue: Tissue| {
        let (mut n, mut kept) = (0usize, 0usize);
        for (v, &label) in values.iter().zip(&phantom.labels) {
            if label == tissue as u8 {
                n += 1;
                kept += usize::from(render_weight(&window, *v as f64) >= 0.5);
            }
        }
        kept as f64 / n.max(1) as f64
    };
    let (vessels, wm, gm) = (shown(Tissue::Vessel), shown(Tissue::Wm), shown(Tissue::Gm));
    eprintln!("shown by the default vessel window: vessels {vessels:.3}, WM {wm:.4}, GM {gm:.4}");
    assert!(vessels >= 0.5, "vessels {vessels:.3}");
    assert!(wm <= 0.02 && gm <= 0.01, "WM {wm:.4}, GM {gm:.4}");
    common::assert_no_validation_errors(&engine);
}

/// Crimson pixels (the vessel colour) of a PNG inside the 3D view's rectangle `[x, y, w, h]`.
fn crimson_pixels(path: &std::path::Path, view: [u32; 4]) -> usize {
    Picture::read(path).find(Some(view), dominant(0)).len()
}

/// The 3D view's rectangle from the session log's layout line (`view X,Y,W,H`).
fn view_rect(log: &str) -> [u32; 4] {
    let line = log
        .lines()
        .find(|l| l.starts_with("layout:"))
        .expect("a layout line");
    let words: Vec<&str> = line.split_whitespace().collect();
    let i = words
        .iter()
        .position(|w| *w == "view")
        .expect("view in the layout line");
    let v: Vec<u32> = words[i + 1]
        .split(',')
        .map(|n| n.parse().unwrap())
        .collect();
    [v[0], v[1], v[2], v[3]]
}

#[test]
fn the_viewer_shows_and_hides_the_vessel_channel_from_a_script() {
    let dir = std::env::temp_dir().join(format!("morphray-vessel-view-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let volume = dir.join("ph.nii.gz");
    let bin = env!("CARGO_BIN_EXE_morphray");
    let o = std::process::Command::new(bin)
        .args([
            "phantom",
            "-o",
            volume.to_str().unwrap(),
            "--dims",
            "64x72x56",
            "--force",
        ])
        .output()
        .unwrap();
    assert!(o.status.success());
    let run = |script: &str, shot: &std::path::Path| {
        let path = shot.with_extension("txt");
        std::fs::write(&path, script).unwrap();
        let o = std::process::Command::new(bin)
            .env_remove("DISPLAY")
            .env_remove("WAYLAND_DISPLAY")
            .env("MORPHRAY_VALIDATION", "required")
            .args([
                "view",
                "--layout",
                "3d",
                "--offscreen",
                volume.to_str().unwrap(),
                "--size",
                "480x360",
            ])
            .args(["--frames", "3", "--script", path.to_str().unwrap()])
            .args(["--screenshot", shot.to_str().unwrap()])
            .output()
            .unwrap();
        let log = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(
            o.status.success() && log.contains("validation layer: 0 error(s)"),
            "{log}\n{}",
            String::from_utf8_lossy(&o.stderr)
        );
        view_rect(&log)
    };
    let hidden = "hide csf\nhide gm\nhide wm\n";
    let on = dir.join("on.png");
    let view = run(&format!("{hidden}show vessels\nwait 4\n"), &on);
    let off = dir.join("off.png");
    let script = format!("{hidden}show vessels\nwait 4\nhide vessels\nwait 2\n");
    let view_off = run(&script, &off);
    let (shown, gone) = (crimson_pixels(&on, view), crimson_pixels(&off, view_off));
    assert!(shown > 40, "the vessels are drawn ({shown} crimson px)");
    assert!(
        gone * 10 < shown,
        "hidden again: {gone} crimson px (shown: {shown})"
    );
}

#[test]
fn tissues_vessels_renders_the_vessels_and_plans_the_vesselness_only_for_dvr() {
    let dir = std::env::temp_dir().join(format!("morphray-vessel-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let volume = dir.join("ph.nii.gz");
    let bin = env!("CARGO_BIN_EXE_morphray");
    let morphray = |args: &[&str]| {
        std::process::Command::new(bin)
            .args(args)
            .env("MORPHRAY_VALIDATION", "required")
            .output()
            .unwrap()
    };
    let path = volume.to_str().unwrap();
    assert!(
        morphray(&["phantom", "-o", path, "--dims", "64x72x56", "--force"])
            .status
            .success()
    );
    let out = dir.join("vessels.png");
    let o = morphray(&[
        "render",
        path,
        "--size",
        "96x96",
        "--tissues",
        "vessels,pathology",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let red = crimson_pixels(&out, [0, 0, 96, 96]);
    assert!(red > 20, "vessels and pathology drawn ({red} px)");
    let passes = |extra: &[&str]| {
        let o = morphray(&[&["plan", path, "--json", "--tissues", "vessels"], extra].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let plan: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        plan["passes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["name"].as_str().unwrap().to_string())
            .collect::<Vec<_>>()
    };
    assert!(passes(&[]).contains(&"vesselness".to_string()));
    assert!(!passes(&["--mode", "mip"]).contains(&"vesselness".to_string()));
    // The vessel channel's colour, window and opacity from the command line (`vessels=`).
    let green = dir.join("green.png");
    let args = [
        "render",
        path,
        "--size",
        "96x96",
        "--tissues",
        "vessels",
        "--color",
        "vessels=#00ff00",
    ];
    let o = morphray(&[&args[..], &["-o", green.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (g, r) = (green_pixels(&green), crimson_pixels(&green, [0, 0, 96, 96]));
    assert!(g > 20 && r == 0, "{g} green, {r} crimson px");
    let none = dir.join("none.png");
    let o = morphray(
        &[
            &args[..],
            &["--opacity", "vessels=0", "-o", none.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success());
    assert_eq!(green_pixels(&none), 0, "opacity 0 hides the channel");
    let narrow = dir.join("narrow.png");
    let o = morphray(
        &[
            &args[..],
            &["--window", "vessels=0.7:1", "-o", narrow.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success());
    let n = green_pixels(&narrow);
    assert!(
        n < g,
        "a narrower vesselness window shows less: {n} vs {g} px"
    );
    // An unknown name lists the channel among the accepted ones.
    let o = morphray(&[
        "render",
        path,
        "--tissues",
        "vessel",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("pathology, vessels"));
}

fn green_pixels(path: &std::path::Path) -> usize {
    Picture::read(path).find(None, dominant(1)).len()
}
