//! `caustica bench --light`: the GPU's light buffer against the exact irradiance on the same
//! planes behind a glass ball (n = 1.5, parallel light head-on, orthographic, no absorption,
//! no softness), per light-transport variant and sample distance: relative L1, the brightest
//! texel, the power inside r < R and on the whole frame, and the GPU time per plane.
//!
//! Each receiver plane is the plane of the GPU's sweep nearest to the wanted distance behind
//! the ball's centre (`reference::plane_light::nearest_sweep_plane`), and the exact trace is
//! run at exactly that depth, so both sides measure the same plane. The exact light is the
//! continuous ball's ([`graded_ball`]: the analytic index ramp the volume samples), traced
//! once for every plane of every sample distance and shared by the variants; the voxelised
//! ball's exact trace is measured against it too, as the error voxelisation alone makes.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use glam::{DVec2, DVec3, Vec3};

use super::{median, write_err, BenchError};
use crate::gpu::Context;
use crate::reference::graded_ball::GradedBall;
use crate::reference::measure::{self, Region, ScalarImage};
use crate::reference::plane_light::{self, nearest_sweep_plane, PlaneSettings};
use crate::render::{DebugView, PreparedScene, RenderRequest, Renderer, ViewSetup};
use crate::scene::view::REFRACTED_BEAMS_PER_VOXEL;
use crate::scene::{Quality, Scene};
use crate::transfer::{ColorRamp, Curve, TransferFunctions};
use crate::volume::{Volume, VolumeError};

/// Refractive index of the ball.
pub const BALL_ETA: f32 = 1.5;
/// Width (voxels) over which the ball's surface ramps from glass to air. A trilinear sphere
/// is faceted: within each voxel its gradient turns by up to ~½ voxel / R, which past the
/// focus draws an eight-fold star into the exact light (at 3 R behind a 1.5-voxel ramp, ±40%
/// around r = R/2; a smooth analytic ball gives ±3%). Three voxels, as the analytic tests.
pub const BALL_EDGE_VOXELS: f64 = 3.0;

/// Label of the rows that measure the voxelised ball's exact trace (no GPU).
pub const VOXELS_LABEL: &str = "exact trace of the voxels (CPU)";

/// A light-transport setting to measure: a label and what it changes in the scene.
pub struct Variant {
    pub label: String,
    pub apply: Box<dyn Fn(&mut Scene) + Send + Sync>,
}

impl Variant {
    pub fn new(label: &str, apply: impl Fn(&mut Scene) + Send + Sync + 'static) -> Variant {
        Variant {
            label: label.into(),
            apply: Box::new(apply),
        }
    }
}

/// The light-transport variants the bench compares by default.
pub fn transport_variants() -> Vec<Variant> {
    use crate::scene::LightTransport;
    vec![
        Variant::new("beams", |s| s.quality.light_transport = LightTransport::Beams),
        Variant::new("beams, ½² per texel", |s| {
            s.quality.light_transport = LightTransport::Beams;
            s.quality.beams_per_texel = 0.5;
        }),
        Variant::new("beams, 2² per texel", |s| {
            s.quality.light_transport = LightTransport::Beams;
            s.quality.beams_per_texel = 2.0;
        }),
        Variant::new("beams, 2² per texel, fourth-order ∇η", |s| {
            s.quality.light_transport = LightTransport::Beams;
            s.quality.beams_per_texel = 2.0;
            s.quality.gradient = crate::scene::Gradient::FourthOrder;
        }),
        Variant::new("backward", |s| s.quality.light_transport = LightTransport::Backward),
    ]
}

/// What to run.
pub struct LightPlan {
    /// Ball radius R, in voxels.
    pub radius: f64,
    /// Square image edge; the frame spans 4 R.
    pub size: u32,
    /// Receiver planes, in R behind the ball's centre.
    pub depths: Vec<f64>,
    pub sample_distances: Vec<f32>,
    pub variants: Vec<Variant>,
    /// GPU renders per plane (median time).
    pub frames: u32,
    pub reference: PlaneSettings,
}

impl LightPlan {
    /// R = 16 voxels at 128² (half-voxel texels), Δs = 2, 1, ½, ¼, the planes of the caustics
    /// checks (1.1, 1.25, 1.5, 2 and 3 R). Δs 2 shows the other side of the default: how the
    /// error grows when the planes are coarser than the voxels.
    pub fn full(variants: Vec<Variant>) -> LightPlan {
        LightPlan {
            radius: 16.0,
            size: 128,
            depths: vec![1.1, 1.25, 1.5, 2.0, 3.0],
            sample_distances: vec![2.0, 1.0, 0.5, 0.25],
            variants,
            frames: 3,
            reference: PlaneSettings {
                rays_per_texel: 8,
                ..PlaneSettings::default()
            },
        }
    }

    /// The sample distance of the picture and of the voxelised ball's exact trace: a scene's
    /// default where the plan has it, else its first.
    pub fn picture_distance(&self) -> f32 {
        let default = Quality::default().sample_distance;
        if self.sample_distances.contains(&default) {
            default
        } else {
            self.sample_distances.first().copied().unwrap_or(default)
        }
    }

    /// The same at 64² (one-voxel texels), one frame per plane, 4² reference rays per texel.
    pub fn quick(variants: Vec<Variant>) -> LightPlan {
        LightPlan {
            size: 64,
            frames: 1,
            reference: PlaneSettings {
                rays_per_texel: 4,
                ..PlaneSettings::default()
            },
            ..LightPlan::full(variants)
        }
    }
}

/// The ball-lens volume for `radius` R: R + 4 voxels of air in front of the ball, room for
/// planes 3 R behind its centre, 1.5 R + 4 each side. Returns the volume, its transfer
/// functions (value 0.5 is glass) and the world z of the ball's centre.
pub fn ball_lens(radius: f64) -> Result<(Volume, TransferFunctions, f64), VolumeError> {
    let side = (3.0 * radius + 8.0).ceil() as usize;
    let depth = (4.0 * radius + 8.0).ceil() as usize;
    let dims = [side, side, depth];
    let centre_z = -(depth as f64) / 2.0 + radius + 4.0;
    let half = [side as f64 / 2.0, side as f64 / 2.0, depth as f64 / 2.0];
    let mut data = Vec::with_capacity(side * side * depth);
    for k in 0..depth {
        for j in 0..side {
            for i in 0..side {
                let p = [i, j, k].map(|v| v as f64 + 0.5);
                let (x, y, z) = (p[0] - half[0], p[1] - half[1], p[2] - half[2] - centre_z);
                let r = (x * x + y * y + z * z).sqrt();
                data.push((0.5 * (0.5 - (r - radius) / BALL_EDGE_VOXELS).clamp(0.0, 1.0)) as f32);
            }
        }
    }
    let tf = TransferFunctions {
        name: None,
        opacity: Curve::constant(0.0),
        color: ColorRamp::constant([1.0; 3]),
        eta: Curve {
            points: vec![[0.0, 1.0], [0.5, BALL_ETA]],
        },
        medium: ColorRamp::constant([1.0; 3]),
        albedo: None,
        anisotropy: None,
    };
    Ok((Volume::new(dims, [1.0; 3], data)?, tf, centre_z))
}

/// The continuous ball that [`ball_lens`] samples: the same index ramp as an analytic field,
/// centred at world z `centre_z` in `volume`'s box. Its exact trace is the truth the light
/// bench and tests measure against (voxelisation is part of the renderer's error).
pub fn graded_ball(volume: &Volume, radius: f64, centre_z: f64) -> GradedBall {
    let extent = |a: usize| volume.dims[a] as f64 * volume.spacing[a] as f64;
    GradedBall {
        centre: DVec3::new(0.0, 0.0, centre_z),
        radius,
        edge: BALL_EDGE_VOXELS,
        eta_in: BALL_ETA as f64,
        eta_out: 1.0,
        half_extent: 0.5 * DVec3::new(extent(0), extent(1), extent(2)),
    }
}

/// The scene around the ball: orthographic, head-on, the frame spanning 4 R; hard white light
/// along the view axis; black background.
pub fn ball_scene(volume: &Volume, tf: &TransferFunctions, radius: f64) -> Scene {
    let extent = Vec3::new(volume.dims[0] as f32, volume.dims[1] as f32, volume.dims[2] as f32);
    // The view spans 2·(bounding radius)/zoom vertically.
    let zoom = extent.length() / (4.0 * radius as f32);
    Scene::head_on("ball lens (light bench)", tf, zoom, Quality::default())
}

/// One measured plane.
#[derive(Clone, Debug)]
pub struct LightRow {
    pub variant: String,
    pub sample_distance: f32,
    /// Wanted distance behind the centre, in R, and the plane's actual one.
    pub depth_r: f64,
    pub plane_r: f64,
    pub plane_index: u32,
    /// Σ|gpu − exact| / Σ exact over [−1.5 R, 1.5 R]².
    pub rel_l1: f64,
    pub gpu_max: f64,
    pub exact_max: f64,
    /// Power inside r < R, GPU / exact.
    pub power_inside_ratio: f64,
    /// Power on the whole frame, GPU / exact.
    pub total_power_ratio: f64,
    /// Angular structure: largest relative deviation from their mean of the power in 16
    /// sectors of the annulus R/4–3R/4 (GPU; the exact light's alongside).
    pub angular_gpu: f64,
    pub angular_exact: f64,
    pub ms_per_plane: f64,
    /// Beams traced per texel and axis (the grid's cells, after the caps per voxel): what a
    /// variant asks for may be capped.
    pub beams_per_texel: f64,
}

/// The results and where they were written.
pub struct LightReport {
    pub rows: Vec<LightRow>,
    pub reference_seconds: f64,
    pub markdown: PathBuf,
    pub csv: PathBuf,
}

fn check(plan: &LightPlan) -> Result<(), BenchError> {
    if !(plan.radius.is_finite() && (2.0..=512.0).contains(&plan.radius)) || plan.size == 0 || plan.depths.is_empty() {
        return Err(BenchError::Plan(format!(
            "ball radius {} must be in [2, 512] voxels, the image at least 1 texel, and a depth given",
            plan.radius
        )));
    }
    Ok(())
}

/// View depth of the ball's centre in `scene`'s camera at `size`².
fn centre_depth(scene: &Scene, volume: &Volume, centre_z: f64, size: u32) -> Result<(ViewSetup, f64), BenchError> {
    let view = ViewSetup::new(scene, volume.dims, volume.spacing, size, size).map_err(BenchError::Plan)?;
    let z = view
        .view_from_world
        .transform_point3(Vec3::new(0.0, 0.0, centre_z as f32))
        .z as f64;
    Ok((view, z))
}

/// Runs `plan` and writes `light.md` and `light.csv` into `out`.
pub fn run(ctx: Arc<Context>, plan: &LightPlan, out: &Path) -> Result<LightReport, BenchError> {
    check(plan)?;
    if plan.variants.is_empty() || plan.sample_distances.is_empty() || plan.frames == 0 {
        return Err(BenchError::Plan(
            "the light bench needs a variant, a sample distance and a frame".into(),
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| write_err(out)(e.to_string()))?;
    let (volume, tf, centre_z) = ball_lens(plan.radius)?;
    let base = ball_scene(&volume, &tf, plan.radius);
    let size = plan.size;
    // The planes: for each sample distance, the sweep plane nearest each wanted depth.
    let mut planes = Vec::new(); // (Δs, depth in R, index, relative depth, z)
    for &ds in &plan.sample_distances {
        let mut scene = base.clone();
        scene.quality.sample_distance = ds;
        let (view, centre_view_z) = centre_depth(&scene, &volume, centre_z, size)?;
        for &d in &plan.depths {
            let (k, depth, z) = nearest_sweep_plane(&view, centre_view_z + d * plan.radius);
            planes.push((ds, d, k, depth, z, (z - centre_view_z) / plan.radius));
        }
    }
    let zs: Vec<f64> = planes.iter().map(|p| p.4).collect();
    let exact_scene = PreparedScene::from_parts(base.clone(), volume.clone(), tf.clone())?;
    let started = Instant::now();
    let ball = graded_ball(&volume, plan.radius, centre_z);
    let exact = plane_light::trace_scene_through(&exact_scene, &ball, size, size, &zs, &plan.reference)?;
    let reference_seconds = started.elapsed().as_secs_f64();
    // The voxelised ball traced exactly: what sampling the lens onto voxels costs by itself,
    // on the planes of the picture's sample distance.
    let picture_ds = plan.picture_distance();
    let picture_zs: Vec<f64> = planes.iter().filter(|p| p.0 == picture_ds).map(|p| p.4).collect();
    let voxels = plane_light::trace_scene(&exact_scene, size, size, &picture_zs, &plan.reference)?;

    let texel = 4.0 * plan.radius / size as f64;
    let centre = DVec2::splat((size as f64 - 1.0) / 2.0);
    let mut renderer = Renderer::new(ctx)?;
    let mut rows = Vec::new();
    // The picture: the exact light and each variant's at `picture_ds`.
    let mut picture: Vec<Vec<ScalarImage>> = vec![planes
        .iter()
        .enumerate()
        .filter(|(_, p)| p.0 == picture_ds)
        .map(|(i, _)| exact.planes[i].channel(1))
        .collect()];
    let ratio = |a: f64, b: f64| if b != 0.0 { a / b } else { f64::NAN };
    let r_texels = plan.radius / texel;
    let annulus = |img: &ScalarImage| measure::sector_variation(img, centre, 0.25 * r_texels, 0.75 * r_texels, 16);
    let compare = |label: &str,
                   ds: f32,
                   d: f64,
                   k: u32,
                   plane_r: f64,
                   test: &ScalarImage,
                   truth: &ScalarImage,
                   ms: f64,
                   beams: f64| {
        let region = Region::square(truth, centre, 1.5 * r_texels);
        LightRow {
            variant: label.into(),
            sample_distance: ds,
            depth_r: d,
            plane_r,
            plane_index: k,
            rel_l1: measure::relative_l1(test, truth, region).unwrap_or(f64::NAN),
            gpu_max: measure::peak(test).value,
            exact_max: measure::peak(truth).value,
            power_inside_ratio: ratio(
                measure::power_inside(test, centre, r_texels),
                measure::power_inside(truth, centre, r_texels),
            ),
            total_power_ratio: ratio(
                measure::total(test, Region::all(test)),
                measure::total(truth, Region::all(truth)),
            ),
            angular_gpu: annulus(test),
            angular_exact: annulus(truth),
            ms_per_plane: ms,
            beams_per_texel: beams,
        }
    };
    picture.push(Vec::new());
    for (j, (i, &(ds, d, k, _, _, plane_r))) in planes.iter().enumerate().filter(|(_, p)| p.0 == picture_ds).enumerate()
    {
        let test = voxels.planes[j].channel(1);
        let truth = exact.planes[i].channel(1);
        if let Some(row) = picture.last_mut() {
            row.push(test.clone());
        }
        rows.push(compare(
            VOXELS_LABEL,
            ds,
            d,
            k,
            plane_r,
            &test,
            &truth,
            f64::NAN,
            f64::NAN,
        ));
    }
    for variant in &plan.variants {
        picture.push(Vec::new());
        let mut prepared: Option<PreparedScene> = None;
        for (i, &(ds, d, k, depth, _, plane_r)) in planes.iter().enumerate() {
            // One prepared scene per sample distance, so that its textures stay on the device.
            if prepared.as_ref().is_none_or(|p| p.scene.quality.sample_distance != ds) {
                let mut scene = base.clone();
                scene.quality.sample_distance = ds;
                (variant.apply)(&mut scene);
                prepared = Some(PreparedScene::from_parts(scene, volume.clone(), tf.clone())?);
            }
            let Some(prepared) = prepared.as_ref() else { continue };
            let mut req = RenderRequest::new(size, size);
            req.debug_view = DebugView::Light;
            req.debug_depth = depth;
            let mut times = Vec::new();
            let mut last = None;
            for _ in 0..plan.frames {
                let frame = renderer.render(prepared, &req)?;
                times.push(frame.stats.gpu_ms / frame.stats.planes_run.max(1) as f64);
                last = Some(frame);
            }
            let Some(frame) = last else { continue };
            let light = prepared.scene.light.color[1] as f64 * prepared.scene.light.intensity as f64;
            let gpu = ScalarImage::from_image(&frame.image, 1);
            let mut truth = exact.planes[i].channel(1);
            truth.data.iter_mut().for_each(|v| *v *= light);
            if ds == picture_ds {
                if let Some(row) = picture.last_mut() {
                    row.push(gpu.clone());
                }
            }
            rows.push(compare(
                &variant.label,
                ds,
                d,
                k,
                plane_r,
                &gpu,
                &truth,
                median(&mut times),
                1.0 / frame.stats.light_cell_pixels.max(1e-6) as f64,
            ));
        }
    }
    let markdown = out.join("light.md");
    let csv = out.join("light.csv");
    let png = out.join("light.png");
    write_picture(&png, &picture).map_err(write_err(&png))?;
    write_markdown(&markdown, &rows, plan, &renderer, reference_seconds, texel).map_err(write_err(&markdown))?;
    write_csv(&csv, &rows).map_err(write_err(&csv))?;
    Ok(LightReport {
        rows,
        reference_seconds,
        markdown,
        csv,
    })
}

fn write_markdown(
    path: &Path,
    rows: &[LightRow],
    plan: &LightPlan,
    renderer: &Renderer,
    reference_seconds: f64,
    texel: f64,
) -> Result<(), String> {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Light buffer (`--debug-view light`) against the exact plane irradiance. Device: {}. Glass ball \
         n = {BALL_ETA}, R = {} voxels (surface ramp {BALL_EDGE_VOXELS} voxels), parallel light head-on, \
         orthographic, {}² texels of {texel} voxel. Exact trace of the continuous ball (the analytic ramp \
         the volume samples): {}² rays per texel, RK4 steps of {} voxel ({reference_seconds:.0} s); the \
         rows `{VOXELS_LABEL}` trace the voxelised ball the same way (trilinear index, ¼-voxel central \
         differences), the error of sampling the lens onto voxels alone. Relative L1 over [−1.5 R, 1.5 R]²; \
         power ratios GPU / exact; angular structure: largest deviation from the mean of the power in 16 \
         sectors of the annulus R/4–3R/4 (rings cancel, a star does not). Beams per texel: the light grid's \
         cells per texel and axis as traced (refracted beams are capped at {REFRACTED_BEAMS_PER_VOXEL} per voxel and axis \
         times the beams per texel asked for, but no coarser than half of it, so a row may trace fewer than its \
         label asks). GPU ms per plane: median \
         of {} renders.\n",
        super::device_label(renderer.context()),
        plan.radius,
        plan.size,
        plan.reference.rays_per_texel,
        plan.reference.step_voxels,
        plan.frames
    );
    let _ = writeln!(
        s,
        "`light.png`: the light on the planes at Δs = {}, one column per plane (nearest to {}), rows: the exact \
         light, the voxelised ball's exact light, then {}; each column scaled to the exact light's brightest texel, square-root tone.\n",
        plan.picture_distance(),
        plan.depths
            .iter()
            .map(|d| format!("{d} R"))
            .collect::<Vec<_>>()
            .join(", "),
        plan.variants
            .iter()
            .map(|v| v.label.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    );
    s.push_str("| transport | beams per texel | Δs | plane (R) | rel. L1 | brightest GPU | brightest exact | power r < R | total power | angular structure GPU / exact | ms per plane |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.3} | {:.3} | {:.2} | {:.2} | {:.3} | {:.4} | {:.3} / {:.3} | {} |",
            r.variant,
            if r.beams_per_texel.is_finite() {
                format!("{:.2}²", r.beams_per_texel)
            } else {
                "—".into()
            },
            r.sample_distance,
            r.plane_r,
            r.rel_l1,
            r.gpu_max,
            r.exact_max,
            r.power_inside_ratio,
            r.total_power_ratio,
            r.angular_gpu,
            r.angular_exact,
            if r.ms_per_plane.is_finite() {
                format!("{:.2}", r.ms_per_plane)
            } else {
                "—".into()
            }
        );
    }
    std::fs::write(path, s).map_err(|e| e.to_string())
}

/// The planes side by side: one row per image set (the exact light first, then each variant),
/// one column per receiver plane, each column scaled to the exact light's brightest texel and
/// shown as its square root (so that the dim disc behind the focus stays visible), each texel
/// drawn as 3 × 3 pixels with a 4-pixel gap.
fn write_picture(path: &Path, rows: &[Vec<ScalarImage>]) -> Result<(), String> {
    const ZOOM: usize = 3;
    const GAP: usize = 4;
    let Some(first) = rows.first().and_then(|r| r.first()) else {
        return Ok(());
    };
    let (w, h) = (first.width, first.height);
    let columns = rows.iter().map(Vec::len).max().unwrap_or(0);
    let width = columns * (w * ZOOM + GAP) + GAP;
    let height = rows.len() * (h * ZOOM + GAP) + GAP;
    let mut img = image::GrayImage::from_pixel(width as u32, height as u32, image::Luma([40]));
    for (ri, row) in rows.iter().enumerate() {
        for (ci, plane) in row.iter().enumerate() {
            let scale = rows[0].get(ci).map_or(1.0, |e| measure::peak(e).value.max(1e-12));
            for y in 0..h * ZOOM {
                for x in 0..w * ZOOM {
                    let v = (plane.at(x / ZOOM, y / ZOOM) / scale).clamp(0.0, 1.0).sqrt();
                    let px = (GAP + ci * (w * ZOOM + GAP) + x) as u32;
                    let py = (GAP + ri * (h * ZOOM + GAP) + y) as u32;
                    img.put_pixel(px, py, image::Luma([(v * 255.0).round() as u8]));
                }
            }
        }
    }
    img.save(path).map_err(|e| e.to_string())
}

fn write_csv(path: &Path, rows: &[LightRow]) -> Result<(), String> {
    let mut s = String::from(
        "transport,sample_distance,depth_r,plane_r,plane_index,rel_l1,gpu_max,exact_max,power_inside_ratio,total_power_ratio,angular_gpu,angular_exact,ms_per_plane,beams_per_texel\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "\"{}\",{},{},{:.6},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.4},{:.4}",
            r.variant,
            r.sample_distance,
            r.depth_r,
            r.plane_r,
            r.plane_index,
            r.rel_l1,
            r.gpu_max,
            r.exact_max,
            r.power_inside_ratio,
            r.total_power_ratio,
            r.angular_gpu,
            r.angular_exact,
            r.ms_per_plane,
            r.beams_per_texel
        );
    }
    std::fs::write(path, s).map_err(|e| e.to_string())
}

/// One run of the exact trace against a finer one.
#[derive(Clone, Debug)]
pub struct ConvergenceRow {
    pub rays_per_texel: u32,
    pub step_voxels: f64,
    pub seconds: f64,
    /// Relative L1 over [−1.5 R, 1.5 R]² at each of the plan's depths.
    pub rel_l1: Vec<f64>,
}

/// The exact trace's own convergence on the plan's ball and planes (exactly at the wanted
/// depths): each (rays per texel edge, RK4 step) of `runs` against a run at `truth`. Writes a
/// Markdown table to `path`; needs no GPU.
pub fn convergence(
    plan: &LightPlan,
    runs: &[(u32, f64)],
    truth: (u32, f64),
    path: &Path,
) -> Result<Vec<ConvergenceRow>, BenchError> {
    check(plan)?;
    let (volume, tf, centre_z) = ball_lens(plan.radius)?;
    let scene = ball_scene(&volume, &tf, plan.radius);
    let (_, centre) = centre_depth(&scene, &volume, centre_z, plan.size)?;
    let zs: Vec<f64> = plan.depths.iter().map(|d| centre + d * plan.radius).collect();
    let prepared = PreparedScene::from_parts(scene, volume, tf)?;
    let trace = |(rays, step): (u32, f64)| -> Result<(Vec<ScalarImage>, f64), BenchError> {
        let settings = PlaneSettings {
            rays_per_texel: rays,
            step_voxels: step,
            ..plan.reference.clone()
        };
        let started = Instant::now();
        let l = plane_light::trace_scene(&prepared, plan.size, plan.size, &zs, &settings)?;
        let images = l.planes.iter().map(|p| p.channel(1)).collect();
        Ok((images, started.elapsed().as_secs_f64()))
    };
    let (best, best_seconds) = trace(truth)?;
    let texel = 4.0 * plan.radius / plan.size as f64;
    let region = Region::square(
        &best[0],
        DVec2::splat((plan.size as f64 - 1.0) / 2.0),
        1.5 * plan.radius / texel,
    );
    let mut rows = Vec::new();
    for &run in runs {
        let (images, seconds) = trace(run)?;
        rows.push(ConvergenceRow {
            rays_per_texel: run.0,
            step_voxels: run.1,
            seconds,
            rel_l1: images
                .iter()
                .zip(&best)
                .map(|(a, b)| measure::relative_l1(a, b, region).unwrap_or(f64::NAN))
                .collect(),
        });
    }
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Exact plane trace against itself: glass ball n = {BALL_ETA}, R = {} voxels, {}² texels of {texel} voxel; \
         relative L1 over [−1.5 R, 1.5 R]² against {}² rays per texel and {}-voxel steps ({best_seconds:.0} s).\n",
        plan.radius, plan.size, truth.0, truth.1
    );
    s.push_str("| rays per texel | RK4 step (voxels) | time (s) |");
    for d in &plan.depths {
        let _ = write!(s, " {d} R |");
    }
    s.push_str("\n|---|---|---|");
    s.push_str(&"---|".repeat(plan.depths.len()));
    s.push('\n');
    for r in &rows {
        let _ = write!(s, "| {}² | {} | {:.1} |", r.rays_per_texel, r.step_voxels, r.seconds);
        for e in &r.rel_l1 {
            let _ = write!(s, " {e:.4} |");
        }
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|e| write_err(path)(e.to_string()))?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::LightPlan;

    #[test]
    fn the_picture_stays_at_the_default_sample_distance_when_the_plan_sweeps_coarser_ones() {
        let full = LightPlan::full(Vec::new());
        // The full plan measures Δs 2 first, but its picture and the voxelised ball's trace
        // are those of the default Δs 1.
        assert_eq!(full.sample_distances.first(), Some(&2.0));
        assert_eq!(full.picture_distance(), 1.0);
        // A plan without Δs 1 shows its first.
        let only = LightPlan {
            sample_distances: vec![0.5, 0.25],
            ..LightPlan::quick(Vec::new())
        };
        assert_eq!(only.picture_distance(), 0.5);
    }
}
