//! `caustica bench --steps`: how far an image at the default plane distance is from the same
//! renderer's fine-step result and from the reference. Per scene: the default image (Δs = 1),
//! the same scene at Δs = 0.25, relative L1 between the two, and, for built-in scenes, both
//! against the reference renderer; the GPU time per plane of each. A renderer whose
//! pre-integration and shading converge shows a small default-against-fine error: woodgrain,
//! banding and sample-position noise all show up there first.

use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{bench_scene, compare, save, write_err, BenchError, Linear};
use crate::gpu::Context;
use crate::reference::photons::PhotonSettings;
use crate::reference::{self, ReferenceSettings};
use crate::render::{PreparedScene, RenderRequest, Renderer};
use crate::scene::Scene;

/// A scene to measure: built-in (with a reference image) or a scene file (GPU only: real
/// volumes are too large for the reference in a bench run).
#[derive(Clone, Debug)]
pub enum StepsScene {
    Builtin(String),
    File(PathBuf),
}

impl StepsScene {
    fn name(&self) -> String {
        match self {
            StepsScene::Builtin(n) => n.clone(),
            StepsScene::File(p) => p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| p.display().to_string()),
        }
    }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct StepsPlan {
    pub scenes: Vec<StepsScene>,
    /// Voxels along the longest axis of the built-in volumes.
    pub resolution: usize,
    /// Square viewport edge of the GPU images.
    pub size: u32,
    /// The default plane distance and the fine one it is compared with (voxels).
    pub sample_distance: f32,
    pub fine_sample_distance: f32,
    /// Square size of the reference images (divides `size`), and its settings; `None`: no
    /// reference.
    pub reference: Option<(u32, ReferenceSettings)>,
    /// Render the scenes' highlights (both renderers model them).
    pub highlights: bool,
}

impl StepsPlan {
    /// The measurement: built-in scenes at 128 voxels, 160² (no reference).
    pub fn convergence(scenes: Vec<StepsScene>) -> StepsPlan {
        StepsPlan {
            scenes,
            resolution: 128,
            size: 160,
            sample_distance: 1.0,
            fine_sample_distance: 0.25,
            reference: None,
            highlights: true,
        }
    }

    /// The bench's quick comparison with the reference: 40³ volumes, 128² against a 64²
    /// reference (64 rays per voxel², half-voxel view steps, 2×2 rays per pixel), as
    /// `bench --quick`. The reference's rays per pixel fall on the GPU image's pixel centres,
    /// which the comparison box-filters 2×2: both are sampled and filtered alike. With one ray
    /// per pixel the comparison counted the reference's aliasing (0.005–0.015 of the glass
    /// scenes' L1), and with 16 rays per voxel² its photon noise in the glass's caustics
    /// (another seed moved glass-beer's L1 by 0.010; at 64 rays by 0.002).
    pub fn quick(scenes: Vec<StepsScene>) -> StepsPlan {
        StepsPlan {
            resolution: 40,
            size: 128,
            reference: Some((
                64,
                ReferenceSettings {
                    photons: PhotonSettings {
                        rays_per_voxel2: 64.0,
                        ..PhotonSettings::default()
                    },
                    view_step_voxels: 0.5,
                    samples_per_axis: 2,
                    ..ReferenceSettings::default()
                },
            )),
            ..StepsPlan::convergence(scenes)
        }
    }
}

/// One scene's row.
#[derive(Clone, Debug)]
pub struct StepsRow {
    pub scene: String,
    pub planes: u32,
    pub ms_per_plane: f64,
    pub fine_planes: u32,
    pub fine_ms_per_plane: f64,
    /// Relative L1 of the default image against the fine one (at the GPU's size).
    pub default_vs_fine: f64,
    /// Relative L1 of the default and the fine image against the reference.
    pub default_vs_reference: Option<f64>,
    pub fine_vs_reference: Option<f64>,
}

fn prepare(scene: &StepsScene, plan: &StepsPlan) -> Result<PreparedScene, BenchError> {
    match scene {
        StepsScene::Builtin(name) => bench_scene(name, plan.resolution, plan.highlights),
        StepsScene::File(path) => {
            let mut s = Scene::load(path)?;
            s.quality.specular &= plan.highlights;
            Ok(PreparedScene::load(&s)?)
        }
    }
}

/// Runs `plan` and writes `steps.md`, `steps.csv` and each scene's images into `out`.
pub fn run(ctx: Arc<Context>, plan: &StepsPlan, out: &Path, progress: bool) -> Result<Vec<StepsRow>, BenchError> {
    if plan.scenes.is_empty() {
        return Err(BenchError::Plan("needs at least one scene".into()));
    }
    if let Some((n, _)) = &plan.reference {
        if *n == 0 || plan.size % n != 0 {
            return Err(BenchError::Plan(format!(
                "viewport {} is not a multiple of the reference size {n}",
                plan.size
            )));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| write_err(out)(e.to_string()))?;
    let mut renderer = Renderer::new(ctx)?;
    let bar = (progress && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(plan.scenes.len() as u64);
        if let Ok(style) = indicatif::ProgressStyle::with_template("bench {pos}/{len} {wide_bar} {eta} {msg}") {
            bar.set_style(style);
        }
        bar
    });
    let mut rows = Vec::new();
    for scene in &plan.scenes {
        let name = scene.name();
        if let Some(b) = &bar {
            b.set_message(name.clone());
        }
        let mut prepared = prepare(scene, plan)?;
        let req = RenderRequest::new(plan.size, plan.size);
        prepared.scene.quality.sample_distance = plan.sample_distance;
        let coarse = renderer.render(&prepared, &req)?;
        prepared.scene.quality.sample_distance = plan.fine_sample_distance;
        let fine = renderer.render(&prepared, &req)?;
        save(&coarse.image, &out.join(format!("{name}-default.png")))?;
        save(&fine.image, &out.join(format!("{name}-fine.png")))?;
        let (c, f) = (Linear::from_image(&coarse.image), Linear::from_image(&fine.image));
        let mismatch = || BenchError::Plan("image sizes do not match".into());
        let default_vs_fine = compare(&c, &f).ok_or_else(mismatch)?.rel_l1;
        let (mut default_vs_reference, mut fine_vs_reference) = (None, None);
        if let (Some((n, settings)), StepsScene::Builtin(_)) = (&plan.reference, scene) {
            prepared.scene.quality.sample_distance = plan.sample_distance;
            let r = reference::render(&prepared, *n, *n, settings, false)?;
            save(&r, &out.join(format!("{name}-reference.png")))?;
            let r = Linear::from_image(&r);
            default_vs_reference = Some(compare(&c, &r).ok_or_else(mismatch)?.rel_l1);
            fine_vs_reference = Some(compare(&f, &r).ok_or_else(mismatch)?.rel_l1);
        }
        rows.push(StepsRow {
            scene: name,
            planes: coarse.stats.planes,
            ms_per_plane: coarse.stats.ms_per_plane,
            fine_planes: fine.stats.planes,
            fine_ms_per_plane: fine.stats.ms_per_plane,
            default_vs_fine,
            default_vs_reference,
            fine_vs_reference,
        });
        if let Some(b) = &bar {
            b.inc(1);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let md = out.join("steps.md");
    std::fs::write(&md, markdown(&rows, plan)).map_err(|e| write_err(&md)(e.to_string()))?;
    let csv = out.join("steps.csv");
    std::fs::write(&csv, csv_text(&rows)).map_err(|e| write_err(&csv)(e.to_string()))?;
    Ok(rows)
}

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "—".to_string(), |v| format!("{v:.4}"))
}

/// The Markdown table of `rows`.
pub fn markdown(rows: &[StepsRow], plan: &StepsPlan) -> String {
    let mut s = String::new();
    let _ = write!(
        s,
        "Built-in volumes at {} voxels, {}² pixels, highlights {}; relative L1 of the image at Δs = {} \
         against Δs = {}",
        plan.resolution,
        plan.size,
        if plan.highlights { "on" } else { "off" },
        plan.sample_distance,
        plan.fine_sample_distance
    );
    if let Some((n, r)) = &plan.reference {
        let _ = write!(
            s,
            " and against the reference at {n}² ({} rays/voxel², {}-voxel view steps)",
            r.photons.rays_per_voxel2, r.view_step_voxels
        );
    }
    s.push_str(".\n\n");
    s.push_str("| scene | planes | ms/plane | fine planes | fine ms/plane | default vs fine | default vs ref. | fine vs ref. |\n");
    s.push_str("|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2} | {} | {:.2} | {:.4} | {} | {} |",
            r.scene,
            r.planes,
            r.ms_per_plane,
            r.fine_planes,
            r.fine_ms_per_plane,
            r.default_vs_fine,
            opt(r.default_vs_reference),
            opt(r.fine_vs_reference)
        );
    }
    s
}

fn csv_text(rows: &[StepsRow]) -> String {
    let mut s = String::from(
        "scene,planes,ms_per_plane,fine_planes,fine_ms_per_plane,default_vs_fine,default_vs_reference,fine_vs_reference\n",
    );
    let o = |v: Option<f64>| v.map_or_else(String::new, |v| format!("{v:.6}"));
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{:.4},{},{:.4},{:.6},{},{}",
            r.scene,
            r.planes,
            r.ms_per_plane,
            r.fine_planes,
            r.fine_ms_per_plane,
            r.default_vs_fine,
            o(r.default_vs_reference),
            o(r.fine_vs_reference)
        );
    }
    s
}
