//! The transfer-function table of a render target (issue 33 item 1): the raymarch's tissue
//! windows as one lookup (`scene::transfer_table`), for variants with CLASSIFY_TABLE.
//!
//! Decisions: one host-visible buffer per frame slot (engine/host_slots.rs), rewritten only when
//! the classification differs from what that slot holds, so a frame in flight never sees its
//! table change and an orbit rebuilds nothing. Building the 8192 entries costs about as much as
//! one smoothstep per entry and window on the host, once per classification change.

use super::Engine;
use super::host_slots::HostSlots;
use super::render::RenderTarget;
use crate::gpu::{Buffer, BufferDesc, GpuResult};
use crate::scene::Scene;
use crate::scene::transfer_table::{TABLE_BYTES, TransferTable};
use std::sync::Arc;

/// The table's buffer: `vec4`s read as a storage buffer, or through its RGBA32F texel view on
/// devices that prefer texel lookups (classification.glsl).
pub fn transfer_table_desc() -> BufferDesc {
    BufferDesc::host_storage("transfer-function table", TABLE_BYTES)
        .with_texel_view(ash::vk::Format::R32G32B32A32_SFLOAT)
}

/// A render target's tables, per frame slot, and the classification each holds.
pub type TableSlots = HostSlots<crate::scene::Classification>;

impl Engine {
    /// The table buffer the raymarch binds this frame: `scene`'s table in `frame_slot` when
    /// `used`, else the placeholder (never read).
    pub(super) fn transfer_table_input(
        &self,
        target: &mut RenderTarget,
        scene: &Scene,
        frame_slot: usize,
        used: bool,
    ) -> GpuResult<Arc<Buffer>> {
        if !used {
            return Ok(self.placeholders.occupancy.clone());
        }
        let classification = scene.classification;
        target.tables.current(
            &self.device,
            frame_slot,
            transfer_table_desc,
            |held| *held == classification,
            classification,
            |buffer| buffer.write(0, TransferTable::new(&classification).bytes()),
        )
    }
}
