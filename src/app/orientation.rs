//! Anatomical orientation in the viewer: the six named views (buttons and keys 1–6) and the
//! orientation marker, a small axis cross in the viewport's corner whose arms point to the
//! patient's left, posterior and superior side (L, P, S; R, A, I at the other ends) as the
//! camera sees them. Shown for patient data only (volumes with a patient frame).

use egui::{Align2, Color32, FontId, Pos2, Rect, Stroke, Ui, Vec2};
use glam::{Mat3, Vec3};

use crate::scene::{Camera, View};

/// Radius of the marker in points.
const MARKER_RADIUS: f32 = 30.0;

/// The key of each view, in [`View::ALL`] order.
pub const VIEW_KEYS: [egui::Key; 6] = [
    egui::Key::Num1,
    egui::Key::Num2,
    egui::Key::Num3,
    egui::Key::Num4,
    egui::Key::Num5,
    egui::Key::Num6,
];

/// One arm of the marker: its letter, where it points on screen (x right, y down, unit for
/// an arm in the image plane) and whether it points towards the viewer.
#[derive(Clone, Debug, PartialEq)]
pub struct Arm {
    pub letter: char,
    pub screen: [f32; 2],
    pub towards_viewer: bool,
}

/// The six arms for `camera` and the volume's residual rotation ([`Mat3`] display from
/// world; see [`crate::volume::PatientFrame::display_from_world`]).
pub fn arms(camera: &Camera, display_from_world: Mat3) -> Vec<Arm> {
    let (right, down, forward) = camera.basis();
    let world_from_display = display_from_world.transpose();
    // Display axes: x left, y superior, z posterior.
    [
        ('L', Vec3::X),
        ('S', Vec3::Y),
        ('P', Vec3::Z),
        ('R', -Vec3::X),
        ('I', -Vec3::Y),
        ('A', -Vec3::Z),
    ]
    .into_iter()
    .map(|(letter, d)| {
        let w = world_from_display * d;
        Arm {
            letter,
            screen: [right.dot(w), down.dot(w)],
            towards_viewer: forward.dot(w) < 0.0,
        }
    })
    .collect()
}

/// Draws the marker in the lower left corner of `viewport`.
pub fn paint_marker(ui: &Ui, viewport: Rect, camera: &Camera, display_from_world: Mat3) {
    // Room for the letters outside the arms.
    let margin = MARKER_RADIUS + 34.0;
    let centre = Pos2::new(viewport.left() + margin, viewport.bottom() - margin);
    let painter = ui.painter_at(viewport);
    painter.circle_filled(centre, MARKER_RADIUS + 10.0, Color32::from_black_alpha(110));
    let mut arms = arms(camera, display_from_world);
    // Far arms first, so the near ones are drawn over them.
    arms.sort_by_key(|a| a.towards_viewer);
    for arm in arms {
        let tip = centre + Vec2::new(arm.screen[0], arm.screen[1]) * MARKER_RADIUS;
        let (stroke, text) = if arm.towards_viewer {
            (Color32::from_rgb(250, 210, 120), Color32::WHITE)
        } else {
            (Color32::from_gray(120), Color32::from_gray(170))
        };
        if "LPS".contains(arm.letter) {
            painter.line_segment([centre, tip], Stroke::new(2.0, stroke));
        }
        // A letter along the view axis would sit on the centre: only the one in front shows.
        let length = Vec2::new(arm.screen[0], arm.screen[1]).length();
        if length > 0.25 || arm.towards_viewer {
            let at = centre + Vec2::new(arm.screen[0], arm.screen[1]) * (MARKER_RADIUS + 8.0);
            painter.text(at, Align2::CENTER_CENTER, arm.letter, FontId::proportional(13.0), text);
        }
    }
}

/// Buttons for the six views; returns the one clicked.
pub fn view_buttons(ui: &mut Ui) -> Option<View> {
    let mut chosen = None;
    ui.horizontal(|ui| {
        for (k, view) in View::ALL.into_iter().enumerate() {
            let r = ui
                .button(view.letter())
                .on_hover_text(format!("{} view (key {})", view.name(), k + 1));
            if r.clicked() {
                chosen = Some(view);
            }
        }
    });
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm(arms: &[Arm], letter: char) -> &Arm {
        arms.iter().find(|a| a.letter == letter).expect("arm")
    }

    #[test]
    fn anterior_view_shows_left_to_the_right_and_superior_up() {
        let a = arms(&Camera::named(View::Anterior, Mat3::IDENTITY), Mat3::IDENTITY);
        let close = |v: [f32; 2], w: [f32; 2]| (v[0] - w[0]).abs() < 1e-5 && (v[1] - w[1]).abs() < 1e-5;
        assert!(close(arm(&a, 'L').screen, [1.0, 0.0]));
        assert!(close(arm(&a, 'S').screen, [0.0, -1.0]));
        assert!(close(arm(&a, 'R').screen, [-1.0, 0.0]));
        // Looking from the front: anterior points at the viewer, posterior away.
        assert!(arm(&a, 'A').towards_viewer && !arm(&a, 'P').towards_viewer);
        // From the left side, anterior is on the left of the image.
        let l = arms(&Camera::named(View::Left, Mat3::IDENTITY), Mat3::IDENTITY);
        assert!(arm(&l, 'A').screen[0] < -0.99 && arm(&l, 'L').towards_viewer);
        // Seen from above, posterior is up.
        let s = arms(&Camera::named(View::Superior, Mat3::IDENTITY), Mat3::IDENTITY);
        assert!(arm(&s, 'P').screen[1] < -0.99 && arm(&s, 'S').towards_viewer);
    }

    #[test]
    fn the_marker_follows_the_residual_rotation_of_oblique_data() {
        // Whatever the obliquity, a named view of it puts the letters where they belong.
        let residual = Mat3::from_rotation_z(0.4) * Mat3::from_rotation_x(0.2);
        let a = arms(&Camera::named(View::Anterior, residual), residual);
        assert!((arm(&a, 'L').screen[0] - 1.0).abs() < 1e-5);
        assert!((arm(&a, 'S').screen[1] + 1.0).abs() < 1e-5);
    }
}
