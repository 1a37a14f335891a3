//! Window surfaces, the swapchain and the per-frame submission that presents to it.
//!
//! One frame in flight: simple, and on lavapipe (where the CPU renders) more frames in
//! flight would only add latency. Each swapchain image has its own "rendered"
//! semaphore, so a semaphore is never re-signalled while a present still waits on it.

use std::ffi::CString;
use std::sync::Arc;

use ash::vk;
use raw_window_handle::{RawDisplayHandle, RawWindowHandle};

use super::commands::Recorder;
use super::device::Device;
use super::error::{CallContext, VkError, VkResult};
use super::instance::Instance;
use super::timing::Timestamps;

/// Instance extensions a window system needs (VK_KHR_surface + the platform's).
pub fn required_instance_extensions(display: RawDisplayHandle) -> VkResult<Vec<CString>> {
    let names = ash_window::enumerate_required_extensions(display).call("enumerate_required_extensions", || "window surface".into())?;
    // SAFETY: ash_window returns pointers to static NUL-terminated extension names.
    Ok(names.iter().map(|&p| unsafe { std::ffi::CStr::from_ptr(p) }.to_owned()).collect())
}

/// Device extensions for presenting.
pub fn required_device_extensions() -> Vec<CString> {
    vec![ash::khr::swapchain::NAME.to_owned()]
}

/// A `VkSurfaceKHR`, owned.
pub struct Surface {
    instance: Arc<Instance>,
    loader: ash::khr::surface::Instance,
    pub(crate) raw: vk::SurfaceKHR,
}

impl Surface {
    /// A surface for a window. The window must outlive the surface (the caller keeps
    /// both in one struct with the surface dropped first).
    pub fn new(instance: &Arc<Instance>, display: RawDisplayHandle, window: RawWindowHandle) -> VkResult<Surface> {
        // SAFETY: the handles come from a live window (caller's contract, see above);
        // the instance was created with `required_instance_extensions`.
        let raw = unsafe { ash_window::create_surface(&instance.entry, &instance.instance, display, window, None) }.call("vkCreate*SurfaceKHR", || "window".into())?;
        let loader = ash::khr::surface::Instance::new(&instance.entry, &instance.instance);
        Ok(Surface { instance: instance.clone(), loader, raw })
    }
}

impl Drop for Surface {
    fn drop(&mut self) {
        let _ = &self.instance; // keeps the instance alive until here
        // SAFETY: the swapchain made from it is dropped first (it holds an Arc<Surface>).
        unsafe { self.loader.destroy_surface(self.raw, None) };
    }
}

/// What `acquire` found.
pub enum Acquired {
    /// Render into image `index` of the swapchain.
    Image(u32),
    /// The window changed size (or was minimized): recreate and try again.
    OutOfDate,
}

/// A swapchain with its image views and the synchronization of one frame in flight.
pub struct Swapchain {
    device: Arc<Device>,
    surface: Arc<Surface>,
    loader: ash::khr::swapchain::Device,
    raw: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    views: Vec<vk::ImageView>,
    pub format: vk::Format,
    pub extent: vk::Extent2D,
    acquired: vk::Semaphore,
    rendered: Vec<vk::Semaphore>,
    in_flight: vk::Fence,
    command_buffer: vk::CommandBuffer,
}

impl Swapchain {
    /// Creates a swapchain of about `width` × `height` for `surface`. Prefers an
    /// `*_SRGB` 8-bit format (the hardware then encodes sRGB) and FIFO presentation.
    pub fn new(device: &Arc<Device>, surface: &Arc<Surface>, width: u32, height: u32) -> VkResult<Swapchain> {
        let pd = device.physical;
        let sl = &surface.loader;
        // SAFETY: queries on live handles.
        let (supported, caps, formats) = unsafe {
            (
                sl.get_physical_device_surface_support(pd, device.queue_family, surface.raw).call("vkGetPhysicalDeviceSurfaceSupportKHR", String::new)?,
                sl.get_physical_device_surface_capabilities(pd, surface.raw).call("vkGetPhysicalDeviceSurfaceCapabilitiesKHR", String::new)?,
                sl.get_physical_device_surface_formats(pd, surface.raw).call("vkGetPhysicalDeviceSurfaceFormatsKHR", String::new)?,
            )
        };
        if !supported {
            return Err(VkError::Unsupported { device: device.info.name.clone(), missing: "presentation to this window".into() });
        }
        let pick = formats
            .iter()
            .find(|f| matches!(f.format, vk::Format::B8G8R8A8_SRGB | vk::Format::R8G8B8A8_SRGB))
            .or_else(|| formats.iter().find(|f| matches!(f.format, vk::Format::B8G8R8A8_UNORM | vk::Format::R8G8B8A8_UNORM)))
            .copied()
            .ok_or_else(|| VkError::Unsupported { device: device.info.name.clone(), missing: "an 8-bit RGBA/BGRA surface format".into() })?;
        let extent = if caps.current_extent.width != u32::MAX {
            caps.current_extent
        } else {
            vk::Extent2D {
                width: width.clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                height: height.clamp(caps.min_image_extent.height, caps.max_image_extent.height),
            }
        };
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(surface.raw)
            .min_image_count(count)
            .image_format(pick.format)
            .image_color_space(pick.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::COLOR_ATTACHMENT)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(vk::CompositeAlphaFlagsKHR::OPAQUE)
            .present_mode(vk::PresentModeKHR::FIFO)
            .clipped(true);
        let loader = ash::khr::swapchain::Device::new(&device.instance.instance, &device.raw);
        // SAFETY: the device was created with VK_KHR_swapchain; the surface is live.
        let raw = unsafe { loader.create_swapchain(&info, None) }.call("vkCreateSwapchainKHR", || format!("{}x{}", extent.width, extent.height))?;
        let mut sc = Swapchain {
            device: device.clone(),
            surface: surface.clone(),
            loader,
            raw,
            images: Vec::new(),
            views: Vec::new(),
            format: pick.format,
            extent,
            acquired: vk::Semaphore::null(),
            rendered: Vec::new(),
            in_flight: vk::Fence::null(),
            command_buffer: vk::CommandBuffer::null(),
        };
        // From here on, Drop cleans up whatever was created.
        // SAFETY: live swapchain.
        sc.images = unsafe { sc.loader.get_swapchain_images(raw) }.call("vkGetSwapchainImagesKHR", String::new)?;
        for &image in &sc.images {
            let view_info = vk::ImageViewCreateInfo::default()
                .image(image)
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(pick.format)
                .subresource_range(vk::ImageSubresourceRange { aspect_mask: vk::ImageAspectFlags::COLOR, base_mip_level: 0, level_count: 1, base_array_layer: 0, layer_count: 1 });
            // SAFETY: image of this swapchain.
            sc.views.push(unsafe { device.raw.create_image_view(&view_info, None) }.call("vkCreateImageView", || "swapchain".into())?);
        }
        // SAFETY: creating sync objects on a live device.
        unsafe {
            sc.acquired = device.raw.create_semaphore(&vk::SemaphoreCreateInfo::default(), None).call("vkCreateSemaphore", String::new)?;
            for _ in 0..sc.images.len() {
                sc.rendered.push(device.raw.create_semaphore(&vk::SemaphoreCreateInfo::default(), None).call("vkCreateSemaphore", String::new)?);
            }
            sc.in_flight = device.raw.create_fence(&vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED), None).call("vkCreateFence", String::new)?;
            let pool = device.command_pool.lock().unwrap_or_else(|e| e.into_inner());
            let alloc = vk::CommandBufferAllocateInfo::default().command_pool(*pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
            sc.command_buffer = device.raw.allocate_command_buffers(&alloc).call("vkAllocateCommandBuffers", || "frame".into())?[0];
        }
        Ok(sc)
    }

    pub fn image_count(&self) -> usize {
        self.images.len()
    }

    /// Whether the format encodes sRGB in hardware (else the shader must).
    pub fn is_srgb(&self) -> bool {
        matches!(self.format, vk::Format::B8G8R8A8_SRGB | vk::Format::R8G8B8A8_SRGB)
    }

    /// Waits for the previous frame, then acquires the next image.
    pub fn acquire(&mut self) -> VkResult<Acquired> {
        // SAFETY: the fence belongs to this device; waiting bounds our one frame in flight.
        unsafe { self.device.raw.wait_for_fences(&[self.in_flight], true, u64::MAX) }.call("vkWaitForFences", || "previous frame".into())?;
        // SAFETY: live swapchain; `acquired` is unsignalled (the previous frame's submit waited on it).
        match unsafe { self.loader.acquire_next_image(self.raw, u64::MAX, self.acquired, vk::Fence::null()) } {
            Ok((index, _suboptimal)) => Ok(Acquired::Image(index)),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(Acquired::OutOfDate),
            Err(result) => Err(VkError::Call { call: "vkAcquireNextImageKHR", result, context: String::new() }),
        }
    }

    /// Records the frame for image `index` with `record`, submits it and presents.
    /// `record` gets the recorder, the swapchain image and its view (in UNDEFINED
    /// layout; it must leave the image in PRESENT_SRC_KHR). Returns false when the
    /// swapchain is out of date.
    pub fn submit_and_present(&mut self, index: u32, record: impl FnOnce(&Recorder<'_>, vk::Image, vk::ImageView)) -> VkResult<bool> {
        let (image, view) = (self.images[index as usize], self.views[index as usize]);
        let cb = self.command_buffer;
        let d = &self.device.raw;
        // SAFETY: the previous use of cb completed (fence waited in acquire); the command
        // pool is only used from this thread while the viewer runs.
        unsafe {
            d.reset_fences(&[self.in_flight]).call("vkResetFences", String::new)?;
            d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty()).call("vkResetCommandBuffer", String::new)?;
            d.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT)).call("vkBeginCommandBuffer", String::new)?;
        }
        record(&Recorder { device: &self.device, cb }, image, view);
        let rendered = self.rendered[index as usize];
        let waits = [vk::SemaphoreSubmitInfo::default().semaphore(self.acquired).stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)];
        let signals = [vk::SemaphoreSubmitInfo::default().semaphore(rendered).stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)];
        let cbs = [vk::CommandBufferSubmitInfo::default().command_buffer(cb)];
        let submit = [vk::SubmitInfo2::default().wait_semaphore_infos(&waits).command_buffer_infos(&cbs).signal_semaphore_infos(&signals)];
        let queue = *self.device.queue.lock().unwrap_or_else(|e| e.into_inner());
        let swapchains = [self.raw];
        let indices = [index];
        let wait_present = [rendered];
        let present = vk::PresentInfoKHR::default().wait_semaphores(&wait_present).swapchains(&swapchains).image_indices(&indices);
        // SAFETY: recording finished below; the queue mutex is not held by anyone else
        // during the viewer's frame (one thread).
        unsafe {
            d.end_command_buffer(cb).call("vkEndCommandBuffer", String::new)?;
            d.queue_submit2(queue, &submit, self.in_flight).call("vkQueueSubmit2", || "frame".into())?;
            match self.loader.queue_present(queue, &present) {
                Ok(_) => Ok(true),
                Err(vk::Result::ERROR_OUT_OF_DATE_KHR) | Err(vk::Result::SUBOPTIMAL_KHR) => Ok(false),
                Err(result) => Err(VkError::Call { call: "vkQueuePresentKHR", result, context: String::new() }),
            }
        }
    }

    /// Milliseconds between two timestamps of the last completed frame.
    pub fn wait_idle_and_read(&self, t: &Timestamps, a: u32, b: u32) -> VkResult<f64> {
        // SAFETY: waiting on our own fence.
        unsafe { self.device.raw.wait_for_fences(&[self.in_flight], true, u64::MAX) }.call("vkWaitForFences", String::new)?;
        t.elapsed_ms(a, b)
    }
}

impl Drop for Swapchain {
    fn drop(&mut self) {
        let d = &self.device.raw;
        // SAFETY: wait for all work, then destroy in reverse order of creation.
        unsafe {
            let _ = d.device_wait_idle();
            if self.command_buffer != vk::CommandBuffer::null() {
                let pool = self.device.command_pool.lock().unwrap_or_else(|e| e.into_inner());
                d.free_command_buffers(*pool, &[self.command_buffer]);
            }
            if self.in_flight != vk::Fence::null() {
                d.destroy_fence(self.in_flight, None);
            }
            for &s in &self.rendered {
                d.destroy_semaphore(s, None);
            }
            if self.acquired != vk::Semaphore::null() {
                d.destroy_semaphore(self.acquired, None);
            }
            for &v in &self.views {
                d.destroy_image_view(v, None);
            }
            self.loader.destroy_swapchain(self.raw, None);
        }
        let _ = &self.surface; // the surface outlives its swapchain
    }
}
