//! Light tiles listed per plane for the forward beams (`list_light_tile` in beams.wgsl): the
//! margin around the volume's box within which beams are stepped, and the plane from which
//! each tile of the light grid is, from the beams' straight lines. Outside the box nothing
//! attenuates or bends a beam, so tiles far from it need not be stepped: on lavapipe only
//! fewer workgroups save time (a CPU driver runs every branch a workgroup takes).

use super::shaders::Pass;
use super::state::ACC_LEVELS;
use crate::scene::view::{BeamGrid, ViewSetup};

/// The start of a light tile none of whose beams comes near the box (`light_start` in
/// common.wgsl): it is never stepped.
pub const NEVER: u32 = u32::MAX;

/// The margins around the volume's box within which beams are stepped when light tiles are
/// listed per plane, in view units: (every beam's, a straight beam's). A view sample sees a
/// particle or an index change at most a voxel outside the box (trilinear sampling, one more
/// for the gradient), and reads the light up to a view segment either side (three steps, for
/// oblique rays) and, without refraction, in the cells around its light line (two cells).
/// With refraction the light is the beams' deposits, which reach half a footprint and a
/// texel of its level beyond a beam, and the view's bilinear read one texel more
/// (`deposit_reach` in beams.wgsl, per beam); a straight beam's footprint is its cell, at most
/// `stride` pixels on any plane, and the largest pixel is the far plane's.
pub fn margins(view: &ViewSetup, grid: &BeamGrid, sample_distance: f32, refraction: bool) -> (f32, f32) {
    let voxel = view.step / sample_distance.max(1e-6);
    let f = view.projection[0].abs().min(view.projection[1].abs()).max(1e-12);
    let z_last = view.plane_z(view.planes - 1);
    let (pixel_far, pixel_first) = if view.perspective {
        (z_last / f, view.z_first / f)
    } else {
        (1.0 / f, 1.0 / f)
    };
    let base = 3.0 * view.step + 2.0 * voxel + 2.0 * grid.stride * pixel_first;
    if !refraction {
        return (base, base);
    }
    let level = grid.stride.max(1.0).log2().ceil().clamp(0.0, (ACC_LEVELS - 1) as f32);
    (base, base + (0.5 * grid.stride + 2.0 * level.exp2()) * pixel_far)
}

/// Texture units per view unit along each axis of the volume at most: a view-space distance d
/// moves texture coordinate i by at most |row i of the linear part| · d.
pub fn texture_scale(view: &ViewSetup) -> [f32; 3] {
    let m = glam::Mat3::from_mat4(view.volume_from_view());
    [0, 1, 2].map(|i| m.row(i).length())
}

/// Per light tile: the first plane (at least 1) on which one of its beams, carried straight
/// along the light from plane 0, is within the texture margin `margin` of the volume's box
/// (NEVER if on none), and the smallest of those over the tile and its eight neighbours (the
/// plane from which `light_tiles_main` steps it). Beams bend only inside the box, so before
/// that plane every beam of the tile is still on its straight line.
pub fn starts(view: &ViewSetup, grid: &BeamGrid, light: glam::Vec3, margin: [f32; 3]) -> Vec<[u32; 2]> {
    let (tx, ty) = (
        grid.width.div_ceil(Pass::TILE) as usize,
        grid.height.div_ceil(Pass::TILE) as usize,
    );
    let mut raw = vec![NEVER; tx * ty];
    let volume_from_view = view.volume_from_view();
    // Texture coordinates per unit of depth along the light.
    let dq = volume_from_view.transform_vector3(light / light.z);
    let span = view.plane_z(view.planes - 1) - view.z_first;
    let [fx, fy, cx, cy] = view.projection;
    for j in 0..grid.height {
        for i in 0..grid.width {
            // The beam's cell centre on plane 0 (pixel-edge coordinates), as `beams_init`.
            let e = glam::Vec2::new(grid.x0, grid.y0) + (glam::Vec2::new(i as f32, j as f32) + 0.5) * grid.stride;
            let ndc = glam::Vec2::new((e.x - cx) / fx, (e.y - cy) / fy);
            let scale = if view.perspective { view.z_first } else { 1.0 };
            let q0 = volume_from_view.transform_point3(glam::Vec3::new(ndc.x * scale, ndc.y * scale, view.z_first));
            let (mut s0, mut s1) = (0.0f32, span);
            for a in 0..3 {
                let (lo, hi) = (-margin[a], 1.0 + margin[a]);
                if dq[a].abs() < 1e-20 {
                    if q0[a] < lo || q0[a] > hi {
                        s1 = -1.0;
                    }
                } else {
                    let (ta, tb) = ((lo - q0[a]) / dq[a], (hi - q0[a]) / dq[a]);
                    s0 = s0.max(ta.min(tb));
                    s1 = s1.min(ta.max(tb));
                }
            }
            if s0 <= s1 {
                let plane = ((s0 / view.step).floor() as u32).max(1);
                let t = (j as usize / Pass::TILE as usize) * tx + i as usize / Pass::TILE as usize;
                raw[t] = raw[t].min(plane);
            }
        }
    }
    (0..tx * ty)
        .map(|t| {
            let (x, y) = (t % tx, t / tx);
            let mut start = NEVER;
            for v in y.saturating_sub(1)..(y + 2).min(ty) {
                for u in x.saturating_sub(1)..(x + 2).min(tx) {
                    start = start.min(raw[v * tx + u]);
                }
            }
            [raw[t], start]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;
    use crate::scene::view::light_direction;

    /// Every beam is outside the margin on the planes before its tile starts: checked plane by
    /// plane along each beam's straight line, independently of the slab test, with a light
    /// at an angle so that tiles start on different planes.
    #[test]
    fn no_beam_comes_near_the_box_before_its_tile_starts() {
        let mut scene = builtin("ball-lens").unwrap().scene;
        scene.light.polar_deg = 35.0;
        scene.light.azimuth_deg = -40.0;
        let view = ViewSetup::new(&scene, [64, 40, 64], [1.0; 3], 48, 48).unwrap();
        let light = light_direction(&scene.light);
        let grid = view.beam_grid(light, 1.0, false);
        let scale = texture_scale(&view);
        let margin = scale.map(|s| s * 2.0 * view.step);
        let starts = starts(&view, &grid, light, margin);
        let tx = grid.width.div_ceil(Pass::TILE) as usize;
        let volume_from_view = view.volume_from_view();
        let mut later = 0;
        for j in 0..grid.height {
            for i in 0..grid.width {
                let e = glam::Vec2::new(grid.x0, grid.y0) + (glam::Vec2::new(i as f32, j as f32) + 0.5) * grid.stride;
                let p0 = view.point_at(e, view.z_first);
                let first = (0..view.planes).find(|&k| {
                    let p = p0 + light * ((view.plane_z(k) - view.z_first) / light.z);
                    let q = volume_from_view.transform_point3(p);
                    (0..3).all(|a| q[a] >= -margin[a] && q[a] <= 1.0 + margin[a])
                });
                let t = (j / Pass::TILE) as usize * tx + (i / Pass::TILE) as usize;
                if let Some(first) = first {
                    assert!(
                        starts[t][0] <= first.max(1),
                        "beam ({i}, {j}) is near the box on plane {first}, its tile starts on {:?}",
                        starts[t]
                    );
                    assert!(starts[t][1] <= starts[t][0]);
                }
                if starts[t][1] > 1 {
                    later += 1;
                }
            }
        }
        assert!(later > 0, "every tile starts on plane 1: the test shows nothing");
    }
}
