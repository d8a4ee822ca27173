//! Scattering by the particles: the Henyey–Greenstein phase function, the per-value table of
//! albedo and anisotropy the GPU reads, and the beam-spread width of Premoze et al. 2004
//! (their Eq. 1 and its corrected form, Eq. 18), which the renderer's spread mode and the
//! checks use.
//!
//! Premoze's equations lost their symbols in the text we have; rebuilt from the special
//! cases the paper states (absorption a, scattering b, mean square scattering angle ⟨θ²⟩,
//! σ = 1/(2⟨θ²⟩) = 1/(4(1 − g)), diffusive length l² = 1/(a b ⟨θ²⟩)):
//!
//! - Eq. 1: w²(S) = ½ (2a/(3S) + 16σ/(bS³))⁻¹ = b⟨θ²⟩S³ / (16 (1 + S²/(12 l²))).
//!   No absorption (l = ∞): b⟨θ²⟩S³/16, as the paper says; long paths (S ≫ l):
//!   (3/4)⟨θ²⟩ b S l², as it says.
//! - Eq. 18 is Eq. 1 times the correction 2/3 that brings the no-absorption case to
//!   Tessendorf's b⟨θ²⟩S³/24, written with the scattering depth τ = bS:
//!   w² = ⟨θ²⟩ τ S² / (24 (1 + τ² (a/b) ⟨θ²⟩ / 12)).
//!
//! What w² measures: Tessendorf's b⟨θ²⟩S³/24 is, in small-angle theory, the variance per
//! axis of where the light of a pencil beam is after a path S *given that it travels along
//! the beam again* (an integrated random walk of the direction pinned at both ends:
//! (b⟨θ²⟩/2)·S³/12). Premoze's Monte Carlo kept exactly those photons. All the light at
//! depth S, whatever its direction, spreads four times as much in variance (Fermi–Eyges:
//! (b⟨θ²⟩/2)·S³/3), which is what lights a medium and what the renderer spreads.

use super::{TransferFunctions, TABLE_SIZE};

/// Henyey–Greenstein phase function relative to the isotropic one (4π·p): 1 for g = 0,
/// integrating to 4π over the sphere. `cos_theta` is the cosine between the direction the
/// light travelled and the one it is scattered into.
pub fn hg_relative(cos_theta: f64, g: f64) -> f64 {
    let denom = 1.0 + g * g - 2.0 * g * cos_theta;
    (1.0 - g * g) / (denom * denom.sqrt())
}

/// ⟨θ²⟩ as Premoze et al. use it: σ = 1/(4(1 − g)) = 1/(2⟨θ²⟩), so ⟨θ²⟩ = 2(1 − g), the
/// small-angle value of 2·E[1 − cos θ].
pub fn mean_square_angle(g: f64) -> f64 {
    2.0 * (1.0 - g)
}

/// Premoze et al. Eq. 1 as printed (before their 2/3 correction): w² at path length `s` for
/// absorption `a` and scattering `b` (per unit length) and mean square angle `theta2`.
pub fn premoze_eq1(a: f64, b: f64, theta2: f64, s: f64) -> f64 {
    if b <= 0.0 || s <= 0.0 {
        return 0.0;
    }
    let sigma = 1.0 / (2.0 * theta2);
    0.5 / (2.0 * a / (3.0 * s) + 16.0 * sigma / (b * s * s * s))
}

/// Premoze et al. Eq. 18: Eq. 1 with the correction factor 2/3, in terms of τ = bS.
pub fn premoze_eq18(a: f64, b: f64, theta2: f64, s: f64) -> f64 {
    if b <= 0.0 || s <= 0.0 {
        return 0.0;
    }
    let tau = b * s;
    theta2 * tau * s * s / (24.0 * (1.0 + tau * tau * (a / b) * theta2 / 12.0))
}

/// Second moments of the light of a beam that scatters in a medium, advanced along the beam
/// step by step with the local scattering b and anisotropy g: the per-plane spread a spread
/// mode blurs by. Exact moment equations of the transport (no small-angle approximation),
/// for light starting along the beam: with k₁ = b(1 − g) (the mean cosine's decay) and
/// k₂ = b(1 − g²) (that of the second Legendre moment P₂, g² for Henyey–Greenstein),
///
///   dP₂/ds = −k₂ P₂,  dC/ds = (2/3)(1 − P₂) − k₁ C,  dR/ds = 2C,
///
/// where P₂ = E[P₂(cos θ)] to the beam, C = E[r⊥·d⊥] and R = E[|r⊥|²] (the light's spread
/// about the beam, summed over both axes). In a homogeneous medium R(s) is the closed form
/// the Monte Carlo reference checks against. s is the path length; absorption thins all
/// paths of one length alike and leaves the moments alone.
///
/// Along the beam, with w = s − z a photon's lag behind the beam (dw/ds = 1 − μ, μ = cos θ)
/// and P₁ = E[μ] (dP₁/ds = −k₁P₁):
///
///   dE[w]/ds = 1 − P₁,  dE[wμ]/ds = P₁ − (1 + 2P₂)/3 − k₁E[wμ],  dE[w²]/ds = 2(E[w] − E[wμ]),
///
/// which the spread mode uses for how much of its light is back behind the face it entered
/// by (`shaders/beams.wgsl`, `spread_behind`).
///
/// The shape across the beam beyond its variance: the fourth moment F = E[|r⊥|⁴]. With u = d⊥
/// (|u|² = 1 − μ²), k₃ = b(1 − g³), and E[|u|²] = (2/3)(1 − P₂), E[|u|⁴] =
/// (8/15)(1 − (10/7)P₂ + (3/7)P₄) (dP₄/ds = −k₄P₄, k₄ = b(1 − g⁴)), the transport closes on
///
///   dM/ds = E[|u|⁴] + (4/5)(k₃ − k₁)C − k₃M,   M = E[(r⊥·u)|u|²],
///   dH/ds = 2M + (k₂/3)R − k₂H,                H = E[(r⊥·u)²],
///   dK/ds = 2M + (2k₂/3)R − k₂K,               K = E[|r⊥|²|u|²],
///   dG/ds = 2H + K − k₁G,                      G = E[|r⊥|²(r⊥·u)],
///   dF/ds = 4G:
///
/// each scattering keeps a direction function's Legendre part of order l times g^l, and
/// (r⊥·d)(1 − μ²), with r⊥ across the beam, is (4/5)(r⊥·d) of order 1 plus the rest of order
/// 3. [`SpreadMoments::scattered_kurtosis`] reads the shape off it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpreadMoments {
    pub p1: f64,
    pub p2: f64,
    pub cross: f64,
    pub r2: f64,
    /// E[w], the light's mean lag behind the beam.
    pub lag: f64,
    /// E[w·μ].
    pub lag_cos: f64,
    /// E[w²].
    pub lag2: f64,
    /// The scattering optical depth ∫b ds: 1 − e^(−∫b ds) of the light has scattered.
    pub scattering_depth: f64,
    /// P₄ = E[P₄(μ)].
    pub p4: f64,
    /// F = E[|r⊥|⁴], and the moments its equation needs: M = E[(r⊥·u)|u|²], H = E[(r⊥·u)²],
    /// K = E[|r⊥|²|u|²], G = E[|r⊥|²(r⊥·u)].
    pub r4: f64,
    pub cross_sine2: f64,
    pub cross2: f64,
    pub r2_sine2: f64,
    pub r2_cross: f64,
}

impl Default for SpreadMoments {
    /// A collimated beam: all light along it, no spread.
    fn default() -> Self {
        SpreadMoments {
            p1: 1.0,
            p2: 1.0,
            cross: 0.0,
            r2: 0.0,
            lag: 0.0,
            lag_cos: 0.0,
            lag2: 0.0,
            scattering_depth: 0.0,
            p4: 1.0,
            r4: 0.0,
            cross_sine2: 0.0,
            cross2: 0.0,
            r2_sine2: 0.0,
            r2_cross: 0.0,
        }
    }
}

impl SpreadMoments {
    /// Advances by path length `ds` through scattering `b` (per unit length) with
    /// anisotropy `g`: P₁, P₂ and P₄ exactly, the others by classical Runge–Kutta in sub-steps
    /// of at most a twentieth of the fastest relaxation length (relative error of R below
    /// 10⁻³; about 10⁻⁴ in the tests).
    pub fn step(&mut self, b: f64, g: f64, ds: f64) {
        let ds = ds.max(0.0);
        let [k1, k2, k3, k4] = if b > 0.0 {
            [1, 2, 3, 4].map(|l| b * (1.0 - g.powi(l)))
        } else {
            [0.0; 4]
        };
        let n = ((k1.max(k2).max(k3).max(k4) * ds / 0.05).ceil() as usize).max(1);
        let h = ds / n as f64;
        for _ in 0..n {
            let (p1, p2, p4) = (self.p1, self.p2, self.p4);
            // y = (C, R, E[w], E[wμ], E[w²], M, H, K, G, F) with P₁, P₂, P₄ exact along the
            // sub-step.
            let f = |t: f64, y: [f64; 10]| {
                let (p1t, p2t, p4t) = (p1 * (-k1 * t).exp(), p2 * (-k2 * t).exp(), p4 * (-k4 * t).exp());
                let sine2 = (2.0 / 3.0) * (1.0 - p2t);
                let sine4 = (8.0 / 15.0) * (1.0 - (10.0 / 7.0) * p2t + (3.0 / 7.0) * p4t);
                let [c, r, w, wmu, _, m, hh, kk, gg, _] = y;
                [
                    sine2 - k1 * c,
                    2.0 * c,
                    1.0 - p1t,
                    p1t - (1.0 + 2.0 * p2t) / 3.0 - k1 * wmu,
                    2.0 * (w - wmu),
                    sine4 + 0.8 * (k3 - k1) * c - k3 * m,
                    2.0 * m + (k2 / 3.0) * r - k2 * hh,
                    2.0 * m + (2.0 * k2 / 3.0) * r - k2 * kk,
                    2.0 * hh + kk - k1 * gg,
                    4.0 * gg,
                ]
            };
            let add = |y: [f64; 10], k: [f64; 10], a: f64| std::array::from_fn::<f64, 10, _>(|i| y[i] + a * k[i]);
            let y = self.advanced().map(|v| *v);
            let ka = f(0.0, y);
            let kb = f(0.5 * h, add(y, ka, 0.5 * h));
            let kc = f(0.5 * h, add(y, kb, 0.5 * h));
            let kd = f(h, add(y, kc, h));
            for (i, v) in self.advanced().into_iter().enumerate() {
                *v = y[i] + h / 6.0 * (ka[i] + 2.0 * kb[i] + 2.0 * kc[i] + kd[i]);
            }
            self.p1 = p1 * (-k1 * h).exp();
            self.p2 = p2 * (-k2 * h).exp();
            self.p4 = p4 * (-k4 * h).exp();
        }
        self.scattering_depth += b.max(0.0) * ds;
    }

    /// The moments [`SpreadMoments::step`] integrates, in its order: C, R, E[w], E[wμ], E[w²],
    /// M, H, K, G, F.
    fn advanced(&mut self) -> [&mut f64; 10] {
        [
            &mut self.cross,
            &mut self.r2,
            &mut self.lag,
            &mut self.lag_cos,
            &mut self.lag2,
            &mut self.cross_sine2,
            &mut self.cross2,
            &mut self.r2_sine2,
            &mut self.r2_cross,
            &mut self.r4,
        ]
    }

    /// The share of the scattered light (not the unscattered) that lies behind the face the
    /// beam entered the medium by, `path` before (its path since then) at `cos_entry` to the
    /// face's normal: a Gaussian of the light's depth below the face, mean (path − E[w])·cos θ
    /// over the scattered fraction, variance Var[w]·cos²θ + (R/2)·sin²θ. The spread mode lets
    /// what comes to lie there leave (`spread_behind` in shaders/beams.wgsl, which this
    /// mirrors, with the same fit of the normal distribution's tail).
    pub fn behind_entry(&self, path: f64, cos_entry: f64) -> f64 {
        let frac = self.scattered_fraction();
        if frac < 1e-6 {
            return 0.0;
        }
        let mean_w = self.lag / frac;
        let var_w = (self.lag2 / frac - mean_w * mean_w).max(0.0);
        let var_t = 0.5 * self.r2 / frac;
        let c = cos_entry;
        let depth = (path - mean_w) * c;
        let var_n = var_w * c * c + var_t * (1.0 - c * c);
        if var_n <= 0.0 {
            return if depth < 0.0 { 1.0 } else { 0.0 };
        }
        normal_tail(depth / var_n.sqrt())
    }

    /// The share of the light that has scattered, 1 − e^(−∫b ds) (the rest is on the beam).
    fn scattered_fraction(&self) -> f64 {
        1.0 - (-self.scattering_depth).exp()
    }

    /// Variance of the light's position per axis about the beam.
    pub fn variance_per_axis(&self) -> f64 {
        0.5 * self.r2
    }

    /// The scattered light's cloud across the beam as the spread mode deposits it: two
    /// Gaussians about the same centre with this second and fourth moment ([`core_and_wings`]
    /// of [`SpreadMoments::scattered_kurtosis`]), as (share, variance per axis) pairs.
    pub fn scattered_cloud(&self) -> [(f64, f64); 2] {
        let frac = self.scattered_fraction();
        let variance = if frac > 0.0 { 0.5 * self.r2 / frac } else { 0.0 };
        core_and_wings(self.scattered_kurtosis()).map(|(share, factor)| (share, factor * variance))
    }

    /// The kurtosis across the beam of the light that has scattered, E[|r⊥|⁴] / (2E[|r⊥|²]²)
    /// over it (the unscattered light is on the beam): 1 for a Gaussian cloud, more where a
    /// narrow core and wide wings hold the same variance. 1 before anything has scattered.
    pub fn scattered_kurtosis(&self) -> f64 {
        let frac = self.scattered_fraction();
        if frac < 1e-12 || self.r2 <= 0.0 {
            return 1.0;
        }
        self.r4 * frac / (2.0 * self.r2 * self.r2)
    }
}

/// The share of the light that forms the core of a cloud split into a core and wings, at
/// least: at kurtosis κ ≤ 1/(1 − f) the core is a Gaussian of its own; beyond, its variance
/// would have to be negative, and the core is taken the larger (a point at most).
pub const CLOUD_CORE_SHARE: f64 = 0.5;

/// Two Gaussians about one centre, as (share, variance) pairs with the variance relative to
/// their mixture's, whose mixture has variance 1 and kurtosis `kurtosis` (E[|r|⁴] / (2E[|r|²]²)
/// in the plane, 1 for one Gaussian): a core of share f at variance 1 − √((κ − 1)(1 − f)/f)
/// and wings of the rest at 1 + √((κ − 1)f/(1 − f)), f = max(CLOUD_CORE_SHARE, 1 − 1/κ). A
/// mixture of Gaussians about one centre cannot be flatter than one Gaussian: at κ ≤ 1 both
/// parts are that Gaussian. `spread_cloud_parts` in shaders/beams.wgsl mirrors this.
pub fn core_and_wings(kurtosis: f64) -> [(f64, f64); 2] {
    let excess = kurtosis - 1.0;
    if excess.is_nan() || excess <= 0.0 {
        return [(CLOUD_CORE_SHARE, 1.0), (1.0 - CLOUD_CORE_SHARE, 1.0)];
    }
    let f = CLOUD_CORE_SHARE.max(1.0 - 1.0 / kurtosis);
    let core = (1.0 - (excess * (1.0 - f) / f).sqrt()).max(0.0);
    let wings = (1.0 - f * core) / (1.0 - f);
    [(f, core), (1.0 - f, wings)]
}

/// Φ(−x), the normal distribution's tail beyond x: Bowling et al. 2009's logistic fit to the
/// normal CDF (error below 1.4·10⁻⁴), as the GPU evaluates it.
fn normal_tail(x: f64) -> f64 {
    1.0 / (1.0 + (1.5976 * x + 0.070566 * x * x * x).clamp(-80.0, 80.0).exp())
}

/// The GPU's scattering table: per data value (TABLE_SIZE entries over [0, 1], the same
/// lattice as the pre-integration tables) the albedo ω, the anisotropy g, 1 where the
/// particles scatter (opacity and ω above 0; where the spread mode's cloud finds the
/// medium's edge, `scatters_at` in shaders/beams.wgsl) else 0, and a zero.
pub fn scattering_table(tf: &TransferFunctions) -> Vec<[f32; 4]> {
    (0..TABLE_SIZE)
        .map(|i| {
            let x = i as f32 / (TABLE_SIZE - 1) as f32;
            let albedo = tf.albedo_at(x);
            let scatters = albedo > 0.0 && tf.opacity.eval(x) > 0.0;
            [albedo, tf.anisotropy_at(x), if scatters { 1.0 } else { 0.0 }, 0.0]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn henyey_greenstein_is_normalised_and_has_mean_cosine_g() {
        for g in [-0.7, 0.0, 0.5, 0.9] {
            // ∫ p dΩ = 1 and ∫ p cos θ dΩ = g, with p = hg_relative / 4π: midpoint rule in
            // cos θ, 200 000 intervals; the sharpest lobe (g = 0.9, width ~0.01 in cos θ) is
            // resolved by ~1000 of them. Bound 1e-6.
            let n = 200_000;
            let (mut norm, mut mean) = (0.0, 0.0);
            for k in 0..n {
                let mu = -1.0 + (k as f64 + 0.5) * 2.0 / n as f64;
                let p = hg_relative(mu, g) / 2.0 * (2.0 / n as f64);
                norm += p;
                mean += p * mu;
            }
            assert!((norm - 1.0).abs() < 1e-6, "g {g}: ∫p = {norm}");
            assert!((mean - g).abs() < 1e-6, "g {g}: mean cosine {mean}");
        }
        assert_eq!(hg_relative(0.3, 0.0), 1.0);
    }

    #[test]
    fn premoze_widths_reduce_to_the_special_cases_of_the_paper() {
        let (b, g, s) = (0.2, 0.9, 30.0);
        let t2 = mean_square_angle(g);
        assert!((t2 - 0.2).abs() < 1e-12);
        // No absorption: b⟨θ²⟩S³/16, and Tessendorf's /24 after the correction.
        let w1 = premoze_eq1(0.0, b, t2, s);
        assert!((w1 - b * t2 * s.powi(3) / 16.0).abs() < 1e-9 * w1);
        let w18 = premoze_eq18(0.0, b, t2, s);
        assert!((w18 - b * t2 * s.powi(3) / 24.0).abs() < 1e-9 * w18);
        // Long paths: (3/4)⟨θ²⟩ b S l² with l² = 1/(a b ⟨θ²⟩).
        let a = 0.5;
        let l2 = 1.0 / (a * b * t2);
        let s_long = 1e4 * l2.sqrt();
        let w = premoze_eq1(a, b, t2, s_long);
        let limit = 0.75 * t2 * b * s_long * l2;
        assert!((w / limit - 1.0).abs() < 1e-6, "{w} vs {limit}");
        // Eq. 18 is Eq. 1 × 2/3 everywhere.
        for (a, s) in [(0.0003, 10.0), (0.01, 50.0), (0.1, 200.0)] {
            let ratio = premoze_eq18(a, b, t2, s) / premoze_eq1(a, b, t2, s);
            assert!((ratio - 2.0 / 3.0).abs() < 1e-12, "{ratio}");
        }
        assert_eq!(premoze_eq1(0.1, 0.0, t2, s), 0.0);
    }

    #[test]
    fn the_share_behind_the_face_grows_with_the_path_and_the_slant() {
        // Before anything scatters there is no cloud; the tail fit is Φ(−x) within 1.4·10⁻⁴
        // (Φ(−1) = 0.158655, Φ(0) = 0.5); a beam entering at a slant puts more of its light
        // behind the face than one entering head-on, and the share grows as the cloud spreads.
        assert_eq!(SpreadMoments::default().behind_entry(0.0, 1.0), 0.0);
        assert!((normal_tail(1.0) - 0.158655).abs() < 1.4e-4);
        assert!((normal_tail(0.0) - 0.5).abs() < 1e-12);
        let mut m = SpreadMoments::default();
        let mut previous = 0.0;
        for step in 1..=20 {
            m.step(0.25, 0.6, 1.0);
            let path = step as f64;
            let (head_on, slant) = (m.behind_entry(path, 1.0), m.behind_entry(path, 0.34));
            assert!(slant > head_on && head_on >= previous, "{path}: {head_on} {slant}");
            previous = head_on;
        }
    }

    #[test]
    fn the_core_and_wings_keep_the_cloud_s_variance_and_give_its_kurtosis() {
        // Per axis a Gaussian of variance v has E[x²] = v and E[x⁴] = 3v²; in the plane
        // E[|r|²] = 2v and E[|r|⁴] = 8v², so the mixture's kurtosis is Σ s·v² / (Σ s·v)².
        // Exact algebra: bound 1e-12 (rounding).
        for kurtosis in [1.0, 1.13, 1.5, 2.0, 2.8, 3.8, 10.0] {
            let parts = core_and_wings(kurtosis);
            let share: f64 = parts.iter().map(|p| p.0).sum();
            let second: f64 = parts.iter().map(|p| p.0 * p.1).sum();
            let fourth: f64 = parts.iter().map(|p| p.0 * p.1 * p.1).sum();
            assert!((share - 1.0).abs() < 1e-12, "κ {kurtosis}: shares {share}");
            assert!((second - 1.0).abs() < 1e-12, "κ {kurtosis}: variance {second}");
            assert!(
                (fourth / (second * second) - kurtosis).abs() < 1e-12 * kurtosis,
                "κ {kurtosis}: {fourth}"
            );
            assert!(parts.iter().all(|p| p.1 >= 0.0), "κ {kurtosis}: {parts:?}");
        }
        // Flatter than a Gaussian is out of reach of a mixture about one centre: one Gaussian.
        assert_eq!(core_and_wings(0.84), [(0.5, 1.0), (0.5, 1.0)]);
        assert_eq!(core_and_wings(f64::NAN), [(0.5, 1.0), (0.5, 1.0)]);
        // The narrow beam's cloud (b = 0.05 /voxel, g = 0.9, 48 voxels) has wide wings: κ is
        // 1.83 there (the recurrence), which puts half the light at 0.09 of the variance and
        // half at 1.91. The bounds (κ > 1.5, wings over twice the core) hold with that margin
        // and fail for a Gaussian cloud (κ 1, both parts alike).
        let mut m = SpreadMoments::default();
        m.step(0.05, 0.9, 48.0);
        let [core, wings] = m.scattered_cloud();
        assert!(
            m.scattered_kurtosis() > 1.5 && wings.1 > 2.0 * core.1,
            "{:?}",
            m.scattered_cloud()
        );
    }

    #[test]
    fn the_table_follows_the_curves() {
        let mut tf = TransferFunctions::default();
        assert!(scattering_table(&tf).iter().all(|e| *e == [0.0; 4]));
        tf.albedo = Some(crate::transfer::Curve {
            points: vec![[0.0, 0.0], [1.0, 1.0]],
        });
        tf.anisotropy = Some(crate::transfer::Curve::constant(0.6));
        let t = scattering_table(&tf);
        assert_eq!(t.len(), TABLE_SIZE);
        assert_eq!(t[TABLE_SIZE - 1], [1.0, 0.6, 1.0, 0.0]);
        assert!((t[TABLE_SIZE / 2][0] - 0.5).abs() < 1.0 / TABLE_SIZE as f32);
        // Where ω is 0 (x = 0) or there are no particles, nothing scatters.
        assert_eq!(t[0][2], 0.0);
        tf.opacity = crate::transfer::Curve::constant(0.0);
        assert!(scattering_table(&tf).iter().all(|e| e[2] == 0.0));
    }
}
