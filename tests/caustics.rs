//! Caustics and light transport of a ball lens (paper Fig. 4, Eqs. 9–13): focus position,
//! the role of the intensity law, and conservation of light power.

mod common;

use caustica::render::{DebugView, PreparedScene};
use caustica::transfer::{Curve, TransferFunctions};
use common::*;

const N: usize = 64;
const SIZE: u32 = 64;
const RADIUS: f32 = 0.2; // fraction of the box
const ETA: f32 = 1.5;

/// A clear glass ball (η = 1.5, no opacity, white medium) centred in the box, lit head-on.
fn ball(intensity_correction: bool) -> PreparedScene {
    ball_of(ETA, intensity_correction)
}

fn ball_of(eta: f32, intensity_correction: bool) -> PreparedScene {
    ball_with(eta, intensity_correction, caustica::scene::LightTransport::Beams)
}

fn ball_with(eta: f32, intensity_correction: bool, transport: caustica::scene::LightTransport) -> PreparedScene {
    let mut tf: TransferFunctions = plain_tf(vec![[0.0, 0.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    tf.eta = Curve {
        points: vec![[0.0, 1.0], [0.5, eta]],
    };
    let mut scene = head_on_scene(&tf);
    scene.quality.intensity_correction = intensity_correction;
    scene.quality.max_intensity_ratio = 4.0;
    scene.quality.light_transport = transport;
    prepared(scene, sphere(N, RADIUS, 0.5), tf)
}

/// Light buffer sums and centre values at each plane (relative depths).
fn profile(gpu: &mut Gpu, p: &PreparedScene, steps: usize) -> Vec<(f32, f64, f32)> {
    (0..=steps)
        .map(|k| {
            let depth = k as f32 / steps as f32;
            let out = gpu.debug(p, SIZE, DebugView::Light, depth);
            let px = &out.image.pixels;
            let total: f64 = px.iter().map(|p| p[1] as f64).sum();
            // Peak of the 2×2 centre texels (the optical axis passes between them).
            let c = SIZE as usize / 2;
            let centre = [(c - 1, c - 1), (c, c - 1), (c - 1, c), (c, c)]
                .iter()
                .map(|(x, y)| px[y * SIZE as usize + x][1])
                .fold(0.0f32, f32::max);
            (depth, total, centre)
        })
        .collect()
}

/// Depth (relative) of the sweep at which the centre light rises fastest: where the caustic
/// forms. (Past the focus the backward scheme cannot represent crossing rays, so the light
/// stays concentrated instead of spreading again; the onset is the well-defined quantity.)
fn caustic_onset(profile: &[(f32, f64, f32)]) -> (f32, f32) {
    let mut best = (0.0f32, 0.0f32);
    for w in profile.windows(2) {
        let rise = w[1].2 - w[0].2;
        if rise > best.1 {
            best = (0.5 * (w[0].0 + w[1].0), rise);
        }
    }
    best
}

#[test]
fn ball_lens_focuses_where_optics_predicts() {
    let mut gpu = Gpu::new();
    let p = ball(true);
    let profile = profile(&mut gpu, &p, 32);
    let peak = profile.iter().map(|r| r.2).fold(0.0f32, f32::max);
    assert!(peak > 4.0, "no caustic: centre light peaks at {peak} (unobstructed: 1)");
    let (depth, _) = caustic_onset(&profile);
    // Orthographic, head-on: the sweep spans the N-voxel box, the ball's centre at depth 0.5.
    let distance = (depth - 0.5) * N as f32;
    let r = RADIUS * N as f32;
    let paraxial = ETA * r / (2.0 * (ETA - 1.0));
    eprintln!(
        "caustic at {distance:.1} voxels from the centre ({:.2} R); paraxial focus {paraxial:.1} ({:.2} R)",
        distance / r,
        paraxial / r
    );
    // A ball lens focuses paraxial rays at nR/(2(n−1)) = 1.5 R from its centre and marginal
    // rays nearer, down to its surface (spherical aberration), so the caustic must lie between
    // R and 1.5 R. Slack of 2 voxels each side: one profile step (2 planes) and the smoothed
    // 1.5-voxel surface of the ball.
    assert!(
        distance >= r - 2.0 && distance <= paraxial + 2.0,
        "caustic at {distance} voxels, expected within [{}, {}]",
        r - 2.0,
        paraxial + 2.0
    );
}

#[test]
fn without_intensity_correction_there_is_no_caustic() {
    // Fig. 4b: backward advection alone only moves light around; bilinear filtering and the
    // (1 − α)·m attenuation are convex, so no value can exceed the unobstructed light (1), up
    // to 16-bit rounding (2^-11).
    let mut gpu = Gpu::new();
    let p = ball_with(ETA, false, caustica::scene::LightTransport::Backward);
    for depth in [0.5f32, 0.7, 0.75, 0.8, 0.9, 1.0] {
        let out = gpu.debug(&p, SIZE, DebugView::Light, depth);
        let max = out.image.max_value();
        assert!(
            max <= 1.0 + 1e-3,
            "light {max} at depth {depth} without intensity correction"
        );
    }
}

#[test]
fn non_absorbing_lens_conserves_light_power() {
    // A weak lens (η = 1.1, focus far outside the box) without opacity or medium: the intensity
    // law must keep the light power (sum over the orthographic buffer, constant texel area)
    // constant from plane to plane. Tolerance 2%: the semi-Lagrangian lookups diffuse light
    // over the buffer border and every plane rounds to 16 bits; measured on lavapipe: 1.2%
    // loss over the 65 planes, 0.04% per plane in the steepest part.
    let mut gpu = Gpu::new();
    let p = ball_of(1.1, true);
    let profile = profile(&mut gpu, &p, 16);
    let first = profile[0].1;
    for (depth, total, _) in &profile {
        let change = (total - first) / first;
        assert!(
            change.abs() < 0.02,
            "light power changed by {:.2}% at depth {depth}",
            100.0 * change
        );
    }
    // The lens does concentrate light on the axis, so the conservation is not trivial.
    let centre_max = profile.iter().map(|r| r.2).fold(0.0f32, f32::max);
    assert!(centre_max > 1.5, "the weak lens did not focus at all: {centre_max}");
}

#[test]
fn a_separate_volume_can_be_the_source_of_eta() {
    // Fig. 12e: refraction from a second volume. The main volume is empty; the η volume holds
    // the ball. A caustic must still form.
    let mut gpu = Gpu::new();
    let mut tf: TransferFunctions = plain_tf(vec![[0.0, 0.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    tf.eta = Curve {
        points: vec![[0.0, 1.0], [0.5, ETA]],
    };
    let mut scene = head_on_scene(&tf);
    scene.eta_volume = Some(caustica::scene::VolumeSource::builtin("test", 0));
    // Window [0, 1] for the main volume; the η volume is mapped through its own value range,
    // so give it values spanning [0, 1] with the ball at 0.5 and one voxel at 1.
    let mut eta_volume = sphere(N, RADIUS, 0.5);
    eta_volume.data[0] = 1.0;
    eta_volume.value_range = [0.0, 1.0];
    let mut p = prepared(scene, volume_from(N, |_, _, _| 0.0), tf);
    p.eta_volume = Some(std::sync::Arc::new(eta_volume));
    assert!(p.features().eta_volume);
    let profile = profile(&mut gpu, &p, 16);
    let peak = profile.iter().map(|r| r.2).fold(0.0f32, f32::max);
    assert!(peak > 4.0, "no caustic from the η volume: peak {peak}");
}
