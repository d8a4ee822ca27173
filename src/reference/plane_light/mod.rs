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

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::measure::ScalarImage;
use super::medium::{Medium, VolumeMedium};
use super::photons::{basis, DistantLight};
use super::ReferenceError;
use crate::scene::Projection;
use crate::scene::{light_direction, PreparedScene, ViewSetup};

mod rays;
mod view;

use rays::{trace_ray, Accumulator, Planes};
pub use view::{nearest_sweep_plane, sweep_plane_at, PlaneView};

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
    trace_scene_through(
        prepared,
        &VolumeMedium::for_scene(prepared),
        width,
        height,
        planes_z,
        settings,
    )
}

/// As [`trace_scene`], with the scene's camera and light but `medium` in place of its volume
/// (an analytic object the volume samples, say).
pub fn trace_scene_through<M: Medium + ?Sized>(
    prepared: &PreparedScene,
    medium: &M,
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
    let d = light_direction(&scene.light);
    let light = DistantLight {
        direction: view
            .world_from_view
            .transform_vector3(DVec3::new(d.x as f64, d.y as f64, d.z as f64))
            .normalize(),
        color: [1.0; 3],
        softness: scene.light.softness as f64,
    };
    trace(medium, &light, &view, planes_z, settings, None)
}
