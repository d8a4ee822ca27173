//! The method of Magnus & Bruckner 2017 on top of `gpu`: plane setup, the propagation pass,
//! the environment pass and read-back. [`Features`] says what a scene needs; the renderer
//! allocates and runs only that.

mod environment;
mod features;
mod geometry;
mod output;
mod params;
pub mod shaders;
mod state;
mod upload;

pub use environment::{srgb_to_linear, EnvError, EnvMap};
pub use features::{DebugView, Features};
pub use geometry::{light_direction, ViewSetup, MAX_LIGHT_VALUE, MIN_LIGHT_DIR_Z, MIN_VIEW_DIR_Z};
pub use output::{linear_to_srgb, OutputError, RenderedImage};
pub use params::{Immediates, Params};
pub use upload::ETA_TABLE_SIZE;

use std::collections::HashMap;
use std::sync::Arc;

use crate::gpu::shader::ShaderSource;
use crate::gpu::{ComputePipeline, Context, GpuError};
use crate::scene::{Environment, Scene, SceneError};
use crate::transfer::TransferFunctions;
use crate::volume::resample::{fitting_dims, resample};
use crate::volume::{dims_text, Format, Histogram, Loaded, Volume, VolumeError, VolumeMeta};

use shaders::Pass;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Volume(#[from] VolumeError),
    #[error(transparent)]
    Environment(#[from] EnvError),
    #[error("cannot render this view: {0}")]
    Setup(String),
}

/// A scene with its data loaded: volumes, transfer functions, environment image.
pub struct PreparedScene {
    pub scene: Scene,
    pub volume: Arc<Volume>,
    pub eta_volume: Option<Arc<Volume>>,
    pub tf: TransferFunctions,
    pub env: Option<EnvMap>,
    /// What the volume's file said about it, and its histogram (computed once at load).
    pub volume_info: VolumeInfo,
}

/// Metadata and histogram of the loaded volume, and the window used when the scene has none.
#[derive(Clone, Debug)]
pub struct VolumeInfo {
    pub meta: VolumeMeta,
    pub histogram: Histogram,
    pub default_window: [f32; 2],
}

impl VolumeInfo {
    fn of(loaded: &Loaded) -> VolumeInfo {
        VolumeInfo {
            meta: loaded.meta.clone(),
            histogram: loaded.histogram.clone(),
            default_window: loaded.default_window(),
        }
    }
}

impl PreparedScene {
    pub fn load(scene: &Scene) -> Result<Self, RenderError> {
        scene.validate()?;
        let loaded = scene.volume.open()?;
        let volume_info = VolumeInfo::of(&loaded);
        let volume = Arc::new(loaded.volume);
        let eta_volume = match &scene.eta_volume {
            Some(src) => {
                let v = src.load()?;
                let v = if v.dims == volume.dims {
                    v
                } else {
                    log::warn!(
                        "resampling the η volume from {} onto the volume's grid {}",
                        dims_text(&v.dims),
                        dims_text(&volume.dims)
                    );
                    resample(&v, volume.dims)?
                };
                Some(Arc::new(v))
            }
            None => None,
        };
        Ok(PreparedScene {
            tf: scene.transfer_functions()?,
            env: EnvMap::for_scene(&scene.environment)?,
            scene: scene.clone(),
            volume,
            eta_volume,
            volume_info,
        })
    }

    pub fn from_parts(scene: Scene, volume: Volume, tf: TransferFunctions) -> Result<Self, RenderError> {
        let loaded = Loaded::new(volume, VolumeMeta::new(Format::Procedural, None));
        Ok(PreparedScene {
            env: EnvMap::for_scene(&scene.environment)?,
            scene,
            volume_info: VolumeInfo::of(&loaded),
            volume: Arc::new(loaded.volume),
            eta_volume: None,
            tf,
        })
    }

    /// The data window mapped onto [0, 1] of the transfer functions: the scene's, or else
    /// the volume's default (CT window for Hounsfield data, histogram percentiles for files,
    /// the value range for procedural volumes).
    pub fn window(&self) -> [f32; 2] {
        self.scene.window.unwrap_or(self.volume_info.default_window)
    }

    /// Replaces the transfer functions with the default for this volume's histogram and units.
    pub fn use_default_transfer(&mut self) {
        self.tf = crate::transfer::default_for(&self.volume_info.meta, &self.volume_info.histogram, self.window());
    }

    /// Loads frame `k` of a time-series volume in place (the viewer's time slider). Call
    /// [`PreparedScene::fit_to_device`] again afterwards if frames may exceed the device limits.
    pub fn load_frame(&mut self, k: usize) -> Result<(), RenderError> {
        self.scene.volume.set_frame(k);
        let loaded = self.scene.volume.open()?;
        self.volume_info = VolumeInfo::of(&loaded);
        self.volume = Arc::new(loaded.volume);
        Ok(())
    }

    /// Downsamples the volumes (and warns) when they exceed `max_dim` voxels along an axis or
    /// `max_bytes` of 16-bit texture memory; with `allow` false that is an error instead.
    /// Returns the new dims when the volume was downsampled.
    pub fn fit_to_device(
        &mut self,
        max_dim: u32,
        max_bytes: u64,
        allow: bool,
    ) -> Result<Option<[usize; 3]>, RenderError> {
        // Each volume texel is 16 bits; a second volume for η doubles that.
        let textures = if self.eta_volume.is_some() { 2 } else { 1 };
        let max_voxels = (max_bytes / (2 * textures)).min(usize::MAX as u64) as usize;
        let Some(dims) = fitting_dims(self.volume.dims, max_dim as usize, max_voxels) else {
            return Ok(None);
        };
        let what = format!(
            "the volume {} exceeds the device's limits ({max_dim} texels per axis, {} MiB for volume textures)",
            dims_text(&self.volume.dims),
            max_bytes >> 20
        );
        if !allow {
            return Err(RenderError::Setup(format!(
                "{what}; allow downsampling or use a smaller volume"
            )));
        }
        log::warn!("{what}: downsampling to {}", dims_text(&dims));
        self.volume = Arc::new(resample(&self.volume, dims)?);
        if let Some(eta) = &self.eta_volume {
            self.eta_volume = Some(Arc::new(resample(eta, dims)?));
        }
        Ok(Some(dims))
    }

    pub fn features(&self) -> Features {
        Features::for_scene(&self.scene, &self.tf)
    }
}

/// What to render.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    pub width: u32,
    pub height: u32,
    pub debug_view: DebugView,
    /// With a debug view: relative depth in [0, 1] of the plane whose buffer is shown.
    pub debug_depth: f32,
    /// Show a progress bar on a terminal.
    pub progress: bool,
}

impl RenderRequest {
    pub fn new(width: u32, height: u32) -> Self {
        RenderRequest {
            width,
            height,
            debug_view: DebugView::Image,
            debug_depth: 1.0,
            progress: false,
        }
    }
}

/// Measurements of one render.
#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    pub features: Features,
    /// Planes of the full sweep.
    pub planes: u32,
    /// Planes actually integrated (fewer with a debug view at a depth < 1).
    pub planes_run: u32,
    /// GPU time of the sweep and the final pass (timestamp queries), in milliseconds.
    pub gpu_ms: f64,
    pub ms_per_plane: f64,
    /// Bytes of the ping-pong state buffers.
    pub state_bytes: u64,
}

pub struct RenderOutput {
    pub image: RenderedImage,
    pub stats: RenderStats,
}

/// Renders prepared scenes; keeps parsed shaders and pipelines between renders.
pub struct Renderer {
    ctx: Arc<Context>,
    sources: HashMap<Pass, ShaderSource>,
    pipelines: HashMap<(Pass, Features, DebugView), Arc<ComputePipeline>>,
}

impl Renderer {
    pub fn new(ctx: Arc<Context>) -> Result<Self, RenderError> {
        let mut sources = HashMap::new();
        for pass in Pass::ALL {
            sources.insert(pass, pass.parse()?);
        }
        Ok(Renderer {
            ctx,
            sources,
            pipelines: HashMap::new(),
        })
    }

    pub fn context(&self) -> &Arc<Context> {
        &self.ctx
    }

    fn pipeline(
        &mut self,
        pass: Pass,
        features: Features,
        debug: DebugView,
    ) -> Result<Arc<ComputePipeline>, RenderError> {
        let debug = if pass == Pass::Finish { debug } else { DebugView::Image };
        if let Some(p) = self.pipelines.get(&(pass, features, debug)) {
            return Ok(p.clone());
        }
        let source = self
            .sources
            .get(&pass)
            .ok_or_else(|| RenderError::Setup("missing shader".into()))?;
        let spirv = source.specialise("main", &features.constants(debug))?;
        let label = format!("{} [{}]", pass.file(), features.describe());
        let p = Arc::new(ComputePipeline::new(
            &self.ctx,
            &label,
            &spirv,
            "main",
            &shaders::bindings(),
            std::mem::size_of::<Immediates>() as u32,
        )?);
        self.pipelines.insert((pass, features, debug), p.clone());
        Ok(p)
    }

    /// Renders one image (or a debug buffer) of `prepared`.
    pub fn render(&mut self, prepared: &PreparedScene, req: &RenderRequest) -> Result<RenderOutput, RenderError> {
        let features = prepared.features();
        let pipelines = [
            self.pipeline(Pass::Init, features, req.debug_view)?,
            self.pipeline(Pass::Propagate, features, req.debug_view)?,
            self.pipeline(Pass::Finish, features, req.debug_view)?,
        ];
        state::run(&self.ctx, prepared, req, features, &pipelines)
    }
}

/// Environment parameters: (rgb background, 1 when an environment map is used).
fn background(env: &Environment) -> [f32; 4] {
    match env {
        Environment::Color { color } => [color[0], color[1], color[2], 0.0],
        _ => [0.0, 0.0, 0.0, 1.0],
    }
}
