//! The built-in scene volumes. Values are transfer-function inputs in [0, 1] (0 = air);
//! sizes are fractions of `n`, the resolution along the longest axis.

use glam::{Vec2, Vec3};

use super::shapes::{build, coverage, fbm, sd_capsule, sd_ellipsoid, sd_sphere, sd_vertical_cylinder, smoothstep};
use crate::volume::Volume;

/// Which part of a scene a volume holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Part {
    /// Everything: the objects and what they stand on.
    #[default]
    Whole,
    /// The objects only, without the ground and walls: the η source of the built-in scenes,
    /// so that the supports' surfaces, blended from air to ground, do not pass through the
    /// objects' values (a ground's edge voxels would otherwise take the glass's η in a film).
    Objects,
}

impl Part {
    fn support(self, value: f32) -> f32 {
        match self {
            Part::Whole => value,
            Part::Objects => 0.0,
        }
    }
}

/// Smallest accepted resolution; below this the shapes fall apart into single voxels.
pub const MIN_RESOLUTION: usize = 8;

/// A glass ball lens floating above a ground slab.
/// Dims `[n, 5n/8, n]`; ground 1.0, glass 0.5. `n` is raised to [`MIN_RESOLUTION`].
pub fn ball_lens(n: usize) -> Volume {
    ball_lens_part(n, Part::Whole)
}

pub(super) fn ball_lens_part(n: usize, part: Part) -> Volume {
    let n = n.max(MIN_RESOLUTION);
    let dims = [n, n * 5 / 8, n];
    let nf = n as f32;
    let ground_top = 0.08 * dims[1] as f32;
    let radius = 0.16 * nf;
    let centre = Vec3::new(0.5 * nf, ground_top + 1.6 * radius, 0.5 * nf);
    build(dims, move |p| {
        let ground = part.support(coverage(p.y - ground_top));
        let ball = 0.5 * coverage(sd_sphere(p, centre, radius));
        ground.max(ball)
    })
}

/// A stemmed wine glass (0.4) partly filled with liquid (0.7) on the ground, in front of a
/// back wall (both 1.0). Dims `[n, n, n]`. `n` is raised to [`MIN_RESOLUTION`].
pub fn glass(n: usize) -> Volume {
    glass_part(n, Part::Whole)
}

pub(super) fn glass_part(n: usize, part: Part) -> Volume {
    let n = n.max(MIN_RESOLUTION);
    let nf = n as f32;
    let axis = Vec2::splat(0.5 * nf);
    let ground_top = 0.06 * nf;
    let back_wall = 0.92 * nf;
    // Kept at least a voxel thick so the glass does not vanish at low resolution.
    let wall = (0.025 * nf).max(1.0);
    let foot_radius = 0.15 * nf;
    let foot_top = ground_top + (0.03 * nf).max(2.0);
    let stem_radius = (0.018 * nf).max(0.8);
    let bowl_radii = Vec3::new(0.17 * nf, 0.22 * nf, 0.17 * nf);
    let bowl_bottom = foot_top + 0.2 * nf;
    let bowl_centre = Vec3::new(axis.x, bowl_bottom + bowl_radii.y, axis.y);
    // Cut above the equator so the bowl narrows towards the rim, like a tulip glass.
    let rim = bowl_centre.y + 0.55 * bowl_radii.y;
    let inner_bottom = bowl_bottom + 0.5 * wall;
    let liquid_top = inner_bottom + 0.6 * (rim - inner_bottom);
    build([n, n, n], move |p| {
        let bowl = sd_ellipsoid(p, bowl_centre, bowl_radii);
        let shell = (bowl.abs() - 0.5 * wall).max(p.y - rim);
        let foot = sd_vertical_cylinder(p, axis, ground_top, foot_top, foot_radius);
        // The stem reaches into the foot and the bowl wall so the parts join without seams.
        let stem = sd_vertical_cylinder(p, axis, foot_top - 1.0, bowl_bottom + wall, stem_radius);
        let glass = shell.min(foot).min(stem);
        let liquid = (bowl + 0.5 * wall).max(p.y - liquid_top);
        let ground = part.support(coverage(p.y - ground_top));
        let wall_cover = part.support(coverage(back_wall - p.z));
        ground
            .max(wall_cover)
            .max(0.4 * coverage(glass))
            .max(0.7 * coverage(liquid))
    })
}

/// A layered, turbulent sphere: core 0.62..0.9, mid layer 0.55 ± 0.05, outer shell 0.3, over
/// a ground slab of 1.0 (above every layer, so no layer edge passes through it). Dims `[n, n, n]`. `n` is raised to [`MIN_RESOLUTION`].
pub fn supernova(n: usize) -> Volume {
    supernova_part(n, Part::Whole)
}

pub(super) fn supernova_part(n: usize, part: Part) -> Volume {
    let n = n.max(MIN_RESOLUTION);
    let nf = n as f32;
    let centre = Vec3::new(0.5 * nf, 0.55 * nf, 0.5 * nf);
    let (core_radius, mid_radius, outer_radius) = (0.18 * nf, 0.3 * nf, 0.38 * nf);
    let ground_top = 0.05 * nf;
    build([n, n, n], move |p| {
        // Noise coordinates scale with n so the pattern is the same at every resolution.
        let q = p / nf * 6.0;
        let turbulence = fbm(q, 11, 4) - 0.5;
        let core_value = 0.62 + 0.28 * fbm(q * 2.0, 23, 4);
        let mid_value = 0.55 + 0.1 * (fbm(q * 1.5, 37, 3) - 0.5);
        let r = (p - centre).length();
        let core = coverage(r - core_radius * (1.0 + 0.25 * turbulence));
        let mid = coverage(r - mid_radius * (1.0 + 0.08 * turbulence));
        let outer = coverage(r - outer_radius * (1.0 + 0.04 * turbulence));
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let layered = lerp(lerp(0.3 * outer, mid_value, mid), core_value, core);
        layered.max(part.support(coverage(p.y - ground_top)))
    })
}

/// A Luneburg-style graded sphere, 0.8 at the centre falling to 0 at the surface, above a
/// ground slab (1.0). Dims `[n, 3n/4, n]`. `n` is raised to [`MIN_RESOLUTION`].
pub fn luneburg(n: usize) -> Volume {
    luneburg_part(n, Part::Whole)
}

pub(super) fn luneburg_part(n: usize, part: Part) -> Volume {
    let n = n.max(MIN_RESOLUTION);
    let nf = n as f32;
    let dims = [n, n * 3 / 4, n];
    let ground_top = 0.06 * dims[1] as f32;
    let radius = 0.3 * nf;
    let centre = Vec3::new(0.5 * nf, ground_top + 1.15 * radius, 0.5 * nf);
    build(dims, move |p| {
        let r2 = (p - centre).length_squared() / (radius * radius);
        let lens = (0.8 * (1.0 - r2)).max(0.0);
        lens.max(part.support(coverage(p.y - ground_top)))
    })
}

/// A faint body (0.35) on six thin bent legs (0.6) standing on a checkered ground slab
/// (0.9 / 1.0 squares of size n/8). Dims `[n, 3n/4, n]`. `n` is raised to [`MIN_RESOLUTION`].
pub fn thin_structures(n: usize) -> Volume {
    thin_structures_part(n, Part::Whole)
}

pub(super) fn thin_structures_part(n: usize, part: Part) -> Volume {
    let n = n.max(MIN_RESOLUTION);
    let nf = n as f32;
    let dims = [n, n * 3 / 4, n];
    let ground_top = 0.06 * dims[1] as f32;
    let body_centre = Vec3::new(0.5 * nf, 0.3 * nf, 0.5 * nf);
    let body_radii = Vec3::new(0.125 * nf, 0.06 * nf, 0.075 * nf);
    let legs = leg_segments(body_centre, nf, ground_top);
    let square = nf / 8.0;
    build(dims, move |p| {
        let body = 0.35 * coverage(sd_ellipsoid(p, body_centre, body_radii));
        let leg_distance = legs
            .iter()
            .map(|&(a, b)| sd_capsule(p, a, b, LEG_RADIUS))
            .fold(f32::INFINITY, f32::min);
        let leg = 0.6 * coverage(leg_distance);
        // Smoothed XOR of the two square waves keeps the checker edges continuous too.
        let (cx, cz) = (square_wave(p.x, square), square_wave(p.z, square));
        let parity = cx + cz - 2.0 * cx * cz;
        let ground = part.support((0.9 + 0.1 * parity) * coverage(p.y - ground_top));
        body.max(leg).max(ground)
    })
}

/// Leg radius in voxels: thin at every resolution, which is the point of the scene.
const LEG_RADIUS: f32 = 1.2;

/// Three segments per leg (hip → knee → ankle → foot), three legs on each side in z.
fn leg_segments(body: Vec3, nf: f32, ground_top: f32) -> Vec<(Vec3, Vec3)> {
    let mut segments = Vec::with_capacity(18);
    for side in [-1.0f32, 1.0] {
        for index in 0..3 {
            let dx = (index as f32 - 1.0) * 0.08 * nf;
            let hip = body + Vec3::new(dx, 0.0, side * 0.04 * nf);
            let knee = body + Vec3::new(1.6 * dx, 0.12 * nf, side * 0.2 * nf);
            let ankle = Vec3::new(body.x + 2.2 * dx, 0.15 * nf, body.z + side * 0.33 * nf);
            // The foot sinks slightly into the ground so leg and slab meet without a gap.
            let foot = Vec3::new(body.x + 2.4 * dx, ground_top - 0.5, body.z + side * 0.36 * nf);
            segments.extend([(hip, knee), (knee, ankle), (ankle, foot)]);
        }
    }
    segments
}

/// 0 on even squares, 1 on odd squares of size `square`, with smoothed edges.
fn square_wave(x: f32, square: f32) -> f32 {
    let half = 0.75;
    let m = x.rem_euclid(2.0 * square);
    smoothstep(square - half, square + half, m) - smoothstep(2.0 * square - half, 2.0 * square + half, m) + 1.0
        - smoothstep(-half, half, m)
}
