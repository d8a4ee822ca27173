//! Building blocks for the procedural scenes: signed distances, anti-aliased coverage,
//! value noise and the grid evaluator. Positions are in voxel units; voxel `i` covers
//! `[i, i + 1]`, so its centre is at `i + 0.5`.

use glam::{Vec2, Vec3};

use crate::volume::{value_range, Volume};

/// Half the width, in voxels, of the smooth transition at every shape edge (~1.5 voxels in
/// total), which keeps the value field continuous for gradient estimation.
const EDGE_HALF_WIDTH: f32 = 0.75;

/// Hermite step: 0 below `e0`, 1 above `e1`, smooth in between. Also works with `e0 > e1`.
pub fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Anti-aliased inside fraction for a signed distance in voxels (negative inside).
pub(super) fn coverage(signed_distance: f32) -> f32 {
    1.0 - smoothstep(-EDGE_HALF_WIDTH, EDGE_HALF_WIDTH, signed_distance)
}

pub(super) fn sd_sphere(p: Vec3, centre: Vec3, radius: f32) -> f32 {
    (p - centre).length() - radius
}

/// Approximate signed distance to an axis-aligned ellipsoid; exact to first order near the
/// surface, which is all the edge smoothing needs.
pub(super) fn sd_ellipsoid(p: Vec3, centre: Vec3, radii: Vec3) -> f32 {
    let q = p - centre;
    let k0 = (q / radii).length();
    let k1 = (q / (radii * radii)).length();
    if k1 > 0.0 {
        k0 * (k0 - 1.0) / k1
    } else {
        -radii.min_element()
    }
}

/// Signed distance to a segment from `a` to `b` thickened to `radius`.
pub(super) fn sd_capsule(p: Vec3, a: Vec3, b: Vec3, radius: f32) -> f32 {
    let pa = p - a;
    let ba = b - a;
    let len2 = ba.length_squared();
    let h = if len2 > 0.0 {
        (pa.dot(ba) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (pa - ba * h).length() - radius
}

/// Signed distance to a vertical cylinder around the axis through `(axis.x, axis.y)` in
/// x/z, spanning heights `y0..y1`.
pub(super) fn sd_vertical_cylinder(p: Vec3, axis: Vec2, y0: f32, y1: f32, radius: f32) -> f32 {
    let r = Vec2::new(p.x, p.z).distance(axis);
    let d = Vec2::new(r - radius, (p.y - 0.5 * (y0 + y1)).abs() - 0.5 * (y1 - y0));
    d.max_element().min(0.0) + d.max(Vec2::ZERO).length()
}

/// Integer lattice hash to [0, 1).
fn hash3(x: i32, y: i32, z: i32, seed: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f)
        ^ seed.wrapping_mul(0x1656_67b1);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297a_2d39);
    h ^= h >> 15;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Smoothly interpolated lattice noise in [0, 1); C1-continuous thanks to the Hermite fade.
pub(super) fn value_noise(p: Vec3, seed: u32) -> f32 {
    let cell = p.floor();
    let f = p - cell;
    let u = f * f * (Vec3::splat(3.0) - 2.0 * f);
    let (ix, iy, iz) = (cell.x as i32, cell.y as i32, cell.z as i32);
    let corner = |dx: i32, dy: i32, dz: i32| hash3(ix + dx, iy + dy, iz + dz, seed);
    let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
    let x00 = lerp(corner(0, 0, 0), corner(1, 0, 0), u.x);
    let x10 = lerp(corner(0, 1, 0), corner(1, 1, 0), u.x);
    let x01 = lerp(corner(0, 0, 1), corner(1, 0, 1), u.x);
    let x11 = lerp(corner(0, 1, 1), corner(1, 1, 1), u.x);
    lerp(lerp(x00, x10, u.y), lerp(x01, x11, u.y), u.z)
}

/// Fractal sum of `octaves` noise layers, normalised back to [0, 1).
pub(super) fn fbm(p: Vec3, seed: u32, octaves: u32) -> f32 {
    let mut sum = 0.0;
    let mut weight = 0.0;
    let mut amplitude = 1.0;
    let mut frequency = 1.0;
    for octave in 0..octaves {
        sum += amplitude * value_noise(p * frequency, seed.wrapping_add(octave));
        weight += amplitude;
        amplitude *= 0.5;
        frequency *= 2.03;
    }
    sum / weight
}

/// Evaluates `field` at every voxel centre (clamped to [0, 1]) with unit spacing, splitting
/// the z slices across threads.
pub(super) fn build(dims: [usize; 3], field: impl Fn(Vec3) -> f32 + Sync) -> Volume {
    let [nx, ny, nz] = dims;
    let slice = nx * ny;
    let mut data = vec![0.0f32; slice * nz];
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get()).clamp(1, nz);
    let slices_per_chunk = nz.div_ceil(threads);
    let field = &field;
    std::thread::scope(|scope| {
        for (chunk_index, chunk) in data.chunks_mut(slice * slices_per_chunk).enumerate() {
            scope.spawn(move || {
                let first = chunk_index * slice * slices_per_chunk;
                for (offset, value) in chunk.iter_mut().enumerate() {
                    let i = first + offset;
                    let p = Vec3::new(
                        (i % nx) as f32 + 0.5,
                        ((i / nx) % ny) as f32 + 0.5,
                        (i / slice) as f32 + 0.5,
                    );
                    *value = field(p).clamp(0.0, 1.0);
                }
            });
        }
    });
    let value_range = value_range(&data);
    Volume {
        dims,
        spacing: [1.0; 3],
        data,
        value_range,
    }
}
