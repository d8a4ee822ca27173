//! Tracks: lists of keys `[at, value...]` over the animation time u ∈ [0, 1], and frame k's
//! scene computed from them. A key's value is reached exactly at its time (no rounding), so
//! a frame that falls on a key renders the keyed scene bit for bit.

use serde::{Deserialize, Serialize};

use super::blend::blend_transfer;
use super::AnimateError;
use crate::scene::{Projection, Scene, TransferSource};
use crate::transfer::TransferFunctions;

/// Scalar keys `[at, value]`, `at` non-decreasing in [0, 1]; empty: not animated.
pub type Keys = Vec<[f64; 2]>;
/// Vector keys `[at, x, y, z]`.
pub type Keys3 = Vec<[f64; 4]>;

/// How a track's value goes from one key to the next.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Interp {
    Linear,
    /// Constant ratio per unit time (distances and zoom factors: equal steps look equal).
    Geometric,
}

/// Camera tracks. The fields are those of the scene's `[camera]`; `magnification` scales
/// the view instead: the distance is divided by it (perspective) or the zoom multiplied
/// (orthographic).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraTracks {
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub yaw_deg: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub pitch_deg: Keys,
    /// Interpolated geometrically.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub distance: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub fov_deg: Keys,
    /// Orthographic zoom, interpolated geometrically.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub zoom: Keys,
    /// Interpolated geometrically.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub magnification: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub target: Keys3,
}

/// Light tracks: the fields of the scene's `[light]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LightTracks {
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub polar_deg: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub azimuth_deg: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub intensity: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub softness: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub color: Keys3,
}

/// Clip-plane tracks; the scene must have a `[clip]` table.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClipTracks {
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub offset: Keys,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub normal: Keys3,
}

/// Frames of a time series between keyed frame numbers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum TimeMode {
    /// The nearest frame, as `render --time T` picks it.
    #[default]
    Hold,
    /// The two frames around the time, blended linearly voxel by voxel.
    Interpolate,
}

/// The time-series track; the scene's volume must be a series.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TimeTrack {
    /// Keys `[at, frame]`, frame numbers 0-based (fractions allowed).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub frame: Keys,
    pub mode: TimeMode,
}

/// Everything an animation changes over time. `K` is the type of a transfer-function key
/// (a file reference while loading, inline functions once normalised).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Tracks<K> {
    #[serde(skip_serializing_if = "CameraTracks::is_empty")]
    pub camera: CameraTracks,
    #[serde(skip_serializing_if = "LightTracks::is_empty")]
    pub light: LightTracks,
    #[serde(skip_serializing_if = "ClipTracks::is_empty")]
    pub clip: ClipTracks,
    #[serde(skip_serializing_if = "TimeTrack::is_empty")]
    pub time: TimeTrack,
    /// Transfer-function keys (at least two when given), interpolated point by point.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub transfer: Vec<K>,
}

impl<K> Default for Tracks<K> {
    fn default() -> Self {
        Tracks {
            camera: CameraTracks::default(),
            light: LightTracks::default(),
            clip: ClipTracks::default(),
            time: TimeTrack::default(),
            transfer: Vec::new(),
        }
    }
}

impl CameraTracks {
    pub fn is_empty(&self) -> bool {
        *self == CameraTracks::default()
    }
}

impl LightTracks {
    pub fn is_empty(&self) -> bool {
        *self == LightTracks::default()
    }
}

impl ClipTracks {
    pub fn is_empty(&self) -> bool {
        *self == ClipTracks::default()
    }
}

impl TimeTrack {
    pub fn is_empty(&self) -> bool {
        self.frame.is_empty()
    }
}

/// A transfer-function key: functions and, optionally, the data window they are meant for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransferKey {
    pub at: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<[f32; 2]>,
    pub functions: TransferFunctions,
}

/// Two frames of a time series blended: the scene's frame and `next_frame` with `weight`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Blend {
    pub next_frame: usize,
    pub weight: f64,
}

/// What frame k shows: a scene, plus a second time-series frame when frames are blended.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameSpec {
    pub index: u32,
    pub scene: Scene,
    pub blend: Option<Blend>,
}

/// The keys around `u` among key times `at` (non-decreasing): `(i, j, w)` with the value
/// `(1 − w)·v_i + w·v_j`. A time on a key gives `(i, i, 0)`, the key itself (the last of
/// equal times, so equal times make a step); before the first key and after the last the
/// end keys hold.
fn locate(at: impl Iterator<Item = f64>, u: f64) -> Option<(usize, usize, f64)> {
    let at: Vec<f64> = at.collect();
    let last = at.len().checked_sub(1)?;
    let i = match at.iter().rposition(|&a| a <= u) {
        Some(i) => i,
        None => return Some((0, 0, 0.0)),
    };
    if i == last || at[i] == u {
        return Some((i, i, 0.0));
    }
    // at[i] ≤ u < at[i + 1], so the span is positive.
    Some((i, i + 1, (u - at[i]) / (at[i + 1] - at[i])))
}

fn mix(a: f64, b: f64, w: f64, interp: Interp) -> f64 {
    if w == 0.0 {
        return a;
    }
    match interp {
        // This form is exact at both ends and stays between a and b.
        Interp::Linear => ((1.0 - w) * a + w * b).clamp(a.min(b), a.max(b)),
        Interp::Geometric => ((1.0 - w) * a.ln() + w * b.ln()).exp().clamp(a.min(b), a.max(b)),
    }
}

fn eval(keys: &Keys, u: f64, interp: Interp) -> Option<f32> {
    let (i, j, w) = locate(keys.iter().map(|k| k[0]), u)?;
    Some(mix(keys[i][1], keys[j][1], w, interp) as f32)
}

fn eval3(keys: &Keys3, u: f64) -> Option<[f32; 3]> {
    let (i, j, w) = locate(keys.iter().map(|k| k[0]), u)?;
    let c = |n: usize| mix(keys[i][n], keys[j][n], w, Interp::Linear) as f32;
    Some([c(1), c(2), c(3)])
}

fn set(field: &mut f32, value: Option<f32>) {
    if let Some(v) = value {
        *field = v;
    }
}

/// Checks a key list: times finite, in [0, 1] and non-decreasing; values finite; values of
/// geometric tracks > 0.
fn check_keys<const N: usize>(name: &str, keys: &[[f64; N]], positive: bool) -> Result<(), AnimateError> {
    let bad = |m: String| Err(AnimateError::Invalid(format!("track {name}: {m}")));
    let mut last = 0.0;
    for (i, k) in keys.iter().enumerate() {
        if k.iter().any(|v| !v.is_finite()) {
            return bad(format!("key {i}: values must be finite numbers"));
        }
        if !(0.0..=1.0).contains(&k[0]) || k[0] < last {
            return bad(format!(
                "key {i}: time {} must be in [0, 1] and not before the previous key's",
                k[0]
            ));
        }
        if positive && k[1..].iter().any(|v| *v <= 0.0) {
            return bad(format!("key {i}: value must be > 0"));
        }
        last = k[0];
    }
    Ok(())
}

impl Tracks<TransferKey> {
    /// Range checks of the keys themselves (the scenes they produce are checked per frame).
    pub fn validate(&self, scene: &Scene) -> Result<(), AnimateError> {
        let c = &self.camera;
        check_keys("camera.yaw_deg", &c.yaw_deg, false)?;
        check_keys("camera.pitch_deg", &c.pitch_deg, false)?;
        check_keys("camera.distance", &c.distance, true)?;
        check_keys("camera.fov_deg", &c.fov_deg, false)?;
        check_keys("camera.zoom", &c.zoom, true)?;
        check_keys("camera.magnification", &c.magnification, true)?;
        check_keys("camera.target", &c.target, false)?;
        let l = &self.light;
        check_keys("light.polar_deg", &l.polar_deg, false)?;
        check_keys("light.azimuth_deg", &l.azimuth_deg, false)?;
        check_keys("light.intensity", &l.intensity, false)?;
        check_keys("light.softness", &l.softness, false)?;
        check_keys("light.color", &l.color, false)?;
        check_keys("clip.offset", &self.clip.offset, false)?;
        check_keys("clip.normal", &self.clip.normal, false)?;
        check_keys("time.frame", &self.time.frame, false)?;
        if !self.clip.is_empty() && scene.clip.is_none() {
            return Err(AnimateError::Invalid(
                "clip tracks need a clip plane in the scene ([clip] with a normal)".into(),
            ));
        }
        if !self.time.is_empty() && !matches!(scene.volume, crate::scene::VolumeSource::Series { .. }) {
            return Err(AnimateError::Invalid(
                "a time track needs a time series (a file pattern with '*' or kind = \"series\")".into(),
            ));
        }
        let t = &self.transfer;
        if t.len() == 1 {
            return Err(AnimateError::Invalid(
                "transfer-function keys: give at least two (one is just the scene's transfer functions)".into(),
            ));
        }
        let times: Keys = t.iter().map(|k| [k.at, 1.0]).collect();
        check_keys("transfer", &times, false)?;
        if t.iter().any(|k| k.window.is_some()) && t.iter().any(|k| k.window.is_none()) {
            return Err(AnimateError::Invalid(
                "transfer-function keys: give a window for every key or for none".into(),
            ));
        }
        for (i, k) in t.iter().enumerate() {
            k.functions
                .validate()
                .map_err(|e| AnimateError::Invalid(format!("transfer key {i}: {e}")))?;
        }
        Ok(())
    }

    /// The scene at animation time `u` (and the blend of two series frames, if any).
    /// `series_len` is the number of frames of the scene's series (0 without a time track).
    pub fn apply(&self, base: &Scene, u: f64, series_len: usize) -> Result<(Scene, Option<Blend>), AnimateError> {
        let mut s = base.clone();
        let c = &self.camera;
        let cam = &mut s.camera;
        set(&mut cam.yaw_deg, eval(&c.yaw_deg, u, Interp::Linear));
        set(&mut cam.pitch_deg, eval(&c.pitch_deg, u, Interp::Linear));
        set(&mut cam.distance, eval(&c.distance, u, Interp::Geometric));
        set(&mut cam.fov_deg, eval(&c.fov_deg, u, Interp::Linear));
        set(&mut cam.zoom, eval(&c.zoom, u, Interp::Geometric));
        if let Some(t) = eval3(&c.target, u) {
            cam.target = t;
        }
        if let Some(m) = eval(&c.magnification, u, Interp::Geometric) {
            match cam.projection {
                Projection::Perspective => cam.distance /= m,
                Projection::Orthographic => cam.zoom *= m,
            }
        }
        let l = &self.light;
        let light = &mut s.light;
        set(&mut light.polar_deg, eval(&l.polar_deg, u, Interp::Linear));
        set(&mut light.azimuth_deg, eval(&l.azimuth_deg, u, Interp::Linear));
        set(&mut light.intensity, eval(&l.intensity, u, Interp::Linear));
        set(&mut light.softness, eval(&l.softness, u, Interp::Linear));
        if let Some(rgb) = eval3(&l.color, u) {
            light.color = rgb;
        }
        if let Some(clip) = &mut s.clip {
            set(&mut clip.offset, eval(&self.clip.offset, u, Interp::Linear));
            if let Some(n) = eval3(&self.clip.normal, u) {
                clip.normal = n;
            }
        }
        let blend = self.time_at(&mut s, u, series_len)?;
        if let Some((i, j, w)) = locate(self.transfer.iter().map(|k| k.at), u) {
            let (a, b) = (&self.transfer[i], &self.transfer[j]);
            s.transfer = TransferSource::Inline(blend_transfer(&a.functions, &b.functions, w));
            if let (Some(wa), Some(wb)) = (a.window, b.window) {
                let m = |n: usize| mix(wa[n] as f64, wb[n] as f64, w, Interp::Linear) as f32;
                s.window = Some([m(0), m(1)]);
            }
        }
        s.validate()?;
        Ok((s, blend))
    }

    /// Sets the series frame for time `u`; returns the blend with the next frame when
    /// interpolating between two frames.
    fn time_at(&self, s: &mut Scene, u: f64, series_len: usize) -> Result<Option<Blend>, AnimateError> {
        let Some((i, j, w)) = locate(self.time.frame.iter().map(|k| k[0]), u) else {
            return Ok(None);
        };
        let t = mix(self.time.frame[i][1], self.time.frame[j][1], w, Interp::Linear);
        let last = series_len.saturating_sub(1) as f64;
        if !(0.0..=last).contains(&t.round()) {
            return Err(AnimateError::Invalid(format!(
                "time track: frame {t} is outside the series' frames 0..={last}"
            )));
        }
        // Frame numbers within 1e-9 of an integer are that frame (rounding in the key mix).
        let nearest = t.round();
        let t = if (t - nearest).abs() < 1e-9 { nearest } else { t };
        let (frame, blend) = match self.time.mode {
            TimeMode::Hold => (nearest as usize, None),
            TimeMode::Interpolate if t == t.floor() => (t as usize, None),
            TimeMode::Interpolate => {
                let lo = t.floor();
                let blend = Blend {
                    next_frame: lo as usize + 1,
                    weight: t - lo,
                };
                (lo as usize, Some(blend))
            }
        };
        s.volume.set_frame(frame);
        Ok(blend)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_hit_exactly_and_held_past_the_ends() {
        let keys: Keys = vec![[0.25, 10.0], [0.5, 0.3], [1.0, -7.1]];
        assert_eq!(eval(&keys, 0.0, Interp::Linear), Some(10.0));
        assert_eq!(eval(&keys, 0.25, Interp::Linear), Some(10.0));
        assert_eq!(eval(&keys, 0.5, Interp::Linear), Some(0.3));
        assert_eq!(eval(&keys, 1.0, Interp::Linear), Some(-7.1));
        // 0.375 is halfway between the first two keys.
        assert_eq!(eval(&keys, 0.375, Interp::Linear), Some(5.15));
        assert_eq!(eval(&Vec::new(), 0.5, Interp::Linear), None);
        // Geometric: halfway between 1 and 4 is 2, and the ends are exact.
        let zoom: Keys = vec![[0.0, 1.0], [1.0, 4.0]];
        let mid = eval(&zoom, 0.5, Interp::Geometric).unwrap();
        assert!((mid - 2.0).abs() < 1e-6, "{mid}");
        assert_eq!(eval(&zoom, 1.0, Interp::Geometric), Some(4.0));
    }

    #[test]
    fn equal_times_make_a_step() {
        let keys: Keys = vec![[0.0, 0.0], [0.5, 1.0], [0.5, 5.0], [1.0, 5.0]];
        assert_eq!(eval(&keys, 0.5, Interp::Linear), Some(5.0), "the later key wins");
        assert_eq!(eval(&keys, 0.25, Interp::Linear), Some(0.5));
    }

    #[test]
    fn bad_keys_are_rejected_with_the_track_named() {
        let scene = crate::scene::builtin("ball-lens").unwrap().scene;
        let mut t = Tracks::<TransferKey>::default();
        t.camera.yaw_deg = vec![[0.5, 0.0], [0.25, 1.0]];
        let e = t.validate(&scene).unwrap_err().to_string();
        assert!(e.contains("camera.yaw_deg") && e.contains("key 1"), "{e}");
        let mut t = Tracks::<TransferKey>::default();
        t.camera.distance = vec![[0.0, 0.0]];
        assert!(t.validate(&scene).unwrap_err().to_string().contains("> 0"));
        let mut t = Tracks::<TransferKey>::default();
        t.clip.offset = vec![[0.0, 0.0]];
        assert!(t.validate(&scene).unwrap_err().to_string().contains("clip plane"));
        let mut t = Tracks::<TransferKey>::default();
        t.time.frame = vec![[0.0, 0.0]];
        assert!(t.validate(&scene).unwrap_err().to_string().contains("time series"));
        let mut t = Tracks::<TransferKey>::default();
        t.light.polar_deg = vec![[0.0, f64::NAN]];
        assert!(t.validate(&scene).unwrap_err().to_string().contains("finite"));
    }

    #[test]
    fn magnification_scales_the_view_of_either_projection() {
        let base = crate::scene::builtin("ball-lens").unwrap().scene;
        let mut t = Tracks::<TransferKey>::default();
        t.camera.magnification = vec![[0.0, 1.0], [1.0, 2.0]];
        let (s, _) = t.apply(&base, 1.0, 0).unwrap();
        assert_eq!(s.camera.distance, base.camera.distance / 2.0);
        let mut ortho = base.clone();
        ortho.camera.projection = Projection::Orthographic;
        let (s, _) = t.apply(&ortho, 1.0, 0).unwrap();
        assert_eq!(s.camera.zoom, ortho.camera.zoom * 2.0);
        assert_eq!(s.camera.distance, ortho.camera.distance);
    }

    #[test]
    fn time_holds_the_nearest_frame_or_blends_two() {
        let mut base = crate::scene::builtin("ball-lens").unwrap().scene;
        base.volume = crate::scene::VolumeSource::Series {
            files: vec!["a".into(), "b".into(), "c".into()],
            pattern: None,
            frame: 0,
        };
        let mut t = Tracks::<TransferKey>::default();
        t.time.frame = vec![[0.0, 0.0], [1.0, 2.0]];
        let frame = |s: &Scene| match s.volume {
            crate::scene::VolumeSource::Series { frame, .. } => frame,
            _ => usize::MAX,
        };
        let (s, blend) = t.apply(&base, 0.3, 3).unwrap();
        assert_eq!((frame(&s), blend), (1, None), "t = 0.6 holds frame 1");
        t.time.mode = TimeMode::Interpolate;
        let (s, blend) = t.apply(&base, 0.75, 3).unwrap();
        assert_eq!(frame(&s), 1);
        assert_eq!(
            blend,
            Some(Blend {
                next_frame: 2,
                weight: 0.5
            })
        );
        let (s, blend) = t.apply(&base, 0.5, 3).unwrap();
        assert_eq!((frame(&s), blend), (1, None), "on a frame: no blend");
        let e = t.apply(&base, 1.0, 2).unwrap_err().to_string();
        assert!(e.contains("outside the series"), "{e}");
    }
}
