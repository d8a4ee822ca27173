//! Camera, planes and light in view space: everything that turns a scene into `Params`.
//!
//! World space is the volume's physical space centred on its bounding box (x right, y up,
//! z back). View space has the camera at the origin, x right, y down and z forward, so that
//! planes of constant z are parallel to the image plane and buffer rows match image rows.

use glam::{Mat3, Mat4, Vec3, Vec4};

use crate::scene::{Camera, Light, Projection, Scene};

/// Light directions stay at least this far from the planes (z component of the unit
/// direction): about 89°, the largest angle a scene may ask for.
pub const MIN_LIGHT_DIR_Z: f32 = 0.017;
/// View rays whose direction gets closer than this to the planes leave the sweep.
pub const MIN_VIEW_DIR_Z: f32 = 0.02;
/// Largest light value stored: far below the 16-bit float maximum (65504), far above any
/// physical concentration the per-plane ratio clamp can build up in a few planes.
pub const MAX_LIGHT_VALUE: f32 = 16384.0;
/// Nearest plane distance for a camera inside the volume, in bounding radii.
pub const NEAR_PLANE: f32 = 1e-3;
/// More planes than this means a sample distance far below a voxel on a huge volume.
pub const MAX_PLANES: u32 = 1 << 15;

/// The sweep starts this many voxels (smallest spacing) in front of the volume's box and ends
/// as far behind it: trilinear sampling reaches half a voxel beyond the box, and the first
/// segment must see the whole index step at the volume's face (Snell's law at the boundary).
pub const SWEEP_MARGIN_VOXELS: f32 = 1.0;

/// At most this many beams per image pixel (× beams_per_texel²): a light nearly parallel to
/// the planes would otherwise need beams along a shadow many images long. Beyond it the
/// beams get wider (coarser light).
pub const MAX_BEAMS_PER_PIXEL: f32 = 2.0;

/// Refracted beams per voxel and axis at most (times `beams_per_texel`), where pixels are
/// smaller than that. Refracted light is bent by an index field that is trilinear between
/// voxels, and beams much finer than it resolve little more. The CT head's full-effects render
/// at 512² (2.1 plane-0 pixels per voxel) against one with four beams per voxel at Δs = ¼:
/// relative L1 0.0470 at 2, 0.0468 at 1.5, 0.0471 at 1.25 and 0.0479 at 1 beam per voxel. The
/// glass ball of `bench --light` (R = 16, two texels per voxel) against the exact trace of the
/// continuous ball, mean relative L1 over its five planes at Δs 1, ½ and ¼: 0.120, 0.116 and
/// 0.107 at 2 beams per voxel, 0.109, 0.113 and 0.109 at 1.5, 0.115, 0.119 and 0.123 at 1.25,
/// 0.121, 0.119 and 0.114 at 1: below 1.5 the caustic gets worse (the plane nearest the focus
/// most), while the CT head's light pass at 512² takes 29 % less at 1.25. The viewer's full
/// frame of the CT head (644×768): 12.4–13.2 s at 2, 9.4–9.7 s at 1.5.
pub const REFRACTED_BEAMS_PER_VOXEL: f32 = 1.5;

/// How many times coarser per axis than `beams_per_texel` asks (in pixels at the volume's
/// centre) the cap of [`REFRACTED_BEAMS_PER_VOXEL`] may make refracted beams. Where pixels are
/// much smaller than voxels the cap alone makes a beam several pixels wide, and its deposit (a
/// box of its footprint) blurs the caustic on the image: the R = 8 ball at four texels per
/// voxel (`tests/transport.rs`) at 1.5 beams per voxel (2.7 pixels a beam) is 0.014–0.053
/// further from the exact trace than with twice the beams, at 2 pixels a beam within 0.02.
pub const REFRACTED_MAX_COARSENING: f32 = 2.0;

/// A floor on the light grid's cells where pixels are smaller than voxels
/// ([`ViewSetup::beam_grid`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelCap {
    /// Beams per voxel and axis at most (times `beams_per_texel`).
    pub beams_per_voxel: f32,
    /// How many times coarser per axis than asked the cap may make the cells.
    pub max_coarsening: f32,
}

impl VoxelCap {
    /// Refracted beams: [`REFRACTED_BEAMS_PER_VOXEL`], [`REFRACTED_MAX_COARSENING`].
    pub const REFRACTED: VoxelCap = VoxelCap {
        beams_per_voxel: REFRACTED_BEAMS_PER_VOXEL,
        max_coarsening: REFRACTED_MAX_COARSENING,
    };
    /// Beams that keep their cells: one per voxel, however wide that makes them. Fewer cost
    /// accuracy for little time: the CT head's soft-light compare scene at 256² against a
    /// render with two beams per texel reads relative L1 0.024 at one beam per voxel, 0.029 at
    /// 0.75 and 0.051 at 0.5, for about a tenth less time at 0.75 (two noisy renders each).
    pub const UNREFRACTED: VoxelCap = VoxelCap {
        beams_per_voxel: 1.0,
        max_coarsening: f32::INFINITY,
    };
}

/// Pixels of the image whose rays can meet the volume: the projection of its box, a pixel
/// wider on each side for the bilinear taps of light lookups. Half-open: x0 ≤ x < x1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl PixelRect {
    /// The whole frame of `width`×`height` pixels.
    pub fn frame(width: u32, height: u32) -> PixelRect {
        PixelRect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
    }

    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
}

/// The beams of the forward light transport: a regular grid of cells on plane 0, in that
/// plane's pixel coordinates (pixel u spans [u, u + 1)). Beam (i, j) starts at the centre of
/// cell [x0 + i·stride, x0 + (i + 1)·stride) × [y0 + j·stride, …) and carries the light that
/// crosses it. The grid covers the volume's shadow on the planes the image needs; light
/// outside it is unobstructed and not traced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamGrid {
    pub x0: f32,
    pub y0: f32,
    pub stride: f32,
    pub width: u32,
    pub height: u32,
}

impl BeamGrid {
    pub fn count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// The grid with its cells moved back by the fractions `fx`, `fy` ∈ [0, 1) of a cell, one
    /// more column and row where moved so that it still covers what it covered.
    pub fn shifted(self, fx: f32, fy: f32) -> BeamGrid {
        let (fx, fy) = (fx.clamp(0.0, 1.0), fy.clamp(0.0, 1.0));
        BeamGrid {
            x0: self.x0 - fx * self.stride,
            y0: self.y0 - fy * self.stride,
            width: self.width + u32::from(fx > 0.0),
            height: self.height + u32::from(fy > 0.0),
            ..self
        }
    }
}

/// The view transform and plane sweep of one render.
#[derive(Clone, Debug)]
pub struct ViewSetup {
    pub view_from_world: Mat4,
    pub world_from_view: Mat4,
    pub tex_from_world: Mat4,
    /// How the volume's textures lay out its axes: axis `memory_axes[i]` of the volume (and
    /// of the world) is the textures' axis i, the first fastest in memory
    /// ([`ViewSetup::memory_axes_for_view`]); [0, 1, 2] for the volume as stored.
    pub memory_axes: [usize; 3],
    /// Physical size of the volume (dims × spacing).
    pub extent: Vec3,
    pub radius: f32,
    pub z_first: f32,
    /// Distance between planes in world units (Δs).
    pub step: f32,
    /// The smallest voxel dimension in world units, of the volume the passes sample (its half
    /// level at `quality.volume_level` 1).
    pub voxel: f32,
    pub planes: u32,
    pub projection: [f32; 4],
    pub perspective: bool,
    /// Pixels whose rays can meet the volume.
    pub rect: PixelRect,
    /// Image size.
    pub width: u32,
    pub height: u32,
}

/// At most [`MAX_PLANES`] planes per sweep.
fn check_planes(planes: u64) -> Result<(), String> {
    if planes > MAX_PLANES as u64 {
        return Err(format!(
            "{planes} planes needed (more than {MAX_PLANES}); increase quality.sample_distance"
        ));
    }
    Ok(())
}

pub fn camera_position(camera: &Camera, radius: f32) -> (Vec3, Vec3) {
    let target = Vec3::from(camera.target) * radius;
    let (_, _, forward) = camera.basis();
    (target - forward * camera.distance * radius, target)
}

impl ViewSetup {
    pub fn new(scene: &Scene, dims: [usize; 3], spacing: [f32; 3], width: u32, height: u32) -> Result<Self, String> {
        let extent = Vec3::new(
            dims[0] as f32 * spacing[0],
            dims[1] as f32 * spacing[1],
            dims[2] as f32 * spacing[2],
        );
        let radius = extent.length() * 0.5;
        let (eye, _) = camera_position(&scene.camera, radius);
        let (right, down, forward) = scene.camera.basis();
        let rotation = Mat3::from_cols(right, down, forward); // world_from_view rotation
        let world_from_view = Mat4::from_translation(eye) * Mat4::from_mat3(rotation);
        let view_from_world = world_from_view.inverse();
        let tex_from_world = Mat4::from_scale(extent.recip()) * Mat4::from_translation(extent * 0.5);

        let min_spacing = spacing.iter().copied().fold(f32::INFINITY, f32::min);
        let step = scene.quality.sample_distance * min_spacing;
        // The voxels the passes sample: at `quality.volume_level` 1 the half level's, whose
        // trilinear reach beyond the box and cross-section are theirs (the sample distance
        // still counts the volume's own).
        let sampled = if scene.quality.volume_level > 0 {
            let coarse = crate::volume::half_level_dims(dims);
            (0..3)
                .map(|a| extent[a] / coarse[a] as f32)
                .fold(f32::INFINITY, f32::min)
        } else {
            min_spacing
        };
        let margin = SWEEP_MARGIN_VOXELS * sampled;
        let corners = box_corners(extent, margin);
        let (mut z_min, mut z_max) = (f32::INFINITY, f32::NEG_INFINITY);
        for c in &corners {
            let z = view_from_world.transform_point3(*c).z;
            z_min = z_min.min(z);
            z_max = z_max.max(z);
        }
        let perspective = scene.camera.projection == Projection::Perspective;
        let near = NEAR_PLANE * radius;
        let inside = perspective && z_min < near;
        if perspective {
            z_min = z_min.max(near);
        }
        if z_max <= z_min {
            return Err("the volume is behind the camera".into());
        }
        let planes = ((z_max - z_min) / step).ceil() as u64 + 1;
        check_planes(planes)?;
        let (w, h) = (width as f32, height as f32);
        let f = if perspective {
            (h * 0.5) / (scene.camera.fov_deg.to_radians() * 0.5).tan()
        } else {
            h / (2.0 * radius / scene.camera.zoom)
        };
        let mut setup = ViewSetup {
            view_from_world,
            world_from_view,
            tex_from_world,
            memory_axes: [0, 1, 2],
            extent,
            radius,
            z_first: z_min,
            step,
            voxel: sampled,
            planes: planes as u32,
            projection: [f, f, w * 0.5, h * 0.5],
            perspective,
            rect: PixelRect::frame(width, height),
            width,
            height,
        };
        if !inside {
            // The box in front of the camera: its projection bounds every pixel that meets it.
            let (mut lo, mut hi) = (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY));
            for c in &corners {
                let p = setup.pixel_of(view_from_world.transform_point3(*c));
                lo = lo.min(p);
                hi = hi.max(p);
            }
            // One pixel of slack for the bilinear taps of light lookups next to the box.
            let clamp = |v: f32, n: u32| v.clamp(0.0, n as f32) as u32;
            setup.rect = PixelRect {
                x0: clamp(lo.x.floor() - 1.0, width),
                y0: clamp(lo.y.floor() - 1.0, height),
                x1: clamp(hi.x.ceil() + 1.0, width),
                y1: clamp(hi.y.ceil() + 1.0, height),
            };
        }
        Ok(setup)
    }

    /// Depth of plane `i`.
    pub fn plane_z(&self, i: u32) -> f32 {
        self.z_first + i as f32 * self.step
    }

    /// Continuous pixel coordinates (pixel u spans [u, u + 1)) of a view-space point, as the
    /// shaders' `project` plus one half.
    pub fn pixel_of(&self, p: Vec3) -> glam::Vec2 {
        let [fx, fy, cx, cy] = self.projection;
        let xy = if self.perspective {
            p.truncate() / p.z
        } else {
            p.truncate()
        };
        glam::Vec2::new(xy.x * fx + cx, xy.y * fy + cy)
    }

    /// The view-space point on the plane at depth `z` at continuous pixel coordinates `px`.
    pub fn point_at(&self, px: glam::Vec2, z: f32) -> Vec3 {
        let [fx, fy, cx, cy] = self.projection;
        let ndc = glam::Vec2::new((px.x - cx) / fx, (px.y - cy) / fy);
        if self.perspective {
            (ndc * z).extend(z)
        } else {
            ndc.extend(z)
        }
    }

    /// Plane-0 pixels per pixel at the volume's centre: z_centre / z0 in perspective (when
    /// the centre lies beyond the first plane), 1 otherwise.
    fn plane0_pixels_per_centre_pixel(&self) -> f32 {
        let z_centre = self.view_from_world.transform_point3(Vec3::ZERO).z;
        if self.perspective && z_centre > self.z_first {
            z_centre / self.z_first
        } else {
            1.0
        }
    }

    /// The beams of the forward transport for light travelling along `light` (view space,
    /// unit, z > 0), `beams_per_texel` per pixel and axis on plane 0. They cover the box's
    /// shadow (what the volume can change) intersected with the light that reaches the pixels
    /// of [`ViewSetup::rect`] on any plane; everything else is unobstructed light.
    ///
    /// With `per_centre_pixel` the cells are sized per pixel at the volume's centre instead
    /// of per pixel on plane 0: in perspective a plane-0 pixel covers less of the scene than
    /// one at the centre (by z0 / z_centre), and light that keeps its cells (no refraction)
    /// need not be traced finer than the image resolves it there. Beams that deposit their
    /// power keep one cell per plane-0 pixel, so that an unrefracted beam is never wider than
    /// a pixel (it lands on the finest level of the deposit pyramid).
    ///
    /// With `voxel_cap` the cells are also no smaller than a voxel over its
    /// `beams_per_voxel` times `beams_per_texel`, but no more than its `max_coarsening` times
    /// coarser than asked. Light that keeps its cells ([`VoxelCap::UNREFRACTED`]) carries no
    /// detail across them finer than the volume that shadows it (and the view takes the last
    /// voxel of its way along each sample's own light line), so where a pixel is smaller than
    /// a voxel a finer grid only costs time. Refracted light is bent by an index field that is
    /// trilinear between voxels; beams a little finer than it still resolve where they
    /// converge, and beams wider than two pixels blur the caustic on the image
    /// ([`VoxelCap::REFRACTED`]).
    pub fn beam_grid(
        &self,
        light: Vec3,
        beams_per_texel: f32,
        per_centre_pixel: bool,
        voxel_cap: Option<VoxelCap>,
    ) -> BeamGrid {
        let z0 = self.z_first;
        let z_last = self.plane_z(self.planes - 1);
        let to_plane0 = |p: Vec3| self.pixel_of(p - light * ((p.z - z0) / light.z));
        let bounds = |points: &mut dyn Iterator<Item = glam::Vec2>| {
            points.fold(
                (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY)),
                |(lo, hi), p| (lo.min(p), hi.max(p)),
            )
        };
        // The shadow of the (dilated) box on plane 0, projected back along the light.
        let margin = SWEEP_MARGIN_VOXELS * 2.0 * self.step.min(self.extent.min_element());
        let (s_lo, s_hi) = bounds(&mut box_corners(self.extent, margin).into_iter().map(|c| {
            let v = self.view_from_world.transform_point3(c);
            to_plane0(Vec3::new(v.x, v.y, v.z.max(z0)))
        }));
        // The light that reaches the rect on the first and the last plane (the rect's
        // back-projection sweeps linearly in between).
        let r = self.rect;
        let mut needed = Vec::new();
        for z in [z0, z_last] {
            for (x, y) in [(r.x0, r.y0), (r.x1, r.y0), (r.x0, r.y1), (r.x1, r.y1)] {
                needed.push(to_plane0(self.point_at(glam::Vec2::new(x as f32, y as f32), z)));
            }
        }
        let (n_lo, n_hi) = bounds(&mut needed.into_iter());
        let lo = s_lo.max(n_lo);
        let hi = s_hi.min(n_hi).max(lo);
        let centre_pixel = self.plane0_pixels_per_centre_pixel();
        let pixels_per_centre_pixel = if per_centre_pixel { centre_pixel } else { 1.0 };
        let mut stride = pixels_per_centre_pixel / beams_per_texel;
        if let Some(cap) = voxel_cap {
            // A voxel's cross-section is the same on every plane (parallel light): its size in
            // plane-0 pixels.
            let pixels_per_unit = self.projection[0] / if self.perspective { z0 } else { 1.0 };
            let per_voxel = self.voxel * pixels_per_unit / (cap.beams_per_voxel * beams_per_texel);
            // Coarser than asked by at most `max_coarsening`, counted in pixels at the
            // volume's centre, where the light is seen.
            let coarsest = cap.max_coarsening * centre_pixel / beams_per_texel;
            stride = stride.max(per_voxel.min(coarsest));
        }
        let pixels = (self.width as f32 * self.height as f32).max(1.0);
        let budget = MAX_BEAMS_PER_PIXEL * pixels * beams_per_texel * beams_per_texel;
        let area = ((hi - lo).x + 2.0 * stride) * ((hi - lo).y + 2.0 * stride);
        if area / (stride * stride) > budget {
            stride = (area / budget).sqrt();
        }
        let x0 = (lo.x / stride).floor() * stride;
        let y0 = (lo.y / stride).floor() * stride;
        BeamGrid {
            x0,
            y0,
            stride,
            width: (((hi.x - x0) / stride).ceil() as u32).max(1),
            height: (((hi.y - y0) / stride).ceil() as u32).max(1),
        }
    }

    /// Moves the planes toward the camera by the fraction `f` ∈ [0, 1) of the plane distance,
    /// with one more plane so that the sweep still starts in front of the volume. A
    /// perspective camera whose near plane is that close (inside or at the volume) keeps its
    /// planes: the sweep starts at the near plane.
    pub fn shift_planes(&mut self, f: f32) -> Result<(), String> {
        let f = f.clamp(0.0, 1.0);
        let earlier = self.z_first - f * self.step;
        if f == 0.0 || (self.perspective && earlier < NEAR_PLANE * self.radius) {
            return Ok(());
        }
        check_planes(self.planes as u64 + 1)?;
        self.z_first = earlier;
        self.planes += 1;
        Ok(())
    }

    /// Volume texture coordinates of a view-space point, along the textures' axes
    /// (`memory_axes`).
    pub fn volume_from_view(&self) -> Mat4 {
        self.memory_from_volume() * self.tex_from_world * self.world_from_view
    }

    /// The volume's axes reordered as the textures lay them out: row i picks axis
    /// `memory_axes[i]`.
    fn memory_from_volume(&self) -> Mat4 {
        let a = self.memory_axes;
        Mat4::from_mat3(Mat3::from_cols(Vec3::AXES[a[0]], Vec3::AXES[a[1]], Vec3::AXES[a[2]]).transpose())
    }

    /// Maps per-texel central differences (f(p+h) − f(p−h) along each texture axis, `spacing`
    /// the voxel size along each) to a view-space gradient.
    pub fn gradient_to_view(&self, spacing: [f32; 3]) -> Mat4 {
        let rotation = Mat3::from_mat4(self.view_from_world);
        let scale = Mat3::from_diagonal(Vec3::new(0.5 / spacing[0], 0.5 / spacing[1], 0.5 / spacing[2]));
        let volume_from_memory = Mat3::from_mat4(self.memory_from_volume()).transpose();
        Mat4::from_mat3(rotation * volume_from_memory * scale)
    }

    /// The layout of the volume's textures that suits this view: as stored, unless the view
    /// looks along the stored fastest axis (x). Then each plane cuts across that axis and its
    /// samples use one texel of every cache line the volume fills, so that every plane reads
    /// the whole volume from memory again (the CT head seen from its side: the full-effects
    /// light pass a fifth longer than with x slowest). So x goes slowest, and
    /// the axis nearest the image's rows fastest, so that the pixels side by side in a row (a
    /// CPU driver's SIMD lanes) sample texels side by side. Looking along y or z a plane's
    /// texels already lie along whole cache lines: as stored, the same speed was measured as
    /// with the viewing axis slowest.
    pub fn memory_axes_for_view(&self) -> [usize; 3] {
        let forward = self.world_from_view.z_axis.truncate().abs();
        let right = self.world_from_view.x_axis.truncate().abs();
        if forward.x < forward.y || forward.x < forward.z {
            return [0, 1, 2];
        }
        let fast = if right.y >= right.z { 1 } else { 2 };
        [fast, 3 - fast, 0]
    }

    /// `v` (a value per volume axis) in the order of the textures' axes.
    pub fn in_memory_order<T: Copy>(&self, v: [T; 3]) -> [T; 3] {
        self.memory_axes.map(|a| v[a])
    }

    /// View-space plane (normal, offset) of a clip plane given in volume axes.
    pub fn clip_plane(&self, normal: [f32; 3], offset: f32) -> Vec4 {
        let n_world = Vec3::from(normal).normalize_or(Vec3::Y);
        let n_view = Mat3::from_mat4(self.view_from_world) * n_world;
        let eye = self.world_from_view.w_axis.truncate();
        Vec4::new(n_view.x, n_view.y, n_view.z, n_world.dot(eye) - offset * self.radius)
    }
}

/// The corners of the volume's box (world space, centred), grown by `margin` on each side.
fn box_corners(extent: Vec3, margin: f32) -> [Vec3; 8] {
    let half = extent * 0.5 + Vec3::splat(margin);
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { -half.x } else { half.x },
            if i & 2 == 0 { -half.y } else { half.y },
            if i & 4 == 0 { -half.z } else { half.z },
        )
    })
}

/// Propagation direction of the light in view space (unit length, z > 0).
pub fn light_direction(light: &Light) -> Vec3 {
    let polar = light
        .polar_deg
        .clamp(0.0, crate::scene::MAX_LIGHT_POLAR_DEG)
        .to_radians();
    let azimuth = light.azimuth_deg.to_radians();
    Vec3::new(-polar.sin() * azimuth.sin(), polar.sin() * azimuth.cos(), polar.cos())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin;

    #[test]
    fn textures_lay_x_out_slowest_only_for_views_along_it() {
        let mut scene = builtin("ball-lens").unwrap().scene;
        // Views along z and y (and between them) keep the stored layout; along x, x goes
        // slowest and the axis the image's rows run along fastest (z without roll, y with the
        // image turned by 90°).
        for (yaw, pitch, roll, expected) in [
            (0.0, 0.0, 0.0, [0, 1, 2]),
            (30.0, 20.0, 0.0, [0, 1, 2]),
            (0.0, 80.0, 0.0, [0, 1, 2]),
            (90.0, 0.0, 0.0, [2, 1, 0]),
            (260.0, 30.0, 0.0, [2, 1, 0]),
            (90.0, 0.0, 90.0, [1, 2, 0]),
        ] {
            scene.camera.yaw_deg = yaw;
            scene.camera.pitch_deg = pitch;
            scene.camera.roll_deg = roll;
            let v = ViewSetup::new(&scene, [40, 32, 24], [1.0, 1.25, 1.5], 48, 48).unwrap();
            assert_eq!(
                v.memory_axes_for_view(),
                expected,
                "yaw {yaw}, pitch {pitch}, roll {roll}"
            );
        }
    }

    #[test]
    fn a_layout_reorders_texture_coordinates_and_gradients_exactly() {
        let mut scene = builtin("ball-lens").unwrap().scene;
        scene.camera.yaw_deg = 75.0;
        scene.camera.pitch_deg = 25.0;
        let (dims, spacing) = ([40, 32, 24], [1.0, 1.25, 1.5]);
        let stored = ViewSetup::new(&scene, dims, spacing, 48, 48).unwrap();
        for axes in [[2, 1, 0], [1, 2, 0], [2, 0, 1], [0, 2, 1]] {
            let mut laid = stored.clone();
            laid.memory_axes = axes;
            // The same coordinates, reordered, to the bit: rows picked by a permutation.
            for p in [Vec3::new(0.3, -2.0, 40.0), Vec3::new(-7.5, 3.25, 55.0)] {
                let a = stored.volume_from_view().transform_point3(p);
                let b = laid.volume_from_view().transform_point3(p);
                assert_eq!(b.to_array(), axes.map(|i| a[i]), "{axes:?}");
            }
            // Central differences along the textures' axes (the voxels' own along each) give the
            // view-space gradient the stored layout gives for the same field, up to the order in
            // which the three products of each component are summed: a few f32 roundings of
            // values below 1 (2^-24 each), far under the 1e-6 allowed.
            let g = Vec3::new(0.25, -0.5, 0.75);
            let from_stored = stored.gradient_to_view(spacing).transform_vector3(g);
            let laid_g = Vec3::from(axes.map(|i| g[i]));
            let from_laid = laid
                .gradient_to_view(laid.in_memory_order(spacing))
                .transform_vector3(laid_g);
            assert!(
                (from_stored - from_laid).length() < 1e-6,
                "{axes:?}: {from_stored} against {from_laid}"
            );
        }
    }

    #[test]
    fn planes_cover_the_volume_front_to_back() {
        let scene = builtin("ball-lens").unwrap().scene;
        let v = ViewSetup::new(&scene, [64, 40, 64], [1.0; 3], 64, 64).unwrap();
        assert!(v.z_first > 0.0);
        // Sweep depth ≥ the box's smallest extent and ≤ its diagonal.
        let depth = v.step * (v.planes - 1) as f32;
        assert!(depth >= 40.0 && depth <= 2.0 * v.radius + v.step);
        // The volume centre is straight ahead.
        let centre = v.view_from_world.transform_point3(Vec3::ZERO);
        assert!(centre.x.abs() < 1e-3 && centre.y.abs() < 1e-3 && centre.z > 0.0);
        let tex = v.volume_from_view().transform_point3(centre);
        assert!((tex - Vec3::splat(0.5)).length() < 1e-4);
    }

    #[test]
    fn voxel_caps_coarsen_the_light_grid_only_where_pixels_are_smaller_than_voxels() {
        let mut scene = builtin("ball-lens").unwrap().scene;
        for projection in [Projection::Orthographic, Projection::Perspective] {
            scene.camera.projection = projection;
            // 32³ voxels over 256² pixels: a voxel is several pixels wide.
            let v = ViewSetup::new(&scene, [32; 3], [1.0; 3], 256, 256).unwrap();
            let stride = |cap| v.beam_grid(Vec3::Z, 1.0, false, cap).stride;
            let asked = stride(None);
            let kept = stride(Some(VoxelCap::UNREFRACTED));
            let refracted = stride(Some(VoxelCap::REFRACTED));
            let centre_pixel = v.plane0_pixels_per_centre_pixel();
            // Beams that keep their cells: one per voxel, several pixels wide.
            assert!(kept > 2.0 * asked, "{projection:?}: {kept} against {asked}");
            // Refracted: 1.5 per voxel would be wider than two pixels at the volume's centre
            // (a beam per texel asked for), which they are then (to 1e-4: the f32 rounding of
            // the stride's few operations).
            let expected = REFRACTED_MAX_COARSENING * centre_pixel;
            assert!(expected > asked && expected < kept / REFRACTED_BEAMS_PER_VOXEL);
            assert!(
                (refracted / expected - 1.0).abs() < 1e-4,
                "{projection:?}: {refracted} against {expected}"
            );
            // 32³ voxels over 16² pixels: a pixel is larger than a voxel and no cap binds.
            let v = ViewSetup::new(&scene, [32; 3], [1.0; 3], 16, 16).unwrap();
            let stride = |cap| v.beam_grid(Vec3::Z, 1.0, false, cap).stride;
            for cap in [VoxelCap::UNREFRACTED, VoxelCap::REFRACTED] {
                assert_eq!(stride(Some(cap)), stride(None), "{projection:?}");
            }
        }
    }

    #[test]
    fn camera_inside_the_volume_starts_the_sweep_at_the_near_plane() {
        // Without NEAR_PLANE the first plane would lie at or behind the camera, where the
        // perspective division breaks down.
        let mut scene = builtin("ball-lens").unwrap().scene;
        for distance in [0.5, 1e-3, 1e-6] {
            scene.camera.distance = distance;
            let v = ViewSetup::new(&scene, [32; 3], [1.0; 3], 16, 16).unwrap();
            assert!(
                v.z_first >= NEAR_PLANE * v.radius * 0.999,
                "distance {distance}: {}",
                v.z_first
            );
            assert!(v.planes <= MAX_PLANES);
        }
    }

    #[test]
    fn a_camera_straight_above_keeps_an_orthonormal_view() {
        let mut scene = builtin("ball-lens").unwrap().scene;
        for pitch in [89.0, 90.0, -90.0, 1000.0] {
            scene.camera.pitch_deg = pitch;
            let v = ViewSetup::new(&scene, [32; 3], [1.0; 3], 16, 16).unwrap();
            let r = Mat3::from_mat4(v.world_from_view);
            let err = (r * r.transpose() - Mat3::IDENTITY)
                .to_cols_array()
                .iter()
                .fold(0.0f32, |m, e| m.max(e.abs()));
            assert!(err < 1e-5, "pitch {pitch}: rotation off by {err}");
        }
    }

    #[test]
    fn too_many_planes_are_refused() {
        // 0.01 voxels on a 2048³ volume would be 355 000 planes: refused with advice instead
        // of a render that takes days.
        let mut scene = builtin("ball-lens").unwrap().scene;
        scene.quality.sample_distance = 0.01;
        let err = ViewSetup::new(&scene, [2048; 3], [1.0; 3], 16, 16).unwrap_err();
        assert!(err.contains("increase quality.sample_distance"), "{err}");
        scene.quality.sample_distance = 1.0;
        assert!(ViewSetup::new(&scene, [2048; 3], [1.0; 3], 16, 16).is_ok());
    }

    #[test]
    fn the_largest_light_angle_is_not_bent_by_the_direction_clamp() {
        // MIN_LIGHT_DIR_Z only acts on light that refraction turned further than any scene
        // may ask for: the unrefracted light at MAX_LIGHT_POLAR_DEG passes untouched.
        let l = Light {
            polar_deg: crate::scene::MAX_LIGHT_POLAR_DEG,
            ..Light::default()
        };
        assert!(light_direction(&l).z >= MIN_LIGHT_DIR_Z);
    }

    #[test]
    fn light_comes_from_the_top_at_azimuth_zero() {
        let mut l = Light {
            polar_deg: 30.0,
            azimuth_deg: 0.0,
            ..Light::default()
        };
        let d = light_direction(&l);
        assert!(d.y > 0.0 && d.z > 0.0 && d.x.abs() < 1e-6); // travels down the image and away
        l.polar_deg = 0.0;
        assert!((light_direction(&l) - Vec3::Z).length() < 1e-6);
    }
}
