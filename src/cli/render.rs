//! `caustica render`: a scene to a PNG or EXR image, refusing images the GPU got wrong.

use std::path::PathBuf;

use caustica::gpu::{Context, ContextDesc, DeviceSelector};
use caustica::input::{fit_to_device, parse_size, InputArgs, Prepared};
use caustica::render::{accumulate, DebugView, RenderRequest, Renderer};
use caustica::{Classify, ExitClass};

use crate::Result;

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

impl Classify for ValidationFailed {
    fn exit_class(&self) -> ExitClass {
        ExitClass::Gpu
    }
}

/// The image holds NaN, infinite or negative values: a renderer fault (exit code 4).
#[derive(Debug, thiserror::Error)]
#[error("the render produced {non_finite} non-finite and {negative} negative values; not writing {output}")]
struct InvalidImage {
    non_finite: usize,
    negative: usize,
    output: String,
}

impl Classify for InvalidImage {
    fn exit_class(&self) -> ExitClass {
        ExitClass::Gpu
    }
}

#[derive(clap::Args)]
pub struct RenderArgs {
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
    /// With --timings: also time each pass apart (light, view, listing, finish). This adds a
    /// timestamp per pass and plane, which a CPU driver pays for (about 0.08 ms per plane on
    /// lavapipe).
    #[arg(long, requires = "timings")]
    pass_timings: bool,
    /// Average N renders whose planes and light grid are moved by fractions of their spacing
    /// (removes banding and woodgrain that follow where the samples fall; N times the time).
    /// Not with --debug-view, which shows one plane's buffer.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024), conflicts_with = "debug_view")]
    accumulate: u32,
}

fn parse_debug_view(s: &str) -> Result<DebugView, String> {
    DebugView::parse(s).ok_or_else(|| format!("'{s}': expected light, light-direction, intensity or medium"))
}

pub fn render(args: &RenderArgs) -> Result<()> {
    let Prepared { mut prepared, notes } = args.input.prepare()?;
    for note in notes {
        eprintln!("{note}");
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    fit_to_device(&mut prepared, &ctx, !args.input.no_downsample, false)?;
    let mut renderer = Renderer::new(ctx.clone())?;
    let mut req = RenderRequest::new(args.size.0, args.size.1);
    req.progress = true;
    req.pass_timings = args.pass_timings;
    if let Some(v) = args.debug_view {
        req.debug_view = v;
        req.debug_depth = args.at_depth;
    }
    let out = accumulate(&mut renderer, &prepared, &req, args.accumulate, |done| {
        if args.accumulate > 1 {
            eprintln!("accumulated {done}/{}", args.accumulate);
        }
    })?;
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
            "device: {}\nfeatures: {}\nprecision: {}\nplanes: {} (integrated {})\nms per plane: {:.3}\ntotal GPU ms: {:.1}\nstate buffers: {:.1} MiB\nscene textures: {:.1} MiB\npeak memory: {:.1} MiB device-local, {:.1} MiB host-visible\nlight grid: {}×{} cells ({})\nvolume footprint: {}×{} pixels",
            ctx.info.name,
            s.features.describe(),
            s.precision.name(),
            s.planes,
            s.planes_run,
            s.ms_per_plane,
            s.gpu_ms,
            mib(s.state_bytes),
            mib(s.texture_bytes),
            mib(s.peak_memory.device_local),
            mib(s.peak_memory.host_visible),
            s.light_grid[0],
            s.light_grid[1],
            s.features.transport.name(),
            s.rect[0],
            s.rect[1],
        );
        if prepared.scene.quality.volume_level > 0 {
            let [x, y, z] = crate::volume::half_level_dims(prepared.volume.dims);
            let [a, b, c] = prepared.volume.dims;
            println!("volume sampled at half resolution: {x}×{y}×{z} of {a}×{b}×{c} voxels (quality.volume_level 1)");
        }
        if args.pass_timings {
            let [light, view, listing, finish] = s.pass_ms;
            println!(
                "GPU ms by pass: light {light:.1}, view {view:.1}, listing and clearing {listing:.1}, finish {finish:.1}"
            );
        }
        if let Some(axes) = s.volume_axes {
            let [f, m, l] = axes.map(|a| ["x", "y", "z"][a as usize]);
            println!("volume textures laid out {f}, {m}, {l} (fastest first; stored x, y, z): the view looks along x");
        }
        println!(
            "view passes: {} over {} planes, each over up to {} planes",
            s.view_passes, s.planes_run, s.view_planes
        );
        if let Some(steps) = s.light_steps {
            let t = s.tile;
            println!("light tile steps: {steps} (tiles of {t}×{t} beams stepped, over all planes)");
        }
        if let Some(l) = &s.lbm {
            println!(
                "lbm: {}×{}×{} cells of {} voxels, {} steps, residual {:.1e}{}, {:.1} GPU ms (in the total), {:.1} MiB",
                l.grid[0],
                l.grid[1],
                l.grid[2],
                l.cell_voxels,
                l.iterations,
                l.residual,
                if l.converged { "" } else { " (not converged)" },
                l.gpu_ms,
                mib(l.bytes),
            );
        }
    }
    eprintln!("wrote {} ({}×{})", args.output.display(), args.size.0, args.size.1);
    Ok(())
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}
