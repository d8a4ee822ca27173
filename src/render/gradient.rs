//! The gradient volume: η and ∇η per voxel, computed on the CPU whenever the transfer
//! functions or the η source change, so that the shaders get both from one trilinear fetch
//! instead of six samples and twelve table lookups.

use half::slice::HalfFloatSliceExt;
use rayon::prelude::*;

use crate::scene::Gradient;
use crate::transfer::Curve;

/// Entries of the η lookup table applied to the 16-bit samples.
const ETA_TABLE: usize = 4096;

/// η of the medium around the volume: what η_tf gives the value outside it (0 after
/// windowing, the shaders' border value).
pub fn ambient_eta(eta: &Curve) -> f32 {
    eta.eval(0.0)
}

/// Per voxel: the differences of η_tf applied to the neighbours along x, y, z (central:
/// η(i+1) − η(i−1); forward: 2·(η(i+1) − η(i)); fourth order: (8·(η(i+1) − η(i−1)) −
/// (η(i+2) − η(i−2)))/6, so all scale alike: twice the derivative) and η − η outside the
/// volume, as rgba16f texels. Voxels beyond the volume count as the outside value 0, so the
/// volume's faces are interfaces when η inside differs from η outside.
pub fn gradient_volume(samples: &[u16], dims: [usize; 3], eta: &Curve, scheme: Gradient) -> Vec<[half::f16; 4]> {
    gradient_volume_per(samples, dims, eta, scheme, [1.0; 3])
}

/// [`gradient_volume`] of texels that span `texel_voxels` of the volume's voxels along each
/// axis (the half-resolution level's: `n / ⌊n/2⌋`), with its differences divided by them, so
/// that they scale as the volume's per-voxel differences do, as the passes read them at
/// either level.
pub fn gradient_volume_per(
    samples: &[u16],
    dims: [usize; 3],
    eta: &Curve,
    scheme: Gradient,
    texel_voxels: [f32; 3],
) -> Vec<[half::f16; 4]> {
    let table: Vec<f32> = (0..ETA_TABLE)
        .map(|i| eta.eval(i as f32 / (ETA_TABLE - 1) as f32))
        .collect();
    let ambient = ambient_eta(eta);
    let eta_of = |s: u16| -> f32 {
        let t = s as f32 / 65535.0 * (ETA_TABLE - 1) as f32;
        let i = (t.floor() as usize).min(ETA_TABLE - 1);
        let j = (i + 1).min(ETA_TABLE - 1);
        let f = t - i as f32;
        table[i] * (1.0 - f) + table[j] * f
    };
    // η of every voxel, looked up once per 16-bit value and once per voxel rather than
    // interpolated for each of the voxel's seven (or thirteen) uses: the same values, in a
    // tenth of the time.
    let per_value: Vec<f32> = (0..=u16::MAX).map(eta_of).collect();
    let etas: Vec<f32> = samples.par_iter().map(|&s| per_value[s as usize]).collect();
    let [nx, ny, nz] = dims;
    let at = |x: isize, y: isize, z: isize| -> f32 {
        if x < 0 || y < 0 || z < 0 || x >= nx as isize || y >= ny as isize || z >= nz as isize {
            ambient
        } else {
            etas[(z as usize * ny + y as usize) * nx + x as usize]
        }
    };
    let per = texel_voxels.map(|v| 1.0 / v);
    let texel = |d: [f32; 3], c: f32| [d[0] * per[0], d[1] * per[1], d[2] * per[2], c - ambient];
    // How far the scheme reaches: voxels at least this far from every face read no outside
    // value, and take their neighbours at fixed offsets without the bounds tests (the same
    // values and operations: the same texels; this took the CT head's gradient volume from
    // 225 to about 130 ms on 2 cores).
    let reach = match scheme {
        Gradient::FourthOrder => 2,
        Gradient::Central | Gradient::Forward => 1,
    };
    let (sx, sy, sz) = (1, nx, nx * ny);
    let mut out = vec![[half::f16::ZERO; 4]; nx * ny * nz];
    out.par_chunks_mut(nx * ny).enumerate().for_each(|(z, slice)| {
        let inner_z = z >= reach && z + reach < nz;
        let z = z as isize;
        // A row's texels in f32, converted to half floats at once (one check of the CPU's
        // conversion instructions and 8 values an instruction, instead of one call per value:
        // the same bits; the CT head's gradient volume in 77 ms instead of 105–131).
        let mut texels = vec![[0.0f32; 4]; nx];
        for y in 0..ny as isize {
            let inner_row = inner_z && y as usize >= reach && y as usize + reach < ny;
            let row = y as usize * nx;
            // The voxels of this row whose whole stencil lies inside, else none.
            let inner = if inner_row && nx > 2 * reach {
                reach..nx - reach
            } else {
                0..0
            };
            for x in inner.clone() {
                let i = z as usize * sz + row + x;
                let e = |offset: isize| etas[(i as isize + offset) as usize];
                let c = etas[i];
                let (sx, sy, sz) = (sx as isize, sy as isize, sz as isize);
                let d = match scheme {
                    Gradient::Central => [e(sx) - e(-sx), e(sy) - e(-sy), e(sz) - e(-sz)],
                    Gradient::FourthOrder => {
                        let d = |a: f32, b: f32, a2: f32, b2: f32| (8.0 * (a - b) - (a2 - b2)) / 6.0;
                        [
                            d(e(sx), e(-sx), e(2 * sx), e(-2 * sx)),
                            d(e(sy), e(-sy), e(2 * sy), e(-2 * sy)),
                            d(e(sz), e(-sz), e(2 * sz), e(-2 * sz)),
                        ]
                    }
                    Gradient::Forward => [2.0 * (e(sx) - c), 2.0 * (e(sy) - c), 2.0 * (e(sz) - c)],
                };
                texels[x] = texel(d, c);
            }
            for x in (0..inner.start as isize).chain(inner.end as isize..nx as isize) {
                let c = at(x, y, z);
                let d = match scheme {
                    Gradient::Central => [
                        at(x + 1, y, z) - at(x - 1, y, z),
                        at(x, y + 1, z) - at(x, y - 1, z),
                        at(x, y, z + 1) - at(x, y, z - 1),
                    ],
                    Gradient::FourthOrder => {
                        let d = |a: f32, b: f32, a2: f32, b2: f32| (8.0 * (a - b) - (a2 - b2)) / 6.0;
                        [
                            d(at(x + 1, y, z), at(x - 1, y, z), at(x + 2, y, z), at(x - 2, y, z)),
                            d(at(x, y + 1, z), at(x, y - 1, z), at(x, y + 2, z), at(x, y - 2, z)),
                            d(at(x, y, z + 1), at(x, y, z - 1), at(x, y, z + 2), at(x, y, z - 2)),
                        ]
                    }
                    Gradient::Forward => [
                        2.0 * (at(x + 1, y, z) - c),
                        2.0 * (at(x, y + 1, z) - c),
                        2.0 * (at(x, y, z + 1) - c),
                    ],
                };
                texels[x as usize] = texel(d, c);
            }
            let halves: &mut [half::f16] = bytemuck::cast_slice_mut(&mut slice[row..row + nx]);
            halves.convert_from_f32_slice(bytemuck::cast_slice(&texels));
        }
    });
    out
}

/// Whether a texel of the gradient volume changes η there (∇η not zero; its w, η itself, may
/// differ from the outside's in a uniform medium without bending anything).
pub fn bends(texel: &[half::f16; 4]) -> bool {
    // Zero of either sign, on the bits: this runs for every texel of the volume.
    texel[..3].iter().any(|g| g.to_bits() & 0x7fff != 0)
}

/// [`bends`] of every texel.
pub fn bend_map(texels: &[[half::f16; 4]]) -> Vec<bool> {
    texels.par_iter().map(bends).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn built_in_grounds_and_walls_do_not_refract() {
        use crate::scene::{builtin, PreparedScene};
        for name in ["ball-lens", "glass-beer", "luneburg"] {
            let mut scene = builtin(name).unwrap().scene;
            scene.set_builtin_resolution(32);
            assert!(scene.has_eta_volume(), "{name}");
            let prepared = PreparedScene::load(&scene).unwrap();
            let tf = &prepared.tf;
            let eta = prepared.eta_volume.as_ref().expect("the objects as the η source");
            assert_eq!(eta.dims, prepared.volume.dims);
            let window = prepared.window();
            let of = |v: &crate::volume::Volume, w: [f32; 2]| {
                gradient_volume(&v.normalized_u16(w), v.dims, &tf.eta, Gradient::Central)
            };
            let from_objects = of(eta, eta.value_range);
            let from_volume = of(&prepared.volume, window);
            // Voxels of the ground's top surface, blended from air to ground, far from the
            // objects (a corner column): their values pass through the glass's, so η taken
            // from the whole volume reaches the glass's there (a refractive film on the
            // ground); from the objects alone it is the air's.
            let [nx, ny, _] = prepared.volume.dims;
            let corner = |y: usize| y * nx + 1;
            let film = (0..ny / 2)
                .map(|y| from_volume[corner(y)][3].to_f32().abs())
                .fold(0.0f32, f32::max);
            // η − η_air at the objects' values reaches 0.3–0.5 (glass 1.5, Luneburg 1.41); bound 0.1.
            assert!(
                film > 0.1,
                "{name}: no film to remove ({film}); the check would pass anyway"
            );
            let left = (0..ny / 2)
                .map(|y| from_objects[corner(y)][3].to_f32().abs())
                .fold(0.0f32, f32::max);
            assert_eq!(left, 0.0, "{name}: η − η_air {left} on the ground");
        }
    }

    #[test]
    fn the_inner_voxels_give_the_texels_of_the_bounds_tested_stencil() {
        // The voxels away from the faces take their neighbours at fixed offsets; every texel
        // must be the one the stencil gives reading each neighbour through the bounds test
        // (outside: the ambient η), bit for bit, for every scheme, on volumes thinner than
        // the stencil along each axis too.
        let eta = Curve {
            points: vec![[0.0, 1.0], [0.3, 1.5], [0.6, 1.2], [1.0, 1.33]],
        };
        let ambient = ambient_eta(&eta);
        let mut seed = 12345u32;
        for dims in [[9, 7, 6], [1, 5, 6], [4, 3, 9], [5, 5, 2], [2, 2, 2]] {
            let [nx, ny, nz] = dims;
            let samples: Vec<u16> = (0..nx * ny * nz)
                .map(|_| {
                    seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    (seed >> 16) as u16
                })
                .collect();
            for scheme in [Gradient::Central, Gradient::FourthOrder, Gradient::Forward] {
                let g = gradient_volume(&samples, dims, &eta, scheme);
                // η per 16-bit value: the same table and interpolation as `gradient_volume`'s.
                let per_value: Vec<f32> = {
                    let table: Vec<f32> = (0..ETA_TABLE)
                        .map(|i| eta.eval(i as f32 / (ETA_TABLE - 1) as f32))
                        .collect();
                    (0..=u16::MAX)
                        .map(|s| {
                            let t = s as f32 / 65535.0 * (ETA_TABLE - 1) as f32;
                            let i = (t.floor() as usize).min(ETA_TABLE - 1);
                            let j = (i + 1).min(ETA_TABLE - 1);
                            let f = t - i as f32;
                            table[i] * (1.0 - f) + table[j] * f
                        })
                        .collect()
                };
                let at = |x: isize, y: isize, z: isize| -> f32 {
                    let inside =
                        (0..nx as isize).contains(&x) && (0..ny as isize).contains(&y) && (0..nz as isize).contains(&z);
                    if inside {
                        per_value[samples[(z as usize * ny + y as usize) * nx + x as usize] as usize]
                    } else {
                        ambient
                    }
                };
                for z in 0..nz as isize {
                    for y in 0..ny as isize {
                        for x in 0..nx as isize {
                            let c = at(x, y, z);
                            let along = |a: [isize; 3]| {
                                let n = |k: isize| at(x + k * a[0], y + k * a[1], z + k * a[2]);
                                match scheme {
                                    Gradient::Central => n(1) - n(-1),
                                    Gradient::FourthOrder => (8.0 * (n(1) - n(-1)) - (n(2) - n(-2))) / 6.0,
                                    Gradient::Forward => 2.0 * (n(1) - c),
                                }
                            };
                            let d = [along([1, 0, 0]), along([0, 1, 0]), along([0, 0, 1])];
                            let expected = [d[0], d[1], d[2], c - ambient].map(half::f16::from_f32);
                            let texel = g[(z as usize * ny + y as usize) * nx + x as usize];
                            assert_eq!(
                                texel.map(half::f16::to_bits),
                                expected.map(half::f16::to_bits),
                                "{dims:?} {scheme:?} at ({x}, {y}, {z})"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_linear_index_ramp_has_a_constant_gradient_and_the_faces_are_interfaces() {
        // η = 1 + v over a volume whose value grows by 1/7 per voxel along x.
        let eta = Curve {
            points: vec![[0.0, 1.0], [1.0, 2.0]],
        };
        let dims = [8, 3, 3];
        let samples: Vec<u16> = (0..72)
            .map(|i| ((i % 8) as f32 / 7.0 * 65535.0).round() as u16)
            .collect();
        let g = gradient_volume(&samples, dims, &eta, Gradient::Central);
        let at = |x: usize, y: usize, z: usize| g[(z * 3 + y) * 8 + x].map(|h| h.to_f32());
        // Inside: (η(x+1) − η(x−1)) = 2/7 along x, 0 along y and z in the middle row.
        let c = at(4, 1, 1);
        assert!((c[0] - 2.0 / 7.0).abs() < 2e-3, "{c:?}");
        assert!(c[1].abs() < 1e-6 && c[2].abs() < 1e-6);
        assert!((c[3] - 4.0 / 7.0).abs() < 2e-3, "η − η outside: {}", c[3]);
        // At the face y = 0 the outside (η = 1) differs from the inside (η = 1 + 4/7).
        assert!(at(4, 0, 1)[1] > 0.5, "no interface at the volume's face");
        let f = gradient_volume(&samples, dims, &eta, Gradient::Forward);
        assert!((f[(3 + 1) * 8 + 4][0].to_f32() - 2.0 / 7.0).abs() < 2e-3);
        let q = gradient_volume(&samples, dims, &eta, Gradient::FourthOrder);
        assert!((q[(3 + 1) * 8 + 4][0].to_f32() - 2.0 / 7.0).abs() < 2e-3);
    }

    #[test]
    fn fourth_order_differences_are_exact_on_a_cubic_index() {
        // η = 1 + (x/11)³ along x: twice its derivative at x = 5 is 6·25/11³. Central
        // differences add 2/11³ (1.3 %); the fourth-order ones are exact for a cubic, up to the
        // 16-bit samples and the f16 texel (a relative 2⁻¹¹).
        let eta = Curve {
            points: vec![[0.0, 1.0], [1.0, 2.0]],
        };
        let dims = [12, 5, 5];
        let samples: Vec<u16> = (0..12 * 25)
            .map(|i| (((i % 12) as f32 / 11.0).powi(3) * 65535.0).round() as u16)
            .collect();
        let at = |g: &[[half::f16; 4]]| g[(2 * 5 + 2) * 12 + 5][0].to_f32();
        let exact = 150.0 / 1331.0;
        let fourth = at(&gradient_volume(&samples, dims, &eta, Gradient::FourthOrder));
        let central = at(&gradient_volume(&samples, dims, &eta, Gradient::Central));
        assert!((fourth - exact).abs() < 2e-4, "fourth order {fourth} vs {exact}");
        assert!((central - exact - 2.0 / 1331.0).abs() < 2e-4, "central {central}");
    }
}
