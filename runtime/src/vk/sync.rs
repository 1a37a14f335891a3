//! Fences, owned.

use ash::vk;

use super::device::Device;
use super::error::{CallContext, VkError, VkResult};

/// How long one submission may run before we call it hung. Generous: lavapipe renders
/// large frames slowly. `FABRIC_GPU_TIMEOUT_S` overrides it.
fn timeout_ns() -> u64 {
    let s = std::env::var("FABRIC_GPU_TIMEOUT_S").ok().and_then(|v| v.parse::<u64>().ok()).unwrap_or(600);
    s.saturating_mul(1_000_000_000)
}

pub struct Fence<'d> {
    device: &'d Device,
    pub(crate) raw: vk::Fence,
}

impl<'d> Fence<'d> {
    pub fn new(device: &'d Device, label: &str) -> VkResult<Fence<'d>> {
        // SAFETY: live device.
        let raw = unsafe { device.raw.create_fence(&vk::FenceCreateInfo::default(), None) }.call("vkCreateFence", || label.into())?;
        Ok(Fence { device, raw })
    }

    pub fn wait(&self, label: &str) -> VkResult<()> {
        // SAFETY: the fence belongs to this device.
        match unsafe { self.device.raw.wait_for_fences(&[self.raw], true, timeout_ns()) } {
            Ok(()) => Ok(()),
            Err(vk::Result::TIMEOUT) => Err(VkError::Timeout(label.into())),
            Err(result) => Err(VkError::Call { call: "vkWaitForFences", result, context: label.into() }),
        }
    }
}

impl Drop for Fence<'_> {
    fn drop(&mut self) {
        // SAFETY: a fence is only dropped after its wait returned or its submission failed;
        // after a timeout we wait for the device first so we never destroy a pending fence.
        unsafe {
            if self.device.raw.get_fence_status(self.raw) != Ok(true) {
                let _ = self.device.raw.device_wait_idle();
            }
            self.device.raw.destroy_fence(self.raw, None);
        }
    }
}
