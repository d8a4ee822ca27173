//! `caustica bench`: the speed–accuracy sweep, or the reference's convergence.

use std::path::PathBuf;

use anyhow::{anyhow, Context as _};

use caustica::gpu::{Context, ContextDesc, DeviceSelector};
use caustica::scene::{builtin, BUILTIN_SCENES};
use caustica::{Classify, ExitClass};

use crate::{input, Result};

/// `bench` saw validation errors: its measurements are not trustworthy (exit code 4).
#[derive(Debug, thiserror::Error)]
#[error("{0} Vulkan validation errors were reported")]
struct BenchValidationFailed(u64);

impl Classify for BenchValidationFailed {
    fn exit_class(&self) -> ExitClass {
        ExitClass::Gpu
    }
}

#[derive(clap::Args)]
pub struct BenchArgs {
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
    /// Switch the scenes' highlights off in both renderers (to compare everything else).
    #[arg(long)]
    no_highlights: bool,
    /// Instead of the sweep, the light-transport table: the light buffer against the exact
    /// light on planes 1.1–3 R behind a glass ball (R = 16 voxels), per transport and sample
    /// distance 1, 0.5, 0.25; writes light.md and light.csv.
    #[arg(long)]
    light: bool,
    /// With --light: the image edge in texels (the frame spans 4 R; default 128, or 64 with
    /// --quick); with --steps: the viewport edge.
    #[arg(long)]
    size: Option<u32>,
    /// Instead of the sweep, measure the reference renderer's convergence (error against a
    /// finer run of itself versus rays per voxel² and step length) on the first scene; with
    /// --light, the exact plane trace's (versus rays per texel and step); no GPU.
    #[arg(long)]
    convergence: bool,
    /// Instead of the sweep, convergence in the plane distance: each scene's default image
    /// against Δs = 0.25 (128-voxel built-in volumes at 160²), and with --quick against the
    /// reference too (40³, 128² against a 64² reference); writes steps.md and steps.csv.
    #[arg(long)]
    steps: bool,
    /// With --steps: scene files measured besides the built-in scenes (GPU only).
    #[arg(long = "scene-file")]
    scene_files: Vec<PathBuf>,
    /// Instead of the sweep, the beam-spread table: the Monte Carlo reference's spread of a
    /// pencil beam in Premoze et al.'s Fig. 4 medium against their Eq. 1 and 18, and against
    /// the exact moments; writes scatter.md; no GPU.
    #[arg(long)]
    scatter: bool,
}

pub fn bench(args: &BenchArgs) -> Result<()> {
    use caustica::bench::{self, Plan};
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
            return Err(input(anyhow!("--frames must be at least 1")));
        }
        plan.frames = f;
    }
    if let Some(r) = args.resolution {
        plan.resolution = r;
    }
    plan.highlights = !args.no_highlights;
    if args.scatter {
        std::fs::create_dir_all(&args.out)
            .with_context(|| format!("creating {}", args.out.display()))
            .map_err(input)?;
        let photons = if args.quick { 20_000 } else { 200_000 };
        print!("{}", bench::scatter::run(photons, &args.out)?);
        eprintln!("wrote {}", args.out.join("scatter.md").display());
        return Ok(());
    }
    if args.light && args.convergence {
        return light_convergence(args);
    }
    if args.convergence {
        let path = args.out.join("convergence.md");
        std::fs::create_dir_all(&args.out)
            .with_context(|| format!("creating {}", args.out.display()))
            .map_err(input)?;
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
        print!("{}", read_report(&path).map_err(input)?);
        eprintln!("wrote {}", path.display());
        return Ok(());
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    if args.steps {
        return steps_bench(args, &plan.scenes, ctx);
    }
    if args.light {
        return light_bench(args, ctx);
    }
    let report = bench::run(ctx.clone(), &plan, &args.out, true)?;
    print!("{}", read_report(&report.markdown).map_err(input)?);
    eprintln!(
        "wrote {}, {} and {}",
        report.markdown.display(),
        report.csv.display(),
        report.plot.display()
    );
    if ctx.validation_errors() > 0 {
        return Err(BenchValidationFailed(ctx.validation_errors()).into());
    }
    Ok(())
}

fn light_convergence(args: &BenchArgs) -> Result<()> {
    use caustica::bench::light::{self, LightPlan};
    let mut plan = if args.quick {
        LightPlan::quick(Vec::new())
    } else {
        LightPlan::full(Vec::new())
    };
    if let Some(size) = args.size {
        if size == 0 {
            return Err(input(anyhow!("--size must be at least 1")));
        }
        plan.size = size;
    }
    let runs: &[(u32, f64)] = &[(1, 0.25), (2, 0.25), (4, 0.25), (8, 0.25), (8, 0.5), (8, 0.125)];
    let truth = if args.quick { (16, 0.125) } else { (16, 0.0625) };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))
        .map_err(input)?;
    let path = args.out.join("light-convergence.md");
    light::convergence(&plan, runs, truth, &path)?;
    print!("{}", read_report(&path).map_err(input)?);
    eprintln!("wrote {}", path.display());
    Ok(())
}

fn light_bench(args: &BenchArgs, ctx: std::sync::Arc<Context>) -> Result<()> {
    use caustica::bench::light::{self, transport_variants, LightPlan};
    let mut plan = if args.quick {
        LightPlan::quick(transport_variants())
    } else {
        LightPlan::full(transport_variants())
    };
    if let Some(f) = args.frames {
        if f == 0 {
            return Err(input(anyhow!("--frames must be at least 1")));
        }
        plan.frames = f;
    }
    if let Some(size) = args.size {
        if size == 0 {
            return Err(input(anyhow!("--size must be at least 1")));
        }
        plan.size = size;
    }
    let report = light::run(ctx.clone(), &plan, &args.out)?;
    print!("{}", read_report(&report.markdown).map_err(input)?);
    eprintln!("wrote {} and {}", report.markdown.display(), report.csv.display());
    if ctx.validation_errors() > 0 {
        return Err(BenchValidationFailed(ctx.validation_errors()).into());
    }
    Ok(())
}

fn steps_bench(args: &BenchArgs, scenes: &[String], ctx: std::sync::Arc<Context>) -> Result<()> {
    use caustica::bench::steps::{self, StepsPlan, StepsScene};
    let mut list: Vec<StepsScene> = if args.scenes.is_empty() && !args.scene_files.is_empty() {
        Vec::new()
    } else {
        scenes.iter().map(|s| StepsScene::Builtin(s.clone())).collect()
    };
    list.extend(args.scene_files.iter().map(|p| StepsScene::File(p.clone())));
    let mut plan = if args.quick {
        StepsPlan::quick(list)
    } else {
        StepsPlan::convergence(list)
    };
    if let Some(r) = args.resolution {
        plan.resolution = r;
    }
    if let Some(size) = args.size {
        if size == 0 {
            return Err(input(anyhow!("--size must be at least 1")));
        }
        plan.size = size;
    }
    plan.highlights = !args.no_highlights;
    steps::run(ctx.clone(), &plan, &args.out, true)?;
    let path = args.out.join("steps.md");
    print!("{}", read_report(&path).map_err(input)?);
    eprintln!("wrote {} and steps.csv", path.display());
    if ctx.validation_errors() > 0 {
        return Err(BenchValidationFailed(ctx.validation_errors()).into());
    }
    Ok(())
}

fn read_report(path: &std::path::Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}
