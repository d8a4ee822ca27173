//! The optical field the reference renderer integrates through: refractive index η and its
//! gradient, optical depths and particle colour at any point, in f64. [`VolumeMedium`] is a
//! scene's volume seen through its transfer functions; tests implement [`Medium`] for analytic
//! fields (linear gradients, smoothed interfaces, Luneburg lenses).

use glam::DVec3;

use crate::scene::PreparedScene;
use crate::scene::{Scene, Toggle};
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

/// Which of a scene's optical effects are rendered: the reference decides this itself, from
/// the scene alone, as the GPU renderer's `Features::for_scene` does (a test checks they
/// agree), so that it shares none of the renderer's code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneOptics {
    /// η varies (or refraction is forced on): rays bend.
    pub refraction: bool,
    /// Cook–Torrance highlights at index interfaces.
    pub specular: bool,
    /// η comes from the scene's separate η volume.
    pub eta_volume: bool,
}

impl SceneOptics {
    pub fn of(scene: &Scene, tf: &TransferFunctions) -> SceneOptics {
        let q = &scene.quality;
        let refraction = match q.refraction {
            Toggle::On => true,
            Toggle::Off => false,
            // An η volume goes through η_tf too: a constant η_tf refracts nothing either way.
            Toggle::Auto => !tf.eta_is_constant(),
        };
        SceneOptics {
            refraction,
            specular: refraction && q.specular && scene.shading.specular > 0.0,
            eta_volume: refraction && scene.has_eta_volume(),
        }
    }
}

/// Samples of one scalar grid spanning the volume's box, windowed to [0, 1].
struct Grid {
    dims: [usize; 3],
    /// Voxel size of this grid (the box divided by its dims).
    spacing: DVec3,
    data: Vec<f64>,
}

impl Grid {
    fn new(volume: &Volume, window: [f32; 2], extent: DVec3) -> Grid {
        let (lo, hi) = (window[0] as f64, window[1] as f64);
        let width = hi - lo;
        let data = volume
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
        let dims = volume.dims;
        Grid {
            dims,
            spacing: extent / DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64),
            data,
        }
    }

    /// Voxel value with zero padding outside the grid.
    fn get(&self, i: i64, j: i64, k: i64) -> f64 {
        let [nx, ny, nz] = self.dims.map(|d| d as i64);
        if i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz {
            return 0.0;
        }
        self.data[(i + nx * (j + ny * k)) as usize]
    }

    /// Trilinear value at a point given in box coordinates (0 at the box's corner).
    fn value(&self, u: DVec3) -> f64 {
        let q = u / self.spacing - DVec3::splat(0.5);
        let base = q.floor();
        let f = q - base;
        let (i, j, k) = (base.x as i64, base.y as i64, base.z as i64);
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let row = |y: i64, z: i64| lerp(self.get(i, y, z), self.get(i + 1, y, z), f.x);
        let plane = |z: i64| lerp(row(j, z), row(j + 1, z), f.y);
        lerp(plane(k), plane(k + 1), f.z)
    }

    /// Whether every voxel that trilinear lookups (and gradient stencils, with a margin of two
    /// voxels) anywhere in the box-coordinate range [lo, hi) can reach has the same value.
    fn constant_over(&self, lo: DVec3, hi: DVec3) -> bool {
        let margin = 2i64;
        let first = [0, 1, 2].map(|a| (lo[a] / self.spacing[a]).floor() as i64 - margin);
        let last = [0, 1, 2].map(|a| (hi[a] / self.spacing[a]).ceil() as i64 + margin);
        let reference = self.get(first[0], first[1], first[2]);
        for k in first[2]..last[2] {
            for j in first[1]..last[1] {
                for i in first[0]..last[0] {
                    if self.get(i, j, k) != reference {
                        return false;
                    }
                }
            }
        }
        true
    }
}

/// A scene volume through its transfer functions. World space as in `render::ViewSetup`: the
/// volume's physical space centred on its bounding box. Values are windowed to [0, 1] without
/// quantisation and interpolated trilinearly; outside the grid the value is 0, as the GPU's
/// clamp-to-border sampler gives. η comes from the volume, or from a second volume over the
/// same box (its own grid, windowed to its value range, as the GPU's η texture); a clip plane
/// zeroes the particles' opacity on its positive side and leaves η and the medium alone.
pub struct VolumeMedium {
    grid: Grid,
    eta_grid: Option<Grid>,
    /// η everywhere, when the scene has refraction switched off.
    eta_constant: Option<f64>,
    /// World-space unit normal and offset: clipped where normal·p > offset.
    clip: Option<(DVec3, f64)>,
    half_extent: DVec3,
    tf: TransferFunctions,
    voxel_length: f64,
    blocks: [usize; 3],
    uniform: Vec<bool>,
}

impl VolumeMedium {
    pub fn new(volume: &Volume, window: [f32; 2], tf: &TransferFunctions) -> Self {
        let spacing = DVec3::new(
            volume.spacing[0] as f64,
            volume.spacing[1] as f64,
            volume.spacing[2] as f64,
        );
        let dims = volume.dims;
        let extent = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * spacing;
        let mut m = VolumeMedium {
            grid: Grid::new(volume, window, extent),
            eta_grid: None,
            eta_constant: None,
            clip: None,
            half_extent: extent * 0.5,
            tf: tf.clone(),
            voxel_length: spacing.min_element(),
            blocks: dims.map(|d| d.div_ceil(BLOCK)),
            uniform: Vec::new(),
        };
        m.uniform = m.find_uniform_blocks();
        m
    }

    /// The medium of a prepared scene: its volume, window and transfer functions, its η volume
    /// (windowed to its value range, like the GPU's), its clip plane, and constant η when the
    /// scene switches refraction off (as the GPU then neither bends rays nor shades highlights).
    pub fn for_scene(prepared: &PreparedScene) -> Self {
        let scene = &prepared.scene;
        let vol = &prepared.volume;
        let mut m = VolumeMedium::new(vol, prepared.window(), &prepared.tf);
        let optics = SceneOptics::of(scene, &prepared.tf);
        if let Some(ev) = prepared.eta_volume.as_ref().filter(|_| optics.eta_volume) {
            m.eta_grid = Some(Grid::new(ev, ev.value_range, m.half_extent * 2.0));
        }
        if !optics.refraction {
            m.eta_constant = Some(m.eta_of(0.0));
        }
        if let Some(c) = &scene.clip {
            // As `ViewSetup::clip_plane`: the normal in volume axes, the offset in bounding radii.
            let n = glam::Vec3::from(c.normal).normalize_or(glam::Vec3::Y);
            let radius = m.half_extent.length();
            m.clip = Some((DVec3::new(n.x as f64, n.y as f64, n.z as f64), c.offset as f64 * radius));
        }
        m.uniform = m.find_uniform_blocks();
        m
    }

    /// Box coordinates (0 at the corner) of a world point.
    fn box_coords(&self, p: DVec3) -> DVec3 {
        p + self.half_extent
    }

    /// Trilinear value in [0, 1] at a world point.
    pub fn value(&self, p: DVec3) -> f64 {
        self.grid.value(self.box_coords(p))
    }

    /// Gradient of the value (per world unit) by central differences `half_width_voxels`
    /// voxels either side along each axis: the surface normal of the data, which highlights
    /// use (as the GPU's, from the volume, not η).
    pub fn value_gradient(&self, p: DVec3, half_width_voxels: f64) -> DVec3 {
        let h = self.grid.spacing * half_width_voxels;
        let d = |axis: DVec3, h: f64| (self.value(p + axis * h) - self.value(p - axis * h)) / (2.0 * h);
        DVec3::new(d(DVec3::X, h.x), d(DVec3::Y, h.y), d(DVec3::Z, h.z))
    }

    fn eta_of(&self, v: f64) -> f64 {
        interpolate(&self.tf.eta.points, v, 1)
    }

    /// Single-scattering albedo and Henyey–Greenstein g at a world point (0 and 0 without
    /// the transfer functions' scattering curves).
    pub fn scattering(&self, p: DVec3) -> (f64, f64) {
        let v = self.value(p);
        let curve = |c: &Option<crate::transfer::Curve>| c.as_ref().map_or(0.0, |c| interpolate(&c.points, v, 1));
        (curve(&self.tf.albedo), curve(&self.tf.anisotropy))
    }

    /// Upper bounds of the optical depths per unit length anywhere in the medium: of the
    /// particles, and of the medium per channel. Values interpolate linearly and the transfer
    /// functions are piecewise linear, so the extremes are at control points.
    pub fn max_optical_depths(&self) -> (f64, [f64; 3]) {
        let per_length = 1.0 / self.voxel_length;
        let max_alpha = self.tf.opacity.points.iter().map(|p| p[1] as f64).fold(0.0, f64::max);
        let min_medium = |k: usize| self.tf.medium.points.iter().map(|p| p[k] as f64).fold(1.0, f64::min);
        (
            depth_per_voxel(1.0 - max_alpha) * per_length,
            [1, 2, 3].map(|k| depth_per_voxel(min_medium(k)) * per_length),
        )
    }

    fn clipped(&self, p: DVec3) -> bool {
        self.clip.is_some_and(|(n, offset)| n.dot(p) > offset)
    }

    /// A block is uniform when every voxel that any point in it (or a gradient stencil around
    /// such a point) can reach has the same value, in the volume and in the η volume.
    fn find_uniform_blocks(&self) -> Vec<bool> {
        let [bx, by, bz] = self.blocks;
        let mut out = Vec::with_capacity(bx * by * bz);
        let cell = self.grid.spacing * BLOCK as f64;
        for z in 0..bz {
            for y in 0..by {
                for x in 0..bx {
                    let lo = DVec3::new(x as f64, y as f64, z as f64) * cell;
                    let hi = lo + cell;
                    let same = self.grid.constant_over(lo, hi)
                        && self.eta_grid.as_ref().is_none_or(|g| g.constant_over(lo, hi));
                    out.push(same);
                }
            }
        }
        out
    }
}

impl Medium for VolumeMedium {
    fn eta(&self, p: DVec3) -> f64 {
        if let Some(eta) = self.eta_constant {
            return eta;
        }
        match &self.eta_grid {
            Some(g) => self.eta_of(g.value(self.box_coords(p))),
            None => self.eta_of(self.value(p)),
        }
    }

    fn grad_eta(&self, p: DVec3) -> DVec3 {
        if self.eta_constant.is_some() {
            return DVec3::ZERO;
        }
        let h = self.grid.spacing * GRADIENT_HALF_WIDTH_VOXELS;
        let d = |axis: DVec3, h: f64| (self.eta(p + axis * h) - self.eta(p - axis * h)) / (2.0 * h);
        DVec3::new(d(DVec3::X, h.x), d(DVec3::Y, h.y), d(DVec3::Z, h.z))
    }

    fn optics(&self, p: DVec3) -> Optics {
        let v = self.value(p);
        let per_length = 1.0 / self.voxel_length;
        let alpha = if self.clipped(p) {
            0.0
        } else {
            interpolate(&self.tf.opacity.points, v, 1)
        };
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
        let mut border = self.grid.spacing;
        if let Some(g) = &self.eta_grid {
            border = border.max(g.spacing);
        }
        let border = self.half_extent + 0.5 * border;
        (-border, border)
    }

    fn voxel_length(&self) -> f64 {
        self.voxel_length
    }

    fn uniform_for(&self, p: DVec3, d: DVec3) -> Option<f64> {
        // Position in voxels from the box corner; blocks cover [b·BLOCK, (b+1)·BLOCK).
        let dims = self.grid.dims;
        let spacing = self.grid.spacing;
        let u = self.box_coords(p) / spacing;
        let mut index = [0usize; 3];
        for a in 0..3 {
            if u[a].is_nan() || u[a] < 0.0 || u[a] >= dims[a] as f64 {
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
            let hi = ((index[a] + 1) * BLOCK).min(dims[a]) as f64;
            let speed = d[a] / spacing[a];
            if speed > 1e-12 {
                t = t.min((hi - u[a]) / speed);
            } else if speed < -1e-12 {
                t = t.min((lo - u[a]) / speed);
            }
        }
        // Opacity changes at the clip plane: stop there.
        if let Some((n, offset)) = self.clip {
            let to_plane = (offset - n.dot(p)) / n.dot(d);
            if to_plane > 0.0 {
                t = t.min(to_plane);
            }
        }
        Some(t.max(0.0))
    }
}
