//! Pre-integration of the transfer functions over a ray segment between two samples.
//!
//! Table entry (f, b) describes a segment of `sample_distance` voxels along which the data
//! value goes linearly from f to b. Opacity and medium are stored as optical depths
//! (τ = −ln transmittance): they scale linearly with segment length, so the shaders can
//! correct for segments longer than Δs exactly, and they keep their relative precision in
//! 16-bit floats where a transmittance of 0.9999 would not.

use super::TransferFunctions;

/// Entries per axis of the 2D tables.
pub const TABLE_SIZE: usize = 256;

/// Optical depth of one voxel at α = 1. e^-16 ≈ 1e-7: fully opaque for any 8-bit or 16-bit
/// output, and finite, so that α = 1 does not produce infinities in the tables.
pub const MAX_OPTICAL_DEPTH_PER_VOXEL: f32 = 16.0;

/// Sub-steps at most per table entry; the data value changes by at most 1/64 per sub-step.
const MAX_SUBSTEPS: usize = 64;

/// The pre-integrated tables, `TABLE_SIZE²` entries each, row = back value b, column = front f.
pub struct PreintegratedTables {
    /// rgb: particle colour premultiplied by the segment opacity; a: opacity optical depth τ_α.
    pub particle: Vec<[f32; 4]>,
    /// rgb: medium optical depth τ_m per channel; a: unused (0).
    pub medium: Vec<[f32; 4]>,
    pub sample_distance: f32,
}

fn optical_depth(transmittance: f32) -> f32 {
    if transmittance <= 0.0 {
        MAX_OPTICAL_DEPTH_PER_VOXEL
    } else {
        (-transmittance.ln()).clamp(0.0, MAX_OPTICAL_DEPTH_PER_VOXEL)
    }
}

/// Builds the tables for segments of `sample_distance` voxels.
pub fn preintegrate(tf: &TransferFunctions, sample_distance: f32) -> PreintegratedTables {
    let n = TABLE_SIZE;
    // Per-voxel quantities on a fine 1D grid; table entries average them along the segment.
    let fine = n * 4;
    let at = |i: usize| i as f32 / (fine - 1) as f32;
    let tau_a: Vec<f32> = (0..fine).map(|i| optical_depth(1.0 - tf.opacity.eval(at(i)))).collect();
    let color: Vec<[f32; 3]> = (0..fine).map(|i| tf.color.eval(at(i))).collect();
    let tau_m: Vec<[f32; 3]> = (0..fine).map(|i| tf.medium.eval(at(i)).map(optical_depth)).collect();
    let sample = |x: f32| -> usize { ((x.clamp(0.0, 1.0) * (fine - 1) as f32).round()) as usize };

    let mut particle = vec![[0.0f32; 4]; n * n];
    let mut medium = vec![[0.0f32; 4]; n * n];
    for b in 0..n {
        for f in 0..n {
            let xf = f as f32 / (n - 1) as f32;
            let xb = b as f32 / (n - 1) as f32;
            let steps = (f.abs_diff(b) * 4).clamp(1, MAX_SUBSTEPS);
            let dl = sample_distance / steps as f32;
            let (mut rgb, mut tau_total, mut m) = ([0.0f32; 3], 0.0f32, [0.0f32; 3]);
            for k in 0..steps {
                let x = xf + (xb - xf) * (k as f32 + 0.5) / steps as f32;
                let i = sample(x);
                let a = 1.0 - (-tau_a[i] * dl).exp();
                let t_before = (-tau_total).exp();
                for c in 0..3 {
                    rgb[c] += t_before * a * color[i][c];
                    m[c] += tau_m[i][c] * dl;
                }
                tau_total += tau_a[i] * dl;
            }
            particle[b * n + f] = [rgb[0], rgb[1], rgb[2], tau_total];
            medium[b * n + f] = [m[0], m[1], m[2], 0.0];
        }
    }
    PreintegratedTables {
        particle,
        medium,
        sample_distance,
    }
}

impl PreintegratedTables {
    /// Bilinear lookup, as the GPU sampler does with clamp-to-edge at texel centres.
    pub fn lookup(table: &[[f32; 4]], front: f32, back: f32) -> [f32; 4] {
        let n = TABLE_SIZE;
        let pos = |x: f32| x.clamp(0.0, 1.0) * (n - 1) as f32;
        let (u, v) = (pos(front), pos(back));
        let (u0, v0) = (u.floor() as usize, v.floor() as usize);
        let (u1, v1) = ((u0 + 1).min(n - 1), (v0 + 1).min(n - 1));
        let (fu, fv) = (u - u0 as f32, v - v0 as f32);
        let mut out = [0.0f32; 4];
        for (c, o) in out.iter_mut().enumerate() {
            let a = table[v0 * n + u0][c] * (1.0 - fu) + table[v0 * n + u1][c] * fu;
            let b = table[v1 * n + u0][c] * (1.0 - fu) + table[v1 * n + u1][c] * fu;
            *o = a * (1.0 - fv) + b * fv;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::{ColorRamp, Curve};

    fn tf(alpha: f32, medium: f32) -> TransferFunctions {
        TransferFunctions {
            name: None,
            opacity: Curve::constant(alpha),
            color: ColorRamp::constant([1.0, 0.5, 0.25]),
            eta: Curve::constant(1.0),
            medium: ColorRamp::constant([medium; 3]),
            albedo: None,
            anisotropy: None,
        }
    }

    #[test]
    fn constant_opacity_matches_length_rescaling() {
        // A homogeneous segment of d voxels must transmit (1 - α)^d.
        for d in [0.25f32, 1.0, 2.0] {
            let t = preintegrate(&tf(0.3, 0.9), d);
            let e = PreintegratedTables::lookup(&t.particle, 0.5, 0.5);
            assert!(((-e[3]).exp() - 0.7f32.powf(d)).abs() < 1e-5);
            // premultiplied colour = colour * opacity of the segment
            assert!((e[0] - (1.0 - 0.7f32.powf(d))).abs() < 1e-4, "{e:?}");
            let m = PreintegratedTables::lookup(&t.medium, 0.1, 0.9);
            assert!(((-m[0]).exp() - 0.9f32.powf(d)).abs() < 1e-5);
        }
    }

    #[test]
    fn full_opacity_stays_finite() {
        let t = preintegrate(&tf(1.0, 0.0), 1.0);
        assert!(t.particle.iter().chain(&t.medium).flatten().all(|v| v.is_finite()));
        assert_eq!(t.particle[0][3], MAX_OPTICAL_DEPTH_PER_VOXEL);
    }

    #[test]
    fn segment_averages_a_ramp() {
        // Opacity 0 below 0.5 and 1 above: a segment from 0 to 1 is half opaque, one from 0 to
        // 0.4 is clear.
        let mut t = tf(0.0, 1.0);
        t.opacity = Curve {
            points: vec![[0.0, 0.0], [0.5, 0.0], [0.5, 0.5]],
        };
        let tables = preintegrate(&t, 1.0);
        let clear = PreintegratedTables::lookup(&tables.particle, 0.0, 0.4);
        let mixed = PreintegratedTables::lookup(&tables.particle, 0.0, 1.0);
        assert!(clear[3] < 1e-6);
        let expected = -(0.5f32.ln()) * 0.5; // half the segment at α = 0.5
        assert!((mixed[3] - expected).abs() < 0.02, "{mixed:?} vs {expected}");
    }
}
