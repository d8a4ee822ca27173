//! A translucent sphere lit from the side: the glow of its scattered light on the GPU (spread
//! and lattice-Boltzmann modes) against the Monte Carlo view gather
//! (`reference::scatter_view`), as profiles of the image.
//!
//! The light is a distant source in the viewer's hemisphere (the sweep carries it with the
//! view, front to back), so "lit from behind" is read as lit at 70° to the view axis, from the
//! right: half the visible disc faces away from the light, and what shows there is light
//! scattered round into the sphere's shadowed side. The glow is one-sided, so the profile that
//! measures it runs along the light's direction on the image (means over strips across it,
//! within the disc's width); the radial profile (means over annuli about the disc's centre)
//! averages the lit and the shadowed sides and is reported beside it.

mod common;

use caustica::reference::scatter_view::{gather, GatherImage, GatherSettings};
use caustica::render::{PreparedScene, RenderRequest};
use caustica::scene::{light_direction, MultipleScattering, Precision, Toggle, ViewSetup};
use caustica::transfer::{Curve, TransferFunctions};
use common::*;
use glam::{Vec2, Vec3};

/// Voxels per side of the volume; the image has SIZE² pixels over the volume's side.
const N: usize = 40;
const SIZE: u32 = 64;
/// Sphere radius, as a fraction of the box side (12 voxels).
const RADIUS: f32 = 0.3;
/// Profile bins, pixels.
const BIN: f32 = 2.0;
/// How far beyond the disc's edge the profiles run, pixels.
const MARGIN: f32 = 6.0;

/// A homogeneous sphere of white particles: extinction per voxel, albedo, HG g; lit at
/// `polar_deg` to the view axis from the right, orthographic, black background, no ground.
struct Sphere {
    sigma_t: f32,
    albedo: f32,
    g: f32,
    polar_deg: f32,
}

impl Sphere {
    fn tf(&self) -> TransferFunctions {
        let alpha = 1.0 - (-self.sigma_t).exp();
        let mut tf = plain_tf(vec![[0.0, 0.0], [1.0, alpha]], vec![[0.0, 1.0, 1.0, 1.0]]);
        tf.albedo = Some(Curve::constant(self.albedo));
        tf.anisotropy = Some(Curve::constant(self.g));
        tf
    }

    fn scene(&self, mode: MultipleScattering) -> PreparedScene {
        let tf = self.tf();
        let mut scene = head_on_scene(&tf);
        // The frame spans the volume's side.
        scene.camera.zoom = 3f32.sqrt();
        scene.light.polar_deg = self.polar_deg;
        scene.light.azimuth_deg = 90.0;
        scene.quality.multiple_scattering = mode;
        if mode == MultipleScattering::Lbm {
            scene.quality.precision = Precision::F32;
        }
        prepared(scene, sphere(N, RADIUS, 1.0), tf)
    }
}

/// The green channel of the GPU's image.
/// A sphere rendered with spread, lbm and none, its Monte Carlo image (256 samples per pixel,
/// the non-scattering fraction shaded as the GPU shades it) and the modes' profile L1 against
/// it (along the light, radial).
struct Measured {
    spread: PreparedScene,
    frame: Frame,
    mc: GatherImage,
    images: [(&'static str, Vec<f64>); 3],
    l1: Vec<(f64, f64)>,
}

impl Sphere {
    fn measure(&self, name: &str) -> Measured {
        let mut gpu = Gpu::new();
        let spread = self.scene(MultipleScattering::Spread);
        let frame = Frame::of(&spread);
        let mc = monte_carlo(&spread, 256, 1, u32::MAX, true);
        let images = [
            ("spread", render(&mut gpu, &spread)),
            ("lbm", render(&mut gpu, &self.scene(MultipleScattering::Lbm))),
            ("none", render(&mut gpu, &self.scene(MultipleScattering::None))),
        ];
        let views: Vec<(&str, &[f64])> = images.iter().map(|(n, i)| (*n, i.as_slice())).collect();
        let l1 = compare(name, &frame, &mc, &views);
        Measured {
            spread,
            frame,
            mc,
            images,
            l1,
        }
    }
}

fn render(gpu: &mut Gpu, p: &PreparedScene) -> Vec<f64> {
    let out = gpu.render(p, &RenderRequest::new(SIZE, SIZE));
    out.image.pixels.iter().map(|p| p[1] as f64).collect()
}

/// The Monte Carlo image (green), shading the particles' non-scattering fraction as the GPU
/// does (`diffuse_rest`), or physically.
fn monte_carlo(p: &PreparedScene, spp: u32, seed: u64, max_order: u32, diffuse_rest: bool) -> GatherImage {
    let settings = GatherSettings {
        max_order,
        diffuse_rest,
        ..GatherSettings::new(spp, seed, 1)
    };
    gather(p, SIZE, SIZE, &settings).expect("the gather renders the scene")
}

/// Where the profiles are taken: the sphere's centre on the image, the unit direction the
/// light travels along on the image, the disc's radius (pixels).
struct Frame {
    centre: Vec2,
    along: Vec2,
    radius: f32,
}

impl Frame {
    fn of(p: &PreparedScene) -> Frame {
        let view = ViewSetup::new(&p.scene, p.volume.dims, p.volume.spacing, SIZE, SIZE).expect("view");
        let c = view.view_from_world.transform_point3(Vec3::ZERO);
        let centre = view.pixel_of(c);
        let l = light_direction(&p.scene.light);
        let along = (view.pixel_of(c + Vec3::new(l.x, l.y, 0.0)) - centre).normalize();
        let edge = view.pixel_of(c + Vec3::new(RADIUS * N as f32, 0.0, 0.0));
        Frame {
            centre,
            along,
            radius: (edge - centre).length(),
        }
    }

    fn extent(&self) -> f32 {
        self.radius + MARGIN
    }

    /// Bin along the light (strips across it within the disc's width), from the lit side.
    fn along_bin(&self, p: Vec2) -> Option<usize> {
        let d = p - self.centre;
        let u = d.dot(self.along);
        (d.perp_dot(self.along).abs() <= self.radius && u.abs() < self.extent())
            .then(|| ((u + self.extent()) / BIN) as usize)
    }

    fn along_bins(&self) -> usize {
        (2.0 * self.extent() / BIN).ceil() as usize
    }

    /// Annulus about the centre.
    fn radial_bin(&self, p: Vec2) -> Option<usize> {
        let r = (p - self.centre).length();
        (r < self.extent()).then(|| (r / BIN) as usize)
    }

    fn radial_bins(&self) -> usize {
        (self.extent() / BIN).ceil() as usize
    }
}

/// Means of `values` (one per pixel) over the bins `key` assigns the pixel centres to, and the
/// number of pixels per bin.
fn binned(values: &[f64], bins: usize, key: impl Fn(Vec2) -> Option<usize>) -> (Vec<f64>, Vec<usize>) {
    let (mut sum, mut count) = (vec![0.0; bins], vec![0usize; bins]);
    for (i, v) in values.iter().enumerate() {
        let p = Vec2::new((i % SIZE as usize) as f32 + 0.5, (i / SIZE as usize) as f32 + 0.5);
        if let Some(b) = key(p) {
            sum[b] += v;
            count[b] += 1;
        }
    }
    let means = sum.iter().zip(&count).map(|(s, &c)| s / c.max(1) as f64).collect();
    (means, count)
}

/// A profile of the Monte Carlo image with the standard errors of its bin means.
fn mc_profile(mc: &GatherImage, bins: usize, key: impl Fn(Vec2) -> Option<usize>) -> (Vec<f64>, Vec<f64>) {
    let (mean, count) = binned(&mc.mean, bins, &key);
    let var: Vec<f64> = mc.std_error.iter().map(|e| e * e).collect();
    let (var, _) = binned(&var, bins, &key);
    // Pixels are independent: the variance of a bin mean is the mean variance over the count.
    let se = var
        .iter()
        .zip(&count)
        .map(|(v, &c)| (v / c.max(1) as f64).sqrt())
        .collect();
    (mean, se)
}

/// Σ|a − b| / Σ|b| over the bins.
fn relative_l1(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum();
    num / b.iter().map(|y| y.abs()).sum::<f64>()
}

/// The L1 that the Monte Carlo's noise alone adds to a comparison: Σ E|noise| / Σ|b| (E|X| =
/// σ√(2/π) for a normal error).
fn noise_l1(se: &[f64], b: &[f64]) -> f64 {
    let num: f64 = se.iter().map(|s| s * (2.0 / std::f64::consts::PI).sqrt()).sum();
    num / b.iter().map(|y| y.abs()).sum::<f64>()
}

/// Relative L1 of each GPU image's profiles (along the light, radial) against the Monte
/// Carlo's, with the table printed.
fn compare(name: &str, frame: &Frame, mc: &GatherImage, gpu: &[(&str, &[f64])]) -> Vec<(f64, f64)> {
    let mut out = vec![(0.0, 0.0); gpu.len()];
    for (kind, bins) in [("along the light", frame.along_bins()), ("radial", frame.radial_bins())] {
        let key = |p: Vec2| match kind {
            "radial" => frame.radial_bin(p),
            _ => frame.along_bin(p),
        };
        let (m, se) = mc_profile(mc, bins, key);
        let profiles: Vec<Vec<f64>> = gpu.iter().map(|(_, img)| binned(img, bins, key).0).collect();
        let l1: Vec<f64> = profiles.iter().map(|p| relative_l1(p, &m)).collect();
        eprintln!(
            "{name}, profile {kind} ({BIN}-pixel bins, Monte Carlo noise adds L1 ≈ {:.3}):",
            noise_l1(&se, &m)
        );
        for (i, (label, _)) in gpu.iter().enumerate() {
            eprintln!("  {label}: relative L1 {:.4}", l1[i]);
            if kind == "radial" {
                out[i].1 = l1[i];
            } else {
                out[i].0 = l1[i];
            }
        }
        let labels: Vec<&str> = gpu.iter().map(|g| g.0).collect();
        eprintln!("  bin: Monte Carlo ± se | {}", labels.join(" | "));
        for b in 0..bins {
            let row: Vec<String> = profiles.iter().map(|p| format!("{:.4}", p[b])).collect();
            eprintln!("  {b:3}: {:.4} ± {:.4} | {}", m[b], se[b], row.join(" | "));
        }
    }
    out
}

/// The Monte Carlo image and the GPU's side by side (grey, each pixel 3 × 3, one scale: the
/// Monte Carlo's brightest pixel is white; gamma 2.2), for docs/accuracy.md.
fn save_picture(path: &str, mc: &[f64], gpu: &[(&str, &[f64])]) {
    const ZOOM: u32 = 3;
    const GAP: u32 = 8;
    let side = SIZE * ZOOM;
    let panels: Vec<&[f64]> = std::iter::once(mc).chain(gpu.iter().map(|g| g.1)).collect();
    let width = panels.len() as u32 * (side + GAP) - GAP;
    let max = mc.iter().cloned().fold(0.0, f64::max);
    let mut img = image::GrayImage::new(width, side);
    for (k, panel) in panels.iter().enumerate() {
        for y in 0..side {
            for x in 0..side {
                let v = panel[((y / ZOOM) * SIZE + x / ZOOM) as usize] / max;
                let grey = (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8;
                img.put_pixel(k as u32 * (side + GAP) + x, y, image::Luma([grey]));
            }
        }
    }
    img.save(path).expect("the picture is written");
    eprintln!("wrote {path}");
}

#[test]
fn the_monte_carlo_gather_is_deterministic_and_refuses_refraction() {
    let s = Sphere {
        sigma_t: 0.25,
        albedo: 0.97,
        g: 0.6,
        polar_deg: 70.0,
    };
    let p = s.scene(MultipleScattering::Spread);
    let a = monte_carlo(&p, 4, 3, u32::MAX, true);
    let b = monte_carlo(&p, 4, 3, u32::MAX, true);
    assert!(a.mean == b.mean && a.std_error == b.std_error, "same seed, same bits");
    let c = monte_carlo(&p, 4, 4, u32::MAX, true);
    assert!(a.mean != c.mean, "another seed, other samples");
    // The image means of two seeds agree within their errors (pixels independent): 5σ of the
    // difference.
    let mean = |g: &GatherImage| g.mean.iter().sum::<f64>() / g.mean.len() as f64;
    let var = |g: &GatherImage| g.std_error.iter().map(|e| e * e).sum::<f64>() / (g.mean.len() as f64).powi(2);
    let sigma = (var(&a) + var(&c)).sqrt();
    assert!(mean(&a) > 0.05, "a lit sphere: {}", mean(&a));
    assert!(
        (mean(&a) - mean(&c)).abs() < 5.0 * sigma,
        "{} vs {}",
        mean(&a),
        mean(&c)
    );
    // Paths are straight: a scene that refracts is refused by name.
    let mut glass = s.tf();
    glass.eta = Curve {
        points: vec![[0.0, 1.0], [1.0, 1.3]],
    };
    let mut scene = head_on_scene(&glass);
    scene.quality.refraction = Toggle::Auto;
    let refracting = prepared(scene, sphere(N, RADIUS, 1.0), glass);
    let err = gather(&refracting, 8, 8, &GatherSettings::new(1, 0, 1)).unwrap_err();
    assert!(err.to_string().contains("refraction"), "{err}");
}

#[test]
fn a_faint_sphere_scatters_the_light_once_like_the_monte_carlo_light() {
    // Optical radius 0.12: single scattering rules, which both modes see through the phase
    // function (at 110° here: the light comes from the viewer's side). This checks the chain
    // the glow check relies on (camera, units, phase function, the shading of the
    // non-scattering fraction) where the transport's approximations hardly matter.
    let s = Sphere {
        sigma_t: 0.01,
        albedo: 0.97,
        g: 0.6,
        polar_deg: 70.0,
    };
    let l1 = s.measure("faint sphere").l1;
    // Measured: spread 0.156 along the light, 0.187 radial (0.186 and 0.221 before the cloud
    // left through the medium's sides, 0.184 and 0.219 before its core and wings), too
    // bright inside the disc: it sees its scattered light as
    // isotropic, while light scattered once in a faint medium still travels near the light's
    // direction (HG(g) about it) and the particles send it towards the viewer through HG(g²)
    // at 110°, about half of isotropic; and it deposits that light as a core and wings about
    // its centroid, where the light scattered once is a forward cone (0.099 and 0.117 before the deposit followed the centroid's lag, which
    // left more of it beyond the sphere; 0.189 and 0.224 before the light scattered back out
    // of the lit face left). lbm 0.032 and 0.024. Monte Carlo noise adds about
    // 0.02. Bounds: about measured + 0.03 (0.033–0.034; lbm 0.028–0.036).
    assert!(l1[0].0 < 0.19 && l1[0].1 < 0.22, "spread {:?}", l1[0]);
    assert!(l1[1].0 < 0.06 && l1[1].1 < 0.06, "lbm {:?}", l1[1]);
    // `none` shades its particles isotropically, with no phase function: the comparison
    // tells it apart (measured 1.88: 3.4 times too bright at this angle).
    assert!(l1[2].0 > 1.0 && l1[2].1 > 1.0, "none {:?}", l1[2]);
}

#[test]
fn a_translucent_sphere_lit_from_the_side_glows_into_its_shadow_like_the_monte_carlo_light() {
    // Albedo 0.97, g = 0.6 (the milk-glass scene's medium), optical radius 3 (σ_t = 0.25 per
    // voxel, 12 voxels): the transport mean free path, 1/(σ_s(1 − g)) ≈ 10 voxels, is about the
    // radius, so the light scattered inside fills the sphere and glows on its far side.
    let s = Sphere {
        sigma_t: 0.25,
        albedo: 0.97,
        g: 0.6,
        polar_deg: 70.0,
    };
    let Measured {
        spread,
        frame,
        mc,
        images,
        l1,
    } = s.measure("translucent sphere");
    if let Ok(path) = std::env::var("CAUSTICA_GLOW_PICTURE") {
        // Less noise for the eye than the profiles need: 4096 samples per pixel.
        let views: Vec<(&str, &[f64])> = images.iter().map(|(n, i)| (*n, i.as_slice())).collect();
        save_picture(&path, &monte_carlo(&spread, 4096, 5, u32::MAX, true).mean, &views);
    }

    // The reference's glow is multiple scattering: on the far (shadowed) third of the disc
    // the light of all orders is many times that of single scattering (measured 14).
    let single = monte_carlo(&spread, 64, 2, 1, true);
    let far = |img: &[f64]| {
        let (p, _) = binned(img, 1, |q| {
            let d = q - frame.centre;
            (d.length() < frame.radius && d.dot(frame.along) > frame.radius / 3.0).then_some(0)
        });
        p[0]
    };
    let ratio = far(&mc.mean) / far(&single.mean);
    eprintln!("far third of the disc: all orders / single scattering = {ratio:.2}");
    assert!(ratio > 5.0, "{ratio}");

    // The target is relative L1 < 0.10 on the glow's profile; the spread mode meets it on
    // both profiles. Measured (256 samples per pixel; Monte Carlo noise adds about 0.01):
    // - spread 0.058 along the light, 0.074 radial: within 4 % in the middle along the light,
    //   1.1–1.3 times at the lit rim and 1.35–1.9 at the far rim, where the light is faint;
    //   radially the disc's centre is 6–9 % too dark and its rim 1.2–1.4 times too bright.
    //   The scattered light that has crossed back out of the face its beam entered by leaves
    //   there (the part of the cloud behind that face, the least the face reflects), and what
    //   reaches the medium's sides leaves there, the cloud cut where the medium ends across
    //   the beam and thinned next to that edge (`cut_cloud` in beams.wgsl). (0.094 and 0.143
    //   while what reached the sides went on with the beams, the rims too bright and the
    //   middle too dark; 0.147 and 0.143 while all scattered light went on with the beams;
    //   0.315 and 0.179 when the deposit put the scattered light on the beam instead of at
    //   its centroid, lagging behind: the lit side was 30–35 % too dark and the far side up
    //   to twice too bright.)
    // - lbm 0.276 along, 0.300 radial: the image is about 0.7 of the Monte Carlo's from the
    //   lit side to the far side (a shape close to right, too little light): the lattice
    //   follows diffusion theory with the similarity σ_s(1 − g), which a sphere one transport
    //   mean free path in radius, lit by g = 0.6 light, is too small for.
    // Bounds: the target for the spread mode (0.027–0.042 above the measured values: the
    // noise, and lavapipe against other drivers); lbm measured + 0.03. What would close the
    // lattice's gap: transport beyond diffusion (more directions than six, or the light
    // scattered a few times traced before it diffuses).
    assert!(l1[0].0 < 0.10 && l1[0].1 < 0.10, "spread {:?}", l1[0]);
    assert!(l1[1].0 < 0.31 && l1[1].1 < 0.33, "lbm {:?}", l1[1]);
    // Both modes are closer to the Monte Carlo glow than the image without multiple
    // scattering (measured 0.486 and 0.555).
    for (i, name) in ["spread", "lbm"].iter().enumerate() {
        assert!(l1[i].0 < l1[2].0, "{name} {:?} against none {:?}", l1[i], l1[2]);
    }
}
