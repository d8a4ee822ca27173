//! The reference image: photon pass, then view rays integrated with RK4 in small steps,
//! reading the fluence grid and compositing with the Oddy–Willis model (paper Eq. 14), with
//! Cook–Torrance highlights where the rays cross an index interface, then the environment in
//! the final ray direction (Section 4.4).

use std::io::IsTerminal;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::medium::{Medium, SceneOptics, VolumeMedium};
use super::photons::{self, DistantLight, LightGrid, PhotonSettings};
use super::rk4::{self, Ray};
use super::shading::{
    cook_torrance, fresnel_dielectric, interface_sides, FRESNEL_MIN_RELATIVE_STEP, INTERFACE_SEARCH_VOXELS,
};
use crate::scene::{light_direction, EnvMap, PreparedScene, RenderedImage, ViewSetup};
use crate::scene::{Environment, Projection};

#[derive(Debug, thiserror::Error)]
pub enum ReferenceError {
    #[error("cannot render this view: {0}")]
    Setup(String),
}

impl crate::Classify for ReferenceError {
    fn exit_class(&self) -> crate::ExitClass {
        crate::ExitClass::Input // a scene the reference cannot render
    }
}

/// Accuracy knobs of the reference.
#[derive(Clone, Debug)]
pub struct ReferenceSettings {
    pub photons: PhotonSettings,
    /// RK4 step of the view rays, in voxels.
    pub view_step_voxels: f64,
    /// Sub-pixel rays per axis (n² per pixel, on a regular grid).
    pub samples_per_axis: u32,
    /// View rays stop once (1 − A)·max(M) falls below this.
    pub cutoff: f64,
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        ReferenceSettings {
            photons: PhotonSettings::default(),
            view_step_voxels: 0.25,
            samples_per_axis: 1,
            cutoff: 1e-4,
        }
    }
}

/// What lies behind the volume.
enum Background<'a> {
    Color([f64; 3]),
    Map(&'a EnvMap),
}

impl Background<'_> {
    /// Equirectangular lookup (y up) of level 0 with bilinear filtering, u wrapping.
    fn radiance(&self, d: DVec3) -> [f64; 3] {
        let map = match self {
            Background::Color(c) => return *c,
            Background::Map(m) => m,
        };
        let (w, h, px) = &map.levels[0];
        let (w, h) = (*w as usize, *h as usize);
        let d = d.normalize();
        let u = d.x.atan2(-d.z) / std::f64::consts::TAU + 0.5;
        let v = d.y.clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
        let x = u * w as f64 - 0.5;
        let y = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let xi = |x: f64| (x as i64).rem_euclid(w as i64) as usize;
        let yi = |y: f64| (y as usize).min(h - 1);
        let at = |x: f64, y: f64| px[yi(y) * w + xi(x)];
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let a = at(x0, y0)[c] as f64 * (1.0 - fx) + at(x0 + 1.0, y0)[c] as f64 * fx;
            let b = at(x0, y0 + 1.0)[c] as f64 * (1.0 - fx) + at(x0 + 1.0, y0 + 1.0)[c] as f64 * fx;
            *o = (a * (1.0 - fy) + b * fy) * map.intensity as f64;
        }
        out
    }
}

pub(super) fn dvec(v: Vec3) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

/// The world-space rays of a scene's camera through points of the image.
pub(super) struct CameraRays {
    world_from_view: glam::Mat4,
    rotation: glam::Mat3,
    eye: DVec3,
    projection: [f64; 4],
    orthographic: bool,
}

impl CameraRays {
    pub(super) fn new(scene: &crate::scene::Scene, view: &ViewSetup) -> CameraRays {
        CameraRays {
            world_from_view: view.world_from_view,
            rotation: glam::Mat3::from_mat4(view.world_from_view),
            eye: dvec(view.world_from_view.w_axis.truncate()),
            projection: view.projection.map(|v| v as f64),
            orthographic: scene.camera.projection == Projection::Orthographic,
        }
    }

    /// Origin and unit direction of the ray through image point (tx, ty) (pixel units; the
    /// centre of pixel (x, y) is at (x + ½, y + ½)).
    pub(super) fn ray(&self, tx: f64, ty: f64) -> (DVec3, DVec3) {
        let [fx, fy, cx, cy] = self.projection;
        let ndc = DVec3::new((tx - cx) / fx, (ty - cy) / fy, 1.0);
        if self.orthographic {
            let o = self
                .world_from_view
                .transform_point3(Vec3::new(ndc.x as f32, ndc.y as f32, 0.0));
            (dvec(o), dvec(self.rotation * Vec3::Z))
        } else {
            (
                self.eye,
                dvec(self.rotation * Vec3::new(ndc.x as f32, ndc.y as f32, 1.0)).normalize(),
            )
        }
    }
}

/// The specular term of a scene that has one.
struct Highlights {
    /// `shading.specular`: the scale of the Cook–Torrance term.
    scale: f64,
    roughness: f64,
    /// Propagation direction of the unrefracted light (world), where no photon arrived.
    source: DVec3,
}

/// Half-width (voxels) of the central differences that give a highlight's normal: over a
/// voxel, as the GPU's gradient volume. Narrower differences follow the trilinear field's
/// facets (its gradient turns at every voxel face), which widen a highlight's lobe: at a
/// quarter voxel a coated glass sphere's highlight read 1.2–1.4 times the exact one's energy,
/// at one voxel within 2.2 %.
const NORMAL_HALF_WIDTH_VOXELS: f64 = 1.0;

/// Gradients of the data value shorter than this (per world unit, relative to 1/voxel) give
/// no surface normal, so no highlight (as the GPU's MIN_GRADIENT_LENGTH).
const MIN_GRADIENT_PER_VOXEL: f64 = 1e-6;

/// Renders `prepared` at `width`×`height` (linear RGBA, alpha 1): every feature the GPU
/// renders, including highlights (counted once per interface crossed, see [`highlight`]), clip
/// planes and a separate η volume.
pub fn render(
    prepared: &PreparedScene,
    width: u32,
    height: u32,
    settings: &ReferenceSettings,
    progress: bool,
) -> Result<RenderedImage, ReferenceError> {
    let scene = &prepared.scene;
    let vol = &prepared.volume;
    let medium = VolumeMedium::for_scene(prepared);
    let view = ViewSetup::new(scene, vol.dims, vol.spacing, width, height).map_err(ReferenceError::Setup)?;
    let rotation = glam::Mat3::from_mat4(view.world_from_view);
    let l = &scene.light;
    let light = DistantLight {
        direction: dvec(rotation * light_direction(l)),
        color: l.color.map(|c| (c * l.intensity) as f64),
        softness: l.softness as f64,
    };
    let bar = progress_bar(progress);
    if let Some(b) = &bar {
        b.set_message("photons");
    }
    let grid = photons::trace(&medium, &light, &settings.photons, bar.as_ref());
    let highlights = SceneOptics::of(scene, &prepared.tf).specular.then_some(Highlights {
        scale: scene.shading.specular as f64,
        roughness: scene.shading.roughness as f64,
        source: light.direction,
    });
    let background = match (&scene.environment, &prepared.env) {
        (Environment::Color { color }, _) => Background::Color(color.map(|c| c as f64)),
        (_, Some(map)) => Background::Map(map),
        (_, None) => Background::Color([0.0; 3]),
    };
    if let Some(b) = &bar {
        b.set_message("view rays");
        b.set_position(0);
        b.set_length(height as u64);
    }
    let camera = CameraRays::new(scene, &view);
    let n = settings.samples_per_axis.max(1);
    let h = settings.view_step_voxels * medium.voxel_length();
    let rows: Vec<Vec<[f32; 4]>> = (0..height)
        .into_par_iter()
        .map(|py| {
            let row = (0..width)
                .map(|px| {
                    let mut sum = [0.0; 3];
                    for sy in 0..n {
                        for sx in 0..n {
                            let tx = px as f64 + (sx as f64 + 0.5) / n as f64;
                            let ty = py as f64 + (sy as f64 + 0.5) / n as f64;
                            let (o, d) = camera.ray(tx, ty);
                            let c = view_ray(
                                &medium,
                                &grid,
                                highlights.as_ref(),
                                &background,
                                o,
                                d,
                                h,
                                settings.cutoff,
                            );
                            for k in 0..3 {
                                sum[k] += c[k];
                            }
                        }
                    }
                    let s = (n * n) as f64;
                    [(sum[0] / s) as f32, (sum[1] / s) as f32, (sum[2] / s) as f32, 1.0]
                })
                .collect();
            if let Some(b) = &bar {
                b.inc(1);
            }
            row
        })
        .collect();
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    Ok(RenderedImage {
        width,
        height,
        pixels: rows.into_iter().flatten().collect(),
    })
}

fn progress_bar(show: bool) -> Option<indicatif::ProgressBar> {
    if !show || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(1);
    if let Ok(style) = indicatif::ProgressStyle::with_template("reference {msg} {pos}/{len} {wide_bar} {eta}") {
        bar.set_style(style);
    }
    Some(bar)
}

/// One view ray: Oddy–Willis compositing (Eq. 14) of the segments it crosses, with highlights
/// where it crosses an interface, then the background in its final direction.
#[allow(clippy::too_many_arguments)]
fn view_ray(
    medium: &VolumeMedium,
    grid: &LightGrid,
    highlights: Option<&Highlights>,
    background: &Background,
    o: DVec3,
    d: DVec3,
    h: f64,
    cutoff: f64,
) -> [f64; 3] {
    let (lo, hi) = medium.bounds();
    let Some((t0, t1)) = rk4::box_interval(o, d, lo, hi) else {
        return background.radiance(d);
    };
    let slack = DVec3::splat(1e-9 * (hi - lo).max_element());
    let inside = |x: DVec3| x.cmpge(lo - slack).all() && x.cmple(hi + slack).all();
    let mut ray = Ray::new(medium, o + d * t0, d);
    let (mut color, mut alpha, mut m) = ([0.0; 3], 0.0, [1.0; 3]);
    let mut budget = 8.0 * (t1 - t0) + 16.0 * h;
    while budget > 0.0 && inside(ray.x) && (1.0 - alpha) * m.iter().cloned().fold(0.0, f64::max) > cutoff {
        let dir = ray.direction();
        let uniform = medium.uniform_for(ray.x, dir);
        let (next, len) = match uniform {
            // A uniform block without extinction contributes nothing: cross it at once.
            Some(len) if medium.optics(ray.x) == Default::default() || len < h => {
                let len = len + 1e-6 * h;
                let empty = medium.optics(ray.x) == Default::default();
                let len = if empty { len } else { len.min(h) };
                (
                    Ray {
                        x: ray.x + dir * len,
                        v: ray.v,
                    },
                    len,
                )
            }
            Some(_) => (
                Ray {
                    x: ray.x + dir * h,
                    v: ray.v,
                },
                h,
            ),
            None => (rk4::step_on_shell(medium, ray, h), h),
        };
        // Four sub-segments per step for extinction and light, each split further (down to
        // 1/64 of a step) wherever it is more than 5% opaque, so that dense surfaces are
        // resolved where their opacity rises rather than wherever the step lattice falls.
        const SUB: usize = 4;
        for k in 0..SUB {
            let a = ray.x.lerp(next.x, k as f64 / SUB as f64);
            let b = ray.x.lerp(next.x, (k + 1) as f64 / SUB as f64);
            // Within a uniform block η does not change: no interface.
            if let (Some(hl), None) = (highlights, uniform) {
                let s = highlight(medium, grid, hl, a, b);
                for c in 0..3 {
                    color[c] += (1.0 - alpha) * m[c] * s[c];
                }
            }
            composite(medium, grid, a, b, len / SUB as f64, 4, &mut color, &mut alpha, &mut m);
        }
        ray = next;
        budget -= len;
    }
    let env = background.radiance(ray.v);
    [0, 1, 2].map(|c| color[c] + (1.0 - alpha) * m[c] * env[c])
}

/// The highlight reflected toward the viewer from the straight piece `a` → `b` of a view ray:
/// where η changes along the piece, the interface there (normal from the data's gradient,
/// η on its two sides from [`interface_sides`]) reflects Fresnel × Cook–Torrance × the light
/// arriving, weighted by the fraction of the interface's index step the piece crosses. A ray
/// crossing an interface thus counts it once, however finely it is stepped.
fn highlight(medium: &VolumeMedium, grid: &LightGrid, hl: &Highlights, a: DVec3, b: DVec3) -> [f64; 3] {
    let none = [0.0; 3];
    let crossed = (medium.eta(b) - medium.eta(a)).abs();
    if crossed == 0.0 {
        return none;
    }
    let p = a.lerp(b, 0.5);
    let g = medium.value_gradient(p, NORMAL_HALF_WIDTH_VOXELS);
    if g.length() * medium.voxel_length() <= MIN_GRADIENT_PER_VOXEL {
        return none;
    }
    let v = (a - b).normalize();
    let mut n = -g.normalize();
    if n.dot(v) < 0.0 {
        n = -n;
    }
    let (eta_view, eta_far) = interface_sides(medium, p, n);
    let step = (eta_far - eta_view).abs();
    if step <= FRESNEL_MIN_RELATIVE_STEP * eta_view.max(eta_far) {
        return none;
    }
    let weight = (crossed / step).min(1.0);
    // The view ray and the light as they travel in front of the interface: the piece may lie
    // inside the index ramp, where the ray has bent part way and the photons there mix light
    // already refracted by it. The ray's direction is carried back across the interface by
    // Snell's law (its component along the interface kept); the light's is the photons' mean
    // beyond the ramp on the viewer's side.
    let v = -in_medium((b - a).normalize() * medium.eta(p), n, eta_view);
    let front = p + n * (INTERFACE_SEARCH_VOXELS * medium.voxel_length());
    let l = -grid.direction(front).unwrap_or(hl.source);
    let f = fresnel_dielectric(n.dot(v), eta_view, eta_far);
    let s = hl.scale * f * cook_torrance(n, l, v, hl.roughness) * weight;
    if s == 0.0 {
        return none;
    }
    let light = grid.sample(p);
    [0, 1, 2].map(|c| s * light[c])
}

/// The unit direction that `w` = η·d (η where it was taken) has in the index `eta` across an
/// interface with unit normal `n`: the component along the interface kept (Snell), the normal
/// one the rest of |w| = eta, on the same side (only the tangential part under total internal
/// reflection).
fn in_medium(w: DVec3, n: DVec3, eta: f64) -> DVec3 {
    let wn = w.dot(n);
    let t = w - wn * n;
    let normal = (eta * eta - t.length_squared()).max(0.0).sqrt();
    (t + if wn < 0.0 { -normal } else { normal } * n).normalize_or_zero()
}

/// Oddy–Willis compositing (Eq. 14) of the straight piece from `a` to `b` (length `len`),
/// sampled at its midpoint, or of its two halves while it is more than 5% opaque and `splits`
/// remain.
#[allow(clippy::too_many_arguments)]
fn composite<M: Medium + ?Sized>(
    medium: &M,
    grid: &LightGrid,
    a: DVec3,
    b: DVec3,
    len: f64,
    splits: u32,
    color: &mut [f64; 3],
    alpha: &mut f64,
    m: &mut [f64; 3],
) {
    let p = a.lerp(b, 0.5);
    let opt = medium.optics(p);
    if opt == Default::default() {
        return;
    }
    let piece_alpha = 1.0 - (-opt.tau_alpha * len).exp();
    if piece_alpha > 0.05 && splits > 0 {
        composite(medium, grid, a, p, 0.5 * len, splits - 1, color, alpha, m);
        composite(medium, grid, p, b, 0.5 * len, splits - 1, color, alpha, m);
        return;
    }
    let light = if piece_alpha > 0.0 { grid.sample(p) } else { [0.0; 3] };
    let t = 1.0 - *alpha;
    for c in 0..3 {
        color[c] += t * m[c] * piece_alpha * opt.color[c] * light[c];
        m[c] *= (-opt.tau_medium[c] * len).exp();
    }
    *alpha += t * piece_alpha;
}
