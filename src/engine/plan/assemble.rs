//! Assembles a plan from what each pass declares, in execution order: the engine's stand-ins,
//! the preparation (the GPU analysis passes, or the host's bricking), I_norm, the derived
//! volumes, empty-space skipping, the raymarch with its target, and last the bricks' staging
//! buffer, sized from what the budget leaves.
//!
//! Decisions: every allocation here is built by the function the engine creates it with
//! (`placeholder_descs`, `sample_descs`, `minmax_descs`, `output_descs`, `render_target_descs`,
//! ...), so names, sizes, formats and usages are written once. This file says which of them a
//! scene needs and each pass's variant and predicted cost (`passes::cost`). Adding a pass is one
//! declaration function here and one call in [`build`].

use super::declare::{Declared, PassDeclaration, PlanContext};
use super::{
    Choices, Degradation, ImageSizes, Layout, Plan, PlanInput, PlannedPass, STORAGE_BRICK,
    STORAGE_HALO, atlas_slots, normalized_format,
};
use crate::engine::{bricked, derive, occupancy, prepare, readback, render, robust, upload};
use crate::gpu::{FRAMES_IN_FLIGHT, recycler};
use crate::passes::cost::{self, PassCost};
use crate::passes::denoise::{Denoise, denoise_descs};
use crate::passes::derivatives::{DerivativeOutputs, output_descs};
use crate::passes::fine_histogram::RESULT_BYTES;
use crate::passes::histogram::BINS;
use crate::passes::occupancy::{BRICK_SIDE, brick_grid};
use crate::passes::raymarch::RaymarchVariant;
use crate::scene::RenderMode;
use crate::volume::SampleKind;
use ash::vk;

/// The extent of the volume's images in the chosen layout (the atlas for a bricked plan).
fn layout_extent(input: &PlanInput, bricked: bool) -> ([u32; 3], Layout) {
    if !bricked {
        return (input.dims, Layout::Whole);
    }
    let grid = input.dims.map(|d| d.div_ceil(STORAGE_BRICK));
    let total = grid.iter().map(|&g| g as u64).product::<u64>();
    let resident =
        ((total as f64 * input.occupied_fraction.clamp(0.0, 1.0)).ceil() as u64).clamp(1, total);
    let slot = (STORAGE_BRICK + 2 * STORAGE_HALO) as u64;
    let per_axis = input.max_image_dimension_3d / (STORAGE_BRICK + 2 * STORAGE_HALO);
    // An atlas the image limit cannot hold is sized as if it could; the upload then fails with
    // the limit named (only for volumes of over per_axis^3 resident bricks, ~10^6 at 4096).
    let slots = atlas_slots(resident as u32, per_axis).unwrap_or([resident as u32, 1, 1]);
    (
        slots.map(|s| (s as u64 * slot).min(u32::MAX as u64) as u32),
        Layout::Bricked {
            brick: STORAGE_BRICK,
            halo: STORAGE_HALO,
            grid,
            resident: resident as u32,
            staging_slots: 0,
        },
    )
}

/// The plan of `choices` on `input`, with `degradations` recorded.
pub(super) fn build(
    input: &PlanInput,
    sizes: &dyn ImageSizes,
    choices: Choices,
    degradations: Vec<Degradation>,
) -> Plan {
    let (extent, mut layout) = layout_extent(input, choices.bricked);
    let ctx = PlanContext {
        input,
        effects: choices.effects,
        normalized_format: normalized_format(choices.normalized_bytes),
        bricked: choices.bricked,
        extent,
    };
    let mut all = engine_fixed();
    all.extend(if ctx.bricked {
        host_preparation(&ctx, &layout)
    } else {
        gpu_analysis(&ctx)
    });
    if !ctx.bricked && input.denoise != Denoise::None {
        all.extend(denoising(&ctx));
    }
    if let Some(outputs) = ctx.effects.derivative_outputs() {
        all.extend(derivatives(&ctx, &outputs));
        if outputs.vesselness && !ctx.bricked {
            all.extend(vesselness(&ctx));
        }
        if outputs.brain != crate::passes::brain::BrainSwitch::Off && !ctx.bricked {
            all.extend(brain(&ctx));
        }
    }
    if ctx.effects.mode == RenderMode::Dvr && ctx.effects.quality.empty_space_skipping {
        all.extend(empty_space_skipping(&ctx));
    }
    all.extend(raymarch(&ctx));
    let unified = input.unified_memory;
    let mut allocations: Vec<_> = all
        .allocations
        .iter()
        .map(|d| d.planned(sizes, unified))
        .collect();
    if let Layout::Bricked {
        resident,
        ref mut staging_slots,
        ..
    } = layout
    {
        // Bricks go up in batches through one staging buffer sized to what the budget leaves
        // (at least one slot, at most 64 or all resident bricks).
        let slot_bytes =
            (STORAGE_BRICK as u64 + 2 * STORAGE_HALO as u64).pow(3) * ctx.normalized_bytes();
        let others: u64 = allocations.iter().map(|a| a.bytes).sum();
        let room = input.budget.saturating_sub(others) / slot_bytes;
        *staging_slots = room.clamp(1, 64.min(resident as u64).max(1)) as u32;
        let staging = bricked::brick_staging_desc(*staging_slots as u64 * slot_bytes);
        allocations.push(Declared::transient(staging).planned(sizes, unified));
    }
    let total_bytes = allocations
        .iter()
        .filter(|a| !a.transient)
        .map(|a| a.bytes)
        .sum();
    let peak_bytes = allocations.iter().map(|a| a.bytes).sum();
    Plan {
        effects: ctx.effects,
        normalized_format: ctx.normalized_format,
        layout,
        passes: all.passes,
        variants: all.variants,
        allocations,
        total_bytes,
        peak_bytes,
        budget: input.budget,
        degradations,
    }
}

/// What every engine holds whatever the scene: the stand-ins bound where a variant declares an
/// input it never reads, and the device's pass breadcrumbs (one slot per reusable submission).
fn engine_fixed() -> PassDeclaration {
    let descs = crate::engine::placeholder_descs();
    PassDeclaration::allocations(vec![
        Declared::held_image(descs.gradient),
        Declared::held_image(descs.normal),
        Declared::held_image(descs.storage),
        Declared::held(descs.buffer),
        Declared::held(descs.uint_texels),
        Declared::held(recycler::breadcrumb_desc()),
    ])
}

/// A whole volume: uploaded, then min/max, the robust range's fine histogram (when asked),
/// normalization into I_norm and the histogram, all on the GPU.
fn gpu_analysis(ctx: &PlanContext) -> PassDeclaration {
    let kind = ctx.input.sample_kind.name();
    let sample_bytes = ctx.sample_bytes() as f64;
    let (voxels, normalized_bytes) = (ctx.voxels() as f64, ctx.normalized_bytes() as f64);
    let padded = upload::padded_sample_bytes(ctx.sample_bytes());
    let (samples, staging) = upload::sample_descs(padded, ctx.input.unified_memory);
    let [range, range_host] = prepare::minmax_descs();
    let mut allocations = vec![Declared::transient(samples)];
    allocations.extend(staging.map(Declared::transient));
    allocations.extend([Declared::transient(range), Declared::transient(range_host)]);
    let mut passes = vec![pass(
        "minmax",
        "per volume",
        format!("minmax_{kind}"),
        cost::minmax(sample_bytes),
    )];
    if ctx.input.robust_range {
        allocations.extend([
            Declared::transient(robust::fine_histogram_desc()),
            Declared::transient(readback::readback_desc("fine histogram", RESULT_BYTES)),
        ]);
        passes.push(pass(
            "fine histogram",
            "per volume (one refinement on a clean scan, up to three with hot voxels)",
            format!("fine_histogram_{kind}"),
            cost::fine_histogram(sample_bytes),
        ));
    }
    allocations.extend([
        Declared::held_image(prepare::normalized_desc(
            ctx.input.dims,
            ctx.normalized_format,
        )),
        Declared::transient(prepare::histogram_desc()),
        Declared::transient(readback::readback_desc("histogram bins", (BINS * 4) as u64)),
    ]);
    passes.push(pass(
        "normalize",
        "per volume",
        format!("normalize (SAMPLE_KIND={kind})"),
        cost::normalize(sample_bytes, voxels, normalized_bytes),
    ));
    passes.push(pass(
        "histogram",
        "per volume",
        format!("histogram_{kind}"),
        cost::histogram(
            voxels,
            normalized_bytes,
            ctx.input.sample_kind == SampleKind::F32,
        ),
    ));
    let variants = passes.iter().map(|p| p.variant.clone()).collect();
    PassDeclaration {
        passes,
        variants,
        allocations,
    }
}

/// Denoising the whole I_norm: the denoised image (and the Gaussian's scratch volumes) exist
/// beside the original only while the pass runs; the original is then dropped, so all of it is
/// transient for the plan (held bytes unchanged, the peak higher).
fn denoising(ctx: &PlanContext) -> PassDeclaration {
    let descs = denoise_descs(&ctx.input.denoise, ctx.extent, ctx.normalized_format);
    let passes = vec![pass(
        "denoise",
        "per volume",
        format!("denoise ({:?})", ctx.input.denoise),
        cost::denoise(ctx.voxels() as f64, ctx.normalized_bytes() as f64),
    )];
    PassDeclaration {
        variants: passes.iter().map(|p| p.variant.clone()).collect(),
        passes,
        allocations: descs.into_iter().map(Declared::transient_image).collect(),
    }
}

/// A bricked volume: normalized on the host brick by brick (the whole-volume sample buffer the
/// GPU kernels read is what does not fit) into an atlas of the resident bricks, found through a
/// brick table. (The staging buffer is sized last, from what the budget leaves.)
fn host_preparation(ctx: &PlanContext, layout: &Layout) -> PassDeclaration {
    let slot = STORAGE_BRICK + 2 * STORAGE_HALO;
    let bricks = match layout {
        Layout::Bricked { grid, .. } => grid.iter().map(|&g| g as u64).product(),
        Layout::Whole => 1,
    };
    let slots = ctx.extent.iter().map(|&e| (e / slot) as u64).product();
    PassDeclaration {
        passes: vec![pass(
            "host prepare",
            "per volume (CPU)",
            "f64 min/max, normalize, histogram; bricks cut with their halo".into(),
            cost::normalize(
                ctx.sample_bytes() as f64,
                ctx.texels() as f64,
                ctx.normalized_bytes() as f64,
            ),
        )],
        variants: Vec::new(),
        allocations: vec![
            Declared::held_image(bricked::atlas_desc(ctx.extent, ctx.normalized_format)),
            Declared::held(bricked::brick_table_desc(bricks)),
            Declared::held(bricked::slot_bounds_desc(slots)),
        ],
    }
}

/// The derived volumes the effects store (a 1-texel stand-in for each output not asked for,
/// dropped after the pass) and the max |g| reduction.
fn derivatives(ctx: &PlanContext, outputs: &DerivativeOutputs) -> PassDeclaration {
    let stored = outputs.magnitude || outputs.curvature;
    let [gradient, normal] = output_descs(outputs, ctx.extent);
    let image = |desc, wanted: bool| Declared {
        transient: !wanted,
        ..Declared::held_image(desc)
    };
    let [maximum, maximum_host] = derive::gradient_maximum_descs();
    let variant = crate::engine::kernels::derivative_variant_name(outputs);
    let cost = cost::derivatives(
        ctx.texels() as f64,
        ctx.normalized_bytes() as f64,
        outputs.curvature,
        outputs.normal,
        if stored {
            outputs.gradient_texel_bytes() as f64
        } else {
            0.0
        },
    );
    PassDeclaration {
        passes: vec![pass(
            "derivatives",
            "per effect change",
            variant.clone(),
            cost,
        )],
        variants: vec![variant],
        allocations: vec![
            image(gradient, stored),
            image(normal, outputs.normal),
            Declared::transient(maximum),
            Declared::transient(maximum_host),
        ],
    }
}

/// The vessel channel's multi-scale vesselness (`passes::vesselness`): the response is held,
/// the two scratch volumes live for the pass; its cost is `cost::vesselness`.
fn vesselness(ctx: &PlanContext) -> PassDeclaration {
    use crate::passes::vesselness::{VesselnessParams, vesselness_descs};
    let [response, scratch_a, scratch_b] = vesselness_descs(ctx.extent);
    let params = VesselnessParams::default();
    let cost = crate::passes::cost::vesselness(ctx.voxels() as f64, &params.scales_mm);
    PassDeclaration {
        passes: vec![pass(
            "vesselness",
            "per volume (when vessels are shown)",
            "vesselness".into(),
            cost,
        )],
        variants: vec!["vesselness".into()],
        allocations: vec![
            Declared::held_image(response),
            Declared {
                transient: true,
                ..Declared::held_image(scratch_a)
            },
            Declared {
                transient: true,
                ..Declared::held_image(scratch_b)
            },
        ],
    }
}

/// Brain extraction (`passes::brain`, `engine/brain.rs`): the mask is held, the smoothed
/// volume, the two distance volumes and the two coarse-cell buffers live for the extraction;
/// its cost is `cost::brain`.
fn brain(ctx: &PlanContext) -> PassDeclaration {
    use crate::passes::brain::{brain_descs, cells_desc, working_extent, working_factors};
    let working = working_extent(ctx.extent, working_factors(ctx.input.spacing_mm));
    let [mask, smoothed, a, b] = brain_descs(working);
    let cells = working
        .map(|n| n.div_ceil(2) as usize)
        .iter()
        .product::<usize>();
    let transient = |desc| Declared {
        transient: true,
        ..Declared::held_image(desc)
    };
    PassDeclaration {
        passes: vec![pass(
            "brain extraction",
            "per volume (when the scene shows brain tissues)",
            "brain extraction".into(),
            cost::brain(working.iter().map(|&n| f64::from(n)).product()),
        )],
        variants: vec!["brain extraction".into()],
        allocations: vec![
            Declared::held_image(mask),
            transient(smoothed),
            transient(a),
            transient(b),
            Declared::transient(cells_desc("brain cells", cells)),
            Declared::transient(cells_desc("brain band cells", cells)),
            Declared::transient(cells_desc("brain head cells", cells)),
        ],
    }
}

/// Empty-space skipping: the per-brick ranges (a GPU pass for a whole volume; a bricked volume's
/// come from the host data it was cut from) and one buffer of occupancy bits per frame in
/// flight (the CPU writes the next frame's bits while the GPU reads these).
fn empty_space_skipping(ctx: &PlanContext) -> PassDeclaration {
    let bricks: u64 = brick_grid(ctx.input.dims)
        .iter()
        .map(|&x| x as u64)
        .product();
    let mut declared = PassDeclaration::default();
    if !ctx.bricked {
        let [ranges, ranges_host] = occupancy::brick_range_descs(bricks);
        let n = ctx.voxels() as f64;
        declared.passes.push(pass(
            "occupancy",
            "per volume",
            "occupancy".into(),
            PassCost {
                bytes_read: n * ctx.normalized_bytes() as f64,
                bytes_written: 8.0 * bricks as f64,
                texel_loads: n * ((BRICK_SIDE + 4) as f64 / BRICK_SIDE as f64).powi(3),
                ..Default::default()
            },
        ));
        declared.variants.push("occupancy".into());
        declared.allocations.extend([
            Declared::transient(ranges),
            Declared::transient(ranges_host),
        ]);
    }
    declared.allocations.extend(
        (0..FRAMES_IN_FLIGHT)
            .map(|_| Declared::held(occupancy::occupancy_bits_desc(bricks, false))),
    );
    declared
}

/// The raymarch and its render target (image, host copy, uniforms per frame in flight, sample
/// counters), and the transfer-function tables of a table-classified variant.
fn raymarch(ctx: &PlanContext) -> PassDeclaration {
    let [w, h] = ctx.input.image.map(|s| s.max(1));
    let pixels = w as f64 * h as f64;
    let mut allocations = Vec::new();
    // RGBA8 at a non-zero size always has descriptions.
    if let Ok(target) = render::render_target_descs(w, h, vk::Format::R8G8B8A8_UNORM) {
        allocations.push(Declared::held_image(target.image));
        allocations.push(Declared::held(target.readback));
        allocations.extend(target.uniforms.into_iter().map(Declared::held));
        allocations.extend(target.counters.into_iter().map(Declared::held));
    }
    let diagonal = ctx
        .input
        .dims
        .iter()
        .map(|&d| (d as f64).powi(2))
        .sum::<f64>()
        .sqrt();
    // Half the pixels' rays cross the volume, at step 0.5.
    let samples = pixels * diagonal / 0.5 * 0.5;
    let variant = RaymarchVariant::of_layout(&ctx.effects, false, ctx.bricked);
    if variant.classify_table {
        // The transfer-function table, one per frame in flight (engine/transfer.rs).
        allocations.extend(
            (0..FRAMES_IN_FLIGHT)
                .map(|_| Declared::held(crate::engine::transfer::transfer_table_desc())),
        );
    }
    if variant.classified {
        // The classified volume (engine/classified.rs), one per render target.
        allocations.push(Declared::held_image(
            crate::engine::classified::classified_desc(ctx.input.dims),
        ));
    }
    if variant.lighting == 2 {
        // The matcap, one per frame in flight (engine/matcap.rs).
        allocations.extend(
            (0..FRAMES_IN_FLIGHT).map(|_| Declared::held(crate::engine::matcap::matcap_desc())),
        );
    }
    let (per_marched, per_classified) = variant.fetches();
    let cost = cost::raymarch(
        pixels,
        samples * per_marched,
        samples * 0.15,
        per_classified,
    );
    let name = variant.describe();
    PassDeclaration {
        passes: vec![pass("raymarch", "per frame", name.clone(), cost)],
        variants: vec![name],
        allocations,
    }
}

fn pass(name: &str, runs: &'static str, variant: String, cost: PassCost) -> PlannedPass {
    PlannedPass {
        name: name.into(),
        runs,
        variant,
        cost,
    }
}
