//! The egui side panel and the viewport's mouse/keyboard handling. Everything goes through
//! egui input, so the whole UI runs headless in tests (`egui::Context::run_ui` with synthetic
//! events) exactly as in the window.

use std::collections::HashMap;
use std::path::PathBuf;

use egui::{Key, Modifiers, PointerButton, Rect, Sense, Ui};

mod sections;

use super::controls;
use super::orientation;
use super::tf_model::{list_presets, TfEditor};
use super::widgets::PointSelection;
use crate::scene::{Camera, Scene, TransferSource, View, VolumeSource};

/// What the status line shows about the frame on screen.
#[derive(Clone, Debug, Default)]
pub struct Status {
    pub level: &'static str,
    pub frame_ms: f64,
    pub planes: u32,
    pub render_size: (u32, u32),
    pub message: String,
}

/// Something the window must do after a frame of UI.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    Screenshot { path: PathBuf, width: u32, height: u32 },
    SaveScene(PathBuf),
    SaveAnimation(PathBuf),
    Quit,
}

/// The editable view: the scene (camera, light, effects, quality, clip), the transfer
/// functions under edit and the panel's own settings.
pub struct ViewState {
    pub scene: Scene,
    pub home_camera: Camera,
    pub tf: TfEditor,
    /// Log-scale histogram of the volume over the transfer-function domain, bars in [0, 1].
    pub histogram: Vec<f32>,
    pub selection: PointSelection,
    pub show_panel: bool,
    pub show_help: bool,
    /// Fraction of the viewport rendered at full quality (1 = one render pixel per pixel).
    pub render_scale: f32,
    pub status: Status,
    pub screenshot_path: String,
    pub screenshot_size: [u32; 2],
    pub scene_path: String,
    pub tf_path: String,
    pub presets: Vec<PathBuf>,
    /// The frames of a time series (empty for a single volume): the panel then shows a time
    /// slider, which selects the scene's frame.
    pub series: Vec<PathBuf>,
    /// Where the rendered image goes, in points (the window minus the panel).
    pub viewport: Rect,
    /// Rects of named widgets of the last frame (used by the headless tests to aim clicks).
    pub rects: HashMap<&'static str, Rect>,
    /// Keyframes recorded for an animation file.
    pub recorder: super::keyframes::Recorder,
    /// Patient data: the volume's residual rotation (display from world). The orientation
    /// marker shows only then; the named views use the identity otherwise.
    pub anatomy: Option<glam::Mat3>,
}

/// Histogram bars: 64 bins of the volume's values over the window, log scale.
pub fn histogram(values: &[f32], window: [f32; 2]) -> Vec<f32> {
    let mut bins = vec![0u64; 64];
    let span = (window[1] - window[0]).max(f32::MIN_POSITIVE);
    for v in values.iter().filter(|v| v.is_finite()) {
        let t = ((v - window[0]) / span).clamp(0.0, 1.0);
        bins[((t * 63.0).round() as usize).min(63)] += 1;
    }
    let max = bins.iter().copied().max().unwrap_or(0).max(1) as f32;
    bins.iter().map(|&c| (1.0 + c as f32).ln() / (1.0 + max).ln()).collect()
}

impl ViewState {
    pub fn new(scene: Scene, histogram: Vec<f32>, presets_dir: &std::path::Path) -> anyhow::Result<Self> {
        let tf = TfEditor::new(scene.transfer_functions()?);
        let series = scene.volume.series()?.map(|s| s.frames).unwrap_or_default();
        Ok(ViewState {
            home_camera: scene.camera.clone(),
            scene,
            tf,
            histogram,
            selection: PointSelection::default(),
            show_panel: true,
            show_help: false,
            render_scale: 1.0,
            status: Status::default(),
            screenshot_path: "caustica-screenshot.png".into(),
            screenshot_size: [1024, 768],
            scene_path: "caustica-view.toml".into(),
            tf_path: "caustica-transfer.json".into(),
            presets: list_presets(presets_dir),
            series,
            viewport: Rect::NOTHING,
            rects: HashMap::new(),
            recorder: Default::default(),
            anatomy: None,
        })
    }

    /// The frame of the time series shown (0 for a single volume).
    pub fn frame(&self) -> usize {
        match self.scene.volume {
            VolumeSource::Series { frame, .. } => frame,
            _ => 0,
        }
    }

    /// The scene as it should be rendered now (transfer functions inline).
    pub fn scene_for_render(&self) -> Scene {
        let mut s = self.scene.clone();
        s.transfer = TransferSource::Inline(self.tf.tf().clone());
        s
    }

    /// One frame of UI: the panel (when shown), the viewport controls, shortcuts and help.
    pub fn ui(&mut self, ui: &mut Ui) -> Vec<Action> {
        let mut actions = Vec::new();
        self.shortcuts(ui, &mut actions);
        if self.show_panel {
            // At most half the window, so a small window still shows the image.
            let max = (ui.available_width() * 0.5).clamp(120.0, 380.0);
            egui::Panel::left("caustica panel")
                .resizable(true)
                .default_size(320.0f32.min(max))
                .size_range(120.0f32.min(max)..=max)
                .show(ui, |ui| {
                    egui::ScrollArea::vertical().show(ui, |ui| self.panel(ui, &mut actions));
                });
        }
        let rect = ui.available_rect_before_wrap();
        self.viewport = rect;
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        self.viewport_input(ui, &response);
        if let Some(residual) = self.anatomy {
            orientation::paint_marker(ui, rect, &self.scene.camera, residual);
        }
        if self.show_help {
            self.help(ui);
        }
        actions
    }

    fn remember(&mut self, name: &'static str, response: &egui::Response) {
        self.rects.insert(name, response.rect);
    }

    fn viewport_input(&mut self, ui: &Ui, response: &egui::Response) {
        let d = response.drag_delta();
        if d != egui::Vec2::ZERO {
            let pan = response.dragged_by(PointerButton::Secondary)
                || response.dragged_by(PointerButton::Middle)
                || (response.dragged_by(PointerButton::Primary) && ui.input(|i| i.modifiers.shift));
            if pan {
                controls::pan(&mut self.scene.camera, d.x, d.y, response.rect.height());
            } else if response.dragged_by(PointerButton::Primary) {
                controls::orbit(&mut self.scene.camera, d.x, d.y);
            }
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                // egui reports ~50 points per wheel notch.
                controls::zoom(&mut self.scene.camera, scroll / 50.0);
            }
        }
    }

    fn shortcuts(&mut self, ui: &Ui, actions: &mut Vec<Action>) {
        if ui.ctx().egui_wants_keyboard_input() {
            return;
        }
        let pressed = |key: Key, m: Modifiers| ui.input_mut(|i| i.consume_key(m, key));
        let none = Modifiers::NONE;
        if pressed(Key::Z, Modifiers::COMMAND | Modifiers::SHIFT) || pressed(Key::Y, Modifiers::COMMAND) {
            self.tf.redo();
        }
        if pressed(Key::Z, Modifiers::COMMAND) {
            self.tf.undo();
        }
        if pressed(Key::S, Modifiers::COMMAND) {
            actions.push(Action::SaveScene(self.scene_path.clone().into()));
        }
        if pressed(Key::F1, none) || pressed(Key::H, none) {
            self.show_help = !self.show_help;
        }
        if pressed(Key::Tab, none) {
            self.show_panel = !self.show_panel;
        }
        for (view, key) in View::ALL.into_iter().zip(orientation::VIEW_KEYS) {
            if pressed(key, none) {
                self.set_view(view);
            }
        }
        if pressed(Key::R, none) {
            self.scene.camera = self.home_camera.clone();
        }
        if !self.series.is_empty() {
            let frame = self.frame();
            if pressed(Key::PageDown, none) && frame + 1 < self.series.len() {
                self.scene.volume.set_frame(frame + 1);
            }
            if pressed(Key::PageUp, none) && frame > 0 {
                self.scene.volume.set_frame(frame - 1);
            }
        }
        if pressed(Key::K, none) {
            self.record_keyframe();
        }
        if pressed(Key::P, none) || pressed(Key::F12, none) {
            actions.push(self.screenshot_action());
        }
        if pressed(Key::Escape, none) || pressed(Key::Q, none) {
            actions.push(Action::Quit);
        }
        if pressed(Key::Delete, none) {
            if let Some((f, i)) = self.selection.selected.take() {
                self.tf.delete(f, i);
            }
        }
        let step = 5.0 / controls::ORBIT_DEG_PER_PIXEL;
        for (key, dx, dy) in [
            (Key::ArrowLeft, -step, 0.0),
            (Key::ArrowRight, step, 0.0),
            (Key::ArrowUp, 0.0, -step),
            (Key::ArrowDown, 0.0, step),
        ] {
            if pressed(key, none) {
                controls::orbit(&mut self.scene.camera, dx, dy);
            }
        }
        if pressed(Key::Plus, none) || pressed(Key::Equals, none) {
            controls::zoom(&mut self.scene.camera, 1.0);
        }
        if pressed(Key::Minus, none) {
            controls::zoom(&mut self.scene.camera, -1.0);
        }
    }

    /// Turns the camera to a named view (of the patient for patient data, of the volume's
    /// axes otherwise).
    pub fn set_view(&mut self, view: View) {
        let residual = self.anatomy.unwrap_or(glam::Mat3::IDENTITY);
        self.scene.camera.set_view(view, residual);
    }

    fn screenshot_action(&self) -> Action {
        Action::Screenshot {
            path: self.screenshot_path.clone().into(),
            width: self.screenshot_size[0],
            height: self.screenshot_size[1],
        }
    }

    fn help(&mut self, ui: &Ui) {
        let mut open = true;
        egui::Window::new("Help")
            .open(&mut open)
            .collapsible(false)
            .show(ui.ctx(), |ui| {
                egui::Grid::new("keys").striped(true).show(ui, |ui| {
                    for (k, what) in HELP {
                        ui.monospace(*k);
                        ui.label(*what);
                        ui.end_row();
                    }
                });
            });
        self.show_help &= open;
    }
}

/// The keyboard and mouse reference shown by F1.
pub const HELP: &[(&str, &str)] = &[
    ("left drag", "orbit"),
    ("right/middle drag, shift+left drag", "pan"),
    ("wheel, + / -", "zoom"),
    ("arrows", "orbit by 5°"),
    ("R", "reset camera"),
    ("1 … 6", "anterior, posterior, left, right, superior, inferior view"),
    ("Page Down / Page Up", "time series: next / previous frame"),
    ("Ctrl+Z / Ctrl+Y, Ctrl+Shift+Z", "undo / redo transfer-function edits"),
    ("Delete", "delete the selected control point"),
    ("P, F12", "screenshot (full quality, offscreen)"),
    ("Ctrl+S", "save scene"),
    ("K", "record the view as an animation keyframe"),
    ("Tab", "show/hide the panel"),
    ("F1, H", "this help"),
    ("Esc, Q", "quit"),
];
