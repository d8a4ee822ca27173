//! Errors of the gpu layer: one enum, each Vulkan failure mapped once to a message a user can act on.

use ash::vk;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no Vulkan loader found ({0}); install a Vulkan driver, e.g. `apt-get install mesa-vulkan-drivers libvulkan1` for the lavapipe CPU driver")]
    NoLoader(String),
    #[error("no Vulkan 1.3 device with a compute queue was found{0}; install a Vulkan driver, e.g. `apt-get install mesa-vulkan-drivers` for the lavapipe CPU driver")]
    NoDevice(String),
    #[error("no Vulkan device matches '{wanted}'; available: {available}")]
    DeviceNotFound { wanted: String, available: String },
    #[error("out of device memory while allocating {what} ({bytes} bytes); try a smaller --size or a lower volume resolution")]
    OutOfDeviceMemory { what: String, bytes: u64 },
    #[error("out of host memory in Vulkan call {call}")]
    OutOfHostMemory { call: &'static str },
    #[error("the Vulkan device was lost during {call} (driver crash, reset or timeout); nothing more can run on it")]
    DeviceLost { call: &'static str },
    #[error("the Vulkan device did not finish a submission within {seconds} s; giving up on it (device hung or lost; CAUSTICA_SUBMIT_TIMEOUT=SECONDS waits longer)")]
    Timeout { seconds: u64 },
    #[error("Vulkan call {call} failed: {result:?}")]
    Vulkan { call: &'static str, result: vk::Result },
    #[error("memory allocation for {what} failed: {message}")]
    Allocation { what: String, message: String },
    #[error("shader {name}: {message}")]
    Shader { name: String, message: String },
    #[error("{what} is {requested} but this device allows at most {limit}")]
    Limit { what: String, requested: u64, limit: u64 },
    #[error("format {0:?} does not support {1} on this device")]
    Format(vk::Format, &'static str),
}

impl crate::Classify for GpuError {
    fn exit_class(&self) -> crate::ExitClass {
        use crate::ExitClass;
        match self {
            GpuError::NoLoader(_) | GpuError::NoDevice(_) | GpuError::DeviceNotFound { .. } => ExitClass::NoVulkan,
            GpuError::Timeout { .. } => ExitClass::GpuHung,
            GpuError::OutOfDeviceMemory { .. }
            | GpuError::OutOfHostMemory { .. }
            | GpuError::DeviceLost { .. }
            | GpuError::Vulkan { .. }
            | GpuError::Allocation { .. }
            | GpuError::Shader { .. }
            | GpuError::Limit { .. }
            | GpuError::Format(..) => ExitClass::Gpu,
        }
    }
}

impl GpuError {
    /// Maps a raw Vulkan result of `call` to the error a user should see.
    pub(crate) fn vk(call: &'static str, result: vk::Result) -> Self {
        match result {
            vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => GpuError::OutOfDeviceMemory {
                what: call.to_string(),
                bytes: 0,
            },
            vk::Result::ERROR_OUT_OF_HOST_MEMORY => GpuError::OutOfHostMemory { call },
            vk::Result::ERROR_DEVICE_LOST => GpuError::DeviceLost { call },
            result => GpuError::Vulkan { call, result },
        }
    }

    /// True for errors where retrying with smaller resources may succeed.
    pub fn is_out_of_memory(&self) -> bool {
        matches!(self, GpuError::OutOfDeviceMemory { .. })
    }
}

/// `result.map_err(vk_err("vkCall"))` shorthand.
pub(crate) fn vk_err(call: &'static str) -> impl Fn(vk::Result) -> GpuError {
    move |r| GpuError::vk(call, r)
}
