//! The transfer-function editing model behind the panel: insert, move and delete control
//! points with clamping, undo/redo, presets and JSON. Plain data, no window, unit-tested.

use std::path::Path;

use crate::transfer::{Curve, TransferError, TransferFunctions, ANISOTROPY_RANGE, ETA_RANGE};

/// Which function an edit applies to: the four of every scene, and the two optional
/// scattering curves (albedo, anisotropy), which stay absent until a point is edited.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Function {
    Opacity,
    Color,
    Eta,
    Medium,
    Albedo,
    Anisotropy,
}

/// What an absent scattering curve holds: 0 everywhere (no scattering, isotropic).
const ABSENT: [[f32; 2]; 1] = [[0.0, 0.0]];

impl Function {
    pub const ALL: [Function; 6] = [
        Function::Opacity,
        Function::Color,
        Function::Eta,
        Function::Medium,
        Function::Albedo,
        Function::Anisotropy,
    ];

    /// The allowed range of the value channels.
    pub fn value_range(self) -> [f32; 2] {
        match self {
            Function::Eta => ETA_RANGE,
            Function::Anisotropy => ANISOTROPY_RANGE,
            _ => [0.0, 1.0],
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Function::Opacity => "opacity",
            Function::Color => "particle colour",
            Function::Eta => "refractive index",
            Function::Medium => "medium colour",
            Function::Albedo => "scattering albedo",
            Function::Anisotropy => "anisotropy g",
        }
    }

    pub fn is_ramp(self) -> bool {
        matches!(self, Function::Color | Function::Medium)
    }
}

/// Most edits kept for undo; older ones are dropped.
pub const UNDO_DEPTH: usize = 200;

/// Transfer functions under edit with an undo history. A drag is one undo step: call
/// [`TfEditor::begin_edit`] when it starts; the moves during it do not push more steps.
#[derive(Clone, Debug)]
pub struct TfEditor {
    tf: TransferFunctions,
    undo: Vec<TransferFunctions>,
    redo: Vec<TransferFunctions>,
    /// Bumped on every change, so the viewer can tell when to re-render.
    revision: u64,
}

/// A control point as the editor sees it: `x` and up to three value channels. An absent
/// scattering curve comes into being (as its implicit constant 0) when it is edited.
fn points_mut(tf: &mut TransferFunctions, f: Function) -> PointsMut<'_> {
    let absent = || Curve {
        points: ABSENT.to_vec(),
    };
    match f {
        Function::Opacity => PointsMut::Curve(&mut tf.opacity.points),
        Function::Eta => PointsMut::Curve(&mut tf.eta.points),
        Function::Color => PointsMut::Ramp(&mut tf.color.points),
        Function::Medium => PointsMut::Ramp(&mut tf.medium.points),
        Function::Albedo => PointsMut::Curve(&mut tf.albedo.get_or_insert_with(absent).points),
        Function::Anisotropy => PointsMut::Curve(&mut tf.anisotropy.get_or_insert_with(absent).points),
    }
}

/// The points of curve `f` (absent scattering curves: their implicit constant 0).
fn curve_points(tf: &TransferFunctions, f: Function) -> &[[f32; 2]] {
    match f {
        Function::Opacity => &tf.opacity.points,
        Function::Eta => &tf.eta.points,
        Function::Albedo => tf.albedo.as_ref().map_or(&ABSENT[..], |c| &c.points[..]),
        Function::Anisotropy => tf.anisotropy.as_ref().map_or(&ABSENT[..], |c| &c.points[..]),
        Function::Color | Function::Medium => &[],
    }
}

enum PointsMut<'a> {
    Curve(&'a mut Vec<[f32; 2]>),
    Ramp(&'a mut Vec<[f32; 4]>),
}

fn clamp(v: f32, range: [f32; 2]) -> f32 {
    if v.is_nan() {
        range[0]
    } else {
        v.clamp(range[0], range[1])
    }
}

impl TfEditor {
    pub fn new(tf: TransferFunctions) -> Self {
        TfEditor {
            tf,
            undo: Vec::new(),
            redo: Vec::new(),
            revision: 0,
        }
    }

    pub fn tf(&self) -> &TransferFunctions {
        &self.tf
    }

    pub fn revision(&self) -> u64 {
        self.revision
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    /// Records the current state as one undo step (start of a drag, or before a one-shot edit).
    pub fn begin_edit(&mut self) {
        self.undo.push(self.tf.clone());
        if self.undo.len() > UNDO_DEPTH {
            self.undo.remove(0);
        }
        self.redo.clear();
    }

    fn changed(&mut self) {
        self.revision += 1;
    }

    pub fn undo(&mut self) -> bool {
        match self.undo.pop() {
            Some(prev) => {
                self.redo.push(std::mem::replace(&mut self.tf, prev));
                self.changed();
                true
            }
            None => false,
        }
    }

    pub fn redo(&mut self) -> bool {
        match self.redo.pop() {
            Some(next) => {
                self.undo.push(std::mem::replace(&mut self.tf, next));
                self.changed();
                true
            }
            None => false,
        }
    }

    pub fn len(&self, f: Function) -> usize {
        match f {
            Function::Color => self.tf.color.points.len(),
            Function::Medium => self.tf.medium.points.len(),
            _ => curve_points(&self.tf, f).len(),
        }
    }

    /// Point `i` of `f` as `[x, v0, v1, v2]` (curves repeat their one value).
    pub fn point(&self, f: Function, i: usize) -> Option<[f32; 4]> {
        match f {
            Function::Color => self.tf.color.points.get(i).copied(),
            Function::Medium => self.tf.medium.points.get(i).copied(),
            _ => curve_points(&self.tf, f).get(i).map(|p| [p[0], p[1], p[1], p[1]]),
        }
    }

    /// The value(s) of `f` at `x` (curves: one value in all three channels).
    pub fn eval(&self, f: Function, x: f32) -> [f32; 3] {
        match f {
            Function::Opacity => [self.tf.opacity.eval(x); 3],
            Function::Eta => [self.tf.eta.eval(x); 3],
            Function::Color => self.tf.color.eval(x),
            Function::Medium => self.tf.medium.eval(x),
            Function::Albedo => [self.tf.albedo_at(x); 3],
            Function::Anisotropy => [self.tf.anisotropy_at(x); 3],
        }
    }

    /// Inserts a point at `x` (clamped to [0, 1]) keeping the points sorted. `value`: the
    /// curve value (channel 0) or the colour; `None` takes the current value there, so the
    /// function does not change until the point is moved. Returns the new point's index.
    pub fn insert(&mut self, f: Function, x: f32, value: Option<[f32; 3]>) -> usize {
        self.begin_edit();
        let x = clamp(x, [0.0, 1.0]);
        let range = f.value_range();
        let v = value.unwrap_or_else(|| self.eval(f, x)).map(|c| clamp(c, range));
        let index = match points_mut(&mut self.tf, f) {
            PointsMut::Curve(p) => {
                let i = p.partition_point(|q| q[0] <= x);
                p.insert(i, [x, v[0]]);
                i
            }
            PointsMut::Ramp(p) => {
                let i = p.partition_point(|q| q[0] <= x);
                p.insert(i, [x, v[0], v[1], v[2]]);
                i
            }
        };
        self.changed();
        index
    }

    /// Moves point `i` to `x` and (curves) value `y`, clamped: x stays between its neighbours
    /// (points never swap order) and inside [0, 1]; y inside the function's range. Does not
    /// push an undo step (call [`TfEditor::begin_edit`] when the drag starts).
    pub fn move_point(&mut self, f: Function, i: usize, x: f32, y: Option<f32>) {
        let range = f.value_range();
        let moved = match points_mut(&mut self.tf, f) {
            PointsMut::Curve(p) => move_in(p, i, x, |q| {
                if let Some(y) = y {
                    q[1] = clamp(y, range);
                }
            }),
            PointsMut::Ramp(p) => move_in(p, i, x, |_| {}),
        };
        if moved {
            self.changed();
        }
    }

    /// Sets the colour of ramp point `i` (channels clamped to [0, 1]); one undo step.
    pub fn set_color(&mut self, f: Function, i: usize, rgb: [f32; 3]) {
        if i >= self.len(f) || !f.is_ramp() {
            return;
        }
        if self.point(f, i).is_some_and(|p| p[1..] == rgb) {
            return;
        }
        self.begin_edit();
        if let PointsMut::Ramp(p) = points_mut(&mut self.tf, f) {
            for (c, v) in p[i][1..].iter_mut().zip(rgb) {
                *c = clamp(v, [0.0, 1.0]);
            }
        }
        self.changed();
    }

    /// Deletes point `i`; the last point of a function is kept (a function needs one).
    pub fn delete(&mut self, f: Function, i: usize) -> bool {
        if self.len(f) <= 1 || i >= self.len(f) {
            return false;
        }
        self.begin_edit();
        match points_mut(&mut self.tf, f) {
            PointsMut::Curve(p) => {
                p.remove(i);
            }
            PointsMut::Ramp(p) => {
                p.remove(i);
            }
        }
        self.changed();
        true
    }

    /// Replaces everything (a preset or file); one undo step.
    pub fn replace(&mut self, tf: TransferFunctions) -> Result<(), TransferError> {
        tf.validate()?;
        self.begin_edit();
        self.tf = tf;
        self.changed();
        Ok(())
    }

    pub fn load(&mut self, path: &Path) -> Result<(), TransferError> {
        self.replace(TransferFunctions::load(path)?)
    }

    /// Writes the functions as JSON (the `transfer_functions/` format), via a temporary file
    /// and a rename so a crash never leaves half a file.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        super::save::write_atomic(path, self.tf.to_json().as_bytes())
    }
}

/// Moves `p[i]` to `x` between its neighbours, then lets `set` change the values.
fn move_in<const N: usize>(p: &mut [[f32; N]], i: usize, x: f32, set: impl FnOnce(&mut [f32; N])) -> bool {
    if i >= p.len() {
        return false;
    }
    let lo = if i > 0 { p[i - 1][0] } else { 0.0 };
    let hi = if i + 1 < p.len() { p[i + 1][0] } else { 1.0 };
    p[i][0] = clamp(x, [lo, hi]);
    set(&mut p[i]);
    true
}

/// The JSON presets in `dir` (`transfer_functions/`), sorted by file name.
pub fn list_presets(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "json"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn editor() -> TfEditor {
        TfEditor::new(TransferFunctions::default())
    }

    #[test]
    fn insert_keeps_order_and_function() {
        let mut e = editor();
        let before = e.eval(Function::Opacity, 0.3);
        let i = e.insert(Function::Opacity, 0.3, None);
        assert_eq!(i, 1);
        assert_eq!(e.len(Function::Opacity), 3);
        // Inserting at the current value leaves the function unchanged.
        assert!((e.eval(Function::Opacity, 0.3)[0] - before[0]).abs() < 1e-6);
        assert!((e.eval(Function::Opacity, 0.7)[0] - 0.35).abs() < 1e-6);
        e.tf().validate().unwrap();
        // Out-of-range input is clamped, and the result still validates.
        let j = e.insert(Function::Eta, 7.0, Some([9.0; 3]));
        assert_eq!(e.point(Function::Eta, j).unwrap()[..2], [1.0, ETA_RANGE[1]]);
        let k = e.insert(Function::Color, -1.0, Some([2.0, -1.0, f32::NAN]));
        assert_eq!(e.point(Function::Color, k).unwrap(), [0.0, 1.0, 0.0, 0.0]);
        e.tf().validate().unwrap();
    }

    #[test]
    fn move_clamps_between_neighbours_and_range() {
        let mut e = editor();
        let i = e.insert(Function::Opacity, 0.5, Some([0.2; 3]));
        e.move_point(Function::Opacity, i, 2.0, Some(-3.0));
        assert_eq!(e.point(Function::Opacity, i).unwrap()[..2], [1.0, 0.0]);
        e.move_point(Function::Opacity, 0, 0.9, Some(0.7));
        // Point 0 cannot pass point 1 at x = 1.
        assert_eq!(e.point(Function::Opacity, 0).unwrap()[..2], [0.9, 0.7]);
        e.move_point(Function::Opacity, 1, 0.1, None);
        assert_eq!(e.point(Function::Opacity, 1).unwrap()[0], 0.9, "cannot cross point 0");
        e.move_point(Function::Eta, 0, 0.5, Some(0.2));
        assert_eq!(e.point(Function::Eta, 0).unwrap()[1], 1.0, "η is at least 1");
        e.tf().validate().unwrap();
    }

    #[test]
    fn delete_keeps_one_point() {
        let mut e = editor();
        assert!(e.delete(Function::Opacity, 0));
        assert!(!e.delete(Function::Opacity, 0), "a function keeps its last point");
        assert!(!e.delete(Function::Opacity, 5));
        assert_eq!(e.len(Function::Opacity), 1);
        assert_eq!(e.point(Function::Opacity, 0).unwrap()[..2], [1.0, 0.5]);
    }

    #[test]
    fn undo_redo_round_trip() {
        let original = editor();
        let mut e = original.clone();
        assert!(!e.undo());
        e.insert(Function::Opacity, 0.5, Some([1.0; 3]));
        // A drag: one undo step for many moves.
        e.begin_edit();
        for k in 0..10 {
            e.move_point(Function::Opacity, 1, 0.5 + k as f32 * 0.01, Some(0.5));
        }
        e.set_color(Function::Medium, 0, [0.5, 0.6, 0.7]);
        let edited = e.tf().clone();
        assert!(e.undo() && e.undo());
        assert_eq!(e.point(Function::Opacity, 1).unwrap()[..2], [0.5, 1.0]);
        assert!(e.undo());
        assert_eq!(e.tf(), original.tf());
        assert!(!e.can_undo());
        assert!(e.redo() && e.redo() && e.redo());
        assert_eq!(e.tf(), &edited);
        assert!(!e.redo());
        // A new edit clears the redo stack.
        e.undo();
        e.delete(Function::Opacity, 0);
        assert!(!e.can_redo());
        assert!(e.revision() > 0);
    }

    #[test]
    fn undo_depth_is_bounded() {
        let mut e = editor();
        for k in 0..UNDO_DEPTH + 20 {
            e.move_point(Function::Opacity, 0, 0.0, Some(0.0));
            e.begin_edit();
            e.move_point(Function::Opacity, 1, 1.0, Some(k as f32 / 1000.0));
        }
        let mut n = 0;
        while e.undo() {
            n += 1;
        }
        assert_eq!(n, UNDO_DEPTH);
    }

    #[test]
    fn save_load_round_trip_and_rejects_invalid() {
        let dir = std::env::temp_dir().join(format!("caustica-tf-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("edited.json");
        let mut e = editor();
        e.insert(Function::Eta, 0.4, Some([1.33; 3]));
        e.insert(Function::Color, 0.6, Some([0.9, 0.2, 0.1]));
        e.save(&path).unwrap();
        let mut f = editor();
        f.load(&path).unwrap();
        assert_eq!(f.tf(), e.tf());
        assert!(f.can_undo(), "loading is an undoable edit");
        std::fs::write(&path, r#"{"opacity": [[0, 2]]}"#).unwrap();
        let before = f.tf().clone();
        assert!(f.load(&path).is_err());
        assert_eq!(f.tf(), &before, "a bad file leaves the functions alone");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn scattering_curves_appear_when_edited() {
        let mut e = editor();
        // Absent: one implicit point at 0, and nothing in the functions.
        assert_eq!(e.len(Function::Albedo), 1);
        assert_eq!(e.point(Function::Anisotropy, 0), Some([0.0; 4]));
        assert!(e.tf().albedo.is_none() && e.tf().anisotropy.is_none());
        assert!(!e.delete(Function::Albedo, 0), "the implicit point stays");
        assert!(e.tf().albedo.is_none(), "a refused edit creates nothing");
        let i = e.insert(Function::Albedo, 0.5, Some([0.9; 3]));
        assert_eq!(i, 1);
        assert!(e.tf().scatters());
        assert!((e.eval(Function::Albedo, 0.75)[0] - 0.9).abs() < 1e-6);
        // g is clamped to its range, not to [0, 1].
        e.begin_edit();
        e.move_point(Function::Anisotropy, 0, 0.0, Some(-5.0));
        assert_eq!(e.point(Function::Anisotropy, 0).unwrap()[1], ANISOTROPY_RANGE[0]);
        e.tf().validate().unwrap();
        assert!(e.undo() && e.undo());
        assert!(e.tf().albedo.is_none(), "undo removes the curve again");
    }

    #[test]
    fn presets_are_listed_and_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("transfer_functions");
        let presets = list_presets(&dir);
        assert!(presets.len() >= 8);
        let mut e = editor();
        e.load(&presets[0]).unwrap();
        assert_ne!(e.tf(), editor().tf());
    }
}
