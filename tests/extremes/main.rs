//! Stress suite: parameters at their limits. Every case must render without NaN or infinite
//! pixels, without negative radiance, within a stated brightness bound, bit-identically on a
//! second run, without validation errors and with a bounded number of planes (no hang: the
//! sweep is at most `MAX_PLANES` planes and every submission waits with a timeout).
//!
//! Each case prints one row of the closing table (run with `--nocapture`):
//! case | max pixel | bound | NaN/Inf | negative | ms | safeguard.
//!
//! This file holds the checks and scenes the cases share; `limits.rs` the cases, and
//! `each_safeguard.rs` one test per safeguard showing what breaks without it.

#[path = "../common/mod.rs"]
mod common;
mod each_safeguard;
mod limits;

use std::time::Instant;

use caustica::render::{
    safeguards, DebugView, PreparedScene, RenderOutput, RenderRequest, MAX_LIGHT_VALUE, MAX_PLANES,
};
use caustica::scene::{Projection, Toggle, MAX_SOFTNESS};
use caustica::transfer::{ColorRamp, Curve, TransferFunctions};
use caustica::volume::{Volume, VolumeError};
use common::*;

const N: usize = 24;
const SIZE: u32 = 32;

/// f16 storage rounds a stored value up by at most 2^-11 of itself; the colour buffer sums a
/// few hundred such values. 1% covers both with a wide margin.
const ROUNDING: f32 = 1.01;

/// Brightness bound of a scene without highlights: every pixel is a convex sum of particle
/// colour (≤ 1) times the light that reaches it, plus the background seen through (≤ its
/// maximum). The light is at most the source × quality.max_concentration (the power budget,
/// enforced per texel), and never above MAX_LIGHT_VALUE.
fn diffuse_bound(p: &PreparedScene, background_max: f32) -> f32 {
    let l = &p.scene.light;
    let source = l.color.iter().fold(0.0f32, |m, c| m.max(c * l.intensity));
    let light = (source * p.scene.quality.max_concentration).min(MAX_LIGHT_VALUE);
    light * ROUNDING + background_max
}

/// With highlights the sum of specular terms is bounded only by the colour-buffer clamp
/// MAX_RADIANCE (a sharp GGX lobe peaks at 1/(2π α³)); the background adds on top.
fn specular_bound(background_max: f32) -> f32 {
    safeguards::MAX_RADIANCE * ROUNDING + background_max
}

/// Renders twice and checks the invariants; prints the table row.
fn check(
    gpu: &mut Gpu,
    case: &str,
    p: &PreparedScene,
    req: &RenderRequest,
    bound: f32,
    safeguard: &str,
) -> RenderOutput {
    let start = Instant::now();
    let a = gpu.render(p, req);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let b = gpu.render(p, req);
    let (non_finite, negative) = a.image.count_invalid();
    let max = a.image.max_value();
    eprintln!("| {case} | {max:.4} | {bound:.4} | {non_finite} | {negative} | {ms:.0} | {safeguard} |");
    assert_eq!(non_finite, 0, "{case}: {non_finite} NaN/Inf values");
    assert_eq!(negative, 0, "{case}: {negative} negative values");
    assert!(max <= bound, "{case}: max pixel {max} above the bound {bound}");
    let bits = |o: &RenderOutput| -> Vec<u32> { o.image.pixels.iter().flatten().map(|v| v.to_bits()).collect() };
    assert!(bits(&a) == bits(&b), "{case}: two renders differ");
    assert!(a.stats.planes <= MAX_PLANES, "{case}: {} planes", a.stats.planes);
    a
}

fn request(w: u32, h: u32) -> RenderRequest {
    RenderRequest::new(w, h)
}

/// Glass filled with a faint white haze (opacity 0.03 per voxel), so the image shows the light
/// that reaches each point; η from `eta` over the data value.
fn glass_tf(eta: Vec<[f32; 2]>) -> TransferFunctions {
    let mut tf = plain_tf(vec![[0.0, 0.03]], vec![[0.0, 1.0, 1.0, 1.0]]);
    tf.eta = Curve { points: eta };
    tf
}

/// A ball with a hard edge: 1 inside radius `r` (fraction of the box), 0 outside, so η jumps
/// from one voxel to the next.
fn hard_ball(n: usize, r: f32) -> Volume {
    volume_from(n, |x, y, z| {
        let d = ((x - 0.5).powi(2) + (y - 0.5).powi(2) + (z - 0.5).powi(2)).sqrt();
        if d < r {
            1.0
        } else {
            0.0
        }
    })
}

/// Glass ball scene (specular off unless asked), lit at `polar` degrees, black background.
fn ball_scene(eta_max: f32, volume: Volume, specular: bool) -> PreparedScene {
    let tf = glass_tf(vec![[0.0, 1.0], [1.0, eta_max]]);
    let mut scene = head_on_scene(&tf);
    scene.light.polar_deg = 30.0;
    scene.shading.specular = if specular { 1.0 } else { 0.0 };
    prepared(scene, volume, tf)
}

/// Max of the light buffer on the last plane: the light itself, not the image.
fn light_max(gpu: &mut Gpu, p: &PreparedScene, size: u32) -> f32 {
    gpu.debug(p, size, DebugView::Light, 1.0).image.max_value()
}

/// η = 4 in front of a tilted interface, 1 behind it: view rays hitting it beyond the critical
/// angle are totally reflected, and with the interface normal 30° off the view axis the
/// reflected rays travel back toward the camera.
fn reflecting_interface(n: usize) -> Volume {
    let (s, c) = (30f32.to_radians().sin(), 30f32.to_radians().cos());
    volume_from(n, move |x, _, z| {
        let t = (x - 0.5) * s + (z - 0.5) * c;
        (0.5 - t * n as f32 / 1.5).clamp(0.0, 1.0)
    })
}

pub fn turning_back_scene() -> PreparedScene {
    let tf = glass_tf(vec![[0.0, 1.0], [1.0, 4.0]]);
    let mut scene = head_on_scene(&tf);
    scene.shading.specular = 0.0;
    scene.environment = caustica::scene::Environment::Studio { intensity: 1.0 };
    prepared(scene, reflecting_interface(N), tf)
}

/// Absorbing, coloured blobs with a linear opacity ramp: every optical term is exercised.
fn blobs_tf() -> TransferFunctions {
    let mut tf = plain_tf(vec![[0.0, 0.0], [1.0, 0.8]], vec![[0.0, 1.0, 0.6, 0.3]]);
    tf.eta = Curve {
        points: vec![[0.0, 1.0], [1.0, 1.6]],
    };
    tf
}

/// A strong ball lens (η = 2.5) near the front of a long box: the focus is well inside the
/// box, and the sweep runs 40 voxels past it, where the backward scheme keeps the light
/// concentrated.
pub fn focus_scene(max_concentration: f32) -> PreparedScene {
    let n = 32;
    let volume = volume_from(n, |x, y, z| {
        let d = ((x - 0.5).powi(2) + (y - 0.5).powi(2) + (z - 0.2).powi(2)).sqrt();
        (0.5 - (d - 0.15) * n as f32 / 1.5).clamp(0.0, 1.0)
    });
    let tf = glass_tf(vec![[0.0, 1.0], [1.0, 2.5]]);
    let mut scene = head_on_scene(&tf);
    scene.light.polar_deg = 0.0;
    scene.shading.specular = 0.0;
    scene.quality.max_concentration = max_concentration;
    // Ratio clamp relaxed: the budget alone must hold the light.
    scene.quality.max_intensity_ratio = 16.0;
    prepared(scene, volume, tf)
}

/// Light buffer at relative depth `depth` with the safeguards `off` switched off.
fn light_at(gpu: &mut Gpu, p: &PreparedScene, depth: f32, off: u32) -> caustica::render::RenderedImage {
    let mut req = request(SIZE, SIZE);
    req.debug_view = DebugView::Light;
    req.debug_depth = depth;
    req.safeguards_off = off;
    gpu.render(p, &req).image
}

/// Light power on an orthographic plane: the sum of the light buffer (green channel; every
/// texel covers the same area). The light enters with power SIZE² (light 1 everywhere).
fn power(img: &caustica::render::RenderedImage) -> f64 {
    img.pixels.iter().map(|q| q[1] as f64).sum()
}

fn image_with(gpu: &mut Gpu, p: &PreparedScene, size: u32, off: u32) -> caustica::render::RenderedImage {
    let mut req = request(size, size);
    req.safeguards_off = off;
    gpu.render(p, &req).image
}

/// Asserts that `p` renders without non-finite values with every safeguard on, and with some
/// once `bit` is switched off. MAX_RADIANCE is off in both renders: its clamp turns a NaN into
/// the maximum and would hide it.
fn assert_nan_without(gpu: &mut Gpu, p: &PreparedScene, size: u32, name: &str, bit: u32) {
    let base = safeguards::MAX_RADIANCE_CLAMP;
    let on = image_with(gpu, p, size, base).count_invalid().0;
    let off = image_with(gpu, p, size, base | bit).count_invalid().0;
    eprintln!("{name}: non-finite values {on} (on), {off} (off)");
    assert!(on == 0 && off > 0);
}

fn head_on(mut p: PreparedScene) -> PreparedScene {
    p.scene.light.polar_deg = 0.0;
    p.scene.camera.projection = Projection::Orthographic;
    p
}
