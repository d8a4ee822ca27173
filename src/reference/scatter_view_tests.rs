//! Checks of the Monte Carlo view gather against exact results: single scattering in a
//! homogeneous slab (closed form), ratio-tracking transmittance (Beer–Lambert), and the light
//! a conservative slab reflects against the forward photon walks' count of it.

use glam::DVec3;

use super::scatter::{slab_balance, Rng, Slab};
use super::scatter_tests::Ramp;
use super::scatter_view::{sample_radiance, transmittance, GatherLight, GatherSettings};
use crate::transfer::scattering::hg_relative;

/// Mean and standard error of `n` samples of `f` (sample i from its own generator).
fn estimate(n: u64, seed: u64, mut f: impl FnMut(&mut Rng) -> f64) -> (f64, f64) {
    let (mut s1, mut s2) = (0.0, 0.0);
    for i in 0..n {
        let v = f(&mut Rng::for_photon(seed, i));
        s1 += v;
        s2 += v * v;
    }
    let mean = s1 / n as f64;
    let var = (s2 / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}

#[test]
fn single_scattering_in_a_slab_is_the_closed_form() {
    // A view ray along +z into a slab 0 ≤ z ≤ D, the light travelling at θ to +z. A particle at
    // depth s sees the light after s/μ (μ = cos θ) of medium and is seen through s, so the
    // single-scattered radiance (relative to isotropic scattering of unit irradiance) is
    // ω·4πp(cos Θ)·σ ∫₀ᴰ e^{−σs(1 + 1/μ)} ds = ω·4πp·(1 − e^{−τ(1 + 1/μ)})/(1 + 1/μ),
    // with τ = σD and cos Θ = l·(−z) = −μ. Shading the non-scattering fraction as the GPU
    // does adds (1 − ω) of the (unscattered) light, isotropically: ω·4πp becomes
    // ω·4πp + 1 − ω.
    for (g, theta_deg, absorption, scattering, diffuse_rest) in [
        (0.6, 60.0f64, 0.1, 0.9, false),
        (-0.3, 30.0, 0.5, 1.5, false),
        (0.6, 60.0, 0.4, 0.6, true),
    ] {
        let slab = Slab {
            thickness: 1.0,
            half_width: 1000.0,
            absorption,
            scattering,
            g,
        };
        let mu = theta_deg.to_radians().cos();
        let light = GatherLight {
            direction: DVec3::new(theta_deg.to_radians().sin(), 0.0, mu),
            irradiance: 2.0,
        };
        let sigma = absorption + scattering;
        let omega = scattering / sigma;
        let k = 1.0 + 1.0 / mu;
        let seen = omega * hg_relative(-mu, g) + if diffuse_rest { 1.0 - omega } else { 0.0 };
        let exact = light.irradiance * seen * (1.0 - (-sigma * k).exp()) / k;
        let settings = GatherSettings {
            max_order: 1,
            diffuse_rest,
            ..GatherSettings::new(1, 0, 1)
        };
        let (mean, se) = estimate(40_000, 5, |rng| {
            sample_radiance(
                &slab,
                &light,
                DVec3::new(0.0, 0.0, -1.0),
                DVec3::Z,
                0.0,
                &settings,
                &|_| 1.0,
                rng,
            )
        });
        eprintln!("g {g}, diffuse rest {diffuse_rest}: single scattering {mean:.5} ± {se:.5}, exact {exact:.5}");
        // 4 standard errors (the estimate's own, 0.5–0.8 % of it at 4·10⁴ samples).
        assert!((mean - exact).abs() < 4.0 * se, "g {g}: {mean} ± {se} vs {exact}");
        assert!(se < 0.02 * exact, "{se}");
    }
}

#[test]
fn ratio_tracking_transmits_beer_lambert_through_a_heterogeneous_medium() {
    let medium = Ramp {
        sigma0: 1.5,
        length: 2.0,
        albedo: 0.5,
    };
    // ∫σ dz = σ₀ L (1 + 1/2) = 4.5 along the axis; e^{−4.5} ≈ 0.011 reaches the roulette.
    let exact = (-4.5f64).exp();
    let (mean, se) = estimate(20_000, 9, |rng| transmittance(&medium, DVec3::ZERO, DVec3::Z, rng));
    eprintln!("transmittance {mean:.5} ± {se:.5}, exact {exact:.5}");
    // 4 standard errors.
    assert!(
        (mean - exact).abs() < 4.0 * se && se < 0.05 * exact,
        "{mean} ± {se} vs {exact}"
    );
}

#[test]
fn a_conservative_slab_reflects_what_the_photon_walks_reflect() {
    // Light falling straight onto a slab (albedo 1, many scatterings) that is wide against
    // its thickness: the reflected flux per unit area, relative to the incident one, is
    // ∫ L cos θ dω / E = (1/4) E_cos[L_rel] for view directions drawn with density cos θ/π
    // (L_rel = 4πL/E, the gather's unit). The forward walks of a pencil beam count the same
    // fraction (a plane wave is a sum of pencils), independently: analog photons, no
    // next-event estimation, no roulette.
    let slab = Slab {
        thickness: 2.0,
        half_width: 100.0,
        absorption: 0.0,
        scattering: 1.5,
        g: 0.7,
    };
    let light = GatherLight {
        direction: DVec3::Z,
        irradiance: 1.0,
    };
    let n = 40_000;
    let all = GatherSettings::new(1, 0, 1);
    let (mean, se) = estimate(n, 17, |rng| {
        let (u1, u2) = (rng.uniform(), rng.uniform());
        let cos = u1.sqrt();
        let sin = (1.0 - u1).sqrt();
        let phi = std::f64::consts::TAU * u2;
        let d = DVec3::new(sin * phi.cos(), sin * phi.sin(), cos);
        sample_radiance(&slab, &light, -d, d, 0.0, &all, &|_| 1.0, rng) / 4.0
    });
    let walks = slab_balance(&slab, n, 18);
    let walk_se = (walks.reflected * (1.0 - walks.reflected) / n as f64).sqrt();
    eprintln!(
        "reflected: gather {mean:.5} ± {se:.5}, photon walks {:.5} ± {walk_se:.5}",
        walks.reflected
    );
    // 4 standard errors of the difference of two independent estimates.
    let bound = 4.0 * (se * se + walk_se * walk_se).sqrt();
    assert!((mean - walks.reflected).abs() < bound, "{mean} vs {}", walks.reflected);
    assert!(walks.reflected > 0.1, "a slab that reflects: {walks:?}");
}
