//! The method of Magnus & Bruckner 2017 on top of `gpu`: plane setup, the propagation pass,
//! the environment pass and read-back. [`Features`] says what a scene needs; the renderer
//! allocates and runs only that.

mod environment;
mod features;
mod geometry;
mod output;
mod params;
pub mod safeguards;
pub mod shaders;
mod state;
mod upload;

pub use environment::{srgb_to_linear, EnvError, EnvMap};
pub use features::{DebugView, Features};
pub use geometry::{light_direction, ViewSetup, MAX_LIGHT_VALUE, MIN_LIGHT_DIR_Z, MIN_VIEW_DIR_Z};
pub use geometry::{MAX_PLANES, NEAR_PLANE};
pub use output::{linear_to_srgb, OutputError, RenderedImage};
pub use params::{Immediates, Params};
pub use upload::ETA_TABLE_SIZE;

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use crate::gpu::{ComputePipeline, Context, GpuError, ShaderSource};
use crate::scene::{Environment, Precision, Scene, SceneError};
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
    /// The request's cancel flag was set (an interactive view changed before it finished).
    #[error("render cancelled")]
    Cancelled,
}

impl crate::Classify for RenderError {
    fn exit_class(&self) -> crate::ExitClass {
        match self {
            RenderError::Gpu(e) => e.exit_class(),
            RenderError::Scene(e) => e.exit_class(),
            RenderError::Volume(e) => e.exit_class(),
            RenderError::Environment(e) => e.exit_class(),
            // A view that cannot be rendered as asked (too many planes, an image larger than
            // the device allows): the request is at fault, not the device.
            RenderError::Setup(_) => crate::ExitClass::Input,
            // Only interactive renders are cancelled; the command line never sees it.
            RenderError::Cancelled => crate::ExitClass::Input,
        }
    }
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
    /// Safeguards to switch off ([`safeguards`] bits). Tests only: 0 in every real render.
    #[doc(hidden)]
    pub safeguards_off: u32,
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
            safeguards_off: 0,
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
    /// Precision the render actually used (lower than the scene's after an out-of-memory retry).
    pub precision: Precision,
    /// What was reduced to fit into device memory, one line each (empty normally).
    pub reductions: Vec<String>,
}

pub struct RenderOutput {
    pub image: RenderedImage,
    pub stats: RenderStats,
}

/// Renders prepared scenes; keeps parsed shaders and pipelines between renders.
pub struct Renderer {
    ctx: Arc<Context>,
    sources: HashMap<(Pass, Precision), ShaderSource>,
    pipelines: HashMap<(Pass, Precision, Features, DebugView, u32), Arc<ComputePipeline>>,
    /// Scene textures of the last render, reused while the volume, transfer functions,
    /// sample distance and environment stay the same.
    textures: Option<upload::CachedTextures>,
}

/// Out of device memory at 16-bit precision: halve the image size at most this many times,
/// rendering at 1/2 then 1/4 of the size and scaling up, before giving up.
pub const MAX_RESOLUTION_REDUCTIONS: u32 = 2;

impl Renderer {
    pub fn new(ctx: Arc<Context>) -> Result<Self, RenderError> {
        Ok(Renderer {
            ctx,
            sources: HashMap::new(),
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
        precision: Precision,
        features: Features,
        debug: DebugView,
        safeguards_off: u32,
    ) -> Result<Arc<ComputePipeline>, RenderError> {
        let debug = if pass == Pass::Finish { debug } else { DebugView::Image };
        let key = (pass, precision, features, debug, safeguards_off);
        if let Some(p) = self.pipelines.get(&key) {
            return Ok(p.clone());
        }
        let source = match self.sources.entry((pass, precision)) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => e.insert(pass.parse(precision)?),
        };
        let mut constants = features.constants(debug);
        for c in constants.iter_mut().filter(|c| c.0 == "SAFEGUARDS_OFF") {
            c.1 = safeguards_off as f64;
        }
        let compiled = source.specialise("main", &constants)?;
        let label = format!("{} [{} {}]", pass.file(), features.describe(), precision.name());
        let p = Arc::new(ComputePipeline::new(&self.ctx, &label, &compiled)?);
        self.pipelines.insert(key, p.clone());
        Ok(p)
    }

    /// Renders one image (or a debug buffer) of `prepared`.
    ///
    /// Out of device memory is retried: first with 16-bit buffers when the scene asked for
    /// 32-bit ones, then at half and a quarter of the image size (scaled up to the requested
    /// size). Each reduction is logged as a warning and listed in [`RenderStats::reductions`].
    pub fn render(&mut self, prepared: &PreparedScene, req: &RenderRequest) -> Result<RenderOutput, RenderError> {
        let mut precision = prepared.scene.quality.precision;
        let mut sub = req.clone();
        let mut halvings = 0;
        let mut reductions = Vec::new();
        loop {
            let e = match self.render_once(prepared, &sub, precision) {
                Ok(mut out) => {
                    if (sub.width, sub.height) != (req.width, req.height) {
                        out.image = out.image.resized(req.width, req.height);
                    }
                    out.stats.reductions = reductions;
                    return Ok(out);
                }
                Err(RenderError::Gpu(e)) if e.is_out_of_memory() => e,
                Err(e) => return Err(e),
            };
            let reduction = if precision == Precision::F32 {
                precision = Precision::F16;
                "precision f32 → f16 (16-bit light, colour and medium buffers)".to_string()
            } else if halvings < MAX_RESOLUTION_REDUCTIONS && (sub.width > 1 || sub.height > 1) {
                halvings += 1;
                sub.width = sub.width.div_ceil(2);
                sub.height = sub.height.div_ceil(2);
                format!(
                    "resolution {}×{} rendered and scaled up to {}×{}",
                    sub.width, sub.height, req.width, req.height
                )
            } else {
                return Err(RenderError::Gpu(e));
            };
            log::warn!("{e}; retrying with {reduction}");
            reductions.push(reduction);
        }
    }

    fn render_once(
        &mut self,
        prepared: &PreparedScene,
        req: &RenderRequest,
        precision: Precision,
    ) -> Result<RenderOutput, RenderError> {
        let features = prepared.features();
        let off = req.safeguards_off;
        let pipelines = [
            self.pipeline(Pass::Init, precision, features, req.debug_view, off)?,
            self.pipeline(Pass::Propagate, precision, features, req.debug_view, off)?,
            self.pipeline(Pass::Finish, precision, features, req.debug_view, off)?,
        ];
        state::run(
            &self.ctx,
            prepared,
            req,
            features,
            precision,
            &pipelines,
            &mut self.textures,
        )
    }
}

/// Environment parameters: (rgb background, 1 when an environment map is used).
fn background(env: &Environment) -> [f32; 4] {
    match env {
        Environment::Color { color } => [color[0], color[1], color[2], 0.0],
        _ => [0.0, 0.0, 0.0, 1.0],
    }
}
