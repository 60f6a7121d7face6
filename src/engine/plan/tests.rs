//! The plan's unit tests: example scenes plan exactly what they need, and the degradation
//! ladder's order.

use super::*;
use crate::gpu::FRAMES_IN_FLIGHT;
use crate::scene::{CurvatureSource, Quality, RenderMode};
use ash::vk;

/// The effects these tests were written for: derived volumes in f16 (the library default is
/// 8-bit, checked in `the_default_stores_derived_volumes_in_8_bits`), no brain extraction (its
/// plan: `brain_extraction_is_planned_and_dropped_before_bricking`).
fn f16_effects() -> Effects {
    let mut e = Effects::default();
    e.quality.derived_precision = DerivedPrecision::F16;
    e.brain = crate::passes::brain::BrainSwitch::Off;
    e
}

#[test]
fn brain_extraction_is_planned_and_dropped_before_bricking() {
    let brain = Effects {
        brain: crate::passes::brain::BrainSwitch::Auto,
        ..f16_effects()
    };
    // The mask is held (R8, a byte a working voxel); the scratch lives for the extraction
    // only. 1 mm voxels: a working grid of 2x2x2 blocks.
    let p = plan(brain, &input(), &TexelSizes).unwrap();
    assert!(passes(&p).contains(&"brain extraction"), "{:?}", passes(&p));
    assert_eq!(held(&p, "brain mask"), ("R8_UNORM".into(), N / 8));
    // 1.75 mm voxels are the working grid itself: the extraction's 13 bytes a voxel outweigh
    // what the 8-bit and R8 steps save (2 bytes), so the ladder reaches its own step.
    let coarse = PlanInput {
        spacing_mm: [1.75; 3],
        ..input()
    };
    let p = plan(brain, &coarse, &TexelSizes).unwrap();
    assert_eq!(held(&p, "brain mask"), ("R8_UNORM".into(), N));
    let without = plan(f16_effects(), &coarse, &TexelSizes).unwrap();
    assert!(p.peak_bytes > without.peak_bytes);
    // A budget that holds everything but the extraction drops it (the 8-bit and R8 steps before
    // it save too little), with its degradation, and does not brick.
    let mut tight = coarse;
    tight.budget = without.peak_bytes;
    let degraded = plan(brain, &tight, &TexelSizes).unwrap();
    let settings: Vec<_> = degraded
        .degradations
        .iter()
        .map(|d| d.accuracy_setting)
        .collect();
    assert_eq!(settings, ["brain off"]);
    assert_eq!(degraded.layout, Layout::Whole);
    assert_eq!(
        degraded.effects.brain,
        crate::passes::brain::BrainSwitch::Off
    );
    // A bricked volume has no brain mask, and says so.
    let mut bricked = input();
    bricked.force_bricking = true;
    let p = plan(brain, &bricked, &TexelSizes).unwrap();
    assert!(!passes(&p).contains(&"brain extraction"));
    assert!(
        p.degradations
            .iter()
            .any(|d| d.what.contains("brain extraction off"))
    );
}

#[test]
fn the_default_stores_derived_volumes_in_8_bits() {
    let p = plan(Effects::default(), &input(), &TexelSizes).unwrap();
    let g = p
        .allocations
        .iter()
        .find(|a| a.name == "gradient magnitude")
        .unwrap();
    assert_eq!(
        (g.format_label().as_str(), g.bytes),
        ("R8_SNORM", 256 * 256 * 192)
    );
    // No degradation is left for the 8-bit step to make.
    assert!(p.degradations.is_empty());
}

fn input() -> PlanInput {
    PlanInput {
        dims: [256, 256, 192],
        sample_kind: SampleKind::I16,
        image: [1920, 1080],
        max_image_dimension_3d: 16384,
        max_storage_buffer_range: u32::MAX as u64,
        unified_memory: false,
        budget: u64::MAX,
        occupied_fraction: 1.0,
        force_bricking: false,
        robust_range: true,
        denoise: crate::passes::denoise::Denoise::None,
        spacing_mm: [1.0; 3],
    }
}

#[test]
fn denoising_raises_the_peak_by_its_images_and_holds_nothing_more() {
    use crate::passes::denoise::Denoise;
    let plain = plan(f16_effects(), &input(), &TexelSizes).unwrap();
    let with = |denoise| {
        plan(
            f16_effects(),
            &PlanInput { denoise, ..input() },
            &TexelSizes,
        )
        .unwrap()
    };
    let voxels = 256 * 256 * 192u64;
    let median = with(Denoise::Median);
    // The denoised I_norm (R16) replaces the original: only the preparation's peak grows.
    assert_eq!(median.total_bytes, plain.total_bytes);
    assert_eq!(median.peak_bytes, plain.peak_bytes + 2 * voxels);
    assert!(median.passes.iter().any(|p| p.name == "denoise"));
    // The Gaussian adds its two R32F scratch volumes.
    let gaussian = with(Denoise::Gaussian { sigma_mm: 1.0 });
    assert_eq!(gaussian.peak_bytes, plain.peak_bytes + 10 * voxels);
}

/// Allocations every plan holds whatever the scene (stand-ins, target, uniforms, counters).
const FIXED: [&str; 12] = [
    "placeholder (gradient)",
    "placeholder (normals)",
    "placeholder (storage)",
    "placeholder (occupancy)",
    "placeholder (uint texels)",
    "pass breadcrumbs",
    "render target",
    "render target (host)",
    "raymarch uniforms (frame 0)",
    "raymarch uniforms (frame 1)",
    "raymarch sample counters",
    "raymarch sample counters (host)",
];

/// The held allocations that depend on the scene.
fn names(p: &Plan) -> Vec<&str> {
    p.allocations
        .iter()
        .filter(|a| !a.transient && !FIXED.contains(&a.name.as_str()) && a.name != TABLE)
        .map(|a| a.name.as_str())
        .collect()
}

fn held(p: &Plan, name: &str) -> (String, u64) {
    let a = p.allocations.iter().find(|a| a.name == name).unwrap();
    (a.format_label(), a.bytes)
}

const N: u64 = 256 * 256 * 192;

/// The transfer-function table's name: held twice by every table-classified DVR plan (checked
/// on its own below, left out of [`names`]).
const TABLE: &str = "transfer-function table";

fn tables(p: &Plan) -> usize {
    p.allocations.iter().filter(|a| a.name == TABLE).count()
}

#[test]
fn dvr_plans_hold_a_table_per_frame_in_flight_and_mip_none() {
    let dvr = plan(f16_effects(), &input(), &TexelSizes).unwrap();
    assert_eq!(tables(&dvr), FRAMES_IN_FLIGHT);
    let mip = Effects {
        mode: RenderMode::Mip,
        ..f16_effects()
    };
    assert_eq!(tables(&plan(mip, &input(), &TexelSizes).unwrap()), 0);
    let mut exact = f16_effects();
    exact.quality.classification = crate::scene::ClassificationLookup::Exact;
    assert_eq!(tables(&plan(exact, &input(), &TexelSizes).unwrap()), 0);
}

#[test]
fn a_classified_volume_is_planned_at_four_bytes_a_voxel() {
    let effects = Effects {
        quality: crate::scene::Quality {
            classification: crate::scene::ClassificationLookup::Volume,
            ..Default::default()
        },
        ..f16_effects()
    };
    let p = plan(effects, &input(), &TexelSizes).unwrap();
    assert_eq!(
        held(&p, "classified volume"),
        ("R8G8B8A8_UNORM".into(), 4 * N)
    );
    assert!(p.variants.iter().any(|v| v.contains("CLASSIFIED=on")));
    let p = plan(f16_effects(), &input(), &TexelSizes).unwrap();
    assert!(p.allocations.iter().all(|a| a.name != "classified volume"));
}

#[test]
fn example_scenes_plan_exactly_the_passes_and_memory_they_need() {
    let dvr = |curvature, shading| Effects {
        curvature,
        shading,
        ..f16_effects()
    };
    let analysis = ["minmax", "fine histogram", "normalize", "histogram"];
    // DVR, no curvature, no shading: |g| only, as R16F.
    let p = plan(dvr(false, false), &input(), &TexelSizes).unwrap();
    assert_eq!(
        passes(&p),
        [&analysis[..], &["derivatives", "occupancy", "raymarch"]].concat()
    );
    assert_eq!(
        names(&p),
        [
            "normalized volume",
            "gradient magnitude",
            "occupancy bits",
            "occupancy bits"
        ]
    );
    assert_eq!(held(&p, "gradient magnitude"), ("R16_SFLOAT".into(), 2 * N));
    assert!(
        p.variants
            .iter()
            .any(|v| v.contains("WANT_CURVATURE=false, WANT_NORMAL=false"))
    );
    // Curvature on: the same passes, a second channel (the Hessian variant).
    let c = plan(dvr(true, false), &input(), &TexelSizes).unwrap();
    assert_eq!(passes(&c), passes(&p));
    assert_eq!(
        held(&c, "gradient magnitude"),
        ("R16G16_SFLOAT".into(), 4 * N)
    );
    assert_eq!(c.total_bytes - p.total_bytes, 2 * N);
    assert!(c.variants.iter().any(|v| v.contains("WANT_CURVATURE=true")));
    // Shading on: normals, 4 bytes a voxel.
    let s = plan(dvr(false, true), &input(), &TexelSizes).unwrap();
    assert_eq!(
        names(&s),
        [
            "normalized volume",
            "gradient magnitude",
            "normals",
            "occupancy bits",
            "occupancy bits"
        ]
    );
    assert_eq!(s.total_bytes - p.total_bytes, 4 * N);
    // Gradients on the fly: the derivative pass only reduces max |g|; nothing is stored.
    let f = plan(
        Effects {
            gradient_source: GradientSource::OnTheFly,
            ..dvr(true, true)
        },
        &input(),
        &TexelSizes,
    )
    .unwrap();
    assert_eq!(
        names(&f),
        ["normalized volume", "occupancy bits", "occupancy bits"]
    );
    assert!(
        f.variants
            .iter()
            .any(|v| v.contains("CURVATURE=on-the-fly"))
    );
    // Tissue visibility is not an effect: every plan above is the same for any tissue set,
    // because `plan` never sees the classification.
}

fn passes(p: &Plan) -> Vec<&str> {
    p.passes.iter().map(|x| x.name.as_str()).collect()
}

#[test]
fn mip_needs_no_derivative_pass_and_no_derived_memory() {
    let p = plan(
        Effects {
            mode: RenderMode::Mip,
            ..f16_effects()
        },
        &input(),
        &TexelSizes,
    )
    .unwrap();
    assert_eq!(
        passes(&p),
        [
            "minmax",
            "fine histogram",
            "normalize",
            "histogram",
            "raymarch"
        ]
    );
    assert_eq!(names(&p), ["normalized volume"]);
    assert!(p.variants.iter().all(|v| !v.starts_with("derivatives")));
}

#[test]
fn the_robust_range_plans_its_fine_histogram_and_min_max_normalization_does_not() {
    let transient = |p: &Plan| {
        p.allocations
            .iter()
            .filter(|a| a.transient)
            .map(|a| a.name.clone())
            .collect::<Vec<_>>()
    };
    let robust = plan(f16_effects(), &input(), &TexelSizes).unwrap();
    let minmax = plan(
        f16_effects(),
        &PlanInput {
            robust_range: false,
            ..input()
        },
        &TexelSizes,
    )
    .unwrap();
    assert!(passes(&robust).contains(&"fine histogram"));
    assert!(!passes(&minmax).contains(&"fine histogram"));
    assert!(robust.variants.contains(&"fine_histogram_i16".to_string()));
    let extra: Vec<_> = transient(&robust)
        .into_iter()
        .filter(|n| !transient(&minmax).contains(n))
        .collect();
    assert_eq!(extra, ["fine histogram", "fine histogram (readback)"]);
    // Held memory is the same; only the preparation peak grows, by the two count buffers.
    assert_eq!(robust.total_bytes, minmax.total_bytes);
    let counts = crate::passes::fine_histogram::RESULT_BYTES;
    assert_eq!(robust.peak_bytes - minmax.peak_bytes, 2 * counts);
}

#[test]
fn dvr_without_curvature_holds_no_curvature_and_shading_off_no_normals() {
    let plain = plan(f16_effects(), &input(), &TexelSizes).unwrap();
    let g = plain
        .allocations
        .iter()
        .find(|a| a.name == "gradient magnitude")
        .unwrap();
    assert_eq!(
        (g.format_label().as_str(), g.bytes),
        ("R16_SFLOAT", 2 * 256 * 256 * 192)
    );
    assert!(!names(&plain).contains(&"normals"));
    let curved = plan(
        Effects {
            curvature: true,
            ..f16_effects()
        },
        &input(),
        &TexelSizes,
    )
    .unwrap();
    let g = curved
        .allocations
        .iter()
        .find(|a| a.name == "gradient magnitude")
        .unwrap();
    assert_eq!(
        (g.format_label().as_str(), g.bytes),
        ("R16G16_SFLOAT", 4 * 256 * 256 * 192)
    );
    let shaded = plan(
        Effects {
            shading: true,
            ..f16_effects()
        },
        &input(),
        &TexelSizes,
    )
    .unwrap();
    assert!(names(&shaded).contains(&"normals"));
    assert_eq!(shaded.total_bytes - plain.total_bytes, 4 * 256 * 256 * 192);
    // Curvature on the fly stores no curvature channel.
    let fly = Effects {
        curvature: true,
        quality: Quality {
            curvature_source: CurvatureSource::OnTheFly,
            ..f16_effects().quality
        },
        ..f16_effects()
    };
    let p = plan(fly, &input(), &TexelSizes).unwrap();
    assert_eq!(
        p.allocations
            .iter()
            .find(|a| a.name == "gradient magnitude")
            .unwrap()
            .format,
        Some(vk::Format::R16_SFLOAT)
    );
}

#[test]
fn budgets_degrade_in_order_then_brick_then_refuse() {
    let full = plan(
        Effects {
            curvature: true,
            shading: true,
            ..f16_effects()
        },
        &input(),
        &TexelSizes,
    )
    .unwrap();
    let mut tight = input();
    tight.budget = full.peak_bytes - 1;
    let p = plan(full.effects, &tight, &TexelSizes).unwrap();
    assert_eq!(
        p.degradations[0].accuracy_setting,
        "default (8-bit derived volumes)"
    );
    assert_eq!(p.degradations.len(), 1);
    assert!(p.peak_bytes <= tight.budget);
    // Where gradients on the fly are needed anyway, the 8-bit step bought nothing and is not
    // applied (the plan keeps only the steps it needs).
    let no_derived = plan(
        Effects {
            gradient_source: GradientSource::OnTheFly,
            ..full.effects
        },
        &input(),
        &TexelSizes,
    )
    .unwrap();
    tight.budget = no_derived.peak_bytes;
    let p = plan(full.effects, &tight, &TexelSizes).unwrap();
    let settings: Vec<_> = p.degradations.iter().map(|d| d.accuracy_setting).collect();
    assert_eq!(settings, ["gradient on the fly"]);
    assert_eq!(p.effects.quality.derived_precision, DerivedPrecision::F16);
    tight.budget = 40 << 20;
    tight.occupied_fraction = 0.2;
    let p = plan(full.effects, &tight, &TexelSizes).unwrap();
    assert!(
        matches!(p.layout, Layout::Bricked { .. }),
        "{:?}",
        p.degradations
    );
    assert!(p.peak_bytes <= tight.budget);
    tight.budget = 1 << 20;
    let err = plan(full.effects, &tight, &TexelSizes).unwrap_err();
    assert!(
        err.to_string()
            .contains("does not fit the memory budget of 1048576 bytes"),
        "{err}"
    );
}

#[test]
fn a_side_over_the_3d_limit_forces_bricking() {
    let mut i = input();
    i.dims = [2100, 64, 64];
    i.max_image_dimension_3d = 2048;
    let p = plan(f16_effects(), &i, &TexelSizes).unwrap();
    assert!(matches!(
        p.layout,
        Layout::Bricked {
            grid: [66, 2, 2],
            ..
        }
    ));
    assert!(p.degradations[0].what.contains("3D image limit of 2048"));
}

#[test]
fn a_volume_thinner_than_a_brick_is_refused_before_bricking_takes_thousands_of_times_its_size() {
    // 70000 x 1 x 1 (280 KB as f32) once built an 886 MiB atlas: every 32-voxel run of the
    // line took a whole 38^3 slot.
    let mut i = input();
    i.dims = [70000, 1, 1];
    i.max_image_dimension_3d = 2048;
    let err = plan(f16_effects(), &i, &TexelSizes).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("cannot be bricked within"), "{text}");
    assert!(text.contains("3D image limit of 2048"), "{text}");
    assert!(err.smallest_bytes > bricking_limit(i.dims), "{err:?}");
    assert!(!text.contains("memory budget"), "{text}");
    // A head-sized volume bricks well within the limit.
    i.dims = [2100, 256, 192];
    let p = plan(f16_effects(), &i, &TexelSizes).unwrap();
    assert!(matches!(p.layout, Layout::Bricked { .. }));
    assert!(p.peak_bytes <= bricking_limit(i.dims));
}

#[test]
fn the_vessel_channel_plans_its_vesselness_and_is_the_rung_before_bricking() {
    let vessels = Effects {
        vessels: true,
        ..Effects::default()
    };
    let p = plan(vessels, &input(), &TexelSizes).unwrap();
    assert!(p.passes.iter().any(|pass| pass.name == "vesselness"));
    let held = |p: &Plan, name: &str| {
        p.allocations
            .iter()
            .find(|a| a.name == name)
            .map(|a| (a.bytes, a.transient))
    };
    let voxels = 256 * 256 * 192;
    assert_eq!(held(&p, "vesselness"), Some((4 * voxels, false)));
    assert_eq!(held(&p, "vesselness scratch A"), Some((4 * voxels, true)));
    // Without vessels: none of it.
    let plain = plan(Effects::default(), &input(), &TexelSizes).unwrap();
    assert!(held(&plain, "vesselness").is_none());
    // A budget between the two peaks drops the channel (the rung before bricking), not the
    // whole-volume layout.
    let tight = PlanInput {
        budget: plain.peak_bytes + 1,
        ..input()
    };
    let p = plan(vessels, &tight, &TexelSizes).unwrap();
    assert!(!p.effects.vessels && p.layout == Layout::Whole, "{p:?}");
    assert!(
        p.degradations
            .iter()
            .any(|d| d.what.starts_with("vessel channel off")),
        "{:?}",
        p.degradations
    );
    // --bricked: no vesselness on a bricked volume, said as a degradation.
    let bricked = PlanInput {
        force_bricking: true,
        ..input()
    };
    let p = plan(vessels, &bricked, &TexelSizes).unwrap();
    assert!(!p.effects.vessels);
    assert!(held(&p, "vesselness").is_none());
    assert!(
        p.degradations
            .iter()
            .any(|d| d.what.contains("no vesselness"))
    );
}

#[test]
fn an_image_too_large_for_the_budget_is_named_as_the_cause_with_the_size_that_fits() {
    // Issue 30: a 16384x16384 render of a 400 KB volume was blamed on bricking the volume.
    let mut i = input();
    i.dims = [48, 48, 40];
    i.image = [16384, 16384];
    i.budget = 2 << 30;
    let err = plan(f16_effects(), &i, &TexelSizes).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("the 16384x16384 image is too large, not the volume"),
        "{text}"
    );
    assert!(text.contains("use a smaller --size"), "{text}");
    let (_, [w, h]) = err.image.unwrap();
    assert_eq!(w, h);
    assert!(w > 1024 && w < 16384, "{w}");
    // The size it names fits, and one pixel more does not.
    i.image = [w, h];
    plan(f16_effects(), &i, &TexelSizes).unwrap();
    i.image = [w + 1, h + 1];
    assert!(plan(f16_effects(), &i, &TexelSizes).is_err());
}
