//! `caustica animate`: frame sequences (turntables, light sweeps, time series, transfer-function
//! morphs, clip-plane sweeps) rendered offscreen, split across machines, encoded to MP4.
//!
//! An [`Animation`] is a base scene plus [`Tracks`]: key lists over the animation time
//! u ∈ [0, 1] for camera, light, clip plane, time-series frame and transfer functions.
//! Frame k is a plain [`Scene`](crate::scene::Scene) computed from them ([`Animation::frame`]),
//! rendered by the same [`Renderer`](crate::render::Renderer) as `caustica render` (one
//! renderer for all frames, so textures stay cached while the volume and transfer functions
//! do not change). What a frame shows is hashed; the hash is written into the frame file, so
//! any run (another shard, a resumed job, `--check`) can tell a frame that is present and
//! current from a missing or stale one without shared state between processes.
//!
//! | file | what it holds |
//! |---|---|
//! | `file.rs` | the animation file (TOML): load, normalise, validate, save, hash |
//! | `tracks.rs` | key lists and their interpolation; frame k's scene |
//! | `blend.rs` | transfer functions interpolated point by point |
//! | `paths.rs` | a scene's file paths made absolute, so an animation file can move |
//! | `frames.rs` | frame names and selection (shards, ranges), frame files with their hash, manifest, `--check` |
//! | `run.rs` | the render loop: one renderer, time-series volumes, progress, resume |
//! | `encode.rs` | MP4 through `ffmpeg` |
//! | `keyframes.rs` | an animation from views recorded in the viewer |
//!
//! The command's options, and how they become an animation, are the binary's
//! (`src/cli/animate.rs`), as for `render` and `bench`.

mod blend;
mod encode;
mod file;
pub mod frames;
pub mod keyframes;
pub mod paths;
mod run;
mod tracks;

pub use blend::blend_transfer;
pub use encode::encode_mp4;
pub use file::{is_animation_file, load_key_file, Animation, ANIMATION_FILE, MANIFEST_FILE};
pub use frames::{CheckReport, FrameFormat, Selection};
pub use run::{render_frames, RunSummary};
pub use tracks::{
    Blend, CameraTracks, ClipTracks, FrameSpec, Keys, Keys3, LightTracks, TimeMode, TimeTrack, Tracks, TransferKey,
};

use std::path::PathBuf;

use crate::gpu::GpuError;
use crate::input::InputError;
use crate::render::RenderError;
use crate::scene::{OutputError, PrepareError, SceneError};
use crate::transfer::TransferError;
use crate::volume::VolumeError;
use crate::{Classify, ExitClass};

#[derive(Debug, thiserror::Error)]
pub enum AnimateError {
    /// Options that do not fit together or do not fit the animation (exit code 2).
    #[error("{0}")]
    Usage(String),
    #[error("cannot read animation file {path}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("animation file {path} is invalid: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("invalid animation: {0}")]
    Invalid(String),
    #[error("cannot write {path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error(
        "cannot write {output}: ffmpeg is not on the PATH (Debian/Ubuntu: apt-get install ffmpeg); \
         the {frames} frames are in {dir}; once ffmpeg is installed, `caustica animate {animation} -o {output}` \
         encodes them without rendering again"
    )]
    NoFfmpeg {
        output: PathBuf,
        dir: PathBuf,
        animation: PathBuf,
        frames: usize,
    },
    #[error(
        "{dir} is incomplete: {missing} missing and {stale} stale frames; `caustica animate {animation} -o {dir}` renders just those"
    )]
    Incomplete {
        dir: PathBuf,
        animation: PathBuf,
        missing: usize,
        stale: usize,
    },
    #[error("ffmpeg failed to encode {output} from the frames in {dir}: {message}")]
    Ffmpeg {
        output: PathBuf,
        dir: PathBuf,
        message: String,
    },
    #[error(
        "the Vulkan validation layer reported {count} error(s) while rendering frame {frame} (first: {first}); not writing it"
    )]
    Validation { frame: u32, count: u64, first: String },
    #[error(
        "frame {frame}: the render produced {non_finite} non-finite and {negative} negative values; not writing it"
    )]
    InvalidImage {
        frame: u32,
        non_finite: usize,
        negative: usize,
    },
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Transfer(#[from] TransferError),
    #[error(transparent)]
    Volume(#[from] VolumeError),
    #[error(transparent)]
    Prepare(#[from] PrepareError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Output(#[from] OutputError),
}

impl Classify for AnimateError {
    /// Usage 2, untrustworthy GPU results 4 (README, "Errors and exit codes"); wrapped errors
    /// keep the class of what they wrap, so a GPU failure maps exactly as for `render`.
    fn exit_class(&self) -> ExitClass {
        match self {
            AnimateError::Usage(_) => ExitClass::Usage,
            AnimateError::Validation { .. } | AnimateError::InvalidImage { .. } => ExitClass::Gpu,
            AnimateError::Io { .. }
            | AnimateError::Parse { .. }
            | AnimateError::Invalid(_)
            | AnimateError::Write { .. }
            | AnimateError::NoFfmpeg { .. }
            | AnimateError::Incomplete { .. }
            | AnimateError::Ffmpeg { .. } => ExitClass::Input,
            AnimateError::Input(e) => e.exit_class(),
            AnimateError::Scene(e) => e.exit_class(),
            AnimateError::Transfer(e) => e.exit_class(),
            AnimateError::Volume(e) => e.exit_class(),
            AnimateError::Prepare(e) => e.exit_class(),
            AnimateError::Render(e) => e.exit_class(),
            AnimateError::Gpu(e) => e.exit_class(),
            AnimateError::Output(e) => e.exit_class(),
        }
    }
}
