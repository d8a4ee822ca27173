//! Exact light on the planes of a view: the irradiance (power crossing the plane per unit
//! plane area) of a distant light on planes of constant view depth, by tracing rays forward
//! through the continuous medium. This is what the GPU's light buffer holds at a plane
//! (`render --debug-view light --at-depth D`), measured independently.
//!
//! Rays start on a plane in front of everything (the volume's bounds and every requested
//! plane), on a regular lattice aligned with the texel axes of the nearest requested plane and
//! spaced `1 / rays_per_texel` of its texel. Seen along any one direction, that lattice lands
//! on every plane of constant depth as an axis-aligned lattice of the same spacing, so each ray
//! deposits its power over a box of one lattice cell (a partition of unity): unobstructed light
//! reads exactly 1 on every plane at any light angle, orthographic or perspective, with no
//! aliasing between the lattice and the texels. The lattice covers every ray that can reach
//! the frame of any requested plane or the medium's bounds (a guard band), so occluders and
//! lenses outside the view act on the light inside it.
//!
//! Inside the medium rays follow the ray equation by RK4 ([`super::rk4`]), losing power by
//! (1 − α)·m along the path as in [`super::photons`]; where a step crosses a plane the crossing
//! point is found on the step's cubic Hermite curve and the power is attenuated up to it.
//! Crossings against +z count negatively: the result is the net flux through the plane, which
//! a non-absorbing medium conserves exactly.

use glam::{DMat4, DVec2, DVec3};
use rayon::prelude::*;

use super::measure::ScalarImage;
use super::medium::{Medium, VolumeMedium};
use super::photons::{basis, DistantLight};
use super::rk4::{self, Ray};
use super::ReferenceError;
use crate::render::{light_direction, PreparedScene, ViewSetup};
use crate::scene::Projection;

/// The camera whose planes receive the light: view space has the camera at the origin, x
/// right, y down, z forward; a texel (u, v) of the plane at depth z is where the primary ray
/// of the pixel centre (u + ½, v + ½) meets it (as `unproject` in `shaders/common.wgsl`).
#[derive(Clone, Debug)]
pub struct PlaneView {
    /// Rigid transform from view to world space.
    pub world_from_view: DMat4,
    /// fx, fy, cx, cy in pixels: a pixel coordinate is f·x + c (orthographic) or f·x/z + c.
    pub projection: [f64; 4],
    pub orthographic: bool,
    pub width: u32,
    pub height: u32,
}

impl PlaneView {
    /// The view of a render: `ViewSetup` for the scene at `width`×`height`.
    pub fn from_setup(view: &ViewSetup, orthographic: bool, width: u32, height: u32) -> PlaneView {
        let m = view.world_from_view.to_cols_array().map(|v| v as f64);
        PlaneView {
            world_from_view: DMat4::from_cols_array(&m),
            projection: view.projection.map(|v| v as f64),
            orthographic,
            width,
            height,
        }
    }

    /// Continuous texel coordinates (texel centres at integers) of a view-space point.
    pub fn texel_of(&self, p: DVec3) -> DVec2 {
        let [fx, fy, cx, cy] = self.projection;
        let xy = if self.orthographic {
            p.truncate()
        } else {
            p.truncate() / p.z
        };
        DVec2::new(xy.x * fx + cx - 0.5, xy.y * fy + cy - 0.5)
    }

    /// The view-space point of plane depth `z` at continuous texel coordinates `t`.
    pub fn point_on_plane(&self, t: DVec2, z: f64) -> DVec3 {
        let [fx, fy, cx, cy] = self.projection;
        let ndc = DVec2::new((t.x + 0.5 - cx) / fx, (t.y + 0.5 - cy) / fy);
        let s = if self.orthographic { 1.0 } else { z };
        DVec3::new(ndc.x * s, ndc.y * s, z)
    }

    /// Edge lengths of a texel on the plane at depth `z`, in world units.
    pub fn texel_size(&self, z: f64) -> DVec2 {
        let s = if self.orthographic { 1.0 } else { z };
        DVec2::new(s / self.projection[0], s / self.projection[1])
    }

    /// The four corners of the frame (outer texel edges) on the plane at depth `z`.
    fn frame_corners(&self, z: f64) -> [DVec3; 4] {
        let (w, h) = (self.width as f64, self.height as f64);
        [(-0.5, -0.5), (w - 0.5, -0.5), (-0.5, h - 0.5), (w - 0.5, h - 0.5)]
            .map(|(u, v)| self.point_on_plane(DVec2::new(u, v), z))
    }
}

/// The plane of a GPU sweep nearest to view depth `z`: (plane index, the relative depth `D`
/// of `--at-depth D` that selects it, its exact depth as the GPU computes it in f32).
pub fn nearest_sweep_plane(view: &ViewSetup, z: f64) -> (u32, f32, f64) {
    let last = view.planes.saturating_sub(1);
    let k = ((z - view.z_first as f64) / view.step as f64)
        .round()
        .clamp(0.0, last as f64) as u32;
    let depth = if last == 0 { 0.0 } else { k as f32 / last as f32 };
    // As `plane_z` in shaders/common.wgsl: z_first + i·Δs in f32.
    let z_plane = view.z_first + k as f32 * view.step;
    (k, depth, z_plane as f64)
}

/// Accuracy knobs of the plane trace.
#[derive(Clone, Debug)]
pub struct PlaneSettings {
    /// Rays per texel edge on the nearest requested plane (its square per texel there). Each
    /// ray deposits over a box of its lattice cell, whose overlap with two texels is linear in
    /// its position: with one ray per texel edge (a box of one texel) first moments of the
    /// light, such as a beam's or a shadow's centroid, are exact on orthographic planes.
    pub rays_per_texel: u32,
    /// RK4 step, in voxels.
    pub step_voxels: f64,
    /// Soft light: a tile of `direction_tile`² neighbouring rays shares that many directions
    /// over the source's cone, one each, and every ray deposits over the tile's area. Larger
    /// tiles sample the cone more finely and blur by more (tile / rays_per_texel texels).
    pub direction_tile: u32,
}

impl Default for PlaneSettings {
    fn default() -> Self {
        PlaneSettings {
            rays_per_texel: 8,
            step_voxels: 0.25,
            direction_tile: 4,
        }
    }
}

/// The light on one plane.
#[derive(Clone, Debug)]
pub struct PlaneIrradiance {
    /// View depth of the plane.
    pub z: f64,
    pub width: u32,
    pub height: u32,
    /// Irradiance per texel (box filter), RGB, relative to what the unobstructed light gives
    /// on this plane: 1 in empty space at any light angle.
    pub texels: Vec<[f64; 3]>,
    /// Net power crossing the plane inside the frame, in units of the unobstructed irradiance
    /// × world area (so an unobstructed frame holds its own area).
    pub power_in_frame: [f64; 3],
    /// Net power crossing the whole plane (every traced ray), same units.
    pub power_crossing: [f64; 3],
    /// Power of the crossings against +z (already subtracted from the two above).
    pub power_backward: [f64; 3],
}

impl PlaneIrradiance {
    /// Channel `c` as a scalar image (for [`super::measure`]).
    pub fn channel(&self, c: usize) -> ScalarImage {
        ScalarImage {
            width: self.width as usize,
            height: self.height as usize,
            data: self.texels.iter().map(|t| t[c]).collect(),
        }
    }
}

/// The light on every requested plane, with the trace's power bookkeeping (same units as
/// [`PlaneIrradiance::power_in_frame`]).
#[derive(Clone, Debug)]
pub struct PlaneLight {
    pub planes: Vec<PlaneIrradiance>,
    /// Power of all rays launched.
    pub power_launched: f64,
    /// Power of the rays that met the medium's bounds.
    pub power_entering: f64,
    /// Power of rays stopped by the path budget inside the bounds (trapped; normally 0).
    pub power_lost: [f64; 3],
    /// Power of rays that left the bounds travelling toward the camera (−z): they never reach
    /// a plane behind the bounds, and cross those in front of it once more, backward.
    pub power_escaped_backward: [f64; 3],
    pub rays: u64,
}

/// More rays than this is a mistake in the settings, not a measurement.
pub const MAX_RAYS: u64 = 1 << 34;

/// Rays below this fraction of their starting power are dropped (counted as absorbed).
const POWER_CUTOFF: f64 = 1e-12;

/// Directions of a soft light: `count` points of a Fibonacci (golden-angle) spiral on the unit
/// disc, equal areas each, all at distinct distances along any axis, so that a soft shadow
/// edge is sampled at `count` offsets rather than a few repeated ones.
fn cone_directions(light: &DistantLight, d: DVec3, count: usize) -> Vec<DVec3> {
    if light.softness <= 0.0 || count <= 1 {
        return vec![d];
    }
    let (a1, a2) = basis(d);
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|j| {
            let r = ((j as f64 + 0.5) / count as f64).sqrt();
            let phi = j as f64 * golden;
            (d + (a1 * phi.cos() + a2 * phi.sin()) * (r * light.softness)).normalize()
        })
        .collect()
}

/// The per-thread sums.
struct Accumulator {
    texels: Vec<[f64; 3]>,
    in_frame: Vec<[f64; 3]>,
    crossing: Vec<[f64; 3]>,
    backward: Vec<[f64; 3]>,
    launched: f64,
    entering: f64,
    lost: [f64; 3],
    escaped_backward: [f64; 3],
    rays: u64,
}

impl Accumulator {
    fn new(planes: usize, texels: usize) -> Self {
        Accumulator {
            texels: vec![[0.0; 3]; planes * texels],
            in_frame: vec![[0.0; 3]; planes],
            crossing: vec![[0.0; 3]; planes],
            backward: vec![[0.0; 3]; planes],
            launched: 0.0,
            entering: 0.0,
            lost: [0.0; 3],
            escaped_backward: [0.0; 3],
            rays: 0,
        }
    }

    fn add(mut self, o: Accumulator) -> Self {
        let sum = |a: &mut [[f64; 3]], b: &[[f64; 3]]| {
            for (x, y) in a.iter_mut().zip(b) {
                for c in 0..3 {
                    x[c] += y[c];
                }
            }
        };
        sum(&mut self.texels, &o.texels);
        sum(&mut self.in_frame, &o.in_frame);
        sum(&mut self.crossing, &o.crossing);
        sum(&mut self.backward, &o.backward);
        sum(std::slice::from_mut(&mut self.lost), &[o.lost]);
        sum(std::slice::from_mut(&mut self.escaped_backward), &[o.escaped_backward]);
        self.launched += o.launched;
        self.entering += o.entering;
        self.rays += o.rays;
        self
    }
}

/// Everything a ray needs to know about the planes.
struct Planes<'a> {
    view: &'a PlaneView,
    view_from_world: DMat4,
    z: &'a [f64],
    /// Footprint of every ray (world units, the same on every plane).
    footprint: DVec2,
}

impl Planes<'_> {
    fn view_point(&self, p: DVec3) -> DVec3 {
        self.view_from_world.transform_point3(p)
    }

    fn view_vector(&self, v: DVec3) -> DVec3 {
        self.view_from_world.transform_vector3(v)
    }

    /// Adds `power` (negative for a crossing against +z) crossing plane `k` at view point `p`,
    /// spread over the ray's footprint box.
    fn deposit(&self, acc: &mut Accumulator, k: usize, p: DVec3, power: [f64; 3], sign: f64) {
        let signed = power.map(|v| v * sign);
        for c in 0..3 {
            acc.crossing[k][c] += signed[c];
            if sign < 0.0 {
                acc.backward[k][c] += power[c];
            }
        }
        let view = self.view;
        let t = view.texel_of(p);
        let size = view.texel_size(self.z[k]);
        let half = DVec2::new(self.footprint.x / size.x, self.footprint.y / size.y) * 0.5;
        let (w, h) = (view.width as i64, view.height as i64);
        // Texel i covers [i − ½, i + ½) in continuous coordinates.
        let range = |lo: f64, hi: f64, n: i64| {
            let first = (lo + 0.5).floor().max(0.0) as i64;
            let last = ((hi + 0.5).floor() as i64).min(n - 1);
            (first, last)
        };
        let (lo, hi) = (t - half, t + half);
        let (x0, x1) = range(lo.x, hi.x, w);
        let (y0, y1) = range(lo.y, hi.y, h);
        let plane = k * (w * h) as usize;
        for y in y0..=y1 {
            let fy = ((hi.y).min(y as f64 + 0.5) - (lo.y).max(y as f64 - 0.5)) / (2.0 * half.y);
            if fy <= 0.0 {
                continue;
            }
            for x in x0..=x1 {
                let fx = ((hi.x).min(x as f64 + 0.5) - (lo.x).max(x as f64 - 0.5)) / (2.0 * half.x);
                if fx <= 0.0 {
                    continue;
                }
                let i = plane + (y * w + x) as usize;
                for c in 0..3 {
                    let v = signed[c] * fx * fy;
                    acc.texels[i][c] += v;
                    acc.in_frame[k][c] += v;
                }
            }
        }
    }

    /// Crossings of the straight piece from `a` (power `power`) along unit `dir` for
    /// `length` (may be infinite), through optical depth `tau` per unit length.
    fn straight(&self, acc: &mut Accumulator, a: DVec3, dir: DVec3, length: f64, power: [f64; 3], tau: [f64; 3]) {
        let (pa, dv) = (self.view_point(a), self.view_vector(dir));
        if dv.z == 0.0 {
            return;
        }
        let zb = if length.is_finite() {
            pa.z + dv.z * length
        } else {
            f64::INFINITY * dv.z.signum()
        };
        for (k, &z) in self.z.iter().enumerate() {
            let sign = crossing_sign(pa.z, zb, z);
            if sign == 0.0 {
                continue;
            }
            let t = (z - pa.z) / dv.z;
            let mut p = pa + dv * t;
            p.z = z;
            let at = [0, 1, 2].map(|c| power[c] * (-tau[c] * t).exp());
            self.deposit(acc, k, p, at, sign);
        }
    }
}

/// +1 if the plane at `z` lies in (za, zb], −1 if in (zb, za], else 0: each crossing of a
/// chain of pieces counts once, and touching a plane without passing it counts zero.
fn crossing_sign(za: f64, zb: f64, z: f64) -> f64 {
    if za < z && z <= zb {
        1.0
    } else if zb < z && z <= za {
        -1.0
    } else {
        0.0
    }
}

/// Cubic Hermite position at σ ∈ [0, 1] from end points and end derivatives (per unit σ).
fn hermite(a: DVec3, ma: DVec3, b: DVec3, mb: DVec3, s: f64) -> DVec3 {
    let (s2, s3) = (s * s, s * s * s);
    a * (2.0 * s3 - 3.0 * s2 + 1.0) + ma * (s3 - 2.0 * s2 + s) + b * (-2.0 * s3 + 3.0 * s2) + mb * (s3 - s2)
}

fn hermite_dz(a: DVec3, ma: DVec3, b: DVec3, mb: DVec3, s: f64) -> f64 {
    let s2 = s * s;
    a.z * (6.0 * s2 - 6.0 * s)
        + ma.z * (3.0 * s2 - 4.0 * s + 1.0)
        + b.z * (-6.0 * s2 + 6.0 * s)
        + mb.z * (3.0 * s2 - 2.0 * s)
}

/// Optical depth per unit length of four quarters of the chord from `a` to `b`.
fn quarter_taus<M: Medium + ?Sized>(medium: &M, a: DVec3, b: DVec3) -> [[f64; 3]; 4] {
    [0, 1, 2, 3].map(|q| {
        let o = medium.optics(a.lerp(b, (q as f64 + 0.5) / 4.0));
        [0, 1, 2].map(|c| o.tau_alpha + o.tau_medium[c])
    })
}

/// Power after the fraction `s` of a step of length `h` through the quarters' depths.
fn attenuated(power: [f64; 3], taus: &[[f64; 3]; 4], h: f64, s: f64) -> [f64; 3] {
    let mut depth = [0.0; 3];
    for (q, tau) in taus.iter().enumerate() {
        let covered = (s * 4.0 - q as f64).clamp(0.0, 1.0) * 0.25 * h;
        for c in 0..3 {
            depth[c] += tau[c] * covered;
        }
    }
    [0, 1, 2].map(|c| power[c] * (-depth[c]).exp())
}

/// Follows one ray from `start` (world, outside the medium's bounds) along unit `dir`.
fn trace_ray<M: Medium + ?Sized>(
    medium: &M,
    planes: &Planes,
    acc: &mut Accumulator,
    start: DVec3,
    dir: DVec3,
    p0: f64,
    h: f64,
) {
    let zero = [0.0; 3];
    let mut power = [p0; 3];
    acc.launched += p0;
    acc.rays += 1;
    let (lo, hi) = medium.bounds();
    let Some((t0, t1)) = rk4::box_interval(start, dir, lo, hi) else {
        planes.straight(acc, start, dir, f64::INFINITY, power, zero);
        return;
    };
    acc.entering += p0;
    planes.straight(acc, start, dir, t0, power, zero);
    let slack = DVec3::splat(1e-9 * (hi - lo).max_element());
    let inside = |x: DVec3| x.cmpge(lo - slack).all() && x.cmple(hi + slack).all();
    let mut ray = Ray::new(medium, start + dir * t0, dir);
    // A ray cannot bend back forever; bound the work by a generous path length.
    let mut budget = 8.0 * (t1 - t0).max(h) + 16.0 * h;
    let cutoff = POWER_CUTOFF * p0;
    while budget > 0.0 && inside(ray.x) {
        if power.iter().all(|p| *p <= cutoff) {
            return; // absorbed
        }
        let d = ray.direction();
        if let Some(len) = medium.uniform_for(ray.x, d) {
            // Uniform block: straight, constant optics; step just past its exit.
            let len = len + 1e-6 * h;
            let o = medium.optics(ray.x);
            let tau = [0, 1, 2].map(|c| o.tau_alpha + o.tau_medium[c]);
            planes.straight(acc, ray.x, d, len, power, tau);
            power = [0, 1, 2].map(|c| power[c] * (-tau[c] * len).exp());
            ray.x += d * len;
            budget -= len;
            continue;
        }
        let next = rk4::step_on_shell(medium, ray, h);
        let taus = quarter_taus(medium, ray.x, next.x);
        let (a, b) = (planes.view_point(ray.x), planes.view_point(next.x));
        let ma = planes.view_vector(d) * h;
        let mb = planes.view_vector(next.direction()) * h;
        for (k, &z) in planes.z.iter().enumerate() {
            let sign = crossing_sign(a.z, b.z, z);
            if sign == 0.0 {
                continue;
            }
            // Newton on the Hermite curve's depth from the chord's crossing.
            let mut s = (z - a.z) / (b.z - a.z);
            for _ in 0..4 {
                let dz = hermite_dz(a, ma, b, mb, s);
                if dz.abs() < 1e-12 {
                    break;
                }
                s = (s - (hermite(a, ma, b, mb, s).z - z) / dz).clamp(0.0, 1.0);
            }
            let mut p = hermite(a, ma, b, mb, s);
            p.z = z;
            planes.deposit(acc, k, p, attenuated(power, &taus, h, s), sign);
        }
        power = attenuated(power, &taus, h, 1.0);
        ray = next;
        budget -= h;
    }
    if inside(ray.x) {
        for c in 0..3 {
            acc.lost[c] += power[c];
        }
    } else {
        let d = ray.direction();
        if planes.view_vector(d).z < 0.0 {
            for c in 0..3 {
                acc.escaped_backward[c] += power[c];
            }
        }
        planes.straight(acc, ray.x, d, f64::INFINITY, power, zero);
    }
}

/// Traces `light` (world direction; its colour is ignored: the result is relative) through
/// `medium` onto the planes of view depth `planes_z` of `view`.
pub fn trace<M: Medium + ?Sized>(
    medium: &M,
    light: &DistantLight,
    view: &PlaneView,
    planes_z: &[f64],
    settings: &PlaneSettings,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<PlaneLight, ReferenceError> {
    let setup = |m: String| Err(ReferenceError::Setup(m));
    if planes_z.is_empty() || view.width == 0 || view.height == 0 {
        return setup("the plane trace needs at least one plane and one texel".into());
    }
    if planes_z
        .iter()
        .any(|z| !z.is_finite() || (!view.orthographic && *z <= 0.0))
    {
        return setup(format!(
            "plane depths {planes_z:?} must be finite (and in front of a perspective camera)"
        ));
    }
    if settings.rays_per_texel == 0 || settings.step_voxels.is_nan() || settings.step_voxels <= 0.0 {
        return setup("rays_per_texel and step_voxels must be positive".into());
    }
    let view_from_world = view.world_from_view.inverse();
    let d = view_from_world.transform_vector3(light.direction).normalize();
    let tile = if light.softness > 0.0 {
        settings.direction_tile.max(1) as usize
    } else {
        1
    };
    let directions = cone_directions(light, d, tile * tile);
    // The cone's rim bounds where its rays can come from.
    let rim: Vec<DVec3> = (0..64)
        .map(|k| {
            let (a1, a2) = basis(d);
            let phi = k as f64 / 64.0 * std::f64::consts::TAU;
            (d + (a1 * phi.cos() + a2 * phi.sin()) * light.softness).normalize()
        })
        .chain(directions.iter().copied())
        .collect();
    let min_z = rim.iter().map(|v| v.z).fold(f64::INFINITY, f64::min);
    if min_z < 1e-3 {
        return setup("the light (with its softness cone) must travel away from the camera".into());
    }

    // Start plane: in front of the bounds and of every requested plane.
    let (lo, hi) = medium.bounds();
    let corners: Vec<DVec3> = (0..8)
        .map(|i| {
            let c = DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            view_from_world.transform_point3(c)
        })
        .collect();
    let voxel = medium.voxel_length();
    let z_near = planes_z.iter().copied().fold(f64::INFINITY, f64::min);
    let z_start = corners.iter().map(|c| c.z).fold(z_near, f64::min) - voxel;
    let mut targets = corners;
    for &z in planes_z {
        targets.extend(view.frame_corners(z));
    }
    // The region on the start plane whose rays can reach a target, along any direction.
    let (mut rmin, mut rmax) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for p in &targets {
        for v in &rim {
            let q = (*p - *v * ((p.z - z_start) / v.z)).truncate();
            rmin = rmin.min(q);
            rmax = rmax.max(q);
        }
    }
    // Lattice: aligned with the texels of the nearest plane, carried back along d.
    let spacing = view.texel_size(z_near) / settings.rays_per_texel as f64;
    let footprint = spacing * tile as f64;
    let origin = view.point_on_plane(DVec2::splat(-0.5), z_near);
    let origin = origin - d * ((z_near - z_start) / d.z);
    // Margin: two footprints (a box straddling the frame edge) and the rim's polygon error.
    let margin = footprint * 2.0 + (rmax - rmin) * 2e-3;
    let first = ((rmin - margin - origin.truncate()) / spacing).floor();
    let last = ((rmax + margin - origin.truncate()) / spacing).ceil();
    let (i0, j0) = (first.x as i64, first.y as i64);
    let (ni, nj) = ((last.x - first.x) as i64 + 1, (last.y - first.y) as i64 + 1);
    if ni as u64 * nj as u64 > MAX_RAYS {
        return setup(format!(
            "the plane trace would need {} rays; use fewer rays per texel or a smaller frame",
            ni as u64 * nj as u64
        ));
    }
    // Power per ray: each direction's sub-lattice gives irradiance ∝ its cos on the plane,
    // normalised so that all of them together give 1.
    let cos_sum: f64 = directions.iter().map(|v| v.z).sum();
    let powers: Vec<f64> = directions
        .iter()
        .map(|v| footprint.x * footprint.y * v.z / cos_sum)
        .collect();
    let world_dirs: Vec<DVec3> = directions
        .iter()
        .map(|v| view.world_from_view.transform_vector3(*v).normalize())
        .collect();

    let planes = Planes {
        view,
        view_from_world,
        z: planes_z,
        footprint,
    };
    let texels = (view.width * view.height) as usize;
    let h = settings.step_voxels * voxel;
    if let Some(p) = progress {
        p.set_length(nj as u64);
    }
    let rows_per_task = (nj as usize / (8 * rayon::current_num_threads().max(1))).max(1);
    let acc = (0..nj as usize)
        .into_par_iter()
        .with_min_len(rows_per_task)
        .fold(
            || Accumulator::new(planes_z.len(), texels),
            |mut acc, j| {
                let row = j0 + j as i64;
                for i in i0..i0 + ni {
                    let q = (i.rem_euclid(tile as i64) + tile as i64 * row.rem_euclid(tile as i64)) as usize;
                    let p = origin + DVec3::new((i as f64 + 0.5) * spacing.x, (row as f64 + 0.5) * spacing.y, 0.0);
                    let start = view.world_from_view.transform_point3(p);
                    trace_ray(medium, &planes, &mut acc, start, world_dirs[q], powers[q], h);
                }
                if let Some(p) = progress {
                    p.inc(1);
                }
                acc
            },
        )
        .reduce(|| Accumulator::new(planes_z.len(), texels), Accumulator::add);

    let out = planes_z
        .iter()
        .enumerate()
        .map(|(k, &z)| {
            let size = view.texel_size(z);
            let area = size.x * size.y;
            PlaneIrradiance {
                z,
                width: view.width,
                height: view.height,
                texels: acc.texels[k * texels..(k + 1) * texels]
                    .iter()
                    .map(|t| t.map(|v| v / area))
                    .collect(),
                power_in_frame: acc.in_frame[k],
                power_crossing: acc.crossing[k],
                power_backward: acc.backward[k],
            }
        })
        .collect();
    Ok(PlaneLight {
        planes: out,
        power_launched: acc.launched,
        power_entering: acc.entering,
        power_lost: acc.lost,
        power_escaped_backward: acc.escaped_backward,
        rays: acc.rays,
    })
}

/// The light of `prepared`'s scene on planes of view depth `planes_z` of its camera at
/// `width`×`height` (relative to the light's colour × intensity, as everything here).
pub fn trace_scene(
    prepared: &PreparedScene,
    width: u32,
    height: u32,
    planes_z: &[f64],
    settings: &PlaneSettings,
) -> Result<PlaneLight, ReferenceError> {
    let scene = &prepared.scene;
    let vol = &prepared.volume;
    let setup = ViewSetup::new(scene, vol.dims, vol.spacing, width, height).map_err(ReferenceError::Setup)?;
    let view = PlaneView::from_setup(
        &setup,
        scene.camera.projection == Projection::Orthographic,
        width,
        height,
    );
    let medium = VolumeMedium::for_scene(prepared);
    let d = light_direction(&scene.light);
    let light = DistantLight {
        direction: view
            .world_from_view
            .transform_vector3(DVec3::new(d.x as f64, d.y as f64, d.z as f64))
            .normalize(),
        color: [1.0; 3],
        softness: scene.light.softness as f64,
    };
    trace(&medium, &light, &view, planes_z, settings, None)
}
