//! What a change of each of the viewer's controls costs the next frame: wall time of the
//! render call (upload and setup included), its GPU part and the bytes copied in, at about
//! the viewer's interactive level (127×152 pixels, planes 6 times the scene's distance apart,
//! a quarter of the beams, the half-resolution volume). Each change is made and undone twice,
//! one frame after each:
//!
//! ```sh
//! datasets/fetch
//! cargo run --release --example edit_costs -- datasets/ct-head.toml
//! ```
//!
//! The first frame after a change that needs another shader variant includes compiling it,
//! unless `--precompile` compiles each change's variant before its first frame, as the viewer
//! does for the variants one click of its panel away once a view has settled:
//!
//! ```sh
//! cargo run --release --example edit_costs -- datasets/ct-head.toml --precompile
//! ```
//!
//! `--only NAME` times the changes whose names contain NAME (`--only window`), for profiling.

use std::time::Instant;

use caustica::gpu::{Context, ContextDesc};
use caustica::render::{PreparedScene, RenderRequest, Renderer};
use caustica::scene::{EnvMap, Environment, Scene, Toggle};

/// A control's name and how to set it (`true`) or back (`false`).
type Change = (&'static str, fn(&mut PreparedScene, bool));

const CHANGES: [Change; 14] = [
    ("nothing", |_, _| {}),
    ("camera yaw", |p, on| {
        p.scene.camera.yaw_deg += if on { 5.0 } else { -5.0 }
    }),
    ("light polar angle", |p, on| {
        p.scene.light.polar_deg += if on { 5.0 } else { -5.0 }
    }),
    ("light softness", |p, on| {
        p.scene.light.softness *= if on { 2.0 } else { 0.5 }
    }),
    ("light intensity", |p, on| {
        p.scene.light.intensity *= if on { 2.0 } else { 0.5 }
    }),
    ("specular", |p, on| {
        p.scene.shading.specular *= if on { 2.0 } else { 0.5 }
    }),
    ("roughness", |p, on| {
        p.scene.shading.roughness *= if on { 2.0 } else { 0.5 }
    }),
    ("termination opacity", |p, on| {
        p.scene.quality.termination_opacity = if on { 0.99 } else { 0.995 }
    }),
    ("opacity", |p, on| {
        for point in &mut p.tf.opacity.points {
            point[1] *= if on { 0.9 } else { 1.0 / 0.9 };
        }
    }),
    ("η", |p, on| {
        for point in &mut p.tf.eta.points {
            point[1] = 1.0 + (point[1] - 1.0) * if on { 0.9 } else { 1.0 / 0.9 };
        }
    }),
    ("data window", |p, on| {
        let [lo, hi] = p.window();
        p.scene.window = Some([lo, hi + if on { 50.0 } else { -50.0 }]);
    }),
    ("environment intensity", |p, on| {
        p.scene.environment = match &p.scene.environment {
            Environment::Studio { intensity } => Environment::Studio {
                intensity: intensity * if on { 2.0 } else { 0.5 },
            },
            Environment::Image { path, intensity } => Environment::Image {
                path: path.clone(),
                intensity: intensity * if on { 2.0 } else { 0.5 },
            },
            other => other.clone(),
        };
    }),
    ("background colour", |p, on| {
        p.scene.environment = Environment::Color {
            color: if on { [0.2, 0.2, 0.3] } else { [0.3, 0.2, 0.2] },
        };
    }),
    ("refraction off", |p, on| {
        p.scene.quality.refraction = if on { Toggle::Off } else { Toggle::Auto };
    }),
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let precompile = args.iter().any(|a| a == "--precompile");
    // `--only NAME`: the changes whose names contain NAME, for profiling one of them.
    let only = args
        .iter()
        .position(|a| a == "--only")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let path = args
        .iter()
        .enumerate()
        .find(|&(i, a)| !a.starts_with("--") && (i == 0 || args[i - 1] != "--only"))
        .map(|(_, a)| a)
        .cloned()
        .unwrap_or_else(|| "datasets/ct-head.toml".into());
    let scene = Scene::load(std::path::Path::new(&path))?;
    let mut p = PreparedScene::load(&scene)?;
    p.scene.quality.sample_distance *= 6.0;
    p.scene.quality.beams_per_texel *= 0.25;
    p.scene.quality.volume_level = 1;
    let mut renderer = Renderer::new(Context::new(&ContextDesc::default())?)?;
    let mut req = RenderRequest::new(127, 152);
    req.keep_coarse_volume = true;
    req.keep_staging = true;
    let frame = |renderer: &mut Renderer, p: &PreparedScene| -> Result<String, Box<dyn std::error::Error>> {
        let start = Instant::now();
        let out = renderer.render(p, &req)?;
        Ok(format!(
            "{:.0} / {:.0} / {:.1}",
            start.elapsed().as_secs_f64() * 1e3,
            out.stats.gpu_ms,
            out.stats.upload_bytes as f64 / (1u64 << 20) as f64
        ))
    };
    frame(&mut renderer, &p)?;
    println!("| change | frames after it: wall ms / GPU ms / MiB copied in |");
    println!("|---|---|");
    for (name, change) in CHANGES {
        if only.as_ref().is_some_and(|o| !name.contains(o.as_str())) {
            continue;
        }
        let mut frames = Vec::new();
        for on in [true, false, true, false] {
            change(&mut p, on);
            if name == "environment intensity" || name == "background colour" {
                // As the viewer's worker does when the scene's environment changes.
                p.env = EnvMap::for_scene(&p.scene.environment)?;
            }
            if precompile {
                // As the viewer's compile thread does, but at once.
                if let Some(job) = renderer.precompile(&p, &req)? {
                    let start = Instant::now();
                    renderer.adopt(job.compile()?);
                    eprintln!(
                        "{name}: compiled ahead in {:.0} ms",
                        start.elapsed().as_secs_f64() * 1e3
                    );
                }
            }
            frames.push(frame(&mut renderer, &p)?);
        }
        println!("| {name} | {} |", frames.join(", "));
    }
    Ok(())
}
