//! The `caustica` command line: parse, call the library, map errors to exit codes.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context as _, Result};
use clap::{Parser, Subcommand};

use caustica::gpu::{list_devices, Context, ContextDesc, DeviceSelector, GpuError};
use caustica::input::{fit_to_device, parse_size, InputArgs, Prepared};
use caustica::render::{DebugView, RenderError, RenderRequest, Renderer};
use caustica::scene::{builtin, BUILTIN_SCENES};
use caustica::volume;

/// Exit codes (see README, "Errors and exit codes").
const EXIT_INPUT: u8 = 1;
const EXIT_NO_VULKAN: u8 = 3;
const EXIT_GPU: u8 = 4;

/// The validation layer reported errors: the render is not trustworthy (exit code 4).
#[derive(Debug, thiserror::Error)]
#[error(
    "the Vulkan validation layer reported {count} error(s) during the render (first: {first}); not writing {output}"
)]
struct ValidationFailed {
    count: u64,
    first: String,
    output: String,
}

/// The image holds NaN, infinite or negative values: a renderer fault (exit code 4).
#[derive(Debug, thiserror::Error)]
#[error("the render produced {non_finite} non-finite and {negative} negative values; not writing {output}")]
struct InvalidImage {
    non_finite: usize,
    negative: usize,
    output: String,
}

#[derive(Parser)]
#[command(
    name = "caustica",
    version,
    about = "Volume rendering with refraction, soft shadows and caustics"
)]
struct Cli {
    /// Without a command: open the ball-lens scene in a window, or, without a display, render
    /// it to caustica.png.
    #[command(subcommand)]
    command: Option<Command>,
}

/// The built-in scene of the default job (`caustica` without a command).
const DEFAULT_SCENE: &str = "ball-lens";

/// `caustica` without a command: the viewer on the default scene when there is a display,
/// otherwise a screenshot of it.
fn default_job() -> Result<Command> {
    let has_display = std::env::var_os("DISPLAY").is_some_and(|d| !d.is_empty());
    let argv: &[&str] = if has_display {
        eprintln!("caustica: opening the {DEFAULT_SCENE} scene (`caustica --help` lists the commands)");
        &["caustica", "view", "--scene", DEFAULT_SCENE]
    } else {
        eprintln!(
            "caustica: no display (DISPLAY is not set); rendering the {DEFAULT_SCENE} scene to caustica.png \
             (`caustica --help` lists the commands)"
        );
        &["caustica", "render", "--scene", DEFAULT_SCENE, "-o", "caustica.png"]
    };
    Cli::try_parse_from(argv)?
        .command
        .context("the default job names no command")
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file, a volume file or a built-in scene to PNG (sRGB) or EXR (linear).
    Render(Box<RenderArgs>),
    /// Open an interactive window: edit camera, light, transfer functions and quality.
    View(Box<caustica::app::ViewArgs>),
    /// List the built-in scenes.
    Scenes,
    /// List the Vulkan devices caustica sees.
    Devices,
    /// Describe a volume file: dims, scalar type, spacing, value range, histogram, window.
    Info(InfoArgs),
    /// Write the volume of a built-in scene to an NRRD file.
    Dataset {
        /// Built-in volume: ball-lens, glass, supernova, luneburg, thin-structures
        name: String,
        #[arg(short, long)]
        output: PathBuf,
        /// Voxels along the longest axis.
        #[arg(long, default_value_t = 128)]
        resolution: usize,
        /// Write uncompressed data (default: gzip).
        #[arg(long)]
        raw: bool,
    },
    /// Measure the speed–accuracy trade: GPU frame times and errors against the reference renderer.
    Bench(BenchArgs),
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Built-in scenes, comma separated (default: all; see `caustica scenes`).
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// A small sweep (40³ volumes, viewports up to 256²) that runs in minutes on lavapipe.
    #[arg(long)]
    quick: bool,
    /// Directory for bench.md, bench.csv, bench.png and the reference images.
    #[arg(long, default_value = "bench")]
    out: PathBuf,
    /// GPU frames per setting (default 5, or 3 with --quick).
    #[arg(long)]
    frames: Option<u32>,
    /// Voxels along the longest axis of the built-in volumes (default 64, or 40 with --quick).
    #[arg(long)]
    resolution: Option<usize>,
    /// Vulkan device: index or name substring (see `caustica devices`).
    #[arg(long, default_value = "auto")]
    device: String,
    /// Instead of the sweep, measure the reference renderer's convergence (error against a
    /// finer run of itself versus rays per voxel² and step length) on the first scene; no GPU.
    #[arg(long)]
    convergence: bool,
}

#[derive(clap::Args)]
struct RenderArgs {
    #[command(flatten)]
    input: InputArgs,
    /// Output image: .png (8-bit sRGB) or .exr (linear float).
    #[arg(short, long, default_value = "caustica.png")]
    output: PathBuf,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    /// Vulkan device: index or name substring (see `caustica devices`).
    #[arg(long, default_value = "auto")]
    device: String,
    /// Write a diagnostic buffer instead of the image: light, light-direction, intensity, medium.
    #[arg(long, value_parser = parse_debug_view)]
    debug_view: Option<DebugView>,
    /// Relative depth in [0, 1] of the plane shown by --debug-view.
    #[arg(long, default_value_t = 0.5)]
    at_depth: f32,
    /// Print planes, ms per plane and total GPU time.
    #[arg(long)]
    timings: bool,
}

fn parse_debug_view(s: &str) -> Result<DebugView, String> {
    DebugView::parse(s).ok_or_else(|| format!("'{s}': expected light, light-direction, intensity or medium"))
}

fn render(args: &RenderArgs) -> Result<()> {
    let Prepared { mut prepared, notes } = args.input.prepare()?;
    for note in notes {
        eprintln!("{note}");
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    fit_to_device(&mut prepared, &ctx, !args.input.no_downsample)?;
    let mut renderer = Renderer::new(ctx.clone())?;
    let mut req = RenderRequest::new(args.size.0, args.size.1);
    req.progress = true;
    if let Some(v) = args.debug_view {
        req.debug_view = v;
        req.debug_depth = args.at_depth;
    }
    let out = renderer.render(&prepared, &req)?;
    if ctx.validation_errors() > 0 {
        return Err(ValidationFailed {
            count: ctx.validation_errors(),
            first: ctx.validation_messages().first().cloned().unwrap_or_default(),
            output: args.output.display().to_string(),
        }
        .into());
    }
    let (non_finite, negative) = out.image.count_invalid();
    if non_finite > 0 || negative > 0 {
        return Err(InvalidImage {
            non_finite,
            negative,
            output: args.output.display().to_string(),
        }
        .into());
    }
    out.image.save(&args.output)?;
    let s = &out.stats;
    if args.timings {
        println!(
            "device: {}\nfeatures: {}\nprecision: {}\nplanes: {} (integrated {})\nms per plane: {:.3}\ntotal GPU ms: {:.1}\nstate buffers: {:.1} MiB",
            ctx.info.name,
            s.features.describe(),
            s.precision.name(),
            s.planes,
            s.planes_run,
            s.ms_per_plane,
            s.gpu_ms,
            s.state_bytes as f64 / (1024.0 * 1024.0)
        );
    }
    eprintln!("wrote {} ({}×{})", args.output.display(), args.size.0, args.size.1);
    Ok(())
}

fn bench(args: &BenchArgs) -> Result<()> {
    use caustica::bench::{self, BenchError, Plan};
    let scenes: Vec<String> = if args.scenes.is_empty() {
        BUILTIN_SCENES.iter().map(|s| s.to_string()).collect()
    } else {
        args.scenes.clone()
    };
    for name in &scenes {
        builtin(name)?;
    }
    let mut plan = if args.quick {
        Plan::quick(scenes)
    } else {
        Plan::full(scenes)
    };
    if let Some(f) = args.frames {
        if f == 0 {
            bail!("--frames must be at least 1");
        }
        plan.frames = f;
    }
    if let Some(r) = args.resolution {
        plan.resolution = r;
    }
    if args.convergence {
        let path = args.out.join("convergence.md");
        std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
        let runs: &[(f64, f64)] = if args.quick {
            &[(1.0, 0.5), (4.0, 0.5), (16.0, 0.5), (16.0, 1.0), (16.0, 0.25)]
        } else {
            &[
                (1.0, 0.25),
                (4.0, 0.25),
                (16.0, 0.25),
                (64.0, 0.25),
                (64.0, 1.0),
                (64.0, 0.5),
                (64.0, 0.125),
            ]
        };
        let truth = if args.quick { (64.0, 0.125) } else { (256.0, 0.0625) };
        bench::convergence::run(
            &plan.scenes[0],
            plan.resolution,
            plan.reference_size,
            runs,
            truth,
            &path,
        )?;
        print!("{}", std::fs::read_to_string(&path)?);
        eprintln!("wrote {}", path.display());
        return Ok(());
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    // Render errors keep their type so that they map to the GPU exit codes.
    let report = bench::run(ctx.clone(), &plan, &args.out, true).map_err(|e| match e {
        BenchError::Render(r) => anyhow::Error::from(r),
        other => anyhow::Error::from(other),
    })?;
    print!("{}", std::fs::read_to_string(&report.markdown)?);
    eprintln!(
        "wrote {}, {} and {}",
        report.markdown.display(),
        report.csv.display(),
        report.plot.display()
    );
    if ctx.validation_errors() > 0 {
        bail!("{} Vulkan validation errors were reported", ctx.validation_errors());
    }
    Ok(())
}

#[derive(clap::Args)]
struct InfoArgs {
    /// A volume file, a DICOM folder, file or DICOMDIR, or a time-series pattern with '*'.
    input: PathBuf,
    /// DICOM: describe this series of several (its number in the listing, or its UID).
    #[arg(long)]
    series: Option<String>,
    /// Rows of the histogram sketch.
    #[arg(long, default_value_t = 16)]
    histogram_rows: usize,
}

fn info(args: &InfoArgs) -> Result<()> {
    let started = std::time::Instant::now();
    let pattern = args.input.to_string_lossy().contains('*');
    let loaded = if pattern {
        let series = volume::series::Series::from_pattern(&args.input)?;
        println!(
            "time series: {} frames (showing frame 0: {})",
            series.len(),
            series.frames[0].display()
        );
        series.open_frame(0)?
    } else {
        match volume::open_series(&args.input, args.series.as_deref()) {
            Err(volume::VolumeError::SeveralSeries { path, listing }) => {
                let series = volume::dicom::list_series(&path)?;
                println!("{}: {} DICOM series", path.display(), series.len());
                print!("{listing}");
                println!("describe one with --series N or --series UID (render and view take the same option)");
                return Ok(());
            }
            other => other?,
        }
    };
    let load_ms = started.elapsed().as_secs_f64() * 1e3;
    let v = &loaded.volume;
    let m = &loaded.meta;
    let h = &loaded.histogram;
    println!("file:        {}", args.input.display());
    println!("format:      {}", m.format);
    println!(
        "dims:        {} ({} voxels)",
        volume::dims_text(&v.dims),
        v.voxel_count()
    );
    println!(
        "scalar type: {}",
        m.scalar.map_or("unknown".to_string(), |s| s.to_string())
    );
    println!("spacing:     {} × {} × {}", v.spacing[0], v.spacing[1], v.spacing[2]);
    let e = v.extent();
    println!("extent:      {} × {} × {}", e[0], e[1], e[2]);
    println!("modality:    {}", m.modality.as_deref().unwrap_or("unknown"));
    match &m.patient {
        Some(p) => println!(
            "orientation: {} (x, y, z run {}; {}), origin ({:.1}, {:.1}, {:.1}) mm LPS{}",
            p.axis_codes(),
            p.axis_words(),
            p.source,
            p.origin.x,
            p.origin.y,
            p.origin.z,
            match p.obliquity_deg() {
                d if d > 0.5 => format!(", {d:.1}° oblique"),
                _ => String::new(),
            }
        ),
        None => println!("orientation: not in the file (axes shown as stored)"),
    }
    println!("units:       {}", m.units);
    println!("value range: [{}, {}]", v.value_range[0], v.value_range[1]);
    println!(
        "percentiles: 0.5% {}  50% {}  99.5% {}",
        h.tails[0],
        h.quantile(0.5),
        h.tails[1]
    );
    println!("window:      {:?} ({})", loaded.default_window(), loaded.window_rule());
    let tf = caustica::transfer::default_for(m, h, loaded.default_window());
    println!(
        "default transfer functions: {}",
        tf.name.as_deref().unwrap_or("automatic")
    );
    for note in &m.notes {
        println!("note:        {note}");
    }
    println!("load time:   {load_ms:.0} ms");
    println!("histogram ({} bins, log scale):", volume::histogram::HISTOGRAM_BINS);
    for line in h.summary(args.histogram_rows) {
        println!("  {line}");
    }
    Ok(())
}

fn run(cli: Cli) -> Result<()> {
    let command = match cli.command {
        Some(c) => c,
        None => default_job()?,
    };
    match command {
        Command::Render(args) => render(&args),
        Command::Bench(args) => bench(&args),
        Command::View(args) => caustica::app::run(&args),
        Command::Info(args) => info(&args),
        Command::Scenes => {
            for name in BUILTIN_SCENES {
                let s = builtin(name)?;
                println!("{:<16} {}", s.name, s.description);
            }
            Ok(())
        }
        Command::Devices => {
            let devices = list_devices()?;
            if devices.is_empty() {
                println!("no Vulkan devices found");
            }
            for d in devices {
                println!(
                    "[{}] {} ({}, Vulkan {}){}",
                    d.index,
                    d.name,
                    d.kind,
                    d.api_version,
                    if d.usable {
                        ""
                    } else {
                        " - not usable: needs Vulkan 1.3"
                    }
                );
            }
            Ok(())
        }
        Command::Dataset {
            name,
            output,
            resolution,
            raw,
        } => {
            let vol = volume::procedural::generate(&name, resolution)?;
            volume::nrrd::write_nrrd(&output, &vol, !raw).with_context(|| format!("writing {}", output.display()))?;
            eprintln!(
                "wrote {} ({}×{}×{})",
                output.display(),
                vol.dims[0],
                vol.dims[1],
                vol.dims[2]
            );
            Ok(())
        }
    }
}

fn exit_code(err: &anyhow::Error) -> u8 {
    if err.downcast_ref::<ValidationFailed>().is_some() || err.downcast_ref::<InvalidImage>().is_some() {
        return EXIT_GPU;
    }
    let gpu = err
        .downcast_ref::<GpuError>()
        .or_else(|| match err.downcast_ref::<RenderError>() {
            Some(RenderError::Gpu(g)) => Some(g),
            _ => None,
        });
    match gpu {
        Some(GpuError::NoLoader(_) | GpuError::NoDevice(_) | GpuError::DeviceNotFound { .. }) => EXIT_NO_VULKAN,
        Some(_) => EXIT_GPU,
        None => EXIT_INPUT,
    }
}

fn is_hang(err: &anyhow::Error) -> bool {
    matches!(
        err.downcast_ref::<RenderError>(),
        Some(RenderError::Gpu(GpuError::Timeout { .. }))
    ) || matches!(err.downcast_ref::<GpuError>(), Some(GpuError::Timeout { .. }))
}

/// Exits without running the C library's exit handlers: after a device hang the driver may
/// still be executing the abandoned work, and tearing the driver down under it can crash or
/// block. stderr is unbuffered, so the message is already out.
fn exit_now(code: u8) -> ! {
    #[cfg(unix)]
    // SAFETY: _exit only ends the process; no Rust state needs to outlive it.
    unsafe {
        libc::_exit(code as i32)
    }
    #[cfg(not(unix))]
    std::process::exit(code as i32)
}

/// Prints library warnings (`log::warn!`) to stderr; quiet otherwise.
struct StderrLogger;

impl log::Log for StderrLogger {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        metadata.level() <= log::Level::Warn
    }

    fn log(&self, record: &log::Record) {
        if self.enabled(record.metadata()) {
            eprintln!("{}: {}", record.level().as_str().to_lowercase(), record.args());
        }
    }

    fn flush(&self) {}
}

static LOGGER: StderrLogger = StderrLogger;

fn main() -> ExitCode {
    let _ = log::set_logger(&LOGGER).map(|()| log::set_max_level(log::LevelFilter::Warn));
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            let code = exit_code(&err);
            if is_hang(&err) {
                exit_now(code);
            }
            ExitCode::from(code)
        }
    }
}
