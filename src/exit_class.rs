//! How a failure ends the command line. Every error enum of the library says, per variant,
//! which class it belongs to ([`Classify`]); wrappers ask what they wrap. `main` turns the
//! class into the exit code in one place (README, "Errors and exit codes").

/// The kinds of failure the command line reports with distinct exit codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExitClass {
    /// Bad input: a missing or malformed file, scene or value, or a view that cannot be
    /// rendered as asked (exit 1).
    Input,
    /// Options that do not fit together or do not fit the animation, found after parsing
    /// (exit 2, the code of the argument parser's own usage errors).
    Usage,
    /// No Vulkan: no loader, no suitable device, no device matching `--device`, or no
    /// validation layer when it is required (exit 3).
    NoVulkan,
    /// The GPU failed: out of device memory after the fallbacks, a lost device, a device
    /// limit, a failed Vulkan call, validation errors, an image with invalid values (exit 4).
    Gpu,
    /// The GPU did not finish a submission: exit 4 at once, without running exit handlers
    /// under the work the driver may still be executing.
    GpuHung,
}

impl ExitClass {
    /// The process exit code.
    pub fn code(self) -> u8 {
        match self {
            ExitClass::Input => 1,
            ExitClass::Usage => 2,
            ExitClass::NoVulkan => 3,
            ExitClass::Gpu | ExitClass::GpuHung => 4,
        }
    }
}

/// An error that knows its [`ExitClass`].
pub trait Classify {
    fn exit_class(&self) -> ExitClass;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::AnimateError;
    use crate::app::ViewError;
    use crate::bench::BenchError;
    use crate::gpu::GpuError;
    use crate::input::InputError;
    use crate::render::RenderError;
    use crate::scene::{PrepareError, SceneError};
    use crate::volume::VolumeError;

    fn lost() -> RenderError {
        RenderError::Gpu(GpuError::DeviceLost { call: "vkQueueSubmit" })
    }

    /// `#[error(transparent)]` wrappers show the inner message; they must report the inner
    /// class too, however deep the GPU error sits.
    #[test]
    fn wrappers_report_the_class_of_what_they_wrap() {
        assert_eq!(ViewError::Render(lost()).exit_class(), ExitClass::Gpu);
        assert_eq!(ViewError::Render(lost()).exit_class().code(), 4);
        assert_eq!(BenchError::Render(lost()).exit_class().code(), 4);
        let hung = RenderError::Gpu(GpuError::Timeout { seconds: 120 });
        assert_eq!(ViewError::Render(hung).exit_class(), ExitClass::GpuHung);
        let no_device = GpuError::NoDevice(String::new());
        assert_eq!(ViewError::Gpu(no_device).exit_class().code(), 3);
        // A frame that failed on the viewer's render thread keeps its class.
        let frame = ViewError::Frame {
            message: "lost".into(),
            class: ExitClass::Gpu,
        };
        assert_eq!(frame.exit_class().code(), 4);
        // Input stays input at every depth.
        let volume = || VolumeError::NonFinite { count: 1 };
        let nested = InputError::Prepare(PrepareError::Scene(SceneError::Volume(volume())));
        assert_eq!(nested.exit_class(), ExitClass::Input);
        assert_eq!(
            RenderError::Prepare(PrepareError::Volume(volume())).exit_class(),
            ExitClass::Input
        );
        assert_eq!(RenderError::Setup("too many planes".into()).exit_class().code(), 1);
    }

    /// `animate` keeps its documented codes: usage 2, frames the GPU got wrong 4, a missing
    /// ffmpeg or an incomplete folder 1, and wrapped render and GPU errors as for `render`.
    #[test]
    fn animate_errors_keep_their_codes() {
        assert_eq!(AnimateError::Usage("--range 2..4".into()).exit_class().code(), 2);
        let validation = AnimateError::Validation {
            frame: 3,
            count: 1,
            first: String::new(),
        };
        assert_eq!(validation.exit_class().code(), 4);
        let invalid = AnimateError::InvalidImage {
            frame: 0,
            non_finite: 1,
            negative: 0,
        };
        assert_eq!(invalid.exit_class().code(), 4);
        let incomplete = AnimateError::Incomplete {
            dir: "f".into(),
            animation: "f/animation.toml".into(),
            missing: 1,
            stale: 0,
        };
        assert_eq!(incomplete.exit_class().code(), 1);
        assert_eq!(AnimateError::Render(lost()).exit_class().code(), 4);
        let hung = AnimateError::Gpu(GpuError::Timeout { seconds: 120 });
        assert_eq!(hung.exit_class(), ExitClass::GpuHung);
        assert_eq!(
            AnimateError::Gpu(GpuError::NoDevice(String::new())).exit_class().code(),
            3
        );
        let volume = AnimateError::Prepare(PrepareError::Volume(VolumeError::NonFinite { count: 1 }));
        assert_eq!(volume.exit_class(), ExitClass::Input);
    }
}
