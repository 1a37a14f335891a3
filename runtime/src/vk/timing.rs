//! GPU timing with timestamp queries: checked for support, period and valid bits applied.

use std::sync::Arc;

use ash::vk;

use super::device::Device;
use super::error::{CallContext, VkError, VkResult};

/// A pool of `count` timestamps.
pub struct Timestamps {
    device: Arc<Device>,
    raw: vk::QueryPool,
    count: u32,
}

impl Timestamps {
    /// Fails with a clear error when the device's queue has no timestamps.
    pub fn new(device: &Arc<Device>, count: u32) -> VkResult<Timestamps> {
        if device.info.timestamp_valid_bits == 0 || device.info.timestamp_period_ns <= 0.0 {
            return Err(VkError::Unsupported { device: device.info.name.clone(), missing: "timestamp queries on the graphics queue".into() });
        }
        let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(count);
        // SAFETY: live device.
        let raw = unsafe { device.raw.create_query_pool(&info, None) }.call("vkCreateQueryPool", String::new)?;
        Ok(Timestamps { device: device.clone(), raw, count })
    }

    /// Records a reset of all queries (call before the first `write` in a submission).
    pub fn reset(&self, cb: vk::CommandBuffer) {
        // SAFETY: cb is recording outside a render pass.
        unsafe { self.device.raw.cmd_reset_query_pool(cb, self.raw, 0, self.count) };
    }

    /// Records timestamp `index` after all previous work completes.
    pub fn write(&self, cb: vk::CommandBuffer, index: u32) {
        // SAFETY: index < count is the caller's contract (validation checks it in tests).
        unsafe { self.device.raw.cmd_write_timestamp2(cb, vk::PipelineStageFlags2::ALL_COMMANDS, self.raw, index) };
    }

    /// Milliseconds between timestamps `a` and `b`, once the submission has completed.
    pub fn elapsed_ms(&self, a: u32, b: u32) -> VkResult<f64> {
        let mut data = vec![0u64; self.count as usize];
        // SAFETY: the submission that wrote them has completed (fence waited).
        unsafe { self.device.raw.get_query_pool_results(self.raw, 0, &mut data, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT) }
            .call("vkGetQueryPoolResults", || "timestamps".into())?;
        let bits = self.device.info.timestamp_valid_bits;
        let mask = if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 };
        let ticks = (data[b as usize] & mask).wrapping_sub(data[a as usize] & mask) & mask;
        Ok(ticks as f64 * self.device.info.timestamp_period_ns as f64 * 1e-6)
    }
}

impl Drop for Timestamps {
    fn drop(&mut self) {
        // SAFETY: results were read after completion.
        unsafe { self.device.raw.destroy_query_pool(self.raw, None) };
    }
}
