//! A CPU front-to-back emission–absorption renderer for straight rays and a light travelling
//! along the view axis (orthographic camera, light polar angle 0): the configuration in which
//! the slice-plane method has an exact discrete counterpart. It samples the same planes and
//! uses the same pre-integrated tables, the same split of each segment at the extremum of
//! the parabola through its ends and its middle, and the same light model over a segment, so
//! the only differences to the GPU come from texture filtering precision and 16-bit storage of
//! the light and colour buffers.

use glam::Vec3;

use crate::scene::Scene;
use crate::scene::ViewSetup;
use crate::transfer::{preintegrate, PreintegratedTables, TransferFunctions};
use crate::volume::Volume;

/// Renders `scene` (orthographic, light along the view axis, η constant, white medium) into
/// linear RGB, background `background`.
pub fn render(
    scene: &Scene,
    volume: &Volume,
    tf: &TransferFunctions,
    width: u32,
    height: u32,
    background: [f32; 3],
) -> Result<Vec<[f32; 3]>, String> {
    let view = ViewSetup::new(scene, volume.dims, volume.spacing, width, height)?;
    let tables = preintegrate(tf, scene.quality.sample_distance);
    let window = scene.window.unwrap_or(volume.value_range);
    let normalized: Vec<f32> = volume
        .normalized_u16(window)
        .iter()
        .map(|v| *v as f32 / 65535.0)
        .collect();
    let vol01 = Volume {
        data: normalized,
        value_range: [0.0, 1.0],
        ..volume.clone()
    };
    let volume_from_view = view.volume_from_view();
    let dims = Vec3::new(volume.dims[0] as f32, volume.dims[1] as f32, volume.dims[2] as f32);
    let sample = |p: Vec3| -> f32 {
        // texture coordinates → voxel coordinates with centres at integers
        let t = volume_from_view.transform_point3(p) * dims - Vec3::splat(0.5);
        vol01.sample_trilinear([t.x, t.y, t.z])
    };
    let light = scene.light.color.map(|c| c * scene.light.intensity);
    let [fx, fy, cx, cy] = view.projection;
    let mut out = Vec::with_capacity((width * height) as usize);
    for py in 0..height {
        for px in 0..width {
            let xy = glam::Vec2::new((px as f32 + 0.5 - cx) / fx, (py as f32 + 0.5 - cy) / fy);
            let mut color = [0.0f32; 3];
            let mut alpha = 0.0f32;
            let mut light_t = [1.0f32; 3]; // light transmittance from plane 0 to the current plane
            let mut prev = sample(Vec3::new(xy.x, xy.y, view.z_first));
            for i in 1..view.planes {
                let z = view.z_first + i as f32 * view.step;
                let cur = sample(Vec3::new(xy.x, xy.y, z));
                let mid = sample(Vec3::new(xy.x, xy.y, z - 0.5 * view.step));
                let e = split_particles(&tables, prev, mid, cur);
                let a = 1.0 - (-e[3]).exp();
                let light_end = light_t.map(|t| t * (1.0 - a));
                if alpha < scene.quality.termination_opacity {
                    for c in 0..3 {
                        let seen = segment_light(light_t[c], light_end[c], a);
                        color[c] += (1.0 - alpha) * e[c] * light[c] * seen;
                    }
                    alpha += (1.0 - alpha) * a;
                }
                light_t = light_end;
                prev = cur;
            }
            out.push([
                color[0] + (1.0 - alpha) * background[0],
                color[1] + (1.0 - alpha) * background[1],
                color[2] + (1.0 - alpha) * background[2],
            ]);
        }
    }
    Ok(out)
}

/// Where the GPU splits a segment with values `v0`, `vm` (middle), `v1`: (fraction in front,
/// value there); the extremum of the parabola through the three when the middle is the
/// extreme, else halfway (shaders/common.wgsl, segment_split).
fn segment_split(v0: f32, vm: f32, v1: f32) -> (f32, f32) {
    let b = 4.0 * vm - 3.0 * v0 - v1;
    let c = 2.0 * (v0 + v1) - 4.0 * vm;
    if (vm > v0.max(v1) || vm < v0.min(v1)) && c.abs() > 1e-6 {
        (
            (-b / (2.0 * c)).clamp(0.0, 1.0),
            (v0 - b * b / (4.0 * c)).clamp(0.0, 1.0),
        )
    } else {
        (0.5, vm)
    }
}

/// Premultiplied colour and optical depth of a segment split at its extremum, front over back.
fn split_particles(tables: &PreintegratedTables, v0: f32, vm: f32, v1: f32) -> [f32; 4] {
    let (t, v) = segment_split(v0, vm, v1);
    let part = |a: f32, b: f32, length: f32| {
        let e = PreintegratedTables::lookup(&tables.particle, a, b);
        let alpha = 1.0 - (-e[3]).exp();
        let alpha_part = 1.0 - (-e[3] * length).exp();
        // The premultiplied colour of a shorter part scales with its opacity.
        let scale = if alpha > 1e-6 { alpha_part / alpha } else { length };
        [e[0] * scale, e[1] * scale, e[2] * scale, e[3] * length]
    };
    let (f, b) = (part(v0, v, t), part(v, v1, 1.0 - t));
    let through = (-f[3]).exp();
    [
        f[0] + through * b[0],
        f[1] + through * b[1],
        f[2] + through * b[2],
        f[3] + b[3],
    ]
}

/// h(x) = (1 − e^−x) / x, h(0) = 1.
fn mean_exp(x: f32) -> f32 {
    if x.abs() < 1e-3 {
        1.0 - x * (0.5 - x / 6.0)
    } else {
        (1.0 - (-x).exp()) / x
    }
}

/// The light a segment's particles see, from `l0` at its front to `l1` at its back, opacity
/// `alpha` (shaders/view.wgsl, segment_light).
fn segment_light(l0: f32, l1: f32, alpha: f32) -> f32 {
    let t = -(1.0 - alpha).max(1e-7).ln();
    if l1 >= l0 {
        let centroid = if t > 1e-3 { 1.0 / t - 1.0 / (t.exp() - 1.0) } else { 0.5 };
        return l0 + (l1 - l0) * centroid;
    }
    let fall = (l0.max(1e-30) / l1.max(1e-30)).ln().clamp(0.0, 14.0);
    l0 * mean_exp(t + fall) / mean_exp(t)
}
