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

/// Fine cells per table entry: entry f's value f/(n−1) is the edge of cell f·4, so a segment
/// between two entries crosses whole cells only.
const CELLS_PER_ENTRY: usize = 4;

/// Cells of the fine 1D grid on which the transfer functions are averaged.
const FINE_CELLS: usize = (TABLE_SIZE - 1) * CELLS_PER_ENTRY;

/// Samples per fine cell when averaging the transfer functions over it.
const CELL_SAMPLES: usize = 8;

/// The pre-integrated tables, `TABLE_SIZE²` entries each, row = back value b, column = front f.
pub struct PreintegratedTables {
    /// rgb: particle colour premultiplied by the segment opacity; a: opacity optical depth τ_α.
    pub particle: Vec<[f32; 4]>,
    /// rgb: medium optical depth τ_m per channel; a: τ_α again, so that one lookup gives a
    /// segment's whole transmittance (particles and medium), which the light needs and the
    /// view's light line: half the lookups of reading both tables.
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
///
/// Every segment between entries d apart spends the same length in each cell it crosses, and
/// the segments from f = 0, 1, 2, … are windows of 4d cells sliding along the cells by 4: each
/// window's composite comes from two partial composites of fixed blocks (van Herk–Gil-Werman),
/// three compositions per cell and d instead of 4d per entry. The colour composite is the
/// "over" operator, associative but not invertible (a cell may be opaque), so the windows are
/// not running sums. This takes the tables from about a tenth of a second to a few ms, which
/// the viewer spends at every edit of the transfer functions and change of level.
pub fn preintegrate(tf: &TransferFunctions, sample_distance: f32) -> PreintegratedTables {
    use rayon::prelude::*;
    let n = TABLE_SIZE;
    let cells = fine_cells(tf);
    let length = f64::from(sample_distance);
    // Per d = |b − f| > 0: the entries (f, f + d) and (f + d, f), front to back.
    let diagonals: Vec<(Vec<Segment>, Vec<Segment>)> = (1..n)
        .into_par_iter()
        .map(|d| {
            // The length a segment spends in each cell it crosses.
            let dl = length / (d * CELLS_PER_ENTRY) as f64;
            let mut forward: Vec<Segment> = cells.iter().map(|c| Segment::cell(c, dl)).collect();
            let window = d * CELLS_PER_ENTRY;
            let up = sliding(&forward, window, CELLS_PER_ENTRY);
            // Value falling from f to b = f − d: the cells from f's edge down to b's.
            forward.reverse();
            let mut down = sliding(&forward, window, CELLS_PER_ENTRY);
            // The window from the top edge, 4(n−1) − 4f, is entry (f, f − d) for f = n − 1, …, d.
            down.reverse();
            (up, down)
        })
        .collect();
    let mut particle = vec![[0.0f32; 4]; n * n];
    let mut medium = vec![[0.0f32; 4]; n * n];
    for f in 0..n {
        // A constant value: the transfer functions at that value, over the whole length.
        let c = cell_at(tf, f as f32 / (n - 1) as f32);
        let a = 1.0 - (-c.tau_a * sample_distance).exp();
        particle[f * n + f] = [
            a * c.color[0],
            a * c.color[1],
            a * c.color[2],
            c.tau_a * sample_distance,
        ];
        let m = c.tau_m.map(|t| t * sample_distance);
        medium[f * n + f] = [m[0], m[1], m[2], c.tau_a * sample_distance];
    }
    // Row = back value b, column = front f.
    for (d, (up, down)) in (1..n).zip(diagonals) {
        for (f, s) in up.into_iter().enumerate() {
            let b = f + d;
            (particle[b * n + f], medium[b * n + f]) = s.texels();
        }
        for (b, s) in down.into_iter().enumerate() {
            let f = b + d;
            (particle[b * n + f], medium[b * n + f]) = s.texels();
        }
    }
    PreintegratedTables {
        particle,
        medium,
        sample_distance,
    }
}

/// A run of fine cells crossed front to back: the colour it sends back and the fraction of
/// light it lets through (composited "over"), and its optical depths.
#[derive(Clone, Copy)]
struct Segment {
    rgb: [f64; 3],
    through: f64,
    tau: f64,
    medium: [f64; 3],
}

impl Segment {
    /// One fine cell crossed over `dl` voxels.
    fn cell(c: &Cell, dl: f64) -> Segment {
        let tau = f64::from(c.tau_a) * dl;
        let a = -(-tau).exp_m1();
        Segment {
            rgb: c.color.map(|x| a * f64::from(x)),
            through: 1.0 - a,
            tau,
            medium: c.tau_m.map(|t| f64::from(t) * dl),
        }
    }

    /// `self` in front of `back`.
    fn then(&self, back: &Segment) -> Segment {
        Segment {
            rgb: [0, 1, 2].map(|i| self.rgb[i] + self.through * back.rgb[i]),
            through: self.through * back.through,
            tau: self.tau + back.tau,
            medium: [0, 1, 2].map(|i| self.medium[i] + back.medium[i]),
        }
    }

    /// The particle and medium table texels: colour premultiplied by the segment's opacity
    /// and τ_α; τ_m per channel and τ_α.
    fn texels(&self) -> ([f32; 4], [f32; 4]) {
        let [r, g, b] = self.rgb.map(|x| x as f32);
        let [mr, mg, mb] = self.medium.map(|x| x as f32);
        ([r, g, b, self.tau as f32], [mr, mg, mb, self.tau as f32])
    }
}

/// The composites of the windows of `len` cells starting at 0, `step`, 2·`step`, … that fit in
/// `cells`. Blocks of `len` cells from 0: a window is a block, or a suffix of one block followed
/// by a prefix of the next.
fn sliding(cells: &[Segment], len: usize, step: usize) -> Vec<Segment> {
    let n = cells.len();
    // suffix[i]: from i to the end of i's block; prefix[i]: from the start of i's block to i.
    let mut suffix = cells.to_vec();
    let mut prefix = cells.to_vec();
    for i in 1..n {
        if i % len != 0 {
            prefix[i] = prefix[i - 1].then(&cells[i]);
        }
    }
    for i in (0..n.saturating_sub(1)).rev() {
        if (i + 1) % len != 0 {
            suffix[i] = cells[i].then(&suffix[i + 1]);
        }
    }
    (0..)
        .map(|k| k * step)
        .take_while(|&l| l + len <= n)
        .map(|l| {
            if l % len == 0 {
                suffix[l]
            } else {
                suffix[l].then(&prefix[l + len - 1])
            }
        })
        .collect()
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

    /// The tables by their definition: each entry walks the cells between its values one by
    /// one, front to back.
    fn walked(tf: &TransferFunctions, length: f64) -> PreintegratedTables {
        let n = TABLE_SIZE;
        let cells = fine_cells(tf);
        let mut particle = vec![[0.0f32; 4]; n * n];
        let mut medium = vec![[0.0f32; 4]; n * n];
        for b in 0..n {
            for f in 0..n {
                if f == b {
                    continue;
                }
                let dl = length / (f.abs_diff(b) * CELLS_PER_ENTRY) as f64;
                let order: Vec<usize> = if b > f {
                    (f * CELLS_PER_ENTRY..b * CELLS_PER_ENTRY).collect()
                } else {
                    (b * CELLS_PER_ENTRY..f * CELLS_PER_ENTRY).rev().collect()
                };
                let (mut rgb, mut through, mut tau, mut m) = ([0.0f64; 3], 1.0f64, 0.0f64, [0.0f64; 3]);
                for i in order {
                    let c = &cells[i];
                    let a = 1.0 - (-f64::from(c.tau_a) * dl).exp();
                    for ch in 0..3 {
                        rgb[ch] += through * a * f64::from(c.color[ch]);
                        m[ch] += f64::from(c.tau_m[ch]) * dl;
                    }
                    through *= 1.0 - a;
                    tau += f64::from(c.tau_a) * dl;
                }
                particle[b * n + f] = [rgb[0] as f32, rgb[1] as f32, rgb[2] as f32, tau as f32];
                medium[b * n + f] = [m[0] as f32, m[1] as f32, m[2] as f32, tau as f32];
            }
        }
        PreintegratedTables {
            particle,
            medium,
            sample_distance: length as f32,
        }
    }

    #[test]
    fn sliding_windows_equal_the_walk_through_every_cell() {
        // Opaque and clear stretches, a spike narrower than a cell, colour and medium that
        // vary: the windows' composites are those of the cells one by one.
        let t = TransferFunctions {
            name: None,
            opacity: Curve {
                points: vec![
                    [0.0, 0.0],
                    [0.2, 0.0],
                    [0.3, 0.9],
                    [0.31, 1.0],
                    [0.5, 0.05],
                    [0.6001, 0.7],
                    [0.6012, 0.0],
                    [1.0, 0.4],
                ],
            },
            color: ColorRamp {
                points: vec![[0.0, 1.0, 0.0, 0.0], [0.4, 0.2, 0.9, 0.1], [1.0, 0.1, 0.3, 1.0]],
            },
            eta: Curve::constant(1.0),
            medium: ColorRamp {
                points: vec![[0.0, 1.0, 1.0, 1.0], [0.5, 0.6, 0.8, 0.95], [1.0, 0.0, 1.0, 0.9]],
            },
            albedo: None,
            anisotropy: None,
        };
        for length in [0.25f32, 1.0, 3.0] {
            let fast = preintegrate(&t, length);
            let slow = walked(&t, f64::from(length));
            let n = TABLE_SIZE;
            for (table, (a, b)) in [
                ("particle", (&fast.particle, &slow.particle)),
                ("medium", (&fast.medium, &slow.medium)),
            ] {
                for i in 0..n * n {
                    if i / n == i % n {
                        continue; // the diagonal is the transfer functions at one value
                    }
                    for ch in 0..4 {
                        let (x, y) = (a[i][ch], b[i][ch]);
                        // f32 rounding of values up to 16 per voxel times 3 voxels; the
                        // compositions are in f64 both ways, in a different order.
                        assert!(
                            (x - y).abs() <= 1e-6 * (1.0 + y.abs()),
                            "{table} at Δs {length}, (f {}, b {}) channel {ch}: {x} vs {y}",
                            i % n,
                            i / n
                        );
                    }
                }
            }
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
    fn the_medium_table_carries_the_particles_optical_depth() {
        // `segment_transmittance` (common.wgsl) reads a segment's whole transmittance from the
        // medium table alone: its alpha must be the particle table's τ_α at every entry.
        let mut curves = tf(0.3, 0.9);
        curves.opacity = Curve {
            points: vec![[0.0, 0.0], [0.5, 0.9], [1.0, 0.2]],
        };
        for length in [0.25f32, 1.0] {
            let t = preintegrate(&curves, length);
            assert!(t.particle.iter().any(|p| p[3] > 0.0));
            for (i, (p, m)) in t.particle.iter().zip(&t.medium).enumerate() {
                assert_eq!(p[3].to_bits(), m[3].to_bits(), "entry {i} at Δs {length}");
            }
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
