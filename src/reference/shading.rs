//! Highlights: the dielectric Fresnel reflectance and the Cook–Torrance (GGX) term, in f64,
//! as `shaders/optics.wgsl` defines them, and where along a view ray an interface reflects.

use glam::DVec3;

use super::medium::{Medium, VolumeMedium};

/// Index differences below this fraction count as no interface (as the GPU's
/// FRESNEL_MIN_RELATIVE_STEP): a last-bit difference must not reach the total-internal-
/// reflection branch.
pub const FRESNEL_MIN_RELATIVE_STEP: f64 = 1e-5;

/// Smallest GGX width α = roughness² (as the GPU's MIN_GGX_ALPHA): at α = 0 the distribution
/// is a delta that no sampled ray can see.
pub const MIN_GGX_ALPHA: f64 = 1e-3;

/// How far (voxels) the two sides of an interface are looked for along its normal, and the
/// step of that search. Far enough to leave the 1.5–3-voxel surface ramps of the built-in
/// scenes; a wall thinner than that gives its peak index instead of a plateau.
pub const INTERFACE_SEARCH_VOXELS: f64 = 3.0;
const INTERFACE_SEARCH_STEP_VOXELS: f64 = 0.25;

/// Unpolarised Fresnel reflectance from index `n1` into `n2` at incidence cosine `cos_i`;
/// 0 for equal indices, 1 under total internal reflection.
pub fn fresnel_dielectric(cos_i: f64, n1: f64, n2: f64) -> f64 {
    if (n1 - n2).abs() <= FRESNEL_MIN_RELATIVE_STEP * n1.max(n2) {
        return 0.0;
    }
    let c = cos_i.clamp(0.0, 1.0);
    let eta = n1 / n2;
    let sin_t2 = eta * eta * (1.0 - c * c);
    if sin_t2 >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t2).sqrt();
    let rs = (n1 * c - n2 * cos_t) / (n1 * c + n2 * cos_t);
    let rp = (n1 * cos_t - n2 * c) / (n1 * cos_t + n2 * c);
    0.5 * (rs * rs + rp * rp)
}

/// GGX normal distribution of width `a` at n·h.
pub fn ggx(nh: f64, a: f64) -> f64 {
    let a2 = a * a;
    let denom = nh * nh * (a2 - 1.0) + 1.0;
    a2 / (std::f64::consts::PI * denom * denom)
}

/// Cook–Torrance with a GGX distribution and Smith–Schlick geometry, times cos(n, l), without
/// the Fresnel factor; `n`, `l` (towards the light) and `v` (towards the viewer) unit.
pub fn cook_torrance(n: DVec3, l: DVec3, v: DVec3, roughness: f64) -> f64 {
    let (nl, nv) = (n.dot(l), n.dot(v));
    if nl <= 0.0 || nv <= 0.0 {
        return 0.0;
    }
    let h = (l + v).normalize();
    let a = (roughness * roughness).max(MIN_GGX_ALPHA);
    let k = a * 0.5;
    let g = (nl / (nl * (1.0 - k) + k)) * (nv / (nv * (1.0 - k) + k));
    ggx(n.dot(h).max(0.0), a) * g / (4.0 * nv)
}

/// The indices on the two sides of the interface through `p` with unit normal `n`: walking
/// from `p` along +n and along −n, each while η keeps moving the way it started (its plateau,
/// or a thin wall's peak), at most [`INTERFACE_SEARCH_VOXELS`].
pub fn interface_sides(medium: &VolumeMedium, p: DVec3, n: DVec3) -> (f64, f64) {
    let voxel = medium.voxel_length();
    let step = INTERFACE_SEARCH_STEP_VOXELS * voxel;
    let steps = (INTERFACE_SEARCH_VOXELS / INTERFACE_SEARCH_STEP_VOXELS).round() as usize;
    let centre = medium.eta(p);
    let side = |dir: DVec3| {
        let mut last = centre;
        let mut trend = 0.0f64;
        for k in 1..=steps {
            let e = medium.eta(p + dir * (step * k as f64));
            let change = e - last;
            if trend == 0.0 {
                trend = change.signum();
            }
            // Stop on a plateau or where η turns back.
            if change == 0.0 || change * trend < 0.0 {
                break;
            }
            last = e;
        }
        last
    };
    (side(n), side(-n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_at_normal_incidence_brewster_and_beyond_the_critical_angle() {
        let r0 = fresnel_dielectric(1.0, 1.0, 1.5);
        assert!((r0 - 0.04).abs() < 1e-12, "{r0}");
        // Same from the dense side at normal incidence.
        assert!((fresnel_dielectric(1.0, 1.5, 1.0) - 0.04).abs() < 1e-12);
        // Brewster: rp = 0, so F = rs²/2 with rs = (cos i − n cos t)/(cos i + n cos t).
        let b = 1.5f64.atan();
        let (ci, ct) = (b.cos(), (b.sin() / 1.5).asin().cos());
        let rs = (ci - 1.5 * ct) / (ci + 1.5 * ct);
        assert!((fresnel_dielectric(ci, 1.0, 1.5) - 0.5 * rs * rs).abs() < 1e-12);
        // Past the critical angle asin(1/1.5) = 41.8° from the dense side: total reflection.
        assert_eq!(fresnel_dielectric(45f64.to_radians().cos(), 1.5, 1.0), 1.0);
        assert_eq!(fresnel_dielectric(0.3, 1.3, 1.3), 0.0);
    }

    #[test]
    fn ggx_is_normalised_over_the_hemisphere() {
        // ∫ D(h) (n·h) dω = 1 for every width.
        for a in [0.05, 0.2, 0.6] {
            let steps = 200_000;
            let mut sum = 0.0;
            for k in 0..steps {
                let theta = (k as f64 + 0.5) / steps as f64 * std::f64::consts::FRAC_PI_2;
                let c = theta.cos();
                sum += ggx(c, a) * c * theta.sin() * std::f64::consts::TAU * std::f64::consts::FRAC_PI_2 / steps as f64;
            }
            // Midpoint rule on 200 000 intervals: the narrowest lobe (a = 0.05) is resolved by
            // ~3000 of them. Bound 1e-4.
            assert!((sum - 1.0).abs() < 1e-4, "a {a}: {sum}");
        }
    }

    #[test]
    fn cook_torrance_at_the_mirror_direction_is_one_over_four_pi_alpha_squared() {
        // n = l = v: D = 1/(π α²), G = 1, so BRDF × cos = 1/(4π α²).
        let z = DVec3::Z;
        let a: f64 = 0.2 * 0.2;
        let ct = cook_torrance(z, z, z, 0.2);
        assert!(
            (ct - 1.0 / (4.0 * std::f64::consts::PI * a * a)).abs() < 1e-9 * ct,
            "{ct}"
        );
        assert_eq!(cook_torrance(z, -z, z, 0.2), 0.0, "light behind the surface");
    }
}
