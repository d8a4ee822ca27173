//! A CPU front-to-back emission–absorption renderer for straight rays and a light travelling
//! along the view axis (orthographic camera, light polar angle 0): the configuration in which
//! the slice-plane method has an exact discrete counterpart. It samples the same planes and
//! uses the same pre-integrated tables, so the only differences to the GPU come from texture
//! filtering precision and 16-bit storage of the light and colour buffers.

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
                let e = PreintegratedTables::lookup(&tables.particle, prev, cur);
                let a = 1.0 - (-e[3]).exp();
                if alpha < scene.quality.termination_opacity {
                    for c in 0..3 {
                        color[c] += (1.0 - alpha) * e[c] * light[c] * light_t[c];
                    }
                    alpha += (1.0 - alpha) * a;
                }
                for t in &mut light_t {
                    *t *= 1.0 - a;
                }
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
