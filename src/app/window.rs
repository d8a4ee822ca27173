//! The winit window: input into egui, progressive frames from the render thread, painting
//! (render image + panel) into a softbuffer surface, screenshots and exit-after-idle.

mod present;

use std::num::NonZeroU32;
use std::path::PathBuf;
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{anyhow, Result};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow};
use winit::window::{Window, WindowId};

use super::panel::{Action, ViewState};
use super::progressive::{progress_title, InFlight, Job, Pace, Progressive, LEVELS, TITLE_EVERY};
use super::raster::{Painter, Target};
use super::worker::{Reply, Request, Worker};
use super::ViewError;
use crate::render::{RenderedImage, SweepProgress};
use crate::scene::Scene;
use present::{blit, pack, Shown};

/// Wakes the event loop when the render thread has a reply.
#[derive(Debug)]
pub struct Wake;

struct Surface {
    window: Rc<Window>,
    surface: softbuffer::Surface<Rc<Window>, Rc<Window>>,
    egui: egui_winit::State,
}

pub struct Options {
    pub size: (u32, u32),
    pub exit_after_idle: bool,
    /// Written once the full-quality frame is on screen: what the window shows, read back.
    pub screenshot: Option<PathBuf>,
    /// Saved once the full-quality frame is on screen.
    pub save_scene: Option<PathBuf>,
    /// Print every frame shown (level, size, planes, render time) and the paint time.
    pub frame_log: bool,
    /// Scripted interaction: after each of the first N frames, orbit by 5° as a drag would.
    pub orbit_frames: u32,
    /// The time an interactive frame may take ([`Pace`]; 0: the level's own spacing).
    pub frame_budget_ms: f64,
    /// Scripted interaction: once settled, resize the window to this size and settle again.
    pub resize_after_idle: Option<(u32, u32)>,
}

pub struct App {
    pub state: ViewState,
    opts: Options,
    worker: Worker,
    progressive: Progressive,
    /// The interactive level's plane spacing, kept within the frame budget.
    pace: Pace,
    egui: egui::Context,
    painter: Painter,
    surface: Option<Surface>,
    shown: Option<Shown>,
    /// The sum of the full-quality passes of the view on screen and their count.
    accumulated: Option<(RenderedImage, u32)>,
    /// What the current version looks like, to detect edits.
    last_scene: Scene,
    last_render_size: (u32, u32),
    cancel: Arc<AtomicBool>,
    /// The viewport has no pixels (minimised): nothing to render, so nothing to wait for.
    no_viewport: bool,
    pub error: Option<ViewError>,
    /// The view version whose settled frame was last written (--screenshot, --save-scene).
    written_version: u64,
    /// The frame being rendered, for the title ([`progress_title`]).
    rendering: Option<Rendering>,
    /// The title the window was given last.
    title: String,
}

/// A frame asked of the render thread and not answered yet: its job, its size, its sweep's
/// progress and when it was asked for.
struct Rendering {
    job: Job,
    size: (u32, u32),
    progress: Arc<SweepProgress>,
    since: Instant,
}

impl App {
    pub fn new(state: ViewState, worker: Worker, opts: Options) -> App {
        let last_scene = state.scene_for_render();
        let pace = Pace::new(opts.frame_budget_ms);
        App {
            state,
            opts,
            worker,
            progressive: Progressive::new(Instant::now()),
            pace,
            egui: egui::Context::default(),
            painter: Painter::default(),
            surface: None,
            shown: None,
            accumulated: None,
            last_scene,
            last_render_size: (0, 0),
            cancel: Arc::new(AtomicBool::new(false)),
            no_viewport: false,
            error: None,
            written_version: 0,
            rendering: None,
            title: "caustica".into(),
        }
    }

    /// Stops the render thread (destroying its GPU objects) and closes the window.
    pub fn shutdown(&mut self) {
        self.cancel.store(true, Ordering::Relaxed);
        self.worker.stop();
        self.surface = None;
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, e: impl Into<ViewError>) {
        self.error.get_or_insert(e.into());
        event_loop.exit();
    }

    fn viewport_pixels(&self, ppp: f32) -> [u32; 4] {
        let r = self.state.viewport;
        if !r.is_positive() {
            return [0; 4];
        }
        let x0 = (r.min.x * ppp).round().max(0.0) as u32;
        let y0 = (r.min.y * ppp).round().max(0.0) as u32;
        let x1 = (r.max.x * ppp).round().max(0.0) as u32;
        let y1 = (r.max.y * ppp).round().max(0.0) as u32;
        [x0, y0, x1.saturating_sub(x0), y1.saturating_sub(y0)]
    }

    fn take_replies(&mut self) {
        while let Ok(reply) = self.worker.replies.try_recv() {
            match reply {
                Reply::Frame {
                    job,
                    image,
                    stats,
                    duration_ms,
                } => {
                    self.answered(job);
                    // What the interactive level costs on this machine, from the frames that
                    // made or copied no scene textures (the first filters the volumes to half
                    // resolution; a new spacing makes new tables) and compiled no shaders.
                    if job.level == 0 && job.pass == 0 && stats.upload_bytes == 0 && stats.compiled == 0 {
                        self.pace.record(duration_ms);
                    }
                    if self.progressive.finished(job, true) {
                        let name = if job.pass > 0 {
                            "accumulate"
                        } else {
                            LEVELS[job.level].name
                        };
                        let image = super::progressive::accumulate(&mut self.accumulated, job, image);
                        self.shown = Some(pack(&image));
                        if self.opts.frame_log {
                            eprintln!(
                                "frame: {:<11} {}x{} {:>4} planes {:>9.1} ms",
                                name, image.width, image.height, stats.planes, duration_ms
                            );
                            // What the device spent of it, by pass; the rest is the CPU's
                            // (scene setup, recording, waiting) and the copy back. The upload:
                            // what of the scene textures had to be made and copied anew; then
                            // the pipelines compiled for it, if any.
                            let [light, view, listing, finish] = stats.pass_ms;
                            eprintln!(
                                "gpu: {:.1} ms (light {light:.1}, view {view:.1}, listing {listing:.1}, finish {finish:.1}), other {:.1} ms, upload {:.1} MiB",
                                stats.gpu_ms,
                                duration_ms - stats.gpu_ms,
                                stats.upload_bytes as f64 / (1024.0 * 1024.0)
                            );
                            if stats.compiled > 0 {
                                eprintln!("compiled: {} pipelines", stats.compiled);
                            }
                        }
                        if self.opts.orbit_frames > 0 {
                            self.opts.orbit_frames -= 1;
                            let step_px = 5.0 / super::controls::ORBIT_DEG_PER_PIXEL;
                            super::controls::orbit(&mut self.state.scene.camera, step_px, 0.0);
                        }
                        let s = &mut self.state.status;
                        s.level = name;
                        s.frame_ms = duration_ms;
                        s.planes = stats.planes;
                        s.render_size = (image.width, image.height);
                    }
                }
                Reply::Precompiled {
                    variants,
                    pipelines,
                    ms,
                } => {
                    if self.opts.frame_log {
                        eprintln!(
                            "precompiled: {pipelines} pipelines for the {variants} variants one click away, {ms:.1} ms after the full frame"
                        );
                    }
                }
                Reply::Cancelled { job } => {
                    self.answered(job);
                    self.progressive.finished(job, false);
                }
                Reply::Failed { job, message, class } => {
                    if let Some(job) = job {
                        self.answered(job);
                        self.progressive.finished(job, false);
                    }
                    self.state.status.message = message.clone();
                    // Without a picture the exit-after-idle run can never settle: stop.
                    if self.opts.exit_after_idle {
                        self.error.get_or_insert(ViewError::Frame { message, class });
                    }
                }
                Reply::Volume { frame, histogram } => {
                    // Bars of an older frame than the one selected would mislead: keep them
                    // only for the frame the slider shows.
                    if frame == self.state.frame() {
                        self.state.histogram = histogram;
                    }
                }
                Reply::Saved { path, result } => {
                    self.state.status.message = match result {
                        Ok(()) => format!("wrote {}", path.display()),
                        Err(e) => format!("screenshot failed: {e}"),
                    };
                }
            }
        }
    }

    /// The render thread has answered `job`: it no longer renders.
    fn answered(&mut self, job: Job) {
        if self.rendering.as_ref().is_some_and(|r| r.job == job) {
            self.rendering = None;
        }
    }

    /// Gives the window the title [`progress_title`] makes of the frame being rendered, if it
    /// changed.
    fn update_title(&mut self, now: Instant) {
        let title = match &self.rendering {
            Some(r) => {
                let (done, total) = r.progress.get();
                let frame = InFlight {
                    name: LEVELS[r.job.level].name,
                    size: r.size,
                    pass: r.job.pass,
                    done,
                    total,
                };
                progress_title(Some(frame), now - r.since)
            }
            None => progress_title(None, Default::default()),
        };
        if title != self.title {
            if let Some(s) = &self.surface {
                s.window.set_title(&title);
            }
            self.title = title;
        }
    }

    fn schedule(&mut self, render_size: (u32, u32)) {
        let now = Instant::now();
        let scene = self.state.scene_for_render();
        if scene != self.last_scene || render_size != self.last_render_size {
            if let Err(e) = scene.validate() {
                self.state.status.message = e.to_string();
                return;
            }
            self.last_scene = scene;
            self.last_render_size = render_size;
            if self.progressive.changed(now) {
                self.cancel.store(true, Ordering::Relaxed);
            }
        }
        self.no_viewport = render_size.0 == 0 || render_size.1 == 0;
        if self.no_viewport {
            return;
        }
        if let Some(job) = self.progressive.next(now) {
            let level = LEVELS[job.level];
            let step_factor = if job.level == 0 {
                self.pace.step_factor()
            } else {
                level.step_factor
            };
            let mut scene = self.last_scene.clone();
            scene.quality.sample_distance = (scene.quality.sample_distance * step_factor).min(16.0);
            scene.quality.beams_per_texel =
                (scene.quality.beams_per_texel * level.beams_factor).max(crate::scene::MIN_BEAMS_PER_TEXEL);
            scene.quality.volume_level = scene.quality.volume_level.max(level.volume_level);
            let (w, h) = level.size(render_size.0, render_size.1);
            self.cancel = Arc::new(AtomicBool::new(false));
            let progress = Arc::new(SweepProgress::default());
            self.rendering = Some(Rendering {
                job,
                size: (w, h),
                progress: progress.clone(),
                since: now,
            });
            self.worker.send(Request::Frame {
                job,
                scene: Box::new(scene),
                width: w,
                height: h,
                cancel: self.cancel.clone(),
                progress,
                // The frame log prints the passes' times (which the timestamps between them
                // add to a little: about 0.08 ms per plane on lavapipe).
                pass_timings: self.opts.frame_log,
            });
        }
    }

    fn act(&mut self, event_loop: &ActiveEventLoop, action: Action) {
        match action {
            Action::Quit => event_loop.exit(),
            Action::SaveScene(path) => {
                self.state.status.message = match super::save::save_scene(&self.state.scene_for_render(), &path) {
                    Ok(()) => format!("saved {}", path.display()),
                    Err(e) => format!("cannot save {}: {e:#}", path.display()),
                };
            }
            Action::SaveAnimation(path) => self.state.status.message = self.state.save_animation(&path),
            Action::Screenshot { path, width, height } => {
                self.state.status.message = format!("rendering {}×{} to {} ...", width, height, path.display());
                self.worker.send(Request::Screenshot {
                    scene: Box::new(self.state.scene_for_render()),
                    width,
                    height,
                    path,
                });
            }
        }
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let start = Instant::now();
        self.take_replies();
        let Some(s) = self.surface.as_mut() else { return };
        let input = s.egui.take_egui_input(&s.window);
        let state = &mut self.state;
        let mut actions = Vec::new();
        let output = self.egui.run_ui(input, |ui| actions = state.ui(ui));
        s.egui.handle_platform_output(&s.window, output.platform_output);
        let ppp = output.pixels_per_point;
        let size = s.window.inner_size();
        for a in actions {
            self.act(event_loop, a);
        }
        let vp = self.viewport_pixels(ppp);
        let scale = self.state.render_scale.clamp(0.05, 1.0);
        let render_size = (
            ((vp[2] as f32) * scale).round() as u32,
            ((vp[3] as f32) * scale).round() as u32,
        );
        self.schedule(render_size);

        self.painter.update_textures(&output.textures_delta);
        let primitives = self.egui.tessellate(output.shapes, ppp);
        let (Some(w), Some(h)) = (NonZeroU32::new(size.width), NonZeroU32::new(size.height)) else {
            // Minimised: nothing to paint.
            self.painter.free_textures(&output.textures_delta);
            return;
        };
        let Some(s) = self.surface.as_mut() else { return };
        let result = (|| -> Result<(), softbuffer::SoftBufferError> {
            s.surface.resize(w, h)?;
            let mut buffer = s.surface.buffer_mut()?;
            let (bw, bh) = (size.width as usize, size.height as usize);
            buffer.fill(0x00_10_10_10);
            if let Some(img) = &self.shown {
                blit(&mut buffer, bw, bh, img, vp);
            }
            let mut target = Target {
                pixels: &mut buffer,
                width: bw,
                height: bh,
            };
            self.painter.paint(&mut target, &primitives, ppp);
            buffer.present()
        })();
        self.painter.free_textures(&output.textures_delta);
        if let Err(e) = result {
            self.fail(event_loop, anyhow!("cannot present the window: {e}"));
            return;
        }
        if self.opts.frame_log {
            let ms = start.elapsed().as_secs_f64() * 1e3;
            eprintln!(
                "paint: {}x{} window, panel and image {ms:.1} ms",
                size.width, size.height
            );
        }
        // Each time the view settles to a new full frame: outputs are (re)written.
        if self.progressive.settled() && self.written_version != self.progressive.version() {
            if let Some((w, h)) = self.opts.resize_after_idle.take() {
                if let Some(s) = &self.surface {
                    // Applied by the window system; the Resized event that follows brings a
                    // new viewport size and so a new progressive sequence.
                    let _ = s.window.request_inner_size(PhysicalSize::new(w, h));
                    s.window.request_redraw();
                }
                return;
            }
            self.written_version = self.progressive.version();
            if let Some(path) = self.opts.screenshot.clone() {
                if let Err(e) = self.capture(&path) {
                    self.fail(event_loop, e);
                    return;
                }
            }
            if let Some(path) = self.opts.save_scene.clone() {
                // The scene of the frame on screen, not of edits made since.
                if let Err(e) = super::save::save_scene(&self.last_scene, &path) {
                    self.fail(event_loop, e);
                    return;
                }
                eprintln!("wrote {}", path.display());
            }
            if self.opts.exit_after_idle {
                event_loop.exit();
            }
        }
        if self.error.is_some() {
            event_loop.exit();
        }
        let repaint = output
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .map(|v| v.repaint_delay);
        if let Some(s) = &self.surface {
            if repaint.is_some_and(|d| d.is_zero()) {
                s.window.request_redraw();
            }
        }
    }

    /// Reads back what the window shows (the X server's copy of the surface, panel included)
    /// and writes it as a PNG.
    fn capture(&mut self, path: &std::path::Path) -> Result<()> {
        let s = self.surface.as_mut().ok_or_else(|| anyhow!("no window"))?;
        let size = s.window.inner_size();
        let pixels = s
            .surface
            .fetch()
            .map_err(|e| anyhow!("cannot read back the window contents: {e}"))?;
        let (ww, wh) = (size.width as usize, size.height as usize);
        if pixels.len() != ww * wh {
            return Err(anyhow!(
                "window read-back has {} pixels, expected {ww}×{wh}",
                pixels.len()
            ));
        }
        let rgb: Vec<u8> = pixels
            .iter()
            .flat_map(|p| [(p >> 16) as u8, (p >> 8) as u8, *p as u8])
            .collect();
        let img = image::RgbImage::from_raw(size.width, size.height, rgb).ok_or_else(|| anyhow!("bad capture size"))?;
        let tmp = path.with_extension("capture.tmp.png");
        img.save(&tmp)?;
        std::fs::rename(&tmp, path)?;
        eprintln!("wrote {} ({ww}×{wh}, window capture)", path.display());
        Ok(())
    }
}

impl ApplicationHandler<Wake> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.surface.is_some() {
            return;
        }
        let attrs = Window::default_attributes()
            .with_title("caustica")
            .with_inner_size(PhysicalSize::new(self.opts.size.0, self.opts.size.1));
        let result = (|| -> Result<Surface> {
            let window = Rc::new(event_loop.create_window(attrs)?);
            let context = softbuffer::Context::new(window.clone()).map_err(|e| anyhow!("{e}"))?;
            let surface = softbuffer::Surface::new(&context, window.clone()).map_err(|e| anyhow!("{e}"))?;
            let egui = egui_winit::State::new(
                self.egui.clone(),
                egui::ViewportId::ROOT,
                &window,
                Some(window.scale_factor() as f32),
                None,
                None,
            );
            Ok(Surface { window, surface, egui })
        })();
        match result {
            Ok(s) => {
                s.window.request_redraw();
                self.surface = Some(s);
            }
            Err(e) => self.fail(event_loop, e.context("cannot open the window")),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(s) = self.surface.as_mut() else { return };
        let response = s.egui.on_window_event(&s.window, &event);
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => event_loop.exit(),
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            _ => {
                if response.repaint {
                    s.window.request_redraw();
                }
            }
        }
    }

    fn user_event(&mut self, _event_loop: &ActiveEventLoop, _event: Wake) {
        if let Some(s) = &self.surface {
            s.window.request_redraw();
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        let now = Instant::now();
        self.update_title(now);
        // While a frame renders, look again at its progress now and then (a title, no repaint).
        let title_at = self.rendering.as_ref().map(|_| now + TITLE_EVERY);
        let mut refine_at = self.progressive.wake_at().filter(|_| !self.no_viewport);
        if refine_at.is_some_and(|t| t <= now) {
            if let Some(s) = &self.surface {
                s.window.request_redraw();
            }
            refine_at = None;
        }
        let next = refine_at.into_iter().chain(title_at).min();
        event_loop.set_control_flow(next.map_or(ControlFlow::Wait, ControlFlow::WaitUntil));
    }
}
