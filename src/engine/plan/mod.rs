//! The pass plan: from a scene and a volume, the minimal set of passes, pipeline variants and
//! allocations, with their predicted cost, fitted into a memory budget.
//!
//! Decisions:
//! - The engine owns the plan, and the passes declare it: each engine module that runs a pass
//!   says once what it allocates (the descriptions it creates from) and what the pass costs
//!   ([`declare`]); `assemble.rs` only puts the declarations in execution order. There is no
//!   second list of allocations to keep in step.
//! - Only what the scene calls for: MIP and MinIP run no derivative pass; DVR without curvature
//!   stores no curvature channel; shading off stores no normals; on-the-fly gradients store no
//!   derived volume at all (the derivative pass then only reduces max |g|); empty-space skipping
//!   adds the brick ranges and bits. Tissue toggles and window drags change no plan: they are
//!   uniforms.
//! - Sizes are what the engine allocates: images as the device reports them before they exist
//!   (vkGetDeviceImageMemoryRequirements, which includes the driver's padding), buffers as sized;
//!   the memory ledger reports the real numbers, and a test holds the two equal.
//! - The budget caps the GPU memory held at once. Transient buffers (the sample upload, staging,
//!   readback of the histogram) are counted in the preparation peak, which must fit too.
//! - Over budget, the plan degrades in a fixed order, cheapest accuracy first as the accuracy study
//!   measured it (ACCURACY.md; each step names its setting there): 8-bit derived volumes (-0.05
//!   dB; already the default, so this step only applies to scenes that asked for f16 or f32
//!   with `--derived-precision`), R8 I_norm (no measurable change), bricking (lossless for the visible tissues, but about
//!   2x the raymarch time and a host-side preparation), and last gradients on the fly (-10.9 dB).
//!   Then only the steps the fitting plan needs are kept. A volume side over the device's 3D
//!   image limit forces bricking. When nothing fits, the error names the volume, the budget and
//!   the smallest plan tried.
//! - A bricked plan may hold at most [`BRICKING_MAX_RATIO`] times the volume's R16 bytes plus
//!   [`BRICKING_SLACK`]: a 32^3 brick with its halo is a 38^3 slot, so a volume thinner than a
//!   brick (70000 x 1 x 1 once built an 886 MiB atlas for 280 KB of data, in half a minute)
//!   would hold thousands of times its size. Such a volume is refused before anything is
//!   allocated, with the bytes it would need.

mod assemble;
pub mod declare;
mod refusal;
#[cfg(test)]
mod tests;

use crate::gpu::{BufferDesc, ImageDesc};
use crate::passes::cost::PassCost;
use crate::scene::{DerivedPrecision, Effects, GradientSource};
use crate::volume::SampleKind;
use ash::vk;
use assemble::build;
use refusal::{does_not_fit, image_that_fits};

/// Side of a storage brick of the bricked layout, in voxels (without halo).
pub const STORAGE_BRICK: u32 = 32;
/// Halo of a storage brick on each side: trilinear and cubic reads, and the derivative stencils
/// at the brick's border, need neighbours up to 3 voxels out.
pub const STORAGE_HALO: u32 = 3;

/// A bricked plan holds at most this many times the volume's bytes as R16 (plus
/// [`BRICKING_SLACK`]); a real head is bricked at under 2x, with halos and partly filled bricks.
pub const BRICKING_MAX_RATIO: u64 = 8;
/// Fixed allowance on top of [`BRICKING_MAX_RATIO`], for small volumes bricked to measure.
pub const BRICKING_SLACK: u64 = 64 << 20;

/// The most a bricked plan of a `dims` volume may hold.
pub fn bricking_limit(dims: [u32; 3]) -> u64 {
    (2 * voxels(dims))
        .saturating_mul(BRICKING_MAX_RATIO)
        .saturating_add(BRICKING_SLACK)
}

/// What the plan needs to know about the volume, the image and the device.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PlanInput {
    /// Volume dimensions.
    pub dims: [u32; 3],
    /// Stored sample encoding.
    pub sample_kind: SampleKind,
    /// Output image size.
    pub image: [u32; 2],
    /// Largest 3D image side the device (or its profile) allows.
    pub max_image_dimension_3d: u32,
    /// Largest storage buffer the device allows.
    pub max_storage_buffer_range: u64,
    /// Uploads go straight to memory the GPU reads (no staging copy).
    pub unified_memory: bool,
    /// Memory the plan may hold at once (user budget, device budget, or heap size).
    pub budget: u64,
    /// Fraction of storage bricks a visible tissue can occupy (1 when unknown); bricked plans hold
    /// only those.
    pub occupied_fraction: f64,
    /// Brick even when the whole volume fits (to measure what bricking costs).
    pub force_bricking: bool,
    /// The intensity range is the robust one (the fine-histogram pass runs).
    pub robust_range: bool,
    /// Denoising of I_norm after the preparation (whole volumes only): its output replaces
    /// I_norm, so it adds to the preparation's peak only (`engine::denoise`).
    pub denoise: crate::passes::denoise::Denoise,
    /// Voxel lengths in mm (brain extraction's working grid depends on them).
    pub spacing_mm: [f64; 3],
}

/// How the normalized volume is laid out on the GPU.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Layout {
    /// One 3D image of the whole volume.
    Whole,
    /// Bricks of `brick`^3 voxels plus `halo` on each side, resident bricks packed in an atlas,
    /// found through a brick table.
    Bricked {
        /// Brick side without halo.
        brick: u32,
        /// Halo on each side.
        halo: u32,
        /// Bricks along each axis.
        grid: [u32; 3],
        /// Bricks held on the GPU.
        resident: u32,
        /// Bricks per upload batch (the staging buffer's size in slots).
        staging_slots: u32,
    },
}

/// One allocation the plan holds or needs transiently.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PlannedAllocation {
    /// Name as the memory ledger will show it.
    pub name: String,
    /// Bytes.
    pub bytes: u64,
    /// Texel format (None for a buffer; serialized as the format's name or `buffer`).
    #[serde(serialize_with = "serialize_format")]
    pub format: Option<vk::Format>,
    /// Where it lives: `device-local`, `host-visible`, `host (staging)` or `host (readback)`.
    pub memory_type: String,
    /// Held only while the volume is prepared (freed before the first frame).
    pub transient: bool,
}

/// One pass of the plan.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PlannedPass {
    /// Pass name as timestamps report it.
    pub name: String,
    /// When it runs: `per volume`, `per effect change` or `per frame`.
    pub runs: &'static str,
    /// Shader variant (shader name and specialization).
    pub variant: String,
    /// Minimum traffic (bytes, fetches; the raymarch's fetches are estimated from the image,
    /// the volume diagonal and the step, before early termination and skipping).
    pub cost: PassCost,
}

/// A step down the degradation ladder, with the accuracy-study setting that measures its cost.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Degradation {
    /// What changed.
    pub what: String,
    /// Bytes it saved.
    pub saved_bytes: u64,
    /// The `morphray accuracy` setting that measures its error (see ACCURACY.md).
    pub accuracy_setting: &'static str,
    /// What that setting cost in the accuracy study (ACCURACY.md).
    pub accuracy_cost: &'static str,
}

/// What each degradation cost in the accuracy study: `morphray accuracy --size 256x256 --views 3
/// --frames 9` on the phantom, on the H100 (ACCURACY.md; lavapipe agrees within 0.2 dB). PSNR is
/// against the f64 pipeline; the default setting scores 46.42 dB.
pub fn measured_cost(setting: &str) -> &'static str {
    match setting {
        "default (8-bit derived volumes)" => {
            "46.37 dB vs the f64 reference (f16: 46.42 dB): -0.05 dB at the default step; at \
             step 0.125 70 dB against f16's 84 dB (lavapipe)"
        }
        "I_norm R8" => "46.42 dB vs the f64 reference (default 46.42 dB): no measurable change",
        "vessels off" => "the vessel channel is not drawn (the tissues are unchanged)",
        "brain off" => {
            "a head scan shows its scalp and face where the brain would be (tissues are classified \
             everywhere, as on a skull-stripped scan)"
        }
        "gradient on the fly" => {
            "35.57 dB vs the f64 reference (default 46.42 dB): -10.9 dB (a gradient of the \
             interpolated field, not of the voxels; see ACCURACY.md)"
        }
        _ => {
            "none for the visible tissues: bricked and whole images differ by at most 3/255 \
             (host f64 vs GPU f32 normalization)"
        }
    }
}

/// The plan.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Plan {
    /// Effects as planned (after degradations).
    pub effects: Effects,
    /// Storage format of I_norm (serialized as its name).
    #[serde(serialize_with = "serialize_vk_format")]
    pub normalized_format: vk::Format,
    /// Whole or bricked.
    pub layout: Layout,
    /// Passes in execution order.
    pub passes: Vec<PlannedPass>,
    /// Pipeline variants the passes need.
    pub variants: Vec<String>,
    /// Every allocation.
    pub allocations: Vec<PlannedAllocation>,
    /// Bytes held while rendering (non-transient allocations).
    pub total_bytes: u64,
    /// Bytes held at the peak of preparation.
    pub peak_bytes: u64,
    /// The budget planned against.
    pub budget: u64,
    /// Degradations applied to fit the budget.
    pub degradations: Vec<Degradation>,
}

/// No plan fits.
#[derive(Clone, Debug, PartialEq)]
pub struct DoesNotFit {
    /// Volume dimensions.
    pub dims: [u32; 3],
    /// Bytes of the volume as R16.
    pub volume_bytes: u64,
    /// The budget.
    pub budget: u64,
    /// Which limit the smallest plan exceeds, as a phrase ("does not fit the memory budget of N
    /// bytes", or the bricking limit).
    pub limit: String,
    /// Description of the smallest plan tried.
    pub smallest_plan: String,
    /// Its peak bytes.
    pub smallest_bytes: u64,
    /// When the output image is what does not fit (the volume would with a small image): its
    /// size and the largest of its shape that fits, `([w, h], [w, h])`.
    pub image: Option<([u32; 2], [u32; 2])>,
}

/// The choices that set the plan's size.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Choices {
    effects: Effects,
    normalized_bytes: u64,
    bricked: bool,
}

fn voxels(dims: [u32; 3]) -> u64 {
    dims.iter().map(|&d| d as u64).product()
}

/// What allocations really take in device memory: drivers pad image rows and tiles (lavapipe
/// aligns a 40-texel R16F row to 128 bytes) and round buffers up to their alignment (NVIDIA), so
/// the engine asks the device; plans made without one use [`TexelSizes`].
pub trait ImageSizes {
    /// Bytes of an image created from `desc`.
    fn image_bytes(&self, desc: &ImageDesc) -> u64;
    /// Bytes of a buffer created from `desc` (its usage sets its alignment).
    fn buffer_bytes(&self, desc: &BufferDesc) -> u64;
}

/// Texels x bytes per texel and buffers as requested, with no driver padding.
#[derive(Clone, Copy, Debug, Default)]
pub struct TexelSizes;

impl ImageSizes for TexelSizes {
    fn image_bytes(&self, desc: &ImageDesc) -> u64 {
        desc.extent.iter().map(|&e| e as u64).product::<u64>() * texel_bytes(desc.format)
    }

    fn buffer_bytes(&self, desc: &BufferDesc) -> u64 {
        desc.size
    }
}

impl PlannedAllocation {
    /// The format's name, or `buffer`.
    pub fn format_label(&self) -> String {
        self.format
            .map(|f| format!("{f:?}"))
            .unwrap_or_else(|| "buffer".into())
    }
}

/// I_norm's format for a number of bytes per voxel (the ladder's R8 step).
pub fn normalized_format(bytes: u64) -> vk::Format {
    if bytes == 1 {
        vk::Format::R8_UNORM
    } else {
        vk::Format::R16_UNORM
    }
}

fn serialize_format<S: serde::Serializer>(f: &Option<vk::Format>, s: S) -> Result<S::Ok, S::Error> {
    match f {
        Some(f) => s.serialize_str(&format!("{f:?}")),
        None => s.serialize_str("buffer"),
    }
}

fn serialize_vk_format<S: serde::Serializer>(f: &vk::Format, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&format!("{f:?}"))
}

/// Bytes per texel of the formats the engine uses (4 for any other).
pub fn texel_bytes(format: vk::Format) -> u64 {
    match format {
        vk::Format::R8_UNORM | vk::Format::R8_SNORM => 1,
        vk::Format::R16_UNORM | vk::Format::R16_SFLOAT | vk::Format::R8G8_SNORM => 2,
        vk::Format::R32G32_SFLOAT => 8,
        vk::Format::R32G32B32A32_SFLOAT => 16,
        _ => 4,
    }
}

/// Slots along x, y, z of an atlas holding `count` bricks with at most `per_axis` slots per axis
/// (the 3D image limit over the slot side), packed with the fewest unused slots (ties: the widest
/// x, then y: drivers pad rows, so long rows waste the least); None when even a full atlas is
/// too small.
pub fn atlas_slots(count: u32, per_axis: u32) -> Option<[u32; 3]> {
    let count = count.max(1) as u64;
    let per_axis = per_axis.max(1) as u64;
    if count > per_axis.pow(3) {
        return None;
    }
    let mut best: Option<([u64; 3], u64)> = None;
    for sx in 1..=per_axis.min(count) {
        for sy in 1..=per_axis.min(count.div_ceil(sx)) {
            let sz = count.div_ceil(sx * sy);
            if sz > per_axis {
                continue;
            }
            let slots = sx * sy * sz;
            let better = match best {
                None => true,
                Some((b, b_slots)) => {
                    slots < b_slots || (slots == b_slots && (sx, sy) > (b[0], b[1]))
                }
            };
            if better {
                best = Some(([sx, sy, sz], slots));
            }
        }
    }
    best.map(|(s, _)| s.map(|v| v as u32))
}

/// One rung of the degradation ladder: what it does, the accuracy setting it
/// corresponds to in `morphray accuracy`, and the change (false when it does not apply).
type LadderStep = (&'static str, &'static str, fn(&mut Choices) -> bool);

/// Plans `effects` on `input`, degrading to fit the budget; `DoesNotFit` when nothing does.
/// `sizes` says what images take on the device (the engine passes its device).
pub fn plan(
    effects: Effects,
    input: &PlanInput,
    sizes: &dyn ImageSizes,
) -> Result<Plan, DoesNotFit> {
    plan_with(effects, input, sizes, true)
}

/// [`plan`]; `explain`: when nothing fits, also find whether a smaller image would.
fn plan_with(
    effects: Effects,
    input: &PlanInput,
    sizes: &dyn ImageSizes,
    explain: bool,
) -> Result<Plan, DoesNotFit> {
    let too_large = input.dims.iter().any(|&d| d > input.max_image_dimension_3d);
    let sample_bytes = voxels(input.dims) * input.sample_kind.size_bytes() as u64;
    let samples_too_large = sample_bytes > input.max_storage_buffer_range;
    let mut choices = Choices {
        effects,
        normalized_bytes: 2,
        bricked: too_large || samples_too_large || input.force_bricking,
    };
    let mut degradations = Vec::new();
    if choices.bricked && choices.effects.vessels {
        // The vesselness needs the whole volume (`Engine::vesselness`).
        choices.effects.vessels = false;
        degradations.push(Degradation {
            what: "vessel channel off: a bricked volume has no vesselness".to_string(),
            saved_bytes: 0,
            accuracy_setting: "vessels off",
            accuracy_cost: measured_cost("vessels off"),
        });
    }
    if choices.bricked {
        degradations.push(Degradation {
            what: if !too_large && !samples_too_large {
                "bricked: asked for (--bricked)".to_string()
            } else if too_large {
                format!("bricked: a side of {:?} exceeds the device's 3D image limit of {}", input.dims, input.max_image_dimension_3d)
            } else {
                format!("bricked: {sample_bytes} bytes of samples exceed the largest storage buffer ({})", input.max_storage_buffer_range)
            },
            saved_bytes: 0,
            accuracy_setting: "default (bricking is lossless for the visible tissues)",
            accuracy_cost: measured_cost("bricked"),
        });
    }
    if choices.bricked && choices.effects.brain != crate::passes::brain::BrainSwitch::Off {
        // Brain extraction needs the whole volume (`Engine::brain_mask`).
        choices.effects.brain = crate::passes::brain::BrainSwitch::Off;
        degradations.push(Degradation {
            what: "brain extraction off: a bricked volume has no brain mask".to_string(),
            saved_bytes: 0,
            accuracy_setting: "brain off",
            accuracy_cost: measured_cost("brain off"),
        });
    }
    let fits = |p: &Plan| {
        p.peak_bytes <= input.budget
            && (p.layout == Layout::Whole || p.peak_bytes <= bricking_limit(input.dims))
    };
    let ladder: [LadderStep; 6] = [
        (
            "derived volumes stored as 8-bit SNORM",
            "default (8-bit derived volumes)",
            |c| {
                let stored = c
                    .effects
                    .derivative_outputs()
                    .is_some_and(|o| o.magnitude || o.curvature || o.normal);
                if stored && c.effects.quality.derived_precision != DerivedPrecision::Snorm8 {
                    c.effects.quality.derived_precision = DerivedPrecision::Snorm8;
                    true
                } else {
                    false
                }
            },
        ),
        ("I_norm stored as R8", "I_norm R8", |c| {
            if c.normalized_bytes > 1 {
                c.normalized_bytes = 1;
                true
            } else {
                false
            }
        }),
        (
            "vessel channel off (its vesselness volume and scratch are not held)",
            "vessels off",
            |c| {
                let on = c.effects.vessels;
                c.effects.vessels = false;
                on
            },
        ),
        (
            "brain extraction off (its mask and scratch volumes are not held)",
            "brain off",
            |c| {
                let on = c.effects.brain != crate::passes::brain::BrainSwitch::Off;
                c.effects.brain = crate::passes::brain::BrainSwitch::Off;
                on
            },
        ),
        (
            "bricked: only bricks a visible tissue can occupy are held",
            "default (bricking is lossless for the visible tissues)",
            |c| {
                // A bricked volume has no vesselness nor brain mask (see above).
                c.effects.vessels = false;
                c.effects.brain = crate::passes::brain::BrainSwitch::Off;
                if c.bricked {
                    false
                } else {
                    c.bricked = true;
                    true
                }
            },
        ),
        (
            "gradients computed on the fly (no stored derived volumes)",
            "gradient on the fly",
            |c| {
                let stored = c
                    .effects
                    .derivative_outputs()
                    .is_some_and(|o| o.magnitude || o.curvature || o.normal);
                if stored {
                    c.effects.gradient_source = GradientSource::OnTheFly;
                    true
                } else {
                    false
                }
            },
        ),
    ];
    // The steps of `mask` that change something, applied in ladder order.
    let apply = |mask: u32| {
        let mut c = choices;
        let mut applied = Vec::new();
        for (i, (_, _, step)) in ladder.iter().enumerate() {
            if mask >> i & 1 == 1 && step(&mut c) {
                applied.push(i);
            }
        }
        (c, applied)
    };
    let peak = |mask: u32| build(input, sizes, apply(mask).0, Vec::new()).peak_bytes;
    // The shortest prefix of the ladder that fits, then without every step it turns out not to
    // need (gradients on the fly make the 8-bit step moot, bricking may make R8 unnecessary).
    let Some(mut mask) = (0..=ladder.len() as u32)
        .map(|k| (1u32 << k) - 1)
        .find(|&m| fits(&build(input, sizes, apply(m).0, Vec::new())))
    else {
        let smallest = build(input, sizes, apply((1 << ladder.len()) - 1).0, Vec::new());
        let mut error = does_not_fit(input, &smallest);
        if explain {
            error.image = image_that_fits(effects, input, sizes);
        }
        return Err(error);
    };
    for i in 0..ladder.len() {
        let without = mask & !(1 << i);
        if without != mask && fits(&build(input, sizes, apply(without).0, Vec::new())) {
            mask = without;
        }
    }
    let (final_choices, applied) = apply(mask);
    let final_peak = peak(mask);
    for i in applied {
        let (what, setting, _) = ladder[i];
        degradations.push(Degradation {
            what: what.to_string(),
            saved_bytes: peak(mask & !(1 << i)).saturating_sub(final_peak),
            accuracy_setting: setting,
            accuracy_cost: measured_cost(setting),
        });
    }
    Ok(build(input, sizes, final_choices, degradations))
}
