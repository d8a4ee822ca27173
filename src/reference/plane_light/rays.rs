//! One ray of the plane trace: straight outside the medium, RK4 inside, each crossing of a
//! requested plane deposited over the ray's footprint box into per-thread sums.

use glam::{DMat4, DVec2, DVec3};

use super::super::medium::Medium;
use super::super::rk4::{self, Ray};
use super::PlaneView;

/// Rays below this fraction of their starting power are dropped (counted as absorbed).
const POWER_CUTOFF: f64 = 1e-12;

/// The per-thread sums.
pub(super) struct Accumulator {
    pub(super) texels: Vec<[f64; 3]>,
    pub(super) in_frame: Vec<[f64; 3]>,
    pub(super) crossing: Vec<[f64; 3]>,
    pub(super) backward: Vec<[f64; 3]>,
    pub(super) launched: f64,
    pub(super) entering: f64,
    pub(super) lost: [f64; 3],
    pub(super) escaped_backward: [f64; 3],
    pub(super) rays: u64,
}

impl Accumulator {
    pub(super) fn new(planes: usize, texels: usize) -> Self {
        Accumulator {
            texels: vec![[0.0; 3]; planes * texels],
            in_frame: vec![[0.0; 3]; planes],
            crossing: vec![[0.0; 3]; planes],
            backward: vec![[0.0; 3]; planes],
            launched: 0.0,
            entering: 0.0,
            lost: [0.0; 3],
            escaped_backward: [0.0; 3],
            rays: 0,
        }
    }

    pub(super) fn add(mut self, o: Accumulator) -> Self {
        let sum = |a: &mut [[f64; 3]], b: &[[f64; 3]]| {
            for (x, y) in a.iter_mut().zip(b) {
                for c in 0..3 {
                    x[c] += y[c];
                }
            }
        };
        sum(&mut self.texels, &o.texels);
        sum(&mut self.in_frame, &o.in_frame);
        sum(&mut self.crossing, &o.crossing);
        sum(&mut self.backward, &o.backward);
        sum(std::slice::from_mut(&mut self.lost), &[o.lost]);
        sum(std::slice::from_mut(&mut self.escaped_backward), &[o.escaped_backward]);
        self.launched += o.launched;
        self.entering += o.entering;
        self.rays += o.rays;
        self
    }
}

/// Everything a ray needs to know about the planes.
pub(super) struct Planes<'a> {
    pub(super) view: &'a PlaneView,
    pub(super) view_from_world: DMat4,
    pub(super) z: &'a [f64],
    /// Footprint of every ray (world units, the same on every plane).
    pub(super) footprint: DVec2,
}

impl Planes<'_> {
    fn view_point(&self, p: DVec3) -> DVec3 {
        self.view_from_world.transform_point3(p)
    }

    fn view_vector(&self, v: DVec3) -> DVec3 {
        self.view_from_world.transform_vector3(v)
    }

    /// Adds `power` (negative for a crossing against +z) crossing plane `k` at view point `p`,
    /// spread over the ray's footprint box.
    fn deposit(&self, acc: &mut Accumulator, k: usize, p: DVec3, power: [f64; 3], sign: f64) {
        let signed = power.map(|v| v * sign);
        for c in 0..3 {
            acc.crossing[k][c] += signed[c];
            if sign < 0.0 {
                acc.backward[k][c] += power[c];
            }
        }
        let view = self.view;
        let t = view.texel_of(p);
        let size = view.texel_size(self.z[k]);
        let half = DVec2::new(self.footprint.x / size.x, self.footprint.y / size.y) * 0.5;
        let (w, h) = (view.width as i64, view.height as i64);
        // Texel i covers [i − ½, i + ½) in continuous coordinates.
        let range = |lo: f64, hi: f64, n: i64| {
            let first = (lo + 0.5).floor().max(0.0) as i64;
            let last = ((hi + 0.5).floor() as i64).min(n - 1);
            (first, last)
        };
        let (lo, hi) = (t - half, t + half);
        let (x0, x1) = range(lo.x, hi.x, w);
        let (y0, y1) = range(lo.y, hi.y, h);
        let plane = k * (w * h) as usize;
        for y in y0..=y1 {
            let fy = ((hi.y).min(y as f64 + 0.5) - (lo.y).max(y as f64 - 0.5)) / (2.0 * half.y);
            if fy <= 0.0 {
                continue;
            }
            for x in x0..=x1 {
                let fx = ((hi.x).min(x as f64 + 0.5) - (lo.x).max(x as f64 - 0.5)) / (2.0 * half.x);
                if fx <= 0.0 {
                    continue;
                }
                let i = plane + (y * w + x) as usize;
                for c in 0..3 {
                    let v = signed[c] * fx * fy;
                    acc.texels[i][c] += v;
                    acc.in_frame[k][c] += v;
                }
            }
        }
    }

    /// Crossings of the straight piece from `a` (power `power`) along unit `dir` for
    /// `length` (may be infinite), through optical depth `tau` per unit length.
    fn straight(&self, acc: &mut Accumulator, a: DVec3, dir: DVec3, length: f64, power: [f64; 3], tau: [f64; 3]) {
        let (pa, dv) = (self.view_point(a), self.view_vector(dir));
        if dv.z == 0.0 {
            return;
        }
        let zb = if length.is_finite() {
            pa.z + dv.z * length
        } else {
            f64::INFINITY * dv.z.signum()
        };
        for (k, &z) in self.z.iter().enumerate() {
            let sign = crossing_sign(pa.z, zb, z);
            if sign == 0.0 {
                continue;
            }
            let t = (z - pa.z) / dv.z;
            let mut p = pa + dv * t;
            p.z = z;
            let at = [0, 1, 2].map(|c| power[c] * (-tau[c] * t).exp());
            self.deposit(acc, k, p, at, sign);
        }
    }
}

/// +1 if the plane at `z` lies in (za, zb], −1 if in (zb, za], else 0: each crossing of a
/// chain of pieces counts once, and touching a plane without passing it counts zero.
fn crossing_sign(za: f64, zb: f64, z: f64) -> f64 {
    if za < z && z <= zb {
        1.0
    } else if zb < z && z <= za {
        -1.0
    } else {
        0.0
    }
}

/// Cubic Hermite position at σ ∈ [0, 1] from end points and end derivatives (per unit σ).
fn hermite(a: DVec3, ma: DVec3, b: DVec3, mb: DVec3, s: f64) -> DVec3 {
    let (s2, s3) = (s * s, s * s * s);
    a * (2.0 * s3 - 3.0 * s2 + 1.0) + ma * (s3 - 2.0 * s2 + s) + b * (-2.0 * s3 + 3.0 * s2) + mb * (s3 - s2)
}

fn hermite_dz(a: DVec3, ma: DVec3, b: DVec3, mb: DVec3, s: f64) -> f64 {
    let s2 = s * s;
    a.z * (6.0 * s2 - 6.0 * s)
        + ma.z * (3.0 * s2 - 4.0 * s + 1.0)
        + b.z * (-6.0 * s2 + 6.0 * s)
        + mb.z * (3.0 * s2 - 2.0 * s)
}

/// Optical depth per unit length of four quarters of the chord from `a` to `b`.
fn quarter_taus<M: Medium + ?Sized>(medium: &M, a: DVec3, b: DVec3) -> [[f64; 3]; 4] {
    [0, 1, 2, 3].map(|q| {
        let o = medium.optics(a.lerp(b, (q as f64 + 0.5) / 4.0));
        [0, 1, 2].map(|c| o.tau_alpha + o.tau_medium[c])
    })
}

/// Power after the fraction `s` of a step of length `h` through the quarters' depths.
fn attenuated(power: [f64; 3], taus: &[[f64; 3]; 4], h: f64, s: f64) -> [f64; 3] {
    let mut depth = [0.0; 3];
    for (q, tau) in taus.iter().enumerate() {
        let covered = (s * 4.0 - q as f64).clamp(0.0, 1.0) * 0.25 * h;
        for c in 0..3 {
            depth[c] += tau[c] * covered;
        }
    }
    [0, 1, 2].map(|c| power[c] * (-depth[c]).exp())
}

/// Follows one ray from `start` (world, outside the medium's bounds) along unit `dir`.
pub(super) fn trace_ray<M: Medium + ?Sized>(
    medium: &M,
    planes: &Planes,
    acc: &mut Accumulator,
    start: DVec3,
    dir: DVec3,
    p0: f64,
    h: f64,
) {
    let zero = [0.0; 3];
    let mut power = [p0; 3];
    acc.launched += p0;
    acc.rays += 1;
    let (lo, hi) = medium.bounds();
    let Some((t0, t1)) = rk4::box_interval(start, dir, lo, hi) else {
        planes.straight(acc, start, dir, f64::INFINITY, power, zero);
        return;
    };
    acc.entering += p0;
    planes.straight(acc, start, dir, t0, power, zero);
    let slack = DVec3::splat(1e-9 * (hi - lo).max_element());
    let inside = |x: DVec3| x.cmpge(lo - slack).all() && x.cmple(hi + slack).all();
    let mut ray = Ray::new(medium, start + dir * t0, dir);
    // A ray cannot bend back forever; bound the work by a generous path length.
    let mut budget = 8.0 * (t1 - t0).max(h) + 16.0 * h;
    let cutoff = POWER_CUTOFF * p0;
    while budget > 0.0 && inside(ray.x) {
        if power.iter().all(|p| *p <= cutoff) {
            return; // absorbed
        }
        let d = ray.direction();
        if let Some(len) = medium.uniform_for(ray.x, d) {
            // Uniform block: straight, constant optics; step just past its exit.
            let len = len + 1e-6 * h;
            let o = medium.optics(ray.x);
            let tau = [0, 1, 2].map(|c| o.tau_alpha + o.tau_medium[c]);
            planes.straight(acc, ray.x, d, len, power, tau);
            power = [0, 1, 2].map(|c| power[c] * (-tau[c] * len).exp());
            ray.x += d * len;
            budget -= len;
            continue;
        }
        let next = rk4::step_on_shell(medium, ray, h);
        let taus = quarter_taus(medium, ray.x, next.x);
        let (a, b) = (planes.view_point(ray.x), planes.view_point(next.x));
        let ma = planes.view_vector(d) * h;
        let mb = planes.view_vector(next.direction()) * h;
        for (k, &z) in planes.z.iter().enumerate() {
            let sign = crossing_sign(a.z, b.z, z);
            if sign == 0.0 {
                continue;
            }
            // Newton on the Hermite curve's depth from the chord's crossing.
            let mut s = (z - a.z) / (b.z - a.z);
            for _ in 0..4 {
                let dz = hermite_dz(a, ma, b, mb, s);
                if dz.abs() < 1e-12 {
                    break;
                }
                s = (s - (hermite(a, ma, b, mb, s).z - z) / dz).clamp(0.0, 1.0);
            }
            let mut p = hermite(a, ma, b, mb, s);
            p.z = z;
            planes.deposit(acc, k, p, attenuated(power, &taus, h, s), sign);
        }
        power = attenuated(power, &taus, h, 1.0);
        ray = next;
        budget -= h;
    }
    if inside(ray.x) {
        for c in 0..3 {
            acc.lost[c] += power[c];
        }
    } else {
        let d = ray.direction();
        if planes.view_vector(d).z < 0.0 {
            for c in 0..3 {
                acc.escaped_backward[c] += power[c];
            }
        }
        planes.straight(acc, ray.x, d, f64::INFINITY, power, zero);
    }
}
