//! The interactive viewer (`caustica view`): a winit window with an egui panel for camera,
//! light, transfer-function, effect and quality editing.
//!
//! Data flow: the panel edits a [`panel::ViewState`] (scene + transfer-function editor); every
//! change bumps the [`progressive`] scheduler, which asks the render thread ([`worker`]) for a
//! coarse frame while the user drags and for finer ones once idle. The render thread runs the
//! very same `render::Renderer` as `caustica render`; its full-quality frame is the offscreen
//! render of the same scene and size, shown pixel for pixel. The window paints that image and
//! the panel on the CPU ([`raster`]) into a softbuffer surface.

pub mod controls;
pub mod keyframes;
pub mod orientation;
pub mod panel;
#[cfg(test)]
mod panel_tests;
pub mod progressive;
pub mod raster;
pub mod save;
pub mod tf_model;
mod widgets;
mod window;
mod worker;

use std::path::{Path, PathBuf};

use anyhow::{Context as _, Result};

use crate::gpu::{Context, ContextDesc, DeviceSelector, GpuError};
use crate::input::{fit_to_device, InputArgs, InputError, Prepared};
use crate::render::{RenderError, Renderer};
use crate::scene::PrepareError;
use crate::{Classify, ExitClass};

/// Why the viewer could not start, or stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Prepare(#[from] PrepareError),
    /// The display, the window or the panel, with their context.
    #[error("{0:#}")]
    Viewer(anyhow::Error),
    /// A frame failed on the render thread (loading a frame of a series, or rendering) and
    /// `--exit-after-idle` cannot settle without it.
    #[error("render failed: {message}")]
    Frame { message: String, class: ExitClass },
    #[error("{0} Vulkan validation errors were reported")]
    Validation(u64),
}

impl From<anyhow::Error> for ViewError {
    fn from(e: anyhow::Error) -> Self {
        ViewError::Viewer(e)
    }
}

impl Classify for ViewError {
    fn exit_class(&self) -> ExitClass {
        match self {
            ViewError::Input(e) => e.exit_class(),
            ViewError::Gpu(e) => e.exit_class(),
            ViewError::Render(e) => e.exit_class(),
            ViewError::Prepare(e) => e.exit_class(),
            // No display, or a window that cannot be painted.
            ViewError::Viewer(_) => ExitClass::Input,
            ViewError::Frame { class, .. } => *class,
            ViewError::Validation(_) => ExitClass::Gpu,
        }
    }
}

/// `caustica view` options.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    #[command(flatten)]
    pub input: InputArgs,
    /// Window size, WIDTHxHEIGHT (pixels).
    #[arg(long, default_value = "1024x768", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Vulkan device: index or name substring (see `caustica devices`).
    #[arg(long, default_value = "auto")]
    pub device: String,
    /// Start with the panel hidden (Tab shows it): the render fills the window.
    #[arg(long)]
    pub no_panel: bool,
    /// Quit once the full-quality frame is on screen.
    #[arg(long)]
    pub exit_after_idle: bool,
    /// Whenever the view settles to its full-quality frame, write what the window shows (read
    /// back from the window system, panel included) to this PNG.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Whenever the view settles to its full-quality frame, save the scene (as Ctrl+S does).
    #[arg(long)]
    pub save_scene: Option<PathBuf>,
    /// Print each frame shown (quality level, size, planes, render time) and paint times.
    #[arg(long)]
    pub frame_log: bool,
    /// Scripted interaction for measurements: after each of the first N frames, orbit the
    /// camera by 5° as a mouse drag would (each frame is then an interactive one).
    #[arg(long, default_value_t = 0)]
    pub orbit_frames: u32,
    /// Scripted interaction for tests: once the full frame is on screen, resize the window to
    /// WIDTHxHEIGHT and refine again (before --screenshot and --exit-after-idle apply).
    #[arg(long, value_parser = parse_size)]
    pub resize_after_idle: Option<(u32, u32)>,
    /// The time an interactive frame (while dragging) may take, in ms: its planes move apart
    /// (from 6 voxels up to 16) or closer (down to 4) to keep the latest frames' median within
    /// it. 0 keeps them 6 voxels apart.
    #[arg(long, default_value_t = progressive::FRAME_BUDGET_MS, value_parser = parse_budget)]
    pub frame_budget: f64,
}

/// A frame budget in ms: a finite number, 0 or more.
fn parse_budget(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(ms) if ms.is_finite() && ms >= 0.0 => Ok(ms),
        _ => Err(format!("'{s}' is not a time in ms (a number, 0 or more)")),
    }
}

/// A window size: [`crate::input::parse_size`], at most 16384 on each side.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = crate::input::parse_size(s)?;
    if w > 16384 || h > 16384 {
        return Err("width and height must be between 1 and 16384".into());
    }
    Ok((w, h))
}

/// Where the transfer-function presets are: `transfer_functions/` next to the working
/// directory, else the one of the source tree this binary was built from.
fn presets_dir() -> PathBuf {
    let local = Path::new("transfer_functions");
    if local.is_dir() {
        local.to_path_buf()
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("transfer_functions")
    }
}

/// Runs the viewer until the window is closed (or, with `--exit-after-idle`, settles).
pub fn run(args: &ViewArgs) -> Result<(), ViewError> {
    let Prepared { mut prepared, notes } = args.input.prepare()?;
    for note in notes {
        eprintln!("{note}");
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    let allow_downsample = !args.input.no_downsample;
    fit_to_device(&mut prepared, &ctx, allow_downsample, true)?;
    let histogram = panel::histogram(&prepared.volume.data, prepared.window());
    let mut state = panel::ViewState::new(prepared.scene.clone(), histogram, &presets_dir())?;
    state.anatomy = prepared
        .volume_info
        .meta
        .patient
        .as_ref()
        .map(|p| p.display_from_world());
    state.show_panel = !args.no_panel;
    state.screenshot_size = [args.size.0, args.size.1];
    let renderer = Renderer::new(ctx.clone())?;
    let event_loop = winit::event_loop::EventLoop::<window::Wake>::with_user_event()
        .build()
        .context("cannot connect to a display (is DISPLAY set? `caustica render` works without one)")?;
    let proxy = event_loop.create_proxy();
    let worker = worker::Worker::start(renderer, prepared, allow_downsample, move || {
        let _ = proxy.send_event(window::Wake);
    });
    let opts = window::Options {
        size: args.size,
        exit_after_idle: args.exit_after_idle,
        screenshot: args.screenshot.clone(),
        save_scene: args.save_scene.clone(),
        frame_log: args.frame_log,
        orbit_frames: args.orbit_frames,
        frame_budget_ms: args.frame_budget,
        resize_after_idle: args.resize_after_idle,
    };
    let mut app = window::App::new(state, worker, opts);
    let result = event_loop.run_app(&mut app);
    app.shutdown();
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    result.context("window event loop failed")?;
    let errors = ctx.validation_errors();
    if errors > 0 {
        return Err(ViewError::Validation(errors));
    }
    Ok(())
}
