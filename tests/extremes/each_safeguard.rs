//! Each safeguard is needed: switched off, the property it protects breaks. And where a
//! fixed floor was replaced by exact handling (zero environment footprint, microscopic
//! scales), the exact case renders right.

use super::*;

#[test]
fn safeguard_concentration_bounds_light_behind_a_focus() {
    // η 1→3 ball, head-on: behind it the backward scheme keeps concentrating the light.
    // Budget 64: measured without it 336 at the back of the box.
    let mut gpu = Gpu::new();
    let p = head_on(ball_scene(3.0, hard_ball(N, 0.3), false));
    let budget = p.scene.quality.max_concentration * ROUNDING;
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
