//! Multiple scattering, spread mode (Premoze et al. 2004), against the Monte Carlo reference
//! (`reference::scatter`): the spread of a narrow beam in a forward-scattering slab, energy in
//! a conservative slab, and today's image when nothing scatters.

mod common;

use caustica::reference::measure::ScalarImage;
use caustica::reference::plane_light::nearest_sweep_plane;
use caustica::reference::scatter::{plane_flux, Slab};
use caustica::render::{DebugView, PreparedScene};
use caustica::scene::{MultipleScattering, ViewSetup};
use caustica::transfer::scattering::SpreadMoments;
use caustica::transfer::{Curve, TransferFunctions};
use caustica::volume::Volume;
use common::*;
use glam::{Vec2, Vec3};

/// Voxels per side of the test volumes; the frame spans them on as many pixels.
const N: usize = 64;
/// Voxel depth where the medium starts (the mask in front of it is 2 voxels thick).
const ENTRY: f32 = 4.0;
const MASK_END: f32 = 6.0;

/// Transfer functions of a medium at data value 0.5 (extinction `a + b` per voxel, albedo
/// b / (a + b), anisotropy g) and an opaque, non-scattering mask at 1.
fn medium_tf(a: f32, b: f32, g: f32) -> TransferFunctions {
    let alpha = 1.0 - (-(a + b)).exp();
    let albedo = if a + b > 0.0 { b / (a + b) } else { 0.0 };
    let mut tf = plain_tf(
        vec![[0.0, 0.0], [0.5, alpha], [0.75, alpha], [1.0, 1.0]],
        vec![[0.0, 1.0, 1.0, 1.0]],
    );
    tf.albedo = Some(Curve {
        points: vec![[0.0, 0.0], [0.5, albedo], [0.75, albedo], [1.0, 0.0]],
    });
    tf.anisotropy = Some(Curve::constant(g));
    tf
}

/// Air in front of voxel depth ENTRY, the medium behind it; with `hole`, an opaque mask from
/// ENTRY to MASK_END with a hole of that radius (voxels) on the axis.
fn slab_volume(hole: Option<f32>) -> Volume {
    volume_from(N, |x, y, z| {
        let n = N as f32;
        let z = z * n - 0.5;
        if z < ENTRY {
            return 0.0;
        }
        let r2 = ((x - 0.5) * n).powi(2) + ((y - 0.5) * n).powi(2);
        match hole {
            Some(r) if z < MASK_END && r2 > r * r => 1.0,
            _ => 0.5,
        }
    })
}

struct Setup {
    p: PreparedScene,
    view: ViewSetup,
}

fn setup(volume: Volume, tf: TransferFunctions, mode: MultipleScattering) -> Setup {
    let mut scene = head_on_scene(&tf);
    // The frame spans the volume's side: one pixel per voxel.
    scene.camera.zoom = 3f32.sqrt();
    scene.quality.multiple_scattering = mode;
    let view = ViewSetup::new(&scene, volume.dims, volume.spacing, N as u32, N as u32).expect("view");
    Setup {
        p: prepared(scene, volume, tf),
        view,
    }
}

impl Setup {
    /// The view-space point on the axis at voxel depth `z`.
    fn axis_point(&self, z: f32) -> Vec3 {
        let world = self
            .view
            .tex_from_world
            .inverse()
            .transform_point3(Vec3::new(0.5, 0.5, z / N as f32));
        self.view.view_from_world.transform_point3(world)
    }

    /// The sweep plane nearest voxel depth `z`: the `--at-depth` value selecting it and the
    /// voxel depth it is at.
    fn plane_near(&self, z: f32) -> (f32, f32) {
        let (_, depth, plane_z) = nearest_sweep_plane(&self.view, self.axis_point(z).z as f64);
        let p = self
            .view
            .point_at(self.view.pixel_of(self.axis_point(z)), plane_z as f32);
        let tex = self
            .view
            .tex_from_world
            .transform_point3(self.view.world_from_view.transform_point3(p));
        (depth, tex.z * N as f32)
    }

    /// Pixel coordinates of the axis, and voxels per pixel.
    fn axis_pixel(&self) -> (Vec2, f32) {
        let a = self.view.pixel_of(self.axis_point(ENTRY));
        let world = self.view.tex_from_world.inverse();
        let p = |t: Vec3| {
            self.view
                .pixel_of(self.view.view_from_world.transform_point3(world.transform_point3(t)))
        };
        let step = p(Vec3::new(0.5 + 1.0 / N as f32, 0.5, 0.5)) - p(Vec3::new(0.5, 0.5, 0.5));
        (a, 1.0 / step.length())
    }
}

/// Light (irradiance on the plane, green channel) within `max_r` voxels of the axis: its sum
/// over the pixels and its mean r² (voxels²).
fn light_moments(img: &ScalarImage, axis: Vec2, voxels_per_pixel: f32, max_r: f32) -> (f64, f64) {
    let (mut sum, mut r2sum) = (0.0, 0.0);
    for y in 0..img.height {
        for x in 0..img.width {
            let r = (Vec2::new(x as f32, y as f32) - axis).length() * voxels_per_pixel;
            if r <= max_r {
                let l = img.at(x, y);
                sum += l;
                r2sum += l * (r as f64).powi(2);
            }
        }
    }
    (sum, r2sum / sum)
}

#[test]
fn a_narrow_beam_spreads_in_a_forward_scattering_slab_like_the_monte_carlo_light() {
    let mut gpu = Gpu::new();
    let g = 0.9;
    let a = 0.002;
    let max_r = 30.0;
    let mut report = Vec::new();
    for b in [0.05f32, 0.1, 0.2] {
        let s = setup(slab_volume(Some(2.0)), medium_tf(a, b, g), MultipleScattering::Spread);
        let (axis, vpp) = s.axis_pixel();
        let depths: Vec<(f32, f32)> = [MASK_END + 1.0, 20.0, 36.0, 52.0]
            .iter()
            .map(|z| s.plane_near(*z))
            .collect();
        let slab = Slab {
            thickness: N as f64 - ENTRY as f64,
            half_width: 1000.0,
            absorption: a as f64,
            scattering: b as f64,
            g: g as f64,
        };
        let mc_depths: Vec<f64> = depths.iter().map(|d| (d.1 - ENTRY) as f64).collect();
        let mc = plane_flux(&slab, &mc_depths, max_r as f64, 100_000, 16);
        let gpu_moments: Vec<(f64, f64)> = depths
            .iter()
            .map(|(d, _)| {
                let img = ScalarImage::from_image(&gpu.debug(&s.p, N as u32, DebugView::Light, *d).image, 1);
                light_moments(&img, axis, vpp, max_r)
            })
            .collect();
        for i in 1..depths.len() {
            // The hole's own width is in both the first and this plane (spreads add): the
            // difference is the pencil beam's.
            let gpu_w = (gpu_moments[i].1 - gpu_moments[0].1).max(0.0).sqrt();
            let mc_w = (mc[i].mean_r2 - mc[0].mean_r2).max(0.0).sqrt();
            let power = gpu_moments[i].0 / gpu_moments[0].0;
            // The moments the spread mode follows, at path length = depth.
            let r2 = |s: f64| {
                let mut m = SpreadMoments::default();
                m.step(b as f64, g as f64, s);
                m.r2
            };
            let model_w = (r2(mc_depths[i]) - r2(mc_depths[0])).sqrt();
            report.push((b, mc_depths[i], gpu_w, mc_w, model_w, power, mc[i].flux / mc[0].flux));
        }
    }
    for r in &report {
        eprintln!(
            "b {} /voxel, depth {:.1}: width GPU {:.3} MC {:.3} moments {:.3} voxels, GPU/MC {:.3}; power GPU {:.4} MC {:.4}",
            r.0,
            r.1,
            r.2,
            r.3,
            r.4,
            r.2 / r.3,
            r.5,
            r.6
        );
    }
    for &(b, depth, gpu_w, mc_w, model_w, ..) in &report {
        // The GPU follows the moment equations it implements: measured within 1.2 % where
        // the light's spread (model width ≤ 15 voxels) stays well inside the 30-voxel
        // window and the frame. 3 % bounds the deposit's rounding and the f16 beam state.
        if model_w <= 15.0 {
            assert!(
                (gpu_w / model_w - 1.0).abs() < 0.03,
                "b {b} depth {depth}: GPU {gpu_w} vs moments {model_w}"
            );
        }
        // Against the Monte Carlo light the target is 15 %; it holds at 32 voxels for every b
        // (measured 0.98–1.04). Elsewhere the model's own limits show (measured 0.71–1.30):
        // near the entry the light crossing depth z has travelled further than z and spread
        // more than the moments at path length z say (GPU 22–29 % narrower at 16 voxels);
        // deep in, the Monte Carlo light's wide wings leave the 30-voxel window (its power
        // there falls to 0.40–0.75 against the GPU's 0.74–0.91), which narrows or widens the
        // windowed moments differently. 0.35 bounds those.
        let ratio = gpu_w / mc_w;
        let bound = if (depth - 32.0).abs() < 1.0 { 0.15 } else { 0.35 };
        assert!(
            (ratio - 1.0).abs() < bound,
            "b {b} depth {depth}: GPU {gpu_w} vs MC {mc_w}"
        );
    }
    // The light spreads further the deeper it goes (a spread mode that ignored the medium
    // would not).
    for w in report.windows(2).filter(|w| w[0].0 == w[1].0) {
        assert!(w[1].2 > w[0].2 + 1.0, "{w:?}");
    }
}
