//! The optical field the reference renderer integrates through: refractive index η and its
//! gradient, optical depths and particle colour at any point, in f64. [`VolumeMedium`] is a
//! scene's volume seen through its transfer functions; tests implement [`Medium`] for analytic
//! fields (linear gradients, smoothed interfaces, Luneburg lenses).

use glam::DVec3;

use crate::transfer::{TransferFunctions, MAX_OPTICAL_DEPTH_PER_VOXEL};
use crate::volume::Volume;

/// Extinction and colour at a point, per unit length (world units).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Optics {
    /// Optical depth of the particles per unit length: a segment of length ℓ keeps e^{-τℓ}.
    pub tau_alpha: f64,
    /// Optical depth of the medium per unit length and channel.
    pub tau_medium: [f64; 3],
    /// Particle colour.
    pub color: [f64; 3],
}

/// A continuous optical field. Outside [`Medium::bounds`] η is constant and nothing absorbs.
pub trait Medium: Sync {
    fn eta(&self, p: DVec3) -> f64;
    fn grad_eta(&self, p: DVec3) -> DVec3;
    fn optics(&self, p: DVec3) -> Optics;
    /// Axis-aligned box (min, max) holding everything that refracts or absorbs.
    fn bounds(&self) -> (DVec3, DVec3);
    /// The length of one voxel (the unit of the transfer functions' opacity and medium colour).
    fn voxel_length(&self) -> f64;
    /// If the field is uniform around `p` (no refraction, constant optics), the distance along
    /// the unit direction `d` for which it stays uniform; rays may cross it in one straight step.
    fn uniform_for(&self, _p: DVec3, _d: DVec3) -> Option<f64> {
        None
    }
}

/// Central-difference half width of ∇η, in voxels: well below the one voxel of the GPU
/// renderer, and wide enough to keep steps in the η transfer function finite.
pub const GRADIENT_HALF_WIDTH_VOXELS: f64 = 0.25;

/// Edge of the blocks whose uniformity is precomputed, in voxels.
const BLOCK: usize = 4;

/// Piecewise-linear interpolation of control points (as `transfer::Curve`), in f64.
fn interpolate<const N: usize>(points: &[[f32; N]], x: f64, k: usize) -> f64 {
    let Some(first) = points.first() else { return 0.0 };
    if x <= first[0] as f64 {
        return first[k] as f64;
    }
    for w in points.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if x < b[0] as f64 {
            let span = (b[0] - a[0]) as f64;
            let t = if span > 0.0 { (x - a[0] as f64) / span } else { 1.0 };
            return a[k] as f64 + (b[k] - a[k]) as f64 * t;
        }
    }
    points[points.len() - 1][k] as f64
}

/// Optical depth of a per-voxel transmittance, clamped as in the GPU's pre-integration.
fn depth_per_voxel(transmittance: f64) -> f64 {
    if transmittance <= 0.0 {
        MAX_OPTICAL_DEPTH_PER_VOXEL as f64
    } else {
        (-transmittance.ln()).clamp(0.0, MAX_OPTICAL_DEPTH_PER_VOXEL as f64)
    }
}

/// A scene volume through its transfer functions. World space as in `render::ViewSetup`: the
/// volume's physical space centred on its bounding box. Values are windowed to [0, 1] without
/// quantisation and interpolated trilinearly; outside the grid the value is 0, as the GPU's
/// clamp-to-border sampler gives.
pub struct VolumeMedium {
    dims: [usize; 3],
    spacing: DVec3,
    half_extent: DVec3,
    data: Vec<f64>,
    tf: TransferFunctions,
    voxel_length: f64,
    blocks: [usize; 3],
    uniform: Vec<bool>,
}

impl VolumeMedium {
    pub fn new(volume: &Volume, window: [f32; 2], tf: &TransferFunctions) -> Self {
        let (lo, hi) = (window[0] as f64, window[1] as f64);
        let width = hi - lo;
        let data: Vec<f64> = volume
            .data
            .iter()
            .map(|&v| {
                let v = v as f64;
                let t = if width > 0.0 {
                    (v - lo) / width
                } else {
                    (v > lo) as u8 as f64
                };
                t.clamp(0.0, 1.0)
            })
            .collect();
        let spacing = DVec3::new(
            volume.spacing[0] as f64,
            volume.spacing[1] as f64,
            volume.spacing[2] as f64,
        );
        let dims = volume.dims;
        let extent = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * spacing;
        let blocks = dims.map(|d| d.div_ceil(BLOCK));
        let mut m = VolumeMedium {
            dims,
            spacing,
            half_extent: extent * 0.5,
            data,
            tf: tf.clone(),
            voxel_length: spacing.min_element(),
            blocks,
            uniform: Vec::new(),
        };
        m.uniform = m.find_uniform_blocks();
        m
    }

    /// Voxel value with zero padding outside the grid.
    fn get(&self, i: i64, j: i64, k: i64) -> f64 {
        let [nx, ny, nz] = self.dims.map(|d| d as i64);
        if i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz {
            return 0.0;
        }
        self.data[(i + nx * (j + ny * k)) as usize]
    }

    /// Continuous voxel coordinates (voxel centres at integers) of a world point.
    fn voxel_coords(&self, p: DVec3) -> DVec3 {
        (p + self.half_extent) / self.spacing - DVec3::splat(0.5)
    }

    /// Trilinear value in [0, 1] at a world point.
    pub fn value(&self, p: DVec3) -> f64 {
        let q = self.voxel_coords(p);
        let base = q.floor();
        let f = q - base;
        let (i, j, k) = (base.x as i64, base.y as i64, base.z as i64);
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let row = |y: i64, z: i64| lerp(self.get(i, y, z), self.get(i + 1, y, z), f.x);
        let plane = |z: i64| lerp(row(j, z), row(j + 1, z), f.y);
        lerp(plane(k), plane(k + 1), f.z)
    }

    fn eta_of(&self, v: f64) -> f64 {
        interpolate(&self.tf.eta.points, v, 1)
    }

    /// A block is uniform when every voxel that any point in it (or a gradient stencil around
    /// such a point) can reach has the same value.
    fn find_uniform_blocks(&self) -> Vec<bool> {
        let [bx, by, bz] = self.blocks;
        let mut out = Vec::with_capacity(bx * by * bz);
        let margin = 2i64;
        for z in 0..bz {
            for y in 0..by {
                for x in 0..bx {
                    let lo = [x, y, z].map(|b| (b * BLOCK) as i64 - margin);
                    let hi = [x, y, z].map(|b| ((b + 1) * BLOCK) as i64 + margin);
                    let first = self.get(lo[0], lo[1], lo[2]);
                    let mut same = true;
                    'scan: for k in lo[2]..hi[2] {
                        for j in lo[1]..hi[1] {
                            for i in lo[0]..hi[0] {
                                if self.get(i, j, k) != first {
                                    same = false;
                                    break 'scan;
                                }
                            }
                        }
                    }
                    out.push(same);
                }
            }
        }
        out
    }
}

impl Medium for VolumeMedium {
    fn eta(&self, p: DVec3) -> f64 {
        self.eta_of(self.value(p))
    }

    fn grad_eta(&self, p: DVec3) -> DVec3 {
        let h = self.spacing * GRADIENT_HALF_WIDTH_VOXELS;
        let d = |axis: DVec3, h: f64| (self.eta(p + axis * h) - self.eta(p - axis * h)) / (2.0 * h);
        DVec3::new(d(DVec3::X, h.x), d(DVec3::Y, h.y), d(DVec3::Z, h.z))
    }

    fn optics(&self, p: DVec3) -> Optics {
        let v = self.value(p);
        let per_length = 1.0 / self.voxel_length;
        let alpha = interpolate(&self.tf.opacity.points, v, 1);
        let m = &self.tf.medium.points;
        let c = &self.tf.color.points;
        Optics {
            tau_alpha: depth_per_voxel(1.0 - alpha) * per_length,
            tau_medium: [1, 2, 3].map(|k| depth_per_voxel(interpolate(m, v, k)) * per_length),
            color: [1, 2, 3].map(|k| interpolate(c, v, k)),
        }
    }

    /// The grid's box and the half voxel around it where trilinear interpolation still blends
    /// the edge voxels with the zero border (as the GPU's clamp-to-border sampler does): a ray
    /// started on the box face itself would miss that part of the index step.
    fn bounds(&self) -> (DVec3, DVec3) {
        let border = self.half_extent + 0.5 * self.spacing;
        (-border, border)
    }

    fn voxel_length(&self) -> f64 {
        self.voxel_length
    }

    fn uniform_for(&self, p: DVec3, d: DVec3) -> Option<f64> {
        // Position in voxels from the box corner; blocks cover [b·BLOCK, (b+1)·BLOCK).
        let u = (p + self.half_extent) / self.spacing;
        let mut index = [0usize; 3];
        for a in 0..3 {
            if u[a].is_nan() || u[a] < 0.0 || u[a] >= self.dims[a] as f64 {
                return None;
            }
            index[a] = (u[a] as usize) / BLOCK;
        }
        let [bx, by, _] = self.blocks;
        if !self.uniform[index[0] + bx * (index[1] + by * index[2])] {
            return None;
        }
        // Distance to the block's exit along d.
        let mut t = f64::INFINITY;
        for a in 0..3 {
            let lo = (index[a] * BLOCK) as f64;
            let hi = ((index[a] + 1) * BLOCK).min(self.dims[a]) as f64;
            let speed = d[a] / self.spacing[a];
            if speed > 1e-12 {
                t = t.min((hi - u[a]) / speed);
            } else if speed < -1e-12 {
                t = t.min((lo - u[a]) / speed);
            }
        }
        Some(t.max(0.0))
    }
}
