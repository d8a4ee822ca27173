//! The viewer's animation recorder: the current view recorded as a keyframe (`K` or the
//! button), and the keyframes saved as an animation file that `caustica animate` renders.

use std::path::Path;

use egui::Ui;

use super::panel::{Action, ViewState};
use crate::animate::keyframes::from_keyframes;
use crate::scene::Scene;

/// Keyframes recorded so far and the settings of the animation file.
pub struct Recorder {
    /// The recorded views (transfer functions inline), in order.
    pub keyframes: Vec<Scene>,
    /// Frames from one keyframe to the next (each keyframe falls on a frame).
    pub frames_between: u32,
    pub fps: f64,
    pub path: String,
}

impl Default for Recorder {
    fn default() -> Self {
        Recorder {
            keyframes: Vec::new(),
            frames_between: 30,
            fps: 30.0,
            path: "caustica-animation.toml".into(),
        }
    }
}

impl ViewState {
    /// Records the view as it is rendered now.
    pub fn record_keyframe(&mut self) {
        self.recorder.keyframes.push(self.scene_for_render());
        self.status.message = format!("keyframe {} recorded", self.recorder.keyframes.len());
    }

    /// Saves the keyframes as an animation of the screenshot size; returns the status line.
    pub fn save_animation(&self, path: &Path) -> String {
        let r = &self.recorder;
        let size = self.screenshot_size;
        let saved = from_keyframes(&r.keyframes, r.frames_between, r.fps, size)
            .and_then(|(animation, notes)| animation.save(path).map(|()| (animation, notes)));
        match saved {
            Ok((animation, notes)) => {
                let mut message = format!(
                    "saved {} ({} frames of {}×{}); render it with `caustica animate {} -o DIR`",
                    path.display(),
                    animation.frames,
                    size[0],
                    size[1],
                    path.display()
                );
                for note in notes {
                    message.push('\n');
                    message.push_str(&note);
                }
                message
            }
            Err(e) => format!("cannot save {}: {e}", path.display()),
        }
    }

    /// The panel's "Animation" section.
    pub(super) fn animation_ui(&mut self, ui: &mut Ui, actions: &mut Vec<Action>) {
        let n = self.recorder.keyframes.len();
        ui.label(format!("{n} keyframe{}", if n == 1 { "" } else { "s" }));
        ui.horizontal(|ui| {
            let add = ui.button("Add keyframe (K)");
            if add.clicked() {
                self.record_keyframe();
            }
            self.rects.insert("add keyframe", add.rect);
            if ui.add_enabled(n > 0, egui::Button::new("Remove last")).clicked() {
                self.recorder.keyframes.pop();
            }
            if ui.add_enabled(n > 0, egui::Button::new("Clear")).clicked() {
                self.recorder.keyframes.clear();
            }
        });
        let r = &mut self.recorder;
        ui.add(
            egui::DragValue::new(&mut r.frames_between)
                .range(1..=100_000)
                .prefix("frames between keyframes: "),
        );
        ui.add(egui::DragValue::new(&mut r.fps).range(1.0..=240.0).suffix(" fps"));
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.recorder.path);
            let save = ui.add_enabled(n >= 2, egui::Button::new("Save animation"));
            if save.clicked() {
                actions.push(Action::SaveAnimation(self.recorder.path.clone().into()));
            }
            self.rects.insert("save animation", save.rect);
        });
        ui.small("frame size: the screenshot size; render with `caustica animate FILE -o DIR`");
    }
}
