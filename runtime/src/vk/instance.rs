//! The Vulkan instance, the optional validation layer and its debug messenger.
//!
//! Validation is on in debug builds (which tests use) and off in release builds;
//! `FABRIC_VALIDATION=1` / `=0` overrides either way. When on and the layer is
//! installed, messages of error severity are collected in a [`ValidationLog`] so a
//! test can fail on them; warnings are printed to stderr.

use std::ffi::{CStr, CString, c_char, c_void};
use std::sync::{Arc, Mutex};

use ash::vk;

use super::error::{CallContext, VkError, VkResult};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Validation messages of error severity, in the order they arrived.
#[derive(Default, Debug)]
pub struct ValidationLog {
    errors: Mutex<Vec<String>>,
}

impl ValidationLog {
    pub fn errors(&self) -> Vec<String> {
        self.errors.lock().map(|e| e.clone()).unwrap_or_default()
    }

    fn push(&self, msg: String) {
        if let Ok(mut e) = self.errors.lock() {
            e.push(msg);
        }
    }
}

/// Whether validation should be enabled, from the build type and `FABRIC_VALIDATION`.
pub fn validation_requested() -> bool {
    match std::env::var("FABRIC_VALIDATION").ok().as_deref() {
        Some("1") | Some("true") | Some("on") => true,
        Some("0") | Some("false") | Some("off") => false,
        _ => cfg!(debug_assertions),
    }
}

/// Owns the loader entry, the `VkInstance` and the debug messenger.
pub struct Instance {
    // Dropped manually in `Drop` (messenger, then instance); the entry last, by field order.
    pub(crate) instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    /// Keeps the user-data pointer of the messenger alive.
    log: Arc<ValidationLog>,
    validation: bool,
    pub(crate) entry: ash::Entry,
}

/// Options for [`Instance::new`].
#[derive(Clone, Debug, Default)]
pub struct InstanceOptions {
    /// Force validation on or off; `None` = [`validation_requested`].
    pub validation: Option<bool>,
    /// Extra instance extensions (e.g. the surface extensions of a window system).
    pub extensions: Vec<CString>,
}

impl Instance {
    pub fn new(options: &InstanceOptions) -> VkResult<Arc<Instance>> {
        // SAFETY: loading the system's libvulkan; its symbols are resolved by ash.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::LoaderMissing(e.to_string()))?;
        let want_validation = options.validation.unwrap_or_else(validation_requested);
        // SAFETY: plain enumeration call on a loaded entry.
        let layers = unsafe { entry.enumerate_instance_layer_properties() }.call("vkEnumerateInstanceLayerProperties", String::new)?;
        let has_layer = layers.iter().any(|l| l.layer_name_as_c_str().ok() == Some(VALIDATION_LAYER));
        let validation = want_validation && has_layer;
        if want_validation && !has_layer {
            eprintln!("note: Vulkan validation requested but VK_LAYER_KHRONOS_validation is not installed (apt-get install vulkan-validationlayers); running without it");
        }

        let app = vk::ApplicationInfo::default()
            .application_name(c"fabric")
            .application_version(1)
            .engine_name(c"fabric-runtime")
            .api_version(vk::API_VERSION_1_3);
        let mut ext_ptrs: Vec<*const c_char> = options.extensions.iter().map(|e| e.as_ptr()).collect();
        let layer_ptrs: Vec<*const c_char> = if validation { vec![VALIDATION_LAYER.as_ptr()] } else { vec![] };
        if validation {
            ext_ptrs.push(ash::ext::debug_utils::NAME.as_ptr());
        }
        let log = Arc::new(ValidationLog::default());
        let mut messenger_info = messenger_create_info(&log);
        let mut info = vk::InstanceCreateInfo::default().application_info(&app).enabled_extension_names(&ext_ptrs).enabled_layer_names(&layer_ptrs);
        if validation {
            // Also catches messages from vkCreateInstance/vkDestroyInstance themselves.
            info = info.push_next(&mut messenger_info);
        }
        // SAFETY: every pointer in `info` refers to locals alive for this call.
        let instance = unsafe { entry.create_instance(&info, None) }.map_err(|result| match result {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => VkError::NoDevice(format!(
                "the Vulkan loader found no compatible driver (vkCreateInstance: {result}); install one (apt-get install mesa-vulkan-drivers) or check VK_DRIVER_FILES / VK_ICD_FILENAMES"
            )),
            _ => VkError::Call { call: "vkCreateInstance", result, context: "Vulkan 1.3 instance".into() },
        })?;
        let debug = if validation {
            let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = messenger_create_info(&log);
            // SAFETY: instance is alive; the callback's user data (`log`) outlives the messenger.
            match unsafe { du.create_debug_utils_messenger(&info, None) } {
                Ok(m) => Some((du, m)),
                Err(result) => {
                    // SAFETY: nothing else was created from this instance yet.
                    unsafe { instance.destroy_instance(None) };
                    return Err(VkError::Call { call: "vkCreateDebugUtilsMessengerEXT", result, context: "validation messenger".into() });
                }
            }
        } else {
            None
        };
        Ok(Arc::new(Instance { instance, debug, log, validation, entry }))
    }

    /// True when the validation layer is active.
    pub fn validation_enabled(&self) -> bool {
        self.validation
    }

    /// The validation errors reported so far.
    pub fn validation_errors(&self) -> Vec<String> {
        self.log.errors()
    }

    pub fn raw(&self) -> &ash::Instance {
        &self.instance
    }

    pub fn entry(&self) -> &ash::Entry {
        &self.entry
    }

    pub(crate) fn debug_utils_device(&self, device: &ash::Device) -> Option<ash::ext::debug_utils::Device> {
        self.debug.as_ref().map(|_| ash::ext::debug_utils::Device::new(&self.instance, device))
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: all devices (which hold an Arc<Instance>) are gone; destroy the
        // messenger before the instance it belongs to.
        unsafe {
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

fn messenger_create_info(log: &Arc<ValidationLog>) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING)
        .message_type(vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE)
        .pfn_user_callback(Some(debug_callback))
        .user_data(Arc::as_ptr(log) as *mut c_void)
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the loader passes valid callback data for the duration of the call; `user`
    // is the `ValidationLog` the messenger was created with, alive as long as the instance.
    let msg = unsafe {
        if data.is_null() || (*data).p_message.is_null() { String::from("(no message)") } else { CStr::from_ptr((*data).p_message).to_string_lossy().into_owned() }
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        eprintln!("vulkan validation error: {msg}");
        if !user.is_null() {
            // SAFETY: see above.
            unsafe { (*(user as *const ValidationLog)).push(msg) };
        }
    } else if !kind.contains(vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE) || std::env::var_os("FABRIC_VALIDATION_VERBOSE").is_some() {
        eprintln!("vulkan validation warning: {msg}");
    }
    vk::FALSE
}
