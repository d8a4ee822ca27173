//! Which cells of a volume can change the light: where particles absorb or show (the value
//! range in the cell and one voxel around it) or where η changes (a gradient volume texel
//! within a voxel of the cell is not zero). At 8³ voxels they are the bricks the view skips
//! (`bricks.rs`); at 4³ ([`CELL`]) the light tiles of the beams start shortly before their
//! first beam comes near such a cell and, without refraction, end shortly after their last
//! beam has passed the last one (`light_tiles::spans`), and with refraction the beams deposit
//! only near them: a beam's light changes nowhere else. The finer grid for the light, because
//! its margin is added on top.

use rayon::prelude::*;

use crate::transfer::TransferFunctions;

/// Voxels per cell edge of the light's grid.
pub const CELL: usize = 4;

/// Per cell (x fastest) whether something in it or within a voxel of it changes the light;
/// the grid's cells along each axis, the voxels it covers and the voxels per cell edge.
#[derive(Clone, Debug)]
pub struct Occupancy {
    pub flags: Vec<bool>,
    pub cells: [usize; 3],
    pub voxels: [usize; 3],
    pub edge: usize,
}

/// The range of the 16-bit samples (0..65535 ↦ [0, 1]) that each cell of `edge` voxels
/// reaches (the cells at the volume's faces reach the value 0 outside it; lo > hi: none). No
/// transfer function changes it: a transfer-function edit finds the occupied cells from it
/// without reading the volume again.
#[derive(Clone, Debug)]
pub struct ValueRanges {
    ranges: Vec<[u16; 2]>,
    cells: [usize; 3],
    voxels: [usize; 3],
    edge: usize,
}

impl ValueRanges {
    /// The ranges that trilinear sampling of the volume itself reaches from each cell.
    pub fn new(samples: &[u16], dims: [usize; 3], edge: usize) -> ValueRanges {
        Extremes::new(samples, dims, edge).ranges(|v| v)
    }

    /// The ranges that trilinear sampling of the volume's half-resolution level
    /// (`coarse.rs`) reaches from each cell ([`half_level_reach`]): its texels are means of
    /// the voxels they cover, so their values lie within those voxels' range.
    pub fn half_level(samples: &[u16], dims: [usize; 3], edge: usize) -> ValueRanges {
        Extremes::half_level(samples, dims, edge).ranges(|v| v)
    }

    /// The cells along each axis.
    pub fn cells(&self) -> [usize; 3] {
        self.cells
    }

    /// The cells whose particles absorb or show under `tf`.
    pub fn visible(&self, tf: &TransferFunctions) -> Occupancy {
        Occupancy {
            flags: self
                .ranges
                .par_iter()
                .map(|&[lo, hi]| lo <= hi && super::bricks::visible(tf, lo as f32 / 65535.0, hi as f32 / 65535.0))
                .collect(),
            cells: self.cells,
            voxels: self.voxels,
            edge: self.edge,
        }
    }
}

/// A volume's values as [`Extremes`] reduces them: the 16-bit samples, or the volume's own
/// values before a data window.
pub trait Value: Copy + PartialOrd + Send + Sync {
    /// The extremes of no value: above and below every value.
    const NONE: [Self; 2];
}

impl Value for u16 {
    const NONE: [u16; 2] = [u16::MAX, 0];
}

impl Value for f32 {
    const NONE: [f32; 2] = [f32::INFINITY, f32::NEG_INFINITY];
}

/// Per cell of `edge` voxels (x fastest), the extremes of the volume's values that trilinear
/// sampling reaches from it ([`Value::NONE`] where it reaches none), and whether it reaches
/// the border beyond the volume (the value 0) too.
#[derive(Clone, Debug)]
pub struct Extremes<V> {
    extremes: Vec<[V; 2]>,
    border: Vec<bool>,
    cells: [usize; 3],
    voxels: [usize; 3],
    edge: usize,
}

/// The extremes of a volume's own values (before a data window) that each cell reaches: under
/// a window, the [`ValueRanges`] of its 16-bit samples ([`RawRanges::windowed`]) without
/// normalising the volume and reading its samples again, since normalising never decreases a
/// value (`volume::normalizer`). A change of the data window maps them: on the CT head the
/// four grids' ranges took about 100 ms of the CPU's time on each change.
pub type RawRanges = Extremes<f32>;

impl<V: Value> Extremes<V> {
    /// Those that sampling the volume itself reaches.
    pub fn new(values: &[V], dims: [usize; 3], edge: usize) -> Extremes<V> {
        Self::reached(values, dims, edge, |i, n| {
            (reach(i, n, edge), i == 0 || (i + 1) * edge >= n)
        })
    }

    /// Those that sampling the volume's half-resolution level reaches
    /// ([`ValueRanges::half_level`]).
    pub fn half_level(values: &[V], dims: [usize; 3], edge: usize) -> Extremes<V> {
        Self::reached(values, dims, edge, |i, n| half_level_reach(i, n, edge))
    }

    /// `reach(i, n)`: along an axis of n voxels, the voxels that samples in cell i read, and
    /// whether they read the border beyond the volume too.
    fn reached(
        values: &[V],
        dims: [usize; 3],
        edge: usize,
        reach: impl Fn(usize, usize) -> (std::ops::Range<usize>, bool) + Sync,
    ) -> Extremes<V> {
        let cells = cells_of(dims, edge);
        let reached = [0, 1, 2].map(|a| (0..cells[a]).map(|i| reach(i, dims[a])).collect::<Vec<_>>());
        let spans = reached
            .each_ref()
            .map(|r| r.iter().map(|(span, _)| span.clone()).collect());
        let min = |a: V, b: V| if b < a { b } else { a };
        let max = |a: V, b: V| if a < b { b } else { a };
        let extremes = over_boxes(
            values,
            dims,
            &spans,
            V::NONE,
            |&v| [v, v],
            |a, b| [min(a[0], b[0]), max(a[1], b[1])],
        );
        let border = (0..extremes.len())
            .map(|c| {
                let [cx, cy, cz] = [c % cells[0], (c / cells[0]) % cells[1], c / (cells[0] * cells[1])];
                reached[0][cx].1 || reached[1][cy].1 || reached[2][cz].1
            })
            .collect();
        Extremes {
            extremes,
            border,
            cells,
            voxels: dims,
            edge,
        }
    }

    /// The ranges of the 16-bit samples that `sample` makes of the values (which it must
    /// never decrease): its extremes, from 0 where the cell reaches the border.
    fn ranges(&self, sample: impl Fn(V) -> u16 + Sync) -> ValueRanges {
        ValueRanges {
            ranges: self
                .extremes
                .par_iter()
                .zip(&self.border)
                .map(|(&[lo, hi], &border)| [if border { 0 } else { sample(lo) }, sample(hi)])
                .collect(),
            cells: self.cells,
            voxels: self.voxels,
            edge: self.edge,
        }
    }
}

impl RawRanges {
    /// The ranges of the volume's 16-bit samples under `window` (`Volume::normalized_u16`): the
    /// same as made from them, to the bit (an empty cell's infinities map to 65535 and 0, as
    /// its samples' empty range is).
    pub fn windowed(&self, window: [f32; 2]) -> ValueRanges {
        self.ranges(crate::volume::normalizer(window))
    }
}

/// The cells of `edge` voxels along each axis of `voxels` (at least one).
pub(crate) fn cells_of(voxels: [usize; 3], edge: usize) -> [usize; 3] {
    voxels.map(|d| d.div_ceil(edge).max(1))
}

/// Per box (x fastest) of `spans[0][i] × spans[1][j] × spans[2][k]` voxels of a `dims`
/// volume, `combine` of `leaf` of its voxels (`empty` where it has none): reduced along x,
/// then y, then z, so that each voxel is read once per box along x that holds it rather than
/// once per box (the boxes overlap by a voxel or more on each side). For an associative and
/// commutative `combine` (min, max, or) the same values as reducing each box at once: on the
/// CT head the cells' value ranges in 12–15 ms instead of 16.5, the half level's in 16–19
/// instead of 30.5 (where the boxes overlap most).
pub(crate) fn over_boxes<V: Sync, T: Copy + Send + Sync>(
    values: &[V],
    dims: [usize; 3],
    spans: &[Vec<std::ops::Range<usize>>; 3],
    empty: T,
    leaf: impl Fn(&V) -> T + Sync,
    combine: impl Fn(T, T) -> T + Sync,
) -> Vec<T> {
    let [nx, ny, nz] = dims;
    assert_eq!(values.len(), nx * ny * nz, "values of a {nx}×{ny}×{nz} volume");
    let [bx, by, bz] = [0, 1, 2].map(|a| spans[a].len());
    let fold = |range: std::ops::Range<usize>, at: &dyn Fn(usize) -> T| range.fold(empty, |acc, i| combine(acc, at(i)));
    // Along x: per row, each box's span of it.
    let mut rows = vec![empty; nz * ny * bx];
    rows.par_chunks_mut(ny * bx).enumerate().for_each(|(z, slice)| {
        for y in 0..ny {
            let row = &values[(z * ny + y) * nx..][..nx];
            for (i, xs) in spans[0].iter().enumerate() {
                slice[y * bx + i] = fold(xs.clone(), &|x| leaf(&row[x]));
            }
        }
    });
    // Along y: per slice.
    let mut planes = vec![empty; nz * by * bx];
    planes.par_chunks_mut(by * bx).enumerate().for_each(|(z, slice)| {
        let rows = &rows[z * ny * bx..][..ny * bx];
        for (j, ys) in spans[1].iter().enumerate() {
            for i in 0..bx {
                slice[j * bx + i] = fold(ys.clone(), &|y| rows[y * bx + i]);
            }
        }
    });
    // Along z.
    let mut out = vec![empty; bz * by * bx];
    out.par_chunks_mut(by * bx).enumerate().for_each(|(k, slice)| {
        for (c, v) in slice.iter_mut().enumerate() {
            *v = fold(spans[2][k].clone(), &|z| planes[z * by * bx + c]);
        }
    });
    out
}

/// The voxel range of cell `i` of `edge` voxels along an axis of `n` voxels, one voxel wider
/// on each side (what trilinear sampling inside the cell reaches).
fn reach(i: usize, n: usize, edge: usize) -> std::ops::Range<usize> {
    (i * edge).saturating_sub(1)..((i + 1) * edge + 1).min(n)
}

/// The voxel range that trilinear sampling of the half-resolution level reaches from cell i of
/// `edge` voxels along an axis of n voxels, and whether it reaches the border. The level's
/// texel j of m = ⌊n/2⌋ (at least 1) covers voxels [j·w, (j+1)·w), w = n/m, in edge
/// coordinates; a sample at p reads texels ⌊p/w − ½⌋ and the next. Cells at the volume's
/// faces also take the samples beyond it (a coordinate clamped to its bricks), which read the
/// border.
pub fn half_level_reach(i: usize, n: usize, edge: usize) -> (std::ops::Range<usize>, bool) {
    let m = crate::volume::half_level_side(n) as i64;
    let w = n as f64 / m as f64;
    let mut first = ((i * edge) as f64 / w - 0.5).floor() as i64;
    let mut last = (((i + 1) * edge) as f64 / w - 0.5).floor() as i64 + 1;
    if i == 0 {
        first = -1;
    }
    if (i + 1) * edge >= n {
        last = m;
    }
    let border = first < 0 || last >= m;
    let (first, last) = (first.clamp(0, m - 1) as f64, last.clamp(0, m - 1) as f64);
    let lo = (first * w).floor() as usize;
    let hi = (((last + 1.0) * w).ceil() as usize).min(n);
    (lo..hi, border)
}

impl Occupancy {
    /// The cells of [`CELL`] voxels where η changes: a texel of the gradient volume
    /// (`gradient.rs`) within a voxel of the cell changes η, as `bends` says of each
    /// ([`super::gradient::bend_map`]).
    pub fn refracting(bends: &[bool], dims: [usize; 3]) -> Occupancy {
        let cells = cells_of(dims, CELL);
        let spans = [0, 1, 2].map(|a| (0..cells[a]).map(|i| reach(i, dims[a], CELL)).collect::<Vec<_>>());
        Occupancy {
            flags: over_boxes(bends, dims, &spans, false, |&b| b, |a, b| a || b),
            cells,
            voxels: dims,
            edge: CELL,
        }
    }

    fn at(&self, c: [usize; 3]) -> bool {
        self.flags[(c[2] * self.cells[1] + c[1]) * self.cells[0] + c[0]]
    }

    /// Cells of the grid per texture unit along each axis.
    fn per_unit(&self) -> [f32; 3] {
        [0, 1, 2].map(|a| self.voxels[a] as f32 / self.edge as f32)
    }

    /// The cells by which [`Occupancy::grown`] grows the occupied ones for `margin`: what the
    /// grown grid depends on.
    pub fn growth(&self, margin: [f32; 3]) -> [usize; 3] {
        let per_unit = self.per_unit();
        [0, 1, 2].map(|a| (margin[a] * per_unit[a]).max(0.0).ceil() as usize)
    }

    /// The grid with every occupied cell grown by `margin` (texture units along each axis,
    /// the volume's box being [0, 1]³), for [`Grown::span`].
    pub fn grown(&self, margin: [f32; 3]) -> Grown {
        let per_unit = self.per_unit();
        let d = self.growth(margin);
        let size = [0, 1, 2].map(|a| self.cells[a] + 2 * d[a]);
        // Separable: grow along x, then y, then z (a box of (2d+1)³ cells about each), each
        // line in one pass either way whatever the margin (the interactive level's coarse
        // planes and beams grow the cells by several).
        let mut flags = vec![false; size[0] * size[1] * size[2]];
        let index = |c: [usize; 3]| (c[2] * size[1] + c[1]) * size[0] + c[0];
        for z in 0..self.cells[2] {
            for y in 0..self.cells[1] {
                for x in 0..self.cells[0] {
                    flags[index([x + d[0], y + d[1], z + d[2]])] = self.at([x, y, z]);
                }
            }
        }
        for (axis, &by) in d.iter().enumerate() {
            flags = dilate(&flags, size, axis, by);
        }
        Grown {
            flags,
            size,
            offset: d,
            per_unit,
        }
    }
}

/// `flags` (a grid of `size` cells, x fastest) with every set cell grown by `d` cells both
/// ways along `axis`: per line, the distance to the last set cell forward and to the next
/// backward.
fn dilate(flags: &[bool], size: [usize; 3], axis: usize, d: usize) -> Vec<bool> {
    if d == 0 {
        return flags.to_vec();
    }
    let stride = [1, size[0], size[0] * size[1]][axis];
    let n = size[axis];
    let mut out = vec![false; flags.len()];
    // Each line's first cell: every `stride`-th run of `stride` cells in each block of n lines.
    let starts = (0..flags.len())
        .step_by(stride * n)
        .flat_map(|block| block..block + stride);
    for start in starts {
        let mut last = None;
        for i in 0..n {
            if flags[start + i * stride] {
                last = Some(i);
            }
            if last.is_some_and(|l| i - l <= d) {
                out[start + i * stride] = true;
            }
        }
        let mut next = None;
        for i in (0..n).rev() {
            if flags[start + i * stride] {
                next = Some(i);
            }
            if next.is_some_and(|m| m - i <= d) {
                out[start + i * stride] = true;
            }
        }
    }
    out
}

/// An [`Occupancy`] grown by a margin, padded by the growth on every side.
pub struct Grown {
    flags: Vec<bool>,
    size: [usize; 3],
    /// Cells of padding before the volume's cell 0 along each axis.
    offset: [usize; 3],
    per_unit: [f32; 3],
}

impl Grown {
    /// The grid as the shaders read it (`deposit_cells` in common.wgsl): a header of cells
    /// along each axis (and a word for the caller), the padding before cell 0 and cells per
    /// texture unit (as f32 bits),
    /// then one word per cell (x fastest), 1 where occupied. `others` (grown by the same
    /// margin over the same box, e.g. the η grid of other dims) are merged in: a cell counts
    /// where any of theirs that overlaps it does.
    pub fn words(&self, others: &[Grown]) -> Vec<u32> {
        let [sx, sy, sz] = self.size;
        let mut words = vec![
            sx as u32,
            sy as u32,
            sz as u32,
            0,
            self.offset[0] as u32,
            self.offset[1] as u32,
            self.offset[2] as u32,
            0,
            self.per_unit[0].to_bits(),
            self.per_unit[1].to_bits(),
            self.per_unit[2].to_bits(),
            0,
        ];
        words.reserve(sx * sy * sz);
        for z in 0..sz {
            for y in 0..sy {
                for x in 0..sx {
                    let c = [x, y, z];
                    let mut occupied = self.flags[(z * sy + y) * sx + x];
                    if !occupied {
                        // The cell's box in texture coordinates, then in each other grid.
                        let lo = [0, 1, 2].map(|a| (c[a] as f32 - self.offset[a] as f32) / self.per_unit[a]);
                        let hi = [0, 1, 2].map(|a| (c[a] as f32 + 1.0 - self.offset[a] as f32) / self.per_unit[a]);
                        occupied = others.iter().any(|o| o.any_in(lo, hi));
                    }
                    words.push(u32::from(occupied));
                }
            }
        }
        words
    }

    /// Whether an occupied cell overlaps the box [lo, hi] (texture coordinates).
    fn any_in(&self, lo: [f32; 3], hi: [f32; 3]) -> bool {
        let range = |a: usize| {
            let g = |t: f32| t * self.per_unit[a] + self.offset[a] as f32;
            let first = g(lo[a]).floor().max(0.0) as usize;
            let last = (g(hi[a]).ceil().max(0.0) as usize).min(self.size[a]);
            first..last
        };
        let (xs, ys) = (range(0), range(1));
        range(2).any(|z| {
            ys.clone().any(|y| {
                xs.clone()
                    .any(|x| self.flags[(z * self.size[1] + y) * self.size[0] + x])
            })
        })
    }

    /// The part of the line q0 + dq·s, s in [s0, s1] (texture coordinates), that passes
    /// through occupied cells: from where it enters the first to where it leaves the last
    /// (cells traversed exactly, Amanatides and Woo), or None.
    pub fn span(&self, q0: glam::Vec3, dq: glam::Vec3, s0: f32, s1: f32) -> Option<(f32, f32)> {
        self.traverse(q0, dq, s0, s1, false)
    }

    /// Where the line q0 + dq·s, s in [s0, s1], enters its first occupied cell, or None: the
    /// first value of [`Grown::span`], without traversing the cells beyond that one.
    pub fn entry(&self, q0: glam::Vec3, dq: glam::Vec3, s0: f32, s1: f32) -> Option<f32> {
        self.traverse(q0, dq, s0, s1, true).map(|(first, _)| first)
    }

    /// [`Grown::span`], stopping at the first occupied cell with `first_only`.
    fn traverse(&self, q0: glam::Vec3, dq: glam::Vec3, s0: f32, s1: f32, first_only: bool) -> Option<(f32, f32)> {
        // Grid coordinates: cell c spans [c, c + 1) along each axis.
        let a = [0, 1, 2].map(|i| q0[i] * self.per_unit[i] + self.offset[i] as f32);
        let b = [0, 1, 2].map(|i| dq[i] * self.per_unit[i]);
        // Clip the segment to the grid's box.
        let (mut t0, mut t1) = (s0, s1);
        for i in 0..3 {
            let hi = self.size[i] as f32;
            if b[i].abs() < 1e-20 {
                if a[i] < 0.0 || a[i] >= hi {
                    return None;
                }
            } else {
                let (ta, tb) = ((0.0 - a[i]) / b[i], (hi - a[i]) / b[i]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
        }
        if t0 > t1 {
            return None;
        }
        let mut cell = [0usize; 3];
        let mut step = [0isize; 3];
        let mut next = [f32::INFINITY; 3];
        let mut delta = [f32::INFINITY; 3];
        for i in 0..3 {
            let p = a[i] + b[i] * t0;
            cell[i] = (p.floor().max(0.0) as usize).min(self.size[i] - 1);
            if b[i] > 1e-20 {
                step[i] = 1;
                next[i] = (cell[i] as f32 + 1.0 - a[i]) / b[i];
                delta[i] = 1.0 / b[i];
            } else if b[i] < -1e-20 {
                step[i] = -1;
                next[i] = (cell[i] as f32 - a[i]) / b[i];
                delta[i] = -1.0 / b[i];
            }
        }
        let mut found: Option<(f32, f32)> = None;
        let mut t = t0;
        loop {
            let axis = (0..3).min_by(|&i, &j| next[i].total_cmp(&next[j])).unwrap_or(0);
            let leave = next[axis].min(t1);
            if self.flags[(cell[2] * self.size[1] + cell[1]) * self.size[0] + cell[0]] {
                found = Some((found.map_or(t, |f| f.0), leave));
                if first_only {
                    break;
                }
            }
            if next[axis] >= t1 {
                break;
            }
            t = next[axis];
            let c = cell[axis] as isize + step[axis];
            if c < 0 || c >= self.size[axis] as isize {
                break;
            }
            cell[axis] = c as usize;
            next[axis] += delta[axis];
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Every voxel that trilinear sampling of the half-resolution level reads from a point in
    /// a cell is within the cell's reach, and the border where a tap falls beyond the level:
    /// sides odd and even, cells of 4 and 8 voxels, points a sixteenth of a voxel apart
    /// (and two voxels beyond the faces, which the face cells take).
    #[test]
    fn the_half_level_reach_covers_every_voxel_its_samples_read() {
        for n in [1usize, 2, 3, 5, 8, 17, 24, 31, 108] {
            let m = crate::volume::half_level_side(n) as i64;
            let w = n as f64 / m as f64;
            for edge in [4usize, 8] {
                let cells = n.div_ceil(edge);
                for i in 0..cells {
                    let (range, border) = half_level_reach(i, n, edge);
                    let lo = if i == 0 { -2.0 } else { (i * edge) as f64 };
                    let hi = if i + 1 == cells {
                        n as f64 + 2.0
                    } else {
                        ((i + 1) * edge) as f64
                    };
                    let mut p = lo;
                    while p < hi {
                        let j0 = (p / w - 0.5).floor() as i64;
                        for j in [j0, j0 + 1] {
                            if j < 0 || j >= m {
                                assert!(border, "n {n}, edge {edge}, cell {i}: p {p} reads the border");
                                continue;
                            }
                            let first = (j as f64 * w).floor() as usize;
                            let last = (((j + 1) as f64 * w).ceil() as usize).min(n);
                            assert!(
                                range.start <= first && last <= range.end,
                                "n {n}, edge {edge}, cell {i}: p {p} reads voxels {first}..{last}, reach {range:?}"
                            );
                        }
                        p += 1.0 / 16.0;
                    }
                    // Not the whole axis: a texel and a half of two voxels or so beyond the cell.
                    assert!(range.len() <= edge + 2 * (1.5 * w).ceil() as usize + 2, "{range:?}");
                }
            }
        }
    }

    /// The extremes of the volume's own values, mapped through a window, are the ranges made
    /// from its samples under that window, to the bit: at both levels and both grids, for a
    /// window inside the values, one that clips them on both sides, one beyond them, and an
    /// empty one (a threshold).
    #[test]
    fn windowed_extremes_give_the_ranges_of_the_windowed_samples() {
        let dims = [23, 18, 13];
        let data: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|i| ((i as f32 * 0.618).fract() * 3000.0 - 1000.0) * if i % 7 == 0 { 0.1 } else { 1.0 })
            .collect();
        for window in [[-1000.0, 2000.0], [-20.0, 35.5], [2500.0, 4000.0], [100.0, 100.0]] {
            let normalize = crate::volume::normalizer(window);
            let samples: Vec<u16> = data.iter().map(|&v| normalize(v)).collect();
            for edge in [CELL, crate::render::bricks::BRICK] {
                let pairs = [
                    (
                        RawRanges::new(&data, dims, edge),
                        ValueRanges::new(&samples, dims, edge),
                    ),
                    (
                        RawRanges::half_level(&data, dims, edge),
                        ValueRanges::half_level(&samples, dims, edge),
                    ),
                ];
                for (level, (raw, made)) in pairs.into_iter().enumerate() {
                    let mapped = raw.windowed(window);
                    assert_eq!(
                        mapped.ranges, made.ranges,
                        "window {window:?}, edge {edge}, level {level}"
                    );
                    assert_eq!(
                        (mapped.cells, mapped.voxels, mapped.edge),
                        (made.cells, made.voxels, made.edge)
                    );
                }
            }
        }
    }

    #[test]
    fn reducing_along_each_axis_in_turn_gives_each_boxs_own_reduction() {
        // Boxes that overlap, that are empty, that hold one voxel and that span an axis.
        let dims = [11usize, 7, 5];
        let spans = [
            vec![0..3, 2..6, 5..5, 4..11, 10..11],
            vec![0..7, 1..2, 3..3, 2..5],
            vec![0..2, 1..5, 4..5],
        ];
        let n: usize = dims.iter().product();
        // A hash of the index: values in no order along any axis.
        let values: Vec<u16> = (0..n)
            .map(|i| ((i as u32).wrapping_mul(2_654_435_761) >> 16) as u16)
            .collect();
        let got = over_boxes(
            &values,
            dims,
            &spans,
            [u16::MAX, 0],
            |&v| [v, v],
            |a, b| [a[0].min(b[0]), a[1].max(b[1])],
        );
        let mut want = Vec::new();
        for zs in &spans[2] {
            for ys in &spans[1] {
                for xs in &spans[0] {
                    let mut r = [u16::MAX, 0];
                    for z in zs.clone() {
                        for y in ys.clone() {
                            for x in xs.clone() {
                                let v = values[(z * dims[1] + y) * dims[0] + x];
                                r = [r[0].min(v), r[1].max(v)];
                            }
                        }
                    }
                    want.push(r);
                }
            }
        }
        assert_eq!(got, want);
    }

    /// Growing is a box of (2d+1) cells per axis about every occupied cell: against a brute
    /// force over a scattered grid, margins of 0 to several cells, different per axis.
    #[test]
    fn growing_matches_a_box_about_every_occupied_cell() {
        let cells = [7, 5, 6];
        let flags: Vec<bool> = (0..cells[0] * cells[1] * cells[2])
            .map(|i| (i * 37 + i / 5) % 11 == 0)
            .collect();
        let occ = Occupancy {
            flags: flags.clone(),
            cells,
            voxels: [28, 20, 24],
            edge: 4,
        };
        for d in [[0usize, 0, 0], [1, 0, 2], [3, 2, 1], [6, 5, 4]] {
            // Margins in texture units that give exactly d cells.
            let margin = [0, 1, 2].map(|a| d[a] as f32 / cells[a] as f32);
            let g = occ.grown(margin);
            assert_eq!(g.offset, d);
            for z in 0..g.size[2] {
                for y in 0..g.size[1] {
                    for x in 0..g.size[0] {
                        let c = [x, y, z];
                        let expected = (0..cells[2]).any(|cz| {
                            (0..cells[1]).any(|cy| {
                                (0..cells[0]).any(|cx| {
                                    flags[(cz * cells[1] + cy) * cells[0] + cx]
                                        && [cx, cy, cz]
                                            .iter()
                                            .enumerate()
                                            .all(|(a, &o)| (o + d[a]).abs_diff(c[a]) <= d[a])
                                })
                            })
                        });
                        let got = g.flags[(z * g.size[1] + y) * g.size[0] + x];
                        assert_eq!(got, expected, "cell {c:?}, margin {d:?}");
                    }
                }
            }
        }
    }

    /// One occupied cell in an 8³-cell grid: the span of lines through, beside and past it,
    /// against the cell's box grown by the margin.
    #[test]
    fn a_line_finds_the_grown_cells_it_crosses() {
        let voxels = [32, 32, 32];
        let mut occ = Occupancy {
            flags: vec![false; 8 * 8 * 8],
            cells: [8, 8, 8],
            voxels,
            edge: CELL,
        };
        // Cell (3, 4, 5): texture [3/8, 4/8) × [4/8, 5/8) × [5/8, 6/8).
        occ.flags[(5 * 8 + 4) * 8 + 3] = true;
        // A margin of one and a half cells grows it by two cells each way.
        let g = occ.grown([1.5 / 8.0; 3]);
        // Along z through the cell's column: enters at z = 3/8, leaves at 8/8.
        let q = Vec3::new(3.5 / 8.0, 4.5 / 8.0, 0.0);
        let (s0, s1) = g.span(q, Vec3::Z, 0.0, 2.0).expect("crosses the cell");
        assert!((s0 - 3.0 / 8.0).abs() < 1e-5 && (s1 - 1.0).abs() < 1e-5, "{s0} {s1}");
        // The segment clipped on both ends.
        let (s0, s1) = g.span(q, Vec3::Z, 0.5, 0.7).expect("inside");
        assert!((s0 - 0.5).abs() < 1e-6 && (s1 - 0.7).abs() < 1e-6, "{s0} {s1}");
        // Two cells to the side still hits (grown by two), three does not.
        assert!(g
            .span(Vec3::new(1.5 / 8.0, 4.5 / 8.0, 0.0), Vec3::Z, 0.0, 2.0)
            .is_some());
        assert!(g
            .span(Vec3::new(-0.5 / 8.0, 4.5 / 8.0, 0.0), Vec3::Z, 0.0, 2.0)
            .is_none());
        // A diagonal line through the grown box's corner region.
        let d = Vec3::new(1.0, 1.0, 1.0);
        let hit = g.span(Vec3::new(0.0, 1.0 / 8.0, 2.0 / 8.0), d, 0.0, 1.0);
        // Occupied cells grown: [1/8, 6/8) × [2/8, 7/8) × [3/8, 8/8); the line enters at
        // s = 1/8 (y and z already inside from s = 1/8 and 1/8) and leaves at x = 6/8.
        let (s0, s1) = hit.expect("diagonal");
        assert!(
            (s0 - 1.0 / 8.0).abs() < 1e-5 && (s1 - 6.0 / 8.0).abs() < 1e-5,
            "{s0} {s1}"
        );
    }

    /// The words the shaders read: the header, the grid's own cells, and a finer grid's
    /// occupied cell merged into the coarse cell it overlaps.
    #[test]
    fn the_deposit_grid_merges_grids_of_other_dims() {
        let mut coarse = Occupancy {
            flags: vec![false; 8 * 8 * 8],
            cells: [8, 8, 8],
            voxels: [32, 32, 32],
            edge: CELL,
        };
        coarse.flags[(5 * 8 + 4) * 8 + 3] = true;
        // Twice the voxels over the same box: its cell (12, 2, 2) is the coarse cell (6, 1, 1).
        let mut fine = Occupancy {
            flags: vec![false; 16 * 16 * 16],
            cells: [16, 16, 16],
            voxels: [64, 64, 64],
            edge: CELL,
        };
        fine.flags[(2 * 16 + 2) * 16 + 12] = true;
        let margin = [0.5 / 8.0; 3]; // half a coarse cell: one cell each way on both grids
        let words = coarse.grown(margin).words(&[fine.grown(margin)]);
        assert_eq!(&words[..8], &[10, 10, 10, 0, 1, 1, 1, 0]);
        assert_eq!(f32::from_bits(words[8]), 8.0);
        let at = |c: [usize; 3]| words[12 + ((c[2] + 1) * 10 + c[1] + 1) * 10 + c[0] + 1];
        // The coarse grid's cell, grown by one.
        assert_eq!(at([3, 4, 5]), 1);
        assert_eq!(at([2, 3, 4]), 1);
        assert_eq!(at([1, 4, 5]), 0);
        // The fine cell grown by one fine cell (half a coarse one) on each side overlaps the
        // coarse cells 5..=6 along x and 0..=1 along y and z.
        assert_eq!(at([6, 1, 1]), 1);
        assert_eq!(at([5, 0, 0]), 1);
        assert_eq!(at([7, 1, 1]), 0);
        assert_eq!(at([6, 2, 1]), 0);
        assert_eq!(words.len(), 12 + 1000);
    }

    #[test]
    fn cells_occupy_where_particles_show_or_eta_changes() {
        use crate::transfer::{ColorRamp, Curve};
        let dims = [16, 16, 16];
        let mut samples = vec![0u16; 16 * 16 * 16];
        samples[(9 * 16 + 9) * 16 + 9] = 60000;
        let tf = TransferFunctions {
            name: None,
            opacity: Curve {
                points: vec![[0.0, 0.0], [0.5, 0.0], [0.6, 1.0]],
            },
            color: ColorRamp::constant([1.0; 3]),
            eta: Curve::constant(1.0),
            medium: ColorRamp {
                points: vec![[0.0, 1.0, 1.0, 1.0]],
            },
            albedo: None,
            anisotropy: None,
        };
        let v = ValueRanges::new(&samples, dims, CELL).visible(&tf);
        // Voxel 9 is in cell 2 and within a voxel of none other (cell 2 spans 8..12).
        assert_eq!(v.cells, [4, 4, 4]);
        assert_eq!(v.flags.iter().filter(|f| **f).count(), 1);
        assert!(v.at([2, 2, 2]));
        // Voxel 8 is within a voxel of cell 1 too.
        let mut texels = vec![[half::f16::ZERO; 4]; 16 * 16 * 16];
        texels[(8 * 16 + 9) * 16 + 9][0] = half::f16::from_f32(0.1);
        // η itself (w) does not count, only its change.
        texels[0][3] = half::f16::from_f32(0.5);
        let r = Occupancy::refracting(&super::super::gradient::bend_map(&texels), dims);
        assert_eq!(r.flags.iter().filter(|f| **f).count(), 2);
        assert!(r.at([2, 2, 2]) && r.at([2, 2, 1]));
    }
}
