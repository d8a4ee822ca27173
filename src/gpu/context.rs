//! The shared device context: device selection, the logical device, its compute queue,
//! command pool and memory allocator. Each Vulkan object is owned by a small RAII type that
//! holds an `Arc` of what it was created from, so a half-built context cleans up after itself
//! on any error, and destruction order never depends on field order.

use std::ffi::CString;
use std::ops::Deref;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, LockResult, Mutex, MutexGuard};
use std::time::Duration;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::error::{vk_err, GpuError};
use super::fault::{Faults, Injector};
use super::instance::{DeviceInfo, Instance, PhysicalDevice};
use super::meter::{MemoryMeter, MemoryUse};

/// How long one submission may run before the device counts as hung. The renderer keeps each
/// submission to a bounded amount of work (see `render::state`), seconds on a CPU driver.
pub const FENCE_TIMEOUT: Duration = Duration::from_secs(120);

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
    /// warning. `CAUSTICA_SUBMIT_TIMEOUT` (seconds) replaces [`FENCE_TIMEOUT`], for runs
    /// under a profiler or an instruction counter, which slow a CPU driver many times over; a
    /// value that is not a whole number of seconds from 1 to a year is ignored with a warning
    /// too.
    pub fn from_env(device: DeviceSelector) -> Self {
        let v = std::env::var("CAUSTICA_VALIDATION").unwrap_or_default();
        let faults = match std::env::var("CAUSTICA_FAULT") {
            Ok(spec) => Faults::parse(&spec).unwrap_or_else(|e| {
                log::warn!("CAUSTICA_FAULT ignored: {e}");
                Faults::default()
            }),
            Err(_) => Faults::default(),
        };
        let fence_timeout = std::env::var("CAUSTICA_SUBMIT_TIMEOUT").ok().and_then(|t| {
            submit_timeout(&t)
                .map_err(|e| log::warn!("CAUSTICA_SUBMIT_TIMEOUT ignored: {e}"))
                .ok()
        });
        ContextDesc {
            device,
            validation: matches!(v.as_str(), "1" | "require" | "true"),
            require_validation: v == "require",
            faults,
            fence_timeout,
        }
    }
}

/// The longest wait for one submission from `CAUSTICA_SUBMIT_TIMEOUT`: whole seconds, from 1
/// to a year.
fn submit_timeout(value: &str) -> Result<Duration, String> {
    const YEAR: u64 = 365 * 86_400;
    match value.trim().parse::<u64>() {
        Ok(s) if (1..=YEAR).contains(&s) => Ok(Duration::from_secs(s)),
        _ => Err(format!("'{value}' is not a whole number of seconds from 1 to {YEAR}")),
    }
}

/// The logical device. `Drop` waits for it to be idle and destroys it; it holds the instance,
/// which therefore outlives it. After a hang nothing is destroyed: the abandoned work may
/// still run, so the device and the instance (with the messenger's canary) are leaked.
pub(crate) struct Device {
    raw: ash::Device,
    instance: Arc<Instance>,
    /// Set when a submission timed out: its work may still be running, so objects it uses are
    /// leaked rather than destroyed under it.
    pub(crate) hung: AtomicBool,
}

impl Deref for Device {
    type Target = ash::Device;

    fn deref(&self) -> &ash::Device {
        &self.raw
    }
}

impl Device {
    fn new(instance: &Arc<Instance>, physical: vk::PhysicalDevice, family: u32) -> Result<Device, GpuError> {
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let device_info = vk::DeviceCreateInfo::default().queue_create_infos(&queue_info);
        // SAFETY: `physical` belongs to `instance`; the create info references locals that
        // live until the call returns.
        let raw = unsafe { instance.create_device(physical, &device_info, None) }.map_err(vk_err("vkCreateDevice"))?;
        Ok(Device {
            raw,
            instance: instance.clone(),
            hung: AtomicBool::new(false),
        })
    }

    pub(crate) fn is_hung(&self) -> bool {
        self.hung.load(Ordering::SeqCst)
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        if self.is_hung() {
            // Keeps the instance (and the canary the driver may still report to) alive for good.
            std::mem::forget(self.instance.clone());
            return;
        }
        // SAFETY: every object created from the device holds an `Arc` of it (directly or
        // through the `Context`) and is gone; waiting for idle covers work nobody waited for.
        unsafe {
            let _ = self.raw.device_wait_idle();
            self.raw.destroy_device(None);
        }
    }
}

/// The command pool the recorders allocate from (locked while allocating or freeing).
pub(crate) struct CommandPool {
    raw: Mutex<vk::CommandPool>,
    device: Arc<Device>,
}

impl CommandPool {
    fn new(device: &Arc<Device>, family: u32) -> Result<CommandPool, GpuError> {
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid create info for a live device; destroyed in Drop.
        let raw = unsafe { device.create_command_pool(&info, None) }.map_err(vk_err("vkCreateCommandPool"))?;
        Ok(CommandPool {
            raw: Mutex::new(raw),
            device: device.clone(),
        })
    }

    pub(crate) fn lock(&self) -> LockResult<MutexGuard<'_, vk::CommandPool>> {
        self.raw.lock()
    }
}

impl Drop for CommandPool {
    fn drop(&mut self) {
        if self.device.is_hung() {
            return; // its command buffers may still be executing: leak
        }
        if let Ok(pool) = self.raw.lock() {
            // SAFETY: every recorder holds an `Arc<Context>`, so no command buffer of the
            // pool is alive or pending.
            unsafe { self.device.destroy_command_pool(*pool, None) };
        }
    }
}

/// The memory allocator; `Drop` frees its memory blocks (leaks them after a hang).
pub(crate) struct MemoryAllocator {
    raw: Mutex<Option<Allocator>>,
    device: Arc<Device>,
    /// Bytes allocated now and at the peak (`meter.rs`).
    pub(crate) meter: MemoryMeter,
}

impl MemoryAllocator {
    fn new(instance: &Instance, device: &Arc<Device>, physical: vk::PhysicalDevice) -> Result<Self, GpuError> {
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: (**instance).clone(),
            device: (***device).clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| GpuError::Allocation {
            what: "allocator".into(),
            message: e.to_string(),
        })?;
        Ok(MemoryAllocator {
            raw: Mutex::new(Some(allocator)),
            device: device.clone(),
            meter: MemoryMeter::default(),
        })
    }

    pub(crate) fn lock(&self) -> LockResult<MutexGuard<'_, Option<Allocator>>> {
        self.raw.lock()
    }
}

impl Drop for MemoryAllocator {
    fn drop(&mut self) {
        let allocator = self.raw.get_mut().ok().and_then(Option::take);
        if self.device.is_hung() {
            // The memory blocks may still be touched by the running work.
            std::mem::forget(allocator);
        }
    }
}

/// The device, its compute queue and allocator. Shared as `Arc<Context>`.
pub struct Context {
    pub(crate) instance: Arc<Instance>,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) device: Arc<Device>,
    pub(crate) queue: vk::Queue,
    pub(crate) queue_family: u32,
    pub(crate) command_pool: CommandPool,
    pub(crate) allocator: MemoryAllocator,
    debug_utils: ash::ext::debug_utils::Device,
    pub(crate) properties: vk::PhysicalDeviceProperties,
    pub info: DeviceInfo,
    pub validation_enabled: bool,
    pub(crate) injector: Injector,
    pub(crate) fence_timeout: Duration,
    /// Set once the device reported loss or a submission timed out: later submissions fail
    /// at once instead of waiting on a device that will not answer.
    lost: AtomicBool,
}

/// Picks the physical device `selector` asks for, or says why none fits.
fn choose(devices: Vec<PhysicalDevice>, selector: &DeviceSelector) -> Result<(PhysicalDevice, u32), GpuError> {
    let available = devices
        .iter()
        .map(|d| format!("[{}] {} ({})", d.info.index, d.info.name, d.info.kind))
        .collect::<Vec<_>>()
        .join(", ");
    let chosen = match selector {
        DeviceSelector::Auto => devices
            .into_iter()
            .filter(|d| d.info.usable)
            .min_by_key(PhysicalDevice::rank),
        DeviceSelector::Index(i) => devices.into_iter().find(|d| d.info.index == *i),
        DeviceSelector::Name(n) => devices
            .into_iter()
            .find(|d| d.info.name.to_lowercase().contains(&n.to_lowercase())),
    };
    match chosen {
        Some(d) => match d.compute_family {
            Some(family) if d.info.usable => Ok((d, family)),
            _ => Err(GpuError::NoDevice(format!(
                " ('{}' reports Vulkan {} or has no compute queue)",
                d.info.name, d.info.api_version
            ))),
        },
        None => Err(match selector {
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
        }),
    }
}

impl Context {
    pub fn new(desc: &ContextDesc) -> Result<Arc<Context>, GpuError> {
        let instance = Arc::new(Instance::new(desc.validation, desc.require_validation)?);
        let (physical, family) = choose(instance.physical_devices()?, &desc.device)?;
        let device = Arc::new(Device::new(&instance, physical.raw, family)?);
        // SAFETY: the device was created with one queue of `family`.
        let queue = unsafe { device.get_device_queue(family, 0) };
        let command_pool = CommandPool::new(&device, family)?;
        let allocator = MemoryAllocator::new(&instance, &device, physical.raw)?;
        let debug_utils = ash::ext::debug_utils::Device::new(&instance, &device);
        let ctx = Context {
            validation_enabled: instance.validating(),
            instance,
            physical: physical.raw,
            device,
            queue,
            queue_family: family,
            command_pool,
            allocator,
            debug_utils,
            properties: physical.properties,
            info: physical.info,
            injector: Injector::new(desc.faults.clone()),
            fence_timeout: desc.fence_timeout.unwrap_or(FENCE_TIMEOUT),
            lost: AtomicBool::new(false),
        };
        if let Ok(pool) = ctx.command_pool.lock() {
            ctx.set_name(*pool, "caustica command pool");
        }
        ctx.set_name(queue, "caustica compute queue");
        if desc.faults.validation_error {
            ctx.provoke_validation_error();
        }
        Ok(Arc::new(ctx))
    }

    /// Bytes of every buffer and image allocated through this context now.
    pub fn memory_in_use(&self) -> MemoryUse {
        self.allocator.meter.in_use()
    }

    /// The most memory allocated at once since [`Context::reset_memory_peak`] (or since the
    /// context was created): each class's own peak, and the peak of their sum. Everything
    /// allocated through the context counts, by whichever thread.
    pub fn memory_peak(&self) -> (MemoryUse, u64) {
        self.allocator.meter.peak()
    }

    /// Starts a new peak at what is allocated now.
    pub fn reset_memory_peak(&self) {
        self.allocator.meter.reset_peak()
    }

    /// True once the device was lost (or hung): nothing more can run on it.
    pub fn is_lost(&self) -> bool {
        self.lost.load(Ordering::SeqCst)
    }

    pub(crate) fn mark_lost(&self, hung: bool) {
        self.lost.store(true, Ordering::SeqCst);
        if hung {
            self.device.hung.store(true, Ordering::SeqCst);
        }
    }

    /// True when work may still be executing on a device that stopped answering.
    pub(crate) fn is_hung(&self) -> bool {
        self.device.is_hung()
    }

    /// Number of validation errors reported so far (always 0 without validation).
    pub fn validation_errors(&self) -> u64 {
        self.instance.canary.errors.load(Ordering::SeqCst)
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
            // SAFETY: the sampler was just created and is used by nothing.
            unsafe { self.device.destroy_sampler(s, None) };
        }
        self.validation_errors() - before
    }

    /// The validation messages reported so far.
    pub fn validation_messages(&self) -> Vec<String> {
        self.instance
            .canary
            .messages
            .lock()
            .map(|m| m.clone())
            .unwrap_or_default()
    }

    /// Gives `object` a debug name; silently ignored where debug utils are unavailable.
    pub(crate) fn set_name<H: vk::Handle>(&self, object: H, name: &str) {
        let d = &self.debug_utils;
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

    /// Whether the device is a CPU driver (lavapipe), whose shaders run the invocations of a
    /// batch in SIMD lanes: it gathers texel fetches, and loads a storage buffer at an
    /// address that varies between them invocation by invocation.
    pub fn is_cpu(&self) -> bool {
        self.properties.device_type == vk::PhysicalDeviceType::CPU
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_submit_timeout_is_whole_seconds_from_one_to_a_year() {
        assert_eq!(submit_timeout("600"), Ok(Duration::from_secs(600)));
        assert_eq!(submit_timeout(" 1 "), Ok(Duration::from_secs(1)));
        assert_eq!(submit_timeout("31536000"), Ok(Duration::from_secs(31_536_000)));
        for bad in [
            "0",
            "-5",
            "2.5",
            "abc",
            "",
            "inf",
            "NaN",
            "31536001",
            "99999999999999999999",
        ] {
            let e = submit_timeout(bad).expect_err(bad);
            assert!(e.contains(&format!("'{bad}'")), "{bad}: {e}");
        }
    }
}
