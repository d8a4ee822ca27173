//! Resampling a volume onto another grid over the same physical box: an η volume onto the
//! main volume's grid, and downsampling to fit a device's 3D-texture limits.

use super::{checked_voxel_count, Volume, VolumeError};

/// Most sub-samples per axis averaged for one target voxel when downsampling.
const MAX_FOOTPRINT_SAMPLES: usize = 4;

/// Resamples `src` onto `dims` voxels spanning the same box; the spacing grows or shrinks so
/// that the physical extent stays the same. Upsampling is trilinear; when downsampling, each
/// target voxel averages trilinear samples spread over its footprint (up to 4 per axis), so
/// thin structures fade instead of vanishing between sample points.
pub fn resample(src: &Volume, dims: [usize; 3]) -> Result<Volume, VolumeError> {
    let count = checked_voxel_count(dims)?;
    if dims == src.dims {
        return Ok(src.clone());
    }
    let extent = src.extent();
    let spacing = [0, 1, 2].map(|a| extent[a] / dims[a] as f32);
    // Voxel centre i of the target lies at (i + 0.5) / n_target of the box, which is source
    // voxel coordinate (i + 0.5) · n_source / n_target − 0.5.
    let scale = [0, 1, 2].map(|a| src.dims[a] as f32 / dims[a] as f32);
    let offsets: [Vec<f32>; 3] = [0, 1, 2].map(|a| {
        if scale[a] <= 1.0 {
            return vec![0.0];
        }
        let k = (scale[a].ceil() as usize).min(MAX_FOOTPRINT_SAMPLES);
        (0..k).map(|j| ((j as f32 + 0.5) / k as f32 - 0.5) * scale[a]).collect()
    });
    let samples = (offsets[0].len() * offsets[1].len() * offsets[2].len()) as f32;
    let coordinate = |a: usize, c: f32| c.clamp(0.0, (src.dims[a] - 1) as f32);
    let centre = |a: usize, i: usize| (i as f32 + 0.5) * scale[a] - 0.5;
    let mut data = Vec::with_capacity(count);
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let mut sum = 0.0f32;
                for dz in &offsets[2] {
                    let sz = coordinate(2, centre(2, z) + dz);
                    for dy in &offsets[1] {
                        let sy = coordinate(1, centre(1, y) + dy);
                        for dx in &offsets[0] {
                            sum += src.sample_trilinear([coordinate(0, centre(0, x) + dx), sy, sz]);
                        }
                    }
                }
                data.push(sum / samples);
            }
        }
    }
    Volume::new(dims, spacing, data)
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
    fn fitting_dims_respects_both_limits_and_the_aspect() {
        assert_eq!(fitting_dims([64, 64, 64], 256, 1 << 30), None);
        let d = fitting_dims([1024, 512, 100], 256, usize::MAX).unwrap();
        assert_eq!(d, [256, 128, 25]);
        let d = fitting_dims([200, 200, 200], 1024, 1_000_000).unwrap();
        assert!(d.iter().product::<usize>() <= 1_000_000 && d[0] == d[2], "{d:?}");
    }
}
