//! Every parameter at its limits, and degenerate volumes, viewports and cameras.

use super::*;

#[test]
fn eta_contrast_one_to_three_across_one_voxel() {
    let mut gpu = Gpu::new();
    for (specular, back) in [(false, false), (true, false), (false, true)] {
        let mut p = ball_scene(3.0, hard_ball(N, 0.3), specular);
        if back {
            p = backward(p);
            assert!(p.features().intensity_correction);
        }
        assert!(p.features().refraction);
        let bound = if specular {
            specular_bound(0.0)
        } else {
            diffuse_bound(&p, 0.0)
        };
        let case = match (specular, back) {
            (true, _) => "η 1→3 in one voxel, specular",
            (false, false) => "η 1→3 in one voxel",
            (false, true) => "η 1→3 in one voxel, backward transport",
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
    assert!(stderr.contains("nan.raw (raw): "), "the file and its format: {stderr}");
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
    // through a focusing lens: the light buffers hold light relative to the source, bounded
    // by the power budget (≤ MAX_LIGHT_VALUE), so they stay f16-safe; the colour buffer is
    // bounded by MAX_RADIANCE.
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
        "CONCENTRATION, MAX_RADIANCE",
    );
    assert!(out.image.max_value() > 1000.0, "the light did not reach the image");
    p.scene.light.intensity *= 2.0;
    assert!(p.scene.validate().is_err(), "a brighter light must be rejected");
}
