//! The Vulkan loader and instance, the validation canary, and what the instance says about
//! the physical devices.

use std::ffi::{c_void, CStr};
use std::ops::Deref;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use ash::vk;

use super::error::{vk_err, GpuError};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// What `caustica devices` shows about one physical device.
#[derive(Clone, Debug)]
pub struct DeviceInfo {
    pub index: usize,
    pub name: String,
    pub kind: String,
    pub api_version: String,
    pub usable: bool,
    pub max_image_3d: u32,
    pub max_image_2d: u32,
}

/// Messages collected by the debug messenger.
#[derive(Default)]
pub(crate) struct Canary {
    pub(crate) errors: AtomicU64,
    pub(crate) messages: Mutex<Vec<String>>,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: `user` is the `Canary` boxed inside the `Instance`, which destroys the messenger
    // before the box; `data` and its message are valid for the duration of the call (Vulkan
    // spec of PFN_vkDebugUtilsMessengerCallbackEXT).
    let (canary, message) = unsafe {
        let canary = &*(user as *const Canary);
        let message = if data.is_null() || (*data).p_message.is_null() {
            String::from("(no message)")
        } else {
            CStr::from_ptr((*data).p_message).to_string_lossy().into_owned()
        };
        (canary, message)
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        canary.errors.fetch_add(1, Ordering::SeqCst);
        eprintln!("[vulkan validation error] {message}");
        if let Ok(mut m) = canary.messages.lock() {
            m.push(message);
        }
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        log::warn!("[vulkan] {message}");
    }
    vk::FALSE
}

/// The loaded Vulkan library, the instance and (with validation) its debug messenger and the
/// canary the messenger reports to. `Drop` destroys the messenger, then the instance; the
/// library is unloaded after both.
pub(crate) struct Instance {
    raw: ash::Instance,
    pub(crate) debug_utils: ash::ext::debug_utils::Instance,
    messenger: vk::DebugUtilsMessengerEXT,
    pub(crate) canary: Box<Canary>,
    /// Kept for the lifetime of the instance: dropping it unloads the library.
    _entry: ash::Entry,
}

impl Deref for Instance {
    type Target = ash::Instance;

    fn deref(&self) -> &ash::Instance {
        &self.raw
    }
}

fn load_entry() -> Result<ash::Entry, GpuError> {
    // SAFETY: loading the system Vulkan loader library runs its initialisers only; no Vulkan
    // call is made yet, and the returned entry keeps the library loaded.
    unsafe { ash::Entry::load() }.map_err(|e| GpuError::NoLoader(e.to_string()))
}

fn validation_layer_present(entry: &ash::Entry) -> bool {
    // SAFETY: enumeration query on a loaded entry.
    unsafe { entry.enumerate_instance_layer_properties() }
        .map(|layers| {
            layers
                .iter()
                .any(|l| l.layer_name_as_c_str().ok() == Some(VALIDATION_LAYER))
        })
        .unwrap_or(false)
}

fn create_raw(entry: &ash::Entry, validation: bool) -> Result<ash::Instance, GpuError> {
    let app_name = c"caustica";
    let app = vk::ApplicationInfo::default()
        .application_name(app_name)
        .engine_name(app_name)
        .api_version(vk::API_VERSION_1_3);
    let mut extensions = Vec::new();
    // SAFETY: plain enumeration query on a loaded entry.
    let available = unsafe { entry.enumerate_instance_extension_properties(None) }
        .map_err(vk_err("vkEnumerateInstanceExtensionProperties"))?;
    let has_ext = |name: &CStr| available.iter().any(|e| e.extension_name_as_c_str().ok() == Some(name));
    if has_ext(ash::ext::debug_utils::NAME) {
        extensions.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    let layers = if validation {
        vec![VALIDATION_LAYER.as_ptr()]
    } else {
        vec![]
    };
    let info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_extension_names(&extensions)
        .enabled_layer_names(&layers);
    // SAFETY: all pointers in `info` reference locals that live until the call returns.
    match unsafe { entry.create_instance(&info, None) } {
        Ok(i) => Ok(i),
        Err(vk::Result::ERROR_INCOMPATIBLE_DRIVER) => {
            Err(GpuError::NoDevice(" (the loader found no compatible driver)".into()))
        }
        Err(e) => Err(GpuError::vk("vkCreateInstance", e)),
    }
}

impl Instance {
    /// Loads Vulkan and creates an instance. With `validation` the Khronos layer is enabled
    /// when installed, and a messenger counts its errors; when the layer is missing that is
    /// an error if `require_validation`, else a warning.
    pub(crate) fn new(validation: bool, require_validation: bool) -> Result<Instance, GpuError> {
        let entry = load_entry()?;
        let layer = validation && validation_layer_present(&entry);
        if validation && !layer {
            if require_validation {
                return Err(GpuError::NoDevice(
                    " with validation: the Khronos validation layer is not installed (apt-get install vulkan-validationlayers)".into(),
                ));
            }
            log::warn!("validation requested but VK_LAYER_KHRONOS_validation is not installed");
        }
        let raw = create_raw(&entry, layer)?;
        let debug_utils = ash::ext::debug_utils::Instance::new(&entry, &raw);
        let mut instance = Instance {
            raw,
            debug_utils,
            messenger: vk::DebugUtilsMessengerEXT::null(),
            canary: Box::<Canary>::default(),
            _entry: entry,
        };
        if layer {
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(debug_callback))
                .user_data(&*instance.canary as *const Canary as *mut c_void);
            // SAFETY: the canary is boxed, so its address is stable, and `Drop` destroys the
            // messenger before the box is freed.
            if let Ok(m) = unsafe { instance.debug_utils.create_debug_utils_messenger(&info, None) } {
                instance.messenger = m;
            }
        }
        Ok(instance)
    }

    /// True when the validation layer is on and its errors are counted.
    pub(crate) fn validating(&self) -> bool {
        self.messenger != vk::DebugUtilsMessengerEXT::null()
    }

    /// Every physical device with what `caustica devices` shows and its first compute queue
    /// family.
    pub(crate) fn physical_devices(&self) -> Result<Vec<PhysicalDevice>, GpuError> {
        // SAFETY: plain enumeration on a live instance.
        let pds = unsafe { self.enumerate_physical_devices() }.map_err(vk_err("vkEnumeratePhysicalDevices"))?;
        Ok(pds
            .into_iter()
            .enumerate()
            .map(|(i, pd)| self.describe(i, pd))
            .collect())
    }

    fn describe(&self, index: usize, raw: vk::PhysicalDevice) -> PhysicalDevice {
        // SAFETY: `raw` was returned by this instance.
        let properties = unsafe { self.get_physical_device_properties(raw) };
        // SAFETY: as above.
        let families = unsafe { self.get_physical_device_queue_family_properties(raw) };
        let compute_family = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
            .map(|i| i as u32);
        let v = properties.api_version;
        let name = properties
            .device_name_as_c_str()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|_| "(unnamed)".into());
        let info = DeviceInfo {
            index,
            name,
            kind: kind_name(properties.device_type).to_string(),
            api_version: format!(
                "{}.{}.{}",
                vk::api_version_major(v),
                vk::api_version_minor(v),
                vk::api_version_patch(v)
            ),
            usable: compute_family.is_some() && v >= vk::API_VERSION_1_3,
            max_image_3d: properties.limits.max_image_dimension3_d,
            max_image_2d: properties.limits.max_image_dimension2_d,
        };
        PhysicalDevice {
            raw,
            info,
            properties,
            compute_family,
        }
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: everything created from the instance holds an `Arc` of it (through the
        // device) and is gone; the messenger goes first because it refers to the canary.
        unsafe {
            if self.validating() {
                self.debug_utils.destroy_debug_utils_messenger(self.messenger, None);
            }
            self.raw.destroy_instance(None);
        }
    }
}

/// One physical device as the instance reports it.
pub(crate) struct PhysicalDevice {
    pub(crate) raw: vk::PhysicalDevice,
    pub(crate) info: DeviceInfo,
    pub(crate) properties: vk::PhysicalDeviceProperties,
    pub(crate) compute_family: Option<u32>,
}

impl PhysicalDevice {
    /// Preference of `caustica devices`' automatic choice: lower is better.
    pub(crate) fn rank(&self) -> u32 {
        match self.properties.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => 0,
            vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
            vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
            vk::PhysicalDeviceType::CPU => 3,
            _ => 4,
        }
    }
}

fn kind_name(t: vk::PhysicalDeviceType) -> &'static str {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => "discrete GPU",
        vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated GPU",
        vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual GPU",
        vk::PhysicalDeviceType::CPU => "CPU",
        _ => "other",
    }
}

/// Lists every physical device the loader reports, usable or not.
pub fn list_devices() -> Result<Vec<DeviceInfo>, GpuError> {
    let instance = Instance::new(false, false)?;
    Ok(instance.physical_devices()?.into_iter().map(|d| d.info).collect())
}
