//! Buffers in GPU memory through gpu-allocator, with staging upload and readback.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};

use super::device::Device;
use super::error::{CallContext, VkError, VkResult};

/// A buffer and its memory. Dropping frees the memory, then destroys the buffer.
pub struct Buffer {
    device: Arc<Device>,
    pub(crate) raw: vk::Buffer,
    allocation: Option<Allocation>,
    size: u64,
    name: String,
}

impl Buffer {
    /// Creates a buffer of `size` bytes. Storage buffers larger than the device's
    /// `maxStorageBufferRange` (128 MiB on lavapipe) are refused: split the data.
    pub fn new(device: &Arc<Device>, name: &str, size: u64, usage: vk::BufferUsageFlags, location: MemoryLocation) -> VkResult<Buffer> {
        if size == 0 {
            return Err(VkError::Invalid(format!("buffer '{name}' has size 0")));
        }
        if usage.contains(vk::BufferUsageFlags::STORAGE_BUFFER) && size > device.info.max_storage_buffer_range {
            return Err(VkError::TooLarge { name: name.into(), bytes: size, limit: device.info.max_storage_buffer_range });
        }
        let info = vk::BufferCreateInfo::default().size(size).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: live device, valid create info.
        let raw = unsafe { device.raw.create_buffer(&info, None) }.call("vkCreateBuffer", || format!("'{name}', {size} bytes"))?;
        // SAFETY: raw was just created on this device.
        let requirements = unsafe { device.raw.get_buffer_memory_requirements(raw) };
        let allocation = device.allocator().allocate(&AllocationCreateDesc { name, requirements, location, linear: true, allocation_scheme: AllocationScheme::GpuAllocatorManaged });
        let allocation = match allocation {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: unbound, unused buffer.
                unsafe { device.raw.destroy_buffer(raw, None) };
                return Err(VkError::Allocation { name: name.into(), bytes: size, source });
            }
        };
        // SAFETY: memory from the allocator satisfies the requirements queried above.
        if let Err(result) = unsafe { device.raw.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) } {
            let _ = device.allocator().free(allocation);
            // SAFETY: unused buffer.
            unsafe { device.raw.destroy_buffer(raw, None) };
            return Err(VkError::Call { call: "vkBindBufferMemory", result, context: name.into() });
        }
        device.set_name(raw, name);
        Ok(Buffer { device: device.clone(), raw, allocation: Some(allocation), size, name: name.into() })
    }

    /// A device-local buffer filled with `data` through a staging buffer.
    pub fn with_data(device: &Arc<Device>, name: &str, data: &[u8], usage: vk::BufferUsageFlags) -> VkResult<Buffer> {
        let buf = Buffer::new(device, name, data.len() as u64, usage | vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuOnly)?;
        buf.upload(data)?;
        Ok(buf)
    }

    pub fn raw(&self) -> vk::Buffer {
        self.raw
    }

    pub fn size(&self) -> u64 {
        self.size
    }

    pub fn name(&self) -> &str {
        &self.name
    }

    /// Host-visible bytes, if this buffer's memory is mapped.
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation.as_ref().and_then(|a| a.mapped_slice()).map(|s| &s[..self.size as usize])
    }

    /// Writes `data` at offset 0: directly when mapped, else through a staging copy.
    pub fn upload(&self, data: &[u8]) -> VkResult<()> {
        if data.len() as u64 > self.size {
            return Err(VkError::Invalid(format!("upload of {} bytes into buffer '{}' of {} bytes", data.len(), self.name, self.size)));
        }
        if data.is_empty() {
            return Ok(());
        }
        let staging = Buffer::new(&self.device, &format!("{} (staging)", self.name), data.len() as u64, vk::BufferUsageFlags::TRANSFER_SRC, MemoryLocation::CpuToGpu)?;
        staging.write_mapped(data)?;
        let region = [vk::BufferCopy { src_offset: 0, dst_offset: 0, size: data.len() as u64 }];
        self.device.run_commands(&format!("upload '{}'", self.name), |cb| {
            // SAFETY: both buffers are alive until run_commands returns (it waits).
            unsafe { self.device.raw.cmd_copy_buffer(cb, staging.raw, self.raw, &region) };
        })
    }

    /// Copies `data` into mapped (host-visible) memory.
    pub fn write_mapped(&self, data: &[u8]) -> VkResult<()> {
        let name = self.name.clone();
        let slice = self
            .allocation
            .as_ref()
            .and_then(|a| a.mapped_ptr())
            .ok_or_else(|| VkError::Invalid(format!("buffer '{name}' is not host-visible")))?;
        if data.len() as u64 > self.size {
            return Err(VkError::Invalid(format!("write of {} bytes into buffer '{name}' of {} bytes", data.len(), self.size)));
        }
        // SAFETY: the mapping covers `size` bytes and the GPU is not using the buffer
        // (callers write before submitting work that reads it).
        unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), slice.as_ptr() as *mut u8, data.len()) };
        Ok(())
    }

    /// Reads the whole buffer back to the host (through a staging copy if needed).
    pub fn download(&self) -> VkResult<Vec<u8>> {
        if let Some(m) = self.mapped() {
            return Ok(m.to_vec());
        }
        let staging = Buffer::new(&self.device, &format!("{} (readback)", self.name), self.size, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)?;
        let region = [vk::BufferCopy { src_offset: 0, dst_offset: 0, size: self.size }];
        self.device.run_commands(&format!("download '{}'", self.name), |cb| {
            // SAFETY: both buffers outlive the wait in run_commands.
            unsafe { self.device.raw.cmd_copy_buffer(cb, self.raw, staging.raw, &region) };
        })?;
        staging.mapped().map(|m| m.to_vec()).ok_or_else(|| VkError::Invalid(format!("readback buffer for '{}' is not mapped", self.name)))
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if let Some(a) = self.allocation.take() {
            let _ = self.device.allocator().free(a);
        }
        // SAFETY: the work using this buffer has completed (all submissions wait).
        unsafe { self.device.raw.destroy_buffer(self.raw, None) };
    }
}
