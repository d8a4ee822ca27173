//! The reference renders every feature of a scene: highlights (once per interface, whatever
//! the step), the clip plane (opacity only), a separate η volume, refraction switched off.

use std::sync::Arc;

use glam::DVec3;

use super::measure::{self, Region};
use super::photons::PhotonSettings;
use super::plane_light::{self, PlaneSettings};
use super::plane_tests::{tf, volume};
use super::shading::{cook_torrance, fresnel_dielectric};
use super::{render, ReferenceSettings};
use crate::scene::{ClipPlane, Environment, Quality, Scene, Toggle, VolumeSource};
use crate::scene::{PreparedScene, RenderedImage};
use crate::transfer::{ColorRamp, Curve, TransferFunctions};
use crate::volume::Volume;

/// Orthographic, head-on, the view spanning the volume's bounding sphere; light along the view
/// axis from behind the viewer, hard; a constant background.
fn scene(tf: &TransferFunctions, background: [f32; 3]) -> Scene {
    let mut scene = Scene::head_on("test", tf, 1.0, Quality::default());
    scene.environment = Environment::Color { color: background };
    scene
}

fn prepared(scene: Scene, vol: Volume, tf: TransferFunctions) -> PreparedScene {
    PreparedScene::from_parts(scene, vol, tf).unwrap()
}

fn settings(view_step_voxels: f64) -> ReferenceSettings {
    ReferenceSettings {
        photons: PhotonSettings {
            rays_per_voxel2: 4.0,
            ..PhotonSettings::default()
        },
        view_step_voxels,
        ..ReferenceSettings::default()
    }
}

fn centre(img: &RenderedImage) -> [f32; 4] {
    img.pixels[(img.height / 2 * img.width + img.width / 2) as usize]
}

#[test]
fn a_gap_in_glass_reflects_fresnel_times_cook_torrance_at_each_face_at_any_step() {
    // A slab of air (η = 1) in glass (η = 1.5 everywhere else, inside and outside the volume)
    // facing the camera, lit along the view axis: each of its two faces is an interface seen
    // at normal incidence with n = l = v, reflecting F = 0.04 times the GGX peak 1/(4π α²) of
    // the light there (1: nothing absorbs, nothing bends at normal incidence). The view ray
    // crosses each 1-voxel index ramp in 4 to 16 pieces; the highlight must not depend on that.
    // (Air in glass rather than a glass plate in air: the side faces of a glass plate guide
    // grazing light into it, where it is trapped and brightens the plate by up to 30%.)
    let vol = volume([40, 40, 24], |p| {
        (p.x.abs() < 16.0 && p.y.abs() < 16.0 && p.z.abs() < 4.0) as u8 as f64
    });
    let glass = tf(vec![[0.0, 1.5], [1.0, 1.0]], vec![[0.0, 0.0]]);
    let p = prepared(scene(&glass, [0.0; 3]), vol, glass);
    let z = DVec3::Z;
    let expected = 2.0 * fresnel_dielectric(1.0, 1.0, 1.5) * cook_torrance(z, z, z, p.scene.shading.roughness as f64);
    for step in [0.5, 0.25, 0.125] {
        let img = render(&p, 9, 9, &settings(step), false).unwrap();
        let v = centre(&img)[1] as f64;
        eprintln!("air gap in glass, view step {step}: highlight {v:.5} (2 F × GGX peak: {expected:.5})");
        // The weights of a monotone ramp's pieces sum to 1 exactly and n = v exactly; the
        // light's fluence and mean direction at the faces come from the photon grid (measured
        // 2.2e-4 above the exact product). Bound 1e-3.
        assert!((v - expected).abs() < 1e-3 * expected, "step {step}: {v} vs {expected}");
    }
    let mut off = p;
    off.scene.quality.specular = false;
    let img = render(&off, 9, 9, &settings(0.25), false).unwrap();
    assert_eq!(
        centre(&img)[1],
        0.0,
        "highlights switched off must leave the background"
    );
}

/// Two overlapping blobs with colour, opacity and a tinted medium, η constant.
fn blobs() -> (Volume, TransferFunctions) {
    let vol = volume([24; 3], |p| {
        let a = (-(p - DVec3::new(-3.0, 1.0, 0.0)).length_squared() / 20.0).exp();
        let b = (-(p - DVec3::new(4.0, -2.0, 2.0)).length_squared() / 12.0).exp();
        (0.9 * a + 0.7 * b).min(1.0)
    });
    let mut t = tf(vec![[0.0, 1.0]], vec![[0.0, 0.0], [0.3, 0.0], [0.9, 0.3]]);
    t.color = ColorRamp {
        points: vec![[0.0, 1.0, 0.5, 0.2], [1.0, 0.2, 0.6, 1.0]],
    };
    t.medium = ColorRamp {
        points: vec![[0.0, 1.0, 1.0, 1.0], [1.0, 0.8, 0.9, 0.95]],
    };
    (vol, t)
}

#[test]
fn the_clip_plane_removes_opacity_on_its_side_only() {
    // Clipping x > 0 (image right): there the image is that of the same volume without any
    // particles (the medium still tints the background); on the left it is unchanged, since
    // light along the view axis does not cross the plane.
    let (vol, t) = blobs();
    let size = 24u32;
    let base = scene(&t, [1.0; 3]);
    let full = render(
        &prepared(base.clone(), vol.clone(), t.clone()),
        size,
        size,
        &settings(0.25),
        false,
    )
    .unwrap();
    let mut clipped_scene = base.clone();
    clipped_scene.clip = Some(ClipPlane {
        normal: [1.0, 0.0, 0.0],
        offset: 0.0,
    });
    let clipped = render(
        &prepared(clipped_scene, vol.clone(), t.clone()),
        size,
        size,
        &settings(0.25),
        false,
    )
    .unwrap();
    let mut clear = t.clone();
    clear.opacity = Curve::constant(0.0);
    let no_particles = render(
        &prepared(scene(&clear, [1.0; 3]), vol, clear),
        size,
        size,
        &settings(0.25),
        false,
    )
    .unwrap();
    let (mut right, mut left, mut right_full, mut tint) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    let s = size as usize;
    for y in 0..s {
        for x in 0..s {
            let i = y * s + x;
            for c in 0..3 {
                let (cl, fu, np) = (clipped.pixels[i][c], full.pixels[i][c], no_particles.pixels[i][c]);
                if x > s / 2 + 1 {
                    right = right.max((cl - np).abs());
                    right_full = right_full.max((fu - np).abs());
                    tint = tint.max(1.0 - np);
                } else if x < s / 2 - 2 {
                    left = left.max((cl - fu).abs());
                }
            }
        }
    }
    eprintln!("clip: right half vs no particles {right:.1e} (unclipped: {right_full:.3}); left half vs unclipped {left:.1e}; medium tint {tint:.3}");
    assert!(
        right_full > 0.05 && tint > 0.05,
        "the test volume must show particles and a tint on the right"
    );
    // The same rays through the same η and medium: only the steps' split at the plane differs
    // (pieces end on it), which moves the sample points of a smooth field. Bound 1e-4.
    assert!(
        right < 1e-4,
        "clipped half differs from the particle-free image by {right}"
    );
    assert!(left < 1e-4, "unclipped half changed by {left}");
}

/// A glass ball of values 0..1 (η 1 → 1.5), R = 8, in 24³; fog of constant opacity that the
/// light's caustic shows up in.
fn ball_and_fog() -> (Volume, TransferFunctions) {
    let vol = volume([24; 3], |p| (0.5 - (p.length() - 8.0) / 1.5).clamp(0.0, 1.0));
    let t = tf(vec![[0.0, 1.0], [1.0, 1.5]], vec![[0.0, 0.03]]);
    (vol, t)
}

#[test]
fn a_separate_eta_volume_refracts_as_the_same_eta_in_the_volume() {
    // The ball's values in the η volume and none in the volume must give what the ball in the
    // volume gives (opacity and colour do not depend on the value here), in the image and in
    // the light on a plane; without the η volume there is no caustic.
    let (ball, t) = ball_and_fog();
    let empty = Volume::new([24; 3], [1.0; 3], vec![0.0; 24 * 24 * 24]).unwrap();
    // Highlights need the volume's gradient, which only one of the two has.
    let mut base = scene(&t, [0.0; 3]);
    base.quality.specular = false;
    let in_volume = prepared(base.clone(), ball.clone(), t.clone());
    let mut with_eta = base.clone();
    with_eta.eta_volume = Some(VolumeSource::builtin("test", 0));
    let mut separate = prepared(with_eta.clone(), empty.clone(), t.clone());
    separate.eta_volume = Some(Arc::new(ball.clone()));
    let none = prepared(base, empty.clone(), t.clone());
    let size = 24;
    let s = settings(0.25);
    let (a, b, c) = (
        render(&in_volume, size, size, &s, false).unwrap(),
        render(&separate, size, size, &s, false).unwrap(),
        render(&none, size, size, &s, false).unwrap(),
    );
    let diff = |x: &RenderedImage, y: &RenderedImage| {
        x.pixels
            .iter()
            .zip(&y.pixels)
            .flat_map(|(p, q)| (0..3).map(move |k| (p[k] - q[k]).abs()))
            .fold(0.0f32, f32::max)
    };
    let (same, without) = (diff(&a, &b), diff(&a, &c));
    // The plane trace too, and with the η volume on a coarser grid over the same box.
    let planes = [6.0 + in_volume_view_z(&in_volume)];
    let ps = PlaneSettings::default();
    let light = |p: &PreparedScene| plane_light::trace_scene(p, size, size, &planes, &ps).unwrap().planes[0].channel(1);
    let (la, lb) = (light(&in_volume), light(&separate));
    let mut coarse = prepared(with_eta, empty, t);
    coarse.eta_volume = Some(Arc::new(crate::volume::resample::resample(&ball, [12; 3]).unwrap()));
    let lc = light(&coarse);
    let region = Region::all(&la);
    let (l_same, l_coarse) = (
        measure::relative_l1(&lb, &la, region).unwrap(),
        measure::relative_l1(&lc, &la, region).unwrap(),
    );
    let peak = measure::peak(&la).value;
    eprintln!(
        "η volume: image max |Δ| {same:.1e} (without it {without:.3}); light on a plane rel. L1 {l_same:.1e}, from a 12³ η volume {l_coarse:.3} (peak {peak:.2})"
    );
    assert!(
        without > 0.01,
        "the caustic must show in the image for the test to mean anything"
    );
    assert!(peak > 2.0, "the ball must focus light onto the plane");
    // Identical η fields and optics: rounding only (f32 pixels).
    assert!(same < 1e-6, "image differs by {same}");
    assert!(l_same < 1e-12, "light differs by {l_same}");
    // The coarse η volume is a blurrier ball; the same caustic within 25% (measured 11%).
    assert!(l_coarse < 0.25, "coarse η volume: {l_coarse}");
}

/// View depth of the volume's centre in the scene's camera.
fn in_volume_view_z(p: &PreparedScene) -> f64 {
    let v = &p.volume;
    let view = crate::scene::ViewSetup::new(&p.scene, v.dims, v.spacing, 8, 8).unwrap();
    view.view_from_world.transform_point3(glam::Vec3::ZERO).z as f64
}

#[test]
fn refraction_switched_off_leaves_the_light_straight() {
    // As the GPU with `quality.refraction = "off"`: the light on a plane behind the ball is
    // that of the same scene with a constant η (the fog's shadow, no caustic).
    let (ball, t) = ball_and_fog();
    let mut off = scene(&t, [0.0; 3]);
    off.quality.refraction = Toggle::Off;
    let off = prepared(off, ball.clone(), t.clone());
    let mut flat = t.clone();
    flat.eta = Curve::constant(1.0);
    let flat = prepared(scene(&flat, [0.0; 3]), ball, flat);
    let planes = [6.0 + in_volume_view_z(&off)];
    let light = |p: &PreparedScene| {
        plane_light::trace_scene(p, 16, 16, &planes, &PlaneSettings::default())
            .unwrap()
            .planes[0]
            .channel(1)
    };
    let (a, b) = (light(&off), light(&flat));
    let l1 = measure::relative_l1(&a, &b, Region::all(&b)).unwrap();
    let dimmest = b.data.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(dimmest < 0.7, "the fog must shadow the plane: {dimmest}");
    // The same straight rays through the same optics: rounding only.
    assert!(l1 < 1e-12, "refraction off differs from constant η by {l1}");
}
