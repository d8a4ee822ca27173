//! An animation through recorded views (the viewer's keyframes): keyframe i at time
//! i / (n − 1), and a track for every property that differs between keyframes: camera,
//! light, clip plane, time-series frame and transfer functions.

use std::path::Path;

use super::file::Animation;
use super::paths::resolve_scene;
use super::tracks::{Keys, Keys3, TimeMode, Tracks, TransferKey};
use super::AnimateError;
use crate::scene::{Scene, VolumeSource};

/// Offset (bounding radii) of a clip plane that clips nothing: every point of the volume is
/// within one radius of its centre. Keyframes without a clip plane get it, so a clip plane
/// switched on between two keyframes sweeps in from outside.
pub const CLIP_OFF_OFFSET: f32 = 1.0;

/// An animation through `keyframes`, `frames_between` frames from one to the next (each
/// keyframe then falls on a frame and is rendered exactly as recorded, as long as its angles
/// need no unwrapping). Returns notes on what could not be animated.
pub fn from_keyframes(
    keyframes: &[Scene],
    frames_between: u32,
    fps: f64,
    size: [u32; 2],
) -> Result<(Animation, Vec<String>), AnimateError> {
    let n = keyframes.len();
    if n < 2 {
        return Err(AnimateError::Invalid(format!(
            "record at least two keyframes (there {} {n})",
            if n == 1 { "is" } else { "are" }
        )));
    }
    if frames_between == 0 {
        return Err(AnimateError::Invalid(
            "frames between keyframes must be at least 1".into(),
        ));
    }
    let mut base = keyframes[0].clone();
    resolve_scene(&mut base, Path::new(""))?;
    let at = |i: usize| i as f64 / (n - 1) as f64;
    // A track only where the values differ, so the file shows what moves.
    let track = |f: &dyn Fn(&Scene) -> f32| -> Keys {
        let v: Vec<f64> = keyframes.iter().map(|s| f(s) as f64).collect();
        if v.iter().all(|x| *x == v[0]) {
            return Vec::new();
        }
        v.iter().enumerate().map(|(i, x)| [at(i), *x]).collect()
    };
    let track3 = |f: &dyn Fn(&Scene) -> [f32; 3]| -> Keys3 {
        let v: Vec<[f32; 3]> = keyframes.iter().map(f).collect();
        if v.iter().all(|x| *x == v[0]) {
            return Vec::new();
        }
        v.iter()
            .enumerate()
            .map(|(i, x)| [at(i), x[0] as f64, x[1] as f64, x[2] as f64])
            .collect()
    };
    let mut tracks = Tracks::<TransferKey>::default();
    let c = &mut tracks.camera;
    c.yaw_deg = unwrap_degrees(track(&|s| s.camera.yaw_deg));
    c.pitch_deg = track(&|s| s.camera.pitch_deg);
    c.distance = track(&|s| s.camera.distance);
    c.fov_deg = track(&|s| s.camera.fov_deg);
    c.zoom = track(&|s| s.camera.zoom);
    c.target = track3(&|s| s.camera.target);
    let l = &mut tracks.light;
    l.polar_deg = track(&|s| s.light.polar_deg);
    l.azimuth_deg = unwrap_degrees(track(&|s| s.light.azimuth_deg));
    l.intensity = track(&|s| s.light.intensity);
    l.softness = track(&|s| s.light.softness);
    l.color = track3(&|s| s.light.color);
    if let Some(clip) = keyframes.iter().find_map(|s| s.clip.clone()) {
        let normal = clip.normal;
        base.clip = Some(clip);
        tracks.clip.offset = track(&|s| s.clip.as_ref().map_or(CLIP_OFF_OFFSET, |c| c.offset));
        tracks.clip.normal = track3(&|s| s.clip.as_ref().map_or(normal, |c| c.normal));
        if let Some(first) = tracks.clip.offset.first() {
            if let Some(c) = &mut base.clip {
                c.offset = first[1] as f32;
            }
        }
    }
    let frame = |s: &Scene| match s.volume {
        VolumeSource::Series { frame, .. } => frame as f32,
        _ => 0.0,
    };
    tracks.time.frame = track(&frame);
    tracks.time.mode = TimeMode::Hold;
    let functions: Vec<_> = keyframes
        .iter()
        .map(|s| s.transfer_functions())
        .collect::<Result<_, _>>()?;
    let windows: Vec<_> = keyframes.iter().map(|s| s.window).collect();
    if functions.iter().any(|f| *f != functions[0]) || windows.iter().any(|w| *w != windows[0]) {
        let all_windows = windows.iter().all(|w| w.is_some());
        tracks.transfer = functions
            .into_iter()
            .zip(windows)
            .enumerate()
            .map(|(i, (functions, window))| TransferKey {
                at: at(i),
                window: window.filter(|_| all_windows),
                functions,
            })
            .collect();
    }
    let mut notes = Vec::new();
    for (i, s) in keyframes.iter().enumerate().skip(1) {
        let fixed = [
            ("projection", s.camera.projection != keyframes[0].camera.projection),
            ("environment", s.environment != keyframes[0].environment),
            ("effects and quality", s.quality != keyframes[0].quality),
            ("shading", s.shading != keyframes[0].shading),
        ];
        for (what, differs) in fixed {
            if differs {
                notes.push(format!(
                    "keyframe {i}: {what} is not animated; the first keyframe's is used"
                ));
            }
        }
    }
    let animation = Animation {
        frames: frames_between * (n as u32 - 1) + 1,
        fps,
        size,
        looped: false,
        tracks,
        scene: base,
    };
    animation.validate()?;
    Ok((animation, notes))
}

/// Angles kept within 180° of the previous key, so 350° → 10° turns 20°, not back 340°.
fn unwrap_degrees(mut keys: Keys) -> Keys {
    for i in 1..keys.len() {
        let prev = keys[i - 1][1];
        keys[i][1] = prev + (keys[i][1] - prev + 180.0).rem_euclid(360.0) - 180.0;
    }
    keys
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{builtin, ClipPlane, TransferSource};

    /// The animation passes through every keyframe: the frame on keyframe i renders the
    /// recorded scene (same scene, field for field), and what did not change gets no track.
    #[test]
    fn frames_on_keyframes_are_the_recorded_views() {
        let mut a = builtin("ball-lens").unwrap().scene;
        a.camera.yaw_deg = 0.0;
        let mut b = a.clone();
        b.camera.yaw_deg = 40.0;
        b.camera.distance = 2.0;
        b.light.polar_deg = 50.0;
        let mut tf = b.transfer_functions().unwrap();
        tf.opacity.points[0][1] = 0.25;
        b.transfer = TransferSource::Inline(tf);
        let mut c = b.clone();
        c.camera.pitch_deg = -10.0;
        c.clip = Some(ClipPlane {
            normal: [1.0, 0.0, 0.0],
            offset: 0.25,
        });
        let (anim, notes) = from_keyframes(&[a.clone(), b.clone(), c.clone()], 4, 24.0, [16, 8]).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(anim.frames, 9);
        assert!(anim.tracks.camera.fov_deg.is_empty(), "unchanged: no track");
        assert_eq!(anim.tracks.transfer.len(), 3);
        let specs = anim.frame_specs().unwrap();
        let mut expected = [a, b, c];
        for s in &mut expected[..2] {
            // The recorded views without a clip plane get one that clips nothing.
            s.clip = Some(ClipPlane {
                normal: [1.0, 0.0, 0.0],
                offset: CLIP_OFF_OFFSET,
            });
        }
        for (i, e) in expected.iter_mut().enumerate() {
            e.transfer = TransferSource::Inline(e.transfer_functions().unwrap());
            assert_eq!(specs[4 * i].scene, *e, "keyframe {i}");
        }
        assert_eq!(specs[2].scene.camera.yaw_deg, 20.0, "halfway between keyframes 0 and 1");
    }

    #[test]
    fn angles_turn_the_short_way_and_one_keyframe_is_not_enough() {
        let keys = unwrap_degrees(vec![[0.0, 350.0], [0.5, 10.0], [1.0, 200.0]]);
        assert_eq!(keys, vec![[0.0, 350.0], [0.5, 370.0], [1.0, 200.0]]);
        let a = builtin("ball-lens").unwrap().scene;
        let e = from_keyframes(std::slice::from_ref(&a), 10, 30.0, [8, 8]).unwrap_err();
        assert!(e.to_string().contains("at least two keyframes"), "{e}");
        let mut b = a.clone();
        b.camera.projection = crate::scene::Projection::Orthographic;
        let (_, notes) = from_keyframes(&[a, b], 10, 30.0, [8, 8]).unwrap();
        assert!(notes[0].contains("projection"), "{notes:?}");
    }
}
