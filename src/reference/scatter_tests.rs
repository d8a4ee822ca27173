//! Checks of the Monte Carlo scattering against exact results: the Henyey–Greenstein
//! moments, Beer–Lambert through a heterogeneous medium, energy balance, the mean-path-length
//! invariance of scattering bodies, and the spread of a beam in the near-ballistic regime.

use glam::DVec3;

use super::scatter::{
    beam_widths, first_crossings_by_order, path_moments, plane_flux, plane_flux_rings, run, sample_hg, slab_balance,
    transverse_moment, walk, Centred, Coefficients, Rng, ScatteringMedium, Slab,
};
use crate::transfer::scattering::hg_relative;

#[test]
fn hg_sampling_follows_the_phase_function() {
    let n = 200_000u64;
    for g in [-0.5, 0.0, 0.9] {
        let bins = 20;
        let mut hist = vec![0u64; bins];
        let (mut m1, mut m2) = (0.0, 0.0);
        let mut rng = Rng::for_photon(7, 0);
        for _ in 0..n {
            let d = sample_hg(DVec3::Z, g, &mut rng);
            assert!((d.length() - 1.0).abs() < 1e-12);
            m1 += d.z;
            m2 += d.z * d.z;
            hist[(((d.z + 1.0) * 0.5 * bins as f64) as usize).min(bins - 1)] += 1;
        }
        let (m1, m2) = (m1 / n as f64, m2 / n as f64);
        // E[cos θ] = g, E[cos² θ] = (1 + 2g²)/3 for HG. Tolerance: 5 standard errors
        // (var cos θ ≤ 1/3, var cos² θ ≤ 1/4 over 2·10⁵ samples: ≤ 0.0013 and 0.0011).
        assert!(
            (m1 - g).abs() < 5.0 * (1.0f64 / 3.0 / n as f64).sqrt(),
            "g {g}: mean cosine {m1}"
        );
        assert!(
            (m2 - (1.0 + 2.0 * g * g) / 3.0).abs() < 5.0 * (0.25 / n as f64).sqrt(),
            "g {g}: {m2}"
        );
        // Each bin of cos θ holds ∫ p over the bin: 5 binomial standard errors.
        for (k, &count) in hist.iter().enumerate() {
            let (lo, hi) = (
                -1.0 + 2.0 * k as f64 / bins as f64,
                -1.0 + 2.0 * (k + 1) as f64 / bins as f64,
            );
            let steps = 400;
            let h = (hi - lo) / steps as f64;
            let p: f64 = (0..steps)
                .map(|i| hg_relative(lo + (i as f64 + 0.5) * h, g) * 0.5 * h)
                .sum();
            let sigma = (p * (1.0 - p) / n as f64).sqrt();
            let got = count as f64 / n as f64;
            assert!((got - p).abs() < 5.0 * sigma + 1e-9, "g {g} bin {k}: {got} vs {p}");
        }
    }
}

/// Extinction rising linearly from σ₀ at z = 0 to 2σ₀ at z = L, scattering `albedo` of it
/// (isotropically). Also the view gather's test medium.
pub(super) struct Ramp {
    pub sigma0: f64,
    pub length: f64,
    pub albedo: f64,
}

impl ScatteringMedium for Ramp {
    fn coefficients(&self, p: DVec3) -> Coefficients {
        Coefficients {
            extinction: self.sigma0 * (1.0 + p.z / self.length),
            albedo: self.albedo,
            g: 0.0,
        }
    }

    fn majorant(&self) -> f64 {
        2.0 * self.sigma0
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        (DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, self.length))
    }
}

#[test]
fn delta_tracking_transmits_beer_lambert_through_a_heterogeneous_medium() {
    let medium = Ramp {
        sigma0: 0.5,
        length: 2.0,
        albedo: 0.0,
    };
    let n = 40_000u64;
    let through = run(
        n,
        3,
        || 0u64,
        |_, rng| match walk(&medium, DVec3::new(0.0, 0.0, 0.0), DVec3::Z, rng, |_, _| {}).0 {
            super::scatter::Fate::Left { position, .. } if position.z >= medium.length - 1e-9 => 1,
            _ => 0,
        },
        |a, b| *a += b,
    );
    let t = through as f64 / n as f64;
    // ∫σ dz = σ₀ L (1 + 1/2) = 1.5.
    let exact = (-1.5f64).exp();
    // 4 binomial standard errors (0.0021 at 4·10⁴ photons).
    let sigma = (exact * (1.0 - exact) / n as f64).sqrt();
    assert!((t - exact).abs() < 4.0 * sigma, "{t} vs {exact}");
}

#[test]
fn runs_are_deterministic_and_seeds_independent() {
    let slab = Slab {
        thickness: 2.0,
        half_width: 50.0,
        absorption: 0.1,
        scattering: 1.0,
        g: 0.5,
    };
    let a = slab_balance(&slab, 5000, 11);
    assert_eq!(a, slab_balance(&slab, 5000, 11), "same seed, same bits");
    let b = slab_balance(&slab, 5000, 12);
    assert_ne!(a, b);
    // Different seeds agree within the statistics: 5 binomial standard errors of a difference.
    let sigma = (2.0 * 0.25 / 5000.0f64).sqrt();
    assert!((a.transmitted - b.transmitted).abs() < 5.0 * sigma);
}

#[test]
fn energy_is_conserved_and_absorption_follows_the_track_length() {
    for g in [0.0, 0.9] {
        // Albedo 1: everything that enters leaves. The slab is 100 thicknesses wide, so hardly
        // any light leaves sideways; what does still counts as having left it.
        let slab = Slab {
            thickness: 1.0,
            half_width: 50.0,
            absorption: 0.0,
            scattering: 4.0,
            g,
        };
        let e = slab_balance(&slab, 20_000, 5);
        let out = e.transmitted + e.reflected + e.sideways;
        assert!((out - 1.0).abs() < 0.02, "g {g}: left {out} of 1: {e:?}");
        assert_eq!((e.absorbed, e.lost), (0.0, 0.0));
        assert!(e.reflected > 0.05 && e.transmitted > 0.1, "{e:?}");
    }
    // With absorption a, the expected absorbed fraction is a × the expected track length in
    // the medium (each unit of track is absorbed at rate a): an identity of the analog walk.
    let slab = Slab {
        thickness: 1.0,
        half_width: 50.0,
        absorption: 0.3,
        scattering: 3.0,
        g: 0.7,
    };
    let n = 20_000u64;
    let [absorbed, length, length2] = run(
        n,
        9,
        || [0.0; 3],
        |_, rng| {
            let mut l = 0.0;
            let (fate, _) = walk(&slab, DVec3::ZERO, DVec3::Z, rng, |a, b| l += a.distance(b));
            [(fate == super::scatter::Fate::Absorbed) as u8 as f64, l, l * l]
        },
        |a, b| (0..3).for_each(|k| a[k] += b[k]),
    );
    let (absorbed, length) = (absorbed / n as f64, length / n as f64);
    let expected = slab.absorption * length;
    // Both estimate the same number from the same photons; their difference has a standard
    // error below sqrt((p(1−p) + a² var ℓ) / n); 5 of them.
    let var_l = length2 / n as f64 - length * length;
    let sigma = ((absorbed * (1.0 - absorbed) + slab.absorption.powi(2) * var_l) / n as f64).sqrt();
    assert!((absorbed - expected).abs() < 5.0 * sigma, "{absorbed} vs {expected}");
}

/// A scattering ball of radius R (albedo 1) in a box.
struct Ball {
    radius: f64,
    scattering: f64,
    g: f64,
}

impl ScatteringMedium for Ball {
    fn coefficients(&self, p: DVec3) -> Coefficients {
        let inside = p.length() <= self.radius;
        Coefficients {
            extinction: if inside { self.scattering } else { 0.0 },
            albedo: 1.0,
            g: self.g,
        }
    }

    fn majorant(&self) -> f64 {
        self.scattering
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        (DVec3::splat(-self.radius), DVec3::splat(self.radius))
    }
}

/// Length of the part of segment a→b inside the ball of radius r around the origin.
fn inside_ball(a: DVec3, b: DVec3, r: f64) -> f64 {
    let d = b - a;
    let len = d.length();
    if len == 0.0 {
        return 0.0;
    }
    let u = d / len;
    let bq = a.dot(u);
    let c = a.length_squared() - r * r;
    let disc = bq * bq - c;
    if disc <= 0.0 {
        return 0.0;
    }
    let (t0, t1) = (-bq - disc.sqrt(), -bq + disc.sqrt());
    (t1.min(len) - t0.max(0.0)).max(0.0)
}

#[test]
fn mean_path_length_in_a_scattering_ball_is_four_volume_over_surface() {
    // Blanco & Fournier 2003: under uniform isotropic (Lambertian) incidence, the mean length
    // light travels inside a non-absorbing body of matched index is 4V/S whatever the
    // scattering (4R/3 for a ball): an exact check of the whole walk.
    let r = 1.0;
    for (scattering, g) in [(0.0, 0.0), (3.0, 0.0), (3.0, 0.9)] {
        let ball = Ball {
            radius: r,
            scattering,
            g,
        };
        let n = 20_000u64;
        let [sum, sum2] = run(
            n,
            21,
            || [0.0; 2],
            |_, rng| {
                // A uniform point on the sphere, a cosine-weighted inward direction.
                let z = 1.0 - 2.0 * rng.uniform();
                let phi = std::f64::consts::TAU * rng.uniform();
                let s = (1.0 - z * z).sqrt();
                let normal = DVec3::new(s * phi.cos(), s * phi.sin(), z);
                let (u1, u2) = (rng.uniform(), rng.uniform());
                let (t, b) = normal.any_orthonormal_pair();
                let (sr, a) = (u1.sqrt(), std::f64::consts::TAU * u2);
                let d = (-normal * (1.0 - u1).sqrt() + (t * a.cos() + b * a.sin()) * sr).normalize();
                let mut l = 0.0;
                walk(&ball, normal * r * (1.0 - 1e-12), d, rng, |a, b| {
                    l += inside_ball(a, b, r)
                });
                [l, l * l]
            },
            |a, b| (0..2).for_each(|k| a[k] += b[k]),
        );
        let mean = sum / n as f64;
        let se = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
        // 5 standard errors of the mean (≈1 % of 4R/3 here).
        assert!(
            (mean - 4.0 * r / 3.0).abs() < 5.0 * se,
            "b {scattering} g {g}: {mean} ± {se}"
        );
    }
}

/// A homogeneous medium around the origin that no photon can leave before path `longest`.
fn unbounded(b: f64, g: f64, absorption: f64, longest: f64) -> Centred {
    let size = 1.01 * longest;
    Centred(Slab {
        thickness: 2.0 * size,
        half_width: size,
        absorption,
        scattering: b,
        g,
    })
}

#[test]
fn spread_after_a_path_length_follows_the_exact_moments() {
    // From ballistic to diffusive (b(1 − g)s from 0.2 to 5), Premoze's g = 0.9 and an
    // isotropic medium.
    for (b, g, lengths) in [(1.0, 0.9, [2.0, 10.0, 50.0]), (1.0, 0.0, [0.5, 2.0, 5.0])] {
        let moments = path_moments(&unbounded(b, g, 0.0003, lengths[2]), &lengths, 20_000, 8);
        let k1 = b * (1.0 - g);
        for m in &moments {
            let s = m.path_length;
            // Only absorption (a·s ≤ 1.5 %) ends a walk before s.
            assert!(m.travelling > 0.98, "{m:?}");
            let (r2, z) = (transverse_moment(b, g, s), (1.0 - (-k1 * s).exp()) / k1);
            eprintln!(
                "b {b} g {g} s {s:.1}: E[r²] {:.3} ± {:.3} vs {r2:.3}; E[z] {:.3} ± {:.3} vs {z:.3}",
                m.mean_r2, m.mean_r2_error, m.mean_z, m.mean_z_error
            );
            // 5 standard errors of the Monte Carlo means.
            assert!(
                (m.mean_r2 - r2).abs() < 5.0 * m.mean_r2_error,
                "b {b} g {g} s {s}: E[r²] {} vs {r2}",
                m.mean_r2
            );
            assert!(
                (m.mean_z - z).abs() < 5.0 * m.mean_z_error,
                "b {b} g {g} s {s}: E[z] {} vs {z}",
                m.mean_z
            );
        }
    }
}

#[test]
fn a_beam_keeps_its_unscattered_core_in_premozes_medium() {
    // Premoze's Fig. 4 medium (g = 0.9, a = 0.0003 per mm), light within 0.1 rad of the beam
    // (their Monte Carlo's selection). `caustica bench --scatter` tables its widths against
    // their Eq. 1 and 18; here the part with an exact value: the unscattered core.
    let (a, g) = (0.0003, 0.9);
    for b in [0.05, 0.1] {
        let slab = Slab {
            thickness: 25.0,
            half_width: 200.0,
            absorption: a,
            scattering: b,
            g,
        };
        let depths = [5.0, 10.0, 20.0];
        let widths = beam_widths(&slab, &depths, 0.5, Some(0.1), 20_000, 4);
        for w in &widths {
            // The unscattered light still fills e^{−(a+b)S} of the fluence: 0.02 is ~6
            // binomial standard errors at 2·10⁴ photons.
            let unscattered = w.fluence - w.scattered_fluence;
            assert!((unscattered - (-(a + b) * w.depth).exp()).abs() < 0.02, "{unscattered}");
        }
    }
}

#[test]
fn a_volume_scatters_through_its_transfer_functions() {
    use super::medium::VolumeMedium;
    use super::scatter::{Fate, VolumeScattering};
    use crate::transfer::{Curve, TransferFunctions};
    // A uniform 16³ volume of value 1, opacity 0.1 per voxel: optical depth −ln 0.9 per voxel.
    let n = 16;
    let volume = crate::volume::Volume::new([n; 3], [1.0; 3], vec![1.0; n * n * n]).unwrap();
    let mut tf = TransferFunctions {
        opacity: Curve::constant(0.1),
        ..TransferFunctions::default()
    };
    let photons = 20_000u64;
    let fates = |tf: &TransferFunctions| {
        let medium = VolumeMedium::new(&volume, [0.0, 1.0], tf);
        let scattering = VolumeScattering::new(&medium, 0);
        // From just inside the face at z = −8 (the box spans ±8 plus the half-voxel border),
        // along +z through the middle.
        let start = DVec3::new(0.0, 0.0, -8.49);
        run(
            photons,
            2,
            || [0u64; 3],
            |_, rng| {
                let mut c = [0u64; 3];
                match walk(&scattering, start, DVec3::Z, rng, |_, _| {}).0 {
                    Fate::Left { position, .. } if position.z > 8.4 && position.x.abs() < 1e-9 => c[0] = 1,
                    Fate::Absorbed => c[1] = 1,
                    _ => c[2] = 1,
                }
                c
            },
            |a, b| (0..3).for_each(|k| a[k] += b[k]),
        )
    };
    // No albedo: Beer–Lambert. The opacity curve is constant, so the whole box the medium
    // reports (the 16 voxels and the half-voxel border on each side, z up to 8.5) holds it:
    // 16.99 voxels from the start.
    let [through, absorbed, _] = fates(&tf);
    let t = through as f64 / photons as f64;
    let exact = (0.9f64).powf(16.99);
    // 4 binomial standard errors (0.0026 here).
    let sigma = (exact * (1.0 - exact) / photons as f64).sqrt();
    assert!((t - exact).abs() < 4.0 * sigma, "{t} vs {exact}");
    assert_eq!(absorbed + through, photons);
    // Albedo 1: nothing is absorbed, and light leaves scattered.
    tf.albedo = Some(Curve::constant(1.0));
    tf.anisotropy = Some(Curve::constant(0.5));
    let [through, absorbed, scattered] = fates(&tf);
    assert_eq!(absorbed, 0);
    assert!(scattered > photons / 2, "{through} {scattered}");
}

#[test]
fn spread_moments_advanced_per_plane_match_the_walk() {
    use crate::transfer::scattering::SpreadMoments;
    // Homogeneous: the per-plane recurrence reproduces the closed form whatever the plane
    // spacing. Bound 10⁻³: RK4 sub-steps of k·h ≤ 0.05 leave ~(k·h)²/20 ≈ 10⁻⁴ relative; the
    // closed form's midpoint rule ~10⁻⁸.
    for (b, g) in [(1.0, 0.9), (0.5, 0.0), (2.0, 0.6)] {
        for ds in [0.1, 1.0, 4.0] {
            let mut m = SpreadMoments::default();
            let mut s = 0.0;
            for _ in 0..10 {
                m.step(b, g, ds);
                s += ds;
                let exact = transverse_moment(b, g, s);
                assert!(
                    (m.r2 / exact - 1.0).abs() < 1e-3,
                    "b {b} g {g} ds {ds} s {s}: {} vs {exact}",
                    m.r2
                );
            }
        }
    }
    // Scattering that changes along the path (b = 1, g = 0.95 for the first 4 units, then
    // b = 3, g = 0.5): a walk in path length (free flights at the local b, resampled at the
    // change, which the exponential's lack of memory allows; HG turns at the local g)
    // against the recurrence stepped with the coefficients in force.
    let layers = |s: f64| if s < 4.0 { (1.0, 0.95) } else { (3.0, 0.5) };
    let lengths = [2.0, 4.0, 6.0, 8.0];
    let n = 20_000u64;
    let sums = run(
        n,
        13,
        || [[0.0f64; 2]; 4],
        |_, rng| {
            let (mut p, mut d, mut s) = (DVec3::ZERO, DVec3::Z, 0.0);
            let mut out = [[0.0; 2]; 4];
            let mut next = 0;
            while next < lengths.len() {
                let (b, g) = layers(s);
                let boundary = if s < 4.0 { 4.0 } else { f64::INFINITY };
                let t = -(1.0 - rng.uniform()).ln() / b;
                let stop = (s + t).min(boundary);
                while next < lengths.len() && lengths[next] <= stop {
                    let q = p + d * (lengths[next] - s);
                    let r2 = q.x * q.x + q.y * q.y;
                    out[next] = [r2, r2 * r2];
                    next += 1;
                }
                p += d * (stop - s);
                if s + t < boundary {
                    d = sample_hg(d, g, rng);
                }
                s = stop;
            }
            out
        },
        |a, b| (0..4).for_each(|k| (0..2).for_each(|j| a[k][j] += b[k][j])),
    );
    let mut m = SpreadMoments::default();
    let mut s = 0.0;
    for (k, &target) in lengths.iter().enumerate() {
        while s < target - 1e-12 {
            let (b, g) = layers(s);
            let ds = 0.5f64.min(target - s);
            m.step(b, g, ds);
            s += ds;
        }
        let mean = sums[k][0] / n as f64;
        let se = ((sums[k][1] / n as f64 - mean * mean) / n as f64).sqrt();
        // 5 standard errors of the Monte Carlo mean.
        assert!(
            (mean - m.r2).abs() < 5.0 * se,
            "s {target}: walk {mean} ± {se}, recurrence {}",
            m.r2
        );
    }
}

#[test]
fn the_fourth_moment_across_the_beam_matches_the_walk() {
    use crate::transfer::scattering::SpreadMoments;
    // E[|r⊥|⁴] of a pencil beam after path s, from walks, against the moment recurrence
    // (per-plane steps of 0.5): Premoze's g = 0.9 from ballistic to diffusive, the glow
    // sphere's medium (g = 0.6) and an isotropic one. Within 5 standard errors of the walks'
    // means, plus 0.5 % for the recurrence's RK4 sub-steps (k·h ≤ 0.05: ~10⁻⁴ per step,
    // summed over up to a thousand).
    for (b, g, lengths) in [
        (0.05, 0.9, [16.0, 32.0, 48.0]),
        (1.0, 0.9, [2.0, 10.0, 30.0]),
        (0.25, 0.6, [5.0, 10.0, 20.0]),
        (1.0, 0.0, [0.5, 2.0, 5.0]),
    ] {
        let walks = path_moments(&unbounded(b, g, 0.0, lengths[2]), &lengths, 40_000, 21);
        let mut m = SpreadMoments::default();
        let mut s = 0.0;
        for w in &walks {
            while s < w.path_length - 1e-12 {
                let ds = 0.5f64.min(w.path_length - s);
                m.step(b, g, ds);
                s += ds;
            }
            eprintln!(
                "b {b} g {g} s {s}: E[r⁴] walk {:.4} ± {:.4}, recurrence {:.4}; scattered kurtosis {:.3}",
                w.mean_r4,
                w.mean_r4_error,
                m.r4,
                m.scattered_kurtosis()
            );
            assert!(
                (w.mean_r4 - m.r4).abs() < 5.0 * w.mean_r4_error + 0.005 * m.r4,
                "b {b} g {g} s {s}: walk {} ± {}, recurrence {}",
                w.mean_r4,
                w.mean_r4_error,
                m.r4
            );
        }
    }
    // A Gaussian cloud's kurtosis is 1; HG's forward peak and wide tail make the light of a
    // narrow beam in Premoze's medium far from it, the glow sphere's medium hardly.
    let kurtosis = |b: f64, g: f64, s: f64| {
        let mut m = SpreadMoments::default();
        m.step(b, g, s);
        m.scattered_kurtosis()
    };
    assert!(kurtosis(0.05, 0.9, 16.0) > 2.0);
    assert!((kurtosis(0.25, 0.6, 10.0) - 1.0).abs() < 0.2);
}

#[test]
fn the_lag_moments_along_the_beam_match_the_walk() {
    use crate::transfer::scattering::SpreadMoments;
    // A pencil beam in a homogeneous medium: the lag w = s − z of each photon behind the beam
    // after path s, its mean and mean square from walks in path length against the moment
    // recurrence (per-plane steps of 0.5), within 5 standard errors of the walks' means.
    let lengths = [1.0, 3.0, 6.0, 10.0];
    let n = 20_000u64;
    for (b, g) in [(1.0, 0.6), (0.5, 0.9), (2.0, 0.0)] {
        let sums = run(
            n,
            17,
            || [[0.0f64; 4]; 4],
            |_, rng| {
                let (mut p, mut d, mut s) = (DVec3::ZERO, DVec3::Z, 0.0);
                let mut out = [[0.0; 4]; 4];
                let mut next = 0;
                while next < lengths.len() {
                    let t = -(1.0 - rng.uniform()).ln() / b;
                    while next < lengths.len() && lengths[next] <= s + t {
                        let w = lengths[next] - (p + d * (lengths[next] - s)).z;
                        out[next] = [w, w * w, w * w * w * w, 0.0];
                        next += 1;
                    }
                    p += d * t;
                    s += t;
                    d = sample_hg(d, g, rng);
                }
                out
            },
            |a, c| (0..4).for_each(|k| (0..4).for_each(|j| a[k][j] += c[k][j])),
        );
        let mut m = SpreadMoments::default();
        let mut s = 0.0;
        for (k, &target) in lengths.iter().enumerate() {
            while s < target - 1e-12 {
                let ds = 0.5f64.min(target - s);
                m.step(b, g, ds);
                s += ds;
            }
            let [w, w2, w4, _] = sums[k].map(|x| x / n as f64);
            let se_w = ((w2 - w * w) / n as f64).sqrt();
            let se_w2 = ((w4 - w2 * w2) / n as f64).sqrt();
            assert!(
                (w - m.lag).abs() < 5.0 * se_w,
                "b {b} g {g} s {target}: E[w] walk {w} ± {se_w}, moments {}",
                m.lag
            );
            assert!(
                (w2 - m.lag2).abs() < 5.0 * se_w2,
                "b {b} g {g} s {target}: E[w²] walk {w2} ± {se_w2}, moments {}",
                m.lag2
            );
        }
    }
}

#[test]
fn net_flux_through_every_plane_of_a_conservative_slab_is_what_it_transmits() {
    // Albedo 1, no absorption: what crosses a plane forward and does not come back is what
    // leaves through the far face, at every depth (the flux has no sources or sinks). The
    // slab is wide enough that hardly any light leaves sideways.
    let slab = Slab {
        thickness: 2.0,
        half_width: 100.0,
        absorption: 0.0,
        scattering: 2.0,
        g: 0.8,
    };
    let n = 20_000;
    let e = slab_balance(&slab, n, 3);
    let flux = plane_flux(&slab, &[0.5, 1.0, 1.5, 1.999], 1e9, n, 3);
    // Same photons, so the estimates share most of their noise; each is a fraction of n
    // photons (σ ≤ 0.5/√n ≈ 0.0035 per estimate): 0.01 covers them.
    for f in &flux {
        assert!(
            (f.flux - e.transmitted).abs() < 0.01,
            "{f:?} vs transmitted {}",
            e.transmitted
        );
        // Light that comes back crosses planes far from the axis: near the entry face the
        // net r² can be negative; it is finite and known to its error.
        assert!(f.mean_r2.is_finite() && f.mean_r2_error.is_finite(), "{f:?}");
    }
    // Without scattering the beam stays on its axis and thins by Beer–Lambert: exactly, up
    // to the counting noise of n photons (5σ).
    let clear = Slab {
        scattering: 0.0,
        absorption: 0.5,
        ..slab
    };
    let f = plane_flux(&clear, &[1.0], 1e9, n, 4)[0];
    let t = (-0.5f64).exp();
    let sigma = (t * (1.0 - t) / n as f64).sqrt();
    assert!((f.flux - t).abs() < 5.0 * sigma && f.mean_r2 == 0.0, "{f:?}");
}

#[test]
fn a_wide_beam_through_a_clear_slab_fills_its_rings_by_their_area() {
    // No scattering: the beam of radius R keeps its disc, thinned by Beer–Lambert, so ring k
    // (width R/4 out to R) holds the fraction (2k + 1)/16 of the light, the rings beyond R
    // none, and the mean r² is R²/2. Each ring's estimate is a fraction of n photons
    // (σ ≤ 0.5/√n ≈ 0.0035); 5σ bounds them. The mean r² has a standard error of
    // R²/√(12·0.6n) ≈ 0.5 % of R²/2 (var r² = R⁴/12 over the 60 % transmitted): 3 % is 6σ. The pencil beam (R = 0) with rings draws the
    // same walks as `plane_flux`: the same numbers.
    let clear = Slab {
        thickness: 2.0,
        half_width: 100.0,
        absorption: 0.5,
        scattering: 0.0,
        g: 0.0,
    };
    let n = 20_000;
    let r = 2.0;
    let (flux, rings) = plane_flux_rings(&clear, &[1.0], 2.0 * r, 8, r, n, 4);
    let t = (-0.5f64).exp();
    let sigma = 0.5 / (n as f64).sqrt();
    for (k, &ring) in rings[0].iter().enumerate() {
        let expected = if k < 4 { t * (2 * k + 1) as f64 / 16.0 } else { 0.0 };
        assert!((ring - expected).abs() < 5.0 * sigma, "ring {k}: {ring} vs {expected}");
    }
    assert!((rings[0].iter().sum::<f64>() - flux[0].flux).abs() < 1e-12);
    assert!((flux[0].mean_r2 / (0.5 * r * r) - 1.0).abs() < 0.03, "{:?}", flux[0]);
    let scattering = Slab {
        scattering: 0.5,
        g: 0.9,
        ..clear
    };
    let (with_rings, _) = plane_flux_rings(&scattering, &[0.5, 1.5], 3.0, 6, 0.0, n, 5);
    assert_eq!(with_rings, plane_flux(&scattering, &[0.5, 1.5], 3.0, n, 5));
}

#[test]
fn first_crossings_split_by_order_keep_the_unscattered_beam_on_its_axis() {
    // A pencil beam into a forward-scattering slab: the light that first crosses the plane at
    // depth 16 without having scattered is Beer–Lambert's e^(−σ_t z), on the axis (r² = 0);
    // the rest has scattered and lies off it. Binomial noise of n photons: 5σ.
    let slab = Slab {
        thickness: 60.0,
        half_width: 1000.0,
        absorption: 0.002,
        scattering: 0.1,
        g: 0.9,
    };
    let n = 20_000;
    let z = 16.0;
    let orders = first_crossings_by_order(&slab, z, 1e9, 4, n, 5);
    assert_eq!(orders.len(), 4);
    let t = (-(slab.absorption + slab.scattering) * z).exp();
    let sigma = (t * (1.0 - t) / n as f64).sqrt();
    assert!((orders[0].share - t).abs() < 5.0 * sigma, "{orders:?} vs {t}");
    assert_eq!(orders[0].r2, 0.0);
    // Unscattered light has come straight: its path is the depth (to rounding); scattered
    // light has come further.
    assert!((orders[0].path / orders[0].share - z).abs() < 1e-9, "{orders:?}");
    assert!(orders[1..].iter().all(|o| o.path / o.share > z), "{orders:?}");
    assert!(orders[1..].iter().all(|o| o.share > 0.0 && o.r2 > 0.0), "{orders:?}");
    // Every photon is counted once at most: what does not cross was absorbed or turned back.
    let crossing: f64 = orders.iter().map(|o| o.share).sum();
    assert!(crossing <= 1.0 && crossing > t, "{crossing}");
    // The same photons, windowed to 2 voxels: nothing scattered far is counted, the axis is.
    // Every crossing counted then has r² ≤ 2², so each order's Σr² is at most 4 times its
    // share (1e-12: the rounding of the sums).
    let near = first_crossings_by_order(&slab, z, 2.0, 4, n, 5);
    assert_eq!(near[0].share, orders[0].share);
    assert!(near
        .iter()
        .zip(&orders)
        .all(|(a, b)| a.share <= b.share && a.r2 <= 4.0 * a.share + 1e-12));
}
