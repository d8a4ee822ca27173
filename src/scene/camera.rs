//! The orbit camera, its projection and orientation, the named anatomical views, and the clip
//! plane.
//!
//! The camera orbits its target at `yaw_deg` around the world's y axis and `pitch_deg` above
//! the x–z plane, turned by `roll_deg` about its view direction. Patient data is shown in the
//! display axes of [`crate::volume::orient`] (x towards the patient's left, y superior,
//! z posterior), so the default camera (yaw 0, pitch 0) is the anterior view with the head up.
//! The named views follow 3D Slicer's: anterior, posterior, left and right with superior up;
//! superior (looking down at the head) with posterior up; inferior with anterior up. For data
//! whose voxel axes are oblique to the body, the views are turned by the volume's residual
//! rotation so that they stay exact.

use std::fmt;

use glam::{Mat3, Vec3};
use serde::{Deserialize, Serialize};

/// Camera pitch is held within ±this many degrees: beyond it the camera would be upside down.
/// At exactly ±90° (the superior and inferior views) the image's right axis is set by the yaw
/// and roll, so the view stays well defined.
pub const MAX_PITCH_DEG: f32 = 90.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Projection {
    #[default]
    Perspective,
    Orthographic,
}

/// An orbit camera around the volume's centre. Distances are in units of the volume's
/// bounding-sphere radius, so scenes do not depend on the voxel spacing. Orientation and the
/// named anatomical views: [`View`], [`Camera::basis`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Camera {
    pub yaw_deg: f32,
    pub pitch_deg: f32,
    /// Rotation of the image about the view direction (positive turns the camera clockwise,
    /// so the picture turns counter-clockwise).
    pub roll_deg: f32,
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
            roll_deg: 0.0,
            distance: 3.0,
            fov_deg: 40.0,
            projection: Projection::Perspective,
            zoom: 1.0,
            target: [0.0; 3],
        }
    }
}

impl Camera {
    /// The camera's axes in world space: image right, image down and view direction (the
    /// renderer's view space has x right, y down, z forward).
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let yaw = self.yaw_deg.to_radians();
        let pitch = self.pitch_deg.clamp(-MAX_PITCH_DEG, MAX_PITCH_DEG).to_radians();
        let forward = Vec3::new(-yaw.sin() * pitch.cos(), -pitch.sin(), yaw.cos() * pitch.cos());
        // Horizontal and independent of the pitch, so it stays defined looking straight down.
        let right = Vec3::new(yaw.cos(), 0.0, yaw.sin());
        let down = right.cross(forward);
        let roll = self.roll_deg.to_radians();
        let (s, c) = roll.sin_cos();
        (right * c + down * s, down * c - right * s, forward)
    }

    /// Points the camera along `forward` with `up` at the top of the image (world axes; `up`
    /// need not be perpendicular to `forward`). Distance, projection and target are kept.
    pub fn look(&mut self, forward: Vec3, up: Vec3) {
        let f = forward.normalize_or(Vec3::Z);
        let pitch = (-f.y).clamp(-1.0, 1.0).asin();
        let yaw = if pitch.cos() > 1e-6 { (-f.x).atan2(f.z) } else { 0.0 };
        // `+ 0.0` turns −0 into 0, which the panel would show as "-0".
        self.yaw_deg = yaw.to_degrees().rem_euclid(360.0) + 0.0;
        self.pitch_deg = pitch.to_degrees() + 0.0;
        self.roll_deg = 0.0;
        let (right0, down0, f0) = self.basis();
        // The wanted right axis: in view space x right, y down, z forward, so right = f × down.
        let right = up.cross(f0).normalize_or(right0);
        self.roll_deg = right.dot(down0).atan2(right.dot(right0)).to_degrees() + 0.0;
    }

    /// Turns the camera to a named view of patient data and centres it. `display_from_world`
    /// is the volume's residual rotation ([`crate::volume::PatientFrame::display_from_world`];
    /// the identity for volumes without a patient frame, whose axes are taken as display axes).
    pub fn set_view(&mut self, view: View, display_from_world: Mat3) {
        let (forward, up) = view.display_basis();
        let world_from_display = display_from_world.transpose();
        self.look(world_from_display * forward, world_from_display * up);
        self.target = [0.0; 3];
    }

    /// A camera showing `view` from the default distance.
    pub fn named(view: View, display_from_world: Mat3) -> Camera {
        let mut camera = Camera {
            pitch_deg: 0.0,
            ..Camera::default()
        };
        camera.set_view(view, display_from_world);
        camera
    }
}

/// A named anatomical view: the side of the patient the camera looks from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    Anterior,
    Posterior,
    Left,
    Right,
    Superior,
    Inferior,
}

impl View {
    pub const ALL: [View; 6] = [
        View::Anterior,
        View::Posterior,
        View::Left,
        View::Right,
        View::Superior,
        View::Inferior,
    ];

    pub fn parse(name: &str) -> Option<View> {
        View::ALL
            .into_iter()
            .find(|v| v.name().eq_ignore_ascii_case(name.trim()) || v.letter().eq_ignore_ascii_case(name.trim()))
    }

    pub fn name(self) -> &'static str {
        match self {
            View::Anterior => "anterior",
            View::Posterior => "posterior",
            View::Left => "left",
            View::Right => "right",
            View::Superior => "superior",
            View::Inferior => "inferior",
        }
    }

    /// The one-letter name (A, P, L, R, S, I), also a keyboard shortcut in the viewer.
    pub fn letter(self) -> &'static str {
        match self {
            View::Anterior => "A",
            View::Posterior => "P",
            View::Left => "L",
            View::Right => "R",
            View::Superior => "S",
            View::Inferior => "I",
        }
    }

    /// View direction and image-up direction in display axes (x left, y superior, z posterior).
    pub fn display_basis(self) -> (Vec3, Vec3) {
        match self {
            View::Anterior => (Vec3::Z, Vec3::Y),
            View::Posterior => (-Vec3::Z, Vec3::Y),
            View::Left => (-Vec3::X, Vec3::Y),
            View::Right => (Vec3::X, Vec3::Y),
            View::Superior => (-Vec3::Y, Vec3::Z),
            View::Inferior => (Vec3::Y, -Vec3::Z),
        }
    }
}

impl fmt::Display for View {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The names `--view` accepts.
pub const VIEW_NAMES: &str = "anterior, posterior, left, right, superior, inferior";

/// A plane that zeroes opacity on its positive side and leaves every other property alone
/// (paper Fig. 9). `normal` in volume axes, `offset` from the centre in bounding radii.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipPlane {
    pub normal: [f32; 3],
    #[serde(default)]
    pub offset: f32,
}

impl ClipPlane {
    /// Through the volume's centre, facing along z: the plane the viewer's clip switch puts in.
    pub const CENTRE_Z: ClipPlane = ClipPlane {
        normal: [0.0, 0.0, 1.0],
        offset: 0.0,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-5
    }

    #[test]
    fn views_look_from_their_side_with_slicers_up_directions() {
        // Display axes: x left, y superior, z posterior. Image right in each view is where a
        // person standing there would see the patient's side on their right.
        let cases = [
            (View::Anterior, Vec3::Z, Vec3::Y, Vec3::X),
            (View::Posterior, -Vec3::Z, Vec3::Y, -Vec3::X),
            (View::Left, -Vec3::X, Vec3::Y, Vec3::Z),
            (View::Right, Vec3::X, Vec3::Y, -Vec3::Z),
            (View::Superior, -Vec3::Y, Vec3::Z, Vec3::X),
            (View::Inferior, Vec3::Y, -Vec3::Z, Vec3::X),
        ];
        for (view, forward, up, right) in cases {
            let c = Camera::named(view, Mat3::IDENTITY);
            let (r, d, f) = c.basis();
            assert!(close(f, forward), "{view}: forward {f}");
            assert!(close(-d, up), "{view}: up {}", -d);
            assert!(close(r, right), "{view}: right {r}");
            assert_eq!(View::parse(view.name()), Some(view));
            assert_eq!(View::parse(view.letter()), Some(view));
        }
        assert_eq!(View::parse("sideways"), None);
        // The default camera's pitch aside, the anterior view is yaw 0, pitch 0, roll 0.
        let a = Camera::named(View::Anterior, Mat3::IDENTITY);
        assert_eq!((a.yaw_deg, a.pitch_deg, a.roll_deg), (0.0, 0.0, 0.0));
    }

    #[test]
    fn basis_is_orthonormal_and_matches_the_orbit_at_any_angle() {
        for (yaw, pitch, roll) in [
            (0.0, 20.0, 0.0),
            (123.0, -45.0, 30.0),
            (10.0, 90.0, -60.0),
            (200.0, -90.0, 5.0),
        ] {
            let c = Camera {
                yaw_deg: yaw,
                pitch_deg: pitch,
                roll_deg: roll,
                ..Camera::default()
            };
            let (r, d, f) = c.basis();
            let m = Mat3::from_cols(r, d, f);
            assert!(
                (m * m.transpose()).abs_diff_eq(Mat3::IDENTITY, 1e-5),
                "{yaw} {pitch} {roll}"
            );
            // The renderer's convention: down = right × forward.
            assert!(close(r.cross(f), d));
        }
    }

    #[test]
    fn oblique_volumes_get_views_turned_by_their_residual_rotation() {
        let residual = Mat3::from_rotation_y(0.3) * Mat3::from_rotation_x(-0.2);
        for view in View::ALL {
            let c = Camera::named(view, residual);
            let (r, d, f) = c.basis();
            let (forward, up) = view.display_basis();
            assert!(close(residual * f, forward), "{view}");
            assert!(close(residual * -d, up), "{view}");
            assert!(close(residual * r, up.cross(forward)), "{view}");
        }
    }
}
