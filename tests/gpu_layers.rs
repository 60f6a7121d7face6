//! Intensity layers in the 3D raymarch (issue 31 item 4) on the GPU, against the f64 twin
//! (`reference::raymarch::ReferenceLayer`): a two-sided z-map on its own coarser, rotated grid
//! over the phantom's tissues, flat, shaded and cut away; a layer where no tissue is visible (empty-space
//! skipping must not skip it); two layers with a cluster size; a threshold above every value
//! changing nothing.

mod common;

use common::twin_compare::{
    Case, TwinInputs, assert_matches, compare, prepare, render_float, rgba,
};

use common::volumes::volume_with_affine;
use morphray::engine::{Engine, LayerVolume};
use morphray::reference::raymarch::{ReferenceDerived, ReferenceLayer, ReferenceRaymarch};
use morphray::scene::Scene;
use morphray::scene::layer::{LayerColormap, LayerStyle};
use morphray::scene::layer_grid::LayerGrid;
use morphray::volume::Samples;
use morphray::volume::phantom::{PhantomSpec, generate};
use std::sync::Arc;

type Attached = Vec<(Arc<LayerVolume>, LayerStyle)>;

fn gpu_render(
    engine: &mut Engine,
    case: &Case,
    layers: &Attached,
    (w, h): (u32, u32),
) -> Vec<[f64; 4]> {
    let frame = render_float(engine, case, &case.scene, (w, h), |target| {
        target.set_layers(layers.clone()).unwrap()
    });
    rgba(&frame)
}

fn twin(engine: &Engine, case: &Case, layers: &Attached, size: (u32, u32)) -> Vec<[f64; 4]> {
    with_twin(engine, case, layers, size, |r| r.render())
}

/// Runs `f` on the f64 twin of `case` with `layers` at `(w, h)` pixels.
fn with_twin<R>(
    engine: &Engine,
    case: &Case,
    layers: &Attached,
    (w, h): (u32, u32),
    f: impl FnOnce(&ReferenceRaymarch) -> R,
) -> R {
    let inputs = TwinInputs::of(engine, case);
    let volume = inputs.volume();
    let (geometry, stats) = (&inputs.geometry, &inputs.stats);
    let codes: Vec<_> = layers.iter().map(|(l, _)| l.grid.codes()).collect();
    let tables: Vec<_> = layers.iter().map(|(_, style)| style.tables()).collect();
    let reference: Vec<ReferenceLayer> = layers
        .iter()
        .zip(&codes)
        .zip(&tables)
        .map(|(((l, style), codes), tables)| ReferenceLayer {
            dims: l.grid.dims,
            codes: &codes.codes,
            decode: [codes.lo, codes.scale],
            index_map: l.index_map,
            window: [style.lo, style.hi, style.threshold],
            opacity: style.opacity,
            positive: &tables.positive,
            negative: style.negative.map(|_| &tables.negative[..]),
        })
        .collect();
    let derived = ReferenceDerived::NONE;
    let twin = ReferenceRaymarch::new(&case.scene, geometry, stats, &volume, &derived, w, h)
        .unwrap()
        .with_layers(&reference);
    f(&twin)
}

/// The 29^3 phantom and a z-map whose blobs lie apart from the first test's (a positive one at
/// layer voxel (8, 5, 9), a negative one at (3, 6, 3), a lone voxel at (2, 9, 10)).
fn phantom_with_blobs_apart() -> (morphray::volume::Volume, morphray::volume::Volume) {
    let phantom = generate(&PhantomSpec::cube(29)).unwrap();
    let layer = z_map(
        &phantom.volume.orientation.affine,
        [13, 11, 12],
        [8.0, 5.0, 9.0],
        [3.0, 6.0, 3.0],
        [2, 9, 10],
    );
    (phantom.volume, layer)
}

/// A layer of `dims` voxels of 2 mm, turned 12 degrees about z and shifted against the base
/// volume `base` (its index-to-world affine), with a positive ball (peak 6) around layer voxel
/// `plus`, a negative one (peak -5) around `minus`, and one lone voxel of 4.5 at `lone`.
fn z_map(
    base: &[[f64; 4]; 4],
    dims: [usize; 3],
    plus: [f64; 3],
    minus: [f64; 3],
    lone: [usize; 3],
) -> morphray::volume::Volume {
    let (c, s) = (12f64.to_radians().cos(), 12f64.to_radians().sin());
    // Layer index -> base index: rotate, scale by 2 (base voxels are about 1 mm here), shift.
    let local = [
        [2.0 * c, -2.0 * s, 0.0, 1.3],
        [2.0 * s, 2.0 * c, 0.0, -0.7],
        [0.0, 0.0, 2.0, 0.4],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let mut affine = [[0.0; 4]; 4];
    for (r, row) in affine.iter_mut().enumerate() {
        for (col, cell) in row.iter_mut().enumerate() {
            *cell = (0..4).map(|m| base[r][m] * local[m][col]).sum();
        }
    }
    let mut values = vec![0f32; dims.iter().product()];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let q = [i as f64, j as f64, k as f64];
                let d2 = |c: [f64; 3]| (0..3).map(|a| (q[a] - c[a]).powi(2)).sum::<f64>();
                let v = 6.0 * (-d2(plus) / 6.0).exp() - 5.0 * (-d2(minus) / 4.0).exp();
                values[i + dims[0] * (j + dims[1] * k)] = v as f32;
            }
        }
    }
    values[lone[0] + dims[0] * (lone[1] + dims[1] * lone[2])] = 4.5;
    volume_with_affine(dims, affine, Samples::from_f32(&values))
}

fn style(lo: f64, hi: f64, cluster: u32) -> LayerStyle {
    LayerStyle {
        colormap: LayerColormap::RedYellow,
        lo,
        hi,
        threshold: lo,
        negative: Some(LayerColormap::BlueLightblue),
        cluster,
        opacity: 0.8,
    }
}

fn upload(
    engine: &mut Engine,
    case: &Case,
    layer: &morphray::volume::Volume,
    style: LayerStyle,
) -> (Arc<LayerVolume>, LayerStyle) {
    let grid = LayerGrid::from_volume(layer).unwrap();
    let (drawn, _) = grid.clustered(&style);
    (
        Arc::new(engine.upload_layer(&case.prepared, drawn).unwrap()),
        style,
    )
}

/// Pixels whose colour is mostly red (positive side) and mostly blue (negative side).
fn red_and_blue(pixels: &[[f64; 4]]) -> (usize, usize) {
    let red = pixels
        .iter()
        .filter(|p| p[0] > 0.4 && p[0] > 2.0 * p[2])
        .count();
    let blue = pixels
        .iter()
        .filter(|p| p[2] > 0.4 && p[2] > 2.0 * p[0])
        .count();
    (red, blue)
}

#[test]
fn a_two_sided_z_map_on_its_own_rotated_grid_matches_the_twin_flat_and_shaded() {
    let mut engine = common::engine();
    // 29 voxels: not a multiple of the 8^3 bricks or the 8x8 tiles.
    let phantom = generate(&PhantomSpec::cube(29)).unwrap();
    let layer = z_map(
        &phantom.volume.orientation.affine,
        [13, 11, 12],
        [6.0, 6.0, 7.0],
        [4.0, 3.0, 4.0],
        [11, 9, 2],
    );
    let size = (64, 48);
    for (shading, cut) in [(false, false), (true, false), (true, true)] {
        let case = prepare(&mut engine, &phantom.volume, |s| {
            s.effects.shading = shading;
            // A cut-away: the layer on the cut face is drawn unshaded, as the tissue there.
            s.cutaway = cut.then(morphray::scene::Cutaway::default);
        });
        let layers = vec![upload(&mut engine, &case, &layer, style(2.0, 5.0, 0))];
        let gpu = gpu_render(&mut engine, &case, &layers, size);
        let cpu = twin(&engine, &case, &layers, size);
        assert_matches(
            &format!("z-map, shading {shading}, cut-away {cut}"),
            &gpu,
            &cpu,
        );
        let plain = gpu_render(&mut engine, &case, &Vec::new(), size);
        let (psnr, _) = compare(&gpu, &plain);
        assert!(
            psnr < 35.0,
            "shading {shading}: the layer changed nothing ({psnr:.1} dB)"
        );
        // A threshold above every value: exactly the picture without the layer.
        let silent = vec![upload(&mut engine, &case, &layer, style(7.0, 9.0, 0))];
        let (psnr, off) = compare(&gpu_render(&mut engine, &case, &silent, size), &plain);
        assert!(
            psnr > 100.0 && off == 0.0,
            "a layer above its threshold drew ({psnr:.1} dB)"
        );
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn layers_where_no_tissue_is_visible_are_drawn_and_not_skipped() {
    let mut engine = common::engine();
    let (phantom, layer) = phantom_with_blobs_apart();
    let size = (56, 40);
    let hide = |s: &mut Scene| {
        for tissue in &mut s.classification.tissues {
            tissue.visible = false;
        }
    };
    let case = prepare(&mut engine, &phantom, hide);
    assert!(case.scene.effects.quality.empty_space_skipping);
    let layers = vec![upload(&mut engine, &case, &layer, style(2.0, 5.0, 0))];
    let gpu = gpu_render(&mut engine, &case, &layers, size);
    assert_matches("no tissue", &gpu, &twin(&engine, &case, &layers, size));
    let (red, blue) = red_and_blue(&gpu);
    assert!(
        red > 40 && blue > 20,
        "the blobs show: {red} red, {blue} blue pixels"
    );
    // Skipping off: the same picture (skipping is lossless with layers).
    let unskipped = prepare(&mut engine, &phantom, |s| {
        hide(s);
        s.effects.quality.empty_space_skipping = false;
    });
    let layers = vec![upload(&mut engine, &unskipped, &layer, style(2.0, 5.0, 0))];
    let (psnr, off) = compare(&gpu_render(&mut engine, &unskipped, &layers, size), &gpu);
    assert!(
        psnr > 60.0 && off == 0.0,
        "skipping lost layer samples ({psnr:.1} dB)"
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn two_layers_draw_both_and_a_cluster_size_removes_the_lone_voxel() {
    let mut engine = common::engine();
    let phantom = generate(&PhantomSpec::cube(29)).unwrap();
    let affine = phantom.volume.orientation.affine;
    let first = z_map(
        &affine,
        [13, 11, 12],
        [6.0, 6.0, 7.0],
        [4.0, 3.0, 4.0],
        [11, 9, 2],
    );
    let second = z_map(
        &affine,
        [9, 10, 8],
        [3.0, 7.0, 3.0],
        [7.0, 2.0, 5.0],
        [1, 1, 1],
    );
    let size = (48, 48);
    let case = prepare(&mut engine, &phantom.volume, |s| {
        s.effects.shading = true;
        for tissue in &mut s.classification.tissues {
            tissue.visible = false;
        }
    });
    let both = vec![
        upload(&mut engine, &case, &first, style(2.0, 5.0, 0)),
        upload(
            &mut engine,
            &case,
            &second,
            LayerStyle {
                colormap: LayerColormap::Green,
                negative: None,
                ..style(2.5, 6.0, 0)
            },
        ),
    ];
    let gpu = gpu_render(&mut engine, &case, &both, size);
    assert_matches("two layers", &gpu, &twin(&engine, &case, &both, size));
    let green = gpu
        .iter()
        .filter(|p| p[1] > 0.3 && p[1] > 1.5 * p[0] && p[1] > 1.5 * p[2])
        .count();
    assert!(green > 20, "the second layer shows: {green} green pixels");
    // The lone voxel of the first layer (4.5, above the threshold) is one cluster of 1 voxel.
    let grid = LayerGrid::from_volume(&first).unwrap();
    let (_, counts) = grid.clustered(&style(2.0, 5.0, 8));
    assert_eq!(counts.1, 1, "one cluster removed: {counts:?}");
    let alone = vec![upload(&mut engine, &case, &first, style(2.0, 5.0, 0))];
    let clustered = vec![upload(&mut engine, &case, &first, style(2.0, 5.0, 8))];
    let with_lone = gpu_render(&mut engine, &case, &alone, size);
    let without = gpu_render(&mut engine, &case, &clustered, size);
    assert_matches(
        "clustered",
        &without,
        &twin(&engine, &case, &clustered, size),
    );
    let changed = with_lone
        .iter()
        .zip(&without)
        .filter(|(a, b)| (0..3).any(|c| (a[c] - b[c]).abs() > 0.05))
        .count();
    assert!(
        (1..60).contains(&changed),
        "the cluster size removed the lone voxel only: {changed} pixels changed"
    );
    common::assert_no_validation_errors(&engine);
}

#[test]
fn a_pick_meets_the_layers_the_picture_shows_where_the_twin_does() {
    let mut engine = common::engine();
    let (phantom, layer) = phantom_with_blobs_apart();
    let case = prepare(&mut engine, &phantom, |s| {
        for tissue in &mut s.classification.tissues {
            tissue.visible = false;
        }
    });
    let layers = vec![upload(&mut engine, &case, &layer, style(2.0, 5.0, 0))];
    let view = [40u32, 32];
    let pixels: Vec<[u32; 2]> = (0..view[1])
        .step_by(3)
        .flat_map(|y| (0..view[0]).step_by(3).map(move |x| [x, y]))
        .collect();
    let threshold = morphray::engine::pick::DEFAULT_PICK_THRESHOLD;
    // Without the layers no tissue is visible: nothing to meet.
    let blind = engine
        .pick(
            &case.prepared,
            case.derived.as_ref(),
            &case.scene,
            view,
            pixels[0],
            threshold,
        )
        .unwrap();
    assert!(blind.is_none());
    engine.set_pick_layers(layers.clone());
    let (twin, step): (Vec<Option<f64>>, f64) =
        with_twin(&engine, &case, &layers, (view[0], view[1]), |r| {
            let picks = pixels
                .iter()
                .map(|&[x, y]| r.pick(x, y, f64::from(threshold)));
            (picks.collect(), r.step_mm())
        });
    let (mut hits, mut agree) = (0, 0);
    for (&p, t) in pixels.iter().zip(&twin) {
        let g = engine
            .pick(
                &case.prepared,
                case.derived.as_ref(),
                &case.scene,
                view,
                p,
                threshold,
            )
            .unwrap();
        match (g, t) {
            (Some(g), Some(t)) => {
                hits += 1;
                // Within one step of the twin's sample (f32 positions at the blob's edge).
                agree += usize::from((g.ray_mm - t).abs() <= step + 1e-3);
            }
            (None, None) => agree += 1,
            _ => {}
        }
    }
    assert!(hits > 10, "{hits} picks met a blob");
    assert!(
        agree + 2 >= pixels.len(),
        "{agree} of {} picks agree with the twin",
        pixels.len()
    );
    common::assert_no_validation_errors(&engine);
}
