//! Images converge in the plane distance Δs: a thin tilted opaque slab is evenly bright at the
//! default Δs = 1 and as bright as at Δs = 0.25, and a highlight's energy does not depend on Δs.
//! Woodgrain (sample positions that drift across a tilted surface) shows as periodic rows in
//! the slab's brightness profile, which the evenness check catches; a deliberately banded
//! profile must fail it, and a deliberately banded highlight the energy check.

mod common;

use caustica::reference::shading::{cook_torrance, fresnel_dielectric};
use caustica::render::{RenderRequest, RenderedImage};
use caustica::scene::{light_direction, Light, Quality, Toggle, ViewSetup};
use caustica::transfer::{Curve, TransferFunctions};
use common::*;
use glam::{DVec3, Vec2, Vec3};

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

/// The slab, opaque (τ = 16 per voxel) above value 0.9: only the top of the profile, a core
/// 2σ·sqrt(2 ln(1/0.9)) ≈ 0.92σ voxels thick, whose peak a sample at Δs = 1 misses by up to
/// half a step. White, at plane distance `ds`, lit from the camera (`head_on_scene`).
fn slab_scene(sigma: f32, tilt_deg: f32, ds: f32) -> caustica::render::PreparedScene {
    let tf = plain_tf(vec![[0.0, 0.0], [0.85, 0.0], [0.95, 1.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let mut scene = head_on_scene(&tf);
    scene.quality = Quality {
        sample_distance: ds,
        ..Quality::default()
    };
    prepared(scene, slab(sigma, tilt_deg), tf)
}

/// The slab lit from the camera. Light from the side makes it uneven at every Δs (the beams
/// cannot resolve a surface this sharp: `a_side_lit_opaque_slab_…` below), which is not what
/// the evenness checks are about.
fn render_slab(gpu: &mut Gpu, sigma: f32, tilt_deg: f32, ds: f32) -> RenderedImage {
    gpu.render(&slab_scene(sigma, tilt_deg, ds), &RenderRequest::new(SIZE, SIZE))
        .image
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

/// The slab of [`slab_scene`] lit from 30° off the view axis at `azimuth` (0: tilted in the
/// plane of the slab's normal, 90: across it), averaged over `renders` jittered sweeps
/// ([`caustica::render::accumulate`]).
fn render_side_lit_slab(
    gpu: &mut Gpu,
    sigma: f32,
    tilt_deg: f32,
    ds: f32,
    renders: u32,
    azimuth: f32,
) -> RenderedImage {
    let mut p = slab_scene(sigma, tilt_deg, ds);
    p.scene.light = Light {
        polar_deg: 30.0,
        azimuth_deg: azimuth,
        ..p.scene.light
    };
    let out = caustica::render::accumulate(&mut gpu.renderer, &p, &RenderRequest::new(SIZE, SIZE), renders, |_| {})
        .expect("render succeeds");
    gpu.assert_clean();
    out.image
}

/// The Lommel–Seeliger law: the brightness of a deep layer of white particles lit by unit light
/// at the cosine `mu0` from its normal and seen at the cosine `mu` (single scattering, isotropic
/// particles, the renderer's model in the limit of fine steps and fine light).
fn lommel_seeliger(mu0: f32, mu: f32) -> f32 {
    mu0 / (mu0 + mu)
}

#[test]
fn a_side_lit_opaque_slab_is_as_bright_as_the_lommel_seeliger_law() {
    // The slab's normal is tilted by t from the view axis toward +y; the light 30° off the view
    // axis, tilted away from the normal (azimuth 0: μ0 = cos(t + 30°)) or across it (azimuth 90:
    // μ0 = cos 30° cos t); the camera sees it at μ = cos t.
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    for (sigma, tilt) in [(1.5f32, 10.0f32), (2.0, 25.0), (1.5, 40.0)] {
        let t = tilt.to_radians();
        for (azimuth, mu0) in [
            (0.0, (t + 30f32.to_radians()).cos()),
            (90.0, 30f32.to_radians().cos() * t.cos()),
        ] {
            let exact = lommel_seeliger(mu0, t.cos());
            for ds in [1.0, 0.25] {
                let m = mean(&profile(&render_side_lit_slab(&mut gpu, sigma, tilt, ds, 1, azimuth)));
                report.push(format!(
                    "σ {sigma} at {tilt}°, azimuth {azimuth}, Δs {ds}: {m:.4} against {exact:.4} ({:+.1}%)",
                    100.0 * (m / exact - 1.0)
                ));
                // 15 %: what the light read a voxel back along each view sample's own light
                // line leaves of the beams' interpolation across the surface (measured −14.4 %
                // to 0 %, the most at 40° with the light 70° from the normal, −12.1 % at Δs 1);
                // reading the beams' light on the sample's plane, the slab was 13–46 % too
                // bright at 25° and 40° with the light tilted away, and one plane back (not a
                // voxel) at Δs ¼ 20 % too dark at 40°.
                assert!((m / exact - 1.0).abs() <= 0.15, "{report:#?}");
            }
        }
    }
    eprintln!("{report:#?}");
}

#[test]
fn a_side_lit_slab_in_a_refracting_scene_is_as_bright_at_fine_steps() {
    // The Lommel–Seeliger check with refraction on (η constant): the refracted beams deposit
    // their light on the planes, and the view takes the attenuation of their last segments
    // along its own light line. At Δs ¼ the beams one plane back still straddle the surface,
    // and the fine render came out darker than the default one; they deposit the power they had
    // a voxel back, as the unrefracted beams' light is read.
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    let mut errors = Vec::new();
    for (sigma, tilt) in [(1.5f32, 10.0f32), (2.0, 25.0), (1.5, 40.0)] {
        let t = tilt.to_radians();
        let exact = lommel_seeliger((t + 30f32.to_radians()).cos(), t.cos());
        for ds in [1.0, 0.25] {
            let mut p = slab_scene(sigma, tilt, ds);
            p.scene.quality.refraction = Toggle::On;
            p.scene.light = Light {
                polar_deg: 30.0,
                azimuth_deg: 0.0,
                ..p.scene.light
            };
            let rows = profile(&gpu.render(&p, &RenderRequest::new(SIZE, SIZE)).image);
            let m = mean(&rows);
            let u = unevenness(&rows);
            report.push(format!(
                "σ {sigma} at {tilt}°, Δs {ds}: {m:.4} against {exact:.4} ({:+.1}%), unevenness {u:.3}",
                100.0 * (m / exact - 1.0)
            ));
            errors.push((tilt, ds, m / exact - 1.0, u));
        }
    }
    eprintln!("{report:#?}");
    for (tilt, ds, e, u) in errors {
        // Measured at Δs 1: −4.7 %, −5.9 %, −12.1 %; at Δs ¼: −3.3 %, −3.9 %, −14.4 %, as the
        // unrefracted light reads (`a_side_lit_opaque_slab_…`, whose 15 % bounds this too).
        // One plane back (not a voxel) at Δs ¼ the slab was −17.8 % at 25° and −25.6 % at 40°.
        assert!(e.abs() <= 0.15, "{tilt}°, Δs {ds}: {e:+.3} {report:#?}");
        // Evenly bright along the slab, as without refraction (5 %, the bound of
        // `a_side_lit_slab_is_evenly_bright_…`; at 40° the beams about a voxel apart do not
        // resolve a surface the light meets 70° from its normal, with or without refraction):
        // measured 0.033 and 0.014 at Δs 1, 0.016 and 0.023 at Δs ¼. Beams whose footprint
        // came out a rounding wider than a texel deposited on the next pyramid level, rows of
        // them at a time, and the slab's rows were 12–59 % off.
        if tilt < 30.0 {
            assert!(u <= 0.05, "{tilt}°, Δs {ds}: unevenness {u:.3} {report:#?}");
        }
    }
}

#[test]
fn a_side_lit_slab_is_evenly_bright_at_the_default_step() {
    // Side light changes along the view ray within a segment faster than the view's own
    // transmittance; where the ends of a segment misjudged how much faster (a thin sheet's
    // core, the light at its back gone out) some rows of sample positions came out much too
    // dark and others too bright.
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    let mut worst = 0.0f32;
    for (sigma, tilt, azimuth) in [
        (1.5, 10.0, 0.0),
        (2.0, 25.0, 0.0),
        (1.5, 10.0, 90.0),
        (2.0, 25.0, 90.0),
        (1.5, 40.0, 90.0),
    ] {
        let u = unevenness(&profile(&render_side_lit_slab(&mut gpu, sigma, tilt, 1.0, 1, azimuth)));
        report.push(format!("σ {sigma} at {tilt}°, azimuth {azimuth}: unevenness {u:.4}"));
        worst = worst.max(u);
    }
    eprintln!("{report:#?}");
    // 5 %: measured 0.033 and 0.014 with the light tilted away, at most 0.011 across; with the
    // light's fall taken from the segment's ends alone 0.52 and 0.26 away. (At 40° with the
    // light tilted away, 70° from the normal, the rows vary by 17 %: the beams, about a voxel
    // apart, do not resolve a surface met that obliquely; `render --accumulate` averages that,
    // below.)
    assert!(worst <= 0.05, "{report:#?}");
}

#[test]
fn accumulated_renders_even_out_a_side_lit_surface() {
    // The side-lit slab's rows vary with where the planes and beams fall across its surface
    // (most at 40°, where the light meets it 70° from the normal); averaging renders over
    // jittered lattices (`render --accumulate`) averages that out.
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    for (sigma, tilt) in [(1.5, 10.0), (1.5, 40.0)] {
        let single = profile(&render_side_lit_slab(&mut gpu, sigma, tilt, 1.0, 1, 0.0));
        let acc = profile(&render_side_lit_slab(&mut gpu, sigma, tilt, 1.0, 8, 0.0));
        report.push(format!(
            "σ {sigma} at {tilt}°: unevenness {:.4} → {:.4}, mean {:.4} → {:.4}",
            unevenness(&single),
            unevenness(&acc),
            mean(&single),
            mean(&acc)
        ));
        // Half: eight renders of patterns that move from render to render leave about 1/√8 of
        // their amplitude where the rows' errors are independent (measured 0.28 and 0.30 of
        // it: 0.033 → 0.009 and 0.155 → 0.046).
        assert!(unevenness(&acc) <= 0.5 * unevenness(&single), "{report:#?}");
        // 6 %: the jittered renders' mean is the standard render's (measured within 0.4 % and
        // 2.2 %; 1.3–4.7 % before side light was taken along the layer).
        assert!((mean(&acc) / mean(&single) - 1.0).abs() <= 0.06, "{report:#?}");
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

/// Glass spheres (η 1.5, radius 0.3 of the box) for highlights, lit from 25° off the view axis.
#[derive(Clone, Copy, Debug)]
enum Glass {
    /// Clear: the outer highlight plus the reflections inside the sphere (its rim and the
    /// light reflected off its back).
    Clear,
    /// A black opaque core under a clear coat (η reaches 1.5 at value 0.6, opacity starts at
    /// 0.7): only the outer highlight shows, which has an exact answer ([`exact_highlight`]).
    Coated,
}

/// Where a highlight is measured: the volume's edge in voxels and the image's in pixels.
#[derive(Clone, Copy, Debug)]
struct Grid {
    voxels: usize,
    pixels: u32,
}

/// The size of the other checks: the sphere 14 voxels in radius, about 12 pixels.
const SMALL: Grid = Grid {
    voxels: N,
    pixels: SIZE,
};
/// A sphere of 19 voxels, about 24 pixels in radius: pixels resolve a lobe of roughness 0.3
/// (the exact highlight's energy moves by 0.4 % when the pixels' samples are moved by a
/// quarter or half of a pixel, [`sampling_spread`]).
const RESOLVED: Grid = Grid {
    voxels: 64,
    pixels: 128,
};

fn glass_scene(glass: Glass, roughness: f32, ds: f32, grid: Grid) -> caustica::render::PreparedScene {
    let (mut tf, eta): (TransferFunctions, _) = match glass {
        Glass::Clear => (
            plain_tf(vec![[0.0, 0.0]], vec![[0.0, 1.0, 1.0, 1.0]]),
            vec![[0.0, 1.0], [1.0, 1.5]],
        ),
        Glass::Coated => (
            plain_tf(vec![[0.0, 0.0], [0.7, 0.0], [0.9, 1.0]], vec![[0.0, 0.0, 0.0, 0.0]]),
            vec![[0.0, 1.0], [0.6, 1.5], [1.0, 1.5]],
        ),
    };
    tf.eta = Curve { points: eta };
    let mut scene = head_on_scene(&tf);
    scene.light = Light {
        polar_deg: 25.0,
        azimuth_deg: 30.0,
        ..scene.light
    };
    scene.shading.roughness = roughness;
    scene.quality = Quality {
        sample_distance: ds,
        refraction: Toggle::On,
        specular: true,
        ..Quality::default()
    };
    prepared(scene, sphere(grid.voxels, 0.3, 1.0), tf)
}

fn energy(img: &RenderedImage) -> f32 {
    img.pixels.iter().map(luminance).sum()
}

fn render_glass(gpu: &mut Gpu, glass: Glass, roughness: f32, ds: f32, grid: Grid) -> RenderedImage {
    gpu.render(
        &glass_scene(glass, roughness, ds, grid),
        &RenderRequest::new(grid.pixels, grid.pixels),
    )
    .image
}

/// 5 %: the bound on a highlight's energy between plane distances, each against the finest
/// (Δs = 0.25), where the pixels resolve the lobe. What bounds it is the highlight's own
/// evaluation (the interface's normal where each segment's share of the index change is
/// centred, from the trilinear gradient of a voxelised sphere): measured +1.9 % and +4.0 % at
/// roughness 0.3, +1.3 % and +2.1 % at 0.4, for Δs = 1 and ½.
fn same_energy(e: f32, finest: f32) -> bool {
    (e - finest).abs() <= 0.05 * finest
}

/// The coated sphere's outer highlight traced exactly at the pixels' samples, moved by
/// `offset` pixels from their centres (the GPU's sampling): Fresnel (1 → 1.5) × Cook–Torrance
/// of the sphere's normal where η is halfway (value 0.3 of `sphere`'s ramp: 0.2 of its
/// 1.5-voxel edge outside the radius), lit by the unit light (`point_at` takes pixel u as
/// [u, u + 1)). The image's energy.
fn exact_highlight(p: &caustica::render::PreparedScene, grid: Grid, offset: Vec2) -> f32 {
    let n = grid.voxels;
    let size = grid.pixels;
    let view = ViewSetup::new(&p.scene, [n; 3], [1.0; 3], size, size).expect("view");
    let centre = view.view_from_world.transform_point3(Vec3::ZERO).as_dvec3();
    let radius = 0.3 * n as f64 + 0.2 * 1.5;
    let l = -light_direction(&p.scene.light).as_dvec3();
    let v = DVec3::new(0.0, 0.0, -1.0);
    let mut e = 0.0;
    for py in 0..size {
        for px in 0..size {
            let o = view
                .point_at(Vec2::new(px as f32 + 0.5, py as f32 + 0.5) + offset, 0.0)
                .as_dvec3();
            let d = DVec3::new(o.x - centre.x, o.y - centre.y, 0.0);
            let h2 = radius * radius - d.length_squared();
            if h2 > 0.0 {
                let n = DVec3::new(d.x, d.y, -h2.sqrt()) / radius;
                e += fresnel_dielectric(n.dot(v), 1.0, 1.5) * cook_torrance(n, l, v, p.scene.shading.roughness as f64);
            }
        }
    }
    e as f32
}

/// How much the exact highlight's energy moves when the pixels' samples move by a quarter or
/// half a pixel: (largest − smallest) / at the centres. Where it is large, which pixels meet
/// the lobe decides its energy, and a plane distance that moves the evaluation by a fraction
/// of a pixel changes it as much.
fn sampling_spread(p: &caustica::render::PreparedScene, grid: Grid) -> f32 {
    let e: Vec<f32> = [
        (0.0, 0.0),
        (0.25, 0.0),
        (0.5, 0.0),
        (0.0, 0.25),
        (0.0, 0.5),
        (0.25, 0.25),
    ]
    .iter()
    .map(|&(x, y)| exact_highlight(p, grid, Vec2::new(x, y)))
    .collect();
    let (lo, hi) = e
        .iter()
        .fold((f32::MAX, f32::MIN), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    (hi - lo) / e[0]
}

#[test]
fn highlight_energy_does_not_depend_on_the_plane_distance() {
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    // The outer highlight where the pixels resolve it. A lobe narrower than a pixel cannot be
    // checked to 5 %: at the small size with roughness 0.2 the exact energy itself moves by
    // 44 % with where the samples fall in the pixels, at roughness 0.3 by 3.3 % (here 0.4 %).
    for roughness in [0.3, 0.4] {
        let spread = sampling_spread(&glass_scene(Glass::Coated, roughness, 1.0, RESOLVED), RESOLVED);
        assert!(spread < 0.01, "the lobe is not resolved: {spread}");
        let e: Vec<f32> = [1.0, 0.5, 0.25]
            .iter()
            .map(|&ds| energy(&render_glass(&mut gpu, Glass::Coated, roughness, ds, RESOLVED)))
            .collect();
        report.push(format!(
            "coated, roughness {roughness}: energy at Δs = 1, 0.5, 0.25: {e:?} (exact's sampling spread {spread:.4})"
        ));
        assert!(e[2] > 0.5, "no highlight: {report:#?}");
        assert!(same_energy(e[0], e[2]) && same_energy(e[1], e[2]), "{report:#?}");
    }
    // The clear sphere adds the highlights inside it, lit by the light the glass focuses; at
    // the small size, where its lobe (roughness 0.2) is narrower than a pixel, this is a
    // check against gross errors only. Before the highlight was evaluated where the
    // segment's index change is centred, with the view ray and the light as they are in front
    // of the interface, it gave 31.7, 21.3, 19.6: 62 % too much at Δs = 1 (a segment end
    // beyond the interface read a refracted light direction and a bent ray). Measured −6.4 %
    // and −2.1 %; bound 9 %, which that error fails.
    let e: Vec<f32> = [1.0, 0.5, 0.25]
        .iter()
        .map(|&ds| energy(&render_glass(&mut gpu, Glass::Clear, 0.2, ds, SMALL)))
        .collect();
    report.push(format!("clear, small: energy at Δs = 1, 0.5, 0.25: {e:?}"));
    assert!(e[2] > 0.5, "no highlight: {report:#?}");
    for x in &e[..2] {
        assert!((x - e[2]).abs() <= 0.09 * e[2], "{report:#?}");
    }
    // Against the exact outer highlight at its pixel centres.
    for roughness in [0.3, 0.4] {
        let p = glass_scene(Glass::Coated, roughness, 1.0, RESOLVED);
        let (gpu_e, exact) = (
            energy(
                &gpu.render(&p, &RenderRequest::new(RESOLVED.pixels, RESOLVED.pixels))
                    .image,
            ),
            exact_highlight(&p, RESOLVED, Vec2::ZERO),
        );
        report.push(format!(
            "coated, roughness {roughness}, Δs = 1: {gpu_e} against exact {exact}"
        ));
        // 10 %: what bounds it is the light the GPU reads at the surface (the light buffer
        // next to the opaque core's shadow: 0.8–0.95 of the source there), the Fresnel share's
        // overcount where the ±1.5-voxel search falls short of the index plateaus (4–7 %) and
        // where the smoothed interface lies (±0.3 voxel of radius: ±3 % of area). Measured
        // −2.4 % (0.3) and −5.7 % (0.4).
        assert!((gpu_e - exact).abs() <= 0.10 * exact, "{report:#?}");
        // The CPU reference's highlight against the same exact one (its view rays traced by
        // RK4, its light from photons). 10 %: measured −0.6 % (0.3) and −2.2 % (0.4). Lit by
        // the unit light it reads +8.0 % and +10.8 % (the voxelised sphere's normals, central
        // differences over a voxel, still widen the lobe a little), and the photons' light it
        // reads at the surface is about 0.92 of the source (their grid's trilinear light next
        // to the opaque core). With normals from quarter-voxel differences, which follow the
        // trilinear field's facets, it read +18 % and +25 %.
        let reference = caustica::reference::render(
            &p,
            RESOLVED.pixels,
            RESOLVED.pixels,
            &caustica::reference::ReferenceSettings::default(),
            false,
        )
        .expect("reference renders");
        let ref_e = energy(&reference);
        report.push(format!(
            "coated, roughness {roughness}: reference {ref_e} against exact {exact}"
        ));
        assert!((ref_e - exact).abs() <= 0.10 * exact, "{report:#?}");
    }
    eprintln!("{report:#?}");
}

#[test]
fn a_banded_highlight_fails_the_energy_check() {
    // Woodgrain in a highlight: the lobe met near its peak on some rows of sample positions
    // and off it on others. One row in three 40 % brighter (13 % more energy where the rows
    // are alike), on the resolved highlight at the finest step, must fail the energy check
    // that the plane distances pass.
    let mut gpu = Gpu::new();
    let img = render_glass(&mut gpu, Glass::Coated, 0.3, 0.25, RESOLVED);
    let fine = energy(&img);
    let w = img.width as usize;
    let banded: f32 = img
        .pixels
        .iter()
        .enumerate()
        .map(|(i, p)| luminance(p) * if (i / w) % 3 == 0 { 1.4 } else { 1.0 })
        .sum();
    assert!(same_energy(fine, fine));
    assert!(
        !same_energy(banded, fine),
        "banding not detected: {banded} against {fine}"
    );
}

#[test]
fn six_samples_of_the_volume_stand_in_for_the_orientation_volume() {
    // Where the device has no room for the orientation volume (`fit_to_device`), the view
    // takes the layers' orientation from six samples of the volume: differences of blended
    // values instead of blended differences, the same reach. The side-lit slab reads as
    // bright and as even either way, and the textures hold 8 bytes per voxel less.
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    for (sigma, tilt) in [(1.5, 10.0), (2.0, 25.0)] {
        let mut p = slab_scene(sigma, tilt, 1.0);
        p.scene.light = Light {
            polar_deg: 30.0,
            azimuth_deg: 0.0,
            ..p.scene.light
        };
        let with = gpu.render(&p, &RenderRequest::new(SIZE, SIZE));
        let voxels = p.volume.dims.iter().product::<usize>() as u64;
        // Room for everything but the orientation volume.
        let bytes = 2 * voxels;
        assert_eq!(p.fit_to_device(1024, bytes + 8 * voxels - 1, false).unwrap(), None);
        assert!(!p.orientation_volume && p.features().sampled_layers);
        let without = gpu.render(&p, &RenderRequest::new(SIZE, SIZE));
        assert!(without.stats.features.describe().contains("sampled-layers"));
        // Less by the orientation volume but its one texel left, which an allocation rounds
        // up (256 bytes on lavapipe; 64 KiB bounds what drivers align images to).
        let saved = with.stats.texture_bytes - without.stats.texture_bytes;
        assert!(
            saved <= 8 * voxels && saved + 65536 >= 8 * voxels,
            "{saved} of {}",
            8 * voxels
        );
        let (a, b) = (profile(&with.image), profile(&without.image));
        report.push(format!(
            "σ {sigma} at {tilt}°: mean {:.4} / {:.4}, unevenness {:.4} / {:.4} (volume / samples)",
            mean(&a),
            mean(&b),
            unevenness(&a),
            unevenness(&b)
        ));
        // 3 %: the two differ by how far the differences reach once blended (measured: the
        // samples 1.6 % and 1.4 % brighter, as the six samples along the view's axes before
        // the orientation volume, `docs/accuracy.md`; their rows 0.038 and 0.018 uneven).
        assert!((mean(&b) / mean(&a) - 1.0).abs() <= 0.03, "{report:#?}");
        // 5 %: the bound of `a_side_lit_slab_is_evenly_bright_…`.
        assert!(unevenness(&b) <= 0.05, "{report:#?}");
    }
    eprintln!("{report:#?}");
}
