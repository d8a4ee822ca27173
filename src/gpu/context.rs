//! Instance creation, device selection and the shared device context (queue, allocator, canary).

use std::ffi::{c_void, CStr, CString};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::error::{vk_err, GpuError};
use super::fault::{Faults, Injector};

/// How long one submission may run before the device counts as hung. The renderer keeps each
/// submission to a bounded amount of work (see `render::state`), seconds on a CPU driver.
pub const FENCE_TIMEOUT: Duration = Duration::from_secs(120);

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Which physical device to use.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum DeviceSelector {
    /// Prefer a discrete GPU, then an integrated one, then anything else (lavapipe last).
    #[default]
    Auto,
    /// Index in the order `caustica devices` prints.
    Index(usize),
    /// Case-insensitive substring of the device name.
    Name(String),
}

impl DeviceSelector {
    pub fn parse(text: &str) -> Self {
        match text.parse::<usize>() {
            Ok(i) => DeviceSelector::Index(i),
            Err(_) if text.is_empty() || text == "auto" => DeviceSelector::Auto,
            Err(_) => DeviceSelector::Name(text.to_string()),
        }
    }
}

/// How to create a [`Context`].
#[derive(Clone, Debug, Default)]
pub struct ContextDesc {
    pub device: DeviceSelector,
    /// Enable the Khronos validation layer and count its errors. When the layer is missing
    /// the context is created without it unless `require_validation` is set.
    pub validation: bool,
    pub require_validation: bool,
    /// Faults to inject (tests); empty in normal use.
    pub faults: Faults,
    /// Longest wait for one submission; [`FENCE_TIMEOUT`] unless set.
    pub fence_timeout: Option<Duration>,
}

impl ContextDesc {
    /// Validation from the environment: `CAUSTICA_VALIDATION=1` enables it,
    /// `CAUSTICA_VALIDATION=require` also fails when the layer is not installed.
    /// `CAUSTICA_FAULT` injects faults (see [`Faults`]); a malformed value is ignored with a
    /// warning.
    pub fn from_env(device: DeviceSelector) -> Self {
        let v = std::env::var("CAUSTICA_VALIDATION").unwrap_or_default();
        let faults = match std::env::var("CAUSTICA_FAULT") {
            Ok(spec) => Faults::parse(&spec).unwrap_or_else(|e| {
                log::warn!("CAUSTICA_FAULT ignored: {e}");
                Faults::default()
            }),
            Err(_) => Faults::default(),
        };
        ContextDesc {
            device,
            validation: matches!(v.as_str(), "1" | "require" | "true"),
            require_validation: v == "require",
            faults,
            fence_timeout: None,
        }
    }
}

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
struct Canary {
    errors: AtomicU64,
    messages: Mutex<Vec<String>>,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: `user` is the `Canary` boxed inside the `Context`, which outlives the messenger;
    // `data` is valid for the duration of the call per the Vulkan spec.
    let canary = &*(user as *const Canary);
    let message = if data.is_null() || (*data).p_message.is_null() {
        String::from("(no message)")
    } else {
        CStr::from_ptr((*data).p_message).to_string_lossy().into_owned()
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

/// The device, its compute queue and allocator. Shared as `Arc<Context>`.
pub struct Context {
    pub(crate) entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) device: ash::Device,
    pub(crate) queue: vk::Queue,
    pub(crate) queue_family: u32,
    pub(crate) command_pool: Mutex<vk::CommandPool>,
    pub(crate) allocator: Mutex<Option<Allocator>>,
    pub(crate) debug_instance: Option<ash::ext::debug_utils::Instance>,
    pub(crate) debug_device: Option<ash::ext::debug_utils::Device>,
    messenger: vk::DebugUtilsMessengerEXT,
    canary: Box<Canary>,
    pub(crate) properties: vk::PhysicalDeviceProperties,
    pub info: DeviceInfo,
    pub validation_enabled: bool,
    pub(crate) injector: Injector,
    pub(crate) fence_timeout: Duration,
    /// Set once the device reported loss or a submission timed out: later submissions fail
    /// at once instead of waiting on a device that will not answer.
    lost: AtomicBool,
    /// Set when a submission timed out: its work may still be running, so objects it uses are
    /// leaked rather than destroyed under it.
    hung: AtomicBool,
}

fn load_entry() -> Result<ash::Entry, GpuError> {
    // SAFETY: loading the system Vulkan loader library; no Vulkan calls are made yet.
    unsafe { ash::Entry::load() }.map_err(|e| GpuError::NoLoader(e.to_string()))
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

fn kind_rank(t: vk::PhysicalDeviceType) -> u32 {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    }
}

fn create_instance(entry: &ash::Entry, validation: bool) -> Result<ash::Instance, GpuError> {
    let app_name = c"caustica";
    let app = vk::ApplicationInfo::default()
        .application_name(app_name)
        .engine_name(app_name)
        .api_version(vk::API_VERSION_1_3);
    let mut extensions = Vec::new();
    // SAFETY: plain enumeration queries on a loaded entry.
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

fn describe(instance: &ash::Instance, index: usize, pd: vk::PhysicalDevice) -> (DeviceInfo, Option<u32>) {
    // SAFETY: `pd` was returned by this instance.
    let props = unsafe { instance.get_physical_device_properties(pd) };
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    let family = families
        .iter()
        .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
        .map(|i| i as u32);
    let v = props.api_version;
    let name = props
        .device_name_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|_| "(unnamed)".into());
    let info = DeviceInfo {
        index,
        name,
        kind: kind_name(props.device_type).to_string(),
        api_version: format!(
            "{}.{}.{}",
            vk::api_version_major(v),
            vk::api_version_minor(v),
            vk::api_version_patch(v)
        ),
        usable: family.is_some() && v >= vk::API_VERSION_1_3,
        max_image_3d: props.limits.max_image_dimension3_d,
        max_image_2d: props.limits.max_image_dimension2_d,
    };
    (info, family)
}

/// Lists every physical device the loader reports, usable or not.
pub fn list_devices() -> Result<Vec<DeviceInfo>, GpuError> {
    let entry = load_entry()?;
    let instance = create_instance(&entry, false)?;
    // SAFETY: instance is valid; destroyed before returning.
    let result = unsafe { instance.enumerate_physical_devices() }
        .map_err(vk_err("vkEnumeratePhysicalDevices"))
        .map(|pds| {
            pds.iter()
                .enumerate()
                .map(|(i, pd)| describe(&instance, i, *pd).0)
                .collect()
        });
    unsafe { instance.destroy_instance(None) };
    result
}

impl Context {
    pub fn new(desc: &ContextDesc) -> Result<Arc<Context>, GpuError> {
        let entry = load_entry()?;
        let mut validation = desc.validation && validation_layer_present(&entry);
        if desc.validation && !validation {
            if desc.require_validation {
                return Err(GpuError::NoDevice(
                    " with validation: the Khronos validation layer is not installed (apt-get install vulkan-validationlayers)".into(),
                ));
            }
            log::warn!("validation requested but VK_LAYER_KHRONOS_validation is not installed");
        }
        let instance = create_instance(&entry, validation)?;
        let canary = Box::<Canary>::default();
        let debug_instance = Some(ash::ext::debug_utils::Instance::new(&entry, &instance));
        let mut messenger = vk::DebugUtilsMessengerEXT::null();
        if validation {
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
                .user_data(&*canary as *const Canary as *mut c_void);
            // SAFETY: the canary box outlives the messenger (destroyed first in Drop).
            match unsafe {
                debug_instance
                    .as_ref()
                    .map(|d| d.create_debug_utils_messenger(&info, None))
            } {
                Some(Ok(m)) => messenger = m,
                _ => validation = false,
            }
        }

        let cleanup_instance = |instance: &ash::Instance| unsafe {
            if messenger != vk::DebugUtilsMessengerEXT::null() {
                if let Some(d) = &debug_instance {
                    d.destroy_debug_utils_messenger(messenger, None);
                }
            }
            instance.destroy_instance(None);
        };

        // SAFETY: instance is valid.
        let pds = match unsafe { instance.enumerate_physical_devices() } {
            Ok(p) => p,
            Err(e) => {
                cleanup_instance(&instance);
                return Err(GpuError::vk("vkEnumeratePhysicalDevices", e));
            }
        };
        let described: Vec<_> = pds
            .iter()
            .enumerate()
            .map(|(i, pd)| (describe(&instance, i, *pd), *pd))
            .collect();
        let available = described
            .iter()
            .map(|((d, _), _)| format!("[{}] {} ({})", d.index, d.name, d.kind))
            .collect::<Vec<_>>()
            .join(", ");
        let chosen = match &desc.device {
            DeviceSelector::Auto => described.iter().filter(|((d, _), _)| d.usable).min_by_key(|(_, pd)| {
                let props = unsafe { instance.get_physical_device_properties(*pd) };
                kind_rank(props.device_type)
            }),
            DeviceSelector::Index(i) => described.iter().find(|((d, _), _)| d.index == *i),
            DeviceSelector::Name(n) => described
                .iter()
                .find(|((d, _), _)| d.name.to_lowercase().contains(&n.to_lowercase())),
        };
        let ((info, family), physical) = match chosen {
            Some(((info, Some(family)), pd)) if info.usable => ((info.clone(), *family), *pd),
            Some(((info, _), _)) => {
                cleanup_instance(&instance);
                return Err(GpuError::NoDevice(format!(
                    " ('{}' reports Vulkan {} or has no compute queue)",
                    info.name, info.api_version
                )));
            }
            None => {
                cleanup_instance(&instance);
                return Err(match &desc.device {
                    DeviceSelector::Auto => GpuError::NoDevice(if available.is_empty() {
                        String::new()
                    } else {
                        format!(" (seen: {available})")
                    }),
                    DeviceSelector::Index(i) => GpuError::DeviceNotFound {
                        wanted: i.to_string(),
                        available,
                    },
                    DeviceSelector::Name(n) => GpuError::DeviceNotFound {
                        wanted: n.clone(),
                        available,
                    },
                });
            }
        };
        let properties = unsafe { instance.get_physical_device_properties(physical) };

        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let device_info = vk::DeviceCreateInfo::default().queue_create_infos(&queue_info);
        // SAFETY: physical device and create info are valid for this instance.
        let device = match unsafe { instance.create_device(physical, &device_info, None) } {
            Ok(d) => d,
            Err(e) => {
                cleanup_instance(&instance);
                return Err(GpuError::vk("vkCreateDevice", e));
            }
        };
        let queue = unsafe { device.get_device_queue(family, 0) };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let command_pool = match unsafe { device.create_command_pool(&pool_info, None) } {
            Ok(p) => p,
            Err(e) => {
                unsafe { device.destroy_device(None) };
                cleanup_instance(&instance);
                return Err(GpuError::vk("vkCreateCommandPool", e));
            }
        };
        let allocator = match Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        }) {
            Ok(a) => a,
            Err(e) => {
                unsafe {
                    device.destroy_command_pool(command_pool, None);
                    device.destroy_device(None);
                }
                cleanup_instance(&instance);
                return Err(GpuError::Allocation {
                    what: "allocator".into(),
                    message: e.to_string(),
                });
            }
        };
        let debug_device = Some(ash::ext::debug_utils::Device::new(&instance, &device));
        let ctx = Context {
            entry,
            instance,
            physical,
            device,
            queue,
            queue_family: family,
            command_pool: Mutex::new(command_pool),
            allocator: Mutex::new(Some(allocator)),
            debug_instance,
            debug_device,
            messenger,
            canary,
            properties,
            info,
            validation_enabled: validation,
            injector: Injector::new(desc.faults.clone()),
            fence_timeout: desc.fence_timeout.unwrap_or(FENCE_TIMEOUT),
            lost: AtomicBool::new(false),
            hung: AtomicBool::new(false),
        };
        ctx.set_name(command_pool, "caustica command pool");
        ctx.set_name(queue, "caustica compute queue");
        if desc.faults.validation_error {
            ctx.provoke_validation_error();
        }
        Ok(Arc::new(ctx))
    }

    /// True once the device was lost (or hung): nothing more can run on it.
    pub fn is_lost(&self) -> bool {
        self.lost.load(Ordering::SeqCst)
    }

    pub(crate) fn mark_lost(&self, hung: bool) {
        self.lost.store(true, Ordering::SeqCst);
        if hung {
            self.hung.store(true, Ordering::SeqCst);
        }
    }

    /// True when work may still be executing on a device that stopped answering.
    pub(crate) fn is_hung(&self) -> bool {
        self.hung.load(Ordering::SeqCst)
    }

    /// Number of validation errors reported so far (always 0 without validation).
    pub fn validation_errors(&self) -> u64 {
        self.canary.errors.load(Ordering::SeqCst)
    }

    /// Makes one deliberately invalid Vulkan call (a sampler with anisotropy, a feature this
    /// crate never enables) so tests can check that the validation canary counts errors.
    /// Returns the number of errors recorded by that call.
    #[doc(hidden)]
    pub fn provoke_validation_error(&self) -> u64 {
        let before = self.validation_errors();
        let info = vk::SamplerCreateInfo::default()
            .anisotropy_enable(true)
            .max_anisotropy(4.0);
        // SAFETY: lavapipe and other drivers accept the call (anisotropy is widely supported);
        // only the validation layer objects because the feature was not enabled. The sampler
        // is destroyed at once.
        if let Ok(s) = unsafe { self.device.create_sampler(&info, None) } {
            unsafe { self.device.destroy_sampler(s, None) };
        }
        self.validation_errors() - before
    }

    /// The validation messages reported so far.
    pub fn validation_messages(&self) -> Vec<String> {
        self.canary.messages.lock().map(|m| m.clone()).unwrap_or_default()
    }

    /// Gives `object` a debug name; silently ignored where debug utils are unavailable.
    pub(crate) fn set_name<H: vk::Handle>(&self, object: H, name: &str) {
        let Some(d) = &self.debug_device else { return };
        let Ok(name) = CString::new(name.replace('\0', " ")) else {
            return;
        };
        let info = vk::DebugUtilsObjectNameInfoEXT::default()
            .object_handle(object)
            .object_name(&name);
        // SAFETY: `object` is a live handle of this device; naming has no other effect.
        let _ = unsafe { d.set_debug_utils_object_name(&info) };
    }

    pub fn limits(&self) -> &vk::PhysicalDeviceLimits {
        &self.properties.limits
    }

    /// Size of the largest device-local memory heap in bytes (system memory on CPU drivers).
    pub fn device_local_bytes(&self) -> u64 {
        // SAFETY: plain query on a valid physical device.
        let props = unsafe { self.instance.get_physical_device_memory_properties(self.physical) };
        let count = (props.memory_heap_count as usize).min(props.memory_heaps.len());
        props.memory_heaps[..count]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(0)
    }

    /// Nanoseconds per timestamp tick.
    pub fn timestamp_period_ns(&self) -> f64 {
        self.properties.limits.timestamp_period as f64
    }

    pub(crate) fn format_features(&self, format: vk::Format) -> vk::FormatFeatureFlags {
        // SAFETY: plain query on a valid physical device.
        unsafe {
            self.instance
                .get_physical_device_format_properties(self.physical, format)
        }
        .optimal_tiling_features
    }

    #[allow(dead_code)]
    pub(crate) fn entry(&self) -> &ash::Entry {
        &self.entry
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: every resource holds an Arc<Context>, so nothing created from this device is
        // alive any more. Order: idle, allocator (frees its memory blocks), pool, device,
        // messenger, instance. After a timeout the device may still be executing: leak it all
        // (the process is about to report the error) rather than wait forever or free memory
        // in use.
        if self.is_hung() {
            // The allocator's memory blocks and the canary (the debug messenger's user data)
            // may still be touched by the running work and the driver: leak them too.
            if let Ok(mut a) = self.allocator.lock() {
                std::mem::forget(a.take());
            }
            std::mem::forget(std::mem::take(&mut self.canary));
            return;
        }
        unsafe {
            let _ = self.device.device_wait_idle();
            if let Ok(mut a) = self.allocator.lock() {
                a.take();
            }
            if let Ok(pool) = self.command_pool.lock() {
                self.device.destroy_command_pool(*pool, None);
            }
            self.device.destroy_device(None);
            if self.messenger != vk::DebugUtilsMessengerEXT::null() {
                if let Some(d) = &self.debug_instance {
                    d.destroy_debug_utils_messenger(self.messenger, None);
                }
            }
            self.instance.destroy_instance(None);
        }
    }
}
