//! The orientation volume: the data value's gradient per voxel, for the view pass's layers
//! (`layer_ratio` in view.wgsl). A view segment whose light falls through particles needs the
//! layer's normal there; taking it from the volume cost six trilinear samples per segment, a
//! quarter of a soft-light view pass on a CPU driver. The gradient depends only on the volume
//! and its window, so it is computed once on the CPU and read with one trilinear fetch.

use rayon::prelude::*;

/// Per voxel: the value's central differences over `reach` world units either side along each
/// volume axis (linear between voxels along the axis; 0 beyond the volume, the shaders' border
/// value), divided by the reach in voxels, so that they scale as per-voxel central differences
/// (`View::gradient_to_view` maps them to view space), as rgba16snorm texels (w is 0) of
/// [`ORIENTATION_SCALE`] times the differences.
///
/// The differences are stored as they are, not as unit directions: in a sheet's core, where
/// the gradient turns over, the fetch blends texels of both sides, and only their own
/// magnitudes make the blend turn over where the value peaks. 8-bit texels are too coarse
/// there: renders over jittered planes of a thin side-lit sheet then varied by 2 % from row to
/// row where 16-bit ones leave 1 % (`tests/steps.rs`).
pub fn orientation_volume(samples: &[u16], dims: [usize; 3], spacing: [f32; 3], reach: f32) -> Vec<[i16; 4]> {
    orientation_volume_per(samples, dims, spacing, reach, [1.0; 3])
}

/// [`orientation_volume`] of texels `spacing` apart that span `texel_voxels` of the volume's
/// voxels along each axis (the half-resolution level's: `n / ⌊n/2⌋`), with its differences
/// divided by them, so that they scale as the volume's per-voxel differences do.
pub fn orientation_volume_per(
    samples: &[u16],
    dims: [usize; 3],
    spacing: [f32; 3],
    reach: f32,
    texel_voxels: [f32; 3],
) -> Vec<[i16; 4]> {
    let [nx, ny, nz] = dims;
    assert_eq!(samples.len(), nx * ny * nz, "samples of a {nx}×{ny}×{nz} volume");
    // (voxels to the first neighbour, weight of the one after it, reach in voxels) along each
    // axis.
    let axis = |a: usize| {
        let r = (reach / spacing[a]).max(f32::MIN_POSITIVE);
        let k = r.floor();
        (k as isize, r - k, r)
    };
    let [(kx, fx, rx), (ky, fy, ry), (kz, fz, rz)] = [axis(0), axis(1), axis(2)];
    let scale = ORIENTATION_SCALE / 65535.0;
    let [vx, vy, vz] = texel_voxels;
    let (sx, sy, sz) = (scale / (rx * vx), scale / (ry * vy), scale / (rz * vz));
    let texel = |d: f32, s: f32| crate::volume::round_half_away(d * s).clamp(-32767.0, 32767.0) as i16;
    // Rows of x, whole: a row beyond the volume reads as the border's zeros.
    let zeros = vec![0u16; nx];
    let row = |y: isize, z: isize| -> &[u16] {
        if y < 0 || z < 0 || y >= ny as isize || z >= nz as isize {
            &zeros
        } else {
            let start = (z as usize * ny + y as usize) * nx;
            &samples[start..start + nx]
        }
    };
    // Differences along y and z, from the rows k and k + 1 ahead and behind, weighted.
    let across = |texels: &mut [[i16; 4]], a: usize, rows: [&[u16]; 4], f: f32, s: f32| {
        let [a0, a1, b0, b1] = rows;
        for x in 0..nx {
            let d = (1.0 - f) * (a0[x] as f32 - b0[x] as f32) + f * (a1[x] as f32 - b1[x] as f32);
            texels[x][a] = texel(d, s);
        }
    };
    let mut out = vec![[0i16; 4]; nx * ny * nz];
    out.par_chunks_mut(nx * ny).enumerate().for_each(|(z, slice)| {
        // The row along x with the border's zeros on both sides, so that x needs no bounds.
        let pad = kx as usize + 1;
        let mut padded = vec![0.0f32; nx + 2 * pad];
        let z = z as isize;
        for y in 0..ny {
            let texels = &mut slice[y * nx..(y + 1) * nx];
            let here = row(y as isize, z);
            for (p, v) in padded[pad..pad + nx].iter_mut().zip(here) {
                *p = *v as f32;
            }
            let k = kx as usize;
            for (x, t) in texels.iter_mut().enumerate() {
                let c = x + pad;
                let d = (1.0 - fx) * (padded[c + k] - padded[c - k]) + fx * (padded[c + k + 1] - padded[c - k - 1]);
                t[0] = texel(d, sx);
            }
            let y = y as isize;
            across(
                texels,
                1,
                [row(y + ky, z), row(y + ky + 1, z), row(y - ky, z), row(y - ky - 1, z)],
                fy,
                sy,
            );
            across(
                texels,
                2,
                [row(y, z + kz), row(y, z + kz + 1), row(y, z - kz), row(y, z - kz - 1)],
                fz,
                sz,
            );
        }
    });
    out
}

/// The texels' units per per-voxel difference of values in [0, 1]: such a difference is at
/// most 1 at any reach (the values a reach r apart differ by at most min(r, 1)), so it fills
/// the 16-bit range.
pub const ORIENTATION_SCALE: f32 = 32767.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ramp_points_along_its_slope_and_the_faces_along_their_normals() {
        // The value grows by 2000 per voxel along x and 1000 along y (of 65535); spacing
        // (1, 0.5, 2) and reach 1.5 make the reach 1.5, 3 and 0.75 voxels. Per-voxel central
        // differences: 4000 along x, 2000 along y, none along z.
        let dims = [12, 12, 6];
        let samples: Vec<u16> = (0..12 * 12 * 6)
            .map(|i| (1000 + 2000 * (i % 12) + 1000 * (i / 12 % 12)) as u16)
            .collect();
        let spacing = [1.0, 0.5, 2.0];
        let out = orientation_volume(&samples, dims, spacing, 1.5);
        let scale = ORIENTATION_SCALE / 65535.0;
        // An interior voxel; within the 16-bit rounding (half a unit) and that of the f32
        // arithmetic.
        let t = out[(3 * 12 + 5) * 12 + 5];
        let expect = [4000.0 * scale, 2000.0 * scale, 0.0];
        for a in 0..3 {
            assert!((t[a] as f32 - expect[a]).abs() <= 1.0, "{t:?} against {expect:?}");
        }
        assert_eq!(t[3], 0);

        // A uniform volume: no gradient inside; its faces step to the outside's 0, so at
        // x = 0 the value grows inward (+x), at the far side outward, and nothing else
        // changes. Reach 1.5: the outside's 0 weighs half at the face voxel.
        let flat = orientation_volume(&vec![30000u16; 12 * 12 * 6], dims, [1.0; 3], 1.5);
        assert_eq!(flat[(3 * 12 + 5) * 12 + 5], [0; 4]);
        let face = 30000.0 * ORIENTATION_SCALE / 65535.0 / 1.5;
        let near = flat[(3 * 12 + 5) * 12];
        assert!(
            (near[0] as f32 - face).abs() <= 1.0 && near[1] == 0 && near[2] == 0,
            "{near:?}"
        );
        let far = flat[(3 * 12 + 5) * 12 + 11];
        assert!(
            (far[0] as f32 + face).abs() <= 1.0 && far[1] == 0 && far[2] == 0,
            "{far:?}"
        );
        // The largest difference a value can make fills the range, at a reach of a voxel and
        // of half a voxel.
        for reach in [1.0, 0.5] {
            let edge = orientation_volume(&[0, 30000, 65535], [3, 1, 1], [1.0; 3], reach);
            assert_eq!(edge[1][0], 32767, "reach {reach}");
        }
    }

    #[test]
    fn blending_the_texels_gives_the_differences_of_the_blended_values() {
        // With a whole number of voxels as the reach, the differences are piecewise linear
        // between voxels, so a trilinear fetch of the texels anywhere is the central
        // difference of the trilinearly sampled value: what sampling the value six times gave.
        let n = 16;
        let values: Vec<u16> = (0..n).map(|i| ((i * 7919 + 13) % 50000) as u16).collect();
        let samples: Vec<u16> = (0..n * 2 * 2).map(|i| values[i % n]).collect();
        let out = orientation_volume(&samples, [n, 2, 2], [1.0; 3], 2.0);
        let scale = ORIENTATION_SCALE / 65535.0;
        let linear = |p: f32| -> f32 {
            let i = p.floor();
            let at = |i: f32| {
                if i < 0.0 || i >= n as f32 {
                    0.0
                } else {
                    values[i as usize] as f32
                }
            };
            at(i) + (p - i) * (at(i + 1.0) - at(i))
        };
        for i in 0..n - 1 {
            for t in [0.25f32, 0.5, 0.9] {
                let p = i as f32 + t;
                let fetched = out[i][0] as f32 + t * (out[i + 1][0] as f32 - out[i][0] as f32);
                let sampled = (linear(p + 2.0) - linear(p - 2.0)) / 2.0 * scale;
                // Each texel is rounded by half a unit; f32 arithmetic on values up to 1e5.
                assert!(
                    (fetched - sampled).abs() <= 0.5 + 1e-4 * sampled.abs(),
                    "at {p}: {fetched} against {sampled}"
                );
            }
        }
    }
}
