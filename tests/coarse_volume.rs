//! `quality.volume_level = 1`: the passes sample the volumes at half resolution, the second
//! mip level of their images. It must render what the same volume halved on the CPU renders,
//! differ from the full resolution where detail is finer than two voxels, and share the
//! renderer's kept textures with renders at the full level.

mod common;

use caustica::render::{PreparedScene, RenderRequest};
use caustica::scene::Quality;
use caustica::volume::Volume;
use common::{diff, head_on_scene, plain_tf, prepared, Gpu};

const N: usize = 48;
/// Pixels across the volume: two voxels a pixel, so that no cap of beams per voxel binds at
/// either resolution and both renders trace the same light grid.
const SIZE: u32 = 24;
/// Mean difference allowed between two renders that read the same half level, one from the
/// GPU's mip level and one from the CPU's interpolation of it (see the test).
const TOLERANCE: f32 = 2.5e-3;

/// A ball with stripes one voxel wide in its left half (detail the half level averages to
/// grey) and a smooth gradient in its right half (which it keeps).
fn striped_ball() -> Volume {
    let mut data = Vec::with_capacity(N * N * N);
    for z in 0..N {
        for y in 0..N {
            for x in 0..N {
                let c = |i: usize| (i as f32 + 0.5) / N as f32 - 0.5;
                let r = (c(x).powi(2) + c(y).powi(2) + c(z).powi(2)).sqrt();
                let v = if r > 0.4 {
                    0.0
                } else if x < N / 2 {
                    if x % 2 == 0 {
                        0.9
                    } else {
                        0.1
                    }
                } else {
                    0.3 + 0.6 * (y as f32 / N as f32)
                };
                data.push(v);
            }
        }
    }
    Volume::new([N; 3], [1.0; 3], data).unwrap()
}

/// The volume halved as the half level is made (the mean of each 2×2×2 block), then brought
/// back to full resolution as trilinear sampling of the half level reads it: at each voxel's
/// centre, the half level's texels interpolated, transparent beyond the box (the sampler's
/// border).
fn halved_and_interpolated(v: &Volume) -> Volume {
    let m = N / 2;
    let mut half = Vec::with_capacity(m * m * m);
    for z in 0..m {
        for y in 0..m {
            for x in 0..m {
                let mut sum = 0.0;
                for (dx, dy, dz) in (0..8).map(|i| (i & 1, (i >> 1) & 1, i >> 2)) {
                    sum += v.data[((2 * z + dz) * N + 2 * y + dy) * N + 2 * x + dx];
                }
                half.push(sum / 8.0);
            }
        }
    }
    let texel = |x: i64, y: i64, z: i64| -> f32 {
        let inside = |i: i64| (0..m as i64).contains(&i);
        if inside(x) && inside(y) && inside(z) {
            half[((z as usize * m) + y as usize) * m + x as usize]
        } else {
            0.0
        }
    };
    // Voxel i's centre in half-level texel coordinates: (i + ½)/2 − ½.
    let at = |i: usize| {
        let u = i as f32 / 2.0 - 0.25;
        (u.floor() as i64, u - u.floor())
    };
    let mut data = Vec::with_capacity(N * N * N);
    for z in 0..N {
        for y in 0..N {
            for x in 0..N {
                let ((x0, fx), (y0, fy), (z0, fz)) = (at(x), at(y), at(z));
                let mut value = 0.0;
                for (dx, dy, dz) in (0..8).map(|i| (i & 1, (i >> 1) & 1, i >> 2)) {
                    let w = [1.0 - fx, fx][dx as usize] * [1.0 - fy, fy][dy as usize] * [1.0 - fz, fz][dz as usize];
                    value += w * texel(x0 + dx, y0 + dy, z0 + dz);
                }
                data.push(value);
            }
        }
    }
    Volume::new([N; 3], [1.0; 3], data).unwrap()
}

fn scene(volume: Volume, sample_distance: f32, volume_level: u32) -> PreparedScene {
    // Opacity and colour both follow the value, so stripes and their mean look different.
    let tf = plain_tf(
        vec![[0.0, 0.0], [0.05, 0.0], [0.5, 0.15], [1.0, 0.6]],
        vec![[0.0, 0.1, 0.2, 0.9], [0.5, 0.9, 0.6, 0.2], [1.0, 1.0, 1.0, 1.0]],
    );
    let quality = Quality {
        sample_distance,
        volume_level,
        ..Quality::default()
    };
    let mut s = head_on_scene(&tf);
    s.quality = quality;
    prepared(s, volume, tf)
}

#[test]
fn the_half_level_renders_what_the_volume_halved_on_the_cpu_renders() {
    let mut gpu = Gpu::new();
    let req = RenderRequest::new(SIZE, SIZE);
    let full = gpu.render(&scene(striped_ball(), 2.0, 0), &req);
    let half_level = gpu.render(&scene(striped_ball(), 2.0, 1), &req);
    // The sweep starts a sampled voxel in front of the box: two of the volume's at the half
    // level, one at full resolution. Half a plane distance earlier (2 voxels), the planes fall
    // where the half level's do.
    let mut aligned = req.clone();
    aligned.jitter[0] = 0.5;
    let cpu = gpu.render(&scene(halved_and_interpolated(&striped_ball()), 2.0, 0), &aligned);
    assert_eq!(half_level.stats.planes, cpu.stats.planes);
    assert_eq!(half_level.stats.light_grid, cpu.stats.light_grid);
    let rgb = |o: &caustica::render::RenderOutput| -> Vec<[f32; 3]> {
        o.image.pixels.iter().map(|p| [p[0], p[1], p[2]]).collect()
    };
    let (mean, max) = diff(&half_level.image.pixels, &rgb(&cpu));
    let (mean_full, _) = diff(&half_level.image.pixels, &rgb(&full));
    println!(
        "half level against the CPU's: mean {mean:.5}, max {max:.5}; against full resolution: mean {mean_full:.5}"
    );
    // Measured: mean 0.0017, at most 0.093 (the same with the bricks and cells of either
    // resolution). Between two voxel centres the CPU's volume is linear where the half level
    // bends at its texel centres (a quarter voxel away), most at the ball's silhouette and the
    // stripes' edges, and it is rounded to 16 bits at each voxel: TOLERANCE on average, 0.15
    // anywhere.
    assert!(mean < TOLERANCE && max < 0.15, "mean {mean}, max {max}");
    // The stripes average out: the full resolution looks different by far more (0.0089).
    assert!(mean_full > 2.0 * TOLERANCE, "full resolution differs by {mean_full}");
}

#[test]
fn renders_at_either_level_share_the_kept_textures() {
    let req = RenderRequest::new(SIZE, SIZE);
    let fresh = |p: &PreparedScene| Gpu::new().render(p, &req).image.pixels;
    let mut gpu = Gpu::new();
    let mut keep = req.clone();
    keep.keep_coarse_volume = true;
    // The viewer's order: a coarse level, the full level, the coarse level again. The first
    // frame makes both levels, and each render after it finds them kept.
    let mut p = scene(striped_ball(), 2.0, 1);
    let first = gpu.render(&p, &keep);
    assert!(first.stats.upload_bytes > 0);
    for (level, name) in [(0, "full level"), (1, "half level")] {
        p.scene.quality.volume_level = level;
        let out = gpu.render(&p, &keep);
        assert_eq!(out.stats.upload_bytes, 0, "{name}: the kept textures serve");
        assert_eq!(out.image.pixels, fresh(&p), "{name}: the image of a fresh upload");
    }
    // Another data window while the coarse level renders (a drag of the viewer's window
    // slider): the volumes are made anew at the half level alone. The full level holds back
    // the volume's 16-bit samples and the orientation volume's four 16-bit channels per voxel
    // (nothing refracts here: no gradient volume at either level), a placeholder texel in a
    // staging slot of 16 bytes in place of each.
    let dims = p.volume.dims;
    let voxels = (dims[0] * dims[1] * dims[2]) as u64;
    p.scene.window = Some([0.0, 0.6]);
    let windowed = gpu.render(&p, &keep);
    assert_eq!(
        windowed.stats.upload_bytes + voxels * (2 + 8),
        first.stats.upload_bytes + 2 * 16,
        "a new data window makes the half level alone"
    );
    assert_ne!(
        windowed.image.pixels, first.image.pixels,
        "the window changes the image"
    );
    assert_eq!(
        windowed.image.pixels,
        fresh(&p),
        "another window: the image of a fresh upload"
    );
    // The first render that reads the full level makes both, whose half level is the same to
    // the bit; the coarse level then finds them kept.
    p.scene.quality.volume_level = 0;
    let full = gpu.render(&p, &keep);
    assert_eq!(full.stats.upload_bytes, first.stats.upload_bytes, "both levels made");
    assert_eq!(full.image.pixels, fresh(&p), "another window, full level");
    p.scene.quality.volume_level = 1;
    let again = gpu.render(&p, &keep);
    assert_eq!(again.stats.upload_bytes, 0, "half level: the kept textures serve");
    assert_eq!(again.image.pixels, windowed.image.pixels, "the half level made alone");
    // Another volume (a time step, another file) is made at the half level alone as well.
    p.volume = std::sync::Arc::new(striped_ball());
    let other = gpu.render(&p, &keep);
    assert_eq!(other.stats.upload_bytes, windowed.stats.upload_bytes, "another volume");
    assert_eq!(
        other.image.pixels,
        fresh(&p),
        "another volume: the image of a fresh upload"
    );

    // Textures made without the half level are made again for a render that reads it.
    let mut gpu = Gpu::new();
    p.scene.quality.volume_level = 0;
    gpu.render(&p, &req);
    p.scene.quality.volume_level = 1;
    let again = gpu.render(&p, &req);
    assert!(again.stats.upload_bytes > 0, "the half level is uploaded");
    assert_eq!(again.image.pixels, fresh(&p));
}
