//! Monte Carlo multiple scattering: volumetric path tracing of single photons through a
//! heterogeneous medium by delta tracking (Woodcock tracking: tentative collisions at the
//! majorant's rate, real with probability σ_t(x)/σ̄), scattering on by Henyey–Greenstein
//! sampling with probability ω (the single-scattering albedo), absorbed otherwise. Straight
//! flights: η is taken to be constant (refraction is the other tracers' business).
//!
//! Deterministic: photon `i` of a run draws from its own generator seeded by (seed, i), and
//! the per-photon results are summed in photon order, so a run gives the same bits on any
//! number of threads. The error of a tally is its standard error over the photons, which the
//! tallies report beside their means.
//!
//! The generator is SplitMix64 (Steele et al. 2014), a few lines: a counter-based stream per
//! photon is what determinism needs, and no random-number crate is otherwise in use.

use glam::DVec3;
use rayon::prelude::*;

use super::medium::{Medium, VolumeMedium};

/// SplitMix64's output function.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Per-photon random numbers: SplitMix64 on a (seed, photon) start.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn for_photon(seed: u64, photon: u64) -> Rng {
        // Start states scattered over the whole period by the mixer: SplitMix64 streams are
        // windows on one sequence, so starts that differ by a few increments would share
        // numbers between photons.
        Rng(mix(mix(seed ^ 0x6a09_e667_f3bc_c909) ^ photon))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix(self.0)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// What a point of the medium does to light, per unit length.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Coefficients {
    /// Extinction σ_t = absorption + scattering.
    pub extinction: f64,
    /// Single-scattering albedo ω: the scattered fraction of what is removed.
    pub albedo: f64,
    /// Henyey–Greenstein mean cosine.
    pub g: f64,
}

/// A medium the photons scatter in.
pub trait ScatteringMedium: Sync {
    fn coefficients(&self, p: DVec3) -> Coefficients;
    /// An upper bound of the extinction everywhere (delta tracking's majorant).
    fn majorant(&self) -> f64;
    /// Axis-aligned box (min, max) outside which nothing interacts; photons that leave it
    /// have left the medium.
    fn bounds(&self) -> (DVec3, DVec3);
}

/// A homogeneous slab 0 ≤ z ≤ `thickness`, |x|, |y| ≤ `half_width`.
#[derive(Clone, Copy, Debug)]
pub struct Slab {
    pub thickness: f64,
    pub half_width: f64,
    /// Absorption a and scattering b per unit length (Premoze's symbols).
    pub absorption: f64,
    pub scattering: f64,
    pub g: f64,
}

impl ScatteringMedium for Slab {
    fn coefficients(&self, _p: DVec3) -> Coefficients {
        let extinction = self.absorption + self.scattering;
        Coefficients {
            extinction,
            albedo: if extinction > 0.0 {
                self.scattering / extinction
            } else {
                0.0
            },
            g: self.g,
        }
    }

    fn majorant(&self) -> f64 {
        self.absorption + self.scattering
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        let h = self.half_width;
        (DVec3::new(-h, -h, 0.0), DVec3::new(h, h, self.thickness))
    }
}

/// A slab whose box is centred on the origin in z too, so a beam from the origin starts in
/// its middle (light turned back stays inside).
pub struct Centred(pub Slab);

impl ScatteringMedium for Centred {
    fn coefficients(&self, p: DVec3) -> Coefficients {
        self.0.coefficients(p)
    }

    fn majorant(&self) -> f64 {
        self.0.majorant()
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        let (lo, hi) = self.0.bounds();
        let half = DVec3::Z * 0.5 * self.0.thickness;
        (lo - half, hi - half)
    }
}

/// E[x² + y²] of all the light after a path length s, exactly, for a walk in an unbounded
/// medium starting along z with scattering b and HG anisotropy g: directions decorrelate as
/// e^{−b(1−g)Δ} and the second Legendre moment (g² for HG) gives E[d_z²](t) =
/// (1 + 2e^{−b(1−g²)t})/3, so E[r⊥²] = (4/3) ∫₀ˢ (1 − e^{−b(1−g²)t}) (1 − e^{−b(1−g)(s−t)})/(b(1−g)) dt
/// (midpoint rule, 4000 intervals: relative error < 10⁻⁶ for the lengths used here).
/// Absorption does not change it: it thins all paths of one length alike.
pub fn transverse_moment(b: f64, g: f64, s: f64) -> f64 {
    let (k1, k2) = (b * (1.0 - g), b * (1.0 - g * g));
    let steps = 4000;
    let h = s / steps as f64;
    let integral: f64 = (0..steps)
        .map(|i| {
            let t = (i as f64 + 0.5) * h;
            (1.0 - (-k2 * t).exp()) * (1.0 - (-k1 * (s - t)).exp()) / k1 * h
        })
        .sum();
    integral * 4.0 / 3.0
}

/// A scene's volume through its transfer functions, for one colour channel: particles remove
/// light at the opacity's optical depth and scatter the fraction ω of it (albedo curve) with
/// the anisotropy curve's g; the medium colour absorbs.
pub struct VolumeScattering<'a> {
    pub medium: &'a VolumeMedium,
    pub channel: usize,
    majorant: f64,
}

impl<'a> VolumeScattering<'a> {
    pub fn new(medium: &'a VolumeMedium, channel: usize) -> Self {
        let (tau_alpha, tau_medium) = medium.max_optical_depths();
        VolumeScattering {
            medium,
            channel,
            majorant: tau_alpha + tau_medium[channel],
        }
    }
}

impl ScatteringMedium for VolumeScattering<'_> {
    fn coefficients(&self, p: DVec3) -> Coefficients {
        let optics = self.medium.optics(p);
        let (albedo, g) = self.medium.scattering(p);
        let extinction = optics.tau_alpha + optics.tau_medium[self.channel];
        Coefficients {
            extinction,
            albedo: if extinction > 0.0 {
                albedo * optics.tau_alpha / extinction
            } else {
                0.0
            },
            g,
        }
    }

    fn majorant(&self) -> f64 {
        self.majorant
    }

    fn bounds(&self) -> (DVec3, DVec3) {
        self.medium.bounds()
    }
}

/// A direction scattered from `d` (unit) by the Henyey–Greenstein phase function with mean
/// cosine `g`, by inverting its cumulative distribution in cos θ.
pub fn sample_hg(d: DVec3, g: f64, rng: &mut Rng) -> DVec3 {
    let (u1, u2) = (rng.uniform(), rng.uniform());
    let cos_theta = if g.abs() < 1e-6 {
        1.0 - 2.0 * u1
    } else {
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    };
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * u2;
    let (t, b) = d.any_orthonormal_pair();
    (d * cos_theta + (t * phi.cos() + b * phi.sin()) * sin_theta).normalize()
}

/// How a photon's walk ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fate {
    /// Left the medium's box at `position`, travelling along `direction`.
    Left {
        position: DVec3,
        direction: DVec3,
    },
    Absorbed,
    /// Still inside after `MAX_SCATTERINGS`: counted apart, so tallies see what is lost.
    Lost,
}

/// Scatterings after which a walk is given up (reported as [`Fate::Lost`]).
pub const MAX_SCATTERINGS: u32 = 100_000;

/// Distance from `p` (inside or on the box) along unit `d` to where it leaves the box.
pub(super) fn exit_distance(p: DVec3, d: DVec3, (lo, hi): (DVec3, DVec3)) -> f64 {
    let mut t = f64::INFINITY;
    for a in 0..3 {
        if d[a] > 0.0 {
            t = t.min((hi[a] - p[a]) / d[a]);
        } else if d[a] < 0.0 {
            t = t.min((lo[a] - p[a]) / d[a]);
        }
    }
    t.max(0.0)
}

/// One photon's walk from `p` along `d` until it leaves, is absorbed or is lost. `segment` sees
/// every straight piece of the path (start, end; null collisions split them), so a tally can
/// integrate along the track.
pub fn walk<M: ScatteringMedium + ?Sized>(
    medium: &M,
    mut p: DVec3,
    mut d: DVec3,
    rng: &mut Rng,
    mut segment: impl FnMut(DVec3, DVec3),
) -> (Fate, u32) {
    let bounds = medium.bounds();
    let majorant = medium.majorant();
    let mut scatterings = 0;
    loop {
        let to_exit = exit_distance(p, d, bounds);
        let t = if majorant > 0.0 {
            -(1.0 - rng.uniform()).ln() / majorant
        } else {
            f64::INFINITY
        };
        if t >= to_exit {
            let q = p + d * to_exit;
            segment(p, q);
            return (
                Fate::Left {
                    position: q,
                    direction: d,
                },
                scatterings,
            );
        }
        let q = p + d * t;
        segment(p, q);
        p = q;
        let c = medium.coefficients(p);
        debug_assert!(c.extinction <= majorant * (1.0 + 1e-9), "majorant below the extinction");
        if rng.uniform() * majorant < c.extinction {
            if rng.uniform() >= c.albedo {
                return (Fate::Absorbed, scatterings);
            }
            scatterings += 1;
            if scatterings > MAX_SCATTERINGS {
                return (Fate::Lost, scatterings);
            }
            d = sample_hg(d, c.g, rng);
        }
    }
}

/// Adds one chunk's tallies to the sums, row by row and entry by entry (`run`'s `add` for
/// tallies kept as rows of sums).
fn add_tallies<R: AsRef<[f64]> + AsMut<[f64]>>(sums: &mut [R], more: Vec<R>) {
    for (row, other) in sums.iter_mut().zip(more) {
        for (x, y) in row.as_mut().iter_mut().zip(other.as_ref()) {
            *x += y;
        }
    }
}

/// Runs `photons` walks in parallel and sums their tallies in photon order (deterministic).
/// `one` traces photon `i` with its own generator and returns its tally; tallies add with
/// `add` from `zero`.
pub fn run<T: Send>(
    photons: u64,
    seed: u64,
    zero: impl Fn() -> T + Sync,
    one: impl Fn(u64, &mut Rng) -> T + Sync,
    add: impl Fn(&mut T, T) + Sync,
) -> T {
    // Chunks of fixed size, summed in order: the same bits on any number of threads.
    const CHUNK: u64 = 1024;
    let chunks: Vec<T> = (0..photons.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut sum = zero();
            for i in c * CHUNK..((c + 1) * CHUNK).min(photons) {
                let mut rng = Rng::for_photon(seed, i);
                add(&mut sum, one(i, &mut rng));
            }
            sum
        })
        .collect();
    let mut total = zero();
    for c in chunks {
        add(&mut total, c);
    }
    total
}

/// Where the light that entered a slab went (fractions of the photons).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SlabBalance {
    /// Left through the far face (z = thickness).
    pub transmitted: f64,
    /// Left back through the entry face (z = 0).
    pub reflected: f64,
    /// Left through the sides.
    pub sideways: f64,
    pub absorbed: f64,
    pub lost: f64,
    pub photons: u64,
}

/// A collimated pencil beam entering `slab` at the centre of its entry face, along +z.
pub fn slab_balance(slab: &Slab, photons: u64, seed: u64) -> SlabBalance {
    let counts = run(
        photons,
        seed,
        || [0u64; 5],
        |_, rng| {
            let (fate, _) = walk(slab, DVec3::ZERO, DVec3::Z, rng, |_, _| {});
            let k = match fate {
                Fate::Left { position, .. } if position.z >= slab.thickness * (1.0 - 1e-12) => 0,
                Fate::Left { position, .. } if position.z <= slab.thickness * 1e-12 => 1,
                Fate::Left { .. } => 2,
                Fate::Absorbed => 3,
                Fate::Lost => 4,
            };
            let mut c = [0u64; 5];
            c[k] = 1;
            c
        },
        |a, b| {
            for k in 0..5 {
                a[k] += b[k];
            }
        },
    );
    let f = |k: usize| counts[k] as f64 / photons.max(1) as f64;
    SlabBalance {
        transmitted: f(0),
        reflected: f(1),
        sideways: f(2),
        absorbed: f(3),
        lost: f(4),
        photons,
    }
}

/// The light of a pencil beam at one depth of a slab: its fluence integrated over the plane
/// (relative to the entering power) and its spread, from the track length the photons leave
/// in a thin layer around the depth (the track-length estimator of fluence).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BeamWidth {
    pub depth: f64,
    /// Fluence over the plane (1 for an unscattered, unabsorbed beam).
    pub fluence: f64,
    /// Mean of x² + y² over the fluence: twice the variance per axis.
    pub mean_r2: f64,
    /// Standard error of `mean_r2` (over the photons).
    pub mean_r2_error: f64,
    /// The same for the light that has scattered at least once.
    pub scattered_fluence: f64,
    pub scattered_mean_r2: f64,
    /// Median of x² + y² over the scattered light's fluence (bins 2.3 % wide in r²): robust
    /// where the mean is ruled by a few photons far out. For a Gaussian profile it is
    /// 2 ln 2 times the variance per axis.
    pub scattered_median_r2: f64,
}

/// Log-spaced bins of r² from 10⁻⁸ to 10⁸ (squared length units).
const R2_BINS: usize = 1600;
const R2_DECADES: f64 = 16.0;
const R2_MIN_LOG10: f64 = -8.0;

fn r2_bin(r2: f64) -> usize {
    let t = (r2.max(1e-300).log10() - R2_MIN_LOG10) / R2_DECADES;
    ((t * R2_BINS as f64).max(0.0) as usize).min(R2_BINS - 1)
}

/// The r² below which half of the histogram's weight lies (interpolated in its bin).
fn weighted_median_r2(hist: &[f64]) -> f64 {
    let total: f64 = hist.iter().sum();
    if total <= 0.0 {
        return 0.0;
    }
    let mut acc = 0.0;
    for (i, &w) in hist.iter().enumerate() {
        if acc + w >= 0.5 * total {
            let f = if w > 0.0 { (0.5 * total - acc) / w } else { 0.0 };
            let log10 = R2_MIN_LOG10 + (i as f64 + f) * R2_DECADES / R2_BINS as f64;
            return 10f64.powf(log10);
        }
        acc += w;
    }
    0.0
}

/// Per-depth sums of one photon: Σℓ, Σℓr², the same for scattered light.
#[derive(Clone, Copy, Default)]
struct Layer {
    l: f64,
    lr2: f64,
    sl: f64,
    slr2: f64,
}

/// Widths of a pencil beam (entering the slab's centre along +z) at `depths`, from
/// `photons` walks; layers `layer` thick centred on each depth. With `max_angle` (radians),
/// only light travelling within that angle of the beam counts (as in Premoze et al.'s Monte
/// Carlo, whose widths are those of light still going the beam's way): the fluence-weighted
/// r² of all the light is dominated by the few photons turned sideways, which run far
/// through a thin layer.
pub fn beam_widths(
    slab: &Slab,
    depths: &[f64],
    layer: f64,
    max_angle: Option<f64>,
    photons: u64,
    seed: u64,
) -> Vec<BeamWidth> {
    let min_cos = max_angle.map_or(-2.0, f64::cos);
    let n = depths.len();
    // Per photon and depth: sums, and for the error of mean r² the squares of (Σℓr², Σℓ).
    let totals = run(
        photons,
        seed,
        || (vec![[0.0f64; 7]; n], vec![0.0f64; n * R2_BINS]),
        |_, rng| {
            let mut sums = vec![Layer::default(); n];
            let mut hist = vec![0.0f64; n * R2_BINS];
            walk(slab, DVec3::ZERO, DVec3::Z, rng, |a, b| {
                // Until it scatters, a photon travels up the axis.
                let on_axis = a.x == 0.0 && a.y == 0.0 && b.x == 0.0 && b.y == 0.0 && b.z > a.z;
                if a == b || (b - a).normalize().z < min_cos {
                    return;
                }
                for (k, &z) in depths.iter().enumerate() {
                    if let Some((l, lr2)) = track_in_layer(a, b, z - 0.5 * layer, z + 0.5 * layer) {
                        let s = &mut sums[k];
                        s.l += l;
                        s.lr2 += lr2;
                        if !on_axis {
                            s.sl += l;
                            s.slr2 += lr2;
                            hist[k * R2_BINS + r2_bin(lr2 / l)] += l;
                        }
                    }
                }
            });
            let moments = sums
                .iter()
                .map(|s| [s.l, s.lr2, s.l * s.l, s.lr2 * s.lr2, s.l * s.lr2, s.sl, s.slr2])
                .collect();
            (moments, hist)
        },
        |a, b| {
            for (x, y) in a.0.iter_mut().zip(b.0) {
                for k in 0..7 {
                    x[k] += y[k];
                }
            }
            for (x, y) in a.1.iter_mut().zip(b.1) {
                *x += y;
            }
        },
    );
    let (totals, hist) = totals;
    let np = photons.max(1) as f64;
    depths
        .iter()
        .zip(totals)
        .zip(hist.chunks(R2_BINS))
        .map(|((&depth, t), hist)| {
            let [l, lr2, l2, lr2_2, l_lr2, sl, slr2] = t.map(|v| v / np);
            let mean_r2 = if l > 0.0 { lr2 / l } else { 0.0 };
            // Delta method for the ratio of means: var(R) ≈ (var(Y) − 2R cov(X, Y) + R² var(X)) / (n X̄²).
            let var = (lr2_2 - lr2 * lr2) - 2.0 * mean_r2 * (l_lr2 - l * lr2) + mean_r2 * mean_r2 * (l2 - l * l);
            BeamWidth {
                depth,
                fluence: l / layer,
                mean_r2,
                mean_r2_error: if l > 0.0 { (var.max(0.0) / np).sqrt() / l } else { 0.0 },
                scattered_fluence: sl / layer,
                scattered_mean_r2: if sl > 0.0 { slr2 / sl } else { 0.0 },
                scattered_median_r2: weighted_median_r2(hist),
            }
        })
        .collect()
}

/// The net flux of a pencil beam through the plane at one depth of a slab (the irradiance a
/// plane of light sees: crossings forward count +1, backward −1), within radius `max_r` of
/// the beam, relative to the entering power, and its spread.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PlaneFlux {
    pub depth: f64,
    /// Net flux through the plane within `max_r` (1 for an unscattered, unabsorbed beam).
    pub flux: f64,
    /// Mean of x² + y² over the net flux.
    pub mean_r2: f64,
    /// Standard error of `mean_r2` (over the photons).
    pub mean_r2_error: f64,
}

/// The net flux of a pencil beam (entering the slab's centre along +z) through the planes at
/// `depths`, counting crossings within `max_r` of the axis, from `photons` walks.
pub fn plane_flux<M: ScatteringMedium + ?Sized + Sync>(
    medium: &M,
    depths: &[f64],
    max_r: f64,
    photons: u64,
    seed: u64,
) -> Vec<PlaneFlux> {
    plane_flux_rings(medium, depths, max_r, 0, 0.0, photons, seed).0
}

/// [`plane_flux`] for a collimated beam of radius `source_radius` (uniform over a disc on the
/// axis; 0 is the pencil beam, the same walks as [`plane_flux`] with the same seed) and, per
/// depth, the net flux through each of `rings` rings of equal width that tile the disc of
/// radius `max_r` (ring k: k·max_r/rings ≤ r < (k + 1)·max_r/rings), relative to the entering
/// power: the radial profile of the light on the plane.
pub fn plane_flux_rings<M: ScatteringMedium + ?Sized + Sync>(
    medium: &M,
    depths: &[f64],
    max_r: f64,
    rings: usize,
    source_radius: f64,
    photons: u64,
    seed: u64,
) -> (Vec<PlaneFlux>, Vec<Vec<f64>>) {
    let n = depths.len();
    let ring_width = max_r / rings.max(1) as f64;
    // Per depth: Σw, Σwr², Σw², Σ(wr²)², Σw·wr² over the photons (w: one photon's net count),
    // then Σw per ring.
    let totals = run(
        photons,
        seed,
        || vec![vec![0.0f64; 5 + rings]; n],
        |_, rng| {
            let mut sums = vec![vec![0.0f64; 2 + rings]; n];
            let start = if source_radius > 0.0 {
                let (r, phi) = (
                    source_radius * rng.uniform().sqrt(),
                    std::f64::consts::TAU * rng.uniform(),
                );
                DVec3::new(r * phi.cos(), r * phi.sin(), 0.0)
            } else {
                DVec3::ZERO
            };
            walk(medium, start, DVec3::Z, rng, |a, b| {
                for (k, &z) in depths.iter().enumerate() {
                    // Half-open in z so that a photon turning exactly on the plane counts once.
                    let sign = if a.z < z && b.z >= z {
                        1.0
                    } else if a.z >= z && b.z < z {
                        -1.0
                    } else {
                        continue;
                    };
                    let p = a.lerp(b, (z - a.z) / (b.z - a.z));
                    let r2 = p.x * p.x + p.y * p.y;
                    if r2 <= max_r * max_r {
                        sums[k][0] += sign;
                        sums[k][1] += sign * r2;
                        if rings > 0 {
                            let ring = ((r2.sqrt() / ring_width) as usize).min(rings - 1);
                            sums[k][2 + ring] += sign;
                        }
                    }
                }
            });
            sums.iter()
                .map(|s| {
                    let (w, wr2) = (s[0], s[1]);
                    let mut t = vec![w, wr2, w * w, wr2 * wr2, w * wr2];
                    t.extend_from_slice(&s[2..]);
                    t
                })
                .collect::<Vec<_>>()
        },
        |a, b| add_tallies(a, b),
    );
    let np = photons.max(1) as f64;
    let profiles = totals.iter().map(|t| t[5..].iter().map(|v| v / np).collect()).collect();
    let flux = depths
        .iter()
        .zip(totals)
        .map(|(&depth, t)| {
            let [w, wr2, w2, wr2_2, w_wr2] = [t[0], t[1], t[2], t[3], t[4]].map(|v| v / np);
            let mean_r2 = if w > 0.0 { wr2 / w } else { 0.0 };
            // Delta method for the ratio of means, as in `beam_widths`.
            let var = (wr2_2 - wr2 * wr2) - 2.0 * mean_r2 * (w_wr2 - w * wr2) + mean_r2 * mean_r2 * (w2 - w * w);
            PlaneFlux {
                depth,
                flux: w,
                mean_r2,
                mean_r2_error: if w > 0.0 { (var.max(0.0) / np).sqrt() / w } else { 0.0 },
            }
        })
        .collect();
    (flux, profiles)
}

/// Light crossing a plane for the first time, by how often it has scattered on its way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CrossingOrder {
    /// Scatterings before the crossing (the last entry: that many or more).
    pub scatterings: usize,
    /// Share of the entering photons that first cross the plane (forward, within the window)
    /// after this many scatterings.
    pub share: f64,
    /// Σ r² of those crossings over the entering photons: the mean r² of the light first
    /// crossing the plane is Σ `r2` / Σ `share` over the orders.
    pub r2: f64,
    /// Σ of those photons' path lengths up to the crossing over the entering photons: their
    /// mean path is `path` / `share` (at least the depth; the depth itself unscattered).
    pub path: f64,
}

/// Where the forward light on the plane at `depth` comes from: a pencil beam entering
/// `medium` along +z at the origin, each photon counted where it first crosses the plane
/// within `max_r` of the axis, grouped by how often it had scattered (0, 1, …, `orders` − 1
/// and more). A scattering is a change of direction between two straight pieces of the walk
/// (a null collision does not turn the photon).
pub fn first_crossings_by_order<M: ScatteringMedium + ?Sized + Sync>(
    medium: &M,
    depth: f64,
    max_r: f64,
    orders: usize,
    photons: u64,
    seed: u64,
) -> Vec<CrossingOrder> {
    let orders = orders.max(1);
    let totals = run(
        photons,
        seed,
        || vec![[0.0f64; 3]; orders],
        |_, rng| {
            let mut sums = vec![[0.0f64; 3]; orders];
            let mut travelled = 0.0f64;
            let mut turns = 0usize;
            let mut last = DVec3::Z;
            let mut crossed = false;
            walk(medium, DVec3::ZERO, DVec3::Z, rng, |a, b| {
                let d = (b - a).normalize_or_zero();
                if d != DVec3::ZERO {
                    if d.dot(last) < 1.0 - 1e-12 {
                        turns += 1;
                    }
                    last = d;
                }
                if !crossed && a.z < depth && b.z >= depth {
                    crossed = true;
                    let p = a.lerp(b, (depth - a.z) / (b.z - a.z));
                    let r2 = p.x * p.x + p.y * p.y;
                    if r2 <= max_r * max_r {
                        let k = turns.min(orders - 1);
                        sums[k][0] += 1.0;
                        sums[k][1] += r2;
                        sums[k][2] += travelled + (p - a).length();
                    }
                }
                travelled += (b - a).length();
            });
            sums
        },
        |a, b| add_tallies(a, b),
    );
    let n = photons.max(1) as f64;
    totals
        .iter()
        .enumerate()
        .map(|(scatterings, t)| CrossingOrder {
            scatterings,
            share: t[0] / n,
            r2: t[1] / n,
            path: t[2] / n,
        })
        .collect()
}

/// The part of the straight segment a→b inside z0 ≤ z ≤ z1: its length and ∫(x² + y²) dℓ.
fn track_in_layer(a: DVec3, b: DVec3, z0: f64, z1: f64) -> Option<(f64, f64)> {
    let dz = b.z - a.z;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    if dz.abs() < 1e-300 {
        if a.z < z0 || a.z > z1 {
            return None;
        }
    } else {
        let (ta, tb) = ((z0 - a.z) / dz, (z1 - a.z) / dz);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
        if t1 <= t0 {
            return None;
        }
    }
    let (p, q) = (a.lerp(b, t0), a.lerp(b, t1));
    let l = p.distance(q);
    // x² is quadratic along the segment: Simpson's rule is exact.
    let r2 = |v: DVec3| v.x * v.x + v.y * v.y;
    let m = (p + q) * 0.5;
    Some((l, l * (r2(p) + 4.0 * r2(m) + r2(q)) / 6.0))
}

/// Where the light of a pencil beam (from the origin along +z) is after a path length `s`,
/// over the photons still travelling then: E[x² + y²] and E[z] with their standard errors.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathMoments {
    pub path_length: f64,
    /// Fraction of the photons that reached the path length inside the medium.
    pub travelling: f64,
    pub mean_r2: f64,
    pub mean_r2_error: f64,
    /// E[(x² + y²)²], the fourth moment across the beam.
    pub mean_r4: f64,
    pub mean_r4_error: f64,
    pub mean_z: f64,
    pub mean_z_error: f64,
}

/// Moments of the light's position after each path length in `lengths` (time-resolved
/// spread): the quantity the transport's exact moment equations give.
pub fn path_moments<M: ScatteringMedium>(medium: &M, lengths: &[f64], photons: u64, seed: u64) -> Vec<PathMoments> {
    let n = lengths.len();
    let sums = run(
        photons,
        seed,
        || vec![[0.0f64; 6]; n],
        |_, rng| {
            let mut out = vec![[0.0f64; 6]; n];
            let mut travelled = 0.0;
            walk(medium, DVec3::ZERO, DVec3::Z, rng, |a, b| {
                let l = a.distance(b);
                for (k, &s) in lengths.iter().enumerate() {
                    if s >= travelled && s < travelled + l {
                        let p = a.lerp(b, (s - travelled) / l);
                        let r2 = p.x * p.x + p.y * p.y;
                        out[k] = [1.0, r2, r2 * r2, p.z, p.z * p.z, r2 * r2 * r2 * r2];
                    }
                }
                travelled += l;
            });
            out
        },
        |a, b| add_tallies(a, b),
    );
    lengths
        .iter()
        .zip(sums)
        .map(|(&path_length, [c, r2, r4, z, z2, r8])| {
            let m = c.max(1.0);
            let (mean_r2, mean_r4, mean_z) = (r2 / m, r4 / m, z / m);
            PathMoments {
                path_length,
                travelling: c / photons.max(1) as f64,
                mean_r2,
                mean_r2_error: ((mean_r4 - mean_r2 * mean_r2).max(0.0) / m).sqrt(),
                mean_r4,
                mean_r4_error: ((r8 / m - mean_r4 * mean_r4).max(0.0) / m).sqrt(),
                mean_z,
                mean_z_error: ((z2 / m - mean_z * mean_z).max(0.0) / m).sqrt(),
            }
        })
        .collect()
}
