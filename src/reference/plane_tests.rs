//! The plane trace against exact answers without refraction: unobstructed light, shadows
//! from outside the frame, a partial shadow, soft shadow edges; the plane a GPU depth selects.
//! Shared helpers for the other plane-trace tests.

use glam::{DMat4, DVec2, DVec3};

use super::measure;
use super::medium::{Medium, Optics, VolumeMedium};
use super::photons::DistantLight;
use super::plane_light::{self, PlaneLight, PlaneSettings, PlaneView};
use crate::scene::{builtin, Projection};
use crate::scene::{light_direction, ViewSetup};
use crate::transfer::{ColorRamp, Curve, TransferFunctions};
use crate::volume::Volume;

/// A view whose space is world space (camera axes = world axes), looking along +z at the
/// z axis, `width`×`height` texels of `texel` world units (orthographic).
pub(super) fn axis_view(width: u32, height: u32, texel: f64) -> PlaneView {
    axis_view_at(width, height, texel, DVec2::ZERO)
}

/// As [`axis_view`], with the frame centred on (`centre`, z) instead of the axis.
pub(super) fn axis_view_at(width: u32, height: u32, texel: f64, centre: DVec2) -> PlaneView {
    PlaneView {
        world_from_view: DMat4::IDENTITY,
        projection: [
            1.0 / texel,
            1.0 / texel,
            width as f64 / 2.0 - centre.x / texel,
            height as f64 / 2.0 - centre.y / texel,
        ],
        orthographic: true,
        width,
        height,
    }
}

pub(super) fn light(direction: DVec3, softness: f64) -> DistantLight {
    DistantLight {
        direction: direction.normalize(),
        color: [1.0; 3],
        softness,
    }
}

/// A volume of `dims` unit voxels from a function of the voxel centre in world space (the box
/// centred on the origin).
pub(super) fn volume(dims: [usize; 3], f: impl Fn(DVec3) -> f64) -> Volume {
    let mut data = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    let half = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * 0.5;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = DVec3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) - half;
                data.push(f(p) as f32);
            }
        }
    }
    Volume::new(dims, [1.0; 3], data).unwrap()
}

/// Clear transfer functions with η(value) given by `eta` and opacity by `opacity`.
pub(super) fn tf(eta: Vec<[f32; 2]>, opacity: Vec<[f32; 2]>) -> TransferFunctions {
    TransferFunctions {
        name: None,
        opacity: Curve { points: opacity },
        color: ColorRamp::constant([1.0; 3]),
        eta: Curve { points: eta },
        medium: ColorRamp::constant([1.0; 3]),
        albedo: None,
        anisotropy: None,
    }
}

pub(super) fn settings(rays_per_texel: u32, step_voxels: f64) -> PlaneSettings {
    PlaneSettings {
        rays_per_texel,
        step_voxels,
        ..PlaneSettings::default()
    }
}

/// Largest |texel − 1| over all planes and channels.
fn worst_from_one(l: &PlaneLight) -> f64 {
    l.planes
        .iter()
        .flat_map(|p| p.texels.iter().flatten())
        .fold(0.0f64, |m, v| m.max((v - 1.0).abs()))
}

#[test]
fn unobstructed_light_reads_one_on_every_plane_at_any_angle() {
    // An empty 24³ volume seen by the built-in camera (pitched 20°, so the volume's box is
    // rotated in view space), light 60° off the view axis: on planes in front of, inside and
    // behind the volume, every texel is exactly 1, including those whose light comes from
    // outside the frame of the nearest plane (the far corners at 60° see light that passed
    // 1.7 plane depths sideways). Hard and soft light, orthographic and perspective.
    let vol = volume([24; 3], |_| 0.0);
    let medium = VolumeMedium::new(&vol, [0.0, 1.0], &tf(vec![[0.0, 1.0]], vec![[0.0, 0.0]]));
    for projection in [Projection::Orthographic, Projection::Perspective] {
        for (polar, softness) in [(0.0, 0.0), (60.0, 0.0), (60.0, 0.3)] {
            let mut scene = builtin("ball-lens").unwrap().scene;
            scene.camera.projection = projection;
            scene.light.polar_deg = polar;
            scene.light.azimuth_deg = 40.0;
            let setup = ViewSetup::new(&scene, vol.dims, vol.spacing, 24, 20).unwrap();
            let view = PlaneView::from_setup(&setup, projection == Projection::Orthographic, 24, 20);
            let world = view
                .world_from_view
                .transform_vector3(as_dvec(light_direction(&scene.light)));
            let z0 = setup.z_first as f64;
            let planes = [z0 - 5.0, z0 + 10.0, z0 + 30.0, z0 + 60.0];
            let l = plane_light::trace(
                &medium,
                &light(world, softness),
                &view,
                &planes,
                &settings(2, 0.5),
                None,
            )
            .unwrap();
            let worst = worst_from_one(&l);
            eprintln!(
                "{projection:?}, light {polar}° softness {softness}: |E − 1| ≤ {worst:.1e} ({} rays)",
                l.rays
            );
            // Each direction's rays land on every plane as a lattice aligned with the texels,
            // depositing over a box of one lattice cell: the sum is exactly 1 up to rounding
            // (1e-12 relative per deposit over ~100 deposits per texel).
            assert!(worst < 1e-9, "{projection:?} {polar}° {softness}: off by {worst}");
            for p in &l.planes {
                let crossing = p.power_crossing[1] / l.power_launched;
                assert!((crossing - 1.0).abs() < 1e-12, "plane {}: crossing {crossing}", p.z);
            }
        }
    }
}

fn as_dvec(v: glam::Vec3) -> DVec3 {
    DVec3::new(v.x as f64, v.y as f64, v.z as f64)
}

#[test]
fn an_occluder_outside_the_frame_shadows_it() {
    // An opaque block at x ∈ [14, 22] in front of a frame that shows only |x| < 12; light
    // from the right at 45° moves its shadow by −(z − z_block) in x, into the frame.
    let vol = volume([48, 16, 48], |p| {
        (p.x > 14.0 && p.x < 22.0 && p.z > -20.0 && p.z < -16.0) as u8 as f64
    });
    let medium = VolumeMedium::new(
        &vol,
        [0.0, 1.0],
        &tf(vec![[0.0, 1.0]], vec![[0.0, 0.0], [0.5, 0.0], [0.5, 1.0]]),
    );
    let view = axis_view(24, 8, 1.0);
    let dir = DVec3::new(-1.0, 0.0, 1.0);
    let l = plane_light::trace(&medium, &light(dir, 0.0), &view, &[10.0], &settings(2, 0.5), None).unwrap();
    // Shadow on z = 10 (28 behind the block's centre at −18): x ∈ [14 − 28 − 2, 22 − 28 + 2]
    // = [−16, −4] (the block's 4-voxel depth widens it by 2 each side).
    let p = &l.planes[0];
    for x in 0..24 {
        let centre = x as f64 - 11.5;
        let e = p.texels[4 * 24 + x][1];
        if centre < -4.5 {
            assert!(e < 1e-9, "texel at x = {centre} should be in the shadow: {e}");
        } else if centre > -3.5 {
            assert!((e - 1.0).abs() < 1e-9, "texel at x = {centre} should be lit: {e}");
        }
    }
}

/// A plate |x|, |y| < `half_width`, 0 < z < `thickness` of optical depth `tau` per unit length,
/// with sharp faces, in otherwise empty space.
struct Plate {
    half_width: f64,
    thickness: f64,
    tau: f64,
}

impl Plate {
    fn contains(&self, p: DVec3) -> bool {
        p.x.abs() < self.half_width && p.y.abs() < self.half_width && p.z > 0.0 && p.z < self.thickness
    }
}

impl Medium for Plate {
    fn eta(&self, _: DVec3) -> f64 {
        1.0
    }
    fn grad_eta(&self, _: DVec3) -> DVec3 {
        DVec3::ZERO
    }
    fn optics(&self, p: DVec3) -> Optics {
        Optics {
            tau_alpha: if self.contains(p) { self.tau } else { 0.0 },
            ..Optics::default()
        }
    }
    fn bounds(&self) -> (DVec3, DVec3) {
        let h = self.half_width + 1.0;
        (DVec3::new(-h, -h, -1.0), DVec3::new(h, h, self.thickness + 1.0))
    }
    fn voxel_length(&self) -> f64 {
        1.0
    }
    /// Straight and uniform up to the next face plane ahead.
    fn uniform_for(&self, p: DVec3, d: DVec3) -> Option<f64> {
        let w = self.half_width;
        let faces = [(0, -w), (0, w), (1, -w), (1, w), (2, 0.0), (2, self.thickness)];
        let t = faces
            .iter()
            .map(|&(a, at)| (at - p[a]) / d[a])
            .filter(|t| *t > 1e-12)
            .fold(f64::INFINITY, f64::min);
        Some(t.min(100.0))
    }
}

#[test]
fn a_partly_opaque_plate_casts_a_shadow_of_its_size_and_depth() {
    // A 16×16-voxel plate one voxel thick, transmitting 1/2 at normal incidence, lit at 30°
    // from −y: on a plane 13.5 voxels behind its mid-plane the shadow is 16 voxels wide in x,
    // its centre moved by 13.5·tan 30° in y, and it keeps (1/2)^(1/cos 30°) of the light.
    let medium = Plate {
        half_width: 8.0,
        thickness: 1.0,
        tau: 2f64.ln(),
    };
    let a = 30f64.to_radians();
    let view = axis_view(96, 96, 0.5);
    let l = plane_light::trace(
        &medium,
        &light(DVec3::new(0.0, a.sin(), a.cos()), 0.0),
        &view,
        &[14.0],
        &settings(4, 0.25),
        None,
    )
    .unwrap();
    let p = &l.planes[0];
    let shift = 13.5 * a.tan();
    let expected_depth = 0.5f64.powf(1.0 / a.cos());
    // Row through the shadow's centre; the half level between lit and shadowed.
    let row = ((shift / 0.5) + 47.5).round() as usize;
    let profile: Vec<f64> = (0..96).map(|x| p.texels[row * 96 + x][1]).collect();
    let inside = profile[48];
    let half = 0.5 * (1.0 + inside);
    let crossing = |range: &mut dyn Iterator<Item = usize>| -> f64 {
        let mut prev: Option<(usize, f64)> = None;
        for x in range {
            if let Some((px, pv)) = prev {
                if (pv - half) * (profile[x] - half) <= 0.0 {
                    let t = (half - pv) / (profile[x] - pv);
                    return (px as f64 + t * (x as f64 - px as f64) - 47.5) * 0.5;
                }
            }
            prev = Some((x, profile[x]));
        }
        f64::NAN
    };
    let left = crossing(&mut (0..48));
    let right = crossing(&mut (48..96));
    let width = right - left;
    // Centre of the missing light in y (symmetric about the plate's mid-plane).
    let (mut m0, mut m1) = (0.0, 0.0);
    for y in 0..96 {
        for x in 0..96 {
            let w = 1.0 - p.texels[y * 96 + x][1];
            m0 += w;
            m1 += w * (y as f64 - 47.5) * 0.5;
        }
    }
    let centre = m1 / m0;
    eprintln!(
        "plate shadow: width {width:.5} (16), centre {centre:.5} ({shift:.5}), depth {inside:.6} ({expected_depth:.6})"
    );
    // The plate's x faces lie on texel edges and the footprints are symmetric boxes, so the
    // half level falls on the edge: rounding only. The missing light's centroid is exact for
    // a shadow symmetric about the shifted centre, up to the texels' box filter, which keeps
    // first moments only where the profile is linear within a texel: the penumbrae (1.15
    // voxels wide, exponential) are not, measured 1.7e-3 voxel. Bound 0.01 voxel.
    assert!((width - 16.0).abs() < 1e-9, "shadow width {width}");
    assert!(
        (centre - shift).abs() < 0.01,
        "shadow centre {centre}, expected {shift}"
    );
    // Straight paths through a uniform plate attenuate by exact exponentials.
    assert!(
        (inside - expected_depth).abs() < 1e-12,
        "shadow depth {inside}, expected {expected_depth}"
    );
}

/// An opaque half-plane x < 0, z ∈ [0, ½], within |x|, |y| < `half`.
struct HalfPlane {
    half: f64,
}

impl Medium for HalfPlane {
    fn eta(&self, _: DVec3) -> f64 {
        1.0
    }
    fn grad_eta(&self, _: DVec3) -> DVec3 {
        DVec3::ZERO
    }
    fn optics(&self, p: DVec3) -> Optics {
        let inside = p.x < 0.0 && p.z > 0.0 && p.z < 0.5;
        Optics {
            tau_alpha: if inside { 1e3 } else { 0.0 },
            ..Optics::default()
        }
    }
    fn bounds(&self) -> (DVec3, DVec3) {
        (
            DVec3::new(-self.half, -self.half, -1.0),
            DVec3::new(self.half, self.half, 1.5),
        )
    }
    fn voxel_length(&self) -> f64 {
        1.0
    }
    fn uniform_for(&self, p: DVec3, d: DVec3) -> Option<f64> {
        let t = [(0, 0.0), (2, 0.0), (2, 0.5)]
            .iter()
            .map(|&(a, at)| (at - p[a]) / d[a])
            .filter(|t| *t > 1e-12)
            .fold(f64::INFINITY, f64::min);
        Some(t.min(10.0))
    }
}

#[test]
fn soft_shadow_edges_widen_like_the_sources_disc() {
    // A source of angular radius atan(s) seen past a straight edge: at distance D the edge's
    // profile is the 1D marginal of a uniform disc of radius D·s, whose 10–90% width is
    // 2 × 0.68705 × D·s (F(u) = ½ + (u√(1−u²) + asin u)/π = 0.9 at u = 0.68705).
    let softness = 0.2;
    let medium = HalfPlane { half: 17.0 };
    let texel = 0.25;
    let view = axis_view(80, 4, texel);
    let planes = [10.25, 20.25, 30.25];
    let s = PlaneSettings {
        rays_per_texel: 8,
        step_voxels: 0.25,
        direction_tile: 8,
    };
    let l = plane_light::trace(&medium, &light(DVec3::Z, softness), &view, &planes, &s, None).unwrap();
    let mut widths = Vec::new();
    for p in &l.planes {
        let d = p.z - 0.25;
        let img = p.channel(1);
        let w = measure::edge_width(&img, DVec2::new(0.0, 1.5), DVec2::new(79.0, 1.5), 791).unwrap() * texel;
        let exact = 2.0 * 0.687_048_8 * d * softness;
        eprintln!("soft edge at D = {d}: 10–90% width {w:.4} voxels (disc source: {exact:.4})");
        // 64 directions (a Fibonacci spiral over the disc) sample the profile at 64 distinct
        // offsets, smoothed by the texel and the one-texel footprint (together a 0.3-voxel box,
        // which widens a 2.7-voxel edge by < 1%): bound 3%.
        assert!((w - exact).abs() < 0.03 * exact, "D = {d}: {w} vs {exact}");
        widths.push(w);
    }
    // Linear in D: the same bound on the ratios.
    assert!((widths[1] / widths[0] - 2.0).abs() < 0.06 && (widths[2] / widths[0] - 3.0).abs() < 0.09);
}

#[test]
fn the_nearest_sweep_plane_is_the_one_the_gpu_shows_at_that_depth() {
    // `render --debug-view light --at-depth D` shows plane 1 + round(D·(planes − 1)) − 1
    // (render/state.rs); the depth returned must select exactly the plane returned, which lies
    // within half a plane spacing of the wanted depth.
    let scene = builtin("ball-lens").unwrap().scene;
    for ds in [1.0f32, 0.5, 0.25, 0.37] {
        let mut s = scene.clone();
        s.quality.sample_distance = ds;
        let view = ViewSetup::new(&s, [48, 40, 56], [1.0; 3], 32, 32).unwrap();
        let span = view.step as f64 * (view.planes - 1) as f64;
        for t in [0.0, 0.013, 0.31, 0.5, 0.77, 0.999, 1.0] {
            let want = view.z_first as f64 + t * span;
            let (k, depth, z) = plane_light::nearest_sweep_plane(&view, want);
            let shown = (depth.clamp(0.0, 1.0) * (view.planes - 1) as f32).round() as u32;
            assert_eq!(shown, k, "Δs {ds}, t {t}");
            assert_eq!(plane_light::sweep_plane_at(&view, depth), (k, z));
            assert_eq!(z, (view.z_first + k as f32 * view.step) as f64);
            assert!(
                (z - want).abs() <= 0.5 * view.step as f64 * (1.0 + 1e-5),
                "Δs {ds}, t {t}"
            );
        }
    }
}
