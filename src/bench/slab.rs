//! The narrow-beam slab that the multiple-scattering tests and `bench --scatter` measure: a
//! collimated beam through a small hole in an opaque mask enters a homogeneous scattering
//! slab head-on (Premoze et al.'s Fig. 4 set-up, in voxel units); the light on sweep planes
//! behind the entry, seen with the light debug view, is compared with the Monte Carlo
//! reference's pencil beam (`reference::scatter::plane_flux`).

use glam::{Vec2, Vec3};

use crate::reference::measure::ScalarImage;
use crate::reference::plane_light::nearest_sweep_plane;
use crate::reference::scatter::Slab;
use crate::render::PreparedScene;
use crate::scene::{Quality, Scene, ViewSetup};
use crate::transfer::{ColorRamp, Curve, TransferFunctions};
use crate::volume::{Volume, VolumeError};

use super::BenchError;

/// Voxels per side of the volume; the frame spans them on as many pixels.
pub const N: usize = 64;
/// Voxel depth where the medium starts (the mask in front of it is 2 voxels thick).
pub const ENTRY: f32 = 4.0;
pub const MASK_END: f32 = 6.0;
/// Radius of the mask's hole, voxels: the beam.
pub const HOLE: f32 = 2.0;

/// Transfer functions of a medium at data value 0.5 (extinction `a + b` per voxel, albedo
/// b / (a + b), anisotropy g) and an opaque, non-scattering mask at 1; white, no refraction.
pub fn medium_tf(a: f32, b: f32, g: f32) -> TransferFunctions {
    let alpha = 1.0 - (-(a + b)).exp();
    let albedo = if a + b > 0.0 { b / (a + b) } else { 0.0 };
    TransferFunctions {
        name: None,
        opacity: Curve {
            points: vec![[0.0, 0.0], [0.5, alpha], [0.75, alpha], [1.0, 1.0]],
        },
        color: ColorRamp {
            points: vec![[0.0, 1.0, 1.0, 1.0]],
        },
        eta: Curve::constant(1.0),
        medium: ColorRamp::constant([1.0; 3]),
        albedo: Some(Curve {
            points: vec![[0.0, 0.0], [0.5, albedo], [0.75, albedo], [1.0, 0.0]],
        }),
        anisotropy: Some(Curve::constant(g)),
    }
}

/// The Monte Carlo reference's slab for the medium of [`medium_tf`]: from the entry to the
/// volume's far side, unbounded sideways.
pub fn reference_slab(a: f32, b: f32, g: f32) -> Slab {
    Slab {
        thickness: N as f64 - ENTRY as f64,
        half_width: 1000.0,
        absorption: a as f64,
        scattering: b as f64,
        g: g as f64,
    }
}

/// Air in front of voxel depth ENTRY, the medium behind it; with `hole`, an opaque mask from
/// ENTRY to MASK_END with a hole of that radius (voxels) on the axis.
pub fn slab_volume(hole: Option<f32>) -> Result<Volume, VolumeError> {
    let n = N as f32;
    let mut data = Vec::with_capacity(N * N * N);
    for z in 0..N {
        for y in 0..N {
            for x in 0..N {
                let z = z as f32;
                if z < ENTRY {
                    data.push(0.0);
                    continue;
                }
                let r2 = (x as f32 + 0.5 - 0.5 * n).powi(2) + (y as f32 + 0.5 - 0.5 * n).powi(2);
                data.push(match hole {
                    Some(r) if z < MASK_END && r2 > r * r => 1.0,
                    _ => 0.5,
                });
            }
        }
    }
    Volume::new([N, N, N], [1.0; 3], data)
}

/// Orthographic and head-on, the light along the view axis, black background; the frame spans
/// the volume's side (one pixel per voxel at N²).
pub fn slab_scene(tf: &TransferFunctions, quality: Quality) -> Scene {
    // The view spans 2·(bounding radius)/zoom: the cube's diagonal √3 N over √3.
    Scene::head_on("scattering slab", tf, 3f32.sqrt(), quality)
}

/// A sweep plane near a wanted depth.
#[derive(Clone, Copy, Debug)]
pub struct SlabPlane {
    /// The `--at-depth` value that selects it.
    pub depth: f32,
    /// Its voxel depth in the volume.
    pub voxel_z: f32,
    /// Its view-space depth.
    pub view_z: f32,
}

/// The slab scene prepared at N², with its view.
pub struct SlabSetup {
    pub prepared: PreparedScene,
    pub view: ViewSetup,
}

impl SlabSetup {
    pub fn new(volume: Volume, tf: TransferFunctions, quality: Quality) -> Result<SlabSetup, BenchError> {
        let scene = slab_scene(&tf, quality);
        let view = ViewSetup::new(&scene, volume.dims, volume.spacing, N as u32, N as u32).map_err(BenchError::Plan)?;
        Ok(SlabSetup {
            prepared: PreparedScene::from_parts(scene, volume, tf)?,
            view,
        })
    }

    /// The view-space point at volume texture coordinates `tex`.
    fn view_point(&self, tex: Vec3) -> Vec3 {
        let world = self.view.tex_from_world.inverse().transform_point3(tex);
        self.view.view_from_world.transform_point3(world)
    }

    /// The view-space point on the axis at voxel depth `z`.
    pub fn axis_point(&self, z: f32) -> Vec3 {
        self.view_point(Vec3::new(0.5, 0.5, z / N as f32))
    }

    /// Voxel coordinates of the view-space point `p`.
    pub fn voxel_of(&self, p: Vec3) -> Vec3 {
        let tex = self
            .view
            .tex_from_world
            .transform_point3(self.view.world_from_view.transform_point3(p));
        tex * N as f32
    }

    /// The sweep plane nearest voxel depth `z`.
    pub fn plane_near(&self, z: f32) -> SlabPlane {
        let (_, depth, plane_z) = nearest_sweep_plane(&self.view, self.axis_point(z).z as f64);
        let p = self
            .view
            .point_at(self.view.pixel_of(self.axis_point(z)), plane_z as f32);
        SlabPlane {
            depth,
            voxel_z: self.voxel_of(p).z,
            view_z: plane_z as f32,
        }
    }

    /// Continuous pixel coordinates of the axis (pixel u spans [u, u + 1)), and voxels per
    /// pixel.
    pub fn axis_pixel(&self) -> (Vec2, f32) {
        let a = self.view.pixel_of(self.axis_point(ENTRY));
        let p = |t: Vec3| self.view.pixel_of(self.view_point(t));
        let step = p(Vec3::new(0.5 + 1.0 / N as f32, 0.5, 0.5)) - p(Vec3::new(0.5, 0.5, 0.5));
        (a, 1.0 / step.length())
    }
}

/// Distance in voxels from the axis of the centre of pixel (x, y).
fn radius(x: usize, y: usize, axis: Vec2, voxels_per_pixel: f32) -> f64 {
    ((Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - axis).length() * voxels_per_pixel) as f64
}

/// Light (irradiance on the plane) within `max_r` voxels of the axis: its sum over the pixels
/// and its mean r² (voxels²).
pub fn light_moments(img: &ScalarImage, axis: Vec2, voxels_per_pixel: f32, max_r: f32) -> (f64, f64) {
    let (mut sum, mut r2sum) = (0.0, 0.0);
    for y in 0..img.height {
        for x in 0..img.width {
            let r = radius(x, y, axis, voxels_per_pixel);
            if r <= max_r as f64 {
                let l = img.at(x, y);
                sum += l;
                r2sum += l * r * r;
            }
        }
    }
    (sum, r2sum / sum)
}

/// The light's power in `rings` rings of equal width tiling the disc of radius `max_r` voxels
/// around the axis (as `reference::scatter::plane_flux_rings`), in voxel² × irradiance.
pub fn ring_profile(img: &ScalarImage, axis: Vec2, voxels_per_pixel: f32, max_r: f32, rings: usize) -> Vec<f64> {
    let mut out = vec![0.0; rings];
    let width = max_r as f64 / rings as f64;
    let pixel_area = (voxels_per_pixel as f64).powi(2);
    for y in 0..img.height {
        for x in 0..img.width {
            let r = radius(x, y, axis, voxels_per_pixel);
            if r <= max_r as f64 && rings > 0 {
                out[((r / width) as usize).min(rings - 1)] += img.at(x, y) * pixel_area;
            }
        }
    }
    out
}

/// Σ|a − b| / Σ|b| over two profiles of equal length.
pub fn relative_l1(a: &[f64], b: &[f64]) -> f64 {
    let l1: f64 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum();
    let total: f64 = b.iter().map(|y| y.abs()).sum();
    l1 / total
}
