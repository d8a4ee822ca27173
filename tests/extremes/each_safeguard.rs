//! Each safeguard is needed: switched off, the property it protects breaks. And where a
//! fixed floor was replaced by exact handling (zero environment footprint, microscopic
//! scales), the exact case renders right.

use super::*;

#[test]
fn safeguard_concentration_bounds_light_behind_a_focus() {
    // η 1→3 ball, head-on: behind it the backward scheme keeps concentrating the light.
    // Budget 64: measured without it 336 at the back of the box.
    let mut gpu = Gpu::new();
    let p = backward(head_on(ball_scene(3.0, hard_ball(N, 0.3), false)));
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
    let p = backward(focus_scene(64.0));
    let input = (SIZE * SIZE) as f64;
    let on = power(&light_at(&mut gpu, &p, 0.5, 0));
    let off = power(&light_at(&mut gpu, &p, 0.5, safeguards::FOLD));
    eprintln!("FOLD: power behind the focus {on:.0} (on), {off:.0} (off), input {input}");
    assert!(on < input && off > input, "on {on}, off {off}");
}

#[test]
fn safeguard_light_min_z_keeps_reflected_light_out() {
    // η 4 → 1 at a 30° interface reflects head-on light totally, back toward the light.
    // Beams that turn back leave the sweep: what reaches the back of the box is at most what
    // entered (measured 550 of 1024). Without the bound they step along a direction of
    // negative or zero depth, onto planes they have left behind. The backward scheme turns such light into grazing light and
    // keeps the power near the input (its intensity law is first order: measured 1080 of
    // 1024); without the bound, light travelling (nearly) inside the planes is looked up from
    // far away and amplified by the area ratio (measured 3449).
    let mut gpu = Gpu::new();
    let input = (SIZE * SIZE) as f64;
    let beams = head_on(turning_back_scene());
    let on = light_at(&mut gpu, &beams, 1.0, 0);
    let off = light_at(&mut gpu, &beams, 1.0, safeguards::LIGHT_MIN_Z);
    eprintln!(
        "LIGHT_MIN_Z, beams: power at the back {:.0} (on), {:.0} with {} non-finite (off), input {input}",
        power(&on),
        power(&off),
        off.count_invalid().0
    );
    // Without the bound the reflected beams land on the back plane too (measured 561).
    assert!(power(&on) <= input && on.count_invalid() == (0, 0));
    assert!(
        power(&off) > power(&on) * 1.005,
        "the reflected light does not reach the back"
    );
    let p = backward(head_on(turning_back_scene()));
    let on = power(&light_at(&mut gpu, &p, 1.0, 0));
    let off = power(&light_at(&mut gpu, &p, 1.0, safeguards::LIGHT_MIN_Z));
    eprintln!("LIGHT_MIN_Z, backward: power at the back {on:.0} (on), {off:.0} (off), input {input}");
    assert!(on < 1.1 * input && off > 2.0 * input, "on {on}, off {off}");
}

#[test]
fn safeguard_intensity_ratio_limits_growth_per_plane() {
    // From one plane to the next the largest light value grows at most by max_intensity_ratio
    // (bilinear gathers and transmittance are convex; the unobstructed light is 1).
    let mut gpu = Gpu::new();
    let tf = blobs_tf();
    let p = backward(prepared(head_on_scene(&tf), sphere(N, 0.35, 1.0), tf));
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
    // Planes half a voxel apart resolve the 1.5-voxel interface: at one voxel the samples of
    // one column of rays straddle it (η 2.2 then 1.0 with no gradient left) and those rays
    // pass it unreflected, which is a sampling limit, not what this guard is about.
    scene.quality.sample_distance = 0.5;
    scene.eta_volume = Some(caustica::scene::VolumeSource::builtin("test", 0));
    let wall = volume_from(N, |_, _, z| if z > 0.85 { 1.0 } else { 0.0 });
    let mut p = prepared(scene, wall, tf);
    p.eta_volume = Some(std::sync::Arc::new(reflecting_interface(N)));
    assert!(p.features().eta_volume);
    // Rays along the box's side faces graze the η 4 → 1 step there (index 4 inside the face,
    // the surrounding medium outside), which cannot turn them; only rays at least two pixels
    // inside the box's projection (columns 10–21 of 32) count.
    let red_pixels = |img: &caustica::render::RenderedImage| {
        img.pixels
            .iter()
            .enumerate()
            .filter(|(i, q)| (10..22).contains(&(*i as u32 % SIZE)) && q[0] > 0.1)
            .count()
    };
    let on = red_pixels(&image_with(&mut gpu, &p, SIZE, 0));
    let off = red_pixels(&image_with(&mut gpu, &p, SIZE, safeguards::VIEW_MIN_Z));
    // Without the interface the wall shows wherever the box is (the orthographic view spans
    // the box's diagonal), so it is not invisible for another reason.
    p.eta_volume = Some(std::sync::Arc::new(volume_from(N, |_, _, _| 0.0)));
    let clear = red_pixels(&image_with(&mut gpu, &p, SIZE, 0));
    eprintln!(
        "VIEW_MIN_Z: pixels showing the wall {on} (on), {off} (off), {clear} without the interface, of {}",
        SIZE * SIZE
    );
    // Orthographic and head-on, every ray meets the interface 30° off its normal, beyond the
    // critical angle (14.5°): all are reflected.
    assert!(
        clear > (12 * SIZE / 2) as usize,
        "the wall is not visible at all: {clear}"
    );
    assert!(on == 0 && off > 0, "on {on}, off {off}");
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
    // The camera just inside a volume of 2^-23-unit voxels (1.2e-7: micrometre data in
    // metres): every plane lies nearer than 1e-6 view units. The image must not depend on the
    // unit: the perspective division sees the planes' own depths, which NEAR_PLANE keeps > 0 at
    // any scale; a fixed floor on the depth would move them. A power of two scales every f32
    // operation exactly, so any difference comes from a length that does not scale with the
    // scene (refracted light through a lens focus amplifies the last-bit rounding of other
    // factors, such as 1e-7, to ~0.4%).
    let mut gpu = Gpu::new();
    let tf = blobs_tf();
    let mut scene = head_on_scene(&tf);
    scene.camera.projection = Projection::Perspective;
    scene.camera.distance = 0.0001;
    scene.camera.fov_deg = 90.0;
    scene.light.polar_deg = 40.0;
    let unit = sphere(N, 0.45, 1.0);
    let mut tiny = unit.clone();
    tiny.spacing = [2f32.powi(-23); 3];
    let a = prepared(scene.clone(), unit, tf.clone());
    let b = prepared(scene, tiny, tf);
    let ia = gpu.render(&a, &request(SIZE, SIZE)).image;
    let ib = check(
        &mut gpu,
        "camera inside 2^-23-unit voxels",
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
    // Measured 0. The former floor of 1e-6 view units on the perspective depth gave 3.4e-3
    // here.
    assert!(diff == 0.0, "the image depends on the length unit: {diff}");
}
