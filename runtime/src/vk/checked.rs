//! The test support's device: validation on, and its log checked when it drops, so a
//! test that provoked a validation error fails even where it forgot to look.

use std::ops::Deref;
use std::sync::Arc;

use super::device::{Device, DeviceOptions};
use super::instance::InstanceOptions;
use super::error::VkResult;

/// A [`Device`] with validation requested whose drop fails the test (panics) if the
/// layer reported any error, unless [`CheckedDevice::expect_errors`] said they are the
/// point of the test.
pub struct CheckedDevice {
    device: Arc<Device>,
    errors_expected: bool,
}

impl CheckedDevice {
    /// The default device with the validation layer on (where it is installed; CI sets
    /// `FABRIC_REQUIRE_VALIDATION=1` so that a missing layer is an error there).
    pub fn new() -> VkResult<CheckedDevice> {
        let device = Device::new(&DeviceOptions { instance: InstanceOptions { validation: Some(true), ..Default::default() }, ..Default::default() })?;
        Ok(CheckedDevice { device, errors_expected: false })
    }

    /// This test provokes validation errors on purpose: do not fail on them.
    pub fn expect_errors(&mut self) {
        self.errors_expected = true;
    }
}

impl Deref for CheckedDevice {
    type Target = Arc<Device>;
    fn deref(&self) -> &Arc<Device> {
        &self.device
    }
}

impl Drop for CheckedDevice {
    fn drop(&mut self) {
        if self.errors_expected || std::thread::panicking() {
            return;
        }
        let errors = self.device.validation_errors();
        if !errors.is_empty() {
            panic!("{} Vulkan validation error(s) during this test:\n{}", errors.len(), errors.join("\n"));
        }
    }
}
