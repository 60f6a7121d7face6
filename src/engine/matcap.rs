//! The matcap of a render target (issue 34 item 2): the engine's matcap image
//! (`scene::matcap`, set by [`Engine::set_matcap`]) in a host-visible buffer per frame slot, for
//! variants lit by a matcap.
//!
//! Decisions: as the transfer-function table, one buffer per frame slot (engine/host_slots.rs),
//! rewritten only when the engine's matcap is not the one that slot holds (compared by identity:
//! `set_matcap` makes a new `Arc`), so a frame in flight never sees its matcap change and an
//! orbit uploads nothing.
//! Every matcap is [`MATCAP_BYTES`] (resampled on the host), so the buffer and the plan's entry
//! have one size.

use super::Engine;
use super::host_slots::HostSlots;
use super::render::RenderTarget;
use crate::gpu::{Buffer, BufferDesc, GpuResult};
use crate::scene::matcap::{MATCAP_BYTES, MatcapImage};
use std::sync::Arc;

/// A render target's matcap buffers, per frame slot, and the image each holds.
pub type MatcapSlots = HostSlots<Arc<MatcapImage>>;

/// The plan's description of one frame slot's matcap buffer.
pub fn matcap_desc() -> BufferDesc {
    BufferDesc::host_storage("matcap", MATCAP_BYTES)
}

impl Engine {
    /// The matcap later frames are lit by (`LightModel::Matcap`); the built-in `clay` until set.
    pub fn set_matcap(&mut self, matcap: MatcapImage) {
        self.matcap = Arc::new(matcap);
    }

    /// The matcap frames are lit by.
    pub fn matcap(&self) -> &MatcapImage {
        &self.matcap
    }

    /// The matcap buffer the raymarch binds this frame: the engine's matcap in `frame_slot`
    /// when `used`, else the placeholder (never read).
    pub(super) fn matcap_input(
        &self,
        target: &mut RenderTarget,
        frame_slot: usize,
        used: bool,
    ) -> GpuResult<Arc<Buffer>> {
        if !used {
            return Ok(self.placeholders.occupancy.clone());
        }
        let matcap = self.matcap.clone();
        target.matcaps.current(
            &self.device,
            frame_slot,
            matcap_desc,
            |held| Arc::ptr_eq(held, &matcap),
            matcap.clone(),
            |buffer| buffer.write(0, matcap.bytes()),
        )
    }
}
