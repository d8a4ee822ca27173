//! A thin, documented layer over `ash` (Vulkan 1.3). Nothing here knows what a volume is.
//!
//! # Contract
//! * All `unsafe` Vulkan calls of the crate live in this module. Callers see safe types, and
//!   no sequence of safe calls can make the GPU use a destroyed object.
//! * [`Context`] owns the instance, the logical device, the one compute queue and the memory
//!   allocator, each through a small RAII owner that holds an `Arc` of what it was made from.
//!   The context is shared through `Arc<Context>`; every resource ([`Buffer`], [`Image`],
//!   [`ComputePipeline`], ...) holds such an `Arc` and destroys its Vulkan object in `Drop`,
//!   so the device always outlives what was created from it.
//! * Lifetimes are in the types: a [`Recorder<'r>`](Recorder) borrows every resource it
//!   records for `'r` (or holds an `Arc` of it), a [`DescriptorSet<'a>`](DescriptorSet)
//!   borrows its pipeline and what is written into it, and a recorder gives its borrows back
//!   only when [`Recorder::submit_and_wait`] has seen the GPU finish. Dropping or rewriting a
//!   resource a pending command uses does not compile.
//! * Synchronisation is explicit and coarse: work is recorded into one-shot command buffers
//!   ([`Recorder`]) and [`Recorder::submit_and_wait`] blocks on a fence. Between dependent
//!   dispatches the recorder inserts a full compute→compute memory barrier. No resource is
//!   used by two submissions at once because every submission is waited for. The wait is
//!   bounded ([`FENCE_TIMEOUT`]): a device that does not finish counts as lost, further
//!   submissions fail at once, and objects the hung work may use are leaked, not destroyed.
//!   The driver's threads may still run that work, so a program should end with `_exit`
//!   after a hang rather than run the C library's exit handlers (the CLI does).
//! * Memory is metered: every allocation and free is counted by where it lives, so
//!   [`Context::memory_peak`] is the most the program held at once, whatever allocated it.
//! * Faults can be injected for tests ([`Faults`]): allocations failing with out of device
//!   memory, a submission reporting a lost device.
//! * Images live in `GENERAL` layout after creation, so one image can be sampled and written
//!   as a storage image in different dispatches without layout transitions.
//! * Every object gets a debug name (visible in validation messages and capture tools).
//! * Validation: with [`ContextDesc::validation`] the Khronos validation layer is enabled and
//!   a debug messenger counts every error it reports ([`Context::validation_errors`]); tests
//!   fail when the count is non-zero (the "validation canary").

mod commands;
mod context;
mod error;
mod fault;
mod instance;
mod meter;
mod pipeline;
mod resources;
pub mod shader;
mod timestamps;

pub use commands::Recorder;
pub use context::{Context, ContextDesc, DeviceSelector, FENCE_TIMEOUT};
pub use error::GpuError;
pub use fault::Faults;
pub use instance::{list_devices, DeviceInfo};
pub use meter::MemoryUse;
pub use pipeline::{ComputePipeline, DescriptorSet, Resource};
pub use resources::{AliasedBuffer, Buffer, Image, ImageDesc, LinearLayout, Sampler, SamplerDesc};
pub use shader::{Binding, BindingKind, CompiledShader, ShaderLayout, ShaderSource};
pub use timestamps::Timestamps;

pub use ash::vk::Format;
