//! The object layer on ash: instance, device choice, memory, buffers, images, samplers,
//! descriptors, pipelines and their cache, command recording and submission, barriers, timestamps.
//!
//! Decisions (details in each file):
//! - RAII everywhere: every object owns its handle and an `Arc` of the device; work in flight
//!   keeps what it uses alive until its fence signals. No `vkDeviceWaitIdle` outside shutdown.
//! - Nothing per frame is created: submissions lease their command pool, fence, query pool and
//!   breadcrumb buffer from the device's recycler (`recycler.rs`), descriptor sets take reset
//!   pools of their pipeline (`descriptor_pools.rs`); both come back only after the fence.
//! - Caller misuse is [`GpuError::InvalidRequest`], faults are [`GpuError::Internal`]; faults in
//!   destructors go to the device's fault log (`faults.rs`), never skipped.
//! - Layouts come from the build-time reflection table (`shaders.rs`), never written by hand.
//! - Barriers come from one access table (`sync.rs`).
//! - Every Vulkan result becomes a typed [`GpuError`]; nothing here unwraps or panics.

pub mod adapter;
pub mod adopt;
pub mod buffer;
pub mod commands;
pub mod debug;
pub mod descriptor_pools;
pub mod descriptors;
pub mod device;
pub mod error;
pub mod faults;
pub mod image;
pub mod instance;
pub mod memory;
pub mod pipeline;
pub mod pipeline_cache;
pub mod pipeline_stats;
pub mod profile;
pub mod recycler;
#[cfg(test)]
mod reuse_tests;
pub mod sampler;
pub mod shaders;
#[cfg(feature = "viewer")]
pub mod swapchain;
pub mod sync;
pub mod timestamps;

pub use adapter::{AdapterInfo, DeviceSelector};
pub use adopt::AdoptedHandles;
pub use buffer::{Buffer, BufferDesc};
pub use commands::{Recording, Submission};
pub use descriptors::{DescriptorSet, Resource};
pub use device::{Device, DeviceConfig, DeviceTimings, Presentation};
pub use error::{GpuError, GpuResult};
pub use image::{Image, ImageDesc};
pub use instance::{Instance, Validation};
pub use memory::{AllocationRecord, MemoryIntent};
pub use pipeline::{ComputePipeline, SpecValue};
pub use pipeline_cache::{CacheLoad, PersistOutcome, PipelineCache, PipelineCacheConfig};
pub use profile::{DeviceProfile, KernelTuning};
pub use recycler::RecyclerCounts;
pub use sampler::{Filter, Sampler};
pub use sync::Access;
pub use timestamps::PassTiming;

/// Frames that may be in flight at once: per-frame uniform buffers of a render target, the
/// swapchain's acquire semaphores and the presenter's per-frame resources all use this one
/// number.
pub const FRAMES_IN_FLIGHT: usize = 2;
