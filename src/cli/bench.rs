//! `caustica bench`: the speed–accuracy sweep, the speed table, the light-transport table, or
//! the reference's convergence.

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
    /// GPU frames per setting (default 5, or 3 with --quick; with --speed 5, or 3 with --quick,
    /// and 1 on a CPU driver).
    #[arg(long)]
    frames: Option<u32>,
    /// Voxels along the longest axis of the built-in volumes (default 64, or 40 with --quick;
    /// with --speed the built-in default, 128).
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
    /// distance 2, 1, 0.5, 0.25; writes light.md and light.csv.
    #[arg(long)]
    light: bool,
    /// With --light: the image edge in texels (the frame spans 4 R; default 128, or 64 with
    /// --quick); with --steps: the viewport edge.
    #[arg(long)]
    size: Option<u32>,
    /// Instead of the sweep, the speed table: GPU ms per frame and per plane, planes,
    /// light-grid cells, light tile steps, footprint pixels and peak memory for each scene at 128², 256², 512²
    /// and 1024² (128² and 256² with --quick; on a CPU driver up to 512², or 256² with --quick)
    /// and 8² (the fixed cost per plane), with the
    /// scaling fit; writes speed.md, speed.csv, speed-fit.csv and speed.png (ms per frame against
    /// pixels × planes). Scenes: the built-in ones at
    /// their own resolution (or --resolution) and the CT head (`ct-head`) when it was fetched.
    #[arg(long)]
    speed: bool,
    /// With --speed: viewport edges in pixels, comma separated (instead of the defaults).
    #[arg(long, value_delimiter = ',')]
    sizes: Vec<u32>,
    /// With --speed: the CT head volume, rendered with the scene of datasets/ct-head.toml
    /// (default: target/datasets/ct-head.nhdr or datasets/data/ct-head.nhdr, whichever
    /// exists; `bash datasets/fetch target/datasets` fetches it).
    #[arg(long)]
    ct_head: Option<PathBuf>,
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
    /// Instead of the sweep, the beam-spread tables: the Monte Carlo reference's spread of a
    /// pencil beam in Premoze et al.'s Fig. 4 medium against their Eq. 1 and 18 and against
    /// the exact moments; then a narrow beam into a slab (g = 0.9, b = 0.05–0.2 per voxel)
    /// rendered with each multiple-scattering mode (none, spread at Δs 1 and 0.5, lbm with
    /// cells of 4 and 2 voxels): width and radial profile against the Monte Carlo light, and
    /// GPU ms per render (--frames: timed renders, default 3, or 1 with --quick); writes
    /// scatter.md, scatter.csv and scatter.png.
    #[arg(long)]
    scatter: bool,
}

pub fn bench(args: &BenchArgs) -> Result<()> {
    use caustica::bench::{self, Plan};
    if args.speed {
        return speed_bench(args);
    }
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
        return scatter_bench(args);
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
        return show_report(None, &path, &[]);
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    if args.steps {
        return steps_bench(args, &plan.scenes, ctx);
    }
    if args.light {
        return light_bench(args, ctx);
    }
    let report = bench::run(ctx.clone(), &plan, &args.out, true)?;
    show_report(Some(&ctx), &report.markdown, &[&report.csv, &report.plot])
}

fn scatter_bench(args: &BenchArgs) -> Result<()> {
    use caustica::bench::scatter::{self, ScatterPlan};
    let mut plan = if args.quick {
        ScatterPlan::quick()
    } else {
        ScatterPlan::full()
    };
    if let Some(f) = args.frames {
        if f == 0 {
            return Err(input(anyhow!("--frames must be at least 1")));
        }
        plan.modes.frames = f;
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    let report = scatter::run(ctx.clone(), &plan, &args.out, true)?;
    show_report(Some(&ctx), &report.markdown, &[&report.csv, &report.plot])
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
    show_report(None, &path, &[])
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
    show_report(Some(&ctx), &report.markdown, &[&report.csv])
}

/// The name of the CT head in `--scenes` and the speed table.
const CT_HEAD: &str = "ct-head";
/// Its scene file, relative to the project's root (where the bench runs).
const CT_HEAD_SCENE: &str = "datasets/ct-head.toml";
/// Where `datasets/fetch` puts the CT head: the folder the tests use, then the script's default.
const CT_HEAD_VOLUMES: [&str; 2] = ["target/datasets/ct-head.nhdr", "datasets/data/ct-head.nhdr"];

/// The CT head scene with its volume at `volume`.
fn ct_head_scene(volume: &std::path::Path) -> Result<caustica::scene::Scene> {
    use caustica::scene::{Scene, VolumeSource};
    let mut scene = Scene::load(std::path::Path::new(CT_HEAD_SCENE))
        .with_context(|| format!("the CT head's scene {CT_HEAD_SCENE} (run the bench from the project's root)"))
        .map_err(input)?;
    scene.volume = VolumeSource::File {
        path: volume.to_path_buf(),
        series: None,
    };
    Ok(scene)
}

fn speed_bench(args: &BenchArgs) -> Result<()> {
    use caustica::bench::speed::{self, SpeedPlan, SpeedScene};
    let asked_ct = args.scenes.iter().any(|s| s == CT_HEAD);
    let ct_volume = match &args.ct_head {
        Some(p) if !p.exists() => {
            return Err(input(anyhow!("--ct-head {}: no such file", p.display())));
        }
        Some(p) => Some(p.clone()),
        None => CT_HEAD_VOLUMES.iter().map(PathBuf::from).find(|p| p.exists()),
    };
    let mut scenes = Vec::new();
    let names: Vec<String> = if args.scenes.is_empty() {
        BUILTIN_SCENES.iter().map(|s| s.to_string()).collect()
    } else {
        args.scenes.iter().filter(|s| *s != CT_HEAD).cloned().collect()
    };
    for name in &names {
        scenes.push(SpeedScene::builtin(name, args.resolution)?);
    }
    if args.scenes.is_empty() || asked_ct {
        match &ct_volume {
            Some(v) => scenes.push(SpeedScene {
                name: CT_HEAD.into(),
                scene: ct_head_scene(v)?,
            }),
            None if asked_ct => {
                return Err(input(anyhow!(
                "the CT head is not at {}: `bash datasets/fetch target/datasets` fetches it, or give --ct-head FILE",
                CT_HEAD_VOLUMES.join(" or ")
            )))
            }
            None => eprintln!(
                "note: the CT head is not at {} and is left out (`bash datasets/fetch target/datasets` fetches it)",
                CT_HEAD_VOLUMES.join(" or ")
            ),
        }
    }
    let ctx = Context::new(&ContextDesc::from_env(DeviceSelector::parse(&args.device)))?;
    let mut plan = SpeedPlan::for_device(scenes, ctx.info.kind == "CPU", args.quick);
    if let Some(f) = args.frames {
        if f == 0 {
            return Err(input(anyhow!("--frames must be at least 1")));
        }
        plan.frames = f;
    }
    if !args.sizes.is_empty() {
        if args.sizes.contains(&0) {
            return Err(input(anyhow!("--sizes must be at least 1 pixel each")));
        }
        plan.sizes = args.sizes.clone();
    }
    let report = speed::run(ctx.clone(), &plan, &args.out, true)?;
    show_report(
        Some(&ctx),
        &report.markdown,
        &[&report.csv, &report.fit_csv, &report.plot],
    )
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
    show_report(Some(&ctx), &args.out.join("steps.md"), &[&args.out.join("steps.csv")])
}

/// Prints the Markdown report at `markdown`, names every file written, and fails when the
/// device reported validation errors during the run.
fn show_report(ctx: Option<&Context>, markdown: &std::path::Path, also: &[&std::path::Path]) -> Result<()> {
    print!("{}", read_report(markdown).map_err(input)?);
    let mut names: Vec<String> = std::iter::once(markdown)
        .chain(also.iter().copied())
        .map(|p| p.display().to_string())
        .collect();
    let last = names.pop().unwrap_or_default();
    if names.is_empty() {
        eprintln!("wrote {last}");
    } else {
        eprintln!("wrote {} and {last}", names.join(", "));
    }
    match ctx.map(Context::validation_errors) {
        Some(n) if n > 0 => Err(BenchValidationFailed(n).into()),
        _ => Ok(()),
    }
}

fn read_report(path: &std::path::Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}
