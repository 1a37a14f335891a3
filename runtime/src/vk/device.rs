//! Physical-device choice, the logical device, its queue, the memory allocator and
//! one-shot command submission.
//!
//! Choice: the device named by `--device NAME` / `FABRIC_DEVICE` (case-insensitive
//! substring of the device name), else the first discrete GPU, else integrated, else
//! virtual, else CPU (lavapipe). Vulkan 1.3 with dynamic rendering, synchronization2
//! and maintenance4 is required (shaderc emits `LocalSizeId`, which needs maintenance4).

use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::error::{CallContext, VkError, VkResult};
use super::instance::{Instance, InstanceOptions};

/// What we know about a physical device.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceInfo {
    pub name: String,
    /// "discrete GPU", "integrated GPU", "virtual GPU", "CPU" or "other".
    pub kind: &'static str,
    pub api_version: String,
    pub driver: String,
    pub vendor_id: u32,
    pub device_id: u32,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    /// Valid bits of timestamps on the chosen queue family (0 = no timestamps).
    pub timestamp_valid_bits: u32,
    pub max_storage_buffer_range: u64,
    pub max_image_dimension_2d: u32,
    pub max_push_constants_size: u32,
    /// Whether the device has what we need; if not, why not.
    pub usable: Result<(), String>,
    #[serde(skip)]
    pub(crate) queue_family: u32,
    #[serde(skip)]
    pub(crate) rank: u32,
}

fn kind_name(t: vk::PhysicalDeviceType) -> (&'static str, u32) {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => ("discrete GPU", 0),
        vk::PhysicalDeviceType::INTEGRATED_GPU => ("integrated GPU", 1),
        vk::PhysicalDeviceType::VIRTUAL_GPU => ("virtual GPU", 2),
        vk::PhysicalDeviceType::CPU => ("CPU", 3),
        _ => ("other", 4),
    }
}

fn describe(instance: &ash::Instance, pd: vk::PhysicalDevice) -> DeviceInfo {
    let mut driver_props = vk::PhysicalDeviceDriverProperties::default();
    let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver_props);
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut features2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f13).push_next(&mut f12);
    // SAFETY: pd comes from this instance; the chained structs live on this stack frame.
    let families = unsafe {
        instance.get_physical_device_properties2(pd, &mut props2);
        instance.get_physical_device_features2(pd, &mut features2);
        instance.get_physical_device_queue_family_properties(pd)
    };
    let p = props2.properties;
    let name = p.device_name_as_c_str().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|_| "(unnamed)".into());
    let driver_name = driver_props.driver_name_as_c_str().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let driver_info = driver_props.driver_info_as_c_str().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let (kind, rank) = kind_name(p.device_type);
    let family = families.iter().position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE));
    let mut missing = Vec::new();
    if p.api_version < vk::API_VERSION_1_3 {
        missing.push(format!("Vulkan 1.3 (has {})", version_string(p.api_version)));
    }
    if f13.dynamic_rendering == 0 {
        missing.push("dynamicRendering".to_string());
    }
    if f13.synchronization2 == 0 {
        missing.push("synchronization2".to_string());
    }
    if f13.maintenance4 == 0 {
        missing.push("maintenance4".to_string());
    }
    if family.is_none() {
        missing.push("a graphics+compute queue".to_string());
    }
    DeviceInfo {
        name,
        kind,
        api_version: version_string(p.api_version),
        driver: format!("{driver_name} {driver_info}").trim().to_string(),
        vendor_id: p.vendor_id,
        device_id: p.device_id,
        timestamp_period_ns: p.limits.timestamp_period,
        timestamp_valid_bits: family.map(|f| families[f].timestamp_valid_bits).unwrap_or(0),
        max_storage_buffer_range: p.limits.max_storage_buffer_range as u64,
        max_image_dimension_2d: p.limits.max_image_dimension2_d,
        max_push_constants_size: p.limits.max_push_constants_size,
        usable: if missing.is_empty() { Ok(()) } else { Err(format!("missing {}", missing.join(", "))) },
        queue_family: family.unwrap_or(0) as u32,
        rank,
    }
}

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

/// Lists every physical device the loader reports.
pub fn enumerate_devices(instance: &Instance) -> VkResult<Vec<DeviceInfo>> {
    // SAFETY: plain enumeration on a live instance.
    let pds = unsafe { instance.instance.enumerate_physical_devices() }.call("vkEnumeratePhysicalDevices", String::new)?;
    Ok(pds.into_iter().map(|pd| describe(&instance.instance, pd)).collect())
}

/// Picks a device by name (substring, case-insensitive) or by type preference.
fn pick(instance: &Instance, wanted: Option<&str>) -> VkResult<(vk::PhysicalDevice, DeviceInfo)> {
    // SAFETY: plain enumeration on a live instance.
    let pds = unsafe { instance.instance.enumerate_physical_devices() }.call("vkEnumeratePhysicalDevices", String::new)?;
    if pds.is_empty() {
        return Err(VkError::NoDevice(
            "the Vulkan loader reports no physical device; install a driver (apt-get install mesa-vulkan-drivers for lavapipe) or check VK_DRIVER_FILES / VK_ICD_FILENAMES".into(),
        ));
    }
    let infos: Vec<(vk::PhysicalDevice, DeviceInfo)> = pds.into_iter().map(|pd| (pd, describe(&instance.instance, pd))).collect();
    let available = infos.iter().map(|(_, i)| format!("'{}' ({})", i.name, i.kind)).collect::<Vec<_>>().join(", ");
    if let Some(w) = wanted.filter(|w| !w.is_empty()) {
        let lw = w.to_lowercase();
        let (pd, info) = infos.into_iter().find(|(_, i)| i.name.to_lowercase().contains(&lw)).ok_or(VkError::DeviceNotFound { wanted: w.into(), available })?;
        if let Err(m) = &info.usable {
            return Err(VkError::Unsupported { device: info.name.clone(), missing: m.clone() });
        }
        return Ok((pd, info));
    }
    let mut usable: Vec<_> = infos.iter().filter(|(_, i)| i.usable.is_ok()).cloned().collect();
    usable.sort_by_key(|(_, i)| i.rank);
    usable.into_iter().next().ok_or_else(|| {
        let why = infos.iter().map(|(_, i)| format!("'{}': {}", i.name, i.usable.clone().err().unwrap_or_default())).collect::<Vec<_>>().join("; ");
        VkError::NoDevice(format!("no device supports Vulkan 1.3 with what we need ({why})"))
    })
}

/// Options for [`Device::new`].
#[derive(Clone, Debug, Default)]
pub struct DeviceOptions {
    /// Device name substring; `None` = `FABRIC_DEVICE` or automatic choice.
    pub name: Option<String>,
    pub instance: InstanceOptions,
    /// Extra device extensions (e.g. the swapchain).
    pub extensions: Vec<std::ffi::CString>,
}

/// The logical device with its queue, allocator and command pool. Shared as
/// `Arc<Device>` by every resource, so it outlives them all.
pub struct Device {
    pub(crate) raw: ash::Device,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) info: DeviceInfo,
    pub(crate) queue: Mutex<vk::Queue>,
    pub(crate) queue_family: u32,
    pub(crate) command_pool: Mutex<vk::CommandPool>,
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) debug_utils: Option<ash::ext::debug_utils::Device>,
    pub(crate) instance: Arc<Instance>,
}

impl Device {
    pub fn new(options: &DeviceOptions) -> VkResult<Arc<Device>> {
        let instance = Instance::new(&options.instance)?;
        let env_name = std::env::var("FABRIC_DEVICE").ok();
        let wanted = options.name.as_deref().or(env_name.as_deref());
        let (physical, info) = pick(&instance, wanted)?;

        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default().queue_family_index(info.queue_family).queue_priorities(&priorities)];
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default().dynamic_rendering(true).synchronization2(true).maintenance4(true);
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut supported12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut supported = vk::PhysicalDeviceFeatures2::default().push_next(&mut supported12);
        // SAFETY: querying features of a device of this instance.
        unsafe { instance.instance.get_physical_device_features2(physical, &mut supported) };
        f12.host_query_reset = supported12.host_query_reset;
        let base = vk::PhysicalDeviceFeatures::default();
        let ext_ptrs: Vec<_> = options.extensions.iter().map(|e| e.as_ptr()).collect();
        let create = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&ext_ptrs)
            .enabled_features(&base)
            .push_next(&mut f13)
            .push_next(&mut f12);
        // SAFETY: the physical device belongs to `instance`; the create info refers to locals.
        let raw = unsafe { instance.instance.create_device(physical, &create, None) }.call("vkCreateDevice", || info.name.clone())?;
        // SAFETY: family/index 0 were requested above.
        let queue = unsafe { raw.get_device_queue(info.queue_family, 0) };
        let pool_info = vk::CommandPoolCreateInfo::default().queue_family_index(info.queue_family).flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: live device.
        let command_pool = match unsafe { raw.create_command_pool(&pool_info, None) } {
            Ok(p) => p,
            Err(result) => {
                // SAFETY: nothing else was created on this device.
                unsafe { raw.destroy_device(None) };
                return Err(VkError::Call { call: "vkCreateCommandPool", result, context: info.name.clone() });
            }
        };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.instance.clone(),
            device: raw.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: only the pool exists on this device.
                unsafe {
                    raw.destroy_command_pool(command_pool, None);
                    raw.destroy_device(None);
                }
                return Err(VkError::Allocation { name: "allocator".into(), bytes: 0, source });
            }
        };
        let debug_utils = instance.debug_utils_device(&raw);
        Ok(Arc::new(Device {
            raw,
            physical,
            queue_family: info.queue_family,
            info,
            queue: Mutex::new(queue),
            command_pool: Mutex::new(command_pool),
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            debug_utils,
            instance,
        }))
    }

    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    pub fn instance(&self) -> &Arc<Instance> {
        &self.instance
    }

    pub fn raw(&self) -> &ash::Device {
        &self.raw
    }

    pub fn physical(&self) -> vk::PhysicalDevice {
        self.physical
    }

    pub fn queue_family(&self) -> u32 {
        self.queue_family
    }

    /// Validation errors reported so far on this device's instance.
    pub fn validation_errors(&self) -> Vec<String> {
        self.instance.validation_errors()
    }

    /// Gives a Vulkan object a debug name (shown in validation messages).
    pub(crate) fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(du) = &self.debug_utils {
            let Ok(cname) = std::ffi::CString::new(name.replace('\0', "")) else { return };
            let info = vk::DebugUtilsObjectNameInfoEXT::default().object_handle(handle).object_name(&cname);
            // SAFETY: the handle belongs to this device; naming failure is harmless.
            let _ = unsafe { du.set_debug_utils_object_name(&info) };
        }
    }

    pub(crate) fn allocator(&self) -> std::sync::MutexGuard<'_, Allocator> {
        // A poisoned lock means another thread panicked mid-allocation; the allocator's
        // bookkeeping is still consistent enough to keep freeing.
        self.allocator.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Records commands with `record`, submits them and waits for completion.
    pub fn run_commands<R>(&self, label: &str, record: impl FnOnce(vk::CommandBuffer) -> R) -> VkResult<R> {
        let pool = self.command_pool.lock().unwrap_or_else(|e| e.into_inner());
        let alloc = vk::CommandBufferAllocateInfo::default().command_pool(*pool).level(vk::CommandBufferLevel::PRIMARY).command_buffer_count(1);
        // SAFETY: the pool is externally synchronized by the mutex held until the end.
        let cb = unsafe { self.raw.allocate_command_buffers(&alloc) }.call("vkAllocateCommandBuffers", || label.into())?[0];
        let result = (|| {
            let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: fresh command buffer from our pool.
            unsafe { self.raw.begin_command_buffer(cb, &begin) }.call("vkBeginCommandBuffer", || label.into())?;
            let out = record(cb);
            // SAFETY: recording started above.
            unsafe { self.raw.end_command_buffer(cb) }.call("vkEndCommandBuffer", || label.into())?;
            self.submit_and_wait(cb, label)?;
            Ok(out)
        })();
        // SAFETY: the command buffer is no longer executing (waited or never submitted).
        unsafe { self.raw.free_command_buffers(*pool, &[cb]) };
        result
    }

    fn submit_and_wait(&self, cb: vk::CommandBuffer, label: &str) -> VkResult<()> {
        let fence = super::sync::Fence::new(self, label)?;
        let cbs = [vk::CommandBufferSubmitInfo::default().command_buffer(cb)];
        let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cbs)];
        {
            let queue = self.queue.lock().unwrap_or_else(|e| e.into_inner());
            // SAFETY: the queue is externally synchronized by the mutex; cb is executable.
            unsafe { self.raw.queue_submit2(*queue, &submit, fence.raw) }.call("vkQueueSubmit2", || label.into())?;
        }
        fence.wait(label)
    }

    /// Waits until the device is idle.
    pub fn wait_idle(&self) -> VkResult<()> {
        // SAFETY: live device.
        unsafe { self.raw.device_wait_idle() }.call("vkDeviceWaitIdle", String::new)
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: every resource holds an Arc<Device>, so none is alive now. Wait for
        // the GPU, then free the allocator's memory blocks before the device goes.
        unsafe {
            let _ = self.raw.device_wait_idle();
            ManuallyDrop::drop(&mut self.allocator);
            let pool = self.command_pool.get_mut().map(|p| *p).unwrap_or_else(|e| *e.into_inner());
            self.raw.destroy_command_pool(pool, None);
            self.raw.destroy_device(None);
        }
    }
}
