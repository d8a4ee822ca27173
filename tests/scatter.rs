//! Multiple scattering, spread mode (Premoze et al. 2004), against the Monte Carlo reference
//! (`reference::scatter`): the spread of a narrow beam in a forward-scattering slab, energy in
//! a conservative slab, and today's image when nothing scatters.

mod common;

use caustica::bench::slab::{self, light_moments, medium_tf, reference_slab, SlabSetup, ENTRY, HOLE, MASK_END, N};
use caustica::reference::measure::ScalarImage;
use caustica::reference::scatter::{plane_flux, slab_balance};
use caustica::render::{DebugView, PreparedScene, RenderRequest};
use caustica::scene::{MultipleScattering, Quality};
use caustica::transfer::scattering::SpreadMoments;
use caustica::transfer::{Curve, TransferFunctions};
use caustica::volume::Volume;
use common::*;

/// The narrow-beam slab of `caustica::bench::slab` with `mode`.
fn setup(volume: Volume, tf: TransferFunctions, mode: MultipleScattering) -> SlabSetup {
    let quality = Quality {
        multiple_scattering: mode,
        ..Quality::default()
    };
    SlabSetup::new(volume, tf, quality).expect("the slab scene prepares")
}

fn slab_volume(hole: Option<f32>) -> Volume {
    slab::slab_volume(hole).expect("the slab volume")
}

#[test]
fn a_narrow_beam_spreads_in_a_forward_scattering_slab_like_the_monte_carlo_light() {
    let mut gpu = Gpu::new();
    let g = 0.9;
    let a = 0.002;
    let max_r = 30.0;
    let mut report = Vec::new();
    for b in [0.05f32, 0.1, 0.2] {
        let s = setup(slab_volume(Some(HOLE)), medium_tf(a, b, g), MultipleScattering::Spread);
        let (axis, vpp) = s.axis_pixel();
        let depths: Vec<_> = [MASK_END + 1.0, 20.0, 36.0, 52.0]
            .iter()
            .map(|z| s.plane_near(*z))
            .collect();
        let mc_depths: Vec<f64> = depths.iter().map(|d| (d.voxel_z - ENTRY) as f64).collect();
        let mc = plane_flux(&reference_slab(a, b, g), &mc_depths, max_r as f64, 100_000, 16);
        let gpu_moments: Vec<(f64, f64)> = depths
            .iter()
            .map(|d| {
                let img =
                    ScalarImage::from_image(&gpu.debug(&s.prepared, N as u32, DebugView::Light, d.depth).image, 1);
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

#[test]
fn a_conservative_slab_passes_on_all_the_light_it_receives() {
    // Albedo 1, no absorption, lit all over: whatever scatters goes on (forward, in this
    // model), so the light on every plane behind the entry is the light that entered. The
    // Monte Carlo slab sends part of it back (reflected), which the spread mode, carrying
    // scattered light forward with the beams, cannot: reported, not asserted.
    let mut gpu = Gpu::new();
    let (b, g) = (0.1f32, 0.9f32);
    let s = setup(slab_volume(None), medium_tf(0.0, b, g), MultipleScattering::Spread);
    let (axis, vpp) = s.axis_pixel();
    let mc = slab_balance(&reference_slab(0.0, b, g), 50_000, 21);
    for z in [20.0, 36.0] {
        let plane = s.plane_near(z);
        let at = plane.voxel_z;
        let img = ScalarImage::from_image(
            &gpu.debug(&s.prepared, N as u32, DebugView::Light, plane.depth).image,
            1,
        );
        // The centre, away from the frame's edges (light scattered beyond them is dropped).
        let (sum, _) = light_moments(&img, axis, vpp, 6.0);
        let (area, _) = light_moments(&ScalarImage::from_fn(N, N, |_, _| 1.0), axis, vpp, 6.0);
        let mean = sum / area;
        let unscattered = (-(b * (at - ENTRY))).exp();
        eprintln!(
            "depth {:.1}: light {mean:.4} (unscattered {unscattered:.3}); Monte Carlo slab: transmitted {:.4}, reflected {:.4}",
            at - ENTRY,
            mc.transmitted,
            mc.reflected
        );
        // Measured 0.985 and 0.982: the beams' power in f16, the albedo table's interpolation
        // (ω 0.998 between its entries at 0.5) and the deposits' rounding; 3 % bounds them.
        // Deeper (56 voxels, 0.84) the scattered light's spread (σ ≈ 16 voxels) reaches the
        // frame's edges, beyond which no beams carry light back in: not a loss of the model.
        assert!((mean - 1.0).abs() < 0.03, "light {mean} at depth {at}");
    }
    assert!(mc.transmitted + mc.reflected > 0.98 && mc.reflected > 0.0, "{mc:?}");
}

#[test]
fn spread_at_zero_albedo_renders_todays_image() {
    // The spread mode with nothing that scatters (albedo 0, isotropic g) is `none`: the same
    // bytes, although it runs its own variant.
    let mut gpu = Gpu::new();
    let mut scene = caustica::scene::builtin("supernova").unwrap().scene;
    scene.set_builtin_resolution(32);
    scene.quality.refraction = caustica::scene::Toggle::Off;
    scene.quality.multiple_scattering = MultipleScattering::None;
    let none = PreparedScene::load(&scene).unwrap();
    let mut tf = none.tf.clone();
    tf.albedo = Some(Curve::constant(0.0));
    tf.anisotropy = Some(Curve::constant(0.0));
    scene.transfer = caustica::scene::TransferSource::Inline(tf);
    scene.quality.multiple_scattering = MultipleScattering::Spread;
    let spread = PreparedScene::load(&scene).unwrap();
    assert!(!none.features().scatter && spread.features().scatter);
    let req = RenderRequest::new(48, 48);
    let (a, b) = (gpu.render(&none, &req), gpu.render(&spread, &req));
    assert!(a.image.pixels.iter().any(|p| p[1] > 0.0), "a lit image");
    assert!(
        a.image.pixels.iter().zip(&b.image.pixels).all(|(x, y)| x == y),
        "spread at zero albedo changed the image"
    );
}

#[test]
fn auto_spreads_when_the_transfer_functions_scatter_and_spread_refuses_refraction() {
    let tf = medium_tf(0.01, 0.1, 0.8);
    let auto = setup(slab_volume(None), tf.clone(), MultipleScattering::Auto);
    assert!(auto.prepared.features().scatter, "auto with an albedo: spread");
    let mut clear = tf.clone();
    clear.albedo = None;
    assert!(
        !setup(slab_volume(None), clear, MultipleScattering::Auto)
            .prepared
            .features()
            .scatter
    );
    assert!(
        !setup(slab_volume(None), tf.clone(), MultipleScattering::None)
            .prepared
            .features()
            .scatter
    );
    // With refraction, auto falls back to none; an explicit spread is refused by name.
    let mut glass = tf;
    glass.eta = Curve {
        points: vec![[0.0, 1.0], [0.5, 1.3]],
    };
    let auto = setup(slab_volume(None), glass.clone(), MultipleScattering::Auto);
    assert!(auto.prepared.features().refraction && !auto.prepared.features().scatter);
    let spread = setup(slab_volume(None), glass, MultipleScattering::Spread);
    let mut gpu = Gpu::new();
    let Err(err) = gpu.renderer.render(&spread.prepared, &RenderRequest::new(16, 16)) else {
        panic!("spread with refraction rendered");
    };
    let err = err.to_string();
    assert!(err.contains("spread") && err.contains("refraction"), "{err}");
}

#[test]
fn the_milk_glass_scene_spreads_its_scattered_light_into_its_shadow() {
    let mut gpu = Gpu::new();
    let mut scene = caustica::scene::builtin("milk-glass").unwrap().scene;
    scene.set_builtin_resolution(48);
    let spread = PreparedScene::load(&scene).unwrap();
    assert!(
        spread.features().scatter,
        "auto picks the spread mode: {:?}",
        spread.features()
    );
    scene.quality.multiple_scattering = MultipleScattering::None;
    let none = PreparedScene::load(&scene).unwrap();
    let image = gpu.render(&spread, &RenderRequest::new(64, 64)).image;
    assert!(image.pixels.iter().all(|p| p.iter().all(|c| c.is_finite())));
    assert!(image.pixels.iter().any(|p| luminance(p) > 0.1), "a lit image");
    // On a plane behind the ball the spread mode has all the light `none` has (the
    // unscattered light is the same) plus the scattered light: nowhere less (up to the
    // deposits' rounding, 1e-3) and, in and around the ball's shadow, clearly more.
    let mut light = |p: &PreparedScene| gpu.debug(p, 64, DebugView::Light, 0.7).image;
    let (a, b) = (light(&spread), light(&none));
    let gain: Vec<f32> = a.pixels.iter().zip(&b.pixels).map(|(x, y)| x[1] - y[1]).collect();
    let least = gain.iter().cloned().fold(f32::INFINITY, f32::min);
    let most = gain.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
    eprintln!("scattered light behind the ball: {least:.4} to {most:.4}");
    assert!(least > -1e-3 && most > 0.05, "{least} .. {most}");
}
