//! The orbit camera, its projection and the clip plane.

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Projection {
    #[default]
    Perspective,
    Orthographic,
}

/// An orbit camera around the volume's centre. Distances are in units of the volume's
/// bounding-sphere radius, so scenes do not depend on the voxel spacing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    pub yaw_deg: f32,
    pub pitch_deg: f32,
    pub distance: f32,
    pub fov_deg: f32,
    pub projection: Projection,
    /// Orthographic only: the view shows `2 / zoom` bounding radii vertically.
    pub zoom: f32,
    /// Look-at point, offset from the volume's centre in bounding radii (x right, y up, z back).
    pub target: [f32; 3],
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            yaw_deg: 0.0,
            pitch_deg: 20.0,
            distance: 3.0,
            fov_deg: 40.0,
            projection: Projection::Perspective,
            zoom: 1.0,
            target: [0.0; 3],
        }
    }
}

/// A plane that zeroes opacity on its positive side and leaves every other property alone
/// (paper Fig. 9). `normal` in volume axes, `offset` from the centre in bounding radii.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipPlane {
    pub normal: [f32; 3],
    #[serde(default)]
    pub offset: f32,
}
