//! The planes' camera: where a texel of a plane of constant view depth lies, and which plane
//! of a GPU sweep a relative depth selects.

use glam::{DMat4, DVec2, DVec3};

use crate::scene::ViewSetup;

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
    pub(super) fn frame_corners(&self, z: f64) -> [DVec3; 4] {
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

/// The plane a GPU sweep shows at relative depth `depth` (`--at-depth`): its index and its
/// view depth as the GPU computes it in f32.
pub fn sweep_plane_at(view: &ViewSetup, depth: f32) -> (u32, f64) {
    // As render/state.rs: planes 0..=round(D·(planes − 1)) are integrated.
    let k = (depth.clamp(0.0, 1.0) * view.planes.saturating_sub(1) as f32).round() as u32;
    (k, (view.z_first + k as f32 * view.step) as f64)
}
