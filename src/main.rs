//! The `caustica` command line: parse, call the library, map errors to exit codes.

mod cli;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Parser, Subcommand};

use caustica::gpu::list_devices;
use caustica::scene::{builtin, BUILTIN_SCENES};
use caustica::{volume, Classify, ExitClass};

use cli::animate::AnimateArgs;
use cli::bench::BenchArgs;
use cli::info::InfoArgs;
use cli::render::RenderArgs;

/// A failed command: the error and how the process ends. Library errors bring their class
/// (`Classify`) through `?`; errors of `main`'s own making say theirs, with [`input`] for bad
/// input.
#[derive(Debug)]
struct Failure {
    error: anyhow::Error,
    class: ExitClass,
}

impl<E: Classify + std::error::Error + Send + Sync + 'static> From<E> for Failure {
    fn from(e: E) -> Self {
        Failure {
            class: e.exit_class(),
            error: e.into(),
        }
    }
}

/// A failure caused by the command's input (arguments, files).
fn input(error: impl Into<anyhow::Error>) -> Failure {
    Failure {
        error: error.into(),
        class: ExitClass::Input,
    }
}

type Result<T, E = Failure> = std::result::Result<T, E>;

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
    Cli::try_parse_from(argv)
        .map_err(input)?
        .command
        .context("the default job names no command")
        .map_err(input)
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file, a volume file or a built-in scene to PNG (sRGB) or EXR (linear).
    Render(Box<RenderArgs>),
    /// Open an interactive window: edit camera, light, transfer functions and quality.
    View(Box<caustica::app::ViewArgs>),
    /// Render an animation (turntable, light sweep, time series, transfer-function and
    /// clip-plane sweeps) to numbered frames or an MP4; splits across machines with --shard.
    Animate(Box<AnimateArgs>),
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

fn run(cli: Cli) -> Result<()> {
    let command = match cli.command {
        Some(c) => c,
        None => default_job()?,
    };
    match command {
        Command::Render(args) => cli::render::render(&args),
        Command::Bench(args) => cli::bench::bench(&args),
        Command::View(args) => Ok(caustica::app::run(&args)?),
        Command::Animate(args) => Ok(cli::animate::animate(&args)?),
        Command::Info(args) => cli::info::info(&args),
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
            volume::nrrd::write_nrrd(&output, &vol, !raw)
                .with_context(|| format!("writing {}", output.display()))
                .map_err(input)?;
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

/// Reports a failure and ends the process with its class's code (README, "Errors and exit
/// codes"); after a hang at once, without exit handlers.
fn exit(failure: Failure) -> ExitCode {
    eprintln!("error: {:#}", failure.error);
    let code = failure.class.code();
    if failure.class == ExitClass::GpuHung {
        exit_now(code);
    }
    ExitCode::from(code)
}

/// Exits without running the C library's exit handlers: after a device hang the driver may
/// still be executing the abandoned work, and tearing the driver down under it can crash or
/// block. stderr is unbuffered, so the message is already out. The crate's one `unsafe` outside
/// `gpu` (Cargo.toml denies it elsewhere).
#[allow(unsafe_code)]
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
        Err(failure) => exit(failure),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use caustica::app::ViewError;
    use caustica::gpu::GpuError;
    use caustica::input::InputError;
    use caustica::render::RenderError;

    /// Every command's options are consistent: no two share a name (a flattened option group
    /// and a command's own option named alike would silently swallow one of them).
    #[test]
    fn the_command_line_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }

    /// What `?` makes of an error is what the process exits with.
    fn fail(error: impl Classify + std::error::Error + Send + Sync + 'static) -> Result<()> {
        Err(error)?
    }

    /// A GPU failure while the viewer handles its input (loading and rendering a frame on its
    /// render thread) reaches `main` wrapped in the viewer's error, and still exits 4.
    #[test]
    fn a_gpu_failure_during_input_handling_exits_4() {
        let lost = GpuError::DeviceLost { call: "vkQueueSubmit" };
        let failure = fail(ViewError::Render(RenderError::Gpu(lost))).unwrap_err();
        assert_eq!(failure.class.code(), 4, "{:#}", failure.error);
        assert!(
            failure.error.to_string().contains("device was lost"),
            "{:#}",
            failure.error
        );
        let hung = GpuError::Timeout { seconds: 120 };
        let failure = fail(ViewError::Render(RenderError::Gpu(hung))).unwrap_err();
        assert_eq!(failure.class, ExitClass::GpuHung, "ends at once (_exit)");
        let failure = fail(ViewError::Input(InputError::Missing)).unwrap_err();
        assert_eq!(failure.class.code(), 1);
    }
}
