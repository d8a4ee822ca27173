//! The side panel's sections: status, time, camera, light, transfer functions, effects and
//! quality, clip plane, saving.

use egui::Ui;

use super::super::controls;
use super::super::orientation;
use super::super::tf_model::Function;
use super::super::widgets;
use super::{Action, ViewState};
use crate::scene::{
    ClipPlane, Environment, LightTransport, MultipleScattering, Projection, Toggle, MAX_BEAMS_PER_TEXEL, MAX_PITCH_DEG,
    MIN_BEAMS_PER_TEXEL,
};

impl ViewState {
    /// The side panel: status, help, then one collapsible section per part of the scene.
    pub(super) fn panel(&mut self, ui: &mut Ui, actions: &mut Vec<Action>) {
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
        egui::CollapsingHeader::new("Animation")
            .default_open(true)
            .show(ui, |ui| self.animation_ui(ui, actions));
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
                Function::Eta | Function::Albedo | Function::Anisotropy => {
                    widgets::curve(ui, &mut self.tf, sel, f, &[])
                }
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
        // The light's transport and the knob each has: the beams' grid (their caustics come
        // from their density, and the light pass's time follows their count) or the backward
        // scheme's intensity law.
        // The spread mode of multiple scattering rides on the beams (`Scene::validate`).
        let spread = q.multiple_scattering == MultipleScattering::Spread;
        ui.horizontal(|ui| {
            ui.label("light");
            for (t, name, key) in [
                (LightTransport::Beams, "beams", "transport beams"),
                (LightTransport::Backward, "backward", "transport backward"),
            ] {
                let enabled = t == LightTransport::Beams || !spread;
                let r = ui
                    .add_enabled(enabled, egui::Button::selectable(q.light_transport == t, name))
                    .on_disabled_hover_text("the spread mode of multiple scattering needs the beams");
                if r.clicked() {
                    q.light_transport = t;
                }
                self.rects.insert(key, r.rect);
            }
        });
        let beams = q.light_transport == LightTransport::Beams;
        let r = ui.add_enabled(
            beams,
            egui::Slider::new(&mut q.beams_per_texel, MIN_BEAMS_PER_TEXEL..=MAX_BEAMS_PER_TEXEL)
                .logarithmic(true)
                .text("beams per pixel"),
        );
        let r = r.on_hover_text(
            "per pixel and axis: ½ traces a quarter of the beams, a faster light pass with coarser caustics",
        );
        self.rects.insert("beams per pixel", r.rect);
        let r = ui
            .add_enabled(
                !beams,
                egui::Checkbox::new(&mut q.intensity_correction, "caustic correction (intensity law)"),
            )
            .on_disabled_hover_text("beams make their caustics from their density");
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
            self.scene.clip = on.then_some(ClipPlane::CENTRE_Z);
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
