//! The render thread: owns the [`Renderer`] and the loaded volume, renders what the window
//! asks for and sends the images back, so the window never waits for the GPU.
//!
//! The Vulkan queue is only ever used from this thread; the window thread only sends requests
//! (latest wins) and raises a cancel flag when a running refinement became outdated.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;

use crate::render::{
    jitter_sequence, EnvMap, PreparedScene, RenderError, RenderRequest, RenderStats, RenderedImage, Renderer,
    SweepProgress, VolumeLayout,
};
use crate::scene::{Scene, VolumeSource};
use crate::{Classify, ExitClass};

use super::progressive::{Job, ACCUMULATE};

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
    while let Ok(first) = requests.recv() {
        // Screenshots are all kept, in order; of the frames only the newest matters.
        let mut frame = None;
        for request in std::iter::once(first).chain(requests.try_iter()) {
            match request {
                Request::Frame { .. } => {
                    if let Some(Request::Frame { job, .. }) = frame.replace(request) {
                        send(Reply::Cancelled { job });
                    }
                }
                screenshot => handle(&mut renderer, &mut prepared, allow_downsample, screenshot, &send),
            }
        }
        if let Some(f) = frame {
            handle(&mut renderer, &mut prepared, allow_downsample, f, &send);
        }
    }
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

fn handle(
    renderer: &mut Renderer,
    prepared: &mut PreparedScene,
    allow_downsample: bool,
    request: Request,
    send: &dyn Fn(Reply),
) {
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
                return;
            }
            let start = Instant::now();
            let half_resolution = scene.quality.volume_level > 0;
            let result = set_scene(renderer, prepared, allow_downsample, *scene, send).and_then(|()| {
                let mut req = RenderRequest::new(width, height);
                req.cancel = Some(cancel);
                req.sweep_progress = Some(progress);
                req.pass_timings = pass_timings;
                // The coarse levels read the volumes' half-resolution level: made with the
                // first frame, so no level uploads the volumes again.
                req.keep_coarse_volume = true;
                // A drag of the data window or of η writes the volumes' staging buffer again.
                req.keep_staging = true;
                // The levels that sample the half-resolution volume keep the textures' layout
                // (a turn would make them anew whenever it brings another layout's axis nearest
                // the view); those at full resolution lay them out for their view, made anew
                // once after such a turn (0.8 s for the CT head, which the full frame and its
                // accumulation passes gain back: `VolumeLayout`).
                if half_resolution {
                    req.volume_layout = VolumeLayout::Kept;
                }
                // Accumulation passes move the planes and the light grid (pass 0 does not).
                req.jitter = jitter_sequence(job.pass, ACCUMULATE);
                renderer.render(prepared, &req)
            });
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
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::{Context, ContextDesc, DeviceSelector};
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
