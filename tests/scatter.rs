//! Multiple scattering, spread mode (Premoze et al. 2004), against the Monte Carlo reference
//! (`reference::scatter`): the spread of a narrow beam in a forward-scattering slab, energy in
//! a conservative slab, the light it lets out of its lit face, and today's image when nothing
//! scatters.

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

/// The mean r² within `max_r` of the axis of the light the spread mode carries at path
/// length `s` through scattering b with anisotropy g, behind the hole (`HOLE`): the
/// unscattered light e^(−bs) across the hole, the scattered light as the core and wings of
/// `SpreadMoments::scattered_cloud` spread further by the hole's width (absorption thins both
/// alike). The hole, a uniform disc, is taken as a Gaussian of the same variance.
fn windowed_cloud_r2(b: f64, g: f64, s: f64, max_r: f64) -> f64 {
    let mut m = SpreadMoments::default();
    m.step(b, g, s);
    let hole = (HOLE as f64).powi(2) / 4.0;
    let scattered = 1.0 - (-b * s).exp();
    let mut parts = vec![(1.0 - scattered, hole)];
    parts.extend(m.scattered_cloud().map(|(share, v)| (scattered * share, v + hole)));
    // A Gaussian of variance v per axis: power within R is 1 − e^(−x), x = R²/2v, and ∫r² over
    // it 2v(1 − e^(−x)(1 + x)).
    let (mut power, mut r2) = (0.0, 0.0);
    for (share, v) in parts {
        let x = max_r * max_r / (2.0 * v.max(1e-12));
        power += share * (1.0 - (-x).exp());
        r2 += share * 2.0 * v * (1.0 - (-x).exp() * (1.0 + x));
    }
    r2 / power
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
            // The cloud the spread mode deposits, at path length = depth, within the window.
            let model_r2 = |s: f64| windowed_cloud_r2(b as f64, g as f64, s, max_r as f64);
            let model_w = (model_r2(mc_depths[i]) - model_r2(mc_depths[0])).max(0.0).sqrt();
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
        // The GPU follows the moment equations it implements, second and fourth moment: its
        // windowed width is the model cloud's within 0.7–2.1 % where the light stays well
        // inside the 30-voxel window (depths 16 and 32: 3 % bounds the deposit's rounding and
        // the f16 beam state) and within 1.8–4.2 % at 48 voxels, where the wings reach the
        // window's edge and the shapes the model takes as Gaussians (the deposit's levels,
        // tents; the hole, a disc) weigh in: 6 %. A Gaussian cloud of the same variance (no
        // fourth moment) is 19 % wider than the model at b = 0.05 and 48 voxels.
        let bound = if depth < 40.0 { 0.03 } else { 0.06 };
        assert!(
            (gpu_w / model_w - 1.0).abs() < bound,
            "b {b} depth {depth}: GPU {gpu_w} vs moments {model_w}"
        );
        // Against the Monte Carlo light the target is 15 %; it holds at 32 and 48 voxels for
        // every b (measured 0.97–1.08). Near the entry the model's own limits show (GPU
        // 23–29 % narrower at 16 voxels): the Monte Carlo's net flux at the first plane has a
        // negative mean r² (−5.6 to −32 voxels²: the slab's diffuse reflection crossing it
        // backward at large radii), and its forward light holds light that has turned back
        // and forth and light crossing steeply (offsets growing as tan θ per unit depth, the
        // moments' as sin θ), which forward-only spread moments do not have
        // (docs/accuracy.md). 0.35 bounds those.
        let ratio = gpu_w / mc_w;
        let bound = if depth > 24.0 { 0.15 } else { 0.35 };
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
    // model, but for the part of the cloud behind the lit face, under 10⁻³ here at g = 0.9:
    // see the isotropic slab below), so the light on every plane behind the entry is the
    // light that entered. The Monte Carlo slab sends part of it back (reflected) from deeper
    // in, which the spread mode, carrying scattered light forward with the beams, cannot:
    // reported, not asserted.
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

/// The light on a plane `depth` voxels into a conservative slab lit head-on (unscattered plus
/// scattered) as the spread mode steps it, by the CPU's moments: each step the cloud loses the
/// share that came to lie behind the lit face since the step before
/// (`SpreadMoments::behind_entry`).
fn kept_light(b: f64, g: f64, depth: f64) -> f64 {
    let (mut m, mut unscattered, mut scattered, mut behind) = (SpreadMoments::default(), 1.0f64, 0.0f64, 0.0f64);
    let steps = (depth / 0.5).round().max(1.0) as usize;
    let h = depth / steps as f64;
    for k in 1..=steps {
        m.step(b, g, h);
        let now = m.behind_entry(k as f64 * h, 1.0);
        let left = (now - behind).max(0.0) / (1.0 - behind).max(1e-6);
        let through = unscattered * (-b * h).exp();
        scattered = scattered * (1.0 - left) + (unscattered - through);
        unscattered = through;
        behind = now;
    }
    unscattered + scattered
}

/// The mean light the light view shows within 6 voxels of the slab's axis on `plane`.
fn slab_light(gpu: &mut Gpu, s: &SlabSetup, plane: &slab::SlabPlane) -> f64 {
    let (axis, vpp) = s.axis_pixel();
    let img = ScalarImage::from_image(
        &gpu.debug(&s.prepared, N as u32, DebugView::Light, plane.depth).image,
        1,
    );
    let (sum, _) = light_moments(&img, axis, vpp, 6.0);
    let (area, _) = light_moments(&ScalarImage::from_fn(N, N, |_, _| 1.0), axis, vpp, 6.0);
    sum / area
}

#[test]
fn an_isotropic_slab_lets_out_of_its_lit_face_what_the_spread_moments_put_behind_it() {
    // Albedo 1, no absorption, lit all over and head-on, b = 0.1: with g = 0 the scattered
    // light soon turns back, and the part of the cloud behind the lit face leaves
    // (`spread_behind`); with g = 0.9 hardly any of it is behind the face at these depths.
    // The ratio of the two slabs' light on the same plane takes out what both lose to the
    // beams' f16 power and the albedo table (the conservative slab's 1.5–1.8 %), and is the
    // ratio of what the moments keep.
    let mut gpu = Gpu::new();
    let b = 0.1f32;
    let isotropic = setup(slab_volume(None), medium_tf(0.0, b, 0.0), MultipleScattering::Spread);
    let forward = setup(slab_volume(None), medium_tf(0.0, b, 0.9), MultipleScattering::Spread);
    let mc = slab_balance(&reference_slab(0.0, b, 0.0), 50_000, 23);
    for z in [20.0, 36.0] {
        let plane = isotropic.plane_near(z);
        let depth = (plane.voxel_z - ENTRY) as f64;
        let (iso, fwd) = (
            slab_light(&mut gpu, &isotropic, &plane),
            slab_light(&mut gpu, &forward, &plane),
        );
        let (kept_iso, kept_fwd) = (kept_light(b as f64, 0.0, depth), kept_light(b as f64, 0.9, depth));
        let (ratio, expected) = (iso / fwd, kept_iso / kept_fwd);
        eprintln!(
            "depth {depth:.1}: light g = 0: {iso:.4}, g = 0.9: {fwd:.4}, ratio {ratio:.4}; moments {kept_iso:.4} and {kept_fwd:.4}, ratio {expected:.4}; Monte Carlo slab (g = 0) reflects {:.4}",
            mc.reflected
        );
        // Measured 0.998 and 0.987 of the moments' ratio (were no light to leave, 1.036 and
        // 1.099). Bound 3 %: the 1.3 % at 32 voxels is not traced; the isotropic light
        // spreads wider, and light beyond the frame's edges is dropped (what brings the
        // g = 0.9 slab's light to 0.84 at 56 voxels), and the beams count their path since
        // the face from the plane where they meet it.
        assert!(
            (ratio / expected - 1.0).abs() < 0.03,
            "ratio {ratio} vs {expected} at depth {depth}"
        );
        // Some light leaves, less than the whole slab reflects (the face lets out the least
        // it can).
        assert!(kept_iso < 0.97 && 1.0 - kept_iso < mc.reflected, "{kept_iso} vs {mc:?}");
    }
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
    // 32-bit state: without scattering a view pass advances the rays over several planes, in
    // the spread mode over one, and f16 state would round the two differently.
    scene.quality.precision = caustica::scene::Precision::F32;
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
