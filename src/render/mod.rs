//! The method of Magnus & Bruckner 2017 on top of `gpu`: plane setup, the propagation pass,
//! the environment pass and read-back. [`Features`] says what a scene needs; the renderer
//! allocates and runs only that.

mod accumulate;
pub mod bricks;
mod coarse;
mod features;
pub mod gradient;
pub mod layers;
pub mod lbm;
mod light_tiles;
mod occupancy;
mod params;
pub mod safeguards;
pub mod shaders;
mod state;
mod upload;

pub use accumulate::{accumulate, jitter_sequence};
pub use features::{DebugView, Features};
pub use params::{Immediates, Params};
// What the renderer takes and gives lives in `scene` (GPU-free, shared with the CPU reference).
pub use crate::scene::view::{
    light_direction, BeamGrid, PixelRect, ViewSetup, MAX_LIGHT_VALUE, MIN_LIGHT_DIR_Z, MIN_VIEW_DIR_Z,
};
pub use crate::scene::view::{MAX_PLANES, NEAR_PLANE};
pub use crate::scene::{linear_to_srgb, srgb_to_linear, EnvError, EnvMap, OutputError, RenderedImage};
pub use crate::scene::{PrepareError, PreparedScene, VolumeInfo};
// The environment map under the name the passes use.
use crate::scene::environment;

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;

use rayon::prelude::*;

use crate::gpu::{CompiledShader, ComputePipeline, Context, GpuError, MemoryUse, ShaderSource};
use crate::scene::{Environment, Precision, SceneError};

use shaders::Pass;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Prepare(#[from] PrepareError),
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
            RenderError::Prepare(e) => e.exit_class(),
            RenderError::Environment(e) => e.exit_class(),
            // A view that cannot be rendered as asked (too many planes, an image larger than
            // the device allows): the request is at fault, not the device.
            RenderError::Setup(_) => crate::ExitClass::Input,
            // Only interactive renders are cancelled; the command line never sees it.
            RenderError::Cancelled => crate::ExitClass::Input,
        }
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
    /// Where the sweep has got, updated after each submission, for a window to show while the
    /// frame renders ([`SweepProgress`]).
    pub sweep_progress: Option<Arc<SweepProgress>>,
    /// Offsets of the sampling lattices, each a fraction in [0, 1): the planes (of the plane
    /// distance, toward the camera) and the light grid (of a cell, along x and y). Zero for the
    /// standard sweep; [`accumulate`] averages renders over a sequence of them, so that
    /// patterns that follow where the planes and beams fall average out.
    pub jitter: [f32; 3],
    /// Planes a view pass advances its rays over at most where the sweep allows several
    /// (beams: their light stays where the light pass left it); 0 for the default, at most 8
    /// (the lists of light tiles hold a pass of 8 planes). Each pass keeps its rays' state in
    /// registers between planes, so 1 and the default give the same image up to the rounding
    /// of the stored state (rays carried over empty bricks land where stepping puts them,
    /// whichever planes a pass skips: `step_empty_view_tiles`).
    pub view_planes: u32,
    /// Keep stepping the light no view ray still alive can read (which a render stops, with
    /// the same image). Tests only: false in every real render.
    #[doc(hidden)]
    pub keep_unseen_light: bool,
    /// Step view rays through empty bricks too (a render carries those not yet bent over
    /// them plane by plane with the steps' arithmetic: the same image to the bit). Tests
    /// only: false in every real render.
    #[doc(hidden)]
    pub step_empty_view_tiles: bool,
    /// Step the soft light's tiles next to tiles not started yet or ended at the edge, each
    /// neighbour read finding its beam's newer half, instead of keeping every beam's state
    /// in the plane's half (`halves_hold_state` in beams.wgsl): the same image to the bit.
    /// Tests only: false in every real render.
    #[doc(hidden)]
    pub light_edge_steps: bool,
    /// Step the light one dispatch per plane where a dispatch could take the planes up to the
    /// next view pass (beams that read no other beam: the same image to the bit). Tests only:
    /// false in every real render.
    #[doc(hidden)]
    pub per_plane_light: bool,
    /// Work in the tiles a GPU works in (`Pass::TILE`) where a CPU driver's render would take
    /// smaller ones (`Pass::CPU_TILE`: the same image to the bit). Tests only: false in every
    /// real render.
    #[doc(hidden)]
    pub gpu_tiles: bool,
    /// Keep the beams' power in pairs of regions where a render would keep a record of them
    /// per beam (`beam_power_texel` in common.wgsl; pairs only where a row of records is wider
    /// than the device's widest image: the same image to the bit). Tests only: false in every
    /// real render.
    #[doc(hidden)]
    pub power_in_pairs: bool,
    /// Read the deposited light as a storage buffer where a render would read it through an
    /// image over the same memory (a CPU driver, `Features::deposit_image`: the same image
    /// to the bit). Tests only: false in every real render.
    #[doc(hidden)]
    pub buffer_deposit_reads: bool,
    /// Time each pass apart: timestamps between the light, view and listing passes of every
    /// plane ([`RenderStats::pass_ms`]). A CPU driver finishes the work before each timestamp,
    /// and on lavapipe they cost about 0.08 ms per plane (a third of the fixed cost of a
    /// plane at 8×8), so a render leaves them out unless asked; the total GPU time
    /// ([`RenderStats::gpu_ms`]) is timed either way.
    pub pass_timings: bool,
    /// Give the volumes their half-resolution level even where this render does not read it
    /// (`quality.volume_level` 0), so that renders which do find it kept: the viewer, whose
    /// coarse levels read it.
    pub keep_coarse_volume: bool,
    /// Keep the staging buffer of the volumes' upload for the next render that makes them
    /// anew (another data window) or makes the gradient volume again (another η), which
    /// writes it again instead of a new one: on the CT head a new one costs about 115 ms of
    /// page faults. It stays in host-visible memory (139 MB on the CT head) and counts in
    /// later renders' memory: the viewer keeps it, a single render need not.
    pub keep_staging: bool,
    /// How the volume's textures lay out its axes in memory ([`VolumeLayout`]).
    pub volume_layout: VolumeLayout,
}

/// How far a render's sweep has got: its steps done (a step per plane: the light to plane k,
/// the view rays to plane k-1, the lists for the planes after) and their number, written by
/// the render thread after each submission and read by another (the viewer's window, which
/// shows them while a long frame renders). Zero of zero until the sweep starts, that is while
/// the scene is being set up.
#[derive(Debug, Default)]
pub struct SweepProgress {
    done: AtomicU32,
    total: AtomicU32,
}

impl SweepProgress {
    /// (done, total).
    pub fn get(&self) -> (u32, u32) {
        // The total first: a reader never sees more done than there are.
        let total = self.total.load(Ordering::Acquire);
        (self.done.load(Ordering::Acquire).min(total), total)
    }

    pub(crate) fn set(&self, done: u32, total: u32) {
        self.total.store(total, Ordering::Release);
        self.done.store(done, Ordering::Release);
    }
}

/// How a render's volume textures lay out the volume's axes in memory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum VolumeLayout {
    /// As suits the view (`ViewSetup::memory_axes_for_view`): looking along the volume's x
    /// axis, its fastest in memory, x slowest, so that each plane's samples lie near each
    /// other in memory (the CT head's scene seen from its side: the light pass 10–15 %
    /// shorter, the view 7–9 %); else as stored.
    #[default]
    ForView,
    /// As the textures kept from the render before lay it out, where they serve this render
    /// but for the layout; else as for the view. For frames that should not wait for the
    /// textures to be made anew when a turn brings another axis nearest the view (the
    /// viewer's first levels: about 0.8 s for the CT head on a CPU).
    Kept,
    /// As the volume is stored.
    Stored,
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
            sweep_progress: None,
            jitter: [0.0; 3],
            view_planes: 0,
            keep_unseen_light: false,
            step_empty_view_tiles: false,
            light_edge_steps: false,
            per_plane_light: false,
            gpu_tiles: false,
            power_in_pairs: false,
            buffer_deposit_reads: false,
            pass_timings: false,
            keep_coarse_volume: false,
            keep_staging: false,
            volume_layout: VolumeLayout::ForView,
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
    /// The sweep's GPU time by pass (timestamps between them), in milliseconds: the light
    /// passes, the view passes, the listing of the next plane's tiles with the clearing of the
    /// deposit ring and the barriers between planes, and the final pass with the read-back.
    /// They add up to `gpu_ms` less the lattice's solve (`lbm`). Zero unless the request
    /// asked for them ([`RenderRequest::pass_timings`]).
    pub pass_ms: [f64; 4],
    pub ms_per_plane: f64,
    /// Bytes of the state buffers (light, beams or light grid, view rays).
    pub state_bytes: u64,
    /// Bytes of the scene textures (volume, gradient volume, tables, environment) and the
    /// brick flags.
    pub texture_bytes: u64,
    /// Bytes copied into the scene textures for this render: all of them for a new scene,
    /// the tables after a change of sample distance or of the transfer functions (η aside),
    /// none where the kept textures served as they were.
    pub upload_bytes: u64,
    /// The most memory allocated on the device at once during the render: scene textures,
    /// state buffers, parameters, staging and read-back, by where it lives (each class's own
    /// peak). Whatever else the program held at the time counts as well.
    pub peak_memory: MemoryUse,
    /// Cells of the light grid (beams or backward lookups), width × height.
    pub light_grid: [u32; 2],
    /// Width of a light-grid cell in plane-0 pixels (its inverse: the beams traced per pixel
    /// and axis, after the caps per voxel and on the grid's size).
    pub light_cell_pixels: f32,
    /// View passes of the sweep (one per plane, or fewer where each advances the rays over
    /// several: [`RenderRequest::view_planes`]).
    pub view_passes: u32,
    /// The most planes a view pass advances its rays over: as the request asks
    /// ([`RenderRequest::view_planes`]), else as many as the ring of light they read holds (up
    /// to eight; at large sizes fewer, which decides much of the view passes' time).
    pub view_planes: u32,
    /// Light passes of the sweep: one per plane, or one per view pass where the light is
    /// stepped over a view pass's planes in one dispatch ([`RenderRequest::per_plane_light`]).
    pub light_passes: u32,
    /// Dispatch commands the sweep recorded, direct and indirect, the final pass included
    /// (each one that has work wakes a CPU driver's threads: `bench --speed`'s dispatch cost).
    pub dispatches: u32,
    /// Light-tile steps (tiles of `tile` × `tile` beams, over all planes) where light tiles
    /// are listed per plane: the light's work.
    pub light_steps: Option<u64>,
    /// The side of the sweep's tiles of pixels and beams (`Pass::TILE`, or `Pass::CPU_TILE` on
    /// a CPU driver).
    pub tile: u32,
    /// Pixels whose rays can meet the volume, width × height.
    pub rect: [u32; 2],
    /// Precision the render actually used (lower than the scene's after an out-of-memory retry).
    pub precision: Precision,
    /// Sweep pipelines compiled for this render: 0 where an earlier render or
    /// [`Renderer::precompile`] built its variant (on a CPU driver a variant's take most of a
    /// small render's time).
    pub compiled: u32,
    /// What was reduced to fit into device memory, one line each (empty normally).
    pub reductions: Vec<String>,
    /// The lattice-Boltzmann pass, when the scene has one.
    pub lbm: Option<Box<lbm::LbmStats>>,
    /// How the volume's textures laid out its axes where not as stored: axis `volume_axes[i]`
    /// of the volume as the textures' axis i, the first fastest in memory ([`VolumeLayout`]).
    pub volume_axes: Option<[u8; 3]>,
}

pub struct RenderOutput {
    pub image: RenderedImage,
    pub stats: RenderStats,
}

/// Renders prepared scenes; keeps parsed shaders and pipelines between renders.
pub struct Renderer {
    ctx: Arc<Context>,
    /// Parsed sources by file (the light and view passes share one).
    sources: HashMap<&'static str, ShaderSource>,
    pipelines: HashMap<(Pass, PipelineKey), Arc<ComputePipeline>>,
    /// Scene textures of the last render, reused while the volume, transfer functions,
    /// sample distance and environment stay the same.
    textures: Option<upload::CachedTextures>,
    lbm: Option<lbm::Pipelines>,
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
            lbm: None,
        })
    }

    pub fn context(&self) -> &Arc<Context> {
        &self.ctx
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
        self.ctx.reset_memory_peak();
        loop {
            let e = match self.render_once(prepared, &sub, precision) {
                Ok(mut out) => {
                    if (sub.width, sub.height) != (req.width, req.height) {
                        out.image = out.image.resized(req.width, req.height);
                    }
                    out.stats.reductions = reductions;
                    out.stats.texture_bytes = self.textures.as_ref().map_or(0, |t| t.textures.bytes());
                    out.stats.peak_memory = self.ctx.memory_peak().0;
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

    /// The sweep pipelines that a render of `prepared` at `req` would compile first,
    /// specialised (a few milliseconds each) and ready to be compiled on another thread; `None`
    /// where they are all built. [`Renderer::adopt`] keeps them once compiled.
    ///
    /// The viewer compiles this way, on threads of the lowest priority, the variants that one
    /// click of its panel would ask for, so that the click's frames compile nothing: a
    /// variant's seven pipelines take 0.7–1 s on a CPU driver.
    pub fn precompile(
        &mut self,
        prepared: &PreparedScene,
        req: &RenderRequest,
    ) -> Result<Option<Precompile>, RenderError> {
        let (_, _, key) = self.sweep_key(prepared, req, prepared.scene.quality.precision);
        let missing = self.missing(key);
        if missing.is_empty() {
            return Ok(None);
        }
        Ok(Some(Precompile {
            ctx: self.ctx.clone(),
            key,
            shaders: specialise(&mut self.sources, &missing, key)?,
        }))
    }

    /// Keeps the pipelines of `compiled` for the renders that need them (where a render
    /// compiled its own meanwhile, that one stays).
    pub fn adopt(&mut self, compiled: Compiled) {
        for (pass, p) in compiled.pipelines {
            self.pipelines
                .entry((pass, compiled.key))
                .or_insert_with(|| Arc::new(p));
        }
    }

    /// The features, plan and pipelines' key of a render of `prepared` at `req`.
    fn sweep_key(
        &self,
        prepared: &PreparedScene,
        req: &RenderRequest,
        precision: Precision,
    ) -> (Features, state::Plan, PipelineKey) {
        let mut features = prepared.features();
        features.deposit_image = !req.buffer_deposit_reads && state::deposit_image(&self.ctx, &features, req);
        let plan = state::plan(&self.ctx, prepared, req, &features);
        let key = PipelineKey {
            precision,
            features,
            debug: req.debug_view,
            safeguards_off: req.safeguards_off,
            spec: plan.spec,
        };
        (features, plan, key)
    }

    /// The sweep's passes whose pipelines for `key` are not built yet.
    fn missing(&self, key: PipelineKey) -> Vec<Pass> {
        Pass::ALL
            .into_iter()
            .filter(|&pass| !self.pipelines.contains_key(&(pass, key)))
            .collect()
    }

    fn render_once(
        &mut self,
        prepared: &PreparedScene,
        req: &RenderRequest,
        precision: Precision,
    ) -> Result<RenderOutput, RenderError> {
        let (features, plan, key) = self.sweep_key(prepared, req, precision);
        if features.lbm && self.lbm.is_none() {
            self.lbm = Some(lbm::Pipelines::new(&self.ctx)?);
        }
        let missing = self.missing(key);
        let compiled = missing.len() as u32;
        let Renderer {
            ctx,
            sources,
            pipelines: cache,
            textures,
            lbm,
        } = self;
        // Pipelines not built before are compiled beside the scene's setup on the CPU (the
        // textures, the light tiles' spans), which needs none of them: on a CPU driver each
        // takes about as long, and either leaves a core idle now and then.
        let ctx: &Arc<Context> = ctx;
        std::thread::scope(|scope| {
            let build = (!missing.is_empty()).then(|| scope.spawn(move || compile(ctx, sources, &missing, key)));
            let sweep = move || -> Result<[Arc<ComputePipeline>; 7], RenderError> {
                if let Some(handle) = build {
                    let built = handle
                        .join()
                        .map_err(|_| RenderError::Setup("internal: the pipelines' compilation panicked".into()))??;
                    for (pass, p) in built {
                        cache.insert((pass, key), Arc::new(p));
                    }
                }
                // In the order `state::run` indexes them.
                Ok(Pass::ALL.map(|pass| cache[&(pass, key)].clone()))
            };
            state::run(
                ctx,
                prepared,
                req,
                features,
                precision,
                state::Passes {
                    sweep: Box::new(sweep),
                    plan,
                    lbm: lbm.as_ref().filter(|_| features.lbm),
                },
                textures,
            )
        })
        .map(|mut out| {
            out.stats.compiled = compiled;
            out
        })
    }
}

/// One shader variant's sweep pipelines, specialised, to be compiled on any thread
/// ([`Renderer::precompile`]).
pub struct Precompile {
    ctx: Arc<Context>,
    key: PipelineKey,
    shaders: Vec<(Pass, String, CompiledShader)>,
}

/// Pipelines compiled from a [`Precompile`], for [`Renderer::adopt`].
pub struct Compiled {
    key: PipelineKey,
    pipelines: Vec<(Pass, ComputePipeline)>,
}

impl Precompile {
    /// Compiles the pipelines one after another on the calling thread.
    pub fn compile(self) -> Result<Compiled, RenderError> {
        let pipelines = self
            .shaders
            .iter()
            .map(|(pass, label, shader)| Ok((*pass, ComputePipeline::new(&self.ctx, label, shader)?)))
            .collect::<Result<Vec<_>, RenderError>>()?;
        Ok(Compiled {
            key: self.key,
            pipelines,
        })
    }
}

impl Compiled {
    /// Pipelines compiled.
    pub fn len(&self) -> usize {
        self.pipelines.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pipelines.is_empty()
    }
}

/// What a sweep pipeline is specialised for, beside its pass.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct PipelineKey {
    precision: Precision,
    features: Features,
    debug: DebugView,
    safeguards_off: u32,
    /// The tiles' side, the planes a view sample reads the beams back from and how the light
    /// tiles are listed and stepped (the `TILE`, `BACK_PLANES`, `LIGHT_LISTS`,
    /// `LIGHT_GROUPS` and `LIGHT_EDGE_STEPS` overrides; `state::plan`).
    spec: state::Specialisation,
}

/// The sweep's pipelines for `passes`: each specialised, then compiled side by side. Compiling
/// is most of a render's setup on a CPU driver, which turns each pipeline into machine code
/// when it is created (the CT head's seven take about half a second on lavapipe), and the
/// pipelines are independent.
fn compile(
    ctx: &Arc<Context>,
    sources: &mut HashMap<&'static str, ShaderSource>,
    passes: &[Pass],
    key: PipelineKey,
) -> Result<Vec<(Pass, ComputePipeline)>, RenderError> {
    let specialised = specialise(sources, passes, key)?;
    let built = specialised
        .par_iter()
        .map(|(_, label, compiled)| ComputePipeline::new(ctx, label, compiled))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(specialised.into_iter().map(|(pass, _, _)| pass).zip(built).collect())
}

/// The shaders of the sweep's `passes` specialised for `key`, each with its pipeline's label.
fn specialise(
    sources: &mut HashMap<&'static str, ShaderSource>,
    passes: &[Pass],
    key: PipelineKey,
) -> Result<Vec<(Pass, String, CompiledShader)>, RenderError> {
    let mut specialised = Vec::new();
    for &pass in passes {
        let source = match sources.entry(pass.file()) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => e.insert(pass.parse()?),
        };
        let mut constants = key.features.constants(key.debug, key.precision);
        for c in constants.iter_mut() {
            match c.0 {
                "SAFEGUARDS_OFF" => c.1 = key.safeguards_off as f64,
                "TILE" => c.1 = key.spec.tile as f64,
                "BACK_PLANES" => c.1 = key.spec.back_planes as f64,
                "LIGHT_GROUPS" => c.1 = f64::from(u8::from(key.spec.light_groups)),
                "LIGHT_LISTS" => c.1 = f64::from(u8::from(key.spec.light_lists)),
                "LIGHT_EDGE_STEPS" => c.1 = f64::from(u8::from(key.spec.light_edge_steps)),
                _ => {}
            }
        }
        let compiled = source.specialise(pass.entry(), &constants)?;
        let label = format!(
            "{}:{} [{} {}]",
            pass.file(),
            pass.entry(),
            key.features.describe(),
            key.precision.name()
        );
        specialised.push((pass, label, compiled));
    }
    Ok(specialised)
}

/// Environment parameters: (rgb background, 1 when an environment map is used).
fn background(env: &Environment) -> [f32; 4] {
    match env {
        Environment::Color { color } => [color[0], color[1], color[2], 0.0],
        _ => [0.0, 0.0, 0.0, 1.0],
    }
}
