//! Errors of the Vulkan layer. Every variant says which call failed and in what
//! context, so a user reading "error: ..." knows what to do.

use ash::vk;

#[derive(Debug, thiserror::Error)]
pub enum VkError {
    /// The Vulkan loader library (libvulkan.so.1) could not be opened.
    #[error("cannot load the Vulkan loader (libvulkan): {0}. Install it (Debian: apt-get install libvulkan1 mesa-vulkan-drivers)")]
    LoaderMissing(String),
    /// A Vulkan call returned an error code.
    #[error("{call} failed: {result} ({context})")]
    Call { call: &'static str, result: vk::Result, context: String },
    /// No physical device supports what we need, or none exists at all.
    #[error("no usable Vulkan device: {0}")]
    NoDevice(String),
    /// The device named with --device / FABRIC_DEVICE does not exist.
    #[error("no Vulkan device matches '{wanted}'; available: {available}")]
    DeviceNotFound { wanted: String, available: String },
    /// The device lacks a feature or limit we need.
    #[error("device '{device}' cannot be used: {missing}")]
    Unsupported { device: String, missing: String },
    /// gpu-allocator failed.
    #[error("GPU memory allocation of '{name}' ({bytes} bytes) failed: {source}")]
    Allocation { name: String, bytes: u64, source: gpu_allocator::AllocationError },
    /// A buffer larger than the device allows for one storage-buffer binding.
    #[error("buffer '{name}' needs {bytes} bytes but the device allows {limit} per storage-buffer binding")]
    TooLarge { name: String, bytes: u64, limit: u64 },
    /// Host-side misuse that the API would have rejected (wrong sizes and the like).
    #[error("{0}")]
    Invalid(String),
    /// GLSL compilation at run time failed.
    #[error("shader '{name}' failed to compile:\n{message}")]
    ShaderCompile { name: String, message: String },
    /// A fence wait ran out of time: the GPU hung or the work was far too large.
    #[error("GPU work '{0}' did not finish within the timeout")]
    Timeout(String),
}

pub type VkResult<T> = Result<T, VkError>;

/// Maps a raw `vk::Result` error into a [`VkError::Call`] with context.
pub(crate) trait CallContext<T> {
    fn call(self, call: &'static str, context: impl FnOnce() -> String) -> VkResult<T>;
}

impl<T> CallContext<T> for Result<T, vk::Result> {
    fn call(self, call: &'static str, context: impl FnOnce() -> String) -> VkResult<T> {
        self.map_err(|result| VkError::Call { call, result, context: context() })
    }
}
