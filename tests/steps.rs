//! Images converge in the plane distance Δs: a thin tilted opaque slab is evenly bright at the
//! default Δs = 1 and as bright as at Δs = 0.25 (a highlight's energy still depends on Δs:
//! docs/accuracy.md gives the measured sizes).
//! Woodgrain (sample positions that drift across a tilted surface) shows as periodic rows in
//! the slab's brightness profile, which the evenness check catches; a deliberately banded
//! profile must fail it.

mod common;

use caustica::render::{RenderRequest, RenderedImage};
use caustica::scene::Quality;
use common::*;

const N: usize = 48;
const SIZE: u32 = 64;

/// A slab through the volume centre with a Gaussian profile of width `sigma` voxels (smooth
/// enough that the volume's trilinear reconstruction barely depends on where the slab lies
/// between voxel centres), its normal tilted by `tilt_deg` from the view axis (z) towards y.
fn slab(sigma: f32, tilt_deg: f32) -> caustica::volume::Volume {
    let (s, c) = tilt_deg.to_radians().sin_cos();
    volume_from(N, |_x, y, z| {
        let d = ((y - 0.5) * s + (z - 0.5) * c) * N as f32;
        (-0.5 * (d / sigma).powi(2)).exp()
    })
}

/// Renders the slab, opaque (τ = 16 per voxel) above value 0.9: only the top of the profile,
/// a core 2σ·sqrt(2 ln(1/0.9)) ≈ 0.92σ voxels thick, whose peak a sample at Δs = 1 misses by
/// up to half a step. White, lit from the camera, at plane distance `ds`.
fn render_slab(gpu: &mut Gpu, sigma: f32, tilt_deg: f32, ds: f32) -> RenderedImage {
    let tf = plain_tf(vec![[0.0, 0.0], [0.85, 0.0], [0.95, 1.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    // head_on_scene's light comes from the camera. Light from the side makes the slab uneven
    // at every Δs (the light grid cannot resolve a surface this sharp: docs/accuracy.md), which
    // is not what this test is about.
    let mut scene = head_on_scene(&tf);
    scene.quality = Quality {
        sample_distance: ds,
        ..Quality::default()
    };
    let p = prepared(scene, slab(sigma, tilt_deg), tf);
    gpu.render(&p, &RenderRequest::new(SIZE, SIZE)).image
}

/// Row means of luminance over the central 3/8 of the image in x and y (the volume covers
/// the central 9/16): the slab runs along x unchanged, and sample positions drift along y.
fn profile(img: &RenderedImage) -> Vec<f32> {
    let (w, h) = (img.width as usize, img.height as usize);
    (5 * h / 16..11 * h / 16)
        .map(|y| {
            let row = &img.pixels[y * w + 5 * w / 16..y * w + 11 * w / 16];
            row.iter().map(luminance).sum::<f32>() / row.len() as f32
        })
        .collect()
}

fn mean(v: &[f32]) -> f32 {
    v.iter().sum::<f32>() / v.len() as f32
}

/// The largest relative deviation of a profile from its mean.
fn unevenness(p: &[f32]) -> f32 {
    let m = mean(p);
    p.iter().map(|v| (v - m).abs() / m).fold(0.0, f32::max)
}

#[test]
fn thin_tilted_slab_is_evenly_bright_and_converged_at_the_default_step() {
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    // Opaque cores about 1.4, 1.8 and 1.4 voxels thick.
    for (sigma, tilt) in [(1.5, 10.0), (2.0, 25.0), (1.5, 40.0)] {
        let coarse = profile(&render_slab(&mut gpu, sigma, tilt, 1.0));
        let fine = profile(&render_slab(&mut gpu, sigma, tilt, 0.25));
        let (mc, mf) = (mean(&coarse), mean(&fine));
        assert!(mf > 0.05, "slab σ {sigma} at {tilt}°: dark ({mf})");
        report.push(format!(
            "σ {sigma} at {tilt}°: unevenness {:.4} (fine {:.4}), mean {mc:.4} vs fine {mf:.4}",
            unevenness(&coarse),
            unevenness(&fine)
        ));
        // 3 %: the bound on woodgrain at the default step. Before the peak-preserving split the
        // 10° slab varied by 3.5 % and was 16 % darker than at Δs = 0.25; now about 1 %, as the
        // fine image (whose own unevenness, from the trilinear reconstruction of the tilted
        // slab, is printed beside it).
        assert!(unevenness(&coarse) <= 0.03, "{report:#?}");
        // 2 %: the default step's brightness against the fine step's (pre-integration and the
        // light's averaging over the segment must make the result independent of Δs).
        assert!((mc - mf).abs() <= 0.02 * mf, "{report:#?}");
    }
    eprintln!("{report:#?}");
}

#[test]
fn a_banded_profile_fails_the_evenness_check() {
    // The check must see banding of the size it is meant to catch: 4 % stripes with a period
    // of 3 rows (what woodgrain at a 25° tilt looks like at this scale) on the fine slab.
    let mut gpu = Gpu::new();
    let fine = profile(&render_slab(&mut gpu, 2.0, 25.0, 0.25));
    assert!(unevenness(&fine) <= 0.03, "the fine slab itself is uneven");
    let banded: Vec<f32> = fine
        .iter()
        .enumerate()
        .map(|(i, v)| v * (1.0 + 0.04 * (i as f32 * std::f32::consts::TAU / 3.0).sin()))
        .collect();
    assert!(
        unevenness(&banded) > 0.03,
        "banding not detected: {}",
        unevenness(&banded)
    );
}
