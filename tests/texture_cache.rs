//! The renderer keeps its scene textures between renders: reused ones must give the same
//! image as a fresh upload, every input of the textures must invalidate them, and a render
//! cancelled before its upload ran must not leave empty textures behind.

mod common;

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use caustica::render::{PreparedScene, RenderError, RenderRequest};
use caustica::scene::{builtin, EnvMap, Environment, Toggle, VolumeSource};
use caustica::transfer::{ColorRamp, TABLE_SIZE};
use common::Gpu;

type Edit = Box<dyn Fn(&mut PreparedScene)>;

fn prepared() -> PreparedScene {
    prepared_at(32)
}

/// The ball-lens scene with its volume at `resolution` voxels along its longest axis.
fn prepared_at(resolution: usize) -> PreparedScene {
    let mut scene = builtin("ball-lens").unwrap().scene;
    scene.volume = VolumeSource::builtin("ball-lens", resolution);
    PreparedScene::load(&scene).unwrap()
}

/// A fresh renderer (no cache) as the reference.
fn fresh(p: &PreparedScene) -> Vec<[f32; 4]> {
    Gpu::new().render(p, &RenderRequest::new(48, 40)).image.pixels
}

#[test]
fn reused_textures_match_a_fresh_upload_and_edits_invalidate_them() {
    let mut gpu = Gpu::new();
    // As the viewer asks: the staging buffer is written again by the next upload of volumes.
    let req = RenderRequest {
        keep_staging: true,
        ..RenderRequest::new(48, 40)
    };
    let mut p = prepared();
    let first = gpu.render(&p, &req).image.pixels;
    // Camera and light do not touch the textures: the second render reuses them.
    p.scene.camera.yaw_deg += 30.0;
    p.scene.light.polar_deg = 50.0;
    assert_eq!(gpu.render(&p, &req).image.pixels, fresh(&p));

    // Each texture input, changed, must give the fresh renderer's image, not the cached one.
    // Another data window makes the volumes anew into the images and staging buffer kept.
    let mut opaque = p.tf.clone();
    opaque.opacity.points = vec![[0.0, 0.0], [0.3, 0.8]];
    let edits: Vec<Edit> = vec![
        Box::new(move |p| p.tf = opaque.clone()),
        Box::new(|p| p.scene.quality.sample_distance = 2.0),
        Box::new(|p| p.scene.window = Some([0.0, 0.5])),
    ];
    for edit in edits {
        let before = gpu.render(&p, &req).image.pixels;
        edit(&mut p);
        let after = gpu.render(&p, &req).image.pixels;
        assert_ne!(after, before, "the edit changes the image");
        assert_eq!(after, fresh(&p));
    }
    assert_ne!(first, gpu.render(&p, &req).image.pixels);
}

#[test]
fn a_render_cancelled_before_its_upload_does_not_poison_the_cache() {
    let mut gpu = Gpu::new();
    let p = prepared();
    let mut req = RenderRequest::new(48, 40);
    req.cancel = Some(Arc::new(AtomicBool::new(true)));
    assert!(matches!(gpu.renderer.render(&p, &req), Err(RenderError::Cancelled)));
    let after = gpu.render(&p, &RenderRequest::new(48, 40)).image.pixels;
    assert_eq!(after, fresh(&p));
    gpu.assert_clean();
}

#[test]
fn sample_distances_changing_back_and_forth_keep_the_images_of_fresh_uploads() {
    // The viewer's levels step the planes 4, 2 and 1 times the scene's distance, and a drag
    // goes back to 4: only the pre-integrated tables are replaced, and each image must be the
    // fresh renderer's. A render cancelled after the tables were replaced but before they
    // were uploaded must not leave them empty either.
    let mut gpu = Gpu::new();
    let req = RenderRequest::new(48, 40);
    let mut p = prepared();
    let base = p.scene.quality.sample_distance;
    for factor in [4.0, 2.0, 1.0, 4.0] {
        p.scene.quality.sample_distance = base * factor;
        assert_eq!(gpu.render(&p, &req).image.pixels, fresh(&p), "Δs × {factor}");
    }
    p.scene.quality.sample_distance = base * 2.0;
    let mut cancelled = RenderRequest::new(48, 40);
    cancelled.cancel = Some(Arc::new(AtomicBool::new(true)));
    assert!(matches!(
        gpu.renderer.render(&p, &cancelled),
        Err(RenderError::Cancelled)
    ));
    assert_eq!(gpu.render(&p, &req).image.pixels, fresh(&p), "after a cancelled render");
    gpu.assert_clean();
}

#[test]
fn a_transfer_function_edit_keeps_the_volume_images_unless_eta_changes() {
    // An edit of opacity, colour or the medium changes only the pre-integrated tables, the
    // bricks and the occupied cells: the volume, gradient and orientation volumes are kept and
    // only the two tables are copied in (16-bit rgba texels, TABLE_SIZE² each). An edit of η
    // remakes the gradient volume too, and it alone of the volumes is copied in again (16-bit
    // rgba texels, with its half level where there is one). Each image must be the fresh
    // renderer's.
    // At `quality.volume_level` 1 the half level's bricks and occupied cells are remade as
    // well (they reach further than the full resolution's).
    // Switching refraction off keeps the gradient volume, which a render without refraction
    // does not read, and makes the bricks and occupied cells anew: nothing is copied in, and
    // switching it on again copies nothing either, unless η changed in between.
    // Then without the objects' η volume, η taken from the volume itself as from a CT, with
    // the textures laying the volume's axes out for a side view.
    // At level 1 also as the viewer asks, keeping the half level on every render: its first
    // frame makes both levels, and an η edit then makes the gradient volume's half level
    // alone, as a render without the full level does.
    for (level, keep) in [(0, false), (1, false), (1, true)] {
        transfer_edits(prepared(), 0.0, None, level, keep);
    }
    // A quarter of the volume along x is cleared to air, so that laying its axes out the
    // other way round (x for z) gives another gradient volume: the ball lens alone is the
    // same either way.
    for level in [0, 1] {
        let mut own_eta = prepared();
        own_eta.eta_volume = None;
        let mut volume = (*own_eta.volume).clone();
        let nx = volume.dims[0];
        for (i, v) in volume.data.iter_mut().enumerate() {
            if i % nx < nx / 4 {
                *v = 0.0;
            }
        }
        own_eta.volume = Arc::new(volume);
        transfer_edits(own_eta, 90.0, Some([2, 1, 0]), level, false);
    }
}

/// The edits on `p` seen from `yaw_deg`, for which the textures lay the volume's axes out as
/// `axes` (`RenderStats::volume_axes`), with `quality.volume_level` at `level`, keeping the
/// half level where asked (`RenderRequest::keep_coarse_volume`).
fn transfer_edits(mut p: PreparedScene, yaw_deg: f32, axes: Option<[u8; 3]>, level: u32, keep: bool) {
    let table_bytes = 2 * (TABLE_SIZE * TABLE_SIZE * 8) as u64;
    let mut gpu = Gpu::new();
    // As the viewer asks: the staging buffer is written again by the next upload of volumes.
    let req = RenderRequest {
        keep_staging: true,
        keep_coarse_volume: keep,
        ..RenderRequest::new(48, 40)
    };
    p.scene.camera.yaw_deg = yaw_deg;
    p.scene.quality.volume_level = level;
    // With η from the volume: the glass's index at first the air's and the ground's raised, so
    // that η changes at the ground alone (its faces at the volume's border).
    let glass_eta = p.eta_volume.is_none().then(|| {
        let glass = p.tf.eta.points.clone();
        p.tf.eta.points = vec![[0.0, 1.0], [0.8, 1.0], [1.0, 1.3]];
        glass
    });
    let first = gpu.render(&p, &req).stats;
    let full = first.upload_bytes;
    assert_eq!(first.volume_axes, axes);
    // The gradient volume has the η volume's dims (the volume's), its half level half of them.
    // A render that reads the half level makes it alone, one texel holding the full level's
    // place (in a staging slot of 16 bytes).
    let texels = |d: [usize; 3]| (d[0] * d[1] * d[2]) as u64;
    let dims = p.volume.dims;
    let half_dims = caustica::volume::half_level_dims(dims);
    let gradient_bytes = if level > 0 {
        16 + 8 * texels(half_dims)
    } else {
        8 * texels(dims)
    };
    assert!(
        full > table_bytes + 32 * 32 * 32 * 2,
        "a new scene copies its volumes: {full} bytes"
    );
    assert!(gpu.render(&p, &req).stats.features.refraction);
    assert_eq!(gpu.render(&p, &req).stats.upload_bytes, 0, "nothing changed");

    let refraction = p.scene.quality.refraction;
    let scale_eta = |p: &mut PreparedScene| {
        for point in &mut p.tf.eta.points {
            point[1] = 1.0 + 0.8 * (point[1] - 1.0);
        }
    };
    // (name, edit, bytes it copies in)
    let mut edits: Vec<(&str, Edit, u64)> = vec![
        (
            "opacity",
            Box::new(|p: &mut PreparedScene| p.tf.opacity.points = vec![[0.0, 0.0], [0.3, 0.8]]),
            table_bytes,
        ),
        (
            // The clear values (the air around the lens) absorb now: bricks that were empty
            // are not any more.
            "opacity of the clear values",
            Box::new(|p: &mut PreparedScene| p.tf.opacity.points = vec![[0.0, 0.05], [0.3, 0.8]]),
            table_bytes,
        ),
        (
            "medium colour",
            Box::new(|p: &mut PreparedScene| {
                p.tf.medium = ColorRamp {
                    points: vec![[0.0, 1.0, 1.0, 1.0], [1.0, 0.6, 0.8, 0.9]],
                }
            }),
            table_bytes,
        ),
        ("η", Box::new(scale_eta), gradient_bytes + table_bytes),
    ];
    if level == 1 {
        // Switching refraction (at one level: the bricks and cells of both are made the same
        // way, `Untouched::occupancy`), first, while the glass is clear: without refraction
        // its bricks and cells are empty.
        let set =
            |toggle: Toggle| -> Edit { Box::new(move |p: &mut PreparedScene| p.scene.quality.refraction = toggle) };
        let toggles: [(&str, Edit, u64); 4] = [
            ("refraction off", set(Toggle::Off), 0),
            ("refraction on", set(refraction), 0),
            ("refraction off again", set(Toggle::Off), 0),
            (
                // The gradient volume kept is of the η before: it is made again.
                "η, then refraction on",
                Box::new(move |p: &mut PreparedScene| {
                    scale_eta(p);
                    p.scene.quality.refraction = refraction;
                }),
                gradient_bytes + table_bytes,
            ),
        ];
        edits.splice(0..0, toggles);
    }
    if let Some(glass) = glass_eta {
        // The glass's index back, before the clear values absorb: the glass, which is clear,
        // bends light where the bricks and cells made so far had it bend nothing.
        edits.insert(
            0,
            (
                "η of the glass",
                Box::new(move |p: &mut PreparedScene| p.tf.eta.points = glass.clone()),
                gradient_bytes + table_bytes,
            ),
        );
    }
    for (name, edit, expected) in edits {
        let before = gpu.render(&p, &req).image.pixels;
        edit(&mut p);
        let out = gpu.render(&p, &req);
        assert!(
            out.image.pixels != before,
            "level {level}, {name}: the edit changes the image"
        );
        let fresh = Gpu::new().render(&p, &req);
        assert!(
            out.image.pixels == fresh.image.pixels,
            "level {level}, {name}: not the fresh renderer's image"
        );
        // The light's tiles start where their beams come near the cells where η changes.
        assert_eq!(
            out.stats.light_steps, fresh.stats.light_steps,
            "level {level}, {name}: light tile steps"
        );
        assert_eq!(
            out.stats.upload_bytes, expected,
            "level {level}, {name}: bytes copied in"
        );
    }
    if keep {
        // The η edits left the full level behind: the first render that reads it makes the
        // volumes anew.
        p.scene.quality.volume_level = 0;
        let out = gpu.render(&p, &req);
        assert!(
            out.image.pixels == Gpu::new().render(&p, &req).image.pixels,
            "full level after the edits"
        );
        assert!(
            out.stats.upload_bytes > full / 2,
            "made anew: {} bytes",
            out.stats.upload_bytes
        );
        p.scene.quality.volume_level = level;
    }
    gpu.assert_clean();
    if level == 0 {
        return;
    }

    // A renderer that starts without refraction makes the gradient volume alone (and the
    // tables) when refraction is switched on: the volume and orientation volumes stay.
    let mut gpu = Gpu::new();
    p.scene.quality.refraction = Toggle::Off;
    let before = gpu.render(&p, &req).image.pixels;
    p.scene.quality.refraction = refraction;
    let out = gpu.render(&p, &req);
    assert!(
        out.image.pixels != before,
        "level {level}: refraction changes the image"
    );
    assert!(
        out.image.pixels == Gpu::new().render(&p, &req).image.pixels,
        "level {level}, refraction on after a start without: not the fresh renderer's image"
    );
    assert_eq!(
        out.stats.upload_bytes,
        gradient_bytes + table_bytes,
        "level {level}, refraction on after a start without: bytes copied in"
    );
    gpu.assert_clean();
}

#[test]
fn a_turn_keeps_the_layout_where_asked_and_lays_the_textures_out_anew_otherwise() {
    // Looking along x a render lays the textures out across the view; a render asking to keep
    // the layout (the viewer's first levels) reuses them when turned back to the front, with
    // no upload but its tables, and gives the image a fresh renderer gives in that layout; a
    // render laying them out for its view makes them anew in the stored layout.
    use caustica::render::VolumeLayout;
    let mut gpu = Gpu::new();
    let mut p = prepared();
    p.scene.camera.yaw_deg = 90.0;
    let side = gpu.render(&p, &RenderRequest::new(48, 40));
    assert_eq!(side.stats.volume_axes, Some([2, 1, 0]));
    p.scene.camera.yaw_deg = 0.0;
    let mut kept = RenderRequest::new(48, 40);
    kept.volume_layout = VolumeLayout::Kept;
    let front = gpu.render(&p, &kept);
    assert_eq!(front.stats.volume_axes, Some([2, 1, 0]), "the layout was kept");
    assert_eq!(front.stats.upload_bytes, 0, "nothing made anew");
    let mut fresh_kept = Gpu::new();
    p.scene.camera.yaw_deg = 90.0;
    fresh_kept.render(&p, &RenderRequest::new(48, 40));
    p.scene.camera.yaw_deg = 0.0;
    assert_eq!(front.image.pixels, fresh_kept.render(&p, &kept).image.pixels);
    let anew = gpu.render(&p, &RenderRequest::new(48, 40));
    assert_eq!(anew.stats.volume_axes, None);
    assert!(
        anew.stats.upload_bytes > side.stats.upload_bytes / 2,
        "made anew: {} bytes",
        anew.stats.upload_bytes
    );
    assert_eq!(anew.image.pixels, fresh(&p));
    gpu.assert_clean();
}

#[test]
fn the_deposit_cells_kept_between_renders_follow_the_viewport() {
    // With refraction the beams deposit only in the occupied cells grown by what a view
    // sample reads, a margin that follows the pixels' size, and the light tiles start where
    // their beams come near those cells; the renderer keeps the grown cells and their words
    // between renders while the growth in cells stays the same (`GrowthCache`). Across
    // viewports whose margins differ, each image must be the fresh renderer's. At 64³ the
    // coarse viewport's pixels (about 5 voxels) read the light of beams more cells away from
    // the ground and the ball than the fine one's margin grows them by: with the fine
    // viewport's cells kept for the coarse one, its image moved by up to 0.019 (of 2.5) and
    // this test failed. At 32³, the size it rendered before, a stale cache went unnoticed.
    let mut gpu = Gpu::new();
    let p = prepared_at(64);
    for (w, h) in [(96, 80), (12, 10), (96, 80)] {
        let req = RenderRequest::new(w, h);
        let fresh = Gpu::new().render(&p, &req).image.pixels;
        assert_eq!(gpu.render(&p, &req).image.pixels, fresh, "{w}×{h}");
    }
    gpu.assert_clean();
}

#[test]
fn an_environment_change_replaces_the_map_alone_and_its_parameters_nothing() {
    // The environment map is a scene texture too: switching between two image environments
    // must give the fresh renderer's image, not the first file's map kept, and copies in the
    // new map alone (the volumes stay). Its intensity and a background colour are parameters
    // of the passes: changing them copies nothing.
    let dir = std::env::temp_dir().join(format!("caustica-env-key-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Two equirectangular maps, 16×8: a warm sky over a dark floor, and a cool one.
    let sky = |top: [u8; 3], bottom: [u8; 3]| {
        image::RgbImage::from_fn(16, 8, |_, y| image::Rgb(if y < 4 { top } else { bottom }))
    };
    let warm = dir.join("warm.png");
    let cool = dir.join("cool.png");
    sky([240, 160, 60], [40, 20, 10]).save(&warm).unwrap();
    sky([60, 120, 240], [10, 20, 40]).save(&cool).unwrap();
    let image = |path: &std::path::Path, intensity: f32| Environment::Image {
        path: path.to_path_buf(),
        intensity,
    };
    let color = |c: f32| Environment::Color { color: [c, 0.5, 0.2] };
    // As the viewer's worker does when the scene's environment changes.
    let set = |p: &mut PreparedScene, environment: Environment| {
        p.scene.environment = environment;
        p.env = EnvMap::for_scene(&p.scene.environment).unwrap();
    };
    // The map's mip levels as 16-bit rgba texels (one black texel for a colour).
    let map_bytes = |p: &PreparedScene| {
        p.env
            .as_ref()
            .map_or(8, |e| e.levels.iter().map(|(w, h, _)| (w * h) as u64 * 8).sum::<u64>())
    };

    // The Luneburg lens floats in front of the sky: the map shows around it and through it.
    let mut scene = builtin("luneburg").unwrap().scene;
    scene.volume = VolumeSource::builtin("luneburg", 32);
    let mut p = PreparedScene::load(&scene).unwrap();
    let mut gpu = Gpu::new();
    let req = RenderRequest::new(48, 40);
    let volume_bytes = gpu.render(&p, &req).stats.upload_bytes;
    assert!(
        volume_bytes > 32 * 32 * 32 * 2,
        "a new scene copies its volumes: {volume_bytes} bytes"
    );

    // (environment, whether it brings another map)
    let steps = [
        (image(&warm, 1.0), true),
        (image(&cool, 1.0), true),
        (image(&cool, 2.5), false),
        (image(&warm, 2.5), true),
        (color(0.1), true),
        (color(0.9), false),
        (Environment::Studio { intensity: 0.5 }, true),
        (Environment::Studio { intensity: 1.5 }, false),
    ];
    for (environment, new_map) in steps {
        let before = gpu.render(&p, &req).image.pixels;
        set(&mut p, environment.clone());
        let out = gpu.render(&p, &req);
        assert_ne!(out.image.pixels, before, "{environment:?} changes the image");
        assert_eq!(out.image.pixels, fresh(&p), "{environment:?}");
        let expected = if new_map { map_bytes(&p) } else { 0 };
        assert_eq!(out.stats.upload_bytes, expected, "{environment:?}: bytes copied in");
    }
    // A transfer-function edit and another map at once: the tables and the map are copied.
    p.tf.opacity.points = vec![[0.0, 0.0], [0.3, 0.8]];
    set(&mut p, image(&cool, 1.0));
    let out = gpu.render(&p, &req);
    assert_eq!(out.image.pixels, fresh(&p), "an edit and another map");
    let table_bytes = 2 * (TABLE_SIZE * TABLE_SIZE * 8) as u64;
    assert_eq!(
        out.stats.upload_bytes,
        table_bytes + map_bytes(&p),
        "an edit and another map"
    );
    gpu.assert_clean();
    std::fs::remove_dir_all(&dir).ok();
}
