//! Resampling a volume onto another grid over the same physical box: an η volume onto the
//! main volume's grid, and downsampling to fit a device's 3D-texture limits.

use super::{checked_voxel_count, Volume, VolumeError};
use rayon::prelude::*;

/// A texel's channels as floats and back (rounded and saturated to the format): what
/// [`resample_texels`] averages, for the volume's f32 samples and the device's texel formats.
pub trait Channels: Copy + Send + Sync {
    const N: usize;
    fn get(&self) -> [f32; 4];
    fn put(v: [f32; 4]) -> Self;
    /// The first [`Channels::N`] channels of [`Channels::get`] of every texel of `src`, one
    /// after another into `dst` (N floats per texel); a format whose conversion has a faster
    /// form for many texels at once overrides it (the same values).
    fn get_all(src: &[Self], dst: &mut [f32]) {
        for (d, s) in dst.chunks_exact_mut(Self::N).zip(src) {
            d.copy_from_slice(&s.get()[..Self::N]);
        }
    }
    /// [`Channels::put`] of every value of `src` into `dst` (of the same length), likewise.
    fn put_all(src: &[[f32; 4]], dst: &mut [Self]) {
        for (d, s) in dst.iter_mut().zip(src) {
            *d = Self::put(*s);
        }
    }
}

impl Channels for f32 {
    const N: usize = 1;
    fn get(&self) -> [f32; 4] {
        [*self, 0.0, 0.0, 0.0]
    }
    fn put(v: [f32; 4]) -> Self {
        v[0]
    }
}

/// Per target voxel along an axis of `n` source voxels resampled onto `m` over the same
/// extent: the source voxels it reads and their weights (summing to 1).
///
/// Downsampling (m < n) is the box filter: target voxel j spans [j·n/m, (j+1)·n/m) in edge
/// coordinates, and each source voxel counts by the part of it covered, so a thin structure
/// keeps its mean however far apart the targets are. Otherwise each target voxel interpolates
/// linearly at its centre, (j + ½)·n/m − ½ in source voxel-centre coordinates, clamped to
/// the outermost centres.
pub fn axis_weights(n: usize, m: usize) -> Vec<Vec<(usize, f32)>> {
    let width = n as f64 / m as f64;
    (0..m)
        .map(|j| {
            if m < n {
                let (lo, hi) = (j as f64 * width, (j + 1) as f64 * width);
                return (lo.floor() as usize..(hi.ceil() as usize).min(n))
                    .filter_map(|i| {
                        let overlap = hi.min(i as f64 + 1.0) - lo.max(i as f64);
                        (overlap > 1e-9).then_some((i, (overlap / width) as f32))
                    })
                    .collect();
            }
            let c = ((j as f64 + 0.5) * width - 0.5).clamp(0.0, (n - 1) as f64);
            let i = (c.floor() as usize).min(n - 1);
            let f = c - i as f64;
            if f > 0.0 && i + 1 < n {
                vec![(i, (1.0 - f) as f32), (i + 1, f as f32)]
            } else {
                vec![(i, 1.0)]
            }
        })
        .collect()
}

/// `texels` (x fastest) of a `dims` volume resampled onto `to` over the same extent, with
/// [`axis_weights`] per axis (a separable filter: box when downsampling, linear otherwise).
pub fn resample_texels<T: Channels>(texels: &[T], dims: [usize; 3], to: [usize; 3]) -> Vec<T> {
    let [nx, ny, nz] = dims;
    assert_eq!(texels.len(), nx * ny * nz, "texels of a {nx}×{ny}×{nz} volume");
    let [wx, wy, wz] = [0, 1, 2].map(|a| axis_weights(dims[a], to[a]));
    let [mx, my, _] = to;
    let mut out = vec![T::put([0.0; 4]); mx * my * wz.len()];
    // Each target row converts the few source rows it reads to floats first, a row at a time
    // ([`Channels::get_all`], into a buffer that stays in the cache), and its sums back
    // likewise: the same sums in the same order as converting each texel where it is read
    // (the same texels), without a conversion call per read (the CT head's gradient volume's
    // half level in about a third of the time).
    out.par_chunks_mut(mx * my).zip(&wz).for_each(|(slice, zs)| {
        let n = T::N;
        let most = wy.iter().map(Vec::len).max().unwrap_or(0);
        let mut floats = vec![0.0f32; zs.len() * most * nx * n];
        let mut sums = vec![[0.0f32; 4]; mx];
        for (yj, ys) in wy.iter().enumerate() {
            // Row (iz, iy) at k = iz · ys.len() + iy.
            let rows = zs
                .iter()
                .flat_map(|&(z, _)| ys.iter().map(move |&(y, _)| (z * ny + y) * nx));
            for (row, to) in rows.zip(floats.chunks_exact_mut(nx * n)) {
                T::get_all(&texels[row..row + nx], to);
            }
            for (sum, xs) in sums.iter_mut().zip(&wx) {
                *sum = [0.0f32; 4];
                for (iz, &(_, fz)) in zs.iter().enumerate() {
                    for (iy, &(_, fy)) in ys.iter().enumerate() {
                        let row = &floats[(iz * ys.len() + iy) * nx * n..][..nx * n];
                        for &(x, fx) in xs {
                            let w = fz * fy * fx;
                            let v = &row[x * n..x * n + n];
                            for c in 0..n {
                                sum[c] += w * v[c];
                            }
                        }
                    }
                }
            }
            T::put_all(&sums, &mut slice[yj * mx..(yj + 1) * mx]);
        }
    });
    out
}

/// Resamples `src` onto `dims` voxels spanning the same box; the spacing grows or shrinks so
/// that the physical extent stays the same. Per axis, downsampling averages the source voxels
/// each target voxel covers (weighted by how much of each), so thin structures fade instead
/// of vanishing between sample points; upsampling interpolates linearly ([`axis_weights`]).
pub fn resample(src: &Volume, dims: [usize; 3]) -> Result<Volume, VolumeError> {
    checked_voxel_count(dims)?;
    if dims == src.dims {
        return Ok(src.clone());
    }
    let extent = src.extent();
    let spacing = [0, 1, 2].map(|a| extent[a] / dims[a] as f32);
    Volume::new(dims, spacing, resample_texels(&src.data, src.dims, dims))
}

/// Dims no larger than `max_dim` per axis and `max_voxels` in total, keeping the aspect ratio;
/// `None` when `dims` already fit.
pub fn fitting_dims(dims: [usize; 3], max_dim: usize, max_voxels: usize) -> Option<[usize; 3]> {
    let largest = *dims.iter().max().unwrap_or(&1);
    let voxels: f64 = dims.iter().map(|&d| d as f64).product();
    if largest <= max_dim && voxels <= max_voxels as f64 {
        return None;
    }
    let by_dim = max_dim as f64 / largest as f64;
    let by_voxels = (max_voxels as f64 / voxels).cbrt();
    let factor = by_dim.min(by_voxels).min(1.0);
    Some(dims.map(|d| ((d as f64 * factor).floor() as usize).clamp(1, max_dim.max(1))))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp_x(dims: [usize; 3], spacing: [f32; 3]) -> Volume {
        let data = (0..dims.iter().product::<usize>())
            .map(|i| (i % dims[0]) as f32)
            .collect();
        Volume::new(dims, spacing, data).unwrap()
    }

    #[test]
    fn resampling_keeps_the_extent_and_a_linear_ramp() {
        let src = ramp_x([8, 4, 2], [1.0, 2.0, 5.0]);
        let up = resample(&src, [16, 4, 4]).unwrap();
        assert_eq!(up.extent(), src.extent());
        // Interior target voxel x = 7 has centre 7.5 / 16 of the box = source coordinate 3.25.
        assert!((up.get(7, 1, 1) - 3.25).abs() < 1e-5, "{}", up.get(7, 1, 1));
        let down = resample(&src, [4, 2, 1]).unwrap();
        assert_eq!(down.spacing, [2.0, 4.0, 10.0]);
        // Target x = 1 covers source voxels 2 and 3: their mean is 2.5.
        assert!((down.get(1, 0, 0) - 2.5).abs() < 1e-5);
    }

    #[test]
    fn downsampling_averages_the_footprint() {
        // One bright voxel in four along x: point sampling between voxels 1 and 2 of each
        // group would miss it entirely; the footprint average keeps its mean, 0.25.
        let data = (0..16).map(|i| if i % 4 == 0 { 1.0 } else { 0.0 }).collect();
        let src = Volume::new([16, 1, 1], [1.0; 3], data).unwrap();
        let down = resample(&src, [4, 1, 1]).unwrap();
        for x in 0..4 {
            assert!((down.get(x, 0, 0) - 0.25).abs() < 1e-6, "{:?}", down.data);
        }
    }

    #[test]
    fn box_weights_cover_every_source_voxel_once_at_any_ratio() {
        for (n, m) in [(2usize, 1usize), (7, 3), (16, 4), (255, 100), (1024, 200), (5, 4)] {
            let w = axis_weights(n, m);
            assert_eq!(w.len(), m);
            let mut coverage = vec![0.0f64; n];
            for texel in &w {
                let total: f64 = texel.iter().map(|&(_, f)| f as f64).sum();
                // Up to ⌈n/m⌉ + 1 f32 weights, each rounded from f64: a few units of 2⁻²⁴
                // each.
                assert!((total - 1.0).abs() < 1e-6, "{n} → {m}: weights sum to {total}");
                for &(i, f) in texel {
                    coverage[i] += f as f64 * n as f64 / m as f64;
                }
            }
            for (i, c) in coverage.iter().enumerate() {
                // The weights' f32 rounding (6e-8 relative) times n/m ≤ 5.2, over at most two
                // targets: under 1e-6.
                assert!((c - 1.0).abs() < 1e-6, "{n} → {m}: voxel {i} covered {c} times");
            }
        }
    }

    #[test]
    fn upsampling_interpolates_between_the_two_nearest_centres() {
        // 4 → 10: target j's centre is source coordinate (j + ½)·0.4 − ½, clamped to [0, 3].
        let w = axis_weights(4, 10);
        assert_eq!(w[0], vec![(0, 1.0)]);
        assert_eq!(w[9], vec![(3, 1.0)]);
        for (j, taps) in w.iter().enumerate() {
            let c = ((j as f32 + 0.5) * 0.4 - 0.5).clamp(0.0, 3.0);
            let at: f32 = taps.iter().map(|&(i, f)| i as f32 * f).sum();
            let total: f32 = taps.iter().map(|&(_, f)| f).sum();
            // f32 rounding of a weight below 1 times an index below 4.
            assert!((at - c).abs() < 1e-5 && (total - 1.0).abs() < 1e-6, "{j}: {taps:?}");
        }
    }

    #[test]
    fn fitting_dims_respects_both_limits_and_the_aspect() {
        assert_eq!(fitting_dims([64, 64, 64], 256, 1 << 30), None);
        let d = fitting_dims([1024, 512, 100], 256, usize::MAX).unwrap();
        assert_eq!(d, [256, 128, 25]);
        let d = fitting_dims([200, 200, 200], 1024, 1_000_000).unwrap();
        assert!(d.iter().product::<usize>() <= 1_000_000 && d[0] == d[2], "{d:?}");
    }
}
