//! The pass plan: from a scene and a volume, the minimal set of passes, pipeline variants and
//! allocations, with their predicted cost, fitted into a memory budget.
//!
//! Decisions:
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

use super::{DerivedPrecision, Effects, GradientSource, RenderMode};
use crate::passes::cost::{self, PassCost};
use crate::passes::derivatives::DerivativeOutputs;
use crate::passes::occupancy::{BRICK_SIDE, brick_grid};
use crate::volume::SampleKind;
use ash::vk;

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
    /// Texel format or `buffer`.
    pub format: String,
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
    /// Storage format of I_norm.
    pub normalized_format: &'static str,
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
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "the volume ({dims:?} voxels, {volume_bytes} bytes as R16) {limit}: the smallest plan tried \
     ({smallest_plan}) needs {smallest_bytes} bytes"
)]
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

fn format_name(bytes: u64) -> &'static str {
    if bytes == 1 { "R8_UNORM" } else { "R16_UNORM" }
}

/// Where an allocation lives, which also says how a buffer is used (its usage flags, hence its
/// alignment on the device).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Memory {
    /// GPU-only memory (storage images and buffers the host never touches).
    DeviceLocal,
    /// Memory the host writes and the GPU reads in place (small tables, bits).
    HostVisible,
    /// A uniform buffer the host writes each frame.
    Uniform,
    /// Device memory that is system memory (integrated GPUs, CPU devices, profiles).
    Unified,
    /// Host memory the GPU writes for the host to read.
    Readback,
    /// Host memory the host fills for a copy to the GPU.
    Staging,
}

impl Memory {
    /// The label plans print.
    pub fn label(self) -> &'static str {
        match self {
            Memory::DeviceLocal => "device-local",
            Memory::HostVisible | Memory::Uniform => "host-visible",
            Memory::Unified => "host-visible (unified)",
            Memory::Readback => "host (readback)",
            Memory::Staging => "host (staging)",
        }
    }
}

/// What allocations really take in device memory: drivers pad image rows and tiles (lavapipe
/// aligns a 40-texel R16F row to 128 bytes) and round buffers up to their alignment (NVIDIA), so
/// the engine asks the device; plans made without one use [`TexelSizes`].
pub trait ImageSizes {
    /// Bytes of an image of `extent` texels of `format` (a 3D volume, or a 2D render target
    /// when `extent[2]` is 1 and `volume` is false).
    fn image_bytes(&self, extent: [u32; 3], format: vk::Format, volume: bool) -> u64;
    /// Bytes of a buffer of `bytes` used as `memory` says.
    fn buffer_bytes(&self, bytes: u64, memory: Memory) -> u64;
}

/// Texels x bytes per texel and buffers as requested, with no driver padding.
#[derive(Clone, Copy, Debug, Default)]
pub struct TexelSizes;

impl ImageSizes for TexelSizes {
    fn image_bytes(&self, extent: [u32; 3], format: vk::Format, _volume: bool) -> u64 {
        extent.iter().map(|&e| e as u64).product::<u64>() * texel_bytes(format)
    }

    fn buffer_bytes(&self, bytes: u64, _memory: Memory) -> u64 {
        bytes
    }
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

fn build(
    input: &PlanInput,
    sizes: &dyn ImageSizes,
    choices: Choices,
    degradations: Vec<Degradation>,
) -> Plan {
    let Choices {
        effects,
        normalized_bytes,
        bricked,
    } = choices;
    let n = voxels(input.dims);
    let (extent, layout) = layout_extent(input, bricked);
    let texels = extent.iter().map(|&e| e as u64).product::<u64>();
    let volume_bytes = |format: vk::Format| sizes.image_bytes(extent, format, true);
    let normalized_format = if normalized_bytes == 1 {
        vk::Format::R8_UNORM
    } else {
        vk::Format::R16_UNORM
    };
    let sample_bytes = n * input.sample_kind.size_bytes() as u64;
    let padded_samples = sample_bytes.div_ceil(16).max(1) * 16;
    let mut allocations = Vec::new();
    // Buffers are sized as the device will allocate them (alignment); images are sized by the
    // caller through `sizes.image_bytes`.
    let mut alloc = |name: &str, bytes: u64, format: &str, memory: Memory, transient: bool| {
        let bytes = if format == "buffer" {
            sizes.buffer_bytes(bytes, memory)
        } else {
            bytes
        };
        allocations.push(PlannedAllocation {
            name: name.to_string(),
            bytes,
            format: format.to_string(),
            memory_type: memory.label().to_string(),
            transient,
        });
    };
    let device_local = if input.unified_memory {
        Memory::Unified
    } else {
        Memory::DeviceLocal
    };
    // The engine's own 1-texel stand-ins, bound where a variant declares an input it never reads.
    alloc(
        "placeholder (gradient)",
        sizes.image_bytes([1; 3], vk::Format::R16G16_SFLOAT, true),
        "R16G16_SFLOAT",
        Memory::DeviceLocal,
        false,
    );
    alloc(
        "placeholder (normals)",
        sizes.image_bytes([1; 3], vk::Format::R8G8B8A8_SNORM, true),
        "R8G8B8A8_SNORM",
        Memory::DeviceLocal,
        false,
    );
    alloc(
        "placeholder (occupancy)",
        16,
        "buffer",
        Memory::HostVisible,
        false,
    );
    // The device's pass breadcrumbs, one slot per reusable submission (gpu/recycler.rs).
    alloc(
        "pass breadcrumbs",
        crate::gpu::recycler::CRUMB_BUFFER_BYTES,
        "buffer",
        Memory::Readback,
        false,
    );
    let mut passes = Vec::new();
    let mut variants = Vec::new();
    let kind = input.sample_kind.name();
    if bricked {
        // Bricked volumes are normalized on the CPU brick by brick (the whole-volume sample
        // buffer the GPU kernels read is what does not fit) and uploaded through staging.
        // (The staging buffer is sized last, from what the budget leaves.)
        passes.push(PlannedPass {
            name: "host prepare".into(),
            runs: "per volume (CPU)",
            variant: "f64 min/max, normalize, histogram; bricks cut with their halo".into(),
            cost: cost::normalize(sample_bytes as f64, texels as f64, normalized_bytes as f64),
        });
    } else {
        alloc(
            "volume samples",
            padded_samples,
            "buffer",
            device_local,
            true,
        );
        if !input.unified_memory {
            alloc(
                "volume samples (staging)",
                padded_samples,
                "buffer",
                Memory::Staging,
                true,
            );
        }
        alloc("min/max result", 8, "buffer", Memory::DeviceLocal, true);
        alloc("min/max result (host)", 8, "buffer", Memory::Readback, true);
        alloc("histogram bins", 1024, "buffer", Memory::DeviceLocal, true);
        alloc(
            "histogram bins (host)",
            1024,
            "buffer",
            Memory::Readback,
            true,
        );
        passes.push(PlannedPass {
            name: "minmax".into(),
            runs: "per volume",
            variant: format!("minmax_{kind}"),
            cost: cost::minmax(sample_bytes as f64),
        });
        passes.push(PlannedPass {
            name: "normalize".into(),
            runs: "per volume",
            variant: format!("normalize (SAMPLE_KIND={kind})"),
            cost: cost::normalize(sample_bytes as f64, n as f64, normalized_bytes as f64),
        });
        passes.push(PlannedPass {
            name: "histogram".into(),
            runs: "per volume",
            variant: format!("histogram_{kind}"),
            cost: cost::histogram(
                n as f64,
                normalized_bytes as f64,
                input.sample_kind == SampleKind::F32,
            ),
        });
        variants.extend([
            format!("minmax_{kind}"),
            format!("normalize (SAMPLE_KIND={kind})"),
            format!("histogram_{kind}"),
        ]);
    }
    let normalized_name = if bricked {
        "normalized volume (brick atlas)"
    } else {
        "normalized volume"
    };
    alloc(
        normalized_name,
        volume_bytes(normalized_format),
        format_name(normalized_bytes),
        device_local,
        false,
    );
    if let Layout::Bricked { grid, .. } = layout {
        alloc(
            "brick table",
            4 * grid.iter().map(|&g| g as u64).product::<u64>(),
            "buffer",
            Memory::HostVisible,
            false,
        );
        let slot = STORAGE_BRICK + 2 * STORAGE_HALO;
        alloc(
            "atlas slot bounds",
            8 * extent.iter().map(|&e| (e / slot) as u64).product::<u64>(),
            "buffer",
            Memory::HostVisible,
            false,
        );
    }
    if let Some(outputs) = effects.derivative_outputs() {
        let stored = outputs.magnitude || outputs.curvature;
        if stored {
            let format =
                crate::passes::derivatives::gradient_format(outputs.precision, outputs.curvature);
            alloc(
                "gradient magnitude",
                volume_bytes(format),
                &format!("{format:?}"),
                device_local,
                false,
            );
        }
        if outputs.normal {
            alloc(
                "normals",
                volume_bytes(vk::Format::R8G8B8A8_SNORM),
                "R8G8B8A8_SNORM",
                device_local,
                false,
            );
        }
        alloc(
            "gradient maximum",
            1024,
            "buffer",
            Memory::DeviceLocal,
            true,
        );
        alloc(
            "gradient maximum (host)",
            1024,
            "buffer",
            Memory::Readback,
            true,
        );
        let variant = derivative_variant(&outputs);
        passes.push(PlannedPass {
            name: "derivatives".into(),
            runs: "per effect change",
            variant: variant.clone(),
            cost: cost::derivatives(
                texels as f64,
                normalized_bytes as f64,
                outputs.curvature,
                outputs.normal,
                if stored {
                    outputs.gradient_texel_bytes() as f64
                } else {
                    0.0
                },
            ),
        });
        variants.push(variant);
    }
    let skip = effects.mode == RenderMode::Dvr && effects.quality.empty_space_skipping;
    if skip {
        let g = brick_grid(input.dims);
        let bricks = g.iter().map(|&x| x as u64).product::<u64>();
        if !bricked {
            alloc(
                "brick ranges",
                8 * bricks,
                "buffer",
                Memory::DeviceLocal,
                true,
            );
            alloc(
                "brick ranges (host)",
                8 * bricks,
                "buffer",
                Memory::Readback,
                true,
            );
        }
        // One per frame in flight: the CPU writes the next frame's bits while the GPU reads these.
        for _ in 0..2 {
            alloc(
                "occupancy bits",
                4 * bricks.div_ceil(32),
                "buffer",
                Memory::HostVisible,
                false,
            );
        }
        // A bricked volume's ranges come from the host data it was cut from.
        passes.extend((!bricked).then(|| PlannedPass {
            name: "occupancy".into(),
            runs: "per volume",
            variant: "occupancy".into(),
            cost: PassCost {
                bytes_read: n as f64 * normalized_bytes as f64,
                bytes_written: 8.0 * bricks as f64,
                texel_loads: n as f64 * ((BRICK_SIDE + 4) as f64 / BRICK_SIDE as f64).powi(3),
                ..Default::default()
            },
        }));
        if !bricked {
            variants.push("occupancy".into());
        }
    }
    let [w, h] = input.image;
    let pixels = w as u64 * h as u64;
    alloc(
        "render target",
        sizes.image_bytes([w, h, 1], vk::Format::R8G8B8A8_UNORM, false),
        "R8G8B8A8_UNORM",
        Memory::DeviceLocal,
        false,
    );
    alloc(
        "render target (host)",
        pixels * 4,
        "buffer",
        Memory::Readback,
        false,
    );
    for frame in 0..2 {
        alloc(
            &format!("raymarch uniforms (frame {frame})"),
            std::mem::size_of::<super::uniforms::RaymarchUniforms>() as u64,
            "buffer",
            Memory::Uniform,
            false,
        );
    }
    alloc(
        "raymarch sample counters",
        4 * crate::passes::raymarch::COUNTER_WORDS as u64,
        "buffer",
        Memory::DeviceLocal,
        false,
    );
    alloc(
        "raymarch sample counters (host)",
        4 * crate::passes::raymarch::COUNTER_WORDS as u64,
        "buffer",
        Memory::Readback,
        false,
    );
    let diagonal = input
        .dims
        .iter()
        .map(|&d| (d as f64).powi(2))
        .sum::<f64>()
        .sqrt();
    let samples = pixels as f64 * diagonal / 0.5 * 0.5; // half the pixels' rays cross the volume, at step 0.5
    let variant =
        crate::passes::raymarch::RaymarchVariant::of_layout(&effects, false, bricked).describe();
    let (per_marched, per_classified) =
        crate::passes::raymarch::RaymarchVariant::of_layout(&effects, false, bricked).fetches();
    passes.push(PlannedPass {
        name: "raymarch".into(),
        runs: "per frame",
        variant: variant.clone(),
        cost: cost::raymarch(
            pixels as f64,
            samples * per_marched,
            samples * 0.15,
            per_classified,
        ),
    });
    variants.push(variant);
    let mut layout = layout;
    if let Layout::Bricked {
        resident,
        ref mut staging_slots,
        ..
    } = layout
    {
        // Bricks go up in batches through one staging buffer sized to what the budget leaves
        // (at least one slot, at most 64 or all resident bricks).
        let slot_bytes = (STORAGE_BRICK as u64 + 2 * STORAGE_HALO as u64).pow(3) * normalized_bytes;
        let others: u64 = allocations.iter().map(|a| a.bytes).sum();
        let room = input.budget.saturating_sub(others) / slot_bytes;
        *staging_slots = room.clamp(1, 64.min(resident as u64).max(1)) as u32;
        allocations.push(PlannedAllocation {
            name: "brick upload (staging)".into(),
            bytes: sizes.buffer_bytes(*staging_slots as u64 * slot_bytes, Memory::Staging),
            format: "buffer".into(),
            memory_type: Memory::Staging.label().into(),
            transient: true,
        });
    }
    let total_bytes = allocations
        .iter()
        .filter(|a| !a.transient)
        .map(|a| a.bytes)
        .sum();
    let peak_bytes = allocations.iter().map(|a| a.bytes).sum();
    Plan {
        effects,
        normalized_format: format_name(normalized_bytes),
        layout,
        passes,
        variants,
        allocations,
        total_bytes,
        peak_bytes,
        budget: input.budget,
        degradations,
    }
}

fn derivative_variant(o: &DerivativeOutputs) -> String {
    format!(
        "derivatives (WANT_MAGNITUDE={}, WANT_CURVATURE={}, WANT_NORMAL={}, {:?})",
        o.magnitude, o.curvature, o.normal, o.precision
    )
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
    let too_large = input.dims.iter().any(|&d| d > input.max_image_dimension_3d);
    let sample_bytes = voxels(input.dims) * input.sample_kind.size_bytes() as u64;
    let samples_too_large = sample_bytes > input.max_storage_buffer_range;
    let choices = Choices {
        effects,
        normalized_bytes: 2,
        bricked: too_large || samples_too_large || input.force_bricking,
    };
    let mut degradations = Vec::new();
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
    let fits = |p: &Plan| {
        p.peak_bytes <= input.budget
            && (p.layout == Layout::Whole || p.peak_bytes <= bricking_limit(input.dims))
    };
    let ladder: [LadderStep; 4] = [
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
            "bricked: only bricks a visible tissue can occupy are held",
            "default (bricking is lossless for the visible tissues)",
            |c| {
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
        return Err(does_not_fit(input, &smallest));
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

/// The error for a plan whose smallest form, `smallest`, still exceeds the budget.
fn does_not_fit(input: &PlanInput, smallest: &Plan) -> DoesNotFit {
    let current = smallest;
    let over_budget = current.peak_bytes > input.budget;
    let limit = bricking_limit(input.dims);
    let over_bricking = current.layout != Layout::Whole && current.peak_bytes > limit;
    let mut limits = Vec::new();
    if over_budget || !over_bricking {
        limits.push(format!(
            "does not fit the memory budget of {} bytes",
            input.budget
        ));
    }
    if over_bricking {
        let why = if input.dims.iter().any(|&d| d > input.max_image_dimension_3d) {
            format!(
                "exceeds the device's 3D image limit of {} whole, ",
                input.max_image_dimension_3d
            )
        } else {
            String::new()
        };
        limits.push(format!(
            "{why}cannot be bricked within {limit} bytes ({BRICKING_MAX_RATIO}x its R16 size plus \
             {} MiB: a volume thinner than a {STORAGE_BRICK}-voxel brick leaves most of every \
             {}^3 slot empty)",
            BRICKING_SLACK >> 20,
            STORAGE_BRICK + 2 * STORAGE_HALO
        ));
    }
    DoesNotFit {
        dims: input.dims,
        volume_bytes: 2 * voxels(input.dims),
        budget: input.budget,
        limit: limits.join(" and "),
        smallest_plan: format!(
            "{}, {}, {:?} gradients",
            current.normalized_format,
            match current.layout {
                Layout::Whole => "whole volume".to_string(),
                Layout::Bricked { resident, .. } => format!("{resident} resident bricks"),
            },
            current.effects.gradient_source
        ),
        smallest_bytes: current.peak_bytes,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{CurvatureSource, Quality};

    /// The effects these tests were written for: derived volumes in f16 (the library default is
    /// 8-bit, checked in `the_default_stores_derived_volumes_in_8_bits`).
    fn f16_effects() -> Effects {
        let mut e = Effects::default();
        e.quality.derived_precision = DerivedPrecision::F16;
        e
    }

    #[test]
    fn the_default_stores_derived_volumes_in_8_bits() {
        let p = plan(Effects::default(), &input(), &TexelSizes).unwrap();
        let g = p
            .allocations
            .iter()
            .find(|a| a.name == "gradient magnitude")
            .unwrap();
        assert_eq!((g.format.as_str(), g.bytes), ("R8_SNORM", 256 * 256 * 192));
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
        }
    }

    /// Allocations every plan holds whatever the scene (stand-ins, target, uniforms, counters).
    const FIXED: [&str; 10] = [
        "placeholder (gradient)",
        "placeholder (normals)",
        "placeholder (occupancy)",
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
            .filter(|a| !a.transient && !FIXED.contains(&a.name.as_str()))
            .map(|a| a.name.as_str())
            .collect()
    }

    fn held(p: &Plan, name: &str) -> (String, u64) {
        let a = p.allocations.iter().find(|a| a.name == name).unwrap();
        (a.format.clone(), a.bytes)
    }

    const N: u64 = 256 * 256 * 192;

    #[test]
    fn example_scenes_plan_exactly_the_passes_and_memory_they_need() {
        let dvr = |curvature, shading| Effects {
            curvature,
            shading,
            ..f16_effects()
        };
        let analysis = ["minmax", "normalize", "histogram"];
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
        assert_eq!(passes(&p), ["minmax", "normalize", "histogram", "raymarch"]);
        assert_eq!(names(&p), ["normalized volume"]);
        assert!(p.variants.iter().all(|v| !v.starts_with("derivatives")));
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
            (g.format.as_str(), g.bytes),
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
            (g.format.as_str(), g.bytes),
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
            "R16_SFLOAT"
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
    fn a_volume_thinner_than_a_brick_is_refused_before_bricking_takes_thousands_of_times_its_size()
    {
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
}
