//! What a pass declares to the plan: the allocations it makes, as the very descriptions the
//! engine creates them from, and the passes it runs with their variants and predicted costs.
//!
//! Decisions:
//! - One list. Each engine module that allocates (prepare, upload, derive, occupancy, render,
//!   bricked, the engine's placeholders) builds its `BufferDesc`/`ImageDesc`s with one function
//!   and calls that same function both when it allocates and when it declares to the plan, so a
//!   name, a size, a format or a usage (hence a driver's alignment) cannot differ between the
//!   two. The memory ledger test (`tests/memory_plan.rs`) still holds them equal on a device.
//! - Sizes are the device's: the plan asks [`ImageSizes`] for each description's bytes, so
//!   driver padding is included before anything exists.
//! - Where an allocation lives is read from its description (its memory intent and usage), not
//!   declared again.

use super::{ImageSizes, PlanInput, PlannedAllocation, PlannedPass};
use crate::gpu::{BufferDesc, ImageDesc, MemoryIntent};
use crate::scene::Effects;
use ash::vk;

/// A buffer or an image as the engine will create it.
#[derive(Clone, Debug)]
pub enum Resource {
    /// A buffer.
    Buffer(BufferDesc),
    /// An image.
    Image(ImageDesc),
}

/// One allocation a pass makes.
#[derive(Clone, Debug)]
pub struct Declared {
    /// What is created.
    pub resource: Resource,
    /// Freed before the first frame (staging, readback of one-off results).
    pub transient: bool,
}

impl Declared {
    /// A buffer held while the volume is rendered.
    pub fn held(desc: BufferDesc) -> Self {
        Declared {
            resource: Resource::Buffer(desc),
            transient: false,
        }
    }

    /// A buffer freed before the first frame.
    pub fn transient(desc: BufferDesc) -> Self {
        Declared {
            resource: Resource::Buffer(desc),
            transient: true,
        }
    }

    /// An image held while the volume is rendered.
    pub fn held_image(desc: ImageDesc) -> Self {
        Declared {
            resource: Resource::Image(desc),
            transient: false,
        }
    }

    /// An image freed before the first frame.
    pub fn transient_image(desc: ImageDesc) -> Self {
        Declared {
            resource: Resource::Image(desc),
            transient: true,
        }
    }

    /// What the plan shows: the device's bytes, the format, where it lives.
    pub fn planned(&self, sizes: &dyn ImageSizes, unified_memory: bool) -> PlannedAllocation {
        let (name, bytes, format, memory) = match &self.resource {
            Resource::Buffer(d) => (&d.name, sizes.buffer_bytes(d), None, buffer_memory(d)),
            Resource::Image(d) => (
                &d.name,
                sizes.image_bytes(d),
                Some(d.format),
                "device-local",
            ),
        };
        let memory = if memory == "device-local" && unified_memory {
            "host-visible (unified)"
        } else {
            memory
        };
        PlannedAllocation {
            name: name.clone(),
            bytes,
            format,
            memory_type: memory.to_string(),
            transient: self.transient,
        }
    }
}

/// Where a buffer lives, from its description.
fn buffer_memory(desc: &BufferDesc) -> &'static str {
    match desc.intent {
        MemoryIntent::GpuOnly => "device-local",
        MemoryIntent::Upload => "host-visible",
        MemoryIntent::Staging => "host (staging)",
        MemoryIntent::Readback => "host (readback)",
    }
}

/// What a pass (or a group of passes run together) adds to the plan.
#[derive(Clone, Debug, Default)]
pub struct PassDeclaration {
    /// The passes, in execution order, with their costs.
    pub passes: Vec<PlannedPass>,
    /// The pipeline variants they need (CPU passes need none).
    pub variants: Vec<String>,
    /// The allocations they make.
    pub allocations: Vec<Declared>,
}

impl PassDeclaration {
    /// Allocations only (no pass of their own: the engine's stand-ins, the render target).
    pub fn allocations(allocations: Vec<Declared>) -> Self {
        PassDeclaration {
            allocations,
            ..PassDeclaration::default()
        }
    }

    /// Appends `other` after this declaration.
    pub fn extend(&mut self, other: PassDeclaration) {
        self.passes.extend(other.passes);
        self.variants.extend(other.variants);
        self.allocations.extend(other.allocations);
    }
}

/// What every declaration may depend on: the volume, the image, the device, and the choices the
/// degradation ladder made.
#[derive(Clone, Copy, Debug)]
pub struct PlanContext<'a> {
    /// The volume, image and device.
    pub input: &'a PlanInput,
    /// The effects as planned (after degradations).
    pub effects: Effects,
    /// I_norm's storage format.
    pub normalized_format: vk::Format,
    /// Bricked layout.
    pub bricked: bool,
    /// Extent of the volume's images (the brick atlas when bricked).
    pub extent: [u32; 3],
}

impl PlanContext<'_> {
    /// Voxels of the volume.
    pub fn voxels(&self) -> u64 {
        self.input.dims.iter().map(|&d| d as u64).product()
    }

    /// Texels of the volume's images (the atlas when bricked).
    pub fn texels(&self) -> u64 {
        self.extent.iter().map(|&d| d as u64).product()
    }

    /// Bytes of the volume's samples as read.
    pub fn sample_bytes(&self) -> u64 {
        self.voxels() * self.input.sample_kind.size_bytes() as u64
    }

    /// Bytes per texel of I_norm.
    pub fn normalized_bytes(&self) -> u64 {
        super::texel_bytes(self.normalized_format)
    }
}
