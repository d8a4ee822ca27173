//! Every built-in scene renders to a finite, non-blank image, and rendering is deterministic.

mod common;

use caustica::render::{DebugView, PreparedScene, RenderRequest};
use caustica::scene::{builtin, Precision, Toggle, BUILTIN_SCENES};
use common::*;

#[test]
fn builtin_scenes_render_finite_non_blank_and_deterministic() {
    let mut gpu = Gpu::new();
    for name in BUILTIN_SCENES {
        let mut scene = builtin(name).unwrap().scene;
        // Small volume and viewport: lavapipe runs every plane on the CPU.
        scene.set_builtin_resolution(32);
        let p = PreparedScene::load(&scene).unwrap();
        let req = RenderRequest::new(48, 48);
        let a = gpu.render(&p, &req);
        let b = gpu.render(&p, &req);
        let (non_finite, negative) = a.image.count_invalid();
        assert_eq!((non_finite, negative), (0, 0), "{name}: invalid pixels");
        let lum: Vec<f32> = a.image.pixels.iter().map(luminance).collect();
        let mean = lum.iter().sum::<f32>() / lum.len() as f32;
        let var = lum.iter().map(|l| (l - mean).powi(2)).sum::<f32>() / lum.len() as f32;
        // Non-blank: not black, and with structure (a flat image has zero variance; the
        // studio background alone has a standard deviation of about 0.03 at this size).
        assert!(mean > 0.05, "{name}: mean luminance {mean}");
        assert!(var.sqrt() > 0.02, "{name}: no structure (std {})", var.sqrt());
        assert_eq!(a.image.to_srgb8(), b.image.to_srgb8(), "{name}: two renders differ");
        assert!(
            a.image.pixels.iter().zip(&b.image.pixels).all(|(x, y)| x == y),
            "{name}: two renders differ in float values"
        );
        assert!(a.stats.planes > 10, "{name}: only {} planes", a.stats.planes);
    }
}

#[test]
fn features_follow_the_scene() {
    // Models only what a scene requires: the ball lens refracts but has a white medium; the
    // wine glass has a coloured medium; forcing refraction off removes the caustic work.
    let mut ball = PreparedScene::load(&builtin("ball-lens").unwrap().scene).unwrap();
    let f = ball.features();
    // Beams (the default) need no intensity law; the backward transport does.
    assert!(f.refraction && !f.intensity_correction && !f.medium);
    assert_eq!(f.transport, caustica::scene::LightTransport::Beams);
    ball.scene.quality.light_transport = caustica::scene::LightTransport::Backward;
    assert!(ball.features().intensity_correction);
    let wine = PreparedScene::load(&builtin("glass-wine").unwrap().scene).unwrap();
    assert!(wine.features().medium);
    let mut plain = builtin("ball-lens").unwrap().scene;
    plain.quality.refraction = caustica::scene::Toggle::Off;
    let f = PreparedScene::load(&plain).unwrap().features();
    assert!(!f.refraction && !f.intensity_correction && !f.specular);
}

#[test]
fn validation_canary_counts_errors() {
    // The canary must see a deliberately invalid call, or a clean run would prove nothing.
    let gpu = Gpu::new();
    assert!(
        gpu.ctx.provoke_validation_error() > 0,
        "the validation layer did not report"
    );
}

/// `render --timings` prints the total GPU time (a stable interface scripts read) and the
/// time of each pass only with `--pass-timings` (its timestamps cost a CPU driver time).
#[test]
fn render_timings_give_the_passes_only_when_asked() {
    let dir = std::env::temp_dir().join(format!("caustica-timings-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "--scene",
            "ball-lens",
            "--resolution",
            "24",
            "--size",
            "32x32",
        ];
        args.extend(["-o", "x.png", "--timings"]);
        args.extend(extra);
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_caustica"))
            .args(&args)
            .current_dir(&dir)
            .env("CAUSTICA_VALIDATION", "require")
            .output()
            .expect("run the caustica binary");
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
        stdout
    };
    let numbers = |line: &str| -> Vec<f64> {
        line.split(|c: char| !(c.is_ascii_digit() || c == '.'))
            .filter_map(|w| w.parse().ok())
            .collect()
    };
    let total = |stdout: &str| -> f64 {
        let line = stdout
            .lines()
            .find(|l| l.starts_with("total GPU ms: "))
            .expect("a total");
        numbers(line)[0]
    };
    let plain = run(&[]);
    assert!(total(&plain) > 0.0, "{plain}");
    assert!(!plain.contains("GPU ms by pass"), "{plain}");
    let split = run(&["--pass-timings"]);
    let passes = numbers(
        split
            .lines()
            .find(|l| l.starts_with("GPU ms by pass"))
            .expect("the passes"),
    );
    assert_eq!(passes.len(), 4, "{split}");
    // The passes split that render's total: equal up to the printing of five numbers to a
    // tenth of a millisecond (0.05 each).
    let sum: f64 = passes.iter().sum();
    assert!((sum - total(&split)).abs() <= 0.25, "{split}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `caustica` without a command and without a display renders the default scene to
/// `caustica.png` in the working directory (the README's first quick-start command).
#[test]
fn the_default_job_writes_a_screenshot_without_a_display() {
    let dir = std::env::temp_dir().join(format!("caustica-default-job-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_caustica"))
        .current_dir(&dir)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env("CAUSTICA_VALIDATION", "require")
        .output()
        .expect("run the caustica binary");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "caustica failed:\n{stderr}");
    assert!(
        stderr.contains("no display") && stderr.contains("caustica.png"),
        "{stderr}"
    );
    let img = image::open(dir.join("caustica.png"))
        .expect("caustica.png is a PNG")
        .to_rgb8();
    assert_eq!(img.dimensions(), (512, 512));
    let lum: Vec<f32> = img
        .pixels()
        .map(|p| p.0.iter().map(|&c| c as f32).sum::<f32>() / 3.0)
        .collect();
    let mean = lum.iter().sum::<f32>() / lum.len() as f32;
    let var = lum.iter().map(|l| (l - mean).powi(2)).sum::<f32>() / lum.len() as f32;
    // Not blank: a black or uniform image (a failed render saved anyway) has std 0. The scene
    // shows a grey studio floor, a bright ground slab and a dark shadow: measured mean 157 and
    // std 36 of 255 on lavapipe, so 20 and 10 leave wide margins for other drivers.
    assert!(
        mean > 20.0 && var.sqrt() > 10.0,
        "blank default image: mean {mean}, std {}",
        var.sqrt()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn scattering_curves_at_zero_render_todays_image_with_todays_work() {
    // Albedo and anisotropy curves that are 0 everywhere are no scattering: the same
    // features (no extra pass, buffer or variant) and the same bytes as without the curves.
    let mut gpu = Gpu::new();
    let mut scene = builtin("supernova").unwrap().scene;
    scene.set_builtin_resolution(32);
    let plain = PreparedScene::load(&scene).unwrap();
    let mut tf = plain.tf.clone();
    assert!(tf.albedo.is_none() && tf.anisotropy.is_none());
    tf.albedo = Some(caustica::transfer::Curve::constant(0.0));
    tf.anisotropy = Some(caustica::transfer::Curve::constant(0.0));
    assert!(!tf.scatters());
    scene.transfer = caustica::scene::TransferSource::Inline(tf);
    let zero = PreparedScene::load(&scene).unwrap();
    assert_eq!(plain.features(), zero.features());
    let req = RenderRequest::new(48, 48);
    let (a, b) = (gpu.render(&plain, &req), gpu.render(&zero, &req));
    assert!(
        a.image.pixels.iter().zip(&b.image.pixels).all(|(x, y)| x == y),
        "zero scattering changed the image"
    );
}

#[test]
fn light_stepped_over_a_view_pass_renders_what_a_dispatch_per_plane_does() {
    // Without refraction, the soft light's exchange or scattering a beam's step reads no other
    // beam, and a render steps the listed light tiles over the planes up to the next view
    // pass in one dispatch, rounding their power after every plane as the stored state is
    // rounded between dispatches: the image (and the medium view) is the one a dispatch per
    // plane gives, to the bit, with f16 as with f32 state. A tile that a dispatch per plane
    // would end on a later plane of a pass is stepped to the pass's end, so the grouped sweep
    // steps at least as many tiles, and per tile at most the planes of a pass (8) less one more.
    let mut gpu = Gpu::new();
    for (name, ds, debug) in [
        ("supernova", 1.0, DebugView::Image),
        ("thin-structures", 0.5, DebugView::Image),
        ("glass-wine", 1.0, DebugView::Medium),
    ] {
        let mut scene = builtin(name).unwrap().scene;
        scene.set_builtin_resolution(32);
        scene.quality.refraction = Toggle::Off;
        scene.quality.light_filter = false;
        scene.quality.sample_distance = ds;
        for precision in [Precision::F16, Precision::F32] {
            scene.quality.precision = precision;
            let p = PreparedScene::load(&scene).unwrap();
            let mut req = RenderRequest::new(40, 40);
            req.debug_view = debug;
            req.per_plane_light = true;
            let per_plane = gpu.render(&p, &req);
            req.per_plane_light = false;
            let grouped = gpu.render(&p, &req);
            let planes = per_plane.stats.planes;
            assert_eq!(
                per_plane.stats.light_passes,
                planes - 1,
                "{name}: a light pass per plane"
            );
            assert!(
                grouped.stats.light_passes * 2 < planes,
                "{name}: {} light passes for {planes} planes",
                grouped.stats.light_passes
            );
            assert!(
                per_plane.image.pixels == grouped.image.pixels,
                "{name} ({precision:?}, {debug:?}): the images differ"
            );
            let (one, group) = (per_plane.stats.light_steps.unwrap(), grouped.stats.light_steps.unwrap());
            let [w, h] = grouped.stats.light_grid;
            let t = grouped.stats.tile;
            let tiles = (w.div_ceil(t) * h.div_ceil(t)) as u64;
            assert!(
                group >= one && group <= one + 7 * tiles,
                "{name}: {group} tile steps grouped, {one} per plane, {tiles} tiles"
            );
        }
    }
}

#[test]
fn view_passes_over_several_planes_render_what_one_plane_per_pass_does() {
    // A view pass advances its rays over several planes, their state kept in the invocation
    // in between. With f32 state nothing is rounded between the planes, so the image is the
    // one a pass per plane gives, to the bit; with f16 state it differs by the rounding the
    // stored state saw on every plane: a relative 2^-11 per plane of the colour, whose sum
    // over the planes bounds the difference. At Δs = ½ each sample reads the beams two planes
    // back (a voxel), so the ring keeps two planes more than a pass spans. With refraction
    // the light a pass reads is the beams' deposits, in a ring of as many slots; the tiles a
    // pass finds empty on all its planes (fewer when it spans more) carry their rays over
    // them as the steps would (`skipping_empty_view_tiles_renders_what_stepping_them_does`).
    let mut gpu = Gpu::new();
    for (name, view_planes, ds, refraction) in [
        ("supernova", 0, 1.0, Toggle::Off),
        ("glass-wine", 3, 1.0, Toggle::Off),
        ("thin-structures", 0, 1.0, Toggle::Off),
        ("supernova", 3, 0.5, Toggle::Off),
        ("glass-wine", 0, 1.0, Toggle::On),
        ("ball-lens", 3, 0.5, Toggle::On),
    ] {
        let mut scene = builtin(name).unwrap().scene;
        scene.set_builtin_resolution(32);
        scene.quality.refraction = refraction;
        scene.quality.sample_distance = ds;
        // At Δs = ½ f16 state differs by a little more than that bound (supernova: 0.048
        // against 0.044, with the light read one plane back as with two: the stored light is
        // rounded as well as the colour), so there the ring is checked with f32 state only.
        let precisions: &[Precision] = if ds == 1.0 {
            &[Precision::F32, Precision::F16]
        } else {
            &[Precision::F32]
        };
        for &precision in precisions {
            scene.quality.precision = precision;
            let p = PreparedScene::load(&scene).unwrap();
            let mut req = RenderRequest::new(40, 40);
            req.view_planes = 1;
            let one = gpu.render(&p, &req);
            req.view_planes = view_planes;
            let several = gpu.render(&p, &req);
            let planes = one.stats.planes;
            // One pass per plane (the first reads plane 0's light); several: fewer than half.
            assert_eq!(one.stats.view_passes, planes, "{name}");
            assert_eq!(one.stats.view_planes, 1, "{name}");
            if view_planes > 0 {
                assert_eq!(several.stats.view_planes, view_planes, "{name}");
            }
            // Every plane is advanced over by a pass: the first two passes take a plane each
            // (`view_pass` in src/render/state.rs), every other at most `view_planes`.
            assert!(
                several.stats.view_planes > 1
                    && several.stats.view_passes.saturating_sub(2) * several.stats.view_planes + 2 >= planes,
                "{name}: {} passes of up to {} planes for {planes} planes",
                several.stats.view_passes,
                several.stats.view_planes
            );
            assert!(
                several.stats.view_passes * 2 < planes,
                "{name}: {} passes for {planes} planes",
                several.stats.view_passes
            );
            let bound = planes as f32 * 2f32.powi(-11);
            let worst = one
                .image
                .pixels
                .iter()
                .zip(&several.image.pixels)
                .flat_map(|(a, b)| (0..4).map(move |c| (a[c] - b[c]).abs() / a[c].abs().max(1e-3)))
                .fold(0.0f32, f32::max);
            match precision {
                Precision::F32 => assert_eq!(worst, 0.0, "{name} ({refraction:?}): f32 state differs"),
                Precision::F16 => assert!(
                    worst <= bound,
                    "{name} ({refraction:?}): f16 state differs by {worst} (bound {bound})"
                ),
            }
        }
    }
}

#[test]
fn skipping_empty_view_tiles_renders_what_stepping_them_does() {
    // Where a view tile's rays are not yet bent and meet no brick that shows or bends light
    // on the planes of a pass, the pass skips the tile, and its rays are carried over those
    // planes when it next steps them. They are carried plane by plane with the segments'
    // own arithmetic, so they land where stepping would have put them, to the bit: the
    // image is the one a render stepping every tile gives, whatever planes were skipped.
    // Carried in one straight jump they rounded differently, refraction at grazing rims
    // amplified that (supernova at 128² had 27 pixels off by up to 0.22), and glass-wine's
    // image here was not the same.
    let mut gpu = Gpu::new();
    for (name, view_planes) in [("supernova", 0), ("glass-wine", 3), ("ball-lens", 1)] {
        let mut scene = builtin(name).unwrap().scene;
        scene.set_builtin_resolution(32);
        scene.quality.refraction = Toggle::On;
        let p = PreparedScene::load(&scene).unwrap();
        let mut req = RenderRequest::new(48, 48);
        req.view_planes = view_planes;
        let skipping = gpu.render(&p, &req);
        req.step_empty_view_tiles = true;
        let stepping = gpu.render(&p, &req);
        assert!(
            skipping.image.pixels == stepping.image.pixels,
            "{name}: skipping empty view tiles changed the image"
        );
    }
}

#[test]
fn smaller_tiles_on_a_cpu_driver_render_the_same_image() {
    // A CPU driver's render works in tiles of 4 × 4 pixels and beams where a GPU's works in
    // 8 × 8: what the tiles decide (which beams are stepped on which plane, which rays are
    // carried over empty space, which light no ray can read any more) leaves the image as
    // every beam and ray stepped would give it, so both give the same bits. Every variant of
    // the sweep: straight light grouped over a view pass (supernova, and glass-wine's medium
    // view), soft light (thin-structures), refracted beams that deposit (ball-lens, glass-wine,
    // also at 8 × 8 pixels, where the tiles pass has fewer invocations than lists to empty),
    // and the spread mode (milk-glass), whose light is not listed.
    let mut gpu = Gpu::new();
    for (name, size, refraction, debug) in [
        ("supernova", 40, Toggle::Off, DebugView::Image),
        ("glass-wine", 40, Toggle::Off, DebugView::Medium),
        ("thin-structures", 40, Toggle::Off, DebugView::Image),
        ("ball-lens", 40, Toggle::On, DebugView::Image),
        ("glass-wine", 48, Toggle::On, DebugView::Image),
        ("glass-wine", 8, Toggle::On, DebugView::Image),
        ("milk-glass", 40, Toggle::Off, DebugView::Image),
    ] {
        let mut scene = builtin(name).unwrap().scene;
        scene.set_builtin_resolution(32);
        scene.quality.refraction = refraction;
        let p = PreparedScene::load(&scene).unwrap();
        let mut req = RenderRequest::new(size, size);
        req.debug_view = debug;
        let small = gpu.render(&p, &req);
        req.gpu_tiles = true;
        let wide = gpu.render(&p, &req);
        if gpu.ctx.is_cpu() {
            assert_eq!((small.stats.tile, wide.stats.tile), (4, 8), "{name}");
        }
        assert!(
            small.image.pixels == wide.image.pixels,
            "{name} ({refraction:?}, {debug:?}) at {size}²: the tiles' side changed the image"
        );
    }
}

#[test]
fn the_beams_power_gives_the_same_image_in_records_as_in_pairs() {
    // Each beam keeps its power per region (the halves, and the power before its segment to
    // the planes the view reads back) in a record of regions side by side, or, where a row of
    // records would be wider than the device allows, in pairs of regions. Only where the
    // words lie changes: straight light grouped over a view pass (supernova, at Δs ¼ too, where
    // the view reads four planes back), soft light (thin-structures, also at f32), refracted
    // beams that keep their power of the planes in a voxel (ball-lens at Δs ½) and the light
    // view must come out the same to the bit.
    let mut gpu = Gpu::new();
    let cases = [
        ("supernova", 1.0, Toggle::Off, DebugView::Image, Precision::F16),
        ("supernova", 0.25, Toggle::Off, DebugView::Image, Precision::F16),
        ("thin-structures", 1.0, Toggle::Off, DebugView::Image, Precision::F16),
        ("thin-structures", 1.0, Toggle::Off, DebugView::Image, Precision::F32),
        ("ball-lens", 0.5, Toggle::On, DebugView::Image, Precision::F16),
        ("thin-structures", 1.0, Toggle::Off, DebugView::Light, Precision::F16),
    ];
    for (name, ds, refraction, debug, precision) in cases {
        let mut scene = builtin(name).unwrap().scene;
        scene.set_builtin_resolution(32);
        scene.quality.sample_distance = ds;
        scene.quality.refraction = refraction;
        scene.quality.precision = precision;
        let p = PreparedScene::load(&scene).unwrap();
        let mut req = RenderRequest::new(40, 40);
        req.debug_view = debug;
        let records = gpu.render(&p, &req);
        req.power_in_pairs = true;
        let pairs = gpu.render(&p, &req);
        assert!(
            records.image.pixels == pairs.image.pixels,
            "{name} (Δs {ds}, {refraction:?}, {debug:?}, {precision:?}): the power's layout changed the image"
        );
        // The layouts differ: with the two halves, the view's planes and one plane back the
        // straight beams keep an odd number of regions, which pairs round up to one more.
        if name == "supernova" && ds == 1.0 {
            assert!(
                pairs.stats.state_bytes > records.stats.state_bytes,
                "pairs {} B, records {} B: the same layout twice",
                pairs.stats.state_bytes,
                records.stats.state_bytes
            );
        }
    }
}

#[test]
fn the_deposited_light_reads_the_same_through_its_image_as_through_its_buffer() {
    // On a CPU driver the view reads the beams' deposits through a linear image over the
    // buffer they are added into (a texel fetch is gathered for all lanes at once, a
    // buffer load made lane by lane); elsewhere it reads the buffer. Both read the same
    // words: refracted light (grey and rgb, with view passes over several planes), the
    // spread mode's seven levels, and the light debug views (the direction's three more
    // channels; the light views' rect is the frame) must come out the same to the bit.
    let mut gpu = Gpu::new();
    let cases = [
        ("supernova", DebugView::Image, true),
        ("glass-wine", DebugView::Image, true),
        ("milk-glass", DebugView::Image, false),
        ("ball-lens", DebugView::LightDirection, true),
        ("ball-lens", DebugView::Light, true),
    ];
    for (name, debug, refract) in cases {
        let mut scene = builtin(name).unwrap().scene;
        scene.set_builtin_resolution(32);
        if refract {
            scene.quality.refraction = Toggle::On;
        }
        let p = PreparedScene::load(&scene).unwrap();
        let mut req = RenderRequest::new(40, 36);
        req.debug_view = debug;
        req.debug_depth = 0.6;
        let image = gpu.render(&p, &req);
        req.buffer_deposit_reads = true;
        let buffer = gpu.render(&p, &req);
        assert_eq!(
            image.stats.features.deposit_image,
            gpu.ctx.is_cpu(),
            "{name} {debug:?}: a CPU driver reads the deposits through the image, others through the buffer"
        );
        assert!(!buffer.stats.features.deposit_image);
        assert!(
            name != "milk-glass" || image.stats.features.scatter,
            "milk-glass runs the spread mode"
        );
        assert!(
            image.image.pixels == buffer.image.pixels,
            "{name} {debug:?}: the image of the deposits read other light than the buffer"
        );
        assert!(
            image.image.pixels.iter().flatten().any(|v| *v > 0.0),
            "{name} {debug:?}: a black image compares equal to anything"
        );
    }
}

#[test]
fn timings_say_when_the_volume_is_sampled_at_half_resolution() {
    let dir = std::env::temp_dir().join(format!("caustica-volume-level-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // The built-in ball-lens volume at resolution 16 is 16×10×16 voxels; its half level has
    // ⌊n/2⌋ per axis.
    let line = "volume sampled at half resolution: 8×5×8 of 16×10×16 voxels";
    for (level, said) in [(1, true), (0, false)] {
        let scene = format!(
            "transfer = {{ opacity = [[0.0, 0.0], [1.0, 0.5]] }}\n\n[volume]\nkind = \"builtin\"\n\
             name = \"ball-lens\"\nresolution = 16\n\n[quality]\nvolume_level = {level}\n"
        );
        std::fs::write(dir.join("scene.toml"), scene).unwrap();
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_caustica"))
            .args(["render", "scene.toml", "--size", "16x16", "-o", "x.png", "--timings"])
            .current_dir(&dir)
            .env("CAUSTICA_VALIDATION", "require")
            .output()
            .expect("run the caustica binary");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
        assert_eq!(stdout.contains(line), said, "volume_level {level}:\n{stdout}");
        assert!(
            stdout.contains(" planes, each over up to "),
            "the view passes' line:\n{stdout}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn refracted_light_renders_the_same_in_either_layout_of_the_volume() {
    // Looking along x the render lays the volume's textures out with x slowest
    // (`VolumeLayout::ForView`): the same texels at the same coordinates, their gradient
    // volume's differences along the textures' axes mapped back to the view's. A lens
    // bends light and view rays by the same angles in either layout up to the order in
    // which a sample's texels are interpolated (float roundings of 1e-7), which refraction
    // amplifies where rays graze a surface: measured relative L1 2.5e-4 (ball-lens) and
    // 3.6e-4 (glass-wine) with f32 state. The gradient's components left in the textures'
    // order (not mapped back) moved the caustic: 6.8e-2 on ball-lens. 1e-3 separates them.
    use caustica::render::VolumeLayout;
    let mut gpu = Gpu::new();
    for name in ["ball-lens", "glass-wine"] {
        let mut scene = builtin(name).unwrap().scene;
        scene.set_builtin_resolution(32);
        scene.quality.precision = Precision::F32;
        scene.camera.yaw_deg = 90.0;
        scene.camera.pitch_deg = 20.0;
        let p = PreparedScene::load(&scene).unwrap();
        let laid = gpu.render(&p, &RenderRequest::new(48, 48));
        let mut req = RenderRequest::new(48, 48);
        req.volume_layout = VolumeLayout::Stored;
        let stored = gpu.render(&p, &req);
        assert_eq!(laid.stats.volume_axes, Some([2, 1, 0]), "{name}");
        assert!(laid.stats.features.refraction, "{name} refracts");
        let (mut num, mut den, mut max) = (0.0f64, 0.0f64, 0.0f32);
        for (a, b) in laid.image.pixels.iter().zip(&stored.image.pixels) {
            for c in 0..3 {
                num += (a[c] - b[c]).abs() as f64;
                den += b[c].abs() as f64;
                max = max.max((a[c] - b[c]).abs());
            }
        }
        let rel = num / den.max(1e-12);
        eprintln!("{name}: laid out vs stored relative L1 {rel:.2e}, max |Δ| {max:.2e}");
        assert!(rel < 1e-3, "{name}: relative L1 {rel}");
    }
    gpu.assert_clean();
}

/// The README's example of what each feature set costs ("Models only what a scene
/// requires"): the ball-lens volume at 24³ rendered at 256×256 with three transfer functions.
/// Its features and state-buffer sizes are exact (the times are a machine's, and are not
/// checked): each row must be what `render --timings` prints today, so that the table cannot
/// go stale as the state's layout changes.
#[test]
fn the_readme_feature_table_gives_the_features_and_state_sizes_a_render_prints() {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let rows: Vec<(String, String, String)> = readme
        .lines()
        .filter(|l| l.starts_with("| `") && l.contains(".json`") && l.contains(" MiB |"))
        .map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            let file = cells[1].split('`').nth(1).unwrap().to_string();
            let features = cells[2].trim_matches('`').to_string();
            (file, features, cells[3].to_string())
        })
        .collect();
    assert_eq!(rows.len(), 3, "the README's feature example has three rows: {rows:?}");
    let dir = std::env::temp_dir().join(format!("caustica-feature-table-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let run = |args: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_caustica"))
            .args(args)
            .current_dir(&dir)
            .env("CAUSTICA_VALIDATION", "require")
            .output()
            .expect("run the caustica binary");
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(out.status.success(), "caustica {args:?} failed:\n{text}");
        text
    };
    run(&["dataset", "ball-lens", "--resolution", "24", "-o", "ball.nhdr"]);
    for (file, features, state) in rows {
        let transfer = format!("{}/transfer_functions/{file}", env!("CARGO_MANIFEST_DIR"));
        let printed = run(&[
            "render",
            "ball.nhdr",
            "--transfer",
            &transfer,
            "--size",
            "256x256",
            "--timings",
            "-o",
            "out.png",
        ]);
        let line = |key: &str| {
            printed
                .lines()
                .find_map(|l| l.strip_prefix(key))
                .unwrap_or_else(|| panic!("no '{key}' line in:\n{printed}"))
                .trim()
                .to_string()
        };
        assert_eq!(line("features:"), features, "{file}");
        assert_eq!(line("state buffers:"), state, "{file}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
