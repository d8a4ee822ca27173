//! The light transport against exact traces and analytic optics: a glass ball lens behind its
//! focus, a cylinder lens's focal line, Snell's law at a volume filled with glass to its edge
//! (light and view rays), soft light as a cone source, and occluders outside the frame.
//!
//! The exact light is `reference::plane_light`: rays traced through the same voxelised index
//! field (RK4) and binned as irradiance on the GPU's own texels, independent of the renderer.

mod common;

use caustica::bench::light::{ball_lens, ball_scene, graded_ball, BALL_EDGE_VOXELS};
use caustica::reference::measure::{self, Region, ScalarImage};
use caustica::reference::plane_light::{self, nearest_sweep_plane, PlaneSettings};
use caustica::render::{safeguards, DebugView, PreparedScene, RenderRequest};
use caustica::scene::{Gradient, LightTransport, Scene, ViewSetup};
use caustica::transfer::{ColorRamp, Curve, TransferFunctions};
use caustica::volume::Volume;
use common::*;
use glam::{DVec2, Vec3};

/// Ball radius in voxels; the frame spans 4 R on `SIZE` texels, so a texel is one voxel.
const R: f64 = 16.0;
const SIZE: u32 = 64;
/// Receiver planes behind the ball's centre, in R.
const DEPTHS: [f64; 5] = [1.1, 1.25, 1.5, 2.0, 3.0];

fn centre() -> DVec2 {
    DVec2::splat((SIZE as f64 - 1.0) / 2.0)
}

/// The light arriving at relative depth `depth` (green channel).
fn light(gpu: &mut Gpu, p: &PreparedScene, size: u32, depth: f32) -> ScalarImage {
    ScalarImage::from_image(&gpu.debug(p, size, DebugView::Light, depth).image, 1)
}

/// View depth of a world point.
fn view_z(view: &ViewSetup, world: Vec3) -> f64 {
    view.view_from_world.transform_point3(world).z as f64
}

/// Every sweep plane from the one nearest `from` R behind the lens's centre to the one nearest
/// `to` R: (the relative depth that selects it, its view depth).
fn sweep_planes(lens: &Lens, from: f64, to: f64) -> Vec<(f32, f64)> {
    let first = nearest_sweep_plane(&lens.view, lens.centre_z + from * R).0;
    let last = nearest_sweep_plane(&lens.view, lens.centre_z + to * R).0;
    (first..=last)
        .map(|k| {
            let (_, depth, z) = nearest_sweep_plane(&lens.view, lens.view.plane_z(k) as f64);
            (depth, z)
        })
        .collect()
}

/// Index of the largest value (the first of equals).
fn argmax(v: &[f64]) -> usize {
    (0..v.len())
        .max_by(|&a, &b| v[a].total_cmp(&v[b]).then(b.cmp(&a)))
        .unwrap_or(0)
}

struct Lens {
    p: PreparedScene,
    view: ViewSetup,
    /// View depth of the lens's centre.
    centre_z: f64,
}

fn ball() -> Lens {
    let (volume, tf, centre_world) = ball_lens(R).expect("ball volume");
    let scene = ball_scene(&volume, &tf, R);
    lens(scene, volume, tf, centre_world)
}

fn lens(scene: Scene, volume: Volume, tf: TransferFunctions, centre_world: f64) -> Lens {
    let view = ViewSetup::new(&scene, volume.dims, volume.spacing, SIZE, SIZE).expect("view");
    let centre_z = view_z(&view, Vec3::new(0.0, 0.0, centre_world as f32));
    Lens {
        p: prepared(scene, volume, tf),
        view,
        centre_z,
    }
}

#[test]
fn ball_lens_light_matches_the_exact_trace_through_and_behind_the_focus() {
    let mut gpu = Gpu::new();
    let lens = ball();
    let planes: Vec<(u32, f32, f64)> = DEPTHS
        .iter()
        .map(|m| nearest_sweep_plane(&lens.view, lens.centre_z + m * R))
        .collect();
    let zs: Vec<f64> = planes.iter().map(|p| p.2).collect();
    let exact = plane_light::trace_scene(&lens.p, SIZE, SIZE, &zs, &PlaneSettings::default()).expect("exact trace");
    let r = R; // texels
    let mut report = Vec::new();
    for (i, &(_, depth, z)) in planes.iter().enumerate() {
        let gpu_light = light(&mut gpu, &lens.p, SIZE, depth);
        let truth = exact.planes[i].channel(1);
        let region = Region::square(&truth, centre(), 1.5 * r);
        let l1 = measure::relative_l1(&gpu_light, &truth, region).expect("light on the plane");
        let inside = measure::power_inside(&gpu_light, centre(), r) / measure::power_inside(&truth, centre(), r);
        let total = measure::total(&gpu_light, Region::all(&gpu_light)) / measure::total(&truth, Region::all(&truth));
        let sectors = (
            measure::sector_variation(&gpu_light, centre(), 0.25 * r, 0.75 * r, 16),
            measure::sector_variation(&truth, centre(), 0.25 * r, 0.75 * r, 16),
        );
        let at = (z - lens.centre_z) / R;
        // Measured on lavapipe, one beam per texel, Δs = 1: L1 0.08–0.18 (the paper's backward
        // scheme 0.5–1.9 at these planes), power inside R 0.94–1.04, total power within 2.2%,
        // the sector variation (`measure::sector_variation`, 16 sectors of the annulus
        // R/4..3R/4) of the exact light 0.009–0.136 (the voxelised sphere's facets, largest
        // near the focus), of the GPU's 0.026–0.112 (0.026–0.047 from 1.5 R on). The residual is
        // sampling: the exact trace itself, run with one ray per texel edge as the beams are,
        // is 0.11–0.22 from its converged result on these planes (`bench --light
        // --convergence`). Bounds: L1 0.2; power inside R within 7%; total within 3% (a
        // transport that loses or gains light behind a focus, as the paper's does by
        // 1.4–9.8×, fails all three); past 1.5 R, where the light spreads again, no more
        // angular structure than the exact light's + 0.06 (the backward scheme's square star
        // reads 0.5–1.0 in `bench --light`).
        assert!(l1 < 0.2, "L1 {l1} at {at:.2} R");
        assert!((inside - 1.0).abs() < 0.07, "power inside R: {inside} at {at:.2} R");
        assert!((total - 1.0).abs() < 0.03, "total power: {total} at {at:.2} R");
        if DEPTHS[i] >= 1.5 {
            assert!(
                sectors.0 < sectors.1 + 0.06,
                "angular structure {sectors:?} at {at:.2} R"
            );
        }
        report.push(format!(
            "{:.2} R: L1 {l1:.3}, power r < R {inside:.3}, total {total:.4}, sectors GPU {:.3} exact {:.3}",
            (z - lens.centre_z) / R,
            sectors.0,
            sectors.1
        ));
        // Safeguards stay safeguards: switching off the budget, the ratio clamp and the
        // saturation of the accumulators changes nothing here.
        let mut req = RenderRequest::new(SIZE, SIZE);
        req.debug_view = DebugView::Light;
        req.debug_depth = depth;
        req.safeguards_off =
            safeguards::CONCENTRATION | safeguards::INTENSITY_RATIO | safeguards::SATURATION | safeguards::FOLD;
        let unguarded = ScalarImage::from_image(&gpu.render(&lens.p, &req).image, 1);
        assert_eq!(
            unguarded.data, gpu_light.data,
            "a safeguard acted at {:.2} R",
            DEPTHS[i]
        );
    }
    eprintln!("ball lens against the exact trace:\n  {}", report.join("\n  "));
}

#[test]
fn ball_lens_light_converges_to_the_continuous_ball_at_fine_steps_and_beams() {
    // The caustics checks at Δs = ¼, 2² beams per texel and the fourth-order gradient, against
    // the exact trace of the continuous ball the volume samples (`graded_ball`: the analytic
    // index ramp, RK4 ¼ voxel, 8² rays per texel), so that voxelising the lens counts as the
    // renderer's error.
    let mut gpu = Gpu::new();
    let (volume, tf, centre_world) = ball_lens(R).expect("ball volume");
    let mut scene = ball_scene(&volume, &tf, R);
    scene.quality.sample_distance = 0.25;
    scene.quality.beams_per_texel = 2.0;
    scene.quality.gradient = Gradient::FourthOrder;
    let ball = graded_ball(&volume, R, centre_world);
    let lens = lens(scene, volume, tf, centre_world);
    let planes: Vec<(u32, f32, f64)> = DEPTHS
        .iter()
        .map(|m| nearest_sweep_plane(&lens.view, lens.centre_z + m * R))
        .collect();
    let zs: Vec<f64> = planes.iter().map(|p| p.2).collect();
    let settings = PlaneSettings {
        rays_per_texel: 8,
        ..PlaneSettings::default()
    };
    let exact = plane_light::trace_scene_through(&lens.p, &ball, SIZE, SIZE, &zs, &settings).expect("exact trace");
    let voxels = plane_light::trace_scene(&lens.p, SIZE, SIZE, &zs, &settings).expect("voxel trace");
    let mut report = Vec::new();
    for (i, &(_, depth, z)) in planes.iter().enumerate() {
        let gpu_light = light(&mut gpu, &lens.p, SIZE, depth);
        let truth = exact.planes[i].channel(1);
        let voxel_light = voxels.planes[i].channel(1);
        let l1 = measure::relative_l1(&gpu_light, &truth, Region::square(&truth, centre(), 1.5 * R)).expect("light");
        let inside = measure::power_inside(&gpu_light, centre(), R) / measure::power_inside(&truth, centre(), R);
        let all = |img: &ScalarImage| measure::total(img, Region::all(img));
        let total = all(&gpu_light) / all(&voxel_light);
        let sectors = measure::sector_variation(&gpu_light, centre(), 0.25 * R, 0.75 * R, 16);
        let voxel_sectors = measure::sector_variation(&voxel_light, centre(), 0.25 * R, 0.75 * R, 16);
        let at = (z - lens.centre_z) / R;
        report.push(format!(
            "{at:.2} R: L1 {l1:.3}, power r < R {inside:.3}, total (vs voxels) {total:.4}, total (vs ball) {:.4}, sectors {sectors:.3} (exact {:.3}, voxels' exact {voxel_sectors:.3})",
            all(&gpu_light) / all(&truth),
            measure::sector_variation(&truth, centre(), 0.25 * R, 0.75 * R, 16)
        ));
        // Measured on lavapipe: L1 0.048–0.091 (0.058–0.088 with central differences; at the
        // defaults, Δs = 1 and one beam per texel, 0.09–0.17; the voxelised ball's own exact
        // trace is 0.08–0.16 from the continuous one), power inside R 0.990–1.028. Bounds: the
        // issue's, 0.10 and 3%.
        assert!(l1 <= 0.10, "L1 {l1} at {at:.2} R");
        assert!((inside - 1.0).abs() <= 0.03, "power inside R: {inside} at {at:.2} R");
        // Conservation on the field the GPU is given: the voxelised ball sends 0.6–1.5% of the
        // light out of the frame past the rim where the continuous one does not, so the total
        // is compared with the voxels' exact trace. Measured 0.993–1.009; bound 1%.
        assert!((total - 1.0).abs() <= 0.01, "total power: {total} at {at:.2} R");
        // Round behind the focus: the sectors of the annulus R/4–3R/4 within 5% (measured
        // 0.002, 0.000 and 0.009 at 1.5, 2 and 3 R; the exact light's 0.001, 0.010 and 0.000;
        // with central differences 0.060 at 1.5 R, whose error has the lattice's four-fold
        // pattern). At 1.1 and 1.25 R, near the focus, the voxelised ball's own exact trace
        // reads 0.14–0.32 (the GPU 0.037 and 0.073; 0.15 and 0.09 while beams changed pyramid
        // level with the rounding of their footprints): the lattice's star is in the voxels
        // there, so the bound is the larger of 5% and what the exact trace of the same voxels
        // shows (`ball_lens_light_is_round_…` checks 5% at Δs = 1 with 2² beams).
        if DEPTHS[i] >= 1.5 {
            assert!(sectors <= 0.05, "angular structure {sectors} at {at:.2} R");
        } else {
            assert!(
                sectors <= voxel_sectors.max(0.05),
                "angular structure {sectors} at {at:.2} R, more than the voxels' exact {voxel_sectors}"
            );
        }
    }
    eprintln!(
        "ball lens (Δs ¼, 2² beams) against the continuous ball:\n  {}",
        report.join("\n  ")
    );
    // In front of the ball the light is unobstructed: 1 on every texel, so the frame holds
    // its area exactly (measured 1.0000 to f32 rounding; at Δs = 1 a deposit box wider than
    // the beams' half-pixel cells spilled the grid's edge beams past its region: 0.9927).
    let mut scene = lens.p.scene.clone();
    scene.quality.sample_distance = 1.0;
    let coarse = self::lens(scene, (*lens.p.volume).clone(), lens.p.tf.clone(), centre_world);
    let front = nearest_sweep_plane(&coarse.view, coarse.centre_z - 1.1 * R);
    let before = light(&mut gpu, &coarse.p, SIZE, front.1);
    let area = measure::total(&before, Region::all(&before)) / (SIZE * SIZE) as f64;
    assert!((area - 1.0).abs() < 1e-3, "unobstructed light over the frame: {area}");
}

#[test]
fn ball_lens_on_axis_maximum_lies_where_the_exact_trace_has_it() {
    let mut gpu = Gpu::new();
    let lens = ball();
    let planes = sweep_planes(&lens, 1.0, 2.0);
    let zs: Vec<f64> = planes.iter().map(|p| p.1).collect();
    let exact = plane_light::trace_scene(&lens.p, SIZE, SIZE, &zs, &PlaneSettings::default()).expect("exact trace");
    // The on-axis value: the four texels around the axis.
    let axis = |img: &ScalarImage| img.sample(centre());
    let gpu_axis: Vec<f64> = planes
        .iter()
        .map(|p| axis(&light(&mut gpu, &lens.p, SIZE, p.0)))
        .collect();
    let exact_axis: Vec<f64> = exact.planes.iter().map(|p| axis(&p.channel(1))).collect();
    let (g, e) = (argmax(&gpu_axis), argmax(&exact_axis));
    eprintln!(
        "on-axis maximum: GPU at {:.3} R ({:.1}), exact at {:.3} R ({:.1}); GPU {gpu_axis:.1?}, exact {exact_axis:.1?}",
        (zs[g] - lens.centre_z) / R,
        gpu_axis[g],
        (zs[e] - lens.centre_z) / R,
        exact_axis[e]
    );
    // Planes are Δs = 1 voxel = R/16 apart; measured: the same plane (1.31 R).
    assert!(g.abs_diff(e) <= 1, "on-axis maximum {g} planes vs exact {e}");
    // Not at the edges of the searched range: the focus lies between R and 2 R.
    assert!(e > 0 && e + 1 < zs.len(), "exact maximum at the range's end");
}

/// A glass cylinder (n = 1.5, radius `R`, axis along y, the ball's surface ramp) with R + 4 voxels of air in front and room for planes 2.5 R behind its axis.
fn cylinder() -> Lens {
    let (volume, tf, _) = ball_lens(R).expect("ball volume");
    let [side, _, depth] = volume.dims;
    let rows = 16usize;
    let centre_z = -(depth as f64) / 2.0 + R + 4.0;
    let mut data = Vec::with_capacity(side * rows * depth);
    for k in 0..depth {
        for _ in 0..rows {
            for i in 0..side {
                let x = i as f64 + 0.5 - side as f64 / 2.0;
                let z = k as f64 + 0.5 - depth as f64 / 2.0 - centre_z;
                let r = (x * x + z * z).sqrt();
                data.push((0.5 * (0.5 - (r - R) / BALL_EDGE_VOXELS).clamp(0.0, 1.0)) as f32);
            }
        }
    }
    let volume = Volume::new([side, rows, depth], [1.0; 3], data).expect("cylinder volume");
    // The same framing as the ball: the frame spans 4 R horizontally.
    let mut scene = ball_scene(&volume, &tf, R);
    let extent = Vec3::new(side as f32, rows as f32, depth as f32);
    scene.camera.zoom = extent.length() / (4.0 * R as f32);
    lens(scene, volume, tf, centre_z)
}

#[test]
fn cylinder_lens_focal_line_lies_where_the_exact_trace_has_it() {
    let mut gpu = Gpu::new();
    let lens = cylinder();
    let zs = sweep_planes(&lens, 1.0, 2.5);
    let exact = plane_light::trace_scene(
        &lens.p,
        SIZE,
        SIZE,
        &zs.iter().map(|p| p.1).collect::<Vec<_>>(),
        &PlaneSettings::default(),
    )
    .expect("exact trace");
    // The light along the focal line: the mean over the middle rows at the axis column.
    let line = |img: &ScalarImage| {
        let c = centre();
        (-3..=3)
            .map(|dy| img.sample(c + DVec2::new(0.0, dy as f64)))
            .sum::<f64>()
            / 7.0
    };
    let gpu_line: Vec<f64> = zs.iter().map(|p| line(&light(&mut gpu, &lens.p, SIZE, p.0))).collect();
    let exact_line: Vec<f64> = exact.planes.iter().map(|p| line(&p.channel(1))).collect();
    let (g, e) = (argmax(&gpu_line), argmax(&exact_line));
    eprintln!(
        "cylinder focal line: GPU at {:.3} R ({:.2}), exact at {:.3} R ({:.2}); GPU {gpu_line:.2?}, exact {exact_line:.2?}",
        (zs[g].1 - lens.centre_z) / R,
        gpu_line[g],
        (zs[e].1 - lens.centre_z) / R,
        exact_line[e]
    );
    // Within one voxel (one plane at Δs = 1) of the exact trace's focal line; measured: the
    // same plane (1.31 R).
    assert!(
        (zs[g].1 - zs[e].1).abs() <= 1.0 + 1e-3,
        "focal line {} voxels from the exact one",
        zs[g].1 - zs[e].1
    );
    assert!(e > 0 && e + 1 < zs.len(), "exact maximum at the range's end");
}

/// η = 1.1 (value 0.5) filling an N³ volume to its faces, air (η = 1) around it; value 1 marks
/// an opaque rod along y, 2 × 2 voxels, at world (0, ·, `ROD_Z`).
const GLASS_N: usize = 48;
const ROD_Z: f32 = 8.0;

fn glass_block(eta: f32) -> (Volume, TransferFunctions) {
    let n = GLASS_N as f32;
    let volume = volume_from(GLASS_N, |x, _, z| {
        let (x, z) = ((x - 0.5) * n, (z - 0.5) * n - ROD_Z);
        if x.abs() < 1.0 && z.abs() < 1.0 {
            1.0
        } else {
            0.5
        }
    });
    let tf = TransferFunctions {
        name: None,
        opacity: Curve {
            points: vec![[0.0, 0.0], [0.7, 0.0], [0.8, 1.0], [1.0, 1.0]],
        },
        color: ColorRamp::constant([1.0; 3]),
        eta: Curve {
            points: vec![[0.0, 1.0], [0.5, eta], [1.0, eta]],
        },
        medium: ColorRamp::constant([1.0; 3]),
        albedo: None,
        anisotropy: None,
    };
    (volume, tf)
}

#[test]
fn glass_to_the_volume_edge_refracts_light_and_view_rays_by_snells_law() {
    let mut gpu = Gpu::new();
    let incidence = 30f64.to_radians();
    let expected = (incidence.sin() / 1.1).asin();
    // Light at 30° off the view axis from the top of the image.
    let (volume, tf) = glass_block(1.1);
    let mut scene = head_on_scene(&tf);
    scene.light.polar_deg = 30.0;
    scene.shading.specular = 0.0;
    let p = prepared(scene, volume.clone(), tf.clone());
    let out = gpu.debug(&p, 64, DebugView::LightDirection, 0.3);
    let px = out.image.pixels[32 * 64 + 20];
    let d = glam::DVec3::new(px[0] as f64, px[1] as f64, px[2] as f64) * 2.0 - glam::DVec3::ONE;
    let light_angle = (d.x * d.x + d.y * d.y).sqrt().atan2(d.z);
    // View rays: the camera turned 30° about y; the rod's image moves by
    // T·(tan θ − tan θ')·cos θ against the same block with η = 1 (T: depth of the rod below
    // the front face).
    let size = 128u32;
    // The rod's centroid in the image (pixels): black against a white background, its
    // silhouette whatever light falls on its faces (the glass refracts the light and the air
    // does not, so lit faces moved the centroid with the light grid: 1.20–1.76 voxels of shift
    // at 0.5–1.33 beams per texel). Within `WINDOW` pixels of `around` (the rod in air): the
    // glass also shows a dark line where rays graze the block's edge.
    const WINDOW: f64 = 6.0;
    let rod_u = |gpu: &mut Gpu, eta: f32, reference: bool, around: Option<f64>| {
        let (volume, mut tf) = glass_block(eta);
        tf.color = ColorRamp::constant([0.0; 3]);
        let mut scene = head_on_scene(&tf);
        scene.camera.yaw_deg = 30.0;
        scene.shading.specular = 0.0;
        scene.environment = caustica::scene::Environment::Color { color: [1.0; 3] };
        let p = prepared(scene, volume, tf);
        let img = if reference {
            caustica::reference::render(
                &p,
                size,
                size,
                &caustica::reference::ReferenceSettings::default(),
                false,
            )
            .unwrap()
        } else {
            gpu.render(&p, &RenderRequest::new(size, size)).image
        };
        let (mut sum, mut weight) = (0.0, 0.0);
        for y in size / 2 - 8..size / 2 + 8 {
            for x in 0..size {
                if around.is_some_and(|u| (x as f64 - u).abs() > WINDOW) {
                    continue;
                }
                // Darker than half the background: the rod, not the glass's slight dimming.
                let v = (0.5 - luminance(&img.pixels[(y * size + x) as usize]) as f64).max(0.0);
                sum += v * x as f64;
                weight += v;
            }
        }
        let view = ViewSetup::new(&p.scene, p.volume.dims, p.volume.spacing, size, size).expect("view");
        (sum / weight, view)
    };
    let (u_air, view) = rod_u(&mut gpu, 1.0, false, None);
    let (u_glass, _) = rod_u(&mut gpu, 1.1, false, Some(u_air));
    // The same measurement on the independent reference (RK4 view rays, photon light).
    let (ref_air, _) = rod_u(&mut gpu, 1.0, true, None);
    let (ref_glass, _) = rod_u(&mut gpu, 1.1, true, Some(ref_air));
    let texel = (view.point_at(glam::Vec2::new(1.0, 0.0), 0.0) - view.point_at(glam::Vec2::ZERO, 0.0)).length();
    let depth = ROD_Z as f64 + GLASS_N as f64 / 2.0;
    let shift = (u_glass - u_air).abs() * texel as f64;
    let angle_of = |shift: f64| (incidence.tan() - shift / (depth * incidence.cos())).atan();
    let view_angle = angle_of(shift);
    let ref_shift = (ref_glass - ref_air).abs() * texel as f64;
    let ref_angle = angle_of(ref_shift);
    eprintln!(
        "Snell 1 → 1.1 at 30°: expected {:.3}°, light {:.3}°, view {:.3}° (rod shifted {shift:.3} voxels), reference view {:.3}° ({ref_shift:.3} voxels)",
        expected.to_degrees(),
        light_angle.to_degrees(),
        view_angle.to_degrees(),
        ref_angle.to_degrees()
    );
    // Light: Snell's angle within 1% (measured: to 0.001°). An initial direction L·η (which
    // scales the tangential component Snell's law keeps) or a sweep that starts on the face
    // and misses the index step in front of its first plane refracts too little (the 1.1
    // block then acts like η ≈ 1.03: 29°).
    assert!(
        (light_angle / expected - 1.0).abs() < 0.01,
        "light at {}°",
        light_angle.to_degrees()
    );
    // View rays, from the rod's shift (1.86 voxels expected, 0 without refraction): measured
    // 1.949 voxels on the GPU and on the reference alike (0.55% from Snell's angle, 26.89°
    // against 27.04°). The rod's silhouette is 3 pixels wide (0.65 voxel each); its centroid is
    // good to about a third of a pixel, 0.2 voxel of shift or 1.3% of the angle at this depth.
    // Bound 1.5% for both; a view ray entering with the direction L·η, or missing the index
    // step in front of the first plane, is off by 5% and more.
    assert!(
        (view_angle / expected - 1.0).abs() < 0.015,
        "view rays at {}°",
        view_angle.to_degrees()
    );
    assert!(
        (ref_angle / expected - 1.0).abs() < 0.015,
        "reference view rays at {}°",
        ref_angle.to_degrees()
    );
    // The two renderers see the same silhouette (measured within 0.001°): bound a tenth of a
    // pixel of shift between them, 0.4% of the angle.
    assert!(
        (view_angle / ref_angle - 1.0).abs() < 0.004,
        "view rays at {}° against the reference's {}°",
        view_angle.to_degrees(),
        ref_angle.to_degrees()
    );
}

/// An opaque half-plane (y < 0 of the box) 4 voxels thick, its back face at world z = −16, in
/// an N³ volume; light head-on with `softness`.
const SHADOW_N: usize = 64;

fn occluder(softness: f32, ds: f32) -> (PreparedScene, ViewSetup) {
    let n = SHADOW_N as f32;
    let volume = volume_from(SHADOW_N, |_, y, z| {
        let z = (z - 0.5) * n;
        ((y < 0.5) && (-20.0..-16.0).contains(&z)) as u8 as f32
    });
    let tf = plain_tf(vec![[0.0, 0.0], [0.5, 1.0], [1.0, 1.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let mut scene = head_on_scene(&tf);
    scene.camera.zoom = (n * 3f32.sqrt()) / SHADOW_N as f32;
    scene.light.softness = softness;
    scene.quality.sample_distance = ds;
    let view = ViewSetup::new(&scene, volume.dims, volume.spacing, 64, 64).expect("view");
    (prepared(scene, volume, tf), view)
}

#[test]
fn soft_shadow_edges_widen_like_a_cone_whatever_the_plane_distance() {
    let mut gpu = Gpu::new();
    let softness = 0.2;
    let distances = [8.0, 16.0, 24.0, 32.0];
    let mut widths = Vec::new();
    let mut exact_widths = Vec::new();
    for ds in [1.0f32, 0.25] {
        let (p, view) = occluder(softness, ds);
        let row: Vec<f64> = distances
            .iter()
            .map(|d| {
                let z = view_z(&view, Vec3::new(0.0, 0.0, -16.0 + *d as f32));
                let (_, depth, _) = nearest_sweep_plane(&view, z);
                let img = light(&mut gpu, &p, 64, depth);
                measure::edge_width(&img, DVec2::new(31.5, 8.0), DVec2::new(31.5, 56.0), 193).unwrap_or(f64::NAN)
            })
            .collect();
        widths.push(row);
        if exact_widths.is_empty() {
            let zs: Vec<f64> = distances
                .iter()
                .map(|d| nearest_sweep_plane(&view, view_z(&view, Vec3::new(0.0, 0.0, -16.0 + *d as f32))).2)
                .collect();
            let exact = plane_light::trace_scene(&p, 64, 64, &zs, &PlaneSettings::default()).expect("exact trace");
            exact_widths = exact
                .planes
                .iter()
                .map(|pl| {
                    measure::edge_width(&pl.channel(1), DVec2::new(31.5, 8.0), DVec2::new(31.5, 56.0), 193)
                        .unwrap_or(f64::NAN)
                })
                .collect();
        }
    }
    eprintln!(
        "soft shadow 10–90% widths (texels) at {distances:?} behind the edge: Δs = 1 {:.2?}, Δs = 0.25 {:.2?}, exact cone {exact_widths:.2?}",
        widths[0], widths[1]
    );
    // The same cone whatever the plane distance: within 10% at every distance (measured 6%).
    for (a, b) in widths[0].iter().zip(&widths[1]) {
        assert!((a / b - 1.0).abs() < 0.1, "widths {a} vs {b} at Δs 1 and 0.25");
    }
    // Growing linearly with the distance: a straight line fits each row to half a texel
    // (measured 0.17), and its slope is the cone's (the exact trace's) within 20%; an
    // incremental blur of radius softness·Δs per plane would grow as √D and fail both.
    let fit = |w: &[f64]| {
        let n = w.len() as f64;
        let mx = distances.iter().sum::<f64>() / n;
        let my = w.iter().sum::<f64>() / n;
        let sxy: f64 = distances.iter().zip(w).map(|(x, y)| (x - mx) * (y - my)).sum();
        let sxx: f64 = distances.iter().map(|x| (x - mx) * (x - mx)).sum();
        let slope = sxy / sxx;
        let worst = distances
            .iter()
            .zip(w)
            .map(|(x, y)| (y - (my + slope * (x - mx))).abs())
            .fold(0.0, f64::max);
        (slope, worst)
    };
    let (exact_slope, _) = fit(&exact_widths);
    for row in &widths {
        let (slope, worst) = fit(row);
        assert!(worst < 0.5, "widths {row:?} off a straight line by {worst}");
        assert!(
            (slope / exact_slope - 1.0).abs() < 0.2,
            "slope {slope} vs the exact cone's {exact_slope}"
        );
    }
}

#[test]
fn occluders_outside_the_frame_shadow_what_is_inside_it() {
    let mut gpu = Gpu::new();
    let n = 64usize;
    // An opaque ball of radius 6 at world (20, 0, −16), outside a frame zoomed to ±16 voxels.
    let volume = volume_from(n, |x, y, z| {
        let p = glam::Vec3::new(x - 0.5, y - 0.5, z - 0.5) * n as f32 - glam::Vec3::new(20.0, 0.0, -16.0);
        (p.length() < 6.0) as u8 as f32
    });
    let tf = plain_tf(vec![[0.0, 0.0], [0.5, 1.0], [1.0, 1.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    let mut scene = head_on_scene(&tf);
    // The frame spans 2·radius/zoom = 32 voxels.
    scene.camera.zoom = (n as f32 * 3f32.sqrt()) / 32.0;
    // Light from the right at 40°: the shadow moves left by tan 40° per voxel of depth.
    scene.light.polar_deg = 40.0;
    scene.light.azimuth_deg = 90.0;
    let view = ViewSetup::new(&scene, volume.dims, volume.spacing, SIZE, SIZE).expect("view");
    let p = prepared(scene, volume, tf);
    let z = view_z(&view, Vec3::new(0.0, 0.0, 8.0));
    let (_, depth, z_plane) = nearest_sweep_plane(&view, z);
    let exact = plane_light::trace_scene(&p, SIZE, SIZE, &[z_plane], &PlaneSettings::default()).expect("exact trace");
    let truth = exact.planes[0].channel(1);
    let gpu_light = light(&mut gpu, &p, SIZE, depth);
    let l1 = measure::relative_l1(&gpu_light, &truth, Region::all(&truth)).expect("light");
    let total = measure::total(&gpu_light, Region::all(&gpu_light)) / measure::total(&truth, Region::all(&truth));
    let darkest = |img: &ScalarImage| img.data.iter().cloned().fold(f64::INFINITY, f64::min);
    eprintln!(
        "shadow from outside the frame: L1 {l1:.3}, total {total:.4}, darkest GPU {:.3} exact {:.3}",
        darkest(&gpu_light),
        darkest(&truth)
    );
    // The shadow is there (the exact light is 0 in its core) and in the right place: L1 within
    // 0.05 (measured 0.005); light entering the frame unobstructed would leave the core lit.
    assert!(darkest(&gpu_light) < 0.05, "no shadow inside the frame");
    assert!(l1 < 0.05, "L1 {l1}");
}

/// η from 1 to 1.5 across z = 0 of an N³ volume (smoothed over 4 voxels), nothing absorbs.
fn oblique_interface() -> (Volume, TransferFunctions) {
    let n = GLASS_N as f32;
    let volume = volume_from(GLASS_N, |_, _, z| {
        let t = (((z - 0.5) * n + 2.0) / 4.0).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t)
    });
    let mut tf = plain_tf(vec![[0.0, 0.0]], vec![[0.0, 1.0, 1.0, 1.0]]);
    tf.eta = Curve {
        points: vec![[0.0, 1.0], [1.0, 1.5]],
    };
    (volume, tf)
}

#[test]
fn light_crossing_an_oblique_interface_keeps_its_irradiance_on_the_planes() {
    // Parallel light at 30° through a plane interface parallel to the planes, nothing
    // absorbing: the power crossing each plane per unit area stays the same (Fresnel
    // reflection is not modelled in the light). The backward scheme's intensity law tracks
    // areas on the planes for the direction the light had; where the direction bends at a
    // plane, its cos term carries the change of the beam's cross-section (without it the
    // light behind the interface reads cos 30° / cos 19.47° = 1.089).
    let mut gpu = Gpu::new();
    let (volume, tf) = oblique_interface();
    for transport in [LightTransport::Beams, LightTransport::Backward] {
        let mut scene = head_on_scene(&tf);
        // A frame of 32 voxels inside the 48-voxel box: no light from its side faces.
        scene.camera.zoom = (GLASS_N as f32 * 3f32.sqrt()) / 32.0;
        scene.quality.precision = caustica::scene::Precision::F32;
        scene.quality.light_transport = transport;
        scene.light.polar_deg = 30.0;
        let p = prepared(scene, volume.clone(), tf.clone());
        let mean = |gpu: &mut Gpu, depth: f32| {
            let img = light(gpu, &p, 64, depth);
            // The central 32 × 32 texels.
            (16..48)
                .flat_map(|y| (16..48).map(move |x| (x, y)))
                .map(|(x, y)| img.at(x, y))
                .sum::<f64>()
                / 1024.0
        };
        let (front, behind) = (mean(&mut gpu, 0.3), mean(&mut gpu, 0.75));
        eprintln!("{transport:?}: light in front {front:.4}, behind {behind:.4}");
        // Measured: 1.0000 on both sides, both transports. Bound 1% (the missing cos term is
        // 8.9%).
        assert!((behind / front - 1.0).abs() < 0.01, "{transport:?}: {front} → {behind}");
        assert!((front - 1.0).abs() < 0.01, "{transport:?}: unobstructed light {front}");
    }
}

/// The cylinder lens with the paper's backward transport, light at `polar_deg` across its
/// axis, soft light of `softness`.
fn backward_cylinder(polar_deg: f32, softness: f32) -> Lens {
    let mut lens = cylinder();
    let scene = &mut lens.p.scene;
    scene.quality.light_transport = LightTransport::Backward;
    scene.light.polar_deg = polar_deg;
    scene.light.azimuth_deg = 90.0;
    scene.light.softness = softness;
    lens.view = ViewSetup::new(scene, lens.p.volume.dims, lens.p.volume.spacing, SIZE, SIZE).expect("view");
    lens
}

/// Relative L1 of the light against the exact trace (a cone source where the light is soft) on
/// every sweep plane from `from` to `to` R behind the lens's axis: (distance in R, L1).
fn light_l1_on_planes(gpu: &mut Gpu, lens: &Lens, from: f64, to: f64) -> Vec<(f64, f64)> {
    let planes = sweep_planes(lens, from, to);
    let zs: Vec<f64> = planes.iter().map(|p| p.1).collect();
    let exact = plane_light::trace_scene(&lens.p, SIZE, SIZE, &zs, &PlaneSettings::default()).expect("exact trace");
    planes
        .iter()
        .zip(&exact.planes)
        .map(|(p, e)| {
            let truth = e.channel(1);
            let gpu_light = light(gpu, &lens.p, SIZE, p.0);
            let l1 = measure::relative_l1(&gpu_light, &truth, Region::all(&truth)).expect("light");
            ((p.1 - lens.centre_z) / R, l1)
        })
        .collect()
}

#[test]
fn backward_light_entering_a_lens_obliquely_follows_the_direction_at_its_foot_point() {
    // Light at 30° across the cylinder's axis, the backward scheme: where the light crosses the
    // front surface, neighbouring cells hold directions that differ by the refraction there,
    // and a cell's ray left the previous plane Δs·tan 30° away from it. Tracing it back along
    // the direction stored at the cell itself (first order, Algorithm 1 line 8) bends it where
    // it has not yet been bent, and the light inside the glass drifts off the exact trace.
    let mut gpu = Gpu::new();
    let lens = backward_cylinder(30.0, 0.0);
    // Planes in the glass between 0.5 R and 0.375 R before the axis: behind the front surface,
    // before rays cross (at and behind a focus the backward scheme fails whatever its lookup).
    let rows = light_l1_on_planes(&mut gpu, &lens, -0.5, -0.375);
    eprintln!("light in the glass, backward, 30°: (R, L1) {rows:.3?}");
    // Measured 0.081 / 0.114 / 0.160; with the cell's own direction 0.130 / 0.209 / 0.337.
    // Bound 0.2: the scheme's remaining error here (bilinear resampling of the refracted
    // light, the voxelised surface) grows from 0.08 to 0.16 over these planes.
    assert!(rows.len() >= 2, "planes {rows:?}");
    for (r, l1) in rows {
        assert!(l1 <= 0.2, "L1 {l1} at {r:.2} R");
    }
}

#[test]
fn backward_soft_light_through_a_lens_keeps_its_focal_length() {
    // Soft light (a cone of 0.25) head-on through the cylinder lens, the backward scheme: the
    // soft-light filter averages the directions of cells up to a few voxels apart, which in the
    // converging light inside the glass differ by tenths of a radian. A plain average is
    // shorter than η; Snell's law at the back surface keeps its (short) tangential part, the
    // light leaves bent too much and focuses early. Averaged directions take the mean length
    // of those averaged.
    let mut gpu = Gpu::new();
    let lens = backward_cylinder(0.0, 0.25);
    // The exact trace's focus lies at 1.1 R; the planes from 0.5 to 0.9 R behind the axis lead
    // up to it.
    let rows = light_l1_on_planes(&mut gpu, &lens, 0.5, 0.9);
    eprintln!("soft light behind the lens, backward: (R, L1) {rows:.3?}");
    // Measured 0.144–0.191; with plain averages 0.157–0.459 (the light peaks at 0.88 R). Bound
    // 0.25: the scheme's error on these planes grows towards the focus (0.19 at 0.9 R, 0.24 at
    // 1.06 R).
    assert!(rows.len() >= 5, "planes {rows:?}");
    for (r, l1) in rows {
        assert!(l1 <= 0.25, "L1 {l1} at {r:.2} R");
    }
}

#[test]
fn light_views_show_the_unobstructed_light_across_the_whole_frame() {
    // A refracting scene whose box covers the middle of the frame, the light view on a plane
    // near the front, where nothing lies between the source and the plane: the light is the
    // source's everywhere in the frame. Beyond the box's footprint the view once read black
    // (the refracted beams deposit only within the rect that view rays can meet); beams whose
    // footprint came out a rounding wider than a texel deposited on the next level, which
    // showed as lines of light 5–40 % short across the frame (orthographic, light at 75°); and
    // the frame's edge pixels read a quarter short (the taps beyond the rect read nothing).
    let mut gpu = Gpu::new();
    let mut report = Vec::new();
    for (projection, polar, azimuth) in [
        (caustica::scene::Projection::Perspective, 40.0, 30.0),
        (caustica::scene::Projection::Orthographic, 75.0, 120.0),
    ] {
        let mut scene = caustica::scene::builtin("ball-lens").expect("ball-lens").scene;
        scene.set_builtin_resolution(32);
        scene.camera.distance = 5.0;
        scene.camera.pitch_deg = 20.0;
        scene.camera.projection = projection;
        scene.camera.zoom = 0.5;
        scene.light.polar_deg = polar;
        scene.light.azimuth_deg = azimuth;
        scene.light.softness = 0.0;
        let p = PreparedScene::load(&scene).expect("scene");
        let img = light(&mut gpu, &p, 96, 0.02);
        let (lo, hi) = img
            .data
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            });
        report.push(format!("{projection:?}, light at {polar}°: light {lo:.4}–{hi:.4}"));
        // 1 %: the deposits' fixed-point rounding (dithered, below 1e-4 per beam) and the
        // beams' power at f16 (2^-11) on a plane that nothing has dimmed (measured 1.0000 to
        // four places in both; 0.0 beyond the footprint with the rect the view rays need, and
        // 0.42–1.53 in the orthographic view with beams on two levels).
        assert!(lo > 0.99 && hi < 1.01, "{report:?}");
    }
    eprintln!("{report:#?}");
}

#[test]
fn ball_lens_light_is_round_through_and_behind_the_focus() {
    // The light of the ball lens at 2² beams per texel, Δs = 1: no star and no grid, near the
    // focus as behind it. A star pattern near the focus had two sources: the lattice's
    // central differences, and beams whose footprint came out a rounding wider than a texel,
    // which deposited on the next pyramid level in rows and columns (before: 0.109 and 0.084 at
    // 1.1 and 1.25 R in `bench --light`).
    let mut gpu = Gpu::new();
    let (volume, tf, centre_world) = ball_lens(R).expect("ball volume");
    let mut scene = ball_scene(&volume, &tf, R);
    scene.quality.beams_per_texel = 2.0;
    let lens = lens(scene, volume, tf, centre_world);
    let mut report = Vec::new();
    for m in DEPTHS {
        let (_, depth, z) = nearest_sweep_plane(&lens.view, lens.centre_z + m * R);
        let gpu_light = light(&mut gpu, &lens.p, SIZE, depth);
        let sectors = measure::sector_variation(&gpu_light, centre(), 0.25 * R, 0.75 * R, 16);
        report.push(((z - lens.centre_z) / R, sectors));
    }
    eprintln!("ball lens, 2² beams per texel, Δs 1: (R, sectors) {report:.3?}");
    // 5 %: the bound on the azimuthal variation at fixed radius (16 sectors of the
    // annulus R/4–3R/4; rings cancel, a star does not). Measured 0.044, 0.042, 0.011, 0.025,
    // 0.000 at 1.1, 1.25, 1.5, 2 and 3 R; 0.083, 0.094, 0.020, 0.029, 0.019 with the rounding's
    // level changes.
    for (at, sectors) in report {
        assert!(sectors <= 0.05, "angular structure {sectors} at {at:.2} R");
    }
}

#[test]
fn refracted_beams_finer_than_half_a_voxel_are_not_traced_and_the_light_stays_as_close_to_the_exact_trace() {
    // A ball of R = 8 voxels seen at four texels per voxel: the refracted beams are capped per
    // voxel (`VoxelCap::REFRACTED`: 1.5 per voxel and axis, but no coarser than half what is
    // asked), half a beam per texel, a quarter of the cells that 2² beams per texel give here
    // (a beam per texel). Both against the exact trace of the continuous ball on the same texels
    // (`graded_ball`, 8² rays per texel: a trace of the voxels with a ray per texel is itself
    // 0.1–0.2 off at four texels per voxel), through and behind the focus.
    let mut gpu = Gpu::new();
    let r = 8.0;
    let size = 128u32;
    let (volume, tf, centre_world) = ball_lens(r).expect("ball volume");
    let scene = ball_scene(&volume, &tf, r);
    let texels_per_voxel = size as f64 / (4.0 * r);
    let view = ViewSetup::new(&scene, volume.dims, volume.spacing, size, size).expect("view");
    let centre_z = view_z(&view, Vec3::new(0.0, 0.0, centre_world as f32));
    let mut fine_scene = scene.clone();
    fine_scene.quality.beams_per_texel = 2.0;
    let ball = graded_ball(&volume, r, centre_world);
    let capped = prepared(scene, volume.clone(), tf.clone());
    let fine = prepared(fine_scene, volume, tf);
    let planes: Vec<(u32, f32, f64)> = [1.25, 1.5, 2.0, 3.0]
        .iter()
        .map(|m| nearest_sweep_plane(&view, centre_z + m * r))
        .collect();
    let zs: Vec<f64> = planes.iter().map(|p| p.2).collect();
    let settings = PlaneSettings {
        rays_per_texel: 8,
        ..PlaneSettings::default()
    };
    let exact = plane_light::trace_scene_through(&capped, &ball, size, size, &zs, &settings).expect("exact trace");
    let c = DVec2::splat((size as f64 - 1.0) / 2.0);
    let radius = r * texels_per_voxel; // texels
    let mut report = Vec::new();
    for (i, &(_, depth, z)) in planes.iter().enumerate() {
        let truth = exact.planes[i].channel(1);
        let region = Region::square(&truth, c, 1.5 * radius);
        let mut measured = Vec::new();
        for p in [&capped, &fine] {
            let out = gpu.debug(p, size, DebugView::Light, depth);
            let cells = out.stats.light_grid[0] as f64 * out.stats.light_grid[1] as f64;
            let l = ScalarImage::from_image(&out.image, 1);
            let l1 = measure::relative_l1(&l, &truth, region).expect("light on the plane");
            measured.push((cells, l1, measure::total(&l, Region::all(&l))));
        }
        let at = (z - centre_z) / r;
        report.push(format!(
            "{at:.2} R: (cells, L1, total) capped {:.3?}, a beam per texel {:.3?}",
            measured[0], measured[1]
        ));
        let ((cells, l1, total), (fine_cells, fine_l1, fine_total)) = (measured[0], measured[1]);
        let total = total / fine_total;
        // The grids cover the same region: a quarter of the cells, within a row and a column
        // of the coarser grid's rounding.
        assert!(cells < 0.3 * fine_cells, "cells {cells} against {fine_cells}");
        // Bound: no more than 0.02 above the finer grid's L1 (the margin between the caustics
        // checks' 0.10 and the default's 0.08 at a texel per voxel), and the same power on the
        // plane within the 1 % of the caustics checks (both grids conserve it).
        assert!(
            l1 <= fine_l1 + 0.02,
            "L1 {l1} against {fine_l1} with a beam per texel at {at:.2} R"
        );
        assert!(
            (total - 1.0).abs() <= 0.01,
            "total power {total} of the finer grid's at {at:.2} R"
        );
    }
    eprintln!("ball lens, R = 8 at four texels per voxel:\n  {}", report.join("\n  "));
}
