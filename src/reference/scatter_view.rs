//! Monte Carlo view gather: the radiance a camera sees from a scattering medium lit by one
//! distant light, by volumetric path tracing from the eye. Per sample, delta tracking finds
//! the real collisions along the view ray and then along the path; at each one, next-event
//! estimation asks the light (transmittance by ratio tracking) through the Henyey–Greenstein
//! phase function, and the path goes on in a direction drawn from it. Each collision weighs the
//! path by the albedo ω; Russian roulette ends weak paths without bias.
//!
//! Units are the GPU image's: the light's irradiance is its colour × intensity, and a particle
//! scatters relative to an isotropic one (4π·p, so a thin layer of optical depth τ, albedo 1,
//! g = 0 reads τ). The particle colour weighs the light the first collision sends to the eye,
//! as the GPU's view shades its particles. The environment lights nothing: only view rays that
//! cross the medium without a collision see it (a uniform colour). Flights are straight (no
//! refraction) and the light is hard (its softness is not modelled).
//!
//! Deterministic: sample s of pixel i draws from `Rng::for_photon(seed, i·spp + s)`, and pixels
//! are independent, so the image is the same on any number of threads.

use glam::DVec3;
use rayon::prelude::*;

use super::medium::{Medium, SceneOptics, VolumeMedium};
use super::rk4::box_interval;
use super::scatter::{
    exit_distance, sample_hg, Coefficients, Rng, ScatteringMedium, VolumeScattering, MAX_SCATTERINGS,
};
use super::view::{dvec, CameraRays};
use super::ReferenceError;
use crate::scene::{light_direction, Environment, PreparedScene, ViewSetup};
use crate::transfer::scattering::hg_relative;

/// Paths whose weight falls below this play Russian roulette (survive with probability ½,
/// weight doubled).
const ROULETTE_WEIGHT: f64 = 0.2;

/// How the gather samples.
#[derive(Clone, Copy, Debug)]
pub struct GatherSettings {
    pub samples_per_pixel: u32,
    pub seed: u64,
    /// Scattering orders counted: 1 is single scattering; `u32::MAX` all of them.
    pub max_order: u32,
    /// Colour channel (0 red, 1 green, 2 blue).
    pub channel: usize,
    /// Shade the fraction 1 − ω of the particles the view sees, which scatters nothing in the
    /// transport, as the GPU renders non-scattering particles: colour × all the light there
    /// (the unscattered light and the scattered fluence), isotropically. Off: the physical
    /// radiance, in which absorbed light is gone.
    pub diffuse_rest: bool,
}

impl GatherSettings {
    /// `samples_per_pixel` samples of all scattering orders, physical shading.
    pub fn new(samples_per_pixel: u32, seed: u64, channel: usize) -> GatherSettings {
        GatherSettings {
            samples_per_pixel,
            seed,
            max_order: u32::MAX,
            channel,
            diffuse_rest: false,
        }
    }
}

/// A distant light for one channel: where its light travels (unit) and its irradiance.
#[derive(Clone, Copy, Debug)]
pub struct GatherLight {
    pub direction: DVec3,
    pub irradiance: f64,
}

/// The next real collision along `p + t·d` (p inside the box) before the path leaves the box,
/// by delta tracking, with the medium there.
fn next_collision<M: ScatteringMedium + ?Sized>(
    medium: &M,
    p: DVec3,
    d: DVec3,
    rng: &mut Rng,
) -> Option<(DVec3, Coefficients)> {
    let bounds = medium.bounds();
    let majorant = medium.majorant();
    if majorant <= 0.0 {
        return None;
    }
    let to_exit = exit_distance(p, d, bounds);
    let mut t = 0.0;
    loop {
        t += -(1.0 - rng.uniform()).ln() / majorant;
        if t >= to_exit {
            return None;
        }
        let x = p + d * t;
        let c = medium.coefficients(x);
        if rng.uniform() * majorant < c.extinction {
            return Some((x, c));
        }
    }
}

/// Transmittance from `p` (inside the box) along unit `d` out of the box, by ratio tracking
/// (an unbiased estimate: the product of the null-collision probabilities at tentative
/// collisions), with Russian roulette once it is small.
pub fn transmittance<M: ScatteringMedium + ?Sized>(medium: &M, p: DVec3, d: DVec3, rng: &mut Rng) -> f64 {
    let majorant = medium.majorant();
    if majorant <= 0.0 {
        return 1.0;
    }
    let to_exit = exit_distance(p, d, medium.bounds());
    let (mut t, mut s) = (1.0, 0.0);
    loop {
        s += -(1.0 - rng.uniform()).ln() / majorant;
        if s >= to_exit {
            return t;
        }
        t *= (1.0 - medium.coefficients(p + d * s).extinction / majorant).max(0.0);
        if t < 1e-3 {
            if t == 0.0 || rng.uniform() < 0.5 {
                return 0.0;
            }
            t *= 2.0;
        }
    }
}

/// A uniformly distributed unit direction.
fn uniform_direction(rng: &mut Rng) -> DVec3 {
    let z = 1.0 - 2.0 * rng.uniform();
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * rng.uniform();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// One sample of the radiance arriving at `o` against the unit direction `d` (the view ray
/// from `o` along `d`): light scattered towards `o` by the medium, plus `background` if the ray
/// crosses the medium without a collision. `colour` weighs the first collision (the particle
/// the view sees); `settings` gives the orders counted and the shading of the particles'
/// non-scattering fraction (its samples and seed are not used here).
#[allow(clippy::too_many_arguments)]
pub fn sample_radiance<M: ScatteringMedium + ?Sized>(
    medium: &M,
    light: &GatherLight,
    o: DVec3,
    d: DVec3,
    background: f64,
    settings: &GatherSettings,
    colour: &dyn Fn(DVec3) -> f64,
    rng: &mut Rng,
) -> f64 {
    let max_order = settings.max_order;
    let (lo, hi) = medium.bounds();
    let Some((t0, _)) = box_interval(o, d, lo, hi) else {
        return background;
    };
    let (mut p, mut d) = (o + d * t0, d);
    let (mut weight, mut sum, mut order) = (1.0, 0.0, 0u32);
    while let Some((x, c)) = next_collision(medium, p, d, rng) {
        order += 1;
        if order == 1 {
            weight *= colour(x);
            if settings.diffuse_rest && c.albedo < 1.0 {
                // The unscattered light, isotropically, and the scattered fluence: the mean
                // over directions of the (scattered) radiance arriving at x, one direction per
                // sample (no diffuse shading further down that path).
                let mut seen = light.irradiance * transmittance(medium, x, -light.direction, rng);
                if max_order > 1 {
                    let inner = GatherSettings {
                        diffuse_rest: false,
                        max_order: max_order - 1,
                        ..*settings
                    };
                    let back = uniform_direction(rng);
                    seen += sample_radiance(medium, light, x, back, 0.0, &inner, &|_| 1.0, rng);
                }
                sum += weight * (1.0 - c.albedo) * seen;
            }
        }
        weight *= c.albedo;
        if weight <= 0.0 {
            return sum;
        }
        // Next-event estimation: the light arriving at x along its direction, turned towards
        // where the path came from (−d).
        let phase = hg_relative(light.direction.dot(-d), c.g);
        sum += weight * phase * light.irradiance * transmittance(medium, x, -light.direction, rng);
        if order >= max_order || order > MAX_SCATTERINGS {
            return sum;
        }
        // Light reaching x from direction d' is scattered into −d with p(d'·d) (HG depends on
        // the cosine alone): the path goes on along a direction drawn about d.
        d = sample_hg(d, c.g, rng);
        p = x;
        if weight < ROULETTE_WEIGHT {
            if rng.uniform() < 0.5 {
                return sum;
            }
            weight *= 2.0;
        }
    }
    if order == 0 {
        background
    } else {
        sum
    }
}

/// A Monte Carlo image of one channel: per pixel, the mean of the samples and its standard
/// error.
#[derive(Clone, Debug)]
pub struct GatherImage {
    pub width: usize,
    pub height: usize,
    pub mean: Vec<f64>,
    pub std_error: Vec<f64>,
    pub samples_per_pixel: u32,
}

/// The scene's image (one channel, rays through the pixel centres) by the Monte Carlo view
/// gather. The scene must not refract and its environment must be a uniform colour.
pub fn gather(
    prepared: &PreparedScene,
    width: u32,
    height: u32,
    settings: &GatherSettings,
) -> Result<GatherImage, ReferenceError> {
    let scene = &prepared.scene;
    let vol = &prepared.volume;
    if SceneOptics::of(scene, &prepared.tf).refraction {
        return Err(ReferenceError::Setup(
            "the Monte Carlo gather follows straight paths: switch refraction off".into(),
        ));
    }
    let Environment::Color { color } = &scene.environment else {
        return Err(ReferenceError::Setup(
            "the Monte Carlo gather needs a uniform background colour (environment = color)".into(),
        ));
    };
    let c = settings.channel.min(2);
    let background = color[c] as f64;
    let view = ViewSetup::new(scene, vol.dims, vol.spacing, width, height).map_err(ReferenceError::Setup)?;
    let rotation = glam::Mat3::from_mat4(view.world_from_view);
    let light = GatherLight {
        direction: dvec(rotation * light_direction(&scene.light)).normalize(),
        irradiance: (scene.light.color[c] * scene.light.intensity) as f64,
    };
    let volume_medium = VolumeMedium::for_scene(prepared);
    let medium = VolumeScattering::new(&volume_medium, c);
    let camera = CameraRays::new(scene, &view);
    let spp = settings.samples_per_pixel.max(1) as u64;
    let pixels: Vec<(f64, f64)> = (0..(width as u64 * height as u64))
        .into_par_iter()
        .map(|i| {
            let (px, py) = (i % width as u64, i / width as u64);
            let (o, d) = camera.ray(px as f64 + 0.5, py as f64 + 0.5);
            let (mut s1, mut s2) = (0.0, 0.0);
            for s in 0..spp {
                let mut rng = Rng::for_photon(settings.seed, i * spp + s);
                let colour = |x: DVec3| volume_medium.optics(x).color[c];
                let v = sample_radiance(&medium, &light, o, d, background, settings, &colour, &mut rng);
                s1 += v;
                s2 += v * v;
            }
            let n = spp as f64;
            let mean = s1 / n;
            let var = if spp > 1 {
                ((s2 - n * mean * mean) / (n - 1.0)).max(0.0)
            } else {
                0.0
            };
            (mean, (var / n).sqrt())
        })
        .collect();
    Ok(GatherImage {
        width: width as usize,
        height: height as usize,
        mean: pixels.iter().map(|p| p.0).collect(),
        std_error: pixels.iter().map(|p| p.1).collect(),
        samples_per_pixel: spp as u32,
    })
}
