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

/// Cells of the fine 1D grid on which the transfer functions are averaged: 4 per table entry.
const FINE_CELLS: usize = TABLE_SIZE * 4;

/// Samples per fine cell when averaging the transfer functions over it.
const CELL_SAMPLES: usize = 8;

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

/// Per-voxel optical depths and colour of the particles and the medium at one data value.
#[derive(Clone, Copy, Default)]
struct Cell {
    tau_a: f32,
    color: [f32; 3],
    tau_m: [f32; 3],
}

fn cell_at(tf: &TransferFunctions, x: f32) -> Cell {
    Cell {
        tau_a: optical_depth(1.0 - tf.opacity.eval(x)),
        color: tf.color.eval(x),
        tau_m: tf.medium.eval(x).map(optical_depth),
    }
}

/// The transfer functions averaged over each fine cell (optical depths, and the colour
/// weighted by the particles' optical depth), so that a feature narrower than a cell still
/// counts with its weight.
fn fine_cells(tf: &TransferFunctions) -> Vec<Cell> {
    (0..FINE_CELLS)
        .map(|i| {
            let mut sum = Cell::default();
            let mut weight = 0.0f32;
            let mut plain = [0.0f32; 3];
            for k in 0..CELL_SAMPLES {
                let x = (i as f32 + (k as f32 + 0.5) / CELL_SAMPLES as f32) / FINE_CELLS as f32;
                let c = cell_at(tf, x);
                sum.tau_a += c.tau_a;
                weight += c.tau_a;
                for (ch, p) in plain.iter_mut().enumerate() {
                    sum.color[ch] += c.tau_a * c.color[ch];
                    *p += c.color[ch];
                    sum.tau_m[ch] += c.tau_m[ch];
                }
            }
            let n = CELL_SAMPLES as f32;
            Cell {
                tau_a: sum.tau_a / n,
                color: if weight > 0.0 {
                    sum.color.map(|c| c / weight)
                } else {
                    plain.map(|c| c / n)
                },
                tau_m: sum.tau_m.map(|t| t / n),
            }
        })
        .collect()
}

/// Builds the tables for segments of `sample_distance` voxels. Along a segment the value goes
/// linearly from f to b, crossing the fine cells between them; each cell contributes exactly
/// (its optical depth times the length the segment spends in it, its colour attenuated by
/// everything in front), so no feature of the transfer functions is stepped over however far
/// apart f and b are.
pub fn preintegrate(tf: &TransferFunctions, sample_distance: f32) -> PreintegratedTables {
    use rayon::prelude::*;
    let n = TABLE_SIZE;
    let cells = fine_cells(tf);
    // The opacity of every fine cell for a segment that crosses it whole, per |b − f|: most of
    // an entry's cells are crossed whole, and its exponentials were most of the tables' time
    // (a tenth of a second at every change of the sample distance).
    let whole: Vec<Vec<f32>> = (0..n)
        .into_par_iter()
        .map(|d| {
            if d == 0 {
                // A constant value: `entry` takes its cell at once.
                return Vec::new();
            }
            let per_unit = segment_per_cell(sample_distance, d);
            cells.iter().map(|c| 1.0 - (-c.tau_a * per_unit).exp()).collect()
        })
        .collect();
    type Row = (Vec<[f32; 4]>, Vec<[f32; 4]>);
    let rows: Vec<Row> = (0..n)
        .into_par_iter()
        .map(|b| {
            let mut particle = vec![[0.0f32; 4]; n];
            let mut medium = vec![[0.0f32; 4]; n];
            for f in 0..n {
                let (p, m) = entry(tf, &cells, &whole[f.abs_diff(b)], f, b, sample_distance);
                particle[f] = p;
                medium[f] = m;
            }
            (particle, medium)
        })
        .collect();
    let (mut particle, mut medium) = (Vec::with_capacity(n * n), Vec::with_capacity(n * n));
    for (p, m) in rows {
        particle.extend(p);
        medium.extend(m);
    }
    PreintegratedTables {
        particle,
        medium,
        sample_distance,
    }
}

/// The length (voxels) a segment of `length` voxels from value f/(n−1) to b/(n−1) spends in
/// each fine cell it crosses whole, d = |b − f| > 0.
fn segment_per_cell(length: f32, d: usize) -> f32 {
    length * (TABLE_SIZE - 1) as f32 / (d as f32 * FINE_CELLS as f32)
}

/// One table entry: a segment of `length` voxels from value f/(n−1) to b/(n−1). `whole`: each
/// fine cell's opacity for the length this segment spends in it when it crosses it whole.
fn entry(
    tf: &TransferFunctions,
    cells: &[Cell],
    whole: &[f32],
    f: usize,
    b: usize,
    length: f32,
) -> ([f32; 4], [f32; 4]) {
    let last = (TABLE_SIZE - 1) as f32;
    let (xf, xb) = (f as f32 / last, b as f32 / last);
    if f == b {
        // A constant value: the transfer functions at that value, over the whole length.
        let c = cell_at(tf, xf);
        let a = 1.0 - (-c.tau_a * length).exp();
        let m = c.tau_m.map(|t| t * length);
        return (
            [a * c.color[0], a * c.color[1], a * c.color[2], c.tau_a * length],
            [m[0], m[1], m[2], 0.0],
        );
    }
    // Walk the cells in the order the segment meets them, each for the length it spends there.
    let fine = FINE_CELLS as f32;
    let (uf, ub) = (xf * fine, xb * fine);
    let per_unit = segment_per_cell(length, f.abs_diff(b));
    let (mut rgb, mut tau, mut through, mut m) = ([0.0f32; 3], 0.0f32, 1.0f32, [0.0f32; 3]);
    let mut visit = |i: usize, span: f32| {
        let i = i.min(FINE_CELLS - 1);
        let c = &cells[i];
        let dl = span * per_unit;
        let a = if span == 1.0 {
            whole[i]
        } else {
            1.0 - (-c.tau_a * dl).exp()
        };
        for ch in 0..3 {
            rgb[ch] += through * a * c.color[ch];
            m[ch] += c.tau_m[ch] * dl;
        }
        through *= 1.0 - a;
        tau += c.tau_a * dl;
    };
    let (lo, hi) = (uf.min(ub), uf.max(ub));
    let cells_crossed = (lo.floor() as usize)..(hi.ceil() as usize);
    let span = |i: usize| (hi.min(i as f32 + 1.0) - lo.max(i as f32)).max(0.0);
    if ub > uf {
        cells_crossed.for_each(|i| visit(i, span(i)));
    } else {
        cells_crossed.rev().for_each(|i| visit(i, span(i)));
    }
    ([rgb[0], rgb[1], rgb[2], tau], [m[0], m[1], m[2], 0.0])
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
    fn a_narrow_feature_counts_at_any_segment_span() {
        // An opaque spike 1/500 of the value range wide (narrower than 1/64, which the
        // sub-stepped integration could step over): every segment across it, whatever its
        // span, meets optical depth ≈ α-depth × length × width / span.
        let mut t = tf(0.0, 1.0);
        t.opacity = Curve {
            points: vec![[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.502, 0.5], [0.502, 0.0]],
        };
        let tables = preintegrate(&t, 1.0);
        let n = TABLE_SIZE;
        let width = 0.002f32;
        let depth = -(0.5f32.ln());
        for (f, b) in [(100, 160), (0, n - 1), (n - 1, 20)] {
            let span = (b as f32 - f as f32).abs() / (n - 1) as f32;
            let tau = tables.particle[b * n + f][3];
            let expected = depth * width / span;
            // 5 %: the spike covers two fine cells, one of them partly (8 samples each).
            assert!(
                (tau - expected).abs() < 0.05 * expected,
                "({f}, {b}): {tau} vs {expected}"
            );
        }
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
