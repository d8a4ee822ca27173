//! egui widgets of the panel: the curve editor (opacity, η, scattering) over the histogram, the colour
//! ramp editor (particle, medium colour) and the light hemisphere.

use egui::{Color32, Pos2, Rect, Sense, Stroke, StrokeKind, Ui, Vec2};

use super::controls;
use super::tf_model::{Function, TfEditor};
use crate::scene::Light;

/// Pick radius of a control point, in points.
const PICK_RADIUS: f32 = 8.0;

/// Which point is selected or being dragged.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PointSelection {
    pub selected: Option<(Function, usize)>,
    pub dragging: Option<(Function, usize)>,
}

fn to_screen(rect: Rect, range: [f32; 2], x: f32, y: f32) -> Pos2 {
    let t = (y - range[0]) / (range[1] - range[0]);
    Pos2::new(rect.left() + x * rect.width(), rect.bottom() - t * rect.height())
}

fn from_screen(rect: Rect, range: [f32; 2], p: Pos2) -> (f32, f32) {
    let x = (p.x - rect.left()) / rect.width();
    let t = (rect.bottom() - p.y) / rect.height();
    (x, range[0] + t * (range[1] - range[0]))
}

fn color32(rgb: [f32; 3]) -> Color32 {
    let q = |c: f32| (crate::render::linear_to_srgb(c) * 255.0 + 0.5) as u8;
    Color32::from_rgb(q(rgb[0]), q(rgb[1]), q(rgb[2]))
}

/// The nearest point of `f` within the pick radius of `pos`, using `place` for its position.
fn pick(tf: &TfEditor, f: Function, pos: Pos2, place: impl Fn([f32; 4]) -> Pos2) -> Option<usize> {
    (0..tf.len(f))
        .filter_map(|i| tf.point(f, i).map(|p| (i, place(p).distance(pos))))
        .filter(|(_, d)| *d <= PICK_RADIUS)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// Shared click/drag handling: press on a point starts a drag (one undo step), press on
/// empty space inserts a point there, right-click deletes the point under the cursor.
fn interact(
    response: &egui::Response,
    tf: &mut TfEditor,
    sel: &mut PointSelection,
    f: Function,
    place: impl Fn([f32; 4]) -> Pos2,
    insert_at: impl Fn(Pos2) -> (f32, Option<[f32; 3]>),
    move_to: impl Fn(Pos2) -> (f32, Option<f32>),
) -> bool {
    let mut changed = false;
    let pos = response.interact_pointer_pos();
    if response.secondary_clicked() {
        if let Some(i) = pos.and_then(|p| pick(tf, f, p, &place)) {
            changed |= tf.delete(f, i);
            sel.selected = None;
        }
        return changed;
    }
    if response.drag_started_by(egui::PointerButton::Primary) {
        // The drag is recognised only after the pointer moved a little: pick at the press.
        if let Some(origin) = response.ctx.input(|i| i.pointer.press_origin()).or(pos) {
            let i = match pick(tf, f, origin, &place) {
                Some(i) => {
                    tf.begin_edit();
                    i
                }
                None => {
                    let (x, v) = insert_at(origin);
                    changed = true;
                    tf.insert(f, x, v)
                }
            };
            sel.selected = Some((f, i));
            sel.dragging = Some((f, i));
        }
    } else if response.clicked() {
        if let Some(p) = pos {
            let i = pick(tf, f, p, &place).unwrap_or_else(|| {
                let (x, v) = insert_at(p);
                changed = true;
                tf.insert(f, x, v)
            });
            sel.selected = Some((f, i));
        }
    }
    if let (Some((df, i)), true, Some(p)) = (sel.dragging, response.dragged(), pos) {
        if df == f {
            let (x, y) = move_to(p);
            let before = tf.revision();
            tf.move_point(f, i, x, y);
            changed |= tf.revision() != before;
        }
    }
    if response.drag_stopped() {
        sel.dragging = None;
    }
    changed
}

/// A curve editor (opacity, η, albedo, anisotropy) over an optional log-scale histogram (bars in [0, 1]).
/// Returns the editor's rect.
pub fn curve(ui: &mut Ui, tf: &mut TfEditor, sel: &mut PointSelection, f: Function, histogram: &[f32]) -> Rect {
    let size = Vec2::new(ui.available_width().max(120.0), 90.0);
    let (rect, response) = ui.allocate_exact_size(size, Sense::click_and_drag());
    let range = match f {
        // η of real media stays far below the allowed 4; show [1, 2.5] unless a point is higher.
        Function::Eta => {
            let top = (0..tf.len(f))
                .filter_map(|i| tf.point(f, i))
                .map(|p| p[1])
                .fold(2.5, f32::max);
            [1.0, top]
        }
        _ => f.value_range(),
    };
    let place = |p: [f32; 4]| to_screen(rect, range, p[0], p[1]);
    interact(
        &response,
        tf,
        sel,
        f,
        place,
        |p| {
            let (x, y) = from_screen(rect, range, p);
            (x, Some([y; 3]))
        },
        |p| {
            let (x, y) = from_screen(rect, range, p);
            (x, Some(y))
        },
    );
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_gray(24));
    if !histogram.is_empty() {
        let w = rect.width() / histogram.len() as f32;
        for (k, h) in histogram.iter().enumerate() {
            let x0 = rect.left() + k as f32 * w;
            let bar = Rect::from_min_max(
                Pos2::new(x0, rect.bottom() - h * rect.height()),
                Pos2::new(x0 + w, rect.bottom()),
            );
            painter.rect_filled(bar, 0.0, Color32::from_gray(60));
        }
    }
    let line: Vec<Pos2> = (0..=64)
        .map(|k| {
            let x = k as f32 / 64.0;
            to_screen(rect, range, x, tf.eval(f, x)[0])
        })
        .collect();
    painter.line(line, Stroke::new(1.5, Color32::from_rgb(230, 200, 80)));
    for i in 0..tf.len(f) {
        if let Some(p) = tf.point(f, i) {
            let selected = sel.selected == Some((f, i));
            let c = if selected {
                Color32::WHITE
            } else {
                Color32::from_rgb(230, 200, 80)
            };
            painter.circle_filled(place(p), if selected { 5.0 } else { 4.0 }, c);
        }
    }
    painter.rect_stroke(rect, 2.0, Stroke::new(1.0, Color32::from_gray(90)), StrokeKind::Inside);
    rect
}

/// A colour ramp editor: the gradient, with point markers below it.
/// Returns the editor's rect.
pub fn ramp(ui: &mut Ui, tf: &mut TfEditor, sel: &mut PointSelection, f: Function) -> Rect {
    let size = Vec2::new(ui.available_width().max(120.0), 34.0);
    let (rect, response) = ui.allocate_exact_size(size, Sense::click_and_drag());
    let bar = Rect::from_min_max(rect.min, Pos2::new(rect.right(), rect.top() + 20.0));
    let marker_y = rect.bottom() - 7.0;
    let place = |p: [f32; 4]| Pos2::new(rect.left() + p[0] * rect.width(), marker_y);
    let x_of = |p: Pos2| (p.x - rect.left()) / rect.width();
    interact(&response, tf, sel, f, place, |p| (x_of(p), None), |p| (x_of(p), None));
    let painter = ui.painter_at(rect);
    let n = 48;
    for k in 0..n {
        let (x0, x1) = (k as f32 / n as f32, (k + 1) as f32 / n as f32);
        let r = Rect::from_min_max(
            Pos2::new(bar.left() + x0 * bar.width(), bar.top()),
            Pos2::new(bar.left() + x1 * bar.width() + 0.5, bar.bottom()),
        );
        painter.rect_filled(r, 0.0, color32(tf.eval(f, (x0 + x1) * 0.5)));
    }
    for i in 0..tf.len(f) {
        if let Some(p) = tf.point(f, i) {
            let selected = sel.selected == Some((f, i));
            let c = place(p);
            painter.circle_filled(c, 5.0, color32([p[1], p[2], p[3]]));
            let stroke = if selected {
                Color32::WHITE
            } else {
                Color32::from_gray(140)
            };
            painter.circle_stroke(c, 5.0, Stroke::new(if selected { 2.0 } else { 1.0 }, stroke));
        }
    }
    rect
}

/// The light hemisphere seen from the camera: the dot is where the light comes from; drag it.
pub fn hemisphere(ui: &mut Ui, light: &mut Light) -> bool {
    let side = 110.0;
    let (rect, response) = ui.allocate_exact_size(Vec2::splat(side), Sense::click_and_drag());
    let c = rect.center();
    let r = side * 0.5 - 4.0;
    let mut changed = false;
    if let Some(p) = response
        .interact_pointer_pos()
        .filter(|_| response.dragged() || response.clicked())
    {
        let before = (light.polar_deg, light.azimuth_deg);
        controls::light_from_disk(light, [(p.x - c.x) / r, (p.y - c.y) / r]);
        changed = before != (light.polar_deg, light.azimuth_deg);
    }
    let painter = ui.painter_at(rect);
    painter.circle_filled(c, r, Color32::from_gray(30));
    for polar in [30.0f32, 60.0] {
        painter.circle_stroke(
            c,
            r * polar.to_radians().sin(),
            Stroke::new(1.0, Color32::from_gray(60)),
        );
    }
    painter.circle_stroke(c, r, Stroke::new(1.0, Color32::from_gray(110)));
    let d = controls::light_to_disk(light);
    painter.circle_filled(
        Pos2::new(c.x + d[0] * r, c.y + d[1] * r),
        6.0,
        Color32::from_rgb(255, 220, 120),
    );
    changed
}
