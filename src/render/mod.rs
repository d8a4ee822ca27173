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
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use crate::gpu::shader::ShaderSource;
use crate::gpu::{ComputePipeline, Context, GpuError};
use crate::scene::{Environment, Scene, SceneError};
use crate::transfer::TransferFunctions;
use crate::volume::{Volume, VolumeError};

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
    /// The request's cancel flag was set (an interactive view changed before it finished).
    #[error("render cancelled")]
    Cancelled,
}

/// A scene with its data loaded: volumes, transfer functions, environment image.
pub struct PreparedScene {
    pub scene: Scene,
    pub volume: Arc<Volume>,
    pub eta_volume: Option<Arc<Volume>>,
    pub tf: TransferFunctions,
    pub env: Option<EnvMap>,
}

impl PreparedScene {
    pub fn load(scene: &Scene) -> Result<Self, RenderError> {
        scene.validate()?;
        let volume = Arc::new(scene.volume.load()?);
        let eta_volume = match &scene.eta_volume {
            Some(src) => {
                let v = src.load()?;
                if v.dims != volume.dims {
                    return Err(RenderError::Setup(format!(
                        "the η volume has dims {:?} but the volume has {:?}; they must share one grid",
                        v.dims, volume.dims
                    )));
                }
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
        })
    }

    pub fn from_parts(scene: Scene, volume: Volume, tf: TransferFunctions) -> Result<Self, RenderError> {
        Ok(PreparedScene {
            env: EnvMap::for_scene(&scene.environment)?,
            scene,
            volume: Arc::new(volume),
            eta_volume: None,
            tf,
        })
    }

    /// The data window mapped onto [0, 1] of the transfer functions.
    pub fn window(&self) -> [f32; 2] {
        self.scene.window.unwrap_or(self.volume.value_range)
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
    /// Checked between submissions: when set, the render stops with [`RenderError::Cancelled`].
    /// Renders with a flag are submitted in smaller chunks so they stop sooner.
    pub cancel: Option<Arc<AtomicBool>>,
}

impl RenderRequest {
    pub fn new(width: u32, height: u32) -> Self {
        RenderRequest {
            width,
            height,
            debug_view: DebugView::Image,
            debug_depth: 1.0,
            progress: false,
            cancel: None,
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
    /// Scene textures of the last render, reused while the volume, transfer functions,
    /// sample distance and environment stay the same.
    textures: Option<upload::CachedTextures>,
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
            textures: None,
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
        state::run(&self.ctx, prepared, req, features, &pipelines, &mut self.textures)
    }
}

/// Environment parameters: (rgb background, 1 when an environment map is used).
fn background(env: &Environment) -> [f32; 4] {
    match env {
        Environment::Color { color } => [color[0], color[1], color[2], 0.0],
        _ => [0.0, 0.0, 0.0, 1.0],
    }
}
