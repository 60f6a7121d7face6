//! The classified volume (issue 33 item 1, `ClassificationLookup::Volume`) on the GPU against
//! its f64 twin (`reference/raymarch/classified.rs`): a 29^3 phantom (not a multiple of the
//! bricks or tiles) flat and shaded, an orbit that rebuilds nothing, a window change that
//! rebuilds once, and a cut scene drawn with the per-sample variant instead. Also the per-sample
//! tables read through texel buffers or storage buffers (`EngineConfig::texel_lookups`): the
//! same picture either way, each matching the twin.

mod common;

use ash::vk;
use common::twin_compare::{
    Case, TwinInputs, assert_matches, compare, prepare, render_float, rgba,
};
use morphray::engine::Engine;
use morphray::reference::raymarch::{ReferenceDerived, ReferenceRaymarch};
use morphray::scene::{ClassificationLookup, LightModel, Scene};
use morphray::volume::phantom::{PhantomSpec, generate};

const SIZE: (u32, u32) = (64, 48);

fn gpu_render(engine: &mut Engine, case: &Case, scene: &Scene) -> Vec<[f64; 4]> {
    rgba(&render_float(engine, case, scene, SIZE, |_| {}))
}

fn reference(engine: &Engine, case: &Case, scene: &Scene) -> Vec<[f64; 4]> {
    let inputs = TwinInputs::of(engine, case);
    let volume = inputs.volume();
    let (geometry, stats) = (&inputs.geometry, &inputs.stats);
    ReferenceRaymarch::new(
        scene,
        geometry,
        stats,
        &volume,
        &ReferenceDerived::NONE,
        SIZE.0,
        SIZE.1,
    )
    .unwrap()
    .render()
}

fn classified(scene: &mut Scene) {
    scene.effects.quality.classification = ClassificationLookup::Volume;
}

#[test]
fn the_classified_volume_matches_its_twin_flat_and_shaded_and_stays_near_the_exact_picture() {
    let mut engine = common::engine();
    let phantom = generate(&PhantomSpec::cube(29)).unwrap();
    for shading in [false, true] {
        let case = prepare(&mut engine, &phantom.volume, |s| {
            s.effects.shading = shading;
            classified(s);
        });
        let runs = engine.counters().classify_runs;
        let gpu = gpu_render(&mut engine, &case, &case.scene);
        assert_eq!(engine.counters().classify_runs, runs + 1, "one build");
        let cpu = reference(&engine, &case, &case.scene);
        assert_matches(&format!("classified, shading {shading}"), &gpu, &cpu);
        // Pre-classification approximates the per-sample classification: near it, not equal.
        let mut table = case.scene;
        table.effects.quality.classification = ClassificationLookup::Table;
        let exact = gpu_render(&mut engine, &case, &table);
        let (psnr, _) = compare(&gpu, &exact);
        eprintln!("shading {shading}: classified against per-sample {psnr:.1} dB");
        assert!(
            (20.0..90.0).contains(&psnr),
            "shading {shading}: {psnr:.1} dB from the per-sample picture"
        );
    }
}

#[test]
fn an_orbit_rebuilds_nothing_a_window_change_rebuilds_once_and_a_cut_uses_the_table() {
    let mut engine = common::engine();
    let phantom = generate(&PhantomSpec::cube(29)).unwrap();
    let case = prepare(&mut engine, &phantom.volume, classified);
    let mut target = engine
        .render_target(SIZE.0, SIZE.1, vk::Format::R32G32B32A32_SFLOAT)
        .unwrap();
    let mut scene = case.scene;
    let mut draw = |engine: &mut Engine, scene: &Scene| {
        let frame = engine
            .render(&mut target, &case.prepared, case.derived.as_ref(), scene)
            .unwrap();
        rgba(&frame)
    };
    let runs = engine.counters().classify_runs;
    draw(&mut engine, &scene);
    scene.camera.azimuth_deg += 40.0;
    let turned = draw(&mut engine, &scene);
    assert_eq!(engine.counters().classify_runs, runs + 1, "an orbit");
    assert_matches("turned", &turned, &reference(&engine, &case, &scene));

    // Hide the last visible tissue: one rebuild, and the twin of the new scene.
    let visible = scene
        .classification
        .tissues
        .iter()
        .rposition(|t| t.visible && t.window.is_some())
        .unwrap();
    scene.classification.tissues[visible].visible = false;
    let hidden = draw(&mut engine, &scene);
    assert_eq!(engine.counters().classify_runs, runs + 2, "a window change");
    assert_matches("hidden", &hidden, &reference(&engine, &case, &scene));
    let (psnr, _) = compare(&hidden, &turned);
    assert!(
        psnr < 30.0,
        "hiding a tissue changed nothing ({psnr:.1} dB)"
    );

    // A cut: drawn per sample (no build), identical to the table's picture.
    scene.clip.crop[0] = [0.0, 0.5];
    let cut = draw(&mut engine, &scene);
    assert_eq!(engine.counters().classify_runs, runs + 2, "a cut scene");
    let mut table = scene;
    table.effects.quality.classification = ClassificationLookup::Table;
    let (psnr, _) = compare(&cut, &draw(&mut engine, &table));
    assert!(psnr > 100.0, "the cut scene is the table's ({psnr:.1} dB)");
}

#[test]
fn texel_and_storage_lookups_draw_the_same_picture_and_match_the_twin() {
    let phantom = generate(&PhantomSpec::cube(29)).unwrap();
    let mut pictures = Vec::new();
    for texel_lookups in [false, true] {
        let mut engine = common::engine_with(|c| c.texel_lookups = Some(texel_lookups));
        assert_eq!(engine.texel_lookups(), texel_lookups);
        // Both light models read the transfer-function table and the occupancy bits.
        for model in [LightModel::Studio, LightModel::Matcap] {
            let case = prepare(&mut engine, &phantom.volume, |s| {
                s.effects.shading = true;
                s.effects.lighting.model = model;
            });
            assert_eq!(
                case.scene.effects.quality.classification,
                ClassificationLookup::Table,
                "the default reads the transfer-function table"
            );
            let frame = render_float(&mut engine, &case, &case.scene, SIZE, |_| {});
            assert!(frame.skipped_empty_space, "the occupancy bits were read");
            let gpu = rgba(&frame);
            let cpu = reference(&engine, &case, &case.scene);
            assert_matches(
                &format!("texel lookups {texel_lookups}, {model:?}"),
                &gpu,
                &cpu,
            );
            pictures.push(gpu);
        }
        common::assert_no_validation_errors(&engine);
    }
    // The same f32 entries and bits through either binding: the same arithmetic after them.
    assert_eq!(pictures[0], pictures[2], "studio");
    assert_eq!(pictures[1], pictures[3], "matcap");
}
