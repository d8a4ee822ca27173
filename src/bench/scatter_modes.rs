//! `caustica bench --scatter`, the renderer's part: the narrow-beam slab ([`super::slab`])
//! rendered with each multiple-scattering mode (none, spread, lbm) at a few quality settings,
//! its light on sweep planes against the Monte Carlo pencil beam: width, radial profile, and
//! GPU time per render (the `--timings` GPU timestamps).

use std::fmt::Write as _;
use std::io::IsTerminal;
use std::sync::Arc;

use glam::Vec2;

use crate::gpu::Context;
use crate::reference::measure::ScalarImage;
use crate::reference::scatter::{first_crossings_by_order, plane_flux_rings, CrossingOrder, PlaneFlux};
use crate::render::lbm::LbmStats;
use crate::render::{DebugView, RenderRequest, Renderer};
use crate::scene::{MultipleScattering, Quality};

use super::slab::{self, SlabPlane, SlabSetup, ENTRY, HOLE, MASK_END, N};
use super::BenchError;

/// One mode at one quality setting.
#[derive(Clone, Debug, PartialEq)]
pub struct ModeVariant {
    pub label: String,
    pub mode: MultipleScattering,
    pub sample_distance: f32,
    /// The lattice's cell edge in voxels (lbm only).
    pub cell_voxels: u32,
}

impl ModeVariant {
    pub fn new(mode: MultipleScattering, sample_distance: f32, cell_voxels: u32) -> ModeVariant {
        let label = match mode {
            MultipleScattering::Lbm => format!("lbm, cells of {cell_voxels} voxels"),
            _ => format!("{}, Δs {sample_distance}", mode.name()),
        };
        ModeVariant {
            label,
            mode,
            sample_distance,
            cell_voxels,
        }
    }

    /// none; spread at plane distance 1 and 0.5; lbm with cells of 4 and 2 voxels.
    pub fn standard() -> Vec<ModeVariant> {
        use MultipleScattering::*;
        vec![
            ModeVariant::new(None, 1.0, 2),
            ModeVariant::new(Spread, 1.0, 2),
            ModeVariant::new(Spread, 0.5, 2),
            ModeVariant::new(Lbm, 1.0, 4),
            ModeVariant::new(Lbm, 1.0, 2),
        ]
    }

    fn quality(&self) -> Quality {
        let mut q = Quality {
            multiple_scattering: self.mode,
            sample_distance: self.sample_distance,
            ..Quality::default()
        };
        q.lbm.cell_voxels = self.cell_voxels;
        q
    }
}

/// What the GPU part runs.
#[derive(Clone, Debug)]
pub struct ModesPlan {
    /// Scattering coefficients b per voxel.
    pub scattering: Vec<f32>,
    pub absorption: f32,
    pub g: f32,
    /// Voxel depths of the planes; the first, just behind the mask, is the baseline whose
    /// spread (the hole's) is subtracted.
    pub depths: Vec<f32>,
    /// Radius of the window the light is measured in, voxels, and rings of its profile.
    pub max_r: f32,
    pub rings: usize,
    /// Monte Carlo photons per b.
    pub photons: u64,
    pub variants: Vec<ModeVariant>,
    /// Timed renders per variant and b (median).
    pub frames: u32,
}

impl ModesPlan {
    /// b = 0.05, 0.1, 0.2 per voxel, 10⁵ photons, 3 timed frames.
    pub fn full() -> ModesPlan {
        ModesPlan {
            scattering: vec![0.05, 0.1, 0.2],
            absorption: 0.002,
            g: 0.9,
            depths: vec![MASK_END + 1.0, 20.0, 36.0, 52.0],
            max_r: 30.0,
            rings: 15,
            photons: 100_000,
            variants: ModeVariant::standard(),
            frames: 3,
        }
    }

    /// b = 0.05 and 0.2, 2·10⁴ photons, one timed frame: minutes on a CPU driver.
    pub fn quick() -> ModesPlan {
        ModesPlan {
            scattering: vec![0.05, 0.2],
            photons: 20_000,
            frames: 1,
            ..ModesPlan::full()
        }
    }
}

/// One variant's light at one plane against the Monte Carlo light.
#[derive(Clone, Debug)]
pub struct ModeRow {
    pub variant: ModeVariant,
    pub b: f32,
    /// Depth S behind the entry of the plane measured, voxels.
    pub depth: f64,
    /// √ of the change of mean r² since the first plane, within the window (voxels).
    pub width: f64,
    pub mc_width: f64,
    /// Standard error of `mc_width`.
    pub mc_width_error: f64,
    /// √⟨r²⟩ of the light within the window at this depth (voxels): the hole's spread and the
    /// medium's together (the Monte Carlo beam has the hole's radius too).
    pub rms_radius: f64,
    pub mc_rms_radius: f64,
    /// Σ|GPU − MC| / Σ MC over the rings, each profile divided by its power in the window:
    /// the shape of the light, whatever its power.
    pub profile_l1: f64,
    /// Power in the window relative to the first plane's, GPU over Monte Carlo.
    pub power_ratio: f64,
    /// GPU time of one render of the image (median over the frames), and for lbm the
    /// lattice's share of it, its steps and its memory.
    pub gpu_ms: f64,
    pub lbm: Option<LbmSummary>,
}

#[derive(Clone, Copy, Debug)]
pub struct LbmSummary {
    pub gpu_ms: f64,
    pub iterations: u32,
    pub converged: bool,
    pub bytes: u64,
}

/// The Monte Carlo light of one b on the planes.
struct McLight {
    flux: Vec<PlaneFlux>,
    rings: Vec<Vec<f64>>,
}

/// The light on a plane: from the light view, plus for lbm the lattice's scattered fluence
/// there (which the light view does not hold: the view sweep reads it from the grid).
fn plane_light(
    renderer: &mut Renderer,
    s: &SlabSetup,
    plane: &SlabPlane,
    lattice: Option<&LbmStats>,
) -> Result<ScalarImage, BenchError> {
    let mut req = RenderRequest::new(N as u32, N as u32);
    req.debug_view = DebugView::Light;
    req.debug_depth = plane.depth;
    let frame = renderer.render(&s.prepared, &req)?;
    let mut img = ScalarImage::from_image(&frame.image, 1);
    if let Some(l) = lattice {
        for y in 0..img.height {
            for x in 0..img.width {
                let p = s.view.point_at(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), plane.view_z);
                let v = s.voxel_of(p);
                img.data[y * img.width + x] += fluence_at(l, v.to_array());
            }
        }
    }
    Ok(img)
}

/// The lattice's scattered fluence at voxel coordinates `v`: trilinear between cell centres,
/// clamped at the grid's faces (as `lbm_in_scattering` in shaders/lbm_view.wgsl).
fn fluence_at(l: &LbmStats, v: [f32; 3]) -> f64 {
    let d = l.grid.map(|n| n as i64);
    let cell = |c: [i64; 3]| {
        let k = [0, 1, 2].map(|a| c[a].clamp(0, d[a] - 1));
        l.fluence[((k[2] * d[1] + k[1]) * d[0] + k[0]) as usize] as f64
    };
    let g = v.map(|x| (x / l.cell_voxels as f32 - 0.5) as f64);
    let c = g.map(|x| x.floor() as i64);
    let t = [0, 1, 2].map(|a| g[a] - g[a].floor());
    let mut sum = 0.0;
    for corner in 0..8 {
        let o = [corner & 1, (corner >> 1) & 1, corner >> 2];
        let w: f64 = (0..3).map(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] }).product();
        sum += w * cell([c[0] + o[0] as i64, c[1] + o[1] as i64, c[2] + o[2] as i64]);
    }
    sum
}

/// Runs the variants of `plan` on `ctx`'s device.
pub fn run(ctx: Arc<Context>, plan: &ModesPlan, progress: bool) -> Result<Vec<ModeRow>, BenchError> {
    if plan.depths.len() < 2 || plan.variants.is_empty() || plan.scattering.is_empty() || plan.frames == 0 {
        return Err(BenchError::Plan(
            "the scattering bench needs two depths, a variant, a b and a frame".into(),
        ));
    }
    let mut renderer = Renderer::new(ctx)?;
    let volume = slab::slab_volume(Some(HOLE))?;
    let total = (plan.scattering.len() * (plan.variants.len() + 1)) as u64;
    let bar = (progress && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(total);
        if let Ok(style) = indicatif::ProgressStyle::with_template("scatter {pos}/{len} {wide_bar} {eta} {msg}") {
            bar.set_style(style);
        }
        bar
    });
    let step = |msg: String| {
        if let Some(b) = &bar {
            b.set_message(msg);
            b.inc(1);
        }
    };
    let mut rows = Vec::new();
    for &b in &plan.scattering {
        let tf = slab::medium_tf(plan.absorption, b, plan.g);
        let mut mc: Option<McLight> = None;
        for variant in &plan.variants {
            let s = SlabSetup::new(volume.clone(), tf.clone(), variant.quality())?;
            let planes: Vec<SlabPlane> = plan.depths.iter().map(|&z| s.plane_near(z)).collect();
            let mc = match &mut mc {
                Some(m) => &*m,
                // The Monte Carlo light once per b, on the first variant's planes (all the
                // variants' planes are within half a plane distance of the wanted depths).
                None => {
                    let depths: Vec<f64> = planes.iter().map(|p| (p.voxel_z - ENTRY) as f64).collect();
                    let (flux, rings) = plane_flux_rings(
                        &slab::reference_slab(plan.absorption, b, plan.g),
                        &depths,
                        plan.max_r as f64,
                        plan.rings,
                        HOLE as f64,
                        plan.photons,
                        16,
                    );
                    step(format!("b {b}: Monte Carlo"));
                    &*mc.insert(McLight { flux, rings })
                }
            };
            // Timed: the image (what a user waits for), the lattice solved in each.
            let mut times = Vec::new();
            let mut lattice = None;
            for _ in 0..plan.frames {
                let frame = renderer.render(&s.prepared, &RenderRequest::new(N as u32, N as u32))?;
                times.push(frame.stats.gpu_ms);
                lattice = frame.stats.lbm;
            }
            let gpu_ms = super::median(&mut times);
            let (axis, vpp) = s.axis_pixel();
            let mut measured = Vec::new();
            for plane in &planes {
                let img = plane_light(&mut renderer, &s, plane, lattice.as_deref())?;
                measured.push((
                    slab::light_moments(&img, axis, vpp, plan.max_r),
                    slab::ring_profile(&img, axis, vpp, plan.max_r, plan.rings),
                ));
            }
            let first = &measured[0];
            let shape = |p: &[f64]| {
                let total: f64 = p.iter().sum();
                p.iter().map(|x| x / total).collect::<Vec<f64>>()
            };
            for (k, ((power, r2), profile)) in measured.iter().enumerate().skip(1) {
                let m = &mc.flux[k];
                let mc_d = m.mean_r2 - mc.flux[0].mean_r2;
                let mc_width = mc_d.max(0.0).sqrt();
                rows.push(ModeRow {
                    variant: variant.clone(),
                    b,
                    depth: m.depth,
                    width: (r2 - first.0 .1).max(0.0).sqrt(),
                    mc_width,
                    mc_width_error: (m.mean_r2_error.hypot(mc.flux[0].mean_r2_error)) / (2.0 * mc_width.max(1e-9)),
                    rms_radius: r2.sqrt(),
                    mc_rms_radius: m.mean_r2.sqrt(),
                    profile_l1: slab::relative_l1(&shape(profile), &shape(&mc.rings[k])),
                    power_ratio: (power / first.0 .0) / (m.flux / mc.flux[0].flux),
                    gpu_ms,
                    lbm: lattice.as_deref().map(|l| LbmSummary {
                        gpu_ms: l.gpu_ms,
                        iterations: l.iterations,
                        converged: l.converged,
                        bytes: l.bytes,
                    }),
                });
            }
            step(format!("b {b}: {}", variant.label));
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    Ok(rows)
}

/// Per variant: mean and worst |width / Monte Carlo − 1|, mean profile L1, mean GPU ms.
pub struct Summary<'a> {
    pub variant: &'a ModeVariant,
    pub width_error: f64,
    pub worst_width_error: f64,
    /// Mean |rms radius / Monte Carlo − 1|.
    pub rms_error: f64,
    pub profile_l1: f64,
    pub gpu_ms: f64,
}

pub fn summarise<'a>(rows: &'a [ModeRow], variants: &'a [ModeVariant]) -> Vec<Summary<'a>> {
    variants
        .iter()
        .map(|v| {
            let mine: Vec<&ModeRow> = rows.iter().filter(|r| &r.variant == v).collect();
            let n = mine.len().max(1) as f64;
            let err = |r: &&ModeRow| (r.width / r.mc_width - 1.0).abs();
            Summary {
                variant: v,
                width_error: mine.iter().map(err).sum::<f64>() / n,
                worst_width_error: mine.iter().map(err).fold(0.0, f64::max),
                rms_error: mine
                    .iter()
                    .map(|r| (r.rms_radius / r.mc_rms_radius - 1.0).abs())
                    .sum::<f64>()
                    / n,
                profile_l1: mine.iter().map(|r| r.profile_l1).sum::<f64>() / n,
                gpu_ms: mine.iter().map(|r| r.gpu_ms).sum::<f64>() / n,
            }
        })
        .collect()
}

/// The Markdown section: widths and profile errors per b and depth, then error against time.
pub fn markdown(rows: &[ModeRow], plan: &ModesPlan, device: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(
        md,
        "\n# The renderer's modes against the Monte Carlo light\n\n\
         A collimated beam through a hole of radius {HOLE} voxels in an opaque mask enters a slab \
         (a = {} per voxel, g = {}) head-on; {N}³ voxels, {N}² light texels, device: {device}. On sweep \
         planes at depth S behind the entry (the nearest to the wanted depths), the width is √ of the \
         change of the light's mean r² since the plane {:.0} voxel behind the mask, within {} voxels of \
         the axis (the hole's own spread cancels; the tests' definition); the Monte Carlo reference \
         (`reference::scatter::plane_flux_rings`, {} photons per b, a beam of the hole's radius) measures the \
         net flux through the same planes. The profile error is Σ|GPU − MC| / Σ MC over {} rings of {:.0} \
         voxels, each profile divided by its power in the window (its shape); the power relative to the first \
         plane is compared alongside. lbm's light is the light view's (unscattered) plus the lattice's \
         scattered fluence at the plane. GPU ms: one render of the {N}² image (median of {}), the \
         lattice's solve included.\n",
        plan.absorption,
        plan.g,
        plan.depths[0] - MASK_END,
        plan.max_r,
        plan.photons,
        plan.rings,
        plan.max_r / plan.rings as f32,
        plan.frames
    );
    let header = |md: &mut String, title: &str| {
        let _ = write!(md, "\n{title}\n\n| b /voxel | S voxels | MC |");
        for v in &plan.variants {
            let _ = write!(md, " {} |", v.label);
        }
        let _ = write!(md, "\n|---|---|---|");
        for _ in &plan.variants {
            let _ = write!(md, "---|");
        }
        let _ = writeln!(md);
    };
    let keys: Vec<(f32, f64)> = {
        let mut k: Vec<(f32, f64)> = Vec::new();
        for r in rows {
            if !k.iter().any(|&(b, d)| b == r.b && (d - r.depth).abs() < 1e-9) {
                k.push((r.b, r.depth));
            }
        }
        k
    };
    // One row per (b, depth): the Monte Carlo's cell, then each variant's (empty where it has
    // no row there).
    let table = |md: &mut String, title: &str, mc: &dyn Fn(&ModeRow) -> String, cell: &dyn Fn(&ModeRow) -> String| {
        header(md, title);
        for &(b, d) in &keys {
            let at = |r: &&ModeRow| r.b == b && (r.depth - d).abs() < 1e-9;
            let first = rows.iter().find(at).expect("the keys come from the rows");
            let _ = write!(md, "| {b} | {d:.1} |{}|", mc(first));
            for v in &plan.variants {
                match rows.iter().filter(at).find(|r| &r.variant == v) {
                    Some(r) => {
                        let _ = write!(md, " {} |", cell(r));
                    }
                    None => md.push_str(" |"),
                }
            }
            let _ = writeln!(md);
        }
    };
    table(
        &mut md,
        "Width (voxels) and its ratio to the Monte Carlo's:",
        &|r| format!(" {:.2} ± {:.2} ", r.mc_width, r.mc_width_error),
        &|r| format!("{:.2} ({:.2})", r.width, r.width / r.mc_width),
    );
    table(
        &mut md,
        "RMS radius √⟨r²⟩ at S (voxels; no subtraction, both beams from the hole) and its ratio to the Monte Carlo's:",
        &|r| format!(" {:.2} ", r.mc_rms_radius),
        &|r| format!("{:.2} ({:.2})", r.rms_radius, r.rms_radius / r.mc_rms_radius),
    );
    table(
        &mut md,
        "Radial profile's shape, relative L1 against the Monte Carlo's (in parentheses: the power in the window relative to the first plane's, GPU / MC):",
        &|_| " ".to_string(),
        &|r| format!("{:.3} ({:.2})", r.profile_l1, r.power_ratio),
    );
    let _ = writeln!(
        md,
        "\nA width of 0 means the mean r² did not grow from the first plane: in lbm the lattice's glow \
         already fills the window there (see the RMS radius).\n\n\
         Error against time (means over the b and depths above; scatter.png plots the profile's L1 against \
         GPU ms):\n\n\
         | variant | mean \\|w / w_MC − 1\\| | worst | mean \\|rms / rms_MC − 1\\| | mean profile L1 | GPU ms per render | lattice |\n|---|---|---|---|---|---|---|"
    );
    for s in summarise(rows, &plan.variants) {
        let lattice = rows
            .iter()
            .filter(|r| &r.variant == s.variant)
            .filter_map(|r| r.lbm.map(|l| (r.b, l)))
            .fold(Vec::<String>::new(), |mut acc, (b, l)| {
                let text = format!(
                    "b {b}: {} steps{}, {:.1} ms, {} KiB",
                    l.iterations,
                    if l.converged { "" } else { " (not converged)" },
                    l.gpu_ms,
                    l.bytes / 1024
                );
                if !acc.contains(&text) {
                    acc.push(text);
                }
                acc
            });
        let _ = writeln!(
            md,
            "| {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} | {} |",
            s.variant.label,
            s.width_error,
            s.worst_width_error,
            s.rms_error,
            s.profile_l1,
            s.gpu_ms,
            lattice.join("; ")
        );
    }
    md
}

/// What carries the Monte Carlo light's mean r² on the shallowest measured plane (the second
/// depth of `plan`): the light that first crosses it (a pencil beam, forward crossings within
/// the window), by how often it scattered on its way (0, 1, 2, 3 or more), and how much of its
/// mean r² each order holds. Light that scattered several times has gone further than the
/// depth, which path-length moments do not follow.
pub fn crossing_orders(plan: &ModesPlan) -> String {
    let mut md = String::new();
    // Per b, the light on every measured plane by order, walked once: the first table splits
    // the shallowest plane's, the second sums the scattered orders of each.
    let depths: Vec<f64> = plan.depths.iter().skip(1).map(|&z| f64::from(z - ENTRY)).collect();
    let Some(&depth) = depths.first() else {
        return md;
    };
    let by_b: Vec<(f32, Vec<Vec<CrossingOrder>>)> = plan
        .scattering
        .iter()
        .map(|&b| {
            let slab = slab::reference_slab(plan.absorption, b, plan.g);
            let planes = depths
                .iter()
                .map(|&z| first_crossings_by_order(&slab, z, f64::from(plan.max_r), 4, plan.photons, 17))
                .collect();
            (b, planes)
        })
        .collect();
    let _ = writeln!(
        md,
        "\nWhat carries the Monte Carlo light's mean r² at {depth:.0} voxels (a pencil beam, {} photons per b, \
         each photon where it first crosses the plane within {} voxels of the axis, by its scatterings so far; \
         `reference::scatter::first_crossings_by_order`):\n\n\
         | b /voxel | order | share of that light | share of its mean r² | mean path so far (voxels) |\n|---|---|---|---|---|",
        plan.photons, plan.max_r
    );
    for (b, planes) in &by_b {
        let orders = &planes[0];
        let light: f64 = orders.iter().map(|o| o.share).sum();
        let r2: f64 = orders.iter().map(|o| o.r2).sum();
        for o in orders {
            let order = if o.scatterings + 1 == orders.len() {
                format!("{} or more", o.scatterings)
            } else {
                o.scatterings.to_string()
            };
            let _ = writeln!(
                md,
                "| {b} | {order} | {:.3} | {:.3} | {:.1} |",
                o.share / light.max(1e-300),
                o.r2 / r2.max(1e-300),
                o.path / o.share.max(1e-300)
            );
        }
    }
    let _ = writeln!(
        md,
        "\nHow much further than the depth the scattered light in the window has come (its mean path up to \
         the plane, less the depth; the same walks):\n\n| b /voxel | S voxels | excess path (voxels) | of the depth |\n|---|---|---|---|"
    );
    for (b, planes) in &by_b {
        for (orders, &depth) in planes.iter().zip(&depths) {
            let (share, path) = orders[1..]
                .iter()
                .fold((0.0, 0.0), |(s, p), o| (s + o.share, p + o.path));
            let excess = path / share.max(1e-300) - depth;
            let _ = writeln!(md, "| {b} | {depth:.0} | {excess:.2} | {:.3} |", excess / depth);
        }
    }
    md
}

/// Header of scatter.csv.
pub const CSV_HEADER: &str = "variant,mode,sample_distance,cell_voxels,b,depth_voxels,width_voxels,mc_width_voxels,mc_width_error,width_ratio,rms_radius_voxels,mc_rms_radius_voxels,profile_rel_l1,power_ratio,gpu_ms,lbm_gpu_ms,lbm_iterations,lbm_bytes";

pub fn csv(rows: &[ModeRow]) -> String {
    let mut out = format!("{CSV_HEADER}\n");
    for r in rows {
        let (lms, lit, lbytes) = r.lbm.map_or((String::new(), String::new(), String::new()), |l| {
            (
                format!("{:.3}", l.gpu_ms),
                l.iterations.to_string(),
                l.bytes.to_string(),
            )
        });
        let _ = writeln!(
            out,
            "{},{},{},{},{},{:.3},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.3},{lms},{lit},{lbytes}",
            r.variant.label.replace(',', ";"),
            r.variant.mode.name(),
            r.variant.sample_distance,
            r.variant.cell_voxels,
            r.b,
            r.depth,
            r.width,
            r.mc_width,
            r.mc_width_error,
            r.width / r.mc_width,
            r.rms_radius,
            r.mc_rms_radius,
            r.profile_l1,
            r.power_ratio,
            r.gpu_ms
        );
    }
    out
}
