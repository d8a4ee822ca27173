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

use crate::render::{EnvMap, PreparedScene, RenderError, RenderRequest, RenderStats, RenderedImage, Renderer};
use crate::scene::Scene;

use super::progressive::Job;

/// What the window asks for.
pub enum Request {
    /// A frame of the view; `scene` already has the level's sample distance.
    Frame {
        job: Job,
        scene: Box<Scene>,
        width: u32,
        height: u32,
        cancel: Arc<AtomicBool>,
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
        stats: RenderStats,
        duration_ms: f64,
    },
    Cancelled {
        job: Job,
    },
    Failed {
        job: Option<Job>,
        message: String,
    },
    Saved {
        path: PathBuf,
        result: Result<(), String>,
    },
}

pub struct Worker {
    requests: Option<Sender<Request>>,
    pub replies: Receiver<Reply>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts the thread; `wake` is called after every reply (to wake the event loop).
    pub fn start(renderer: Renderer, prepared: PreparedScene, wake: impl Fn() + Send + 'static) -> Worker {
        let (req_tx, req_rx) = channel::<Request>();
        let (rep_tx, rep_rx) = channel::<Reply>();
        let thread = std::thread::Builder::new()
            .name("caustica render".into())
            .spawn(move || run(renderer, prepared, req_rx, rep_tx, wake))
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
                screenshot => handle(&mut renderer, &mut prepared, screenshot, &send),
            }
        }
        if let Some(f) = frame {
            handle(&mut renderer, &mut prepared, f, &send);
        }
    }
}

fn set_scene(prepared: &mut PreparedScene, scene: Scene) -> Result<(), RenderError> {
    if scene.environment != prepared.scene.environment {
        prepared.env = EnvMap::for_scene(&scene.environment)?;
    }
    prepared.tf = scene.transfer_functions()?;
    prepared.scene = scene;
    Ok(())
}

fn handle(renderer: &mut Renderer, prepared: &mut PreparedScene, request: Request, send: &dyn Fn(Reply)) {
    match request {
        Request::Frame {
            job,
            scene,
            width,
            height,
            cancel,
        } => {
            if cancel.load(Ordering::Relaxed) {
                send(Reply::Cancelled { job });
                return;
            }
            let start = Instant::now();
            let result = set_scene(prepared, *scene).and_then(|()| {
                let mut req = RenderRequest::new(width, height);
                req.cancel = Some(cancel);
                renderer.render(prepared, &req)
            });
            send(match result {
                Ok(out) => Reply::Frame {
                    job,
                    image: out.image,
                    stats: out.stats,
                    duration_ms: start.elapsed().as_secs_f64() * 1e3,
                },
                Err(RenderError::Cancelled) => Reply::Cancelled { job },
                Err(e) => Reply::Failed {
                    job: Some(job),
                    message: e.to_string(),
                },
            });
        }
        Request::Screenshot {
            scene,
            width,
            height,
            path,
        } => {
            let result = set_scene(prepared, *scene)
                .and_then(|()| renderer.render(prepared, &RenderRequest::new(width, height)))
                .map_err(|e| e.to_string())
                .and_then(|out| super::save::save_image(&out.image, &path).map_err(|e| format!("{e:#}")));
            send(Reply::Saved { path, result });
        }
    }
}
