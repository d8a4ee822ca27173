//! Volume data on the GPU: anisotropic spacing is honoured, an η volume on another grid is
//! resampled, oversized volumes are downsampled (or refused), time-series frames load.

mod common;

use caustica::render::{PreparedScene, RenderRequest};
use caustica::scene::{Projection, VolumeSource};
use caustica::volume::Volume;

use common::{head_on_scene, plain_tf, prepared, Gpu};

/// Bounding box (columns, rows) of the pixels brighter than the black background.
fn silhouette(pixels: &[[f32; 4]], size: usize) -> (usize, usize) {
    let (mut x0, mut x1, mut y0, mut y1) = (size, 0, size, 0);
    for y in 0..size {
        for x in 0..size {
            if pixels[y * size + x][0] > 0.05 {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
    }
    assert!(x1 >= x0 && y1 >= y0, "nothing visible");
    (x1 - x0 + 1, y1 - y0 + 1)
}

#[test]
fn anisotropic_spacing_is_not_squashed() {
    // 32 × 32 × 8 voxels of 1 × 1 × 4 mm: a 32 mm cube in space, a flat slab in voxels.
    let dims = [32, 32, 8];
    let data = vec![1.0; 32 * 32 * 8];
    let cube = Volume::new(dims, [1.0, 1.0, 4.0], data).expect("volume");
    let tf = plain_tf(vec![[0.0, 0.0], [0.5, 1.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let mut scene = head_on_scene(&tf);
    // Seen from the side (along x) the image shows y vertically and z horizontally.
    scene.camera.yaw_deg = 90.0;
    scene.camera.projection = Projection::Orthographic;
    let mut gpu = Gpu::new();
    let size = 64;
    let out = gpu.render(&prepared(scene, cube, tf), &RenderRequest::new(size, size));
    let (width, height) = silhouette(&out.image.pixels, size as usize);
    // Orthographic at zoom 1: the image spans the bounding diameter, √3 · 32 mm.
    let px_per_mm = size as f32 / (3.0f32.sqrt() * 32.0);
    let cube_px = 32.0 * px_per_mm;
    // Linear filtering with a zero border lets each face fade out over half a voxel outside
    // the box, so a side may look up to one voxel (4 mm along z, 1 mm along y) larger, plus a
    // pixel of rounding. Squashed into voxel units, the 8-voxel depth would be 9 px wide.
    let fits = |px: usize, voxel_mm: f32| {
        let px = px as f32;
        px >= cube_px - 1.0 && px <= cube_px + voxel_mm * px_per_mm + 1.0
    };
    assert!(
        fits(width, 4.0),
        "width {width} px: the 32 mm depth along z should span {cube_px:.1} px"
    );
    assert!(
        fits(height, 1.0),
        "height {height} px: the 32 mm height should span {cube_px:.1} px"
    );
}

#[test]
fn eta_volume_on_another_grid_is_resampled() {
    let dir = std::env::temp_dir().join(format!("caustica-formats-eta-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let main = Volume::new([32, 32, 32], [1.0; 3], vec![0.5; 32 * 32 * 32]).unwrap();
    let eta = Volume::new([16, 16, 16], [2.0; 3], (0..4096).map(|i| (i % 16) as f32).collect()).unwrap();
    let (main_path, eta_path) = (dir.join("main.nrrd"), dir.join("eta.nrrd"));
    caustica::volume::nrrd::write_nrrd(&main_path, &main, false).unwrap();
    caustica::volume::nrrd::write_nrrd(&eta_path, &eta, false).unwrap();
    let tf = plain_tf(vec![[0.0, 0.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let mut scene = head_on_scene(&tf);
    scene.volume = VolumeSource::File {
        path: main_path,
        series: None,
    };
    scene.eta_volume = Some(VolumeSource::File {
        path: eta_path,
        series: None,
    });
    let p = PreparedScene::load(&scene).expect("a different grid is resampled, not refused");
    let resampled = p.eta_volume.as_ref().expect("eta volume");
    assert_eq!(resampled.dims, [32, 32, 32]);
    assert_eq!(resampled.extent(), p.volume.extent());
    // The ramp along x survives: ends near 0 and 15, increasing.
    assert!(resampled.get(0, 5, 5) < 0.5 && resampled.get(31, 5, 5) > 14.5);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn oversized_volume_is_downsampled_or_refused() {
    let tf = plain_tf(vec![[0.0, 0.0], [1.0, 0.5]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let vol = common::sphere(48, 0.3, 1.0);
    let scene = head_on_scene(&tf);
    let mut refused = prepared(scene.clone(), vol.clone(), tf.clone());
    let err = refused.fit_to_device(32, u64::MAX, false).unwrap_err().to_string();
    assert!(err.contains("48×48×48") && err.contains("32 texels"), "{err}");
    let mut p = prepared(scene, vol, tf);
    assert_eq!(p.fit_to_device(32, u64::MAX, true).unwrap(), Some([32, 32, 32]));
    assert_eq!(p.volume.extent(), [48.0; 3]);
    // Byte budget: 2 bytes per voxel, 16³ voxels allowed.
    assert_eq!(
        p.fit_to_device(1024, 2 * 16 * 16 * 16, true).unwrap(),
        Some([16, 16, 16])
    );
    let mut gpu = Gpu::new();
    let out = gpu.render(&p, &RenderRequest::new(32, 32));
    assert_eq!(out.image.count_invalid(), (0, 0));
    assert!(out.image.max_value() > 0.05, "the downsampled sphere is still visible");
}

/// The byte budget counts what the device holds: 2 bytes per voxel of the volume and, with
/// refraction, 8 per voxel of the gradient volume (of the η volume when there is one, whose own
/// samples are not uploaded).
#[test]
fn the_byte_budget_counts_the_gradient_volume_of_a_refracting_scene() {
    let vol = common::sphere(48, 0.3, 1.0);
    let clear = plain_tf(vec![[0.0, 0.0], [1.0, 0.5]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let mut glass = clear.clone();
    glass.eta = caustica::transfer::Curve {
        points: vec![[0.0, 1.0], [1.0, 1.5]],
    };
    let budget = 10 * 16 * 16 * 16;
    // Without refraction 2 bytes per voxel: 20480 voxels fit, 27³.
    let mut p = prepared(head_on_scene(&clear), vol.clone(), clear.clone());
    assert_eq!(p.fit_to_device(1024, budget, true).unwrap(), Some([27, 27, 27]));
    // With refraction 10: 16³.
    let mut p = prepared(head_on_scene(&glass), vol.clone(), glass.clone());
    assert_eq!(p.fit_to_device(1024, budget, true).unwrap(), Some([16, 16, 16]));
    // 16³ with refraction fits exactly, and refraction switched off frees the gradient's share.
    assert_eq!(p.fit_to_device(1024, budget, true).unwrap(), None);
    let mut off = head_on_scene(&glass);
    off.quality.refraction = caustica::scene::Toggle::Off;
    let mut p = prepared(off, vol.clone(), glass.clone());
    assert_eq!(p.fit_to_device(1024, budget, true).unwrap(), Some([27, 27, 27]));
    // An η volume of its own: its gradient is counted at its dims, and both are resampled to
    // the volume's new dims. A 16³ volume with a 48³ η volume needs 2·16³ + 8·48³ bytes.
    let mut p = prepared(head_on_scene(&glass), common::sphere(16, 0.3, 1.0), glass.clone());
    p.eta_volume = Some(std::sync::Arc::new(vol));
    let err = p.fit_to_device(1024, budget, false).unwrap_err().to_string();
    assert!(err.contains("exceeds"), "{err}");
    assert_eq!(p.fit_to_device(1024, budget, true).unwrap(), Some([16, 16, 16]));
    assert_eq!(p.eta_volume.as_ref().map(|e| e.dims), Some([16, 16, 16]));
}

/// The orientation volume (8 bytes per voxel of the volume) is made only where it fits beside
/// the other volume textures; where it does not, the view samples the volume instead and the
/// volume keeps its size.
#[test]
fn the_orientation_volume_is_kept_only_where_it_fits() {
    let clear = plain_tf(vec![[0.0, 0.0], [1.0, 0.5]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let voxels = 16 * 16 * 16;
    let mut p = prepared(head_on_scene(&clear), common::sphere(16, 0.3, 1.0), clear);
    assert!(p.orientation_volume, "made unless a device says otherwise");
    // 2 + 8 bytes per voxel fit: kept.
    assert_eq!(p.fit_to_device(1024, 10 * voxels, false).unwrap(), None);
    assert!(p.orientation_volume && !p.features().sampled_layers);
    // A byte less: dropped, and the volume is not downsampled for it.
    assert_eq!(p.fit_to_device(1024, 10 * voxels - 1, false).unwrap(), None);
    assert!(!p.orientation_volume && p.features().sampled_layers);
    // Downsampled for its axes alone, the smaller volume has room for it again.
    assert_eq!(p.fit_to_device(8, 10 * voxels - 1, true).unwrap(), Some([8, 8, 8]));
    assert!(p.orientation_volume);
}

/// The volumes' half-resolution level (an image of ⌊n/2⌋ per axis beside each volume image)
/// counts in the byte budget where it is made: where the scene reads it
/// (`quality.volume_level`) or the renders keep it (the viewer).
#[test]
fn the_byte_budget_counts_the_half_resolution_level() {
    let clear = plain_tf(vec![[0.0, 0.0], [1.0, 0.5]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let (full, half) = (16 * 16 * 16, 8 * 8 * 8);
    let mut coarse = head_on_scene(&clear);
    coarse.quality.volume_level = 1;
    let mut p = prepared(coarse, common::sphere(16, 0.3, 1.0), clear.clone());
    // 2 + 8 bytes per voxel of the full volumes and of their half level fit: all kept.
    assert_eq!(p.fit_to_device(1024, 10 * (full + half), false).unwrap(), None);
    assert!(p.orientation_volume);
    // The full volumes' bytes alone, which fit without the half level: the orientation volume
    // is dropped for it.
    assert_eq!(p.fit_to_device(1024, 10 * full, false).unwrap(), None);
    assert!(!p.orientation_volume);
    let mut plain = prepared(head_on_scene(&clear), common::sphere(16, 0.3, 1.0), clear.clone());
    assert_eq!(plain.fit_to_device(1024, 10 * full, false).unwrap(), None);
    assert!(plain.orientation_volume, "without the half level they fit");
    assert_eq!(plain.fit_to_device_keeping(1024, 10 * full, false, true).unwrap(), None);
    assert!(!plain.orientation_volume, "kept for the viewer, the half level counts");
    // The 16-bit volume alone fits in 2·16³ bytes, not with its half level: downsampled, to
    // 2·(n³ + ⌊n/2⌋³) ≤ 2·16³, 15³ (2·(3375 + 343) = 7436 ≤ 8192).
    let err = p.fit_to_device(1024, 2 * full, false).unwrap_err().to_string();
    assert!(err.contains("exceeds"), "{err}");
    assert_eq!(p.fit_to_device(1024, 2 * full, true).unwrap(), Some([15, 15, 15]));
}

#[test]
fn time_series_scene_loads_the_selected_frame() {
    let dir = std::env::temp_dir().join(format!("caustica-formats-series-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for k in 0..3 {
        let vol = Volume::new([4, 4, 4], [1.0; 3], vec![k as f32 * 10.0 + 1.0; 64]).unwrap();
        caustica::volume::nrrd::write_nrrd(&dir.join(format!("t{k}.nrrd")), &vol, true).unwrap();
    }
    let scene_path = dir.join("series.toml");
    std::fs::write(
        &scene_path,
        "transfer = { opacity = [[0.0, 0.0], [1.0, 0.5]] }\n[volume]\nkind = \"series\"\npattern = \"t*.nrrd\"\nframe = 1\n",
    )
    .unwrap();
    let scene = caustica::scene::Scene::load(&scene_path).expect("series scene");
    assert_eq!(scene.volume.series().unwrap().map(|s| s.len()), Some(3));
    let mut p = PreparedScene::load(&scene).expect("frame 1 loads");
    assert_eq!(p.volume.data[0], 11.0);
    p.load_frame(2).expect("frame 2 loads");
    assert_eq!(p.volume.data[0], 21.0);
    assert!(p
        .load_frame(3)
        .unwrap_err()
        .to_string()
        .contains("frame 3 does not exist"));
    let _ = std::fs::remove_dir_all(&dir);
}
