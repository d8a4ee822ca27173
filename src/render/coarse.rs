//! The volumes' half-resolution level (`quality.volume_level = 1`): each texel the box-filtered
//! mean of the voxels it covers, for coarse renders (the viewer's first levels) whose planes
//! and pixels are too far apart to resolve the full volume. On a CPU driver every trilinear
//! fetch there lands on memory no neighbouring sample touched; an eighth of the texels keeps
//! the fetches of neighbouring pixels and planes close.
//!
//! The level is an image of its own beside each volume image (a mip level's extent: ⌊n/2⌋ per
//! axis, at least 1), bound in its place, so the passes read it unchanged. The volume's half
//! level is the box filter of its values; the gradient and orientation volumes' half levels are
//! made from those values at the half level's resolution (their differences scaled to the
//! volume's voxels), so that they need neither the full levels nor the time to make them.

use half::slice::HalfFloatSliceExt;

pub use crate::volume::half_level_dims as half_dims;
use crate::volume::resample::resample_texels;
pub use crate::volume::resample::Channels;
use crate::volume::round_half_away;

impl Channels for u16 {
    const N: usize = 1;
    fn get(&self) -> [f32; 4] {
        [*self as f32, 0.0, 0.0, 0.0]
    }
    fn put(v: [f32; 4]) -> Self {
        round_half_away(v[0]).clamp(0.0, u16::MAX as f32) as u16
    }
}

impl Channels for [i16; 4] {
    const N: usize = 4;
    fn get(&self) -> [f32; 4] {
        self.map(|c| c as f32)
    }
    fn put(v: [f32; 4]) -> Self {
        // SNORM: −32768 and −32767 both read as −1.
        v.map(|c| round_half_away(c).clamp(-32767.0, 32767.0) as i16)
    }
    // Loops over the channels rather than `map`, which the compiler leaves as a call per
    // texel here: the same values.
    fn get_all(src: &[Self], dst: &mut [f32]) {
        for (d, s) in dst.chunks_exact_mut(4).zip(src) {
            for c in 0..4 {
                d[c] = s[c] as f32;
            }
        }
    }
    fn put_all(src: &[[f32; 4]], dst: &mut [Self]) {
        for (d, s) in dst.iter_mut().zip(src) {
            for c in 0..4 {
                d[c] = round_half_away(s[c]).clamp(-32767.0, 32767.0) as i16;
            }
        }
    }
}

/// The four channels converted at once (one check of the CPU's conversion instructions and
/// one instruction, instead of a call per channel: the same bits).
impl Channels for [half::f16; 4] {
    const N: usize = 4;
    fn get(&self) -> [f32; 4] {
        let mut v = [0.0; 4];
        self.convert_to_f32_slice(&mut v);
        v
    }
    fn put(v: [f32; 4]) -> Self {
        let mut h = [half::f16::ZERO; 4];
        h.convert_from_f32_slice(&v);
        h
    }
    fn get_all(src: &[Self], dst: &mut [f32]) {
        let halves: &[half::f16] = bytemuck::cast_slice(src);
        halves.convert_to_f32_slice(dst);
    }
    fn put_all(src: &[[f32; 4]], dst: &mut [Self]) {
        let halves: &mut [half::f16] = bytemuck::cast_slice_mut(dst);
        halves.convert_from_f32_slice(bytemuck::cast_slice(src));
    }
}

/// The half-resolution level of `texels` (x fastest) of a `dims` volume: each coarse texel the
/// mean of the voxels it covers, weighted by how much of each it covers (the box filter of
/// `volume::resample`, which downsamples volumes to fit a device). Texel j of m = ⌊n/2⌋ spans
/// voxels [j·n/m, (j+1)·n/m) in edge coordinates, so that normalised texture coordinates
/// address the same place at both levels; where n is odd a texel covers two voxels and part
/// of a third.
pub fn half_level<T: Channels>(texels: &[T], dims: [usize; 3]) -> Vec<T> {
    resample_texels(texels, dims, half_dims(dims))
}

/// The coarse texels' weights along an axis of `n` voxels.
#[cfg(test)]
fn half_axis_weights(n: usize) -> Vec<Vec<(usize, f32)>> {
    crate::volume::resample::axis_weights(n, crate::volume::half_level_side(n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_float_texels_convert_as_each_channel_alone() {
        // Values across the half floats' range: subnormals, rounding ties, beyond the largest
        // (infinity), negative zero and NaN.
        let mut values: Vec<f32> = vec![0.0, -0.0, 6e-8, 3e-8, 65504.0, 65520.0, 1e9, f32::NAN, -1.0 / 3.0];
        values.extend((0..20_000).map(|i| ((i as f32) * 0.618_034).sin() * 10f32.powi(i % 12 - 6)));
        values.extend((0..2048).map(|m| 1.0 + (2 * m + 1) as f32 * 2f32.powi(-12)));
        for v in values.chunks_exact(4) {
            let v = [v[0], v[1], v[2], v[3]];
            let alone = v.map(half::f16::from_f32);
            let texel = <[half::f16; 4] as Channels>::put(v);
            assert_eq!(texel.map(|h| h.to_bits()), alone.map(|h| h.to_bits()), "{v:?}");
            let back = texel.get();
            assert_eq!(back.map(f32::to_bits), alone.map(|h| h.to_f32().to_bits()), "{v:?}");
        }
    }

    #[test]
    fn each_coarse_texel_weighs_what_it_covers_of_every_voxel() {
        for n in [1usize, 2, 3, 7, 8, 108, 255] {
            let w = half_axis_weights(n);
            assert_eq!(w.len(), crate::volume::half_level_side(n));
            // Every voxel is covered exactly once over all coarse texels: each texel's weights
            // sum to 1 and, times the texel's width n/m, to the voxels it spans.
            let mut coverage = vec![0.0f64; n];
            for texel in &w {
                let total: f32 = texel.iter().map(|(_, f)| f).sum();
                // At most three f32 weights, each rounded from f64: a few units of 2⁻²⁴.
                assert!((total - 1.0).abs() < 1e-6, "n {n}: weights sum to {total}");
                for &(i, f) in texel {
                    coverage[i] += f as f64 * n as f64 / w.len() as f64;
                }
            }
            for (i, c) in coverage.iter().enumerate() {
                // The f32 weights' rounding (1e-7 relative) times up to n/m ≤ 3, summed over
                // at most two texels: well under 1e-5.
                assert!((c - 1.0).abs() < 1e-5, "n {n}: voxel {i} covered {c} times");
            }
        }
    }

    #[test]
    fn a_linear_ramp_keeps_its_values_at_the_coarse_texel_centres() {
        // The box filter of a linear function is its value at the box's centre, and the coarse
        // texel j's centre lies at (j + ½)·n/m − ½ in voxel-centre coordinates. (Where n is
        // odd, the voxel cut by a box's edge counts with its value at its own centre, which
        // moves the mean by at most 0.05 voxel: even sides here.)
        let dims = [8usize, 6, 4];
        let f = |x: f32, y: f32, z: f32| 1000.0 + 300.0 * x + 70.0 * y + 1100.0 * z;
        let mut texels = Vec::new();
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    texels.push(f(x as f32, y as f32, z as f32).round() as u16);
                }
            }
        }
        let coarse = half_level(&texels, dims);
        let m = half_dims(dims);
        assert_eq!(coarse.len(), m.iter().product::<usize>());
        let centre = |j: usize, a: usize| (j as f32 + 0.5) * dims[a] as f32 / m[a] as f32 - 0.5;
        for z in 0..m[2] {
            for y in 0..m[1] {
                for x in 0..m[0] {
                    let want = f(centre(x, 0), centre(y, 1), centre(z, 2));
                    let got = coarse[(z * m[1] + y) * m[0] + x] as f32;
                    // The rounding of the input and the output to integers: at most 1.
                    assert!((got - want).abs() <= 1.0, "({x}, {y}, {z}): {got} against {want}");
                }
            }
        }
    }

    #[test]
    fn vector_texels_are_averaged_per_channel_and_saturate_to_their_format() {
        let dims = [2usize, 2, 2];
        let snorm: Vec<[i16; 4]> = (0..8).map(|i| [32767, -32767, i * 1000, 0]).collect();
        assert_eq!(half_level(&snorm, dims), vec![[32767, -32767, 3500, 0]]);
        let halves: Vec<[half::f16; 4]> = (0..8)
            .map(|i| [1.0, i as f32, -2.0, 0.25].map(half::f16::from_f32))
            .collect();
        assert_eq!(half_level(&halves, dims)[0].map(|c| c.to_f32()), [1.0, 3.5, -2.0, 0.25]);
    }

    /// Each target texel as the filter's definition reads it: every source texel converted
    /// where it is read, the weights multiplied z, y, x and summed in that order.
    fn per_texel<T: Channels>(texels: &[T], dims: [usize; 3], to: [usize; 3]) -> Vec<T> {
        let [wx, wy, wz] = [0, 1, 2].map(|a| crate::volume::resample::axis_weights(dims[a], to[a]));
        let mut out = Vec::new();
        for zs in &wz {
            for ys in &wy {
                for xs in &wx {
                    let mut sum = [0.0f32; 4];
                    for &(z, fz) in zs {
                        for &(y, fy) in ys {
                            for &(x, fx) in xs {
                                let v = texels[(z * dims[1] + y) * dims[0] + x].get();
                                for c in 0..T::N {
                                    sum[c] += fz * fy * fx * v[c];
                                }
                            }
                        }
                    }
                    out.push(T::put(sum));
                }
            }
        }
        out
    }

    #[test]
    fn rows_converted_at_once_give_the_texels_of_each_texel_converted_where_it_is_read() {
        // Odd and even sides (a coarse texel sharing a voxel with the next), down and up.
        let cases = [
            ([7usize, 6, 5], None),
            ([8, 9, 4], None),
            ([6, 5, 3], Some([11usize, 7, 5])),
            ([9, 7, 6], Some([4, 3, 2])),
        ];
        for (dims, to) in cases {
            let to = to.unwrap_or(half_dims(dims));
            let n: usize = dims.iter().product();
            // Values whose sums round differently in another order: a wide range of exponents.
            let value =
                |i: usize, c: usize| ((i * 7 + c * 13) as f32 * 0.618_034).sin() * 10f32.powi((i % 9) as i32 - 4);
            let halves: Vec<[half::f16; 4]> = (0..n)
                .map(|i| [0, 1, 2, 3].map(|c| half::f16::from_f32(value(i, c))))
                .collect();
            let snorm: Vec<[i16; 4]> = (0..n)
                .map(|i| [0, 1, 2, 3].map(|c| (value(i, c) * 3000.0).clamp(-32767.0, 32767.0) as i16))
                .collect();
            let words: Vec<u16> = (0..n)
                .map(|i| (value(i, 0).abs() * 6000.0).min(65535.0) as u16)
                .collect();
            let bits = |t: &[[half::f16; 4]]| t.iter().map(|h| h.map(|c| c.to_bits())).collect::<Vec<_>>();
            let resampled = crate::volume::resample::resample_texels(&halves, dims, to);
            assert_eq!(
                bits(&resampled),
                bits(&per_texel(&halves, dims, to)),
                "{dims:?} → {to:?}"
            );
            let resampled = crate::volume::resample::resample_texels(&snorm, dims, to);
            assert_eq!(resampled, per_texel(&snorm, dims, to), "{dims:?} → {to:?}");
            let resampled = crate::volume::resample::resample_texels(&words, dims, to);
            assert_eq!(resampled, per_texel(&words, dims, to), "{dims:?} → {to:?}");
        }
    }
}
