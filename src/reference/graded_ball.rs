//! An analytic lens: a ball whose refractive index ramps linearly from `eta_in` to `eta_out`
//! across a shell of width `edge` centred on radius `radius` — the continuous object that
//! `bench::light::ball_lens` samples onto voxels. Tracing it measures the GPU's light against
//! the lens itself, voxelisation included, with nothing shared but the geometry's formula.

use glam::DVec3;

use super::medium::{Medium, Optics};

#[derive(Clone, Debug)]
pub struct GradedBall {
    /// Centre (world space).
    pub centre: DVec3,
    pub radius: f64,
    /// Width of the surface ramp.
    pub edge: f64,
    pub eta_in: f64,
    pub eta_out: f64,
    /// Half extent of the box around the origin that holds the medium (the volume's).
    pub half_extent: DVec3,
}

impl GradedBall {
    /// Position in the ramp: 1 inside, 0 outside.
    fn ramp(&self, r: f64) -> f64 {
        (0.5 - (r - self.radius) / self.edge).clamp(0.0, 1.0)
    }

    fn in_shell(&self, r: f64) -> bool {
        (r - self.radius).abs() < 0.5 * self.edge
    }
}

/// Distance along unit `d` from `p` to the sphere of radius `r` about the origin (first
/// crossing ahead).
pub(crate) fn to_sphere(p: DVec3, d: DVec3, r: f64) -> f64 {
    let b = p.dot(d);
    let c = p.length_squared() - r * r;
    let disc = b * b - c;
    if disc < 0.0 {
        return f64::INFINITY;
    }
    let s = disc.sqrt();
    [-b - s, -b + s]
        .into_iter()
        .filter(|t| *t > 1e-12)
        .fold(f64::INFINITY, f64::min)
}

impl Medium for GradedBall {
    fn eta(&self, p: DVec3) -> f64 {
        self.eta_out + (self.eta_in - self.eta_out) * self.ramp((p - self.centre).length())
    }

    fn grad_eta(&self, p: DVec3) -> DVec3 {
        let q = p - self.centre;
        let r = q.length();
        if self.in_shell(r) && r > 0.0 {
            -(self.eta_in - self.eta_out) / self.edge * q / r
        } else {
            DVec3::ZERO
        }
    }

    fn optics(&self, _p: DVec3) -> Optics {
        Optics::default()
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        (-self.half_extent, self.half_extent)
    }

    fn voxel_length(&self) -> f64 {
        1.0
    }

    fn uniform_for(&self, p: DVec3, d: DVec3) -> Option<f64> {
        let q = p - self.centre;
        if self.in_shell(q.length()) {
            return None;
        }
        let inner = self.radius - 0.5 * self.edge;
        let outer = self.radius + 0.5 * self.edge;
        Some(to_sphere(q, d, inner).min(to_sphere(q, d, outer)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ball() -> GradedBall {
        GradedBall {
            centre: DVec3::new(1.0, -2.0, 3.0),
            radius: 10.0,
            edge: 3.0,
            eta_in: 1.5,
            eta_out: 1.0,
            half_extent: DVec3::splat(20.0),
        }
    }

    #[test]
    fn gradient_is_the_derivative_of_the_index() {
        let b = ball();
        for p in [
            DVec3::new(10.0, -2.0, 3.5),
            DVec3::new(-6.0, 5.0, 1.0),
            DVec3::new(1.0, 8.9, 3.0),
        ] {
            let h = 1e-6;
            let numeric = DVec3::new(
                b.eta(p + DVec3::X * h) - b.eta(p - DVec3::X * h),
                b.eta(p + DVec3::Y * h) - b.eta(p - DVec3::Y * h),
                b.eta(p + DVec3::Z * h) - b.eta(p - DVec3::Z * h),
            ) / (2.0 * h);
            // Central differences of a linear ramp are exact up to rounding (1e-16 / 1e-6).
            assert!(
                (numeric - b.grad_eta(p)).length() < 1e-8,
                "{numeric} vs {}",
                b.grad_eta(p)
            );
        }
        assert_eq!(b.eta(b.centre), 1.5);
        assert_eq!(b.eta(b.centre + DVec3::X * 11.6), 1.0);
    }

    #[test]
    fn uniform_stretches_end_at_the_shell() {
        let b = ball();
        let p = b.centre - DVec3::Z * 15.0;
        // Head-on towards the centre: the shell's outer edge is 15 − 11.5 ahead.
        let t = b.uniform_for(p, DVec3::Z).expect("outside the shell");
        assert!((t - 3.5).abs() < 1e-12, "{t}");
        assert!(b.uniform_for(b.centre + DVec3::X * 10.0, DVec3::Z).is_none());
    }
}
