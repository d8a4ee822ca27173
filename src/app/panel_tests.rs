//! The panel and viewport controls run headless: `egui::Context::run_ui` with synthetic
//! pointer and key events, exactly the code the window runs.

use egui::{Event, Key, Modifiers, PointerButton, Pos2, RawInput, Rect, Vec2};

use super::panel::{Action, ViewState};
use super::tf_model::Function;
use crate::scene::{builtin, LightTransport, MultipleScattering, VolumeSource, MIN_BEAMS_PER_TEXEL};

struct Harness {
    ctx: egui::Context,
    state: ViewState,
    screen: Vec2,
}

impl Harness {
    fn new() -> Self {
        Self::with_screen(Vec2::new(1024.0, 768.0))
    }

    /// A taller screen shows the whole panel without scrolling.
    fn with_screen(screen: Vec2) -> Self {
        Self::with_scene(builtin("ball-lens").unwrap().scene, screen)
    }

    fn with_scene(scene: crate::scene::Scene, screen: Vec2) -> Self {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("transfer_functions");
        let histogram = super::panel::histogram(&[0.0, 0.0, 0.5, 1.0], [0.0, 1.0]);
        let mut h = Harness {
            ctx: egui::Context::default(),
            state: ViewState::new(scene, histogram, &dir).unwrap(),
            screen,
        };
        // Settle the layout (egui sizes some widgets on the second pass).
        h.frame(vec![]);
        h.frame(vec![]);
        h
    }

    fn frame(&mut self, events: Vec<Event>) -> Vec<Action> {
        let input = RawInput {
            screen_rect: Some(Rect::from_min_size(Pos2::ZERO, self.screen)),
            events,
            ..Default::default()
        };
        let state = &mut self.state;
        let mut actions = Vec::new();
        let out = self.ctx.run_ui(input, |ui| actions.extend(state.ui(ui)));
        assert!(
            !self.state.show_panel || !out.shapes.is_empty(),
            "the panel paints something"
        );
        actions
    }

    fn button(pos: Pos2, button: PointerButton, pressed: bool) -> Event {
        Event::PointerButton {
            pos,
            button,
            pressed,
            modifiers: Modifiers::NONE,
        }
    }

    fn click(&mut self, pos: Pos2, button: PointerButton) -> Vec<Action> {
        let mut a = self.frame(vec![Event::PointerMoved(pos), Self::button(pos, button, true)]);
        a.extend(self.frame(vec![Self::button(pos, button, false)]));
        a.extend(self.frame(vec![]));
        a
    }

    fn drag(&mut self, from: Pos2, to: Pos2) {
        self.frame(vec![
            Event::PointerMoved(from),
            Self::button(from, PointerButton::Primary, true),
        ]);
        for k in 1..=4 {
            self.frame(vec![Event::PointerMoved(from + (to - from) * (k as f32 / 4.0))]);
        }
        self.frame(vec![Self::button(to, PointerButton::Primary, false)]);
    }

    fn key(&mut self, key: Key, modifiers: Modifiers) -> Vec<Action> {
        let ev = |pressed| Event::Key {
            key,
            physical_key: None,
            pressed,
            repeat: false,
            modifiers,
        };
        self.frame(vec![ev(true), ev(false)])
    }

    fn rect(&self, name: &str) -> Rect {
        *self
            .state
            .rects
            .get(name)
            .unwrap_or_else(|| panic!("no widget '{name}' was laid out"))
    }
}

#[test]
fn viewport_is_beside_the_panel_and_fills_the_window_without_it() {
    let mut h = Harness::new();
    let vp = h.state.viewport;
    assert!(vp.min.x > 200.0 && vp.max.x == 1024.0 && vp.height() == 768.0, "{vp:?}");
    h.key(Key::Tab, Modifiers::NONE);
    h.frame(vec![]);
    assert!(!h.state.show_panel);
    assert_eq!(
        h.state.viewport,
        Rect::from_min_size(Pos2::ZERO, Vec2::new(1024.0, 768.0))
    );
}

#[test]
fn clicking_the_opacity_curve_adds_a_point_and_undo_removes_it() {
    let mut h = Harness::new();
    let before = h.state.tf.tf().clone();
    let n = h.state.tf.len(Function::Opacity);
    let r = h.rect("opacity");
    // An empty spot: half way across, near the top (the ball-lens curve is low there).
    let spot = Pos2::new(r.left() + 0.37 * r.width(), r.top() + 0.1 * r.height());
    h.click(spot, PointerButton::Primary);
    assert_eq!(h.state.tf.len(Function::Opacity), n + 1);
    let (f, i) = h.state.selection.selected.expect("the new point is selected");
    assert_eq!(f, Function::Opacity);
    let p = h.state.tf.point(f, i).unwrap();
    assert!((p[0] - 0.37).abs() < 0.02 && (p[1] - 0.9).abs() < 0.03, "{p:?}");
    assert!(
        h.state.scene_for_render() != h.state.scene,
        "the edit reaches the rendered scene"
    );

    // Drag the point down to the bottom: one undo step for the whole drag.
    let at = Pos2::new(r.left() + p[0] * r.width(), r.top() + (1.0 - p[1]) * r.height());
    h.drag(at, Pos2::new(at.x, r.bottom() + 40.0));
    let moved = h.state.tf.point(Function::Opacity, i).unwrap();
    assert_eq!(moved[1], 0.0, "dragging past the bottom clamps to 0");

    h.key(Key::Z, Modifiers::COMMAND);
    assert!((h.state.tf.point(Function::Opacity, i).unwrap()[1] - p[1]).abs() < 1e-6);
    h.key(Key::Z, Modifiers::COMMAND);
    assert_eq!(h.state.tf.tf(), &before);
    h.key(Key::Y, Modifiers::COMMAND);
    assert_eq!(h.state.tf.len(Function::Opacity), n + 1);

    // Right-click on the point deletes it.
    let p = h.state.tf.point(Function::Opacity, i).unwrap();
    let at = Pos2::new(r.left() + p[0] * r.width(), r.top() + (1.0 - p[1]) * r.height());
    h.click(at, PointerButton::Secondary);
    assert_eq!(h.state.tf.len(Function::Opacity), n);
}

#[test]
fn colour_ramp_click_inserts_without_changing_the_gradient() {
    // Tall enough that the medium ramp, low in the panel, is on screen.
    let mut h = Harness::with_screen(Vec2::new(1024.0, 1000.0));
    let r = h.rect("medium colour");
    let n = h.state.tf.len(Function::Medium);
    let before = h.state.tf.eval(Function::Medium, 0.62);
    h.click(
        Pos2::new(r.left() + 0.62 * r.width(), r.center().y),
        PointerButton::Primary,
    );
    assert_eq!(h.state.tf.len(Function::Medium), n + 1);
    let after = h.state.tf.eval(Function::Medium, 0.62);
    for k in 0..3 {
        assert!((after[k] - before[k]).abs() < 1e-5);
    }
}

#[test]
fn viewport_drag_orbits_and_wheel_zooms() {
    let mut h = Harness::new();
    let c0 = h.state.scene.camera.clone();
    let vp = h.state.viewport;
    h.drag(vp.center(), vp.center() + Vec2::new(50.0, 20.0));
    let c1 = h.state.scene.camera.clone();
    assert!(
        (c1.yaw_deg - (c0.yaw_deg - 50.0 * 0.4).rem_euclid(360.0)).abs() < 1e-3,
        "{c1:?}"
    );
    assert!((c1.pitch_deg - (c0.pitch_deg + 8.0)).abs() < 1e-3);
    h.frame(vec![
        Event::PointerMoved(vp.center()),
        Event::MouseWheel {
            unit: egui::MouseWheelUnit::Line,
            delta: Vec2::new(0.0, 3.0),
            phase: egui::TouchPhase::Move,
            modifiers: Modifiers::NONE,
        },
    ]);
    for _ in 0..30 {
        h.frame(vec![]);
    }
    assert!(h.state.scene.camera.distance < c1.distance, "wheel up moves closer");
    h.key(Key::R, Modifiers::NONE);
    assert_eq!(h.state.scene.camera, c0, "R resets the camera");
}

#[test]
fn checkbox_screenshot_and_save_shortcuts() {
    let mut h = Harness::with_screen(Vec2::new(1024.0, 2000.0));
    // The intensity law is the backward transport's: with the beams (the default) its
    // checkbox is off limits, with the backward transport it toggles.
    let on = h.state.scene.quality.intensity_correction;
    let checkbox = h.rect("caustic correction").left_center() + Vec2::new(8.0, 0.0);
    h.click(checkbox, PointerButton::Primary);
    assert_eq!(h.state.scene.quality.intensity_correction, on, "no effect with beams");
    h.click(h.rect("transport backward").center(), PointerButton::Primary);
    assert_eq!(h.state.scene.quality.light_transport, LightTransport::Backward);
    h.frame(vec![]);
    h.click(checkbox, PointerButton::Primary);
    assert_eq!(h.state.scene.quality.intensity_correction, !on);
    h.click(h.rect("transport beams").center(), PointerButton::Primary);
    assert_eq!(h.state.scene.quality.light_transport, LightTransport::Beams);
    let a = h.click(h.rect("screenshot").center(), PointerButton::Primary);
    assert!(
        matches!(
            a.as_slice(),
            [Action::Screenshot {
                width: 1024,
                height: 768,
                ..
            }]
        ),
        "{a:?}"
    );
    assert!(matches!(
        h.key(Key::P, Modifiers::NONE).as_slice(),
        [Action::Screenshot { .. }]
    ));
    assert!(matches!(
        h.key(Key::S, Modifiers::COMMAND).as_slice(),
        [Action::SaveScene(_)]
    ));
    h.key(Key::F1, Modifiers::NONE);
    assert!(h.state.show_help);
    assert_eq!(h.key(Key::Escape, Modifiers::NONE), vec![Action::Quit]);
}

#[test]
fn the_beams_slider_sets_the_light_grid_and_rests_with_the_backward_transport() {
    let mut h = Harness::with_screen(Vec2::new(1024.0, 2000.0));
    assert_eq!(h.state.scene.quality.beams_per_texel, 1.0);
    // The slider's left end is the fewest beams (logarithmic: a few pixels in, still under ½).
    let left = h.rect("beams per pixel").left_center() + Vec2::new(3.0, 0.0);
    h.click(left, PointerButton::Primary);
    let b = h.state.scene.quality.beams_per_texel;
    assert!((MIN_BEAMS_PER_TEXEL..0.5).contains(&b), "{b}");
    h.click(h.rect("transport backward").center(), PointerButton::Primary);
    h.frame(vec![]);
    let right = h.rect("beams per pixel").left_center() + Vec2::new(60.0, 0.0);
    h.click(right, PointerButton::Primary);
    assert_eq!(
        h.state.scene.quality.beams_per_texel, b,
        "the backward transport has no beams"
    );
    // A scene that asks for the spread mode of multiple scattering keeps the beams it needs.
    let mut scene = builtin("ball-lens").unwrap().scene;
    scene.quality.multiple_scattering = MultipleScattering::Spread;
    let mut h = Harness::with_scene(scene, Vec2::new(1024.0, 2000.0));
    h.click(h.rect("transport backward").center(), PointerButton::Primary);
    assert_eq!(h.state.scene.quality.light_transport, LightTransport::Beams);
}

#[test]
fn histogram_is_log_scaled() {
    let mut values = vec![0.0f32; 1000];
    values.push(1.0);
    let h = super::panel::histogram(&values, [0.0, 1.0]);
    assert_eq!(h.len(), 64);
    assert_eq!(h[0], 1.0);
    // One sample against a thousand: ln 2 / ln 1001 ≈ 0.1, far above the linear 0.001.
    assert!((h[63] - 2f32.ln() / 1001f32.ln()).abs() < 1e-6);
    assert!(h[1..63].iter().all(|v| *v == 0.0));
}

/// The time slider is there only for a time series; moving it selects the scene's frame,
/// which the rendered (and saved) scene carries.
#[test]
fn time_slider_appears_for_a_series_and_selects_the_frame() {
    let screen = Vec2::new(1024.0, 2000.0);
    let h = Harness::with_scene(builtin("ball-lens").unwrap().scene, screen);
    assert!(h.state.series.is_empty());
    assert!(
        !h.state.rects.contains_key("time"),
        "no time slider for a single volume"
    );

    let mut scene = builtin("ball-lens").unwrap().scene;
    // A list of files: the panel only needs their names, the render thread loads them.
    scene.volume = VolumeSource::Series {
        files: ["a.nrrd", "b.nrrd", "c.nrrd"].map(std::path::PathBuf::from).to_vec(),
        pattern: None,
        frame: 0,
    };
    let mut h = Harness::with_scene(scene, screen);
    assert_eq!(h.state.series.len(), 3);
    let r = h.rect("time");
    let slider_width = h.ctx.global_style().spacing.slider_width;
    // The slider's right end is the last frame, its left end the first.
    h.click(
        Pos2::new(r.left() + slider_width - 1.0, r.center().y),
        PointerButton::Primary,
    );
    assert_eq!(h.state.frame(), 2);
    let frame_of = |s: &crate::scene::Scene| match s.volume {
        VolumeSource::Series { frame, .. } => frame,
        _ => usize::MAX,
    };
    assert_eq!(frame_of(&h.state.scene_for_render()), 2);
    h.click(Pos2::new(r.left() + 1.0, r.center().y), PointerButton::Primary);
    assert_eq!(frame_of(&h.state.scene_for_render()), 0);
    // Page Down / Page Up step through the frames and stop at the ends.
    h.key(Key::PageUp, Modifiers::NONE);
    assert_eq!(h.state.frame(), 0);
    for expected in [1, 2, 2] {
        h.key(Key::PageDown, Modifiers::NONE);
        assert_eq!(h.state.frame(), expected);
    }
    h.key(Key::PageUp, Modifiers::NONE);
    assert_eq!(h.state.frame(), 1);
}

/// `K` records the view; the Save animation button asks the window to save; the saved file
/// is an animation whose first and last frames are the two recorded views.
#[test]
fn keyframes_recorded_with_k_save_an_animation_through_the_views() {
    let mut h = Harness::with_screen(Vec2::new(1024.0, 2400.0));
    h.key(Key::K, Modifiers::NONE);
    let first = h.state.scene_for_render();
    h.key(Key::ArrowRight, Modifiers::NONE);
    h.key(Key::ArrowUp, Modifiers::NONE);
    h.key(Key::K, Modifiers::NONE);
    let second = h.state.scene_for_render();
    assert_ne!(first.camera, second.camera, "the arrows orbit between the keyframes");
    assert_eq!(h.state.recorder.keyframes, vec![first.clone(), second.clone()]);
    h.state.recorder.frames_between = 3;
    h.frame(vec![]);
    let path = std::env::temp_dir().join(format!("caustica-keyframes-{}.toml", std::process::id()));
    h.state.recorder.path = path.display().to_string();
    let actions = h.click(h.rect("save animation").center(), PointerButton::Primary);
    assert_eq!(actions, vec![Action::SaveAnimation(path.clone())]);
    let message = h.state.save_animation(&path);
    assert!(message.starts_with("saved"), "{message}");
    let animation = crate::animate::Animation::load(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    assert_eq!(animation.frames, 4);
    let specs = animation.frame_specs().unwrap();
    assert_eq!(specs[0].scene, first);
    assert_eq!(specs[3].scene, second);
    assert_ne!(specs[1].scene.camera, first.camera);
}

#[test]
fn number_keys_turn_to_the_named_views_and_patient_data_gets_the_marker() {
    use crate::scene::{Camera, View};
    let mut h = Harness::new();
    h.state.show_panel = false;
    // Without a patient frame the views follow the volume's axes and no marker is drawn.
    h.key(Key::Num3, Modifiers::NONE);
    assert_eq!(
        h.state.scene.camera.yaw_deg,
        Camera::named(View::Left, glam::Mat3::IDENTITY).yaw_deg
    );
    let count_shapes = |h: &mut Harness| {
        let input = RawInput {
            screen_rect: Some(Rect::from_min_size(Pos2::ZERO, h.screen)),
            ..Default::default()
        };
        let state = &mut h.state;
        h.ctx.run_ui(input, |ui| drop(state.ui(ui))).shapes.len()
    };
    let plain = count_shapes(&mut h);
    // Patient data, oblique by a small rotation: key 5 looks from above along the body axis.
    let residual = glam::Mat3::from_rotation_y(0.2);
    h.state.anatomy = Some(residual);
    h.key(Key::Num5, Modifiers::NONE);
    let (_, _, forward) = h.state.scene.camera.basis();
    assert!((residual * forward - glam::Vec3::NEG_Y).length() < 1e-5, "{forward}");
    assert!(count_shapes(&mut h) > plain, "the orientation marker paints");
}
