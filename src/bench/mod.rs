//! `caustica bench`: sweeps the speed knobs of the GPU renderer over built-in scenes and
//! measures, for each setting, the GPU frame time and the error against the reference renderer
//! (`reference`). Writes a Markdown table, a CSV file and a PNG plot of error against time
//! with each scene's Pareto front. [`light`] measures the light buffer against the exact
//! light on the same planes behind a ball lens; [`speed`] measures time, work and memory per
//! frame over viewport sizes.

pub mod convergence;
pub mod dispatch;
pub mod light;
pub mod metrics;
pub mod plot;
mod report;
pub mod scatter;
pub mod scatter_modes;
pub mod slab;
pub mod speed;
mod speed_report;
pub mod steps;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::gpu::Context;
use crate::reference::photons::PhotonSettings;
use crate::reference::{self, ReferenceError, ReferenceSettings};
use crate::render::{PreparedScene, RenderError, RenderRequest, Renderer};
use crate::scene::{builtin, Gradient, LightTransport, Precision, PrepareError, SceneError};

pub use metrics::{compare, ImageError, Linear};
pub use report::{write_csv, write_markdown};

#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Prepare(#[from] PrepareError),
    #[error(transparent)]
    Reference(#[from] ReferenceError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Volume(#[from] crate::volume::VolumeError),
    #[error("cannot write {path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error("invalid bench plan: {0}")]
    Plan(String),
}

impl crate::Classify for BenchError {
    fn exit_class(&self) -> crate::ExitClass {
        match self {
            BenchError::Render(e) => e.exit_class(),
            BenchError::Prepare(e) => e.exit_class(),
            BenchError::Reference(e) => e.exit_class(),
            BenchError::Scene(e) => e.exit_class(),
            BenchError::Volume(e) => e.exit_class(),
            BenchError::Write { .. } | BenchError::Plan(_) => crate::ExitClass::Input,
        }
    }
}

/// One point of the sweep: the knobs a user can turn.
#[derive(Clone, Debug, PartialEq)]
pub struct Setting {
    pub label: String,
    pub sample_distance: f32,
    /// Square viewport edge, pixels.
    pub size: u32,
    pub light_filter: bool,
    pub precision: Precision,
    /// The backward transport's intensity law (the beams make their caustics from their density
    /// and ignore it).
    pub intensity_correction: bool,
    pub gradient: Gradient,
    pub light_transport: LightTransport,
    /// `quality.beams_per_texel`: the light grid's density, which the light pass's time
    /// follows (its cells scale with its square).
    pub beams_per_texel: f32,
}

impl Setting {
    /// The default quality at `size`².
    pub fn base(size: u32) -> Setting {
        Setting {
            label: "default".into(),
            sample_distance: 1.0,
            size,
            light_filter: true,
            precision: Precision::F16,
            intensity_correction: true,
            gradient: Gradient::Central,
            light_transport: LightTransport::Beams,
            beams_per_texel: 1.0,
        }
    }

    fn with(&self, label: &str, change: impl FnOnce(&mut Setting)) -> Setting {
        let mut s = self.clone();
        s.label = label.into();
        change(&mut s);
        s
    }

    /// The default plus one knob turned at a time.
    pub fn one_at_a_time(base_size: u32, sample_distances: &[f32], sizes: &[u32], beams: &[f32]) -> Vec<Setting> {
        let base = Setting::base(base_size);
        let mut v = vec![base.clone()];
        for &d in sample_distances {
            v.push(base.with(&format!("sample distance {d}"), |s| s.sample_distance = d));
        }
        for &n in sizes {
            v.push(base.with(&format!("viewport {n}²"), |s| s.size = n));
        }
        for &b in beams {
            v.push(base.with(&format!("beams per texel {b}"), |s| s.beams_per_texel = b));
        }
        v.push(base.with("no light filter", |s| s.light_filter = false));
        v.push(base.with("f32 buffers", |s| s.precision = Precision::F32));
        v.push(base.with("backward transport", |s| s.light_transport = LightTransport::Backward));
        v.push(base.with("forward gradient", |s| s.gradient = Gradient::Forward));
        v
    }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct Plan {
    pub scenes: Vec<String>,
    /// Voxels along the longest axis of the built-in volumes.
    pub resolution: usize,
    /// Square size of the reference images; every viewport must be a multiple of it.
    pub reference_size: u32,
    pub reference: ReferenceSettings,
    pub settings: Vec<Setting>,
    /// GPU frames per setting (median, min, max of their GPU times).
    pub frames: u32,
    /// Render the scenes' highlights (both renderers model them; off compares the rest alone).
    pub highlights: bool,
}

impl Plan {
    /// The full sweep: sample distance 0.25–4, viewport 128²–1024², beams per texel 0.5 and 2,
    /// and each on/off knob.
    pub fn full(scenes: Vec<String>) -> Plan {
        Plan {
            scenes,
            resolution: 64,
            reference_size: 128,
            reference: ReferenceSettings {
                photons: PhotonSettings {
                    rays_per_voxel2: 16.0,
                    ..PhotonSettings::default()
                },
                samples_per_axis: 2,
                ..ReferenceSettings::default()
            },
            settings: Setting::one_at_a_time(256, &[0.25, 0.5, 2.0, 4.0], &[128, 512, 1024], &[0.5, 2.0]),
            frames: 5,
            highlights: true,
        }
    }

    /// A small sweep that runs in minutes on a CPU Vulkan driver. The reference is sampled
    /// like the default viewport after its 2×2 box filter (2×2 rays per pixel on its pixel
    /// centres), with 64 rays per voxel² (`StepsPlan::quick`).
    pub fn quick(scenes: Vec<String>) -> Plan {
        Plan {
            scenes,
            resolution: 40,
            reference_size: 64,
            reference: ReferenceSettings {
                photons: PhotonSettings {
                    rays_per_voxel2: 64.0,
                    ..PhotonSettings::default()
                },
                view_step_voxels: 0.5,
                samples_per_axis: 2,
                ..ReferenceSettings::default()
            },
            settings: Setting::one_at_a_time(128, &[0.5, 2.0, 4.0], &[64, 256], &[0.5, 2.0]),
            frames: 3,
            highlights: true,
        }
    }
}

/// One measured row.
#[derive(Clone, Debug)]
pub struct Row {
    pub scene: String,
    pub setting: Setting,
    pub planes: u32,
    /// The light grid's cells (beams), x × y.
    pub light_grid: [u32; 2],
    /// The scene's particles scatter light (an albedo), which the reference does not model:
    /// its photons are absorbed, never scattered, so the renderer's scattered light reads as
    /// error (`bench --scatter` measures it against a Monte Carlo reference that has it).
    pub scatters: bool,
    pub ms_median: f64,
    pub ms_min: f64,
    pub ms_max: f64,
    pub error: ImageError,
}

/// The bench's results and where they were written.
pub struct Report {
    pub rows: Vec<Row>,
    pub device: String,
    pub markdown: PathBuf,
    pub csv: PathBuf,
    pub plot: PathBuf,
}

/// A built-in scene prepared for the bench: at `resolution`, with its highlights or without.
pub fn bench_scene(name: &str, resolution: usize, highlights: bool) -> Result<PreparedScene, BenchError> {
    let mut scene = builtin(name)?.scene;
    scene.set_builtin_resolution(resolution);
    scene.quality.specular &= highlights;
    Ok(PreparedScene::load(&scene)?)
}

fn apply(prepared: &mut PreparedScene, s: &Setting) {
    let q = &mut prepared.scene.quality;
    q.sample_distance = s.sample_distance;
    q.light_filter = s.light_filter;
    q.precision = s.precision;
    q.intensity_correction = s.intensity_correction;
    q.light_transport = s.light_transport;
    q.gradient = s.gradient;
    q.beams_per_texel = s.beams_per_texel;
}

/// The median of `v` (the mean of the middle two where their number is even); sorts `v`.
pub(crate) fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The device a bench ran on, as its reports name it: the Vulkan device, and for a CPU
/// driver the processor it ran on and how many threads it had (the same driver runs a
/// quarter to a half faster against a peer on one 2-core machine than on another).
pub fn device_label(ctx: &Context) -> String {
    if !ctx.is_cpu() {
        return ctx.info.name.clone();
    }
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| cpu_model(&text))
        .unwrap_or_else(|| "an unnamed processor".into());
    let threads = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{} on {model}, {threads} threads", ctx.info.name)
}

/// The processor's name in the text of Linux's /proc/cpuinfo: its first `model name` (x86) or
/// `Model` (Arm boards) line.
fn cpu_model(cpuinfo: &str) -> Option<String> {
    cpuinfo.lines().find_map(|line| {
        let (key, value) = line.split_once(':')?;
        let value = value.trim();
        (matches!(key.trim(), "model name" | "Model") && !value.is_empty()).then(|| value.to_string())
    })
}

fn write_err(path: &Path) -> impl Fn(String) -> BenchError + '_ {
    move |message| BenchError::Write {
        path: path.to_path_buf(),
        message,
    }
}

fn save(img: &crate::render::RenderedImage, path: &Path) -> Result<(), BenchError> {
    img.save(path).map_err(|e| write_err(path)(e.to_string()))
}

/// Runs `plan` on the device of `ctx` and writes `bench.md`, `bench.csv`, `bench.png` and the
/// reference and default-setting images of each scene into `out`.
pub fn run(ctx: Arc<Context>, plan: &Plan, out: &Path, progress: bool) -> Result<Report, BenchError> {
    if plan.frames == 0 || plan.settings.is_empty() || plan.scenes.is_empty() {
        return Err(BenchError::Plan(
            "needs at least one scene, one setting and one frame".into(),
        ));
    }
    if let Some(s) = plan.settings.iter().find(|s| s.size % plan.reference_size != 0) {
        return Err(BenchError::Plan(format!(
            "viewport {} is not a multiple of the reference size {}",
            s.size, plan.reference_size
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| write_err(out)(e.to_string()))?;
    let mut renderer = Renderer::new(ctx.clone())?;
    let total = (plan.scenes.len() * (plan.settings.len() + 1)) as u64;
    let bar = (progress && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(total);
        if let Ok(style) = indicatif::ProgressStyle::with_template("bench {pos}/{len} {wide_bar} {eta} {msg}") {
            bar.set_style(style);
        }
        bar
    });
    let mut rows = Vec::new();
    for name in &plan.scenes {
        let mut prepared = bench_scene(name, plan.resolution, plan.highlights)?;
        let scatters = prepared.tf.scatters();
        if let Some(b) = &bar {
            b.set_message(format!("{name}: reference"));
        }
        let n = plan.reference_size;
        let reference_image = reference::render(&prepared, n, n, &plan.reference, false)?;
        save(&reference_image, &out.join(format!("{name}-reference.png")))?;
        let reference_linear = Linear::from_image(&reference_image);
        if let Some(b) = &bar {
            b.inc(1);
        }
        for setting in &plan.settings {
            if let Some(b) = &bar {
                b.set_message(format!("{name}: {}", setting.label));
            }
            apply(&mut prepared, setting);
            let req = RenderRequest::new(setting.size, setting.size);
            // One untimed frame first: a setting that needs another shader variant (the light
            // filter off, f32 buffers) has its first frame on a CPU driver slowed by compiling
            // it (1.2–1.8 s instead of 0.3 s on lavapipe), which a median of two frames keeps.
            renderer.render(&prepared, &req)?;
            let mut times = Vec::new();
            let mut last = None;
            for _ in 0..plan.frames {
                let frame = renderer.render(&prepared, &req)?;
                times.push(frame.stats.gpu_ms);
                last = Some(frame);
            }
            let Some(frame) = last else { continue };
            if setting.label == "default" {
                save(&frame.image, &out.join(format!("{name}-default.png")))?;
            }
            let error = compare(&Linear::from_image(&frame.image), &reference_linear)
                .ok_or_else(|| BenchError::Plan("viewport and reference sizes do not match".into()))?;
            let (ms_min, ms_max) = times
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), t| (a.min(*t), b.max(*t)));
            rows.push(Row {
                scene: name.clone(),
                setting: setting.clone(),
                planes: frame.stats.planes,
                light_grid: frame.stats.light_grid,
                scatters,
                ms_median: median(&mut times),
                ms_min,
                ms_max,
                error,
            });
            if let Some(b) = &bar {
                b.inc(1);
            }
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let device = device_label(&ctx);
    let markdown = out.join("bench.md");
    let csv = out.join("bench.csv");
    let plot_path = out.join("bench.png");
    write_markdown(&markdown, &rows, &device, plan).map_err(write_err(&markdown))?;
    write_csv(&csv, &rows).map_err(write_err(&csv))?;
    let series: Vec<plot::Series> = plan
        .scenes
        .iter()
        .map(|name| plot::Series {
            name,
            points: rows
                .iter()
                .filter(|r| &r.scene == name)
                .map(|r| (r.ms_median, r.error.rel_l1))
                .collect(),
        })
        .collect();
    plot::write(
        &plot_path,
        &series,
        "median GPU ms per frame",
        "relative L1 error vs reference",
        plot::Join::ParetoFront,
    )
    .map_err(write_err(&plot_path))?;
    Ok(Report {
        rows,
        device,
        markdown,
        csv,
        plot: plot_path,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_processor_is_named_from_cpuinfo() {
        let x86 =
            "processor\t: 0\nvendor_id\t: GenuineIntel\nmodel\t\t: 167\nmodel name\t: Intel(R) Xeon(R) Processor\n\
                   flags\t\t: fpu vme\n\nprocessor\t: 1\nmodel name\t: Intel(R) Xeon(R) Processor\n";
        assert_eq!(super::cpu_model(x86).as_deref(), Some("Intel(R) Xeon(R) Processor"));
        let arm = "processor\t: 0\nBogoMIPS\t: 108.00\nCPU part\t: 0xd08\n\nHardware\t: BCM2835\n\
                   Model\t\t: Raspberry Pi 4 Model B Rev 1.4\n";
        assert_eq!(super::cpu_model(arm).as_deref(), Some("Raspberry Pi 4 Model B Rev 1.4"));
        // x86's `model` is a number, not a name; an empty name is none.
        assert_eq!(super::cpu_model("model\t\t: 167\nmodel name\t:\n"), None);
    }
}
