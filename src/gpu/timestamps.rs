//! GPU timestamps around every pass of a recording.
//!
//! Decisions: one query pool per recording with two queries per pass, reset inside the command
//! buffer (no hostQueryReset needed); the pool is the recording's lease's (`recycler.rs`), reused
//! from submission to submission and destroyed with the lease; both timestamps are written at ALL_COMMANDS, i.e. when all
//! earlier work has finished, so a pass's time is the gap between the end of the work before it
//! and its own end. Ticks are masked to the queue's `timestampValidBits` (36 on Intel Gen12) and
//! scaled by `timestampPeriod`. A queue without timestamps yields no timings, never fake ones.

use super::device::DeviceShared;
use super::error::{GpuResult, vk_err};
use ash::vk;

/// Passes one recording can time.
pub const MAX_PASSES: u32 = 64;

/// GPU time of one pass.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PassTiming {
    /// Pass name as given to `begin_pass`.
    pub name: String,
    /// Milliseconds between the end of the previous work and the end of this pass.
    pub gpu_ms: f64,
}

pub(crate) struct TimestampPool {
    pool: vk::QueryPool,
    names: Vec<String>,
    valid_mask: u64,
    period_ns: f64,
}

impl TimestampPool {
    /// Timestamps written into `pool` (a lease's); None when the queue has no timestamps (the
    /// lease then has no pool).
    pub(crate) fn new(device: &DeviceShared, pool: vk::QueryPool) -> Option<Self> {
        let bits = device.adapter.timestamp_valid_bits;
        if bits == 0 || pool == vk::QueryPool::null() {
            return None;
        }
        let valid_mask = if bits >= 64 {
            u64::MAX
        } else {
            (1u64 << bits) - 1
        };
        Some(TimestampPool {
            pool,
            names: Vec::new(),
            valid_mask,
            period_ns: device.adapter.timestamp_period_ns,
        })
    }

    pub(crate) fn reset(&self, device: &DeviceShared, cmd: vk::CommandBuffer) {
        // SAFETY: cmd is recording; the pool belongs to this device.
        unsafe {
            device
                .raw
                .cmd_reset_query_pool(cmd, self.pool, 0, 2 * MAX_PASSES)
        };
    }

    /// Writes the start timestamp; false when the pool is full (the pass is then not timed).
    pub(crate) fn begin(
        &mut self,
        device: &DeviceShared,
        cmd: vk::CommandBuffer,
        name: &str,
    ) -> bool {
        let index = self.names.len() as u32;
        if index >= MAX_PASSES {
            return false;
        }
        self.names.push(name.to_string());
        // SAFETY: query 2*index was reset at the start of this command buffer.
        unsafe {
            device.raw.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                2 * index,
            )
        };
        true
    }

    pub(crate) fn end(&self, device: &DeviceShared, cmd: vk::CommandBuffer) {
        let index = self.names.len() as u32 - 1;
        // SAFETY: as above.
        unsafe {
            device.raw.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                2 * index + 1,
            )
        };
    }

    /// Reads the results; call only after the submission's fence signalled.
    pub(crate) fn results(&self, device: &DeviceShared) -> GpuResult<Vec<PassTiming>> {
        if self.names.is_empty() {
            return Ok(Vec::new());
        }
        let mut ticks = vec![0u64; 2 * self.names.len()];
        // SAFETY: every query in range was written by completed work.
        unsafe {
            device.raw.get_query_pool_results(
                self.pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(vk_err("vkGetQueryPoolResults"))?;
        Ok(self
            .names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let start = ticks[2 * i] & self.valid_mask;
                let end = ticks[2 * i + 1] & self.valid_mask;
                // Wrap-around of a 36-bit counter between the two queries.
                let delta = end.wrapping_sub(start) & self.valid_mask;
                PassTiming {
                    name: name.clone(),
                    gpu_ms: delta as f64 * self.period_ns * 1e-6,
                }
            })
            .collect())
    }
}
