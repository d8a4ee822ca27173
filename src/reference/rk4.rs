//! The ray equation of geometric optics, d/ds(η dx/ds) = ∇η (paper Eq. 6), as the first-order
//! system dx/ds = v/η, dv/ds = ∇η (Eq. 7), integrated with classical fourth-order Runge–Kutta
//! in the arc length s. The GPU renderer uses the Euler form (Eq. 8) with one step per plane.

use glam::DVec3;

use super::medium::Medium;

/// A point on a ray and its direction vector v = η dx/ds (|v| = η).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub x: DVec3,
    pub v: DVec3,
}

impl Ray {
    /// A ray at `x` travelling along `direction` (any length).
    pub fn new<M: Medium + ?Sized>(medium: &M, x: DVec3, direction: DVec3) -> Ray {
        Ray {
            x,
            v: direction.normalize() * medium.eta(x),
        }
    }

    /// Unit tangent dx/ds.
    pub fn direction(&self) -> DVec3 {
        self.v.normalize()
    }
}

fn derivative<M: Medium + ?Sized>(medium: &M, x: DVec3, v: DVec3) -> (DVec3, DVec3) {
    (v / medium.eta(x), medium.grad_eta(x))
}

/// One RK4 step of arc length `h`.
pub fn step<M: Medium + ?Sized>(medium: &M, r: Ray, h: f64) -> Ray {
    let (k1x, k1v) = derivative(medium, r.x, r.v);
    let (k2x, k2v) = derivative(medium, r.x + 0.5 * h * k1x, r.v + 0.5 * h * k1v);
    let (k3x, k3v) = derivative(medium, r.x + 0.5 * h * k2x, r.v + 0.5 * h * k2v);
    let (k4x, k4v) = derivative(medium, r.x + h * k3x, r.v + h * k3v);
    Ray {
        x: r.x + h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
        v: r.v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v),
    }
}

/// One RK4 step, then the change of v scaled so that |v| = η at the new point (the ray
/// equation keeps |v| = η exactly; RK4 only to its truncation error, which is large where ∇η
/// has kinks: through the one-voxel index ramp at a volume's face, 5% of the index step at
/// 0.25-voxel steps, and where the central-difference gradient reaches past the end of an
/// index ramp, which η itself does not). Correcting along the change of v rather than
/// rescaling v leaves the components that ∇η never touched alone: where η varies along one
/// direction only, the tangential part of v stays exact and so does Snell's law, at any step.
/// For smooth fields the correction is of the order of RK4's own error, O(h⁵) per step.
pub fn step_on_shell<M: Medium + ?Sized>(medium: &M, r: Ray, h: f64) -> Ray {
    let next = step(medium, r, h);
    let eta = medium.eta(next.x);
    let dv = next.v - r.v;
    let (a, b, c) = (dv.length_squared(), r.v.dot(dv), r.v.length_squared() - eta * eta);
    let disc = b * b - a * c;
    if a > 1e-30 && disc >= 0.0 {
        // The root of |v + μ Δv|² = η² nearest μ = 1 (μ = 0 where the index did not change
        // but RK4 bent the ray: a gradient stencil reaching past a ramp's end).
        let (m1, m2) = ((-b + disc.sqrt()) / a, (-b - disc.sqrt()) / a);
        let mu = if (m1 - 1.0).abs() <= (m2 - 1.0).abs() { m1 } else { m2 };
        if (-0.5..=2.0).contains(&mu) {
            return Ray {
                x: next.x,
                v: r.v + dv * mu,
            };
        }
    }
    let length = next.v.length();
    if length > 0.0 {
        Ray {
            x: next.x,
            v: next.v * (eta / length),
        }
    } else {
        next
    }
}

/// Follows `r` with steps of at most `h` until `stop` holds or `max_length` of arc is used;
/// returns the final ray.
pub fn trace<M: Medium + ?Sized>(
    medium: &M,
    mut r: Ray,
    h: f64,
    max_length: f64,
    mut stop: impl FnMut(&Ray) -> bool,
) -> Ray {
    let mut s = 0.0;
    while s < max_length && !stop(&r) {
        let dh = h.min(max_length - s);
        r = step(medium, r, dh);
        s += dh;
    }
    r
}

/// Entry and exit distances of the line `o + t d` through the box (lo, hi), if it meets it.
pub fn box_interval(o: DVec3, d: DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        if d[a].abs() < 1e-300 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
            continue;
        }
        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t1 > t0.max(0.0)).then_some((t0.max(0.0), t1))
}
