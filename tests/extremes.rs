//! Stress suite: parameters at their limits. Every case must render without NaN or infinite
//! pixels, without negative radiance, within a stated brightness bound, bit-identically on a
//! second run, without validation errors and with a bounded number of planes (no hang: the
//! sweep is at most `MAX_PLANES` planes and every submission waits with a timeout).
//!
//! Each case prints one row of the closing table (run with `--nocapture`):
//! case | max pixel | bound | NaN/Inf | negative | ms | safeguard.

mod common;

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
    let light = (source * p.scene.quality.max_concentration()).min(MAX_LIGHT_VALUE);
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

#[test]
fn eta_contrast_one_to_three_across_one_voxel() {
    let mut gpu = Gpu::new();
    for specular in [false, true] {
        let p = ball_scene(3.0, hard_ball(N, 0.3), specular);
        assert!(p.features().intensity_correction);
        let bound = if specular {
            specular_bound(0.0)
        } else {
            diffuse_bound(&p, 0.0)
        };
        let case = if specular {
            "η 1→3 in one voxel, specular"
        } else {
            "η 1→3 in one voxel"
        };
        check(
            &mut gpu,
            case,
            &p,
            &request(SIZE, SIZE),
            bound,
            "CONCENTRATION, INTENSITY_RATIO, FOLD",
        );
        let light = light_max(&mut gpu, &p, SIZE);
        assert!(light <= diffuse_bound(&p, 0.0), "light {light} above the budget");
    }
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

#[test]
fn index_gradient_turns_view_rays_back() {
    let mut gpu = Gpu::new();
    let p = turning_back_scene();
    // Studio environment: at most 0.95 (its brightest sky colour).
    check(
        &mut gpu,
        "rays turned back (η 4→1, 30° interface)",
        &p,
        &request(SIZE, SIZE),
        diffuse_bound(&p, 0.95),
        "VIEW_MIN_Z, LIGHT_MIN_Z",
    );
}

#[test]
fn light_from_zero_to_89_degrees() {
    let mut gpu = Gpu::new();
    for polar in [0.0f32, 45.0, 80.0, 89.0] {
        let mut p = ball_scene(1.5, sphere(N, 0.3, 1.0), false);
        p.scene.light.polar_deg = polar;
        p.scene.light.azimuth_deg = 60.0;
        let bound = diffuse_bound(&p, 0.0);
        check(
            &mut gpu,
            &format!("light at {polar}°"),
            &p,
            &request(SIZE, SIZE),
            bound,
            "MIN_LIGHT_DIR_Z",
        );
    }
}

/// Absorbing, coloured blobs with a linear opacity ramp: every optical term is exercised.
fn blobs_tf() -> TransferFunctions {
    let mut tf = plain_tf(vec![[0.0, 0.0], [1.0, 0.8]], vec![[0.0, 1.0, 0.6, 0.3]]);
    tf.eta = Curve {
        points: vec![[0.0, 1.0], [1.0, 1.6]],
    };
    tf
}

#[test]
fn sample_distance_from_005_to_8_voxels() {
    let mut gpu = Gpu::new();
    for d in [0.05f32, 1.0, 8.0] {
        let tf = blobs_tf();
        let mut scene = head_on_scene(&tf);
        scene.quality.sample_distance = d;
        let p = prepared(scene, sphere(N, 0.35, 1.0), tf);
        check(
            &mut gpu,
            &format!("sample distance {d} voxels"),
            &p,
            &request(SIZE, SIZE),
            specular_bound(0.0),
            "MAX_RADIANCE, MAX_PLANES",
        );
    }
}

#[test]
fn softness_from_zero_to_maximum() {
    let mut gpu = Gpu::new();
    for softness in [0.0, 0.5, MAX_SOFTNESS] {
        let mut p = ball_scene(1.5, sphere(N, 0.3, 1.0), false);
        p.scene.light.softness = softness;
        let bound = diffuse_bound(&p, 0.0);
        check(
            &mut gpu,
            &format!("softness {softness}"),
            &p,
            &request(SIZE, SIZE),
            bound,
            "convex filter weights",
        );
    }
}

#[test]
fn opacity_zero_and_one_everywhere_and_black_medium() {
    let mut gpu = Gpu::new();
    let cases: [(&str, f32, [f32; 3], &str); 3] = [
        ("opacity 0 everywhere", 0.0, [1.0; 3], "SEGMENT_OPACITY"),
        ("opacity 1 everywhere", 1.0, [1.0; 3], "MAX_OPTICAL_DEPTH_PER_VOXEL"),
        ("black medium", 0.2, [0.0; 3], "MAX_OPTICAL_DEPTH_PER_VOXEL"),
    ];
    for (case, alpha, medium, safeguard) in cases {
        let mut tf = blobs_tf();
        tf.opacity = Curve::constant(alpha);
        tf.medium = ColorRamp::constant(medium);
        let mut scene = head_on_scene(&tf);
        scene.environment = caustica::scene::Environment::Color { color: [0.5; 3] };
        let p = prepared(scene, sphere(N, 0.3, 1.0), tf);
        let out = check(&mut gpu, case, &p, &request(SIZE, SIZE), specular_bound(0.5), safeguard);
        if alpha == 0.0 {
            // Nothing absorbs and the medium is white: the background shows through everywhere
            // (bent, but the background is uniform), plus highlights.
            assert!(out.image.pixels.iter().all(|q| q[1] >= 0.5 - 1e-3));
        }
    }
}

#[test]
fn degenerate_volumes() {
    let mut gpu = Gpu::new();
    let tf = blobs_tf();
    let volumes: Vec<(&str, Volume)> = vec![
        ("volume 1×1×1", Volume::new([1, 1, 1], [1.0; 3], vec![1.0]).unwrap()),
        (
            "volume 2×2×2",
            Volume::new([2, 2, 2], [1.0; 3], vec![0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0, 1.0]).unwrap(),
        ),
        (
            "volume 1×24×24",
            Volume::new([1, N, N], [1.0; 3], (0..N * N).map(|i| (i % 7) as f32 / 6.0).collect()).unwrap(),
        ),
        (
            "spacing 1:20 (24×24×3)",
            Volume::new(
                [N, N, 3],
                [1.0, 1.0, 20.0],
                (0..N * N * 3).map(|i| (i % 5) as f32 / 4.0).collect(),
            )
            .unwrap(),
        ),
        (
            "spacing 20:1 (2×24×24)",
            Volume::new(
                [2, N, N],
                [20.0, 1.0, 1.0],
                (0..N * N * 2).map(|i| (i % 3) as f32 / 2.0).collect(),
            )
            .unwrap(),
        ),
    ];
    for (case, volume) in volumes {
        let mut scene = head_on_scene(&tf);
        scene.camera.projection = Projection::Perspective;
        scene.camera.yaw_deg = 30.0;
        scene.camera.pitch_deg = 20.0;
        // Window [0, 1] (from head_on_scene): the 1×1×1 volume's own range would be empty.
        let p = prepared(scene, volume, tf.clone());
        check(
            &mut gpu,
            case,
            &p,
            &request(SIZE, SIZE),
            specular_bound(0.0),
            "MAX_RADIANCE",
        );
    }
}

#[test]
fn constant_volume_with_refraction_forced_on() {
    // ∇η and ∇f are exactly zero: no normal, no highlight, no bending. The window of a
    // constant volume is empty (min = max), which the upload treats as a threshold.
    let mut gpu = Gpu::new();
    for value in [0.0f32, 0.5] {
        let tf = blobs_tf();
        let mut scene = head_on_scene(&tf);
        scene.window = None;
        scene.quality.refraction = Toggle::On;
        scene.environment = caustica::scene::Environment::Color { color: [0.25; 3] };
        let p = prepared(scene, volume_from(N, |_, _, _| value), tf);
        assert!(p.features().specular);
        check(
            &mut gpu,
            &format!("constant volume {value}"),
            &p,
            &request(SIZE, SIZE),
            diffuse_bound(&p, 0.25),
            "GRADIENT_LENGTH",
        );
    }
}

#[test]
fn nan_and_infinite_voxels_are_rejected_with_a_clear_error() {
    // Contract: a volume with NaN or ±Inf samples is bad input. Nothing sensible can be
    // windowed or interpolated from it, and replacing values silently would hide a corrupt
    // file; the error counts them.
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut data = vec![0.5f32; 8];
        data[3] = bad;
        data[5] = bad;
        let err = Volume::new([2, 2, 2], [1.0; 3], data).unwrap_err();
        assert!(matches!(err, VolumeError::NonFinite { count: 2 }), "{bad}: {err}");
        assert!(err.to_string().contains("2 non-finite voxel values (NaN or infinity)"));
    }
    // The same through the command line: exit code 1, the message, no image.
    let dir = std::env::temp_dir().join(format!("caustica-extremes-nan-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let raw: Vec<u8> = [1.0f32, f32::NAN, f32::INFINITY, 0.0, 1.0, 2.0, 3.0, f32::NEG_INFINITY]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    std::fs::write(dir.join("nan.raw"), raw).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_caustica"))
        .current_dir(&dir)
        .args([
            "render",
            "nan.raw",
            "--raw-dims",
            "2x2x2",
            "--raw-type",
            "f32",
            "-o",
            "out.png",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("3 non-finite voxel values"), "{stderr}");
    assert!(!dir.join("out.png").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn viewports_from_one_pixel_to_the_device_maximum() {
    let mut gpu = Gpu::new();
    let max = gpu.ctx.limits().max_image_dimension2_d;
    let p = ball_scene(1.5, sphere(N, 0.3, 1.0), true);
    for (w, h) in [(1, 1), (1, 2), (3, 1), (64, 64), (max, 1), (1, max)] {
        check(
            &mut gpu,
            &format!("viewport {w}×{h}"),
            &p,
            &request(w, h),
            specular_bound(0.0),
            "bounds-checked texel fetches",
        );
    }
    // One past the maximum is refused before anything is allocated.
    let err = gpu.renderer.render(&p, &request(max + 1, 1)).err().expect("too wide");
    assert!(err.to_string().contains("must be between 1×1"), "{err}");
}

#[test]
fn camera_inside_the_volume() {
    let mut gpu = Gpu::new();
    for distance in [0.5f32, 0.05, 0.0001] {
        let tf = blobs_tf();
        let mut scene = head_on_scene(&tf);
        scene.camera.projection = Projection::Perspective;
        scene.camera.distance = distance;
        scene.camera.fov_deg = 90.0;
        let p = prepared(scene, sphere(N, 0.45, 1.0), tf);
        check(
            &mut gpu,
            &format!("camera inside, distance {distance}"),
            &p,
            &request(SIZE, SIZE),
            specular_bound(0.0),
            "NEAR_PLANE",
        );
    }
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
    scene.quality.max_concentration = Some(max_concentration);
    // Ratio clamp relaxed: the budget alone must hold the light.
    scene.quality.max_intensity_ratio = 16.0;
    prepared(scene, volume, tf)
}

#[test]
fn focal_point_where_the_area_goes_to_zero() {
    let mut gpu = Gpu::new();
    let p = focus_scene(64.0);
    check(
        &mut gpu,
        "focus (η 2.5 ball lens)",
        &p,
        &request(SIZE, SIZE),
        diffuse_bound(&p, 0.0),
        "CONCENTRATION, FOLD, INTENSITY_RATIO",
    );
    // The light itself, over the depth of the sweep: a caustic forms, and nowhere exceeds
    // the budget.
    let peak = (1..=10)
        .map(|k| light_at(&mut gpu, &p, k as f32 / 10.0, 0).max_value())
        .fold(0.0f32, f32::max);
    let budget = diffuse_bound(&p, 0.0);
    eprintln!("| focus: light buffer, peak over depth | {peak:.4} | {budget:.4} | 0 | 0 | | CONCENTRATION |");
    assert!(peak > 4.0, "no caustic at all: {peak}");
    assert!(peak <= budget, "light {peak} above the budget");
}

#[test]
fn dispersal_where_the_area_grows_without_bound() {
    // A bubble (η 1) in glass (η 2.5): a diverging lens. Light spreads, the intensity law
    // ratio falls below 1 plane after plane, and the light must stay finite and ≥ 0.
    let mut gpu = Gpu::new();
    let tf = glass_tf(vec![[0.0, 2.5], [1.0, 1.0]]);
    let mut scene = head_on_scene(&tf);
    scene.shading.specular = 0.0;
    scene.light.polar_deg = 10.0;
    let p = prepared(scene, sphere(N, 0.3, 1.0), tf);
    check(
        &mut gpu,
        "dispersal (η 1 bubble in η 2.5)",
        &p,
        &request(SIZE, SIZE),
        diffuse_bound(&p, 0.0),
        "INTENSITY_RATIO, MIN_CONCENTRATION",
    );
    let light = gpu.debug(&p, SIZE, DebugView::Light, 1.0);
    let min = light
        .image
        .pixels
        .iter()
        .flat_map(|q| &q[..3])
        .fold(f32::MAX, |m, v| m.min(*v));
    assert!(min >= 0.0 && light.image.count_invalid() == (0, 0));
}

#[test]
fn brightest_allowed_light() {
    // light colour × intensity at its maximum (scene::MAX_LIGHT_RADIANCE = MAX_LIGHT_VALUE)
    // through a focusing lens: the light buffer is bounded by MAX_LIGHT_VALUE, f16-safe.
    let mut gpu = Gpu::new();
    let mut p = focus_scene(64.0);
    p.scene.light.intensity = caustica::scene::MAX_LIGHT_RADIANCE;
    p.scene.validate().unwrap();
    let out = check(
        &mut gpu,
        "light intensity 16384 through a focus",
        &p,
        &request(SIZE, SIZE),
        diffuse_bound(&p, 0.0),
        "MAX_LIGHT",
    );
    assert!(out.image.max_value() > 1000.0, "the light did not reach the image");
    p.scene.light.intensity *= 2.0;
    assert!(p.scene.validate().is_err(), "a brighter light must be rejected");
}

// ---- Each safeguard is needed: switched off, the property it protects breaks. ----

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

#[test]
fn safeguard_concentration_bounds_light_behind_a_focus() {
    // η 1→3 ball, head-on: behind it the backward scheme keeps concentrating the light.
    // Budget 64: measured without it 336 at the back of the box.
    let mut gpu = Gpu::new();
    let p = head_on(ball_scene(3.0, hard_ball(N, 0.3), false));
    let budget = p.scene.quality.max_concentration() * ROUNDING;
    let on = light_at(&mut gpu, &p, 1.0, 0).max_value();
    let off = light_at(&mut gpu, &p, 1.0, safeguards::CONCENTRATION).max_value();
    eprintln!("CONCENTRATION: light max {on} (on), {off} (off), budget {budget}");
    assert!(on <= budget && off > budget, "on {on}, off {off}, budget {budget}");
}

#[test]
fn safeguard_fold_stops_concentration_past_the_focus() {
    // Past the focus of the η 2.5 lens the light must not gain power: the input power is
    // SIZE² and the haze only absorbs. Without fold detection the backward map keeps
    // concentrating (measured: power 1178 of 1024 at mid-depth, vs 598).
    let mut gpu = Gpu::new();
    let p = focus_scene(64.0);
    let input = (SIZE * SIZE) as f64;
    let on = power(&light_at(&mut gpu, &p, 0.5, 0));
    let off = power(&light_at(&mut gpu, &p, 0.5, safeguards::FOLD));
    eprintln!("FOLD: power behind the focus {on:.0} (on), {off:.0} (off), input {input}");
    assert!(on < input && off > input, "on {on}, off {off}");
}

#[test]
fn safeguard_light_min_z_keeps_reflected_light_out() {
    // η 4 → 1 at a 30° interface reflects head-on light totally, back toward the light: what
    // reaches the back of the box is less than what entered. Without the bound on the light
    // direction, light travelling (nearly) inside the planes is looked up from far away and
    // amplified by the area ratio (measured: 1984 of 1024 vs 334).
    let mut gpu = Gpu::new();
    let p = head_on(turning_back_scene());
    let input = (SIZE * SIZE) as f64;
    let on = power(&light_at(&mut gpu, &p, 1.0, 0));
    let off = power(&light_at(&mut gpu, &p, 1.0, safeguards::LIGHT_MIN_Z));
    eprintln!("LIGHT_MIN_Z: power at the back {on:.0} (on), {off:.0} (off), input {input}");
    assert!(on < input && off > input, "on {on}, off {off}");
}

#[test]
fn safeguard_intensity_ratio_limits_growth_per_plane() {
    // From one plane to the next the largest light value grows at most by max_intensity_ratio
    // (bilinear gathers and transmittance are convex; the unobstructed light is 1).
    let mut gpu = Gpu::new();
    let tf = blobs_tf();
    let p = prepared(head_on_scene(&tf), sphere(N, 0.35, 1.0), tf);
    let planes = gpu.render(&p, &request(SIZE, SIZE)).stats.planes;
    let max_ratio = p.scene.quality.max_intensity_ratio;
    let worst_growth = |gpu: &mut Gpu, off: u32| {
        let mut prev = 1.0f32;
        let mut worst = 0.0f32;
        for k in 0..planes {
            let depth = k as f32 / (planes - 1) as f32;
            let max = light_at(gpu, &p, depth, off).max_value();
            worst = worst.max(max / prev.max(1.0));
            prev = max;
        }
        worst
    };
    let on = worst_growth(&mut gpu, 0);
    let off = worst_growth(&mut gpu, safeguards::INTENSITY_RATIO);
    eprintln!("INTENSITY_RATIO: worst growth per plane {on} (on), {off} (off), limit {max_ratio}");
    assert!(
        on <= max_ratio * ROUNDING && off > max_ratio * ROUNDING,
        "on {on}, off {off}"
    );
}

#[test]
fn safeguard_max_light_keeps_f16_light_finite() {
    // The brightest allowed light through a focus: concentrated 4× it passes the 16-bit float
    // maximum (65504). Without the clamp it leaves the stated bound, and the f16 store either
    // overflows to infinity or saturates at 65504, depending on the device's rounding
    // (lavapipe saturates).
    let mut gpu = Gpu::new();
    let mut p = focus_scene(64.0);
    p.scene.light.intensity = caustica::scene::MAX_LIGHT_RADIANCE;
    let depths = [0.15f32, 0.2, 0.25, 0.3, 0.35];
    let scan = |gpu: &mut Gpu, off: u32| {
        depths
            .iter()
            .map(|d| {
                let img = light_at(gpu, &p, *d, off);
                (img.count_invalid().0, img.max_value())
            })
            .fold((0, 0.0f32), |(n, m), (a, b)| (n + a, m.max(b)))
    };
    let (bad_on, max_on) = scan(&mut gpu, 0);
    let (bad_off, max_off) = scan(&mut gpu, safeguards::MAX_LIGHT);
    eprintln!("MAX_LIGHT: max {max_on}, non-finite {bad_on} (on); max {max_off}, non-finite {bad_off} (off)");
    assert!(bad_on == 0 && max_on <= MAX_LIGHT_VALUE);
    assert!(bad_off > 0 || max_off > MAX_LIGHT_VALUE, "the clamp changed nothing");
}

/// Hard η 1.5 ball seen head-on with the light from behind the viewer: the centre pixel's
/// normal, view and light directions coincide, the peak of a sharp highlight.
fn mirror_ball(specular: f32) -> PreparedScene {
    let mut p = head_on(ball_scene(1.5, hard_ball(N, 0.3), true));
    p.scene.shading.specular = specular;
    p.scene.shading.roughness = 0.0;
    p
}

#[test]
fn safeguard_ggx_alpha_keeps_a_mirror_highlight_finite() {
    // Roughness 0: α = 0 makes the GGX distribution 0/0 where n = h (the centre pixel of an
    // odd-sized image). MAX_RADIANCE is off in both renders so that it cannot hide a NaN.
    let mut gpu = Gpu::new();
    let p = mirror_ball(1.0);
    assert_nan_without(&mut gpu, &p, 33, "GGX_ALPHA", safeguards::GGX_ALPHA);
}

#[test]
fn safeguard_max_radiance_keeps_f16_colour_finite() {
    // Specular 100 (the maximum) on a mirror highlight: 100 × F × 1/(π α²) with α = 1e-3 is
    // about 1e6, beyond the 16-bit colour buffer (which overflows to infinity or saturates at
    // 65504 depending on the device's rounding).
    let mut gpu = Gpu::new();
    let p = mirror_ball(caustica::scene::MAX_SPECULAR);
    let on = image_with(&mut gpu, &p, 33, 0);
    let off = image_with(&mut gpu, &p, 33, safeguards::MAX_RADIANCE_CLAMP);
    let (bad_off, max_off) = (off.count_invalid().0, off.max_value());
    eprintln!(
        "MAX_RADIANCE: max {} (on); max {max_off}, non-finite {bad_off} (off)",
        on.max_value()
    );
    assert_eq!(on.count_invalid(), (0, 0));
    assert!(on.max_value() <= specular_bound(0.0));
    assert!(
        bad_off > 0 || max_off > specular_bound(0.0),
        "the clamp changed nothing"
    );
}

#[test]
fn safeguard_segment_opacity_handles_transparent_segments() {
    let mut gpu = Gpu::new();
    let mut tf = blobs_tf();
    tf.opacity = Curve::constant(0.0);
    let p = prepared(head_on_scene(&tf), sphere(N, 0.35, 1.0), tf);
    assert_nan_without(&mut gpu, &p, SIZE, "SEGMENT_OPACITY", safeguards::SEGMENT_OPACITY);
}

#[test]
fn safeguard_gradient_length_handles_homogeneous_regions() {
    let mut gpu = Gpu::new();
    let tf = blobs_tf();
    let mut scene = head_on_scene(&tf);
    scene.quality.refraction = Toggle::On;
    let p = prepared(scene, volume_from(N, |_, _, _| 0.5), tf);
    assert_nan_without(&mut gpu, &p, SIZE, "GRADIENT_LENGTH", safeguards::GRADIENT_LENGTH);
}

#[test]
fn safeguard_view_min_z_stops_rays_that_turned_back() {
    // Behind a totally reflecting interface (η 4 → 1, its normal 30° off the view axis) lies
    // an opaque red wall. Rays reflected back toward the camera must not see it. Without the
    // safeguard they keep stepping with a negative z direction, i.e. mirrored, and composite
    // the wall anyway.
    let mut gpu = Gpu::new();
    let mut tf = plain_tf(vec![[0.0, 0.0], [0.5, 0.0], [0.6, 1.0]], vec![[0.0, 1.0, 0.0, 0.0]]);
    tf.eta = Curve {
        points: vec![[0.0, 1.0], [1.0, 4.0]],
    };
    let mut scene = head_on_scene(&tf);
    scene.shading.specular = 0.0;
    scene.eta_volume = Some(caustica::scene::VolumeSource::Builtin {
        name: "test".into(),
        resolution: 0,
    });
    let wall = volume_from(N, |_, _, z| if z > 0.85 { 1.0 } else { 0.0 });
    let mut p = prepared(scene, wall, tf);
    p.eta_volume = Some(std::sync::Arc::new(reflecting_interface(N)));
    assert!(p.features().eta_volume);
    let red_pixels = |img: &caustica::render::RenderedImage| img.pixels.iter().filter(|q| q[0] > 0.1).count();
    let on = red_pixels(&image_with(&mut gpu, &p, SIZE, 0));
    let off = red_pixels(&image_with(&mut gpu, &p, SIZE, safeguards::VIEW_MIN_Z));
    // Without the interface the wall shows wherever the box is (a third of this view: the
    // orthographic view spans the box's diagonal), so it is not invisible for another reason.
    p.eta_volume = Some(std::sync::Arc::new(volume_from(N, |_, _, _| 0.0)));
    let clear = red_pixels(&image_with(&mut gpu, &p, SIZE, 0));
    eprintln!(
        "VIEW_MIN_Z: pixels showing the wall {on} (on), {off} (off), {clear} without the interface, of {}",
        SIZE * SIZE
    );
    // Orthographic and head-on, every ray meets the interface 30° off its normal, beyond the
    // critical angle (14.5°): all are reflected.
    assert!(
        clear > (SIZE * SIZE / 4) as usize,
        "the wall is not visible at all: {clear}"
    );
    assert!(on == 0 && off > 0, "on {on}, off {off}");
}

/// An opaque slab (voxels 4–12 in depth) in front of an index drop from η 4 to 1 (voxels
/// 14–18, a second volume), both exactly perpendicular to the view axis, lit head-on: ∇η
/// points exactly against the light, with no sideways part. With planes 8 voxels apart one
/// step of Eq. 10 (v += Δs ∇η) overshoots and reverses the light: v = (0, 0, < 0). Turning it
/// back into the sweep (LIGHT_MIN_Z) needs its sideways direction, normalize((0, 0, 0)).
fn reversed_light_scene() -> PreparedScene {
    let mut tf = plain_tf(vec![[0.0, 0.0], [0.5, 0.0], [0.6, 1.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    tf.eta = Curve {
        points: vec![[0.0, 1.0], [1.0, 4.0]],
    };
    let mut scene = head_on_scene(&tf);
    scene.shading.specular = 0.0;
    scene.quality.sample_distance = 8.0;
    scene.quality.light_filter = false;
    scene.eta_volume = Some(caustica::scene::VolumeSource::Builtin {
        name: "test".into(),
        resolution: 0,
    });
    let n = N as f32;
    let slab = volume_from(N, move |_, _, z| if (4.0..12.0).contains(&(z * n)) { 1.0 } else { 0.0 });
    let mut p = prepared(scene, slab, tf);
    p.eta_volume = Some(std::sync::Arc::new(volume_from(N, move |_, _, z| {
        (1.0 - (z * n - 14.0) / 4.0).clamp(0.0, 1.0)
    })));
    p
}

#[test]
fn safeguard_direction_length_handles_a_reversed_light() {
    let mut gpu = Gpu::new();
    let p = reversed_light_scene();
    assert!(p.features().eta_volume && p.features().refraction);
    check(
        &mut gpu,
        "light reversed by an index drop (η 4→1, Δs 8)",
        &p,
        &request(SIZE, SIZE),
        diffuse_bound(&p, 0.0),
        "DIRECTION_LENGTH, LIGHT_MIN_Z",
    );
    // The texels in the slab's shadow: the centre of the view (the box covers its middle
    // third; around it light passes beside the box).
    let centre = |img: &caustica::render::RenderedImage| -> Vec<[f32; 4]> {
        (12..20)
            .flat_map(|y| (12..20).map(move |x| (y * SIZE + x) as usize))
            .map(|i| img.pixels[i])
            .collect()
    };
    // The scene does what it says: behind the drop the light points back toward the camera
    // (z of the direction -1, shown as 0).
    let dir = centre(&gpu.debug(&p, SIZE, DebugView::LightDirection, 1.0).image);
    assert!(
        dir.iter().all(|q| q[2] < 0.01),
        "the light was not reversed: {:?}",
        dir[0]
    );
    // Without the safeguard the sideways direction is NaN, the lookup point of the light too,
    // and a NaN point counts as outside the buffer: the reversed texels get the unobstructed
    // source light, which leaks through the opaque slab.
    let mut max_light = |off: u32| {
        centre(&light_at(&mut gpu, &p, 1.0, off))
            .iter()
            .fold(0.0f32, |m, q| m.max(q[1]))
    };
    let on = max_light(0);
    let off = max_light(safeguards::DIRECTION_LENGTH);
    eprintln!("DIRECTION_LENGTH: light behind the opaque slab {on} (on), {off} (off)");
    // 8 voxels at opacity 1 (optical depth 16 per voxel) let nothing through: e^-128.
    assert!(on < 1e-3 && off > 0.1, "on {on}, off {off}");
}

#[test]
fn parallel_rays_take_the_full_resolution_environment() {
    // Orthographic and without refraction every view ray has the same direction: the angle
    // between neighbours, hence the environment footprint, is exactly 0 (log2(0) = -inf).
    // Looking 30° up, into the smooth sky gradient of the studio, through a clear volume.
    let mut gpu = Gpu::new();
    let tf = plain_tf(vec![[0.0, 0.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let mut scene = head_on_scene(&tf);
    scene.environment = caustica::scene::Environment::Studio { intensity: 1.0 };
    scene.camera.pitch_deg = -30.0;
    let mut p = prepared(scene, sphere(N, 0.3, 1.0), tf);
    assert!(!p.features().refraction);
    let ortho = check(
        &mut gpu,
        "parallel view rays (orthographic, environment)",
        &p,
        &request(SIZE, SIZE),
        diffuse_bound(&p, 0.95),
        "environment mip level",
    )
    .image;
    p.scene.camera.projection = Projection::Perspective;
    p.scene.camera.fov_deg = 1.0;
    let narrow = gpu.render(&p, &request(SIZE, SIZE)).image;
    let c = (SIZE * SIZE / 2 + SIZE / 2) as usize;
    let diff = (0..3).fold(0.0f32, |m, k| m.max((ortho.pixels[c][k] - narrow.pixels[c][k]).abs()));
    eprintln!(
        "parallel rays: pixel {:?}, 1° perspective centre {:?}, difference {diff}",
        ortho.pixels[c], narrow.pixels[c]
    );
    // Every ray sees the same sky: identical pixels, and not black.
    assert!(
        ortho.pixels.iter().all(|q| *q == ortho.pixels[c]),
        "orthographic pixels differ"
    );
    assert!(ortho.pixels[c][2] > 0.5, "no sky: {:?}", ortho.pixels[c]);
    // The 1° view's rays are 0.03° apart, a footprint far below one texel: level 0 as well.
    // Its centre ray is half a pixel (0.016°) off the axis, along a smooth sky gradient
    // (measured difference 9e-5). The coarsest level, what a device that clamps log2(0) to
    // the upper bound would take, is the mean of the whole map, sky and floor: 0.31 darker
    // when forced for a zero footprint.
    assert!(
        diff < 1e-3,
        "orthographic {:?}, perspective {:?}",
        ortho.pixels[c],
        narrow.pixels[c]
    );
}

#[test]
fn camera_inside_a_microscopic_volume() {
    // The camera just inside a volume of 1e-7-unit voxels (micrometre data in metres): every
    // plane lies nearer than 1e-6 view units. The image must not depend on the unit: the
    // perspective division sees the planes' own depths, which NEAR_PLANE keeps > 0 at any
    // scale; a fixed floor on the depth would move them.
    let mut gpu = Gpu::new();
    let tf = blobs_tf();
    let mut scene = head_on_scene(&tf);
    scene.camera.projection = Projection::Perspective;
    scene.camera.distance = 0.0001;
    scene.camera.fov_deg = 90.0;
    scene.light.polar_deg = 40.0;
    let unit = sphere(N, 0.45, 1.0);
    let mut tiny = unit.clone();
    tiny.spacing = [1e-7; 3];
    let a = prepared(scene.clone(), unit, tf.clone());
    let b = prepared(scene, tiny, tf);
    let ia = gpu.render(&a, &request(SIZE, SIZE)).image;
    let ib = check(
        &mut gpu,
        "camera inside 1e-7-unit voxels",
        &b,
        &request(SIZE, SIZE),
        specular_bound(0.0),
        "NEAR_PLANE",
    )
    .image;
    let diff = ia
        .pixels
        .iter()
        .zip(&ib.pixels)
        .flat_map(|(p, q)| (0..3).map(move |k| (p[k] - q[k]).abs()))
        .fold(0.0f32, f32::max);
    eprintln!("microscopic volume: largest difference to 1-unit voxels {diff}");
    // Scaling every length by 1e-7 changes only f32 rounding (2^-24 relative), far below one
    // f16 step of the colour buffer (2^-11); measured 0. The former floor of 1e-6 view units
    // on the perspective depth gave 3.4e-3 here.
    assert!(diff < 5e-4, "the image depends on the length unit: {diff}");
}
