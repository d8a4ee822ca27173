//! Light tiles listed per plane for the forward beams (`list_light_tile` in beams.wgsl): the
//! margins around what can change the light within which beams are stepped, and the planes
//! from which and (without refraction) until which each tile of the light grid is stepped,
//! from the beams' straight lines through the occupied cells (`occupancy.rs`). Away from them
//! nothing attenuates or bends a beam, so tiles far from them need not be stepped: on lavapipe
//! only fewer workgroups save time (a CPU driver runs every branch a workgroup takes).

use rayon::prelude::*;

use super::occupancy::Grown;
use super::state::ACC_LEVELS;
use crate::scene::view::{BeamGrid, ViewSetup};

/// The start of a light tile none of whose beams comes near the box (`light_start` in
/// common.wgsl): it is never stepped.
pub const NEVER: u32 = u32::MAX;

/// The margins around the volume's box within which beams are stepped when light tiles are
/// listed per plane, in view units: (every beam's, a straight beam's). A view sample sees a
/// particle or an index change at most a voxel outside the box (trilinear sampling, one more
/// for the gradient), and reads the light up to a view segment either side (three steps, for
/// oblique rays: up to 72° from the planes' normal) and, without refraction, in the cells
/// around its light line (two cells). Refraction can turn a view ray further, up to
/// `MIN_VIEW_DIR_Z` (about 50 steps sideways per plane) before it leaves the sweep. A margin
/// that wide would give up most of what the margins save (with every beam depositing, the CT
/// head's light pass at 384² takes 6–18 % longer), so the few segments that graze a rim that
/// steeply may read light the beams left out (measured in `deposit_read`, beams.wgsl).
/// With refraction the light is the beams' deposits, which reach half a footprint and a
/// texel of its level beyond a beam, and the view's bilinear read one texel more
/// (`deposit_reach` in beams.wgsl, per beam); a straight beam's footprint is its cell, at most
/// `stride` pixels on any plane, and the largest pixel is the far plane's. Without refraction
/// a view sample reads the beams further back along its light line by `back` (view units).
pub fn margins(view: &ViewSetup, grid: &BeamGrid, sample_distance: f32, refraction: bool, back: f32) -> (f32, f32) {
    let voxel = view.step / sample_distance.max(1e-6);
    let f = view.projection[0].abs().min(view.projection[1].abs()).max(1e-12);
    let z_last = view.plane_z(view.planes - 1);
    let (pixel_far, pixel_first) = if view.perspective {
        (z_last / f, view.z_first / f)
    } else {
        (1.0 / f, 1.0 / f)
    };
    let base = 3.0 * view.step + 2.0 * voxel + 2.0 * grid.stride * pixel_first + back;
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

/// Per light tile (`tile` × `tile` beams): the first plane (at least 1) on which one of its
/// beams, carried straight along the light from plane 0, is in an occupied cell of `grown`
/// (the cells grown by the margin; NEVER if on none); the smallest of those over the tile and
/// its eight neighbours (the plane from which `list_light_tile` steps it); and the last plane
/// on which one of its beams is in one (0 if none). Beams bend only in occupied cells, so
/// before the first of those planes every beam of the tile is still on its straight line, and
/// without refraction after the last its light no longer changes. Without `last` (bent beams,
/// whose end the device finds) the last plane is left 0 and each line is traversed only to the
/// first occupied cell it meets.
pub fn spans(
    view: &ViewSetup,
    grid: &BeamGrid,
    light: glam::Vec3,
    grown: &[Grown],
    last: bool,
    tile: u32,
) -> Vec<[u32; 4]> {
    let (tx, ty) = (grid.width.div_ceil(tile) as usize, grid.height.div_ceil(tile) as usize);
    let volume_from_view = view.volume_from_view();
    // Texture coordinates per unit of depth along the light.
    let dq = volume_from_view.transform_vector3(light / light.z);
    let span = view.plane_z(view.planes - 1) - view.z_first;
    let [fx, fy, cx, cy] = view.projection;
    // Per row of beams: the first and last plane of each tile it crosses.
    let rows: Vec<Vec<(u32, u32)>> = (0..grid.height)
        .into_par_iter()
        .map(|j| {
            let mut row = vec![(NEVER, 0u32); tx];
            for i in 0..grid.width {
                // The beam's cell centre on plane 0 (pixel-edge coordinates), as `beams_init`.
                let e = glam::Vec2::new(grid.x0, grid.y0) + (glam::Vec2::new(i as f32, j as f32) + 0.5) * grid.stride;
                let ndc = glam::Vec2::new((e.x - cx) / fx, (e.y - cy) / fy);
                let scale = if view.perspective { view.z_first } else { 1.0 };
                let q0 = volume_from_view.transform_point3(glam::Vec3::new(ndc.x * scale, ndc.y * scale, view.z_first));
                let t = &mut row[(i / tile) as usize];
                for g in grown {
                    // Without `last`, an end of 0 leaves the last plane at 0.
                    let hit = if last {
                        g.span(q0, dq, 0.0, span)
                    } else {
                        g.entry(q0, dq, 0.0, span).map(|s0| (s0, 0.0))
                    };
                    if let Some((s0, s1)) = hit {
                        t.0 = t.0.min(((s0 / view.step).floor() as u32).max(1));
                        t.1 = t.1.max((s1 / view.step).ceil() as u32);
                    }
                }
            }
            row
        })
        .collect();
    let mut raw = vec![(NEVER, 0u32); tx * ty];
    for (j, row) in rows.iter().enumerate() {
        for (x, &(first, last)) in row.iter().enumerate() {
            let t = &mut raw[(j / tile as usize) * tx + x];
            *t = (t.0.min(first), t.1.max(last));
        }
    }
    (0..tx * ty)
        .map(|t| {
            let (x, y) = (t % tx, t / tx);
            let mut start = NEVER;
            for v in y.saturating_sub(1)..(y + 2).min(ty) {
                for u in x.saturating_sub(1)..(x + 2).min(tx) {
                    start = start.min(raw[v * tx + u].0);
                }
            }
            [raw[t].0, start, raw[t].1, 0]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::occupancy::{Occupancy, CELL};
    use crate::render::shaders::Pass;
    use crate::scene::builtin;
    use crate::scene::view::light_direction;

    /// Every beam is outside the margin of the occupied cells on the planes before its tile
    /// starts and after its last plane: checked plane by plane along each beam's straight
    /// line against each occupied cell's box grown by the margin, independently of the
    /// traversal, with a light at an angle so that tiles start and end on different planes.
    #[test]
    fn no_beam_comes_near_an_occupied_cell_outside_its_tile_span() {
        let mut scene = builtin("ball-lens").unwrap().scene;
        scene.light.polar_deg = 35.0;
        scene.light.azimuth_deg = -40.0;
        let voxels = [64, 40, 64];
        let view = ViewSetup::new(&scene, voxels, [1.0; 3], 48, 48).unwrap();
        let light = light_direction(&scene.light);
        let grid = view.beam_grid(light, 1.0, false, None);
        let scale = texture_scale(&view);
        let margin = scale.map(|s| s * 2.0 * view.step);
        // A few occupied cells: one inside, one at a corner, one at a face.
        let cells = voxels.map(|d| d.div_ceil(CELL));
        let mut occupancy = Occupancy {
            flags: vec![false; cells[0] * cells[1] * cells[2]],
            cells,
            voxels,
            edge: CELL,
        };
        let occupied = [[7, 5, 9], [0, 0, 0], [15, 3, 4]];
        for c in occupied {
            occupancy.flags[(c[2] * cells[1] + c[1]) * cells[0] + c[0]] = true;
        }
        let near = |q: glam::Vec3| {
            occupied.iter().any(|c| {
                (0..3).all(|a| {
                    let lo = (c[a] * CELL) as f32 / voxels[a] as f32 - margin[a];
                    let hi = ((c[a] + 1) * CELL) as f32 / voxels[a] as f32 + margin[a];
                    q[a] >= lo && q[a] <= hi
                })
            })
        };
        // Either side of tile the sweep may work in.
        let (mut later, mut earlier) = (0, 0);
        for tile in [Pass::TILE, Pass::CPU_TILE] {
            let spans = spans(&view, &grid, light, &[occupancy.grown(margin)], true, tile);
            // Without the last planes (bent beams) each line stops at its first occupied cell:
            // the first planes are the same.
            let firsts = super::spans(&view, &grid, light, &[occupancy.grown(margin)], false, tile);
            for (a, b) in spans.iter().zip(&firsts) {
                assert_eq!((a[0], a[1], 0), (b[0], b[1], b[2]), "{a:?} against {b:?}");
            }
            let tx = grid.width.div_ceil(tile) as usize;
            let volume_from_view = view.volume_from_view();
            for j in 0..grid.height {
                for i in 0..grid.width {
                    let e =
                        glam::Vec2::new(grid.x0, grid.y0) + (glam::Vec2::new(i as f32, j as f32) + 0.5) * grid.stride;
                    let p0 = view.point_at(e, view.z_first);
                    let t = (j / tile) as usize * tx + (i / tile) as usize;
                    for k in 0..view.planes {
                        let p = p0 + light * ((view.plane_z(k) - view.z_first) / light.z);
                        if near(volume_from_view.transform_point3(p)) {
                            assert!(
                                spans[t][0] <= k.max(1) && spans[t][2] >= k,
                                "beam ({i}, {j}) is near a cell on plane {k}, its tile spans {:?}",
                                spans[t]
                            );
                        }
                    }
                    assert!(spans[t][1] <= spans[t][0]);
                    if spans[t][1] > 1 && spans[t][1] != NEVER {
                        later += 1;
                    }
                    if spans[t][0] != NEVER && spans[t][2] + 1 < view.planes {
                        earlier += 1;
                    }
                }
            }
        }
        assert!(
            later > 0 && earlier > 0,
            "every tile spans all planes: the test shows nothing"
        );
    }
}
