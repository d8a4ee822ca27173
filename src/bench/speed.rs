//! `caustica bench --speed`: GPU time per frame and per plane, the work behind it (planes,
//! light-grid cells, the volume's footprint in pixels) and the memory it holds, for each
//! scene at a series of square viewports; and how the time scales with pixels × planes.
//! Writes `speed.md`, `speed.csv` and `speed-fit.csv`.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use crate::gpu::{Context, MemoryUse};
use crate::render::{PreparedScene, RenderRequest, Renderer};
use crate::scene::{builtin, Scene};

use super::dispatch::DispatchCost;
use super::{median, write_err, BenchError};

/// A scene to measure, under the name the tables give it.
#[derive(Clone, Debug)]
pub struct SpeedScene {
    pub name: String,
    pub scene: Scene,
}

impl SpeedScene {
    /// A built-in scene, at `resolution` voxels along its longest axis when given.
    pub fn builtin(name: &str, resolution: Option<usize>) -> Result<SpeedScene, BenchError> {
        let mut scene = builtin(name)?.scene;
        if let Some(n) = resolution {
            scene.set_builtin_resolution(n);
        }
        Ok(SpeedScene {
            name: name.to_string(),
            scene,
        })
    }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct SpeedPlan {
    pub scenes: Vec<SpeedScene>,
    /// Square viewport edges in pixels; the scaling fit spans all of them.
    pub sizes: Vec<u32>,
    /// Edge of a tiny viewport whose time per plane is the fixed cost of a plane (its pixels
    /// cost next to nothing); 0 measures none.
    pub tiny_size: u32,
    /// Timed frames per scene and size (the median is reported); the tiny viewport takes at
    /// least `TINY_FRAMES` ([`SpeedPlan::frames_at`]).
    pub frames: u32,
}

/// Timed frames at the tiny viewport at least: each costs tens of milliseconds, and one frame
/// there moves by a third between runs on a busy CPU (a core's other work weighs on every
/// dispatch), which a median of several steadies.
pub const TINY_FRAMES: u32 = 9;

/// Dispatches per kind and round, and rounds, of the dispatch cost (`dispatch::measure`):
/// about a second on a CPU driver with 2 cores.
const DISPATCHES_PER_ROUND: u32 = 200;
const DISPATCH_ROUNDS: u32 = 5;

impl SpeedPlan {
    /// 128² to 1024², five frames each, and 8² for the fixed cost.
    pub fn full(scenes: Vec<SpeedScene>) -> SpeedPlan {
        SpeedPlan {
            scenes,
            sizes: vec![128, 256, 512, 1024],
            tiny_size: 8,
            frames: 5,
        }
    }

    /// 128² and 256², three frames each.
    pub fn quick(scenes: Vec<SpeedScene>) -> SpeedPlan {
        SpeedPlan {
            sizes: vec![128, 256],
            frames: 3,
            ..SpeedPlan::full(scenes)
        }
    }

    /// Timed frames at a size: `frames`, or at the tiny viewport at least `TINY_FRAMES`.
    pub fn frames_at(&self, tiny: bool) -> u32 {
        if tiny {
            self.frames.max(TINY_FRAMES)
        } else {
            self.frames
        }
    }

    /// The default plan for a device: [`SpeedPlan::full`] (or [`SpeedPlan::quick`]) on a GPU.
    /// A CPU driver takes minutes per frame at 1024² with every effect, so there the default
    /// stops at 512² (256² when quick) with one timed frame each; `sizes` and `frames` can
    /// still ask for more.
    pub fn for_device(scenes: Vec<SpeedScene>, cpu_driver: bool, quick: bool) -> SpeedPlan {
        let mut plan = if quick {
            SpeedPlan::quick(scenes)
        } else {
            SpeedPlan::full(scenes)
        };
        if cpu_driver {
            plan.sizes.retain(|&s| s <= if quick { 256 } else { 512 });
            plan.frames = 1;
        }
        plan
    }
}

/// Median, min and max of a set of times, milliseconds.
#[derive(Clone, Copy, Debug)]
pub struct Spread {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

impl Spread {
    fn of(mut v: Vec<f64>) -> Spread {
        let (min, max) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| (a.min(*t), b.max(*t)));
        Spread {
            median: median(&mut v),
            min,
            max,
        }
    }
}

/// One scene at one viewport.
#[derive(Clone, Debug)]
pub struct SpeedRow {
    pub scene: String,
    /// The features the renderer ran (`Features::describe`).
    pub features: String,
    /// Square viewport edge, pixels.
    pub size: u32,
    /// The tiny viewport of the fixed cost, not part of the scaling fit.
    pub tiny: bool,
    pub planes: u32,
    /// GPU time per frame (timestamp queries).
    pub gpu_ms: Spread,
    /// Time of the whole `Renderer::render` call (recording, submission, waits, read-back).
    pub wall_ms: Spread,
    /// Median GPU time per frame of each pass (`RenderStats::pass_ms`: light, view, listing
    /// and clearing, finish).
    pub pass_ms: [f64; 4],
    /// GPU time per frame of the frames the passes were timed in (pass timings on: the
    /// timestamps between the passes add to it).
    pub pass_frames_ms: Spread,
    pub light_grid: [u32; 2],
    /// Dispatch commands per frame (`RenderStats::dispatches`).
    pub dispatches: u32,
    /// Light-tile steps (`RenderStats::light_steps`), where light tiles are listed.
    pub light_steps: Option<u64>,
    /// The side of the tiles they count (`RenderStats::tile`).
    pub tile: u32,
    /// Pixels whose rays can meet the volume, width × height.
    pub footprint: [u32; 2],
    pub state_bytes: u64,
    pub texture_bytes: u64,
    /// The largest peak over the timed frames.
    pub peak_memory: MemoryUse,
}

impl SpeedRow {
    pub fn ms_per_plane(&self) -> f64 {
        self.gpu_ms.median / self.planes.max(1) as f64
    }

    /// Dispatch commands per plane.
    pub fn dispatches_per_plane(&self) -> f64 {
        self.dispatches as f64 / self.planes.max(1) as f64
    }

    /// Viewport pixels × planes: the work a frame would be if every plane covered the image.
    pub fn pixel_planes(&self) -> f64 {
        self.size as f64 * self.size as f64 * self.planes as f64
    }
}

/// How one scene's time scales.
#[derive(Clone, Debug)]
pub struct SpeedFit {
    pub scene: String,
    /// Least-squares slope of log GPU time against log (pixels × planes) over the plan's
    /// sizes: 1 is linear; less means a fixed cost still weighs in.
    pub exponent: Option<f64>,
    /// GPU ms per plane at the tiny viewport.
    pub fixed_ms_per_plane: Option<f64>,
    /// Dispatch commands per plane at the tiny viewport (the same at every size but for the
    /// view passes' count).
    pub fixed_dispatches_per_plane: Option<f64>,
    /// Straight-line fit of ms per plane against viewport pixels over every size (the tiny one
    /// included): the intercept (ms per plane at no pixels) and the slope in ns per pixel-plane.
    pub intercept_ms_per_plane: Option<f64>,
    pub ns_per_pixel_plane: Option<f64>,
    /// The render after an edit of the opacity curve at the smallest viewport of the fit (the
    /// viewer's editor: the volume images are kept), set by [`run`].
    pub edit: Option<EditTiming>,
}

/// Renders after edits of the transfer functions that keep η: what the viewer waits for after
/// each change in its editor, past the GPU's part of the frame.
#[derive(Clone, Copy, Debug)]
pub struct EditTiming {
    /// Viewport edge, pixels.
    pub size: u32,
    /// The whole `Renderer::render` call after each edit.
    pub wall_ms: Spread,
    /// Its GPU part (timestamp queries).
    pub gpu_ms: Spread,
    /// Bytes copied into the scene textures by the render after an edit (the largest): the
    /// pre-integrated tables where the volume images are kept.
    pub upload_bytes: u64,
}

/// Least-squares line through the points: (intercept, slope); None without two distinct x.
pub fn line_fit(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = points.len() as f64;
    if points.len() < 2 {
        return None;
    }
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    // Relative to the spread of x, so that large pixel counts do not count as distinct noise.
    if sxx <= 1e-12 * mx.abs().max(1.0).powi(2) {
        return None;
    }
    let slope = sxy / sxx;
    Some((my - slope * mx, slope))
}

impl SpeedFit {
    pub fn of(scene: &str, rows: &[SpeedRow]) -> SpeedFit {
        let mine: Vec<&SpeedRow> = rows.iter().filter(|r| r.scene == scene).collect();
        // The tiny viewport's row: the fixed cost.
        let tiny = mine.iter().copied().find(|r| r.tiny);
        let log_points: Vec<(f64, f64)> = mine
            .iter()
            .filter(|r| !r.tiny && r.gpu_ms.median > 0.0)
            .map(|r| (r.pixel_planes().ln(), r.gpu_ms.median.ln()))
            .collect();
        let per_plane: Vec<(f64, f64)> = mine
            .iter()
            .map(|r| (r.size as f64 * r.size as f64, r.ms_per_plane()))
            .collect();
        let line = line_fit(&per_plane);
        SpeedFit {
            scene: scene.to_string(),
            exponent: line_fit(&log_points).map(|l| l.1),
            fixed_ms_per_plane: tiny.map(SpeedRow::ms_per_plane),
            fixed_dispatches_per_plane: tiny.map(SpeedRow::dispatches_per_plane),
            intercept_ms_per_plane: line.map(|l| l.0),
            ns_per_pixel_plane: line.map(|l| l.1 * 1e6),
            edit: None,
        }
    }
}

/// The results and where they were written.
pub struct SpeedReport {
    pub rows: Vec<SpeedRow>,
    pub fits: Vec<SpeedFit>,
    pub device: String,
    pub markdown: PathBuf,
    pub csv: PathBuf,
    pub fit_csv: PathBuf,
    /// GPU ms per frame against pixels × planes (`write_plot`).
    pub plot: PathBuf,
    /// The device's own cost of a dispatch (with the tiny viewport only).
    pub dispatch_cost: Option<DispatchCost>,
}

/// Plots each scene's GPU ms per frame against its viewport's pixels × planes (millions), log
/// against log, beside the line proportional scaling would follow from its smallest size: a
/// scene whose time grows more slowly than its work (a fixed cost, work skipped) bends below
/// it. The legend gives each scene's fitted exponent.
pub fn write_plot(path: &Path, rows: &[SpeedRow], fits: &[SpeedFit]) -> Result<(), String> {
    let names: Vec<String> = fits
        .iter()
        .map(|f| match f.exponent {
            Some(e) => format!("{} {:.2}", f.scene, e),
            None => f.scene.clone(),
        })
        .collect();
    let series: Vec<super::plot::Series> = fits
        .iter()
        .zip(&names)
        .map(|(f, name)| super::plot::Series {
            name,
            points: rows
                .iter()
                .filter(|r| r.scene == f.scene && !r.tiny)
                .map(|r| (r.pixel_planes() / 1e6, r.gpu_ms.median))
                .collect(),
        })
        .collect();
    super::plot::write(
        path,
        &series,
        "pixels x planes (millions)",
        "ms per frame (scenes: fitted exponent)",
        super::plot::Join::Proportional,
    )
}

/// The 1, 5 and 15 minute load averages (Linux), to judge how much other work shared the
/// processor during a run on a CPU driver.
fn load_average() -> Option<String> {
    let s = std::fs::read_to_string("/proc/loadavg").ok()?;
    Some(s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
}

fn measure(
    renderer: &mut Renderer,
    prepared: &PreparedScene,
    name: &str,
    size: u32,
    tiny: bool,
    frames: u32,
) -> Result<SpeedRow, BenchError> {
    let req = RenderRequest::new(size, size);
    let (mut gpu, mut wall) = (Vec::new(), Vec::new());
    let mut passes: [Vec<f64>; 4] = Default::default();
    let mut peak = MemoryUse::default();
    let mut last = None;
    for _ in 0..frames {
        let start = Instant::now();
        let out = renderer.render(prepared, &req)?;
        wall.push(start.elapsed().as_secs_f64() * 1e3);
        gpu.push(out.stats.gpu_ms);
        peak.device_local = peak.device_local.max(out.stats.peak_memory.device_local);
        peak.host_visible = peak.host_visible.max(out.stats.peak_memory.host_visible);
        last = Some(out.stats);
    }
    // The passes' times from frames of their own: the timestamps between the passes take
    // time of their own on a CPU driver, which the frames above are timed without.
    let timed = RenderRequest {
        pass_timings: true,
        ..req.clone()
    };
    let mut passes_total = Vec::new();
    for _ in 0..frames {
        let out = renderer.render(prepared, &timed)?;
        for (p, ms) in passes.iter_mut().zip(out.stats.pass_ms) {
            p.push(ms);
        }
        passes_total.push(out.stats.gpu_ms);
    }
    let s = last.ok_or_else(|| BenchError::Plan("needs at least one frame".into()))?;
    Ok(SpeedRow {
        scene: name.to_string(),
        features: s.features.describe(),
        size,
        tiny,
        planes: s.planes,
        gpu_ms: Spread::of(gpu),
        wall_ms: Spread::of(wall),
        pass_ms: passes.map(|mut p| median(&mut p)),
        pass_frames_ms: Spread::of(passes_total),
        light_grid: s.light_grid,
        dispatches: s.dispatches,
        light_steps: s.light_steps,
        tile: s.tile,
        footprint: s.rect,
        state_bytes: s.state_bytes,
        texture_bytes: s.texture_bytes,
        peak_memory: peak,
    })
}

/// Renders at `size`² after each of `edits` (at least 3) edits of the opacity curve, which
/// alternately scale its values by 0.9 and back: a new table pair each time, nothing else.
fn measure_edits(
    renderer: &mut Renderer,
    prepared: &mut PreparedScene,
    size: u32,
    edits: u32,
) -> Result<EditTiming, BenchError> {
    let req = RenderRequest::new(size, size);
    let (mut wall, mut gpu, mut upload) = (Vec::new(), Vec::new(), 0u64);
    let original = prepared.tf.opacity.clone();
    for i in 0..edits.max(3) {
        let factor = if i % 2 == 0 { 0.9 } else { 1.0 };
        prepared.tf.opacity.points = original.points.iter().map(|&[x, a]| [x, a * factor]).collect();
        let start = Instant::now();
        let out = renderer.render(prepared, &req)?;
        wall.push(start.elapsed().as_secs_f64() * 1e3);
        gpu.push(out.stats.gpu_ms);
        upload = upload.max(out.stats.upload_bytes);
    }
    prepared.tf.opacity = original;
    Ok(EditTiming {
        size,
        wall_ms: Spread::of(wall),
        gpu_ms: Spread::of(gpu),
        upload_bytes: upload,
    })
}

/// Runs `plan` on the device of `ctx` and writes `speed.md`, `speed.csv` and `speed-fit.csv`
/// into `out`. Each scene gets one untimed frame at the smallest size first (upload of its
/// textures, pipeline creation), so the timed frames measure the sweep alone.
pub fn run(ctx: Arc<Context>, plan: &SpeedPlan, out: &Path, progress: bool) -> Result<SpeedReport, BenchError> {
    if plan.frames == 0 || plan.sizes.is_empty() || plan.scenes.is_empty() || plan.sizes.contains(&0) {
        return Err(BenchError::Plan(
            "needs at least one scene, one size (≥ 1 pixel) and one frame".into(),
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| write_err(out)(e.to_string()))?;
    let load_before = load_average();
    let mut sizes: Vec<(u32, bool)> = Vec::new();
    if plan.tiny_size > 0 {
        sizes.push((plan.tiny_size, true));
    }
    sizes.extend(plan.sizes.iter().map(|&s| (s, false)));
    let bar = (progress && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new((plan.scenes.len() * sizes.len()) as u64);
        if let Ok(style) = indicatif::ProgressStyle::with_template("bench --speed {pos}/{len} {wide_bar} {eta} {msg}") {
            bar.set_style(style);
        }
        bar
    });
    // The device's cost of a dispatch, before the scenes' textures take its memory: the unit
    // the fixed cost of a plane is also given in.
    let dispatch_cost = if plan.tiny_size > 0 {
        if let Some(b) = &bar {
            b.set_message("the cost of a dispatch");
        }
        Some(
            super::dispatch::measure(&ctx, DISPATCHES_PER_ROUND, DISPATCH_ROUNDS)
                .map_err(crate::render::RenderError::Gpu)?,
        )
    } else {
        None
    };
    let mut renderer = Renderer::new(ctx.clone())?;
    let mut rows = Vec::new();
    let mut edits = Vec::new();
    for s in &plan.scenes {
        let mut prepared = PreparedScene::load(&s.scene)?;
        crate::input::fit_to_device(&mut prepared, &ctx, true, false)?;
        let smallest = sizes.iter().map(|s| s.0).min().unwrap_or(1);
        renderer.render(&prepared, &RenderRequest::new(smallest, smallest))?;
        for &(size, tiny) in &sizes {
            if let Some(b) = &bar {
                b.set_message(format!("{} at {size}²", s.name));
            }
            rows.push(measure(
                &mut renderer,
                &prepared,
                &s.name,
                size,
                tiny,
                plan.frames_at(tiny),
            )?);
            if let Some(b) = &bar {
                b.inc(1);
            }
        }
        // At the smallest size of the fit: at the tiny one the occupied cells are grown by
        // margins of whole pixels, a quarter of the volume, which no viewer level has.
        let edit_size = plan.sizes.iter().copied().min().unwrap_or(smallest);
        if let Some(b) = &bar {
            b.set_message(format!("{}: transfer-function edits at {edit_size}²", s.name));
        }
        edits.push(measure_edits(&mut renderer, &mut prepared, edit_size, plan.frames)?);
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let fits: Vec<SpeedFit> = plan
        .scenes
        .iter()
        .zip(edits)
        .map(|(s, edit)| SpeedFit {
            edit: Some(edit),
            ..SpeedFit::of(&s.name, &rows)
        })
        .collect();
    let device = super::device_label(&ctx);
    let markdown = out.join("speed.md");
    let csv = out.join("speed.csv");
    let fit_csv = out.join("speed-fit.csv");
    let plot = out.join("speed.png");
    let load_after = load_average();
    let context = super::speed_report::Context {
        device: &device,
        frames: plan.frames,
        tiny_frames: plan.frames_at(true),
        sizes: &plan.sizes,
        tiny_size: plan.tiny_size,
        load_before: load_before.as_deref(),
        load_after: load_after.as_deref(),
        dispatch_cost: dispatch_cost.as_ref(),
    };
    super::speed_report::write_markdown(&markdown, &rows, &fits, &context).map_err(write_err(&markdown))?;
    super::speed_report::write_csv(&csv, &rows).map_err(write_err(&csv))?;
    super::speed_report::write_fit_csv(&fit_csv, &fits, dispatch_cost.as_ref()).map_err(write_err(&fit_csv))?;
    write_plot(&plot, &rows, &fits).map_err(write_err(&plot))?;
    Ok(SpeedReport {
        rows,
        fits,
        device,
        markdown,
        csv,
        fit_csv,
        plot,
        dispatch_cost,
    })
}

#[cfg(test)]
mod tests {
    use super::{line_fit, SpeedPlan, TINY_FRAMES};

    #[test]
    fn the_tiny_viewport_takes_several_frames_even_where_the_others_take_one() {
        // On a CPU driver the plan times one frame per size; the fixed cost's frames cost tens
        // of milliseconds, and their median is what the goal is read from.
        let plan = SpeedPlan::for_device(Vec::new(), true, false);
        assert_eq!(plan.frames, 1);
        assert_eq!(plan.frames_at(false), 1);
        assert_eq!(plan.frames_at(true), TINY_FRAMES);
        // A plan that asks for more frames keeps them at the tiny viewport too.
        let many = SpeedPlan {
            frames: 20,
            ..SpeedPlan::full(Vec::new())
        };
        assert_eq!(many.frames_at(true), 20);
    }

    #[test]
    fn line_fit_recovers_a_line_and_refuses_one_point() {
        let pts: Vec<(f64, f64)> = (0..5).map(|i| (i as f64, 2.0 + 0.5 * i as f64)).collect();
        let (a, b) = line_fit(&pts).unwrap();
        // Exact data: only rounding separates the fit from the line.
        assert!((a - 2.0).abs() < 1e-12 && (b - 0.5).abs() < 1e-12, "{a} {b}");
        assert!(line_fit(&pts[..1]).is_none());
        assert!(line_fit(&[(3.0, 1.0), (3.0, 2.0)]).is_none());
    }
}
