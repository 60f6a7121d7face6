//! Small host-written buffers the raymarch reads, one per frame slot (the transfer-function
//! table, engine/transfer.rs; the matcap, engine/matcap.rs), rewritten only when what a slot
//! holds is not what the frame needs.
//!
//! Decisions: one buffer per frame slot, created on first use (a scene that never needs the
//! buffer allocates nothing), so a frame in flight never sees its contents change; the caller
//! says what the slot must hold (`is_current` on the key it stored) and how to write it, and an
//! orbit, which changes neither, rewrites nothing.

use crate::gpu::{Buffer, BufferDesc, Device, GpuResult};
use std::sync::Arc;

/// Buffers per frame slot, each with the key of what it holds.
pub struct HostSlots<K> {
    slots: Vec<Option<(Arc<Buffer>, K)>>,
}

impl<K> Default for HostSlots<K> {
    fn default() -> Self {
        HostSlots { slots: Vec::new() }
    }
}

impl<K> HostSlots<K> {
    /// The buffer of `frame_slot`: as it is when `is_current` accepts its key, else created
    /// from `desc` (first use) or reused, written by `write`, and stored with `key`.
    pub fn current(
        &mut self,
        device: &Device,
        frame_slot: usize,
        desc: impl FnOnce() -> BufferDesc,
        is_current: impl FnOnce(&K) -> bool,
        key: K,
        write: impl FnOnce(&Buffer) -> GpuResult<()>,
    ) -> GpuResult<Arc<Buffer>> {
        if self.slots.len() <= frame_slot {
            self.slots.resize_with(frame_slot + 1, || None);
        }
        if let Some((buffer, held)) = &self.slots[frame_slot]
            && is_current(held)
        {
            return Ok(buffer.clone());
        }
        let buffer = match self.slots[frame_slot].take() {
            Some((buffer, _)) => buffer,
            None => Buffer::new(device, desc())?,
        };
        // Host writes before the submission that reads them; the other slots' buffers, which a
        // frame in flight may read, are untouched.
        write(&buffer)?;
        self.slots[frame_slot] = Some((buffer.clone(), key));
        Ok(buffer)
    }
}
