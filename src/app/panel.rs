//! The egui side panel and the viewport's mouse/keyboard handling. Everything goes through
//! egui input, so the whole UI runs headless in tests (`egui::Context::run_ui` with synthetic
//! events) exactly as in the window.

use std::collections::HashMap;
use std::path::PathBuf;

use egui::{Key, Modifiers, PointerButton, Rect, Sense, Ui};

use super::controls;
use super::orientation;
use super::tf_model::{list_presets, Function, TfEditor};
use super::widgets::{self, PointSelection};
use crate::scene::{
    Camera, ClipPlane, Environment, Projection, Scene, Toggle, TransferSource, View, VolumeSource, MAX_PITCH_DEG,
};

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

    fn panel(&mut self, ui: &mut Ui, actions: &mut Vec<Action>) {
        let s = &self.status;
        ui.heading("caustica");
        ui.label(format!(
            "{} · {:.0} ms · {} planes · {}×{}",
            s.level, s.frame_ms, s.planes, s.render_size.0, s.render_size.1
        ));
        if !s.message.is_empty() {
            ui.colored_label(egui::Color32::from_rgb(240, 190, 90), &s.message);
        }
        ui.horizontal(|ui| {
            let r = ui.button("Help (F1)");
            if r.clicked() {
                self.show_help = !self.show_help;
            }
        });
        if !self.series.is_empty() {
            egui::CollapsingHeader::new("Time")
                .default_open(true)
                .show(ui, |ui| self.time_ui(ui));
        }
        egui::CollapsingHeader::new("Camera")
            .default_open(true)
            .show(ui, |ui| self.camera_ui(ui));
        egui::CollapsingHeader::new("Light")
            .default_open(true)
            .show(ui, |ui| self.light_ui(ui));
        egui::CollapsingHeader::new("Transfer functions")
            .default_open(true)
            .show(ui, |ui| self.tf_ui(ui));
        egui::CollapsingHeader::new("Effects and quality")
            .default_open(true)
            .show(ui, |ui| self.effects_ui(ui));
        egui::CollapsingHeader::new("Clip plane").show(ui, |ui| self.clip_ui(ui));
        egui::CollapsingHeader::new("Save")
            .default_open(true)
            .show(ui, |ui| self.save_ui(ui, actions));
    }

    /// The time slider: the frame index (as `--time` takes it), "frame k of n" and its file.
    fn time_ui(&mut self, ui: &mut Ui) {
        let n = self.series.len();
        let mut frame = self.frame().min(n - 1);
        let r = ui.add(egui::Slider::new(&mut frame, 0..=n - 1).text("frame"));
        self.remember("time", &r);
        if r.changed() {
            // The render thread loads the frame; the histogram follows when it has.
            self.scene.volume.set_frame(frame);
        }
        let name = self.series[frame]
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        ui.label(format!("frame {frame} of {n}: {name}"));
    }

    fn camera_ui(&mut self, ui: &mut Ui) {
        if let Some(view) = orientation::view_buttons(ui) {
            self.set_view(view);
        }
        let c = &mut self.scene.camera;
        ui.add(egui::Slider::new(&mut c.yaw_deg, 0.0..=360.0).text("yaw °"));
        ui.add(egui::Slider::new(&mut c.pitch_deg, -MAX_PITCH_DEG..=MAX_PITCH_DEG).text("pitch °"));
        ui.add(egui::Slider::new(&mut c.roll_deg, -180.0..=180.0).text("roll °"));
        ui.horizontal(|ui| {
            ui.selectable_value(&mut c.projection, Projection::Perspective, "perspective");
            ui.selectable_value(&mut c.projection, Projection::Orthographic, "orthographic");
        });
        match c.projection {
            Projection::Perspective => {
                ui.add(
                    egui::Slider::new(
                        &mut c.distance,
                        controls::DISTANCE_RANGE[0]..=controls::DISTANCE_RANGE[1],
                    )
                    .logarithmic(true)
                    .text("distance"),
                );
                ui.add(egui::Slider::new(&mut c.fov_deg, 5.0..=120.0).text("fov °"));
            }
            Projection::Orthographic => {
                ui.add(
                    egui::Slider::new(&mut c.zoom, 0.02..=50.0)
                        .logarithmic(true)
                        .text("zoom"),
                );
            }
        }
        let r = ui.button("Reset camera (R)");
        if r.clicked() {
            self.scene.camera = self.home_camera.clone();
        }
        self.remember("reset camera", &r);
    }

    fn light_ui(&mut self, ui: &mut Ui) {
        let l = &mut self.scene.light;
        ui.horizontal(|ui| {
            let _ = widgets::hemisphere(ui, l);
            ui.vertical(|ui| {
                ui.label(format!("polar {:.0}°\nazimuth {:.0}°", l.polar_deg, l.azimuth_deg));
                ui.color_edit_button_rgb(&mut l.color);
            });
        });
        ui.add(egui::Slider::new(&mut l.softness, 0.0..=crate::scene::MAX_SOFTNESS).text("softness"));
        ui.add(egui::Slider::new(&mut l.intensity, 0.0..=10.0).text("intensity"));
    }

    fn tf_ui(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            let undo = ui.add_enabled(self.tf.can_undo(), egui::Button::new("Undo"));
            if undo.clicked() {
                self.tf.undo();
            }
            self.remember("undo", &undo);
            if ui.add_enabled(self.tf.can_redo(), egui::Button::new("Redo")).clicked() {
                self.tf.redo();
            }
            let name = self.tf.tf().name.clone().unwrap_or_else(|| "(edited)".into());
            egui::ComboBox::from_id_salt("preset")
                .selected_text(name)
                .show_ui(ui, |ui| {
                    for p in self.presets.clone() {
                        let label = p
                            .file_stem()
                            .map(|s| s.to_string_lossy().into_owned())
                            .unwrap_or_default();
                        if ui.selectable_label(false, label).clicked() {
                            if let Err(e) = self.tf.load(&p) {
                                self.status.message = e.to_string();
                            }
                        }
                    }
                });
        });
        ui.small("click: add · drag: move · right-click: delete");
        let sel = &mut self.selection;
        for f in Function::ALL {
            ui.label(f.label());
            let rect = match f {
                Function::Opacity => widgets::curve(ui, &mut self.tf, sel, f, &self.histogram),
                Function::Eta => widgets::curve(ui, &mut self.tf, sel, f, &[]),
                _ => widgets::ramp(ui, &mut self.tf, sel, f),
            };
            self.rects.insert(f.label(), rect);
        }
        if let Some((f, i)) = self.selection.selected {
            if let Some(p) = self.tf.point(f, i) {
                ui.horizontal(|ui| {
                    ui.label(format!("{} point {i}: x = {:.3}", f.label(), p[0]));
                    if f.is_ramp() {
                        let mut rgb = [p[1], p[2], p[3]];
                        if ui.color_edit_button_rgb(&mut rgb).changed() {
                            self.tf.set_color(f, i, rgb);
                        }
                    } else {
                        ui.label(format!("value {:.3}", p[1]));
                    }
                    if ui.button("Delete").clicked() {
                        self.tf.delete(f, i);
                        self.selection.selected = None;
                    }
                });
            } else {
                self.selection.selected = None;
            }
        }
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.tf_path);
            if ui.button("Save functions").clicked() {
                self.status.message = match self.tf.save(std::path::Path::new(&self.tf_path)) {
                    Ok(()) => format!("saved {}", self.tf_path),
                    Err(e) => format!("cannot save {}: {e}", self.tf_path),
                };
            }
            if ui.button("Load").clicked() {
                if let Err(e) = self.tf.load(std::path::Path::new(&self.tf_path)) {
                    self.status.message = e.to_string();
                }
            }
        });
    }

    fn effects_ui(&mut self, ui: &mut Ui) {
        let q = &mut self.scene.quality;
        ui.horizontal(|ui| {
            ui.label("refraction");
            for (t, name) in [(Toggle::Auto, "auto"), (Toggle::On, "on"), (Toggle::Off, "off")] {
                ui.selectable_value(&mut q.refraction, t, name);
            }
        });
        let r = ui.checkbox(&mut q.intensity_correction, "caustic correction (intensity law)");
        self.rects.insert("caustic correction", r.rect);
        let q = &mut self.scene.quality;
        ui.checkbox(&mut q.light_filter, "light filtering (soft light)");
        ui.checkbox(&mut q.specular, "specular");
        ui.add(
            egui::Slider::new(&mut q.sample_distance, 0.25..=8.0)
                .logarithmic(true)
                .text("sample distance"),
        );
        ui.add(egui::Slider::new(&mut self.render_scale, 0.25..=1.0).text("render scale"));
        let env = &mut self.scene.environment;
        let mut map = !matches!(env, Environment::Color { .. });
        if ui.checkbox(&mut map, "environment map").changed() {
            *env = if map {
                Environment::Studio { intensity: 1.0 }
            } else {
                Environment::Color { color: [0.0; 3] }
            };
        }
        match env {
            Environment::Studio { intensity } | Environment::Image { intensity, .. } => {
                ui.add(egui::Slider::new(intensity, 0.0..=4.0).text("environment intensity"));
            }
            Environment::Color { color } => {
                ui.horizontal(|ui| {
                    ui.label("background");
                    ui.color_edit_button_rgb(color);
                });
            }
        }
    }

    fn clip_ui(&mut self, ui: &mut Ui) {
        let mut on = self.scene.clip.is_some();
        if ui.checkbox(&mut on, "clip").changed() {
            self.scene.clip = on.then_some(ClipPlane {
                normal: [0.0, 0.0, 1.0],
                offset: 0.0,
            });
        }
        if let Some(c) = &mut self.scene.clip {
            // Orientation as two angles; the normal is kept unit length.
            let n = glam::Vec3::from(c.normal).normalize_or(glam::Vec3::Z);
            let mut azimuth = n.x.atan2(n.z).to_degrees();
            let mut elevation = n.y.clamp(-1.0, 1.0).asin().to_degrees();
            let a = ui.add(egui::Slider::new(&mut azimuth, -180.0..=180.0).text("azimuth °"));
            let e = ui.add(egui::Slider::new(&mut elevation, -90.0..=90.0).text("elevation °"));
            if a.changed() || e.changed() {
                let (az, el) = (azimuth.to_radians(), elevation.to_radians());
                c.normal = [az.sin() * el.cos(), el.sin(), az.cos() * el.cos()];
            }
            ui.add(egui::Slider::new(&mut c.offset, -1.0..=1.0).text("offset"));
        }
    }

    fn save_ui(&mut self, ui: &mut Ui, actions: &mut Vec<Action>) {
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.scene_path);
            if ui.button("Save scene (Ctrl+S)").clicked() {
                actions.push(Action::SaveScene(self.scene_path.clone().into()));
            }
        });
        ui.horizontal(|ui| {
            ui.text_edit_singleline(&mut self.screenshot_path);
        });
        ui.horizontal(|ui| {
            ui.add(
                egui::DragValue::new(&mut self.screenshot_size[0])
                    .range(1..=16384)
                    .suffix(" px"),
            );
            ui.label("×");
            ui.add(
                egui::DragValue::new(&mut self.screenshot_size[1])
                    .range(1..=16384)
                    .suffix(" px"),
            );
            let r = ui.button("Screenshot (P)");
            if r.clicked() {
                actions.push(self.screenshot_action());
            }
            self.remember("screenshot", &r);
        });
        ui.small("PNG or EXR by extension; rendered offscreen at full quality");
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
    ("Tab", "show/hide the panel"),
    ("F1, H", "this help"),
    ("Esc, Q", "quit"),
];
