//! The render thread: owns the [`Renderer`] and the loaded volume, renders what the window
//! asks for and sends the images back, so the window never waits for the GPU.
//!
//! The Vulkan queue is only ever used from this thread; the window thread only sends requests
//! (latest wins) and raises a cancel flag when a running refinement became outdated.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender, TryRecvError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::render::{
    jitter_sequence, Compiled, EnvMap, Precompile, PreparedScene, RenderError, RenderRequest, RenderStats,
    RenderedImage, Renderer, SweepProgress, VolumeLayout,
};
use crate::scene::{ClipPlane, LightTransport, MultipleScattering, Scene, Toggle, VolumeSource};
use crate::{Classify, ExitClass};

use super::progressive::{Job, ACCUMULATE, FULL};

/// What the window asks for.
pub enum Request {
    /// A frame of the view; `scene` already has the level's sample distance.
    Frame {
        job: Job,
        scene: Box<Scene>,
        width: u32,
        height: u32,
        cancel: Arc<AtomicBool>,
        /// Where the frame's sweep has got, for the window to show while it renders.
        progress: Arc<SweepProgress>,
        /// Time each pass apart (the frame log prints them).
        pass_timings: bool,
    },
    /// A full-quality offscreen render written to `path` (PNG or EXR).
    Screenshot {
        scene: Box<Scene>,
        width: u32,
        height: u32,
        path: PathBuf,
    },
}

/// What the render thread answers.
pub enum Reply {
    Frame {
        job: Job,
        image: RenderedImage,
        stats: Box<RenderStats>,
        duration_ms: f64,
    },
    Cancelled {
        job: Job,
    },
    Failed {
        job: Option<Job>,
        message: String,
        /// How the command line ends if this failure ends the viewer.
        class: ExitClass,
    },
    Saved {
        path: PathBuf,
        result: Result<(), String>,
    },
    /// A time series moved to another frame: the histogram bars of the new frame's values
    /// (see [`super::panel::histogram`]), sent before the first image of that frame.
    Volume {
        frame: usize,
        histogram: Vec<f32>,
    },
    /// The shader variants one click of the panel away from the settled view are built:
    /// `pipelines` compiled for `variants` on threads of the lowest priority, `ms` after the
    /// view settled, so that such a click's frames compile nothing. Sent when any was compiled.
    Precompiled {
        variants: usize,
        pipelines: usize,
        ms: f64,
    },
}

pub struct Worker {
    requests: Option<Sender<Request>>,
    pub replies: Receiver<Reply>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts the thread; `wake` is called after every reply (to wake the event loop).
    /// A frame of a time series loaded later is downsampled to the device's limits when
    /// `allow_downsample`, as the first one was.
    pub fn start(
        renderer: Renderer,
        prepared: PreparedScene,
        allow_downsample: bool,
        wake: impl Fn() + Send + 'static,
    ) -> Worker {
        let (req_tx, req_rx) = channel::<Request>();
        let (rep_tx, rep_rx) = channel::<Reply>();
        let thread = std::thread::Builder::new()
            .name("caustica render".into())
            .spawn(move || run(renderer, prepared, allow_downsample, req_rx, rep_tx, wake))
            .ok();
        Worker {
            requests: Some(req_tx),
            replies: rep_rx,
            thread,
        }
    }

    pub fn send(&self, request: Request) {
        if let Some(tx) = &self.requests {
            let _ = tx.send(request);
        }
    }

    /// Stops the thread after its current render and waits for it: the renderer and every
    /// GPU object it holds are destroyed before this returns.
    pub fn stop(&mut self) {
        self.requests.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.stop();
    }
}

/// A render the window may ask for after one click of the panel: its scene and size.
struct Variant {
    scene: Scene,
    width: u32,
    height: u32,
}

/// The shader variants still to build for the settled view, the threads that compile them,
/// and what building them took.
#[derive(Default)]
struct Precompiler {
    variants: VecDeque<Variant>,
    /// Threads compiling the variants' pipelines at the lowest priority, so that the render
    /// thread's frames are neither held up nor slowed down by them: started with the first
    /// variant to compile, they take each one's specialised shaders and hand back its
    /// pipelines.
    threads: Option<CompileThreads>,
    /// Variants handed to the threads and not back yet.
    in_flight: usize,
    /// When the settled view's variants started, the variants looked at and the pipelines
    /// compiled, for [`Reply::Precompiled`].
    started: Option<Instant>,
    looked_at: usize,
    pipelines: usize,
    /// The variants that may still be compiled ahead in this session; `None`: no bound.
    budget: Option<usize>,
}

/// The variants compiled ahead in a session on a CPU driver, about two settled views' worth
/// of new ones. On lavapipe each adds 25–36 MB of host memory that destroying its pipelines
/// does not give back (LLVM's code and caches), so without a bound a session that clicks
/// through many combinations of the switches would gather gigabytes; these take at most
/// about 0.9 GB. A GPU driver's pipelines take far less: no bound there.
const CPU_PRECOMPILE_BUDGET: usize = 24;

struct CompileThreads {
    jobs: Option<Sender<Precompile>>,
    done: Receiver<Result<Compiled, RenderError>>,
    handles: Vec<JoinHandle<()>>,
}

impl CompileThreads {
    /// One per core: each compiles a variant's pipelines one after another.
    fn start() -> CompileThreads {
        let (jobs, job_rx) = channel::<Precompile>();
        let job_rx = Arc::new(std::sync::Mutex::new(job_rx));
        let (done_tx, done) = channel();
        let n = std::thread::available_parallelism().map_or(1, |n| n.get());
        let handles = (0..n)
            .filter_map(|_| {
                let (job_rx, done_tx) = (job_rx.clone(), done_tx.clone());
                std::thread::Builder::new()
                    .name("caustica compile".into())
                    .spawn(move || {
                        if let Err(e) =
                            thread_priority::set_current_thread_priority(thread_priority::ThreadPriority::Min)
                        {
                            log::debug!("a compile thread keeps its priority: {e:?}");
                        }
                        loop {
                            let job = match job_rx.lock() {
                                Ok(rx) => rx.recv(),
                                Err(_) => break,
                            };
                            let Ok(job) = job else { break };
                            if done_tx.send(job.compile()).is_err() {
                                break;
                            }
                        }
                    })
                    .ok()
            })
            .collect();
        CompileThreads {
            jobs: Some(jobs),
            done,
            handles,
        }
    }
}

impl Drop for CompileThreads {
    /// Waits for the pipelines being compiled: no GPU object outlives the render thread.
    fn drop(&mut self) {
        self.jobs.take();
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

impl Precompiler {
    /// One that compiles at most `budget` variants ahead (`None`: any number).
    fn with_budget(budget: Option<usize>) -> Precompiler {
        Precompiler {
            budget,
            ..Precompiler::default()
        }
    }

    /// Starts over with the variants one click away from `frames` (the settled view's
    /// requests, the level a click's first frame renders at first).
    fn start(&mut self, frames: &[(&Scene, u32, u32)]) {
        self.variants.clear();
        for &(scene, width, height) in frames {
            self.variants.extend(
                one_click_variants(scene)
                    .into_iter()
                    .map(|scene| Variant { scene, width, height }),
            );
        }
        self.started = Some(Instant::now());
        self.looked_at = 0;
        self.pipelines = 0;
    }

    /// The view is being edited: what is one click away is worked out again when it settles
    /// (the variants being compiled are still taken).
    fn forget(&mut self) {
        self.variants.clear();
        self.started = None;
    }

    /// Whether variants are left to compile or being compiled.
    fn busy(&self) -> bool {
        self.in_flight > 0 || !self.variants.is_empty()
    }

    /// Takes the pipelines the threads have compiled and hands each idle one the next variant
    /// that needs any. Returns the reply to send once the settled view's last variant is built.
    fn poll(&mut self, renderer: &mut Renderer, prepared: &mut PreparedScene) -> Option<Reply> {
        if let Some(t) = &self.threads {
            while self.in_flight > 0 {
                match t.done.try_recv() {
                    Ok(Ok(compiled)) => {
                        self.pipelines += compiled.len();
                        renderer.adopt(compiled);
                    }
                    // Its render, if the window asks for it, reports the error.
                    Ok(Err(e)) => log::debug!("a variant was not compiled ahead: {e}"),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => {
                        self.in_flight = 0;
                        break;
                    }
                }
                self.in_flight -= 1;
            }
        }
        loop {
            let idle = self.threads.as_ref().map_or(1, |t| t.handles.len()) > self.in_flight;
            if !idle {
                break;
            }
            if self.budget == Some(0) {
                self.variants.clear();
                break;
            }
            let Some(v) = self.variants.pop_front() else {
                break;
            };
            self.looked_at += 1;
            // The variant's scene differs from the one prepared in its switches alone (the
            // same volume and transfer functions): in place for the plan, then put back.
            let kept = std::mem::replace(&mut prepared.scene, v.scene);
            let req = frame_request(&prepared.scene, v.width, v.height, 0);
            let job = renderer.precompile(prepared, &req);
            prepared.scene = kept;
            match job {
                Ok(Some(job)) => {
                    let threads = self.threads.get_or_insert_with(CompileThreads::start);
                    match threads.jobs.as_ref().map(|jobs| jobs.send(job)) {
                        Some(Ok(())) if !threads.handles.is_empty() => {
                            self.in_flight += 1;
                            if let Some(b) = self.budget.as_mut() {
                                *b -= 1;
                                if *b == 0 {
                                    log::info!(
                                        "the panel's variants are compiled ahead no more in this session (each \
                                         holds about 30 MB of host memory on a CPU driver): a switch to another \
                                         compiles it in its first frame"
                                    );
                                }
                            }
                        }
                        _ => {
                            self.variants.clear();
                            break;
                        }
                    }
                }
                Ok(None) => {}
                Err(e) => log::debug!("a variant was not specialised ahead: {e}"),
            }
        }
        if self.busy() || self.pipelines == 0 {
            return None;
        }
        let started = self.started.take()?;
        Some(Reply::Precompiled {
            variants: self.looked_at,
            pipelines: std::mem::take(&mut self.pipelines),
            ms: started.elapsed().as_secs_f64() * 1e3,
        })
    }
}

/// `scene` after each click of the panel's switches that picks another shader variant
/// (`panel::sections`' effects and clip): refraction, the light's transport, the caustic
/// correction of the backward transport, soft light, highlights and the clip plane. Most
/// likely first; variants that come out the same are compiled once.
fn one_click_variants(scene: &Scene) -> Vec<Scene> {
    let mut out = Vec::new();
    let mut with = |change: &dyn Fn(&mut Scene)| {
        let mut s = scene.clone();
        change(&mut s);
        out.push(s);
    };
    for t in [Toggle::Off, Toggle::Auto, Toggle::On] {
        if t != scene.quality.refraction {
            with(&|s| s.quality.refraction = t);
        }
    }
    with(&|s| s.quality.light_filter = !s.quality.light_filter);
    with(&|s| s.quality.specular = !s.quality.specular);
    match scene.quality.light_transport {
        LightTransport::Beams if scene.quality.multiple_scattering != MultipleScattering::Spread => {
            with(&|s| s.quality.light_transport = LightTransport::Backward)
        }
        LightTransport::Beams => {}
        LightTransport::Backward => {
            with(&|s| s.quality.light_transport = LightTransport::Beams);
            with(&|s| s.quality.intensity_correction = !s.quality.intensity_correction);
        }
    }
    with(&|s| {
        s.clip = match s.clip {
            Some(_) => None,
            None => Some(ClipPlane::CENTRE_Z),
        }
    });
    out
}

fn run(
    mut renderer: Renderer,
    mut prepared: PreparedScene,
    allow_downsample: bool,
    requests: Receiver<Request>,
    replies: Sender<Reply>,
    wake: impl Fn(),
) {
    let send = |r: Reply| {
        let _ = replies.send(r);
        wake();
    };
    // Once a view has settled to its full frame, the variants one click away are compiled
    // beside it, and its accumulation passes wait for them: a click is worth more than the
    // passes it delays, and its frames then compile nothing (0.7–1 s per variant on a CPU
    // driver).
    let mut precompiler = Precompiler::with_budget(renderer.context().is_cpu().then_some(CPU_PRECOMPILE_BUDGET));
    // The newest interactive frame's request, for the variants' first frames.
    let mut interactive: Option<(u64, Scene, u32, u32)> = None;
    // An accumulation pass waiting for the variants.
    let mut held: Option<Request> = None;
    loop {
        let mut batch = Vec::new();
        let mut closed = false;
        if precompiler.busy() {
            // The compile threads are looked at between requests.
            match requests.recv_timeout(COMPILE_POLL) {
                Ok(r) => batch.push(r),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => closed = true,
            }
        } else if held.is_none() {
            match requests.recv() {
                Ok(r) => batch.push(r),
                Err(_) => return,
            }
        }
        while !closed {
            match requests.try_recv() {
                Ok(r) => batch.push(r),
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => closed = true,
            }
        }
        // Screenshots are all kept, in order; of the frames only the newest matters.
        let mut frame = held.take();
        for request in batch {
            match request {
                Request::Frame { .. } => {
                    if let Some(Request::Frame { job, .. }) = frame.replace(request) {
                        send(Reply::Cancelled { job });
                    }
                }
                screenshot => {
                    handle(&mut renderer, &mut prepared, allow_downsample, screenshot, &send);
                }
            }
        }
        if let Some(reply) = precompiler.poll(&mut renderer, &mut prepared) {
            send(reply);
        }
        // Once the window has gone, a frame would be rendered for no one.
        if closed {
            return;
        }
        let Some(f) = frame else {
            continue;
        };
        let Request::Frame { job, width, height, .. } = f else {
            unreachable!("only frames are kept")
        };
        if job.level == FULL && job.pass > 0 && precompiler.busy() {
            held = Some(f);
            continue;
        }
        // A frame rendered leaves its scene in `prepared` (`set_scene`).
        let rendered = handle(&mut renderer, &mut prepared, allow_downsample, f, &send);
        if job.level < FULL {
            precompiler.forget();
        }
        if rendered && job.level == 0 {
            interactive = Some((job.version, prepared.scene.clone(), width, height));
        }
        if rendered && job.level == FULL && job.pass == 0 {
            let mut frames = Vec::new();
            if let Some((version, s, w, h)) = &interactive {
                if *version == job.version {
                    frames.push((s, *w, *h));
                }
            }
            frames.push((&prepared.scene, width, height));
            precompiler.start(&frames);
            if let Some(reply) = precompiler.poll(&mut renderer, &mut prepared) {
                send(reply);
            }
        }
    }
}

/// How often the render thread looks at the compile threads while it has nothing to render.
const COMPILE_POLL: Duration = Duration::from_millis(20);

/// The request for a frame of `scene` at `width` × `height`, `pass` its accumulation pass
/// (the cancel flag and the progress aside).
fn frame_request(scene: &Scene, width: u32, height: u32, pass: u32) -> RenderRequest {
    let mut req = RenderRequest::new(width, height);
    // The coarse levels read the volumes' half-resolution level: made with the first frame
    // and kept by the levels at full resolution, so that no coarse level uploads the volumes
    // again. A coarse frame that must make them anew after a change of the data window, of η
    // or of the volume makes the half level alone, an eighth of the volumes; the next level
    // at full resolution makes the rest.
    req.keep_coarse_volume = true;
    // A drag of the data window or of η writes the volumes' staging buffer again.
    req.keep_staging = true;
    // The levels that sample the half-resolution volume keep the textures' layout (a turn
    // would make them anew whenever it brings another layout's axis nearest the view); those
    // at full resolution lay them out for their view, made anew once after such a turn (0.8 s
    // for the CT head, which the full frame and its accumulation passes gain back:
    // `VolumeLayout`).
    if scene.quality.volume_level > 0 {
        req.volume_layout = VolumeLayout::Kept;
    }
    // Accumulation passes move the planes and the light grid (pass 0 does not).
    req.jitter = jitter_sequence(pass, ACCUMULATE);
    req
}

/// Makes `prepared` the data of `scene`. A new frame of a time series is loaded here, on the
/// render thread, and fitted to the device like the first one; its histogram goes to the window.
fn set_scene(
    renderer: &Renderer,
    prepared: &mut PreparedScene,
    allow_downsample: bool,
    scene: Scene,
    send: &dyn Fn(Reply),
) -> Result<(), RenderError> {
    if scene.volume != prepared.scene.volume {
        let VolumeSource::Series { frame, .. } = scene.volume else {
            return Err(RenderError::Setup(
                "the viewer cannot switch to another volume; open it with `caustica view FILE`".into(),
            ));
        };
        let before = (
            std::mem::replace(&mut prepared.scene.volume, scene.volume.clone()),
            prepared.volume.clone(),
            prepared.volume_info.clone(),
        );
        let loaded = prepared
            .load_frame(frame)
            .and_then(|()| crate::input::fit_to_device(prepared, renderer.context(), allow_downsample, true));
        if let Err(e) = loaded {
            // Back to the frame that was there: the next request for this one tries again.
            (prepared.scene.volume, prepared.volume, prepared.volume_info) = before;
            return Err(e.into());
        }
        let window = scene.window.unwrap_or(prepared.volume_info.default_window);
        send(Reply::Volume {
            frame,
            histogram: super::panel::histogram(&prepared.volume.data, window),
        });
    }
    if scene.environment != prepared.scene.environment {
        prepared.env = EnvMap::for_scene(&scene.environment)?;
    }
    prepared.tf = scene.transfer_functions()?;
    prepared.scene = scene;
    Ok(())
}

/// Renders a frame or a screenshot and sends what came of it. Returns whether a frame was
/// rendered.
fn handle(
    renderer: &mut Renderer,
    prepared: &mut PreparedScene,
    allow_downsample: bool,
    request: Request,
    send: &dyn Fn(Reply),
) -> bool {
    match request {
        Request::Frame {
            job,
            scene,
            width,
            height,
            cancel,
            progress,
            pass_timings,
        } => {
            if cancel.load(Ordering::Relaxed) {
                send(Reply::Cancelled { job });
                return false;
            }
            let start = Instant::now();
            let result = set_scene(renderer, prepared, allow_downsample, *scene, send).and_then(|()| {
                let mut req = frame_request(&prepared.scene, width, height, job.pass);
                req.cancel = Some(cancel);
                req.sweep_progress = Some(progress);
                req.pass_timings = pass_timings;
                renderer.render(prepared, &req)
            });
            let rendered = result.is_ok();
            send(match result {
                Ok(out) => Reply::Frame {
                    job,
                    image: out.image,
                    stats: Box::new(out.stats),
                    duration_ms: start.elapsed().as_secs_f64() * 1e3,
                },
                Err(RenderError::Cancelled) => Reply::Cancelled { job },
                Err(e) => Reply::Failed {
                    job: Some(job),
                    message: e.to_string(),
                    class: e.exit_class(),
                },
            });
            rendered
        }
        Request::Screenshot {
            scene,
            width,
            height,
            path,
        } => {
            let result = set_scene(renderer, prepared, allow_downsample, *scene, send)
                .and_then(|()| renderer.render(prepared, &RenderRequest::new(width, height)))
                .map_err(|e| e.to_string())
                .and_then(|out| super::save::save_image(&out.image, &path).map_err(|e| format!("{e:#}")));
            send(Reply::Saved { path, result });
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::{Context, ContextDesc, DeviceSelector};
    use crate::render::Features;
    use crate::scene::{builtin, VolumeSource};
    use std::time::Duration;

    /// A request for `job`, a frame of `scene` at w×h, its cancel flag already raised or not,
    /// its sweep reported to `progress`.
    fn frame(job: Job, scene: &Scene, (w, h): (u32, u32), cancelled: bool, progress: &Arc<SweepProgress>) -> Request {
        Request::Frame {
            job,
            scene: Box::new(scene.clone()),
            width: w,
            height: h,
            cancel: Arc::new(AtomicBool::new(cancelled)),
            progress: progress.clone(),
            pass_timings: false,
        }
    }

    fn small_scene() -> Scene {
        let mut scene = builtin("ball-lens").unwrap().scene;
        scene.volume = VolumeSource::builtin("ball-lens", 32);
        scene
    }

    /// The screenshot path renders offscreen at the requested size with the same renderer,
    /// PNG and EXR; a frame whose cancel flag is already set is answered as cancelled.
    #[test]
    fn screenshots_match_a_direct_render_and_cancel_is_honoured() {
        let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::Auto)).expect("Vulkan device");
        let scene = small_scene();
        let prepared = PreparedScene::load(&scene).unwrap();
        let mut direct = Renderer::new(ctx.clone()).unwrap();
        let expected = direct.render(&prepared, &RenderRequest::new(40, 30)).unwrap().image;
        drop(direct);

        let worker_prepared = PreparedScene::load(&scene).unwrap();
        let mut worker = Worker::start(Renderer::new(ctx.clone()).unwrap(), worker_prepared, true, || {});
        let dir = std::env::temp_dir().join(format!("caustica-worker-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let job = |version| Job {
            version,
            level: 2,
            pass: 0,
        };
        let (cancelled, rendered) = (job(7), job(8));
        let cancelled_progress = Arc::new(SweepProgress::default());
        worker.send(frame(cancelled, &scene, (40, 30), true, &cancelled_progress));
        // A frame rendered: its progress ends with every step of its sweep done.
        let progress = Arc::new(SweepProgress::default());
        worker.send(frame(rendered, &scene, (40, 30), false, &progress));
        for ext in ["png", "exr"] {
            worker.send(Request::Screenshot {
                scene: Box::new(scene.clone()),
                width: 40,
                height: 30,
                path: dir.join(format!("shot.{ext}")),
            });
        }
        let (mut saved, mut was_cancelled, mut planes_run) = (0, false, None);
        while saved < 2 || !was_cancelled || planes_run.is_none() {
            match worker.replies.recv_timeout(Duration::from_secs(120)).expect("a reply") {
                Reply::Saved { result, .. } => {
                    result.unwrap();
                    saved += 1;
                }
                Reply::Cancelled { job } => was_cancelled = job == cancelled,
                Reply::Frame { job, stats, .. } => {
                    assert_eq!(job, rendered, "a cancelled frame was rendered");
                    planes_run = Some(stats.planes_run);
                }
                Reply::Failed { message, .. } => panic!("{message}"),
                Reply::Volume { .. } => panic!("the volume did not change"),
                Reply::Precompiled { .. } => panic!("no full frame was asked for"),
            }
        }
        worker.stop();
        assert!(was_cancelled);
        // It ends at the sweep's last step: one per plane the image integrates.
        let planes_run = planes_run.unwrap();
        assert!(planes_run > 1, "{planes_run} planes");
        assert_eq!(
            progress.get(),
            (planes_run, planes_run),
            "the rendered frame's progress"
        );
        assert_eq!(cancelled_progress.get(), (0, 0), "a frame cancelled before it started");
        let png = image::open(dir.join("shot.png")).unwrap().to_rgba8();
        assert_eq!((png.width(), png.height()), (40, 30));
        assert_eq!(
            png.into_raw(),
            expected.to_srgb8(),
            "PNG = the direct render, byte for byte"
        );
        let exr = exr::prelude::read_first_rgba_layer_from_file(
            dir.join("shot.exr"),
            |res, _| vec![[0f32; 4]; res.width() * res.height()],
            |px: &mut Vec<[f32; 4]>, pos, (r, g, b, a): (f32, f32, f32, f32)| px[pos.y() * 40 + pos.x()] = [r, g, b, a],
        )
        .unwrap();
        assert_eq!(
            exr.layer_data.channel_data.pixels, expected.pixels,
            "EXR keeps the linear floats"
        );
        assert_eq!(ctx.validation_errors(), 0, "{:?}", ctx.validation_messages());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Once a view settles to its full frame, the render thread compiles the shader variants
    /// one click of the panel away, at the interactive level's request and the full frame's,
    /// before the accumulation pass asked for meanwhile: each such click's frames then compile
    /// nothing, while a view two clicks away still compiles its variant.
    #[test]
    fn the_variants_one_click_away_are_compiled_before_the_accumulation_passes() {
        let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::Auto)).expect("Vulkan device");
        // Planes half a voxel apart, so that the full frame's view samples read the beams back
        // from two planes and the interactive level's from one: two variants of each scene.
        let mut scene = small_scene();
        scene.quality.sample_distance = 0.5;
        // The interactive level's scene, as the window makes it: planes further apart, fewer
        // beams, the half-resolution volume, a smaller image.
        let mut coarse = scene.clone();
        coarse.quality.sample_distance *= 6.0;
        coarse.quality.beams_per_texel *= 0.25;
        coarse.quality.volume_level = 1;
        let prepared = PreparedScene::load(&scene).unwrap();
        let mut worker = Worker::start(Renderer::new(ctx.clone()).unwrap(), prepared, true, || {});
        let progress = Arc::new(SweepProgress::default());
        let job = |version, level, pass| Job { version, level, pass };
        let reply = |worker: &Worker| worker.replies.recv_timeout(Duration::from_secs(300)).expect("a reply");
        let compiled = |worker: &Worker, request: Request| {
            worker.send(request);
            match reply(worker) {
                Reply::Frame { stats, .. } => stats.compiled,
                Reply::Failed { message, .. } => panic!("{message}"),
                _ => panic!("unexpected reply"),
            }
        };
        assert!(compiled(&worker, frame(job(1, 0, 0), &coarse, (20, 15), false, &progress)) > 0);
        assert!(compiled(&worker, frame(job(1, FULL, 0), &scene, (40, 30), false, &progress)) > 0);
        // The first accumulation pass, asked for once the full frame is on screen, comes after
        // the variants.
        worker.send(frame(job(1, FULL, 1), &scene, (40, 30), false, &progress));
        let mut replies = Vec::new();
        while replies.len() < 2 {
            match reply(&worker) {
                Reply::Precompiled {
                    variants, pipelines, ..
                } => {
                    assert_eq!(variants, 2 * one_click_variants(&scene).len());
                    assert!(pipelines > 0);
                    replies.push("precompiled");
                }
                Reply::Frame { job, stats, .. } => {
                    assert_eq!(job.pass, 1);
                    assert_eq!(stats.compiled, 0);
                    replies.push("accumulation pass");
                }
                Reply::Failed { message, .. } => panic!("{message}"),
                _ => panic!("unexpected reply"),
            }
        }
        assert_eq!(replies, ["precompiled", "accumulation pass"]);
        let mut version = 2;
        for (fine, coarse) in one_click_variants(&scene).iter().zip(one_click_variants(&coarse)) {
            for (s, size, level) in [(&coarse, (20, 15), 0), (fine, (40, 30), FULL)] {
                let n = compiled(&worker, frame(job(version, level, 0), s, size, false, &progress));
                assert_eq!(
                    n,
                    0,
                    "{:?} at level {level}",
                    Features::for_scene(s, &s.transfer_functions().unwrap())
                );
            }
            version += 1;
        }
        // Two clicks away: refraction off and no soft light.
        let mut two = scene.clone();
        two.quality.refraction = Toggle::Off;
        two.quality.light_filter = !two.quality.light_filter;
        assert!(compiled(&worker, frame(job(version, FULL, 0), &two, (40, 30), false, &progress)) > 0);
        worker.stop();
        assert_eq!(ctx.validation_errors(), 0, "{:?}", ctx.validation_messages());
    }

    #[test]
    fn no_more_variants_are_compiled_ahead_than_the_budget() {
        let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::Auto)).expect("Vulkan device");
        let scene = small_scene();
        let mut prepared = PreparedScene::load(&scene).unwrap();
        let mut renderer = Renderer::new(ctx.clone()).unwrap();
        let size = (20, 15);
        // Whether a variant's pipelines are all built.
        let built = |renderer: &mut Renderer, prepared: &mut PreparedScene, variant: &Scene| {
            let kept = std::mem::replace(&mut prepared.scene, variant.clone());
            let job = renderer.precompile(prepared, &frame_request(&prepared.scene, size.0, size.1, 0));
            prepared.scene = kept;
            job.unwrap().is_none()
        };
        let variants = one_click_variants(&scene);
        assert!(variants.len() > 2);
        assert!(variants.iter().all(|v| !built(&mut renderer, &mut prepared, v)));
        let mut precompiler = Precompiler::with_budget(Some(2));
        let settle = |precompiler: &mut Precompiler, renderer: &mut Renderer, prepared: &mut PreparedScene| {
            precompiler.start(&[(&scene, size.0, size.1)]);
            let mut replies = Vec::new();
            let deadline = Instant::now() + Duration::from_secs(300);
            loop {
                replies.extend(precompiler.poll(renderer, prepared));
                if !precompiler.busy() || Instant::now() > deadline {
                    break;
                }
                std::thread::sleep(COMPILE_POLL);
            }
            assert!(!precompiler.busy(), "still compiling after 300 s");
            replies
        };
        let replies = settle(&mut precompiler, &mut renderer, &mut prepared);
        assert!(matches!(replies[..], [Reply::Precompiled { variants: 2, .. }]));
        // The two most likely variants are built, the others are left to their first frames.
        let now_built: Vec<bool> = variants
            .iter()
            .map(|v| built(&mut renderer, &mut prepared, v))
            .collect();
        assert!(
            now_built[..2].iter().all(|&b| b) && !now_built[2..].iter().any(|&b| b),
            "{now_built:?}"
        );
        // Settling again compiles nothing more: the budget is spent.
        assert!(settle(&mut precompiler, &mut renderer, &mut prepared).is_empty());
        assert!(variants[2..].iter().all(|v| !built(&mut renderer, &mut prepared, v)));
        drop(precompiler);
        assert_eq!(ctx.validation_errors(), 0, "{:?}", ctx.validation_messages());
    }

    /// A request for another frame of a time series loads it on the render thread: the
    /// window first gets that frame's histogram, then the image, which is the direct render
    /// of the frame.
    #[test]
    fn a_new_frame_is_loaded_with_its_histogram() {
        let dir = std::env::temp_dir().join(format!("caustica-worker-series-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (k, name) in ["ball-lens", "glass"].iter().enumerate() {
            let v = crate::volume::procedural::generate(name, 16).unwrap();
            crate::volume::nrrd::write_nrrd(&dir.join(format!("t{k}.nrrd")), &v, false).unwrap();
        }
        let mut scene = small_scene();
        scene.volume = VolumeSource::Series {
            files: Vec::new(),
            pattern: Some(dir.join("t*.nrrd")),
            frame: 0,
        };
        scene.window = Some([0.0, 1.0]);
        let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::Auto)).expect("Vulkan device");
        let mut later = scene.clone();
        later.volume.set_frame(1);
        let frame1 = PreparedScene::load(&later).unwrap();
        let expected_bars = crate::app::panel::histogram(&frame1.volume.data, [0.0, 1.0]);
        let mut direct = Renderer::new(ctx.clone()).unwrap();
        let expected = direct.render(&frame1, &RenderRequest::new(32, 24)).unwrap().image;
        drop(direct);

        let prepared = PreparedScene::load(&scene).unwrap();
        assert_ne!(
            crate::app::panel::histogram(&prepared.volume.data, [0.0, 1.0]),
            expected_bars,
            "the frames differ"
        );
        let mut worker = Worker::start(Renderer::new(ctx.clone()).unwrap(), prepared, true, || {});
        let job = |version| Job {
            version,
            level: 0,
            pass: 0,
        };
        let progress = Arc::new(SweepProgress::default());
        worker.send(frame(job(1), &later, (32, 24), false, &progress));
        let mut bars = None;
        let image = loop {
            match worker.replies.recv_timeout(Duration::from_secs(120)).expect("a reply") {
                Reply::Volume { frame, histogram } => bars = Some((frame, histogram)),
                Reply::Frame { image, .. } => break image,
                Reply::Failed { message, .. } => panic!("{message}"),
                _ => panic!("unexpected reply"),
            }
        };
        // A frame that cannot be read fails, and fails again when asked for again (the render
        // thread does not take the frame it kept for the broken one).
        std::fs::write(dir.join("t2.nrrd"), b"NRRD0004\nnot a header\n").unwrap();
        let mut broken = scene.clone();
        broken.volume.set_frame(2);
        for version in [2, 3] {
            worker.send(frame(job(version), &broken, (32, 24), false, &progress));
            match worker.replies.recv_timeout(Duration::from_secs(120)).expect("a reply") {
                Reply::Failed { message, .. } => assert!(message.contains("t2.nrrd"), "{message}"),
                _ => panic!("frame 2 is broken, yet the request did not fail"),
            }
        }
        worker.stop();
        assert_eq!(bars, Some((1, expected_bars)), "the histogram of frame 1 comes first");
        assert_eq!(image.pixels, expected.pixels, "the image is the render of frame 1");
        assert_eq!(ctx.validation_errors(), 0, "{:?}", ctx.validation_messages());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
