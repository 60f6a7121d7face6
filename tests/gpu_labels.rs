//! Label overlays in the 3D raymarch (issue 16 item 3) on the GPU, against the f64 reference
//! (`reference::raymarch::ReferenceLabels`): the phantom's lesion and vessels over its tissues
//! with and without shading, an oblique anisotropic volume whose labels sit where no tissue is
//! visible (empty-space skipping must not skip them), and hidden labels changing nothing.

mod common;

use common::twin_compare::{
    Case, TwinInputs, assert_matches, compare, prepare, render_float, rgba,
};

use common::volumes::{Rng, smooth_field, volume_with_affine};
use morphray::engine::{Engine, LabelVolume, label_colours};
use morphray::reference::raymarch::{ReferenceDerived, ReferenceLabels, ReferenceRaymarch};
use morphray::scene::overlay::{LabelTable, Labels};
use morphray::volume::Samples;
use morphray::volume::phantom::{PhantomSpec, generate};
use std::collections::BTreeSet;
use std::sync::Arc;

fn gpu_render(
    engine: &mut Engine,
    case: &Case,
    labels: Option<(&Arc<LabelVolume>, &[u32])>,
    (w, h): (u32, u32),
) -> Vec<[f64; 4]> {
    let frame = render_float(engine, case, &case.scene, (w, h), |target| {
        target.set_labels(labels.map(|(l, c)| (l.clone(), c.to_vec())))
    });
    rgba(&frame)
}

fn reference(
    engine: &Engine,
    case: &Case,
    labels: &Labels,
    colours: &[u32],
    (w, h): (u32, u32),
) -> Vec<[f64; 4]> {
    let inputs = TwinInputs::of(engine, case);
    let volume = inputs.volume();
    let (geometry, stats) = (&inputs.geometry, &inputs.stats);
    let derived = ReferenceDerived {
        gradient_magnitude: None,
        curvature: None,
        normals: None,
    };
    ReferenceRaymarch::new(&case.scene, geometry, stats, &volume, &derived, w, h)
        .unwrap()
        .with_labels(ReferenceLabels {
            values: &labels.values,
            colours,
        })
        .unwrap()
        .render()
}

fn table(entries: &[(u16, [u8; 3])]) -> LabelTable {
    let text: String = entries
        .iter()
        .map(|(l, [r, g, b])| format!("{l} label{l} {r} {g} {b} 0\n"))
        .collect();
    LabelTable::parse(&text, "test").unwrap()
}

#[test]
fn the_phantoms_lesion_and_vessels_match_the_reference_shaded_and_flat() {
    let mut engine = common::engine();
    // 29 voxels: not a multiple of the 8^3 bricks or the 8x8 tiles.
    let phantom = generate(&PhantomSpec::cube(29)).unwrap();
    let dims = phantom.volume.dims;
    // The lesion (5) and vessels (6); the other labels are left out of the map.
    let values = phantom
        .labels
        .iter()
        .map(|&l| if l == 5 || l == 6 { u16::from(l) } else { 0 })
        .collect();
    let labels = Labels { dims, values };
    let size = (64, 48);
    for shading in [false, true] {
        let case = prepare(&mut engine, &phantom.volume, |s| {
            s.effects.shading = shading
        });
        let uploaded = Arc::new(engine.upload_labels(&case.prepared, &labels).unwrap());
        assert_eq!(uploaded.present, vec![5, 6]);
        let colours = label_colours(
            &table(&[(5, [255, 255, 0]), (6, [255, 0, 0])]),
            &uploaded.present,
            0.8,
            &BTreeSet::new(),
        );
        let gpu = gpu_render(&mut engine, &case, Some((&uploaded, &colours)), size);
        let cpu = reference(&engine, &case, &labels, &colours, size);
        assert_matches(&format!("phantom, shading {shading}"), &gpu, &cpu);
        // The labels show: the picture differs from the one without them.
        let plain = gpu_render(&mut engine, &case, None, size);
        let (psnr, _) = compare(&gpu, &plain);
        assert!(
            psnr < 35.0,
            "shading {shading}: the labels changed nothing ({psnr:.1} dB)"
        );
        // Every label hidden: exactly the picture without labels.
        let hidden = label_colours(
            &LabelTable::default(),
            &uploaded.present,
            0.8,
            &BTreeSet::from([5, 6]),
        );
        let none = gpu_render(&mut engine, &case, Some((&uploaded, &hidden)), size);
        let (psnr, off) = compare(&none, &plain);
        assert!(
            psnr > 100.0 && off == 0.0,
            "hidden labels drawn ({psnr:.1} dB)"
        );
    }
    common::assert_no_validation_errors(&engine);
}

#[test]
fn labels_where_no_tissue_is_visible_are_drawn_on_an_oblique_anisotropic_grid() {
    let mut engine = common::engine();
    let dims = [23usize, 19, 17];
    // Rotated about z by 20 degrees, 0.9 x 1.3 x 0.7 mm, flipped x.
    let (c, s) = (20f64.to_radians().cos(), 20f64.to_radians().sin());
    let affine = [
        [-0.9 * c, -1.3 * s, 0.0, 10.0],
        [-0.9 * s, 1.3 * c, 0.0, -4.0],
        [0.0, 0.0, 0.7, 2.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let field = smooth_field(dims, &mut Rng(7), 100.0, 900.0);
    let samples: Vec<f32> = field.iter().map(|&v| v as f32).collect();
    let volume = volume_with_affine(dims, affine, Samples::from_f32(&samples));
    // A ball of label 3 and a slab of label 700 (a label far above the table's first entries).
    let mut values = vec![0u16; dims.iter().product()];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let d2 =
                    (i as f64 - 7.0).powi(2) + (j as f64 - 9.0).powi(2) + (k as f64 - 8.0).powi(2);
                let at = i + dims[0] * (j + dims[1] * k);
                if d2 <= 16.0 {
                    values[at] = 3;
                } else if (15..18).contains(&i) && j > 3 {
                    values[at] = 700;
                }
            }
        }
    }
    let labels = Labels { dims, values };
    let size = (56, 40);
    for shading in [false, true] {
        // No tissue visible: every brick is empty to the classification, and only the label
        // bricks are marched (skipping on by default).
        let case = prepare(&mut engine, &volume, |s| {
            s.effects.shading = shading;
            for tissue in &mut s.classification.tissues {
                tissue.visible = false;
            }
        });
        assert!(case.scene.effects.quality.empty_space_skipping);
        let uploaded = Arc::new(engine.upload_labels(&case.prepared, &labels).unwrap());
        let colours = label_colours(
            &table(&[(3, [0, 200, 255])]),
            &uploaded.present,
            0.6,
            &BTreeSet::new(),
        );
        assert_eq!(colours.len(), 701);
        let gpu = gpu_render(&mut engine, &case, Some((&uploaded, &colours)), size);
        let cpu = reference(&engine, &case, &labels, &colours, size);
        assert_matches(&format!("oblique, shading {shading}"), &gpu, &cpu);
        let lit = gpu.iter().filter(|p| p[0] + p[1] + p[2] > 0.05).count();
        assert!(
            lit > 200,
            "shading {shading}: only {lit} pixels show a label"
        );
    }
    common::assert_no_validation_errors(&engine);
}
