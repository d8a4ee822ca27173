//! Scene data on the GPU: volume textures, pre-integrated tables, η table, environment map.

use std::cell::{Cell, RefCell};
use std::sync::Arc;

use half::f16;

use crate::gpu::{Buffer, Context, Format, GpuError, Image, ImageDesc, Recorder, Sampler, SamplerDesc};
use crate::scene::Gradient;
use crate::transfer::{preintegrate, Curve, TransferFunctions, TABLE_SIZE};
use crate::volume::Volume;

use super::environment::EnvMap;
use super::gradient::gradient_volume;
use super::occupancy::{Grown, Occupancy, RawRanges, ValueRanges};

type Levels = Vec<(u64, [u32; 3])>;

/// What one staging buffer holds: (index into [`SceneTextures::images`], (staging offset,
/// extent) per mip level).
type StagedImages = Vec<(usize, Levels)>;

/// Everything sampled by the passes, uploaded once per render.
pub struct SceneTextures {
    pub volume: Image,
    /// η and ∇η per voxel (`gradient.rs`); 1×1×1 when nothing refracts.
    pub gradient: Image,
    /// The value's gradient per voxel, for the view's layers (`layers.rs`).
    pub orientation: Image,
    /// The volume, gradient and orientation volumes at half resolution (`coarse.rs`), where
    /// asked for and each is more than a placeholder texel.
    pub half: [Option<Image>; 3],
    pub particle_table: Image,
    pub medium_table: Image,
    pub env: Image,
    pub env_levels: u32,
    pub linear_clamp: Sampler,
    pub volume_sampler: Sampler,
    pub env_sampler: Sampler,
    /// Which 8³ bricks absorb or show, or with refraction change η (`bricks.rs`), one u32
    /// each.
    pub bricks: Buffer,
    pub brick_dims: [u32; 3],
    /// Where the light can change, on the CPU (`occupancy.rs`): the cells where particles
    /// absorb or show, and with refraction those where η changes.
    pub occupancy: Vec<Occupancy>,
    /// The same for renders that sample the half-resolution level, where it was made: its
    /// texels reach a few voxels further than the volume's (`occupancy::half_level_reach`).
    pub half_bricks: Option<(Buffer, Vec<Occupancy>)>,
    /// The tables' texels for the sample distances used last (`replace_tables`).
    kept_tables: Vec<TableTexels>,
    /// What the transfer functions do not change, for [`SceneTextures::replace_transfer`].
    untouched: Untouched,
    /// The extremes of the volume's own values per brick and cell, where the upload made them
    /// (the viewer's), for the next change of the data window to map.
    raw: RawSet,
}

/// The bricks' and cells' extremes of a volume's own values ([`RawRanges`]) at the levels
/// made: the textures of the next data window of the same volume, laid out the same way, map
/// them through it instead of reading its samples again.
#[derive(Clone, Default)]
pub struct RawSet {
    full: Option<Arc<[RawRanges; 2]>>,
    half: Option<Arc<[RawRanges; 2]>>,
}

impl RawSet {
    /// With the levels asked for (`full`, `half`) made from `volume` where they are not yet.
    fn filled(mut self, volume: &Volume, full: bool, half: bool) -> RawSet {
        let grids = |f: fn(&[f32], [usize; 3], usize) -> RawRanges| {
            let (bricks, cells) = rayon::join(
                || f(&volume.data, volume.dims, super::bricks::BRICK),
                || f(&volume.data, volume.dims, super::occupancy::CELL),
            );
            Arc::new([bricks, cells])
        };
        if full && self.full.is_none() {
            self.full = Some(grids(RawRanges::new));
        }
        if half && self.half.is_none() {
            self.half = Some(grids(RawRanges::half_level));
        }
        self
    }
}

/// What a transfer-function edit leaves as it was (its η aside): the range of the volume's
/// samples in each brick and each occupied-cell grid cell, from which the bricks and the
/// occupied cells are found again, and with refraction the bricks and cells where η changes.
struct Untouched {
    brick_ranges: ValueRanges,
    cell_ranges: ValueRanges,
    refracting: Option<(Vec<u32>, Occupancy)>,
    /// The same as sampled from the half-resolution level, where it was made.
    half: Option<Box<Untouched>>,
    /// The half level's values (under the textures' data window), for an η edit that makes
    /// the gradient volume's half level alone: it need not normalise the volume again (on the
    /// CT head an eighth of its samples, 1.8 MB, against 28–42 ms).
    values: Option<Vec<u16>>,
}

impl Untouched {
    /// The bricks and the grids of occupied cells under `tf`: where its particles absorb or
    /// show, and for a render that refracts (`refraction`) where η changes.
    fn occupancy(&self, tf: &TransferFunctions, refraction: bool) -> (super::bricks::Bricks, Vec<Occupancy>) {
        let mut bricks = super::bricks::visible_bricks(&self.brick_ranges, tf);
        let mut cells = vec![self.cell_ranges.visible(tf)];
        if let Some((bends, refracting_cells)) = self.refracting.as_ref().filter(|_| refraction) {
            for (flag, bent) in bricks.flags.iter_mut().zip(bends) {
                *flag |= bent;
            }
            cells.push(refracting_cells.clone());
        }
        (bricks, cells)
    }

    /// [`Untouched::occupancy`] as sampled from the half-resolution level, where it was
    /// made, with the bricks' buffer.
    fn half_occupancy(
        &self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        refraction: bool,
    ) -> Result<Option<(Buffer, Vec<Occupancy>)>, GpuError> {
        let Some(half) = &self.half else {
            return Ok(None);
        };
        let (bricks, cells) = half.occupancy(tf, refraction);
        let buffer = Buffer::new_storage_from(ctx, "bricks at half resolution", bytemuck::cast_slice(&bricks.flags))?;
        Ok(Some((buffer, cells)))
    }
}

/// The contents of freshly created [`SceneTextures`], staged for [`SceneTextures::record_upload`].
pub struct PendingUpload {
    /// Each staging buffer with what it holds.
    parts: Vec<(Arc<Buffer>, StagedImages)>,
    /// Bytes staged (a staging buffer written again may be larger).
    bytes: u64,
}

/// Texels to stage, owned: a volume's are written once, straight into the mapped staging
/// buffer (on the CT head the volume, gradient and orientation volumes are about 130 MB, and a
/// copy through a staging `Vec` on the way cost as much again in copies and page faults).
trait Blob {
    fn bytes(&self) -> &[u8];
}

impl<T: bytemuck::Pod> Blob for Vec<T> {
    fn bytes(&self) -> &[u8] {
        bytemuck::cast_slice(self)
    }
}

/// Collects byte blobs for one staging buffer, at offsets aligned to 16 bytes.
#[derive(Default)]
struct Staging {
    blobs: Vec<(u64, Box<dyn Blob>)>,
    len: u64,
}

impl Staging {
    /// A new buffer with the staged blobs, and their bytes.
    fn into_buffer(self, ctx: &Arc<Context>) -> Result<(Arc<Buffer>, u64), GpuError> {
        self.into_kept(ctx, None)
    }

    /// The staged blobs written into `kept` where it is large enough and nothing else holds it
    /// (its copies have executed), else into a new buffer. A buffer written again needs no new
    /// pages: on the CT head a new one took 115 ms of page faults for its 139 MB.
    fn into_kept(self, ctx: &Arc<Context>, kept: Option<Arc<Buffer>>) -> Result<(Arc<Buffer>, u64), GpuError> {
        // A kept buffer that cannot serve goes before a new one is allocated.
        let usable = kept.and_then(|mut b| (b.size >= self.len && Arc::get_mut(&mut b).is_some()).then_some(b));
        let mut buffer = match usable {
            Some(b) => b,
            None => Arc::new(Buffer::new_upload(
                ctx,
                "scene staging",
                self.len,
                ash::vk::BufferUsageFlags::TRANSFER_SRC,
            )?),
        };
        let target = Arc::get_mut(&mut buffer).ok_or_else(missing)?;
        for (offset, blob) in &self.blobs {
            target.write_at(*offset, blob.bytes())?;
        }
        Ok((buffer, self.len))
    }

    /// Stages `blob` as it is; its offset.
    fn push_owned(&mut self, blob: Box<dyn Blob>) -> u64 {
        let offset = self.len.next_multiple_of(16);
        self.len = offset + blob.bytes().len() as u64;
        self.blobs.push((offset, blob));
        offset
    }

    /// Stages a copy of `data`; its offset.
    fn push(&mut self, data: &[u8]) -> u64 {
        self.push_owned(Box::new(data.to_vec()))
    }
}

/// The pre-integrated particle and medium tables for one sample distance, as the 16-bit
/// texels their images hold.
struct TableTexels {
    sample_distance: f32,
    particle: Vec<u8>,
    medium: Vec<u8>,
}

impl TableTexels {
    fn new(tf: &TransferFunctions, sample_distance: f32) -> TableTexels {
        let tables = preintegrate(tf, sample_distance);
        let texels = |data: &[[f32; 4]]| halves(data.iter().flatten().copied());
        TableTexels {
            sample_distance,
            particle: texels(&tables.particle),
            medium: texels(&tables.medium),
        }
    }
}

/// Table texels kept per sample distance: the viewer's levels use three, and pre-integrating
/// takes tens of ms at each change of level.
const KEPT_TABLES: usize = 4;

/// The particle and medium table images for `texels`, created and staged: (image, staging
/// offset) each, in that order.
fn tables(ctx: &Arc<Context>, texels: &TableTexels, staging: &mut Staging) -> Result<[(Image, u64); 2], GpuError> {
    let n = TABLE_SIZE as u32;
    let mut table = |label: &str, data: &[u8]| -> Result<(Image, u64), GpuError> {
        let img = Image::new(
            ctx,
            ImageDesc::sampled(label, Format::R16G16B16A16_SFLOAT, [n, n, 1], false, 1),
        )?;
        Ok((img, staging.push(data)))
    };
    Ok([
        table("particle table", &texels.particle)?,
        table("medium table", &texels.medium)?,
    ])
}

/// The environment map's image, its mip levels staged in `staging`: one black texel where
/// the background is a plain colour, which reads no map.
fn env_image(ctx: &Arc<Context>, env: Option<&EnvMap>, staging: &mut Staging) -> Result<(Image, Levels), GpuError> {
    let fallback;
    let env_levels: &[(u32, u32, Vec<[f32; 4]>)] = match env {
        Some(e) => &e.levels,
        None => {
            fallback = vec![(1u32, 1u32, vec![[0.0f32; 4]])];
            &fallback
        }
    };
    let (w0, h0) = (env_levels[0].0, env_levels[0].1);
    let image = Image::new(
        ctx,
        ImageDesc::sampled(
            "environment",
            Format::R16G16B16A16_SFLOAT,
            [w0, h0, 1],
            false,
            env_levels.len() as u32,
        ),
    )?;
    let levels = env_levels
        .iter()
        .map(|(w, h, px)| {
            (
                staging.push_owned(Box::new(halves(px.iter().flatten().copied()))),
                [*w, *h, 1],
            )
        })
        .collect();
    Ok((image, levels))
}

/// 16-bit floats for the tables and the environment map, saturated at the largest finite
/// half (65504): a brighter pixel of an HDR environment image would otherwise become
/// infinite on the GPU.
fn halves(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values
        .flat_map(|v| f16::from_f32(v.min(f16::MAX.to_f32())).to_le_bytes())
        .collect()
}

/// The images being created and the contents staged for them, in the order
/// [`SceneTextures::images`] indexes them.
#[derive(Default)]
struct Staged {
    staging: Staging,
    /// (index into `images`, (staging offset, extent) per mip level)
    uploads: Vec<(usize, Levels)>,
    images: Vec<Image>,
    /// Images of textures made before, taken where one is what an image to create would be.
    pool: Vec<Image>,
}

impl Staged {
    /// An image of `desc`: one of the pool's where one has the same description (label,
    /// format, extent, levels and usage; written again, its memory needs no new pages: on the
    /// CT head new volume images took about as long in page faults as their staging buffer),
    /// else a new one, after the pool's image of that label (the same role) is freed.
    fn image(&mut self, ctx: &Arc<Context>, desc: ImageDesc) -> Result<Image, GpuError> {
        if let Some(i) = self.pool.iter().position(|i| i.desc == desc) {
            return Ok(self.pool.swap_remove(i));
        }
        self.pool.retain(|i| i.desc.label != desc.label);
        Image::new(ctx, desc)
    }

    /// Creates a sampled 3D image of `extent` texels in `format` and stages `texels` for it;
    /// with `half` (texels and extent), a second image of its half-resolution level after it.
    /// Whether it made the second. An image of its own rather than a mip level read through a
    /// sampler clamped to it: llvmpipe compiles a variant of each shader per sampler state, and
    /// with two the viewer's preview (the first level at full resolution after the coarse
    /// ones) compiled them all again (2.1 s instead of 0.5 s on the ball-lens scene).
    fn volume<T: super::coarse::Channels + bytemuck::Pod>(
        &mut self,
        ctx: &Arc<Context>,
        label: &str,
        format: Format,
        extent: [u32; 3],
        texels: Vec<T>,
        half: Option<(Vec<T>, [u32; 3])>,
    ) -> Result<bool, GpuError> {
        let image = self.image(ctx, ImageDesc::sampled(label, format, extent, true, 1))?;
        self.uploads.push((
            self.images.len(),
            vec![(self.staging.push_owned(Box::new(texels)), extent)],
        ));
        self.images.push(image);
        let Some((half, half_extent)) = half else {
            return Ok(false);
        };
        let image = self.image(
            ctx,
            ImageDesc::sampled(&format!("{label} at half resolution"), format, half_extent, true, 1),
        )?;
        self.uploads.push((
            self.images.len(),
            vec![(self.staging.push_owned(Box::new(half)), half_extent)],
        ));
        self.images.push(image);
        Ok(true)
    }
}

/// With `coarse`, the half-resolution level (`coarse.rs`) of `texels` of a `dims` volume; none
/// for a placeholder texel, which has no finer level to filter.
fn half_of<T: super::coarse::Channels>(texels: &[T], dims: [usize; 3], coarse: bool) -> Option<Vec<T>> {
    has_half(dims, coarse).then(|| super::coarse::half_level(texels, dims))
}

/// Whether a `dims` volume gets a half-resolution level where `coarse` asks for one: not a
/// placeholder texel, which has no finer level to filter.
fn has_half(dims: [usize; 3], coarse: bool) -> bool {
    coarse && dims.iter().product::<usize>() > 1
}

/// How many of a `dims` volume's voxels a texel of its half-resolution level spans along each
/// axis (`n / ⌊n/2⌋`: 2, or a little more along an odd side).
fn half_texel_voxels(dims: [usize; 3]) -> [f32; 3] {
    let half = super::coarse::half_dims(dims);
    [0, 1, 2].map(|a| dims[a] as f32 / half[a] as f32)
}

/// The orientation volume's half level (`layers::orientation_volume`) from `samples_half`, the
/// half level of a `dims` volume's samples `spacing` apart: over the same `reach`, its
/// differences scaled to the volume's voxels.
fn half_orientation(samples_half: &[u16], dims: [usize; 3], spacing: [f32; 3], reach: f32) -> Vec<[i16; 4]> {
    let voxels = half_texel_voxels(dims);
    let half_spacing = [0, 1, 2].map(|a| spacing[a] * voxels[a]);
    let half_dims = super::coarse::half_dims(dims);
    super::layers::orientation_volume_per(samples_half, half_dims, half_spacing, reach, voxels)
}

/// The resolution levels of the volumes that textures hold, or that a render asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Resolutions {
    /// The volumes at full resolution (`quality.volume_level` 0).
    pub full: bool,
    /// Their half-resolution level (`coarse.rs`; `quality.volume_level` 1).
    pub half: bool,
}

impl Resolutions {
    /// Whether textures with these levels serve a render that asks for `other`'s.
    fn serve(self, other: Resolutions) -> bool {
        (self.full || !other.full) && (self.half || !other.half)
    }

    /// Whether a `dims` volume is made at full resolution: where asked for, and where it has
    /// no half level to stand in (a placeholder texel).
    fn makes_full(self, dims: [usize; 3]) -> bool {
        self.full || !has_half(dims, self.half)
    }
}

/// Where the gradient volume's η comes from: a separate η volume with its value range (else
/// the volume itself), and the difference scheme.
pub type EtaSource<'a> = (Option<(&'a Volume, [f32; 2])>, Gradient);

/// The gradient volume (`gradient.rs`) with its half-resolution level where asked for, and
/// where each level bends light: per brick and per occupied cell.
struct Refracting {
    extent: [u32; 3],
    texels: Vec<[f16; 4]>,
    /// The half level's texels and extent.
    half: Option<(Vec<[f16; 4]>, [u32; 3])>,
    /// The bricks where η changes (one word each) and the cells.
    bending: (Vec<u32>, Occupancy),
    half_bending: Option<(Vec<u32>, Occupancy)>,
}

impl Refracting {
    /// From `source`'s η volume, else from `samples`, the volume's (of `dims` voxels, in
    /// `bricks` bricks, with `samples_half` its half-resolution level where made), under
    /// `eta`, at the `levels` asked for. The half level is the gradient of η over the half
    /// level's values, not the half level of the gradient: the η the half level's values
    /// classify to, and made without the full level.
    #[allow(clippy::too_many_arguments)]
    fn new(
        samples: &[u16],
        samples_half: Option<&[u16]>,
        dims: [usize; 3],
        bricks: [usize; 3],
        source: EtaSource<'_>,
        eta: &Curve,
        levels: Resolutions,
    ) -> Self {
        let (eta_source, scheme) = source;
        let own;
        let (g_dims, values) = match eta_source {
            Some((ev, w)) => {
                own = ev.normalized_u16(w);
                (ev.dims, &own[..])
            }
            None => (dims, samples),
        };
        let half_dims = super::coarse::half_dims(g_dims);
        let half = has_half(g_dims, levels.half).then(|| {
            let own_half;
            let values_half = match (eta_source, samples_half) {
                (None, Some(h)) => h,
                _ => {
                    own_half = super::coarse::half_level(values, g_dims);
                    &own_half[..]
                }
            };
            super::gradient::gradient_volume_per(values_half, half_dims, eta, scheme, half_texel_voxels(g_dims))
        });
        let full = levels.makes_full(g_dims);
        let (g_extent, texels) = if full {
            (g_dims, gradient_volume(values, g_dims, eta, scheme))
        } else {
            ([1, 1, 1], vec![[f16::ZERO; 4]])
        };
        // Where η changes, as read from `texels` of `g_dims` voxels.
        let bending = |texels: &[[f16; 4]], g_dims: [usize; 3]| {
            let mut bends = super::bricks::Bricks {
                flags: vec![0; bricks.iter().product()],
                dims: bricks.map(|n| n as u32),
            };
            let map = super::gradient::bend_map(texels);
            super::bricks::add_refracting(&mut bends, dims, &map, g_dims);
            (bends.flags, Occupancy::refracting(&map, g_dims))
        };
        let half_bending = half.as_ref().map(|h| bending(h, half_dims));
        let half = half.map(|h| (h, half_dims.map(|n| n as u32)));
        // Without the full level, no render reads its flags: those of the half level stand in.
        let bending = match (&half_bending, full) {
            (Some(h), false) => h.clone(),
            _ => bending(&texels, g_extent),
        };
        Refracting {
            extent: g_extent.map(|n| n as u32),
            bending,
            half_bending,
            half,
            texels,
        }
    }
}

impl PendingUpload {
    /// `staging`: the buffer and the bytes staged in it.
    fn new(staging: (Arc<Buffer>, u64), uploads: StagedImages) -> Self {
        let (buffer, bytes) = staging;
        PendingUpload {
            parts: vec![(buffer, uploads)],
            bytes,
        }
    }

    /// The staging buffer of its first part.
    fn staging(&self) -> Option<Arc<Buffer>> {
        self.parts.first().map(|(b, _)| b.clone())
    }

    /// Nothing to copy in.
    fn none() -> Self {
        PendingUpload {
            parts: Vec::new(),
            bytes: 0,
        }
    }

    /// Bytes staged for the copy.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// This upload and `other` (of other images) in one.
    pub fn and(mut self, other: PendingUpload) -> PendingUpload {
        self.parts.extend(other.parts);
        self.bytes += other.bytes;
        self
    }
}

impl SceneTextures {
    /// Creates the textures and stages their contents; [`SceneTextures::record_upload`]
    /// copies them in. `orientation`: make the orientation volume. `refraction`: the η source
    /// (the η volume with its value range, or the volume itself) for the gradient volume.
    /// `levels`: the volumes' resolution levels to make (`quality.volume_level`); where the
    /// full level is not asked for, its images are placeholder texels, which no render at the
    /// half level reads.
    /// `kept_staging`: a staging buffer kept from an earlier upload, used again where it is large
    /// enough ([`PendingUpload::staging`] gives this one's); `reuse`: volume images of
    /// textures made before (of the same volume), each taken where it is what a new one would
    /// be, the others freed; `raw`: the extremes of the volume's values held by textures made
    /// before of the same volume laid out the same way (another data window), or none yet for
    /// a render that expects such changes: the value ranges are mapped from them (made where
    /// they lack them) and kept. Without, the ranges are made from the samples.
    #[allow(clippy::too_many_arguments)]
    pub fn upload(
        ctx: &Arc<Context>,
        volume: &Volume,
        window: [f32; 2],
        orientation: bool,
        refraction: Option<EtaSource<'_>>,
        tf: &TransferFunctions,
        sample_distance: f32,
        env: Option<&EnvMap>,
        levels: Resolutions,
        kept_staging: Option<Arc<Buffer>>,
        reuse: Vec<Image>,
        raw: Option<RawSet>,
    ) -> Result<(Self, PendingUpload), GpuError> {
        let mut staged = Staged {
            pool: reuse,
            ..Staged::default()
        };
        let vol_dims = volume.dims;
        let vol_extent = vol_dims.map(|n| n as u32);
        let samples = volume.normalized_u16(window);
        // The half level's values first: the gradient and orientation volumes' half levels are
        // made from them, not from their own full levels, which a render that reads only the
        // half level (the viewer's coarse levels) then need not wait for.
        let samples_half = half_of(&samples, vol_dims, levels.half);
        let full = levels.makes_full(vol_dims);
        let half_dims = super::coarse::half_dims(vol_dims);
        let half_extent = half_dims.map(|n| n as u32);
        let brick_cells = super::occupancy::cells_of(vol_dims, super::bricks::BRICK);
        // The value ranges, the gradient volume and the orientation volume (each with its
        // half level) are made side by side: each is parallel within, but not everywhere
        // (allocating, a last slice, the reductions' later axes), and one fills the other's
        // gaps.
        let ranges = || {
            // Another data window: the extremes of the volume's values mapped through it.
            let raw = raw.map(|r| r.filled(volume, full, samples_half.is_some()));
            // A level's bricks' and cells' ranges: mapped from its extremes where there are,
            // else made from the samples (`from_samples`).
            let level = |extremes: Option<&Arc<[RawRanges; 2]>>,
                         from_samples: fn(&[u16], [usize; 3], usize) -> ValueRanges| {
                match extremes {
                    Some(g) => (g[0].windowed(window), g[1].windowed(window)),
                    None => (
                        from_samples(&samples, vol_dims, super::bricks::BRICK),
                        from_samples(&samples, vol_dims, super::occupancy::CELL),
                    ),
                }
            };
            let half_ranges = samples_half.as_ref().map(|_| {
                let (brick_ranges, cell_ranges) =
                    level(raw.as_ref().and_then(|r| r.half.as_ref()), ValueRanges::half_level);
                Box::new(Untouched {
                    brick_ranges,
                    cell_ranges,
                    refracting: None,
                    half: None,
                    values: samples_half.clone(),
                })
            });
            // Without the full level, no render reads its ranges: the half level's (on the
            // same grids) stand in.
            let (brick_ranges, cell_ranges) = match (&half_ranges, full) {
                (Some(h), false) => (h.brick_ranges.clone(), h.cell_ranges.clone()),
                _ => level(raw.as_ref().and_then(|r| r.full.as_ref()), ValueRanges::new),
            };
            (brick_ranges, cell_ranges, half_ranges, raw.unwrap_or_default())
        };
        let gradient = || {
            refraction.map(|source| {
                let half = samples_half.as_deref();
                Refracting::new(&samples, half, vol_dims, brick_cells, source, &tf.eta, levels)
            })
        };
        // The layers' reach: the index interfaces' half-width, the same in world units along
        // every axis, so that a profile that curves within it tilts the normal no more than
        // it shortens it. Without room on the device, one texel: the view samples instead.
        let layers = || {
            if !orientation {
                return ([1, 1, 1], vec![[0i16; 4]], None);
            }
            let reach = super::state::interface_half_width(volume.spacing);
            let half = samples_half
                .as_ref()
                .map(|h| (half_orientation(h, vol_dims, volume.spacing, reach), half_extent));
            if full {
                let texels = super::layers::orientation_volume(&samples, vol_dims, volume.spacing, reach);
                (vol_extent, texels, half)
            } else {
                ([1, 1, 1], vec![[0i16; 4]], half)
            }
        };
        let table_texels = || TableTexels::new(tf, sample_distance);
        let ((ranges, gradient), ((orientation_extent, orientation_texels, orientation_half), table_texels)) =
            rayon::join(|| rayon::join(ranges, gradient), || rayon::join(layers, table_texels));
        let (brick_ranges, cell_ranges, mut half_ranges, raw) = ranges;
        let mut refracting = None;
        let mut gradient_half = None;
        let (gradient_extent, gradient_texels) = match gradient {
            Some(g) => {
                refracting = Some(g.bending);
                if let (Some(h), Some(bending)) = (half_ranges.as_mut(), g.half_bending) {
                    h.refracting = Some(bending);
                }
                gradient_half = g.half;
                (g.extent, g.texels)
            }
            None => ([1, 1, 1], vec![[half::f16::ZERO; 4]]),
        };

        // Each volume's texels go to the staging buffer as they are, once all are made.
        let mut made_half = [false; 3];
        let samples_half = samples_half.map(|h| (h, half_extent));
        made_half[0] = if full {
            staged.volume(ctx, "volume", Format::R16_UNORM, vol_extent, samples, samples_half)?
        } else {
            drop(samples);
            staged.volume(ctx, "volume", Format::R16_UNORM, [1, 1, 1], vec![0u16], samples_half)?
        };
        made_half[1] = staged.volume(
            ctx,
            "gradient volume",
            Format::R16G16B16A16_SFLOAT,
            gradient_extent,
            gradient_texels,
            gradient_half,
        )?;
        made_half[2] = staged.volume(
            ctx,
            "orientation volume",
            Format::R16G16B16A16_SNORM,
            orientation_extent,
            orientation_texels,
            orientation_half,
        )?;

        for (img, offset) in tables(ctx, &table_texels, &mut staged.staging)? {
            staged
                .uploads
                .push((staged.images.len(), vec![(offset, img.desc.extent)]));
            staged.images.push(img);
        }

        let (img, levels) = env_image(ctx, env, &mut staged.staging)?;
        let env_levels = levels.len() as u32;
        staged.uploads.push((staged.images.len(), levels));
        staged.images.push(img);

        let Staged {
            staging,
            uploads,
            images,
            pool,
        } = staged;
        // The images made before that were not taken are freed.
        drop(pool);
        let buffer = staging.into_kept(ctx, kept_staging)?;

        use ash::vk::SamplerAddressMode as A;
        let linear_clamp = Sampler::new(
            ctx,
            &SamplerDesc {
                label: "tables (linear, clamp to edge)".into(),
                linear: true,
                mipmaps: false,
                address: [A::CLAMP_TO_EDGE; 3],
            },
        )?;
        let volume_sampler = Sampler::new(
            ctx,
            &SamplerDesc {
                label: "volume (linear, zero outside)".into(),
                linear: true,
                mipmaps: false,
                address: [A::CLAMP_TO_BORDER; 3],
            },
        )?;
        let env_sampler = Sampler::new(
            ctx,
            &SamplerDesc {
                label: "environment (trilinear, wrap longitude)".into(),
                linear: true,
                mipmaps: true,
                address: [A::REPEAT, A::CLAMP_TO_EDGE, A::CLAMP_TO_EDGE],
            },
        )?;

        let mut it = images.into_iter();
        let mut half = [None, None, None];
        let mut volumes = Vec::new();
        for (made, half) in made_half.iter().zip(&mut half) {
            volumes.push(it.next().ok_or_else(missing)?);
            if *made {
                *half = Some(it.next().ok_or_else(missing)?);
            }
        }
        let [volume, gradient, orientation]: [Image; 3] = volumes.try_into().map_err(|_| missing())?;
        let particle_table = it.next().ok_or_else(missing)?;
        let medium_table = it.next().ok_or_else(missing)?;
        let env = it.next().ok_or_else(missing)?;
        let untouched = Untouched {
            brick_ranges,
            cell_ranges,
            refracting,
            half: half_ranges,
            values: None,
        };
        let refracts = untouched.refracting.is_some();
        let (occupancy, cells) = untouched.occupancy(tf, refracts);
        let bricks = Buffer::new_storage_from(ctx, "bricks", bytemuck::cast_slice(&occupancy.flags))?;
        let half_bricks = untouched.half_occupancy(ctx, tf, refracts)?;
        let textures = SceneTextures {
            volume,
            gradient,
            orientation,
            half,
            particle_table,
            medium_table,
            env,
            env_levels,
            linear_clamp,
            volume_sampler,
            env_sampler,
            bricks,
            brick_dims: occupancy.dims,
            occupancy: cells,
            half_bricks,
            kept_tables: vec![table_texels],
            untouched,
            raw,
        };
        Ok((textures, PendingUpload::new(buffer, uploads)))
    }

    /// Replaces the pre-integrated tables with those for another sample distance (the
    /// viewer's levels step the planes differently) and stages their contents; the volume, the
    /// gradient volume and the environment stay.
    fn replace_tables(
        &mut self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        sample_distance: f32,
    ) -> Result<PendingUpload, GpuError> {
        let kept = self
            .kept_tables
            .iter()
            .position(|t| t.sample_distance.to_bits() == sample_distance.to_bits());
        let texels = match kept {
            Some(i) => self.kept_tables.remove(i),
            None => TableTexels::new(tf, sample_distance),
        };
        self.put_tables(ctx, texels)
    }

    /// Replaces the pre-integrated tables with `texels`' and stages them.
    fn put_tables(&mut self, ctx: &Arc<Context>, texels: TableTexels) -> Result<PendingUpload, GpuError> {
        let mut staging = Staging::default();
        let [(particle, p), (medium, m)] = tables(ctx, &texels, &mut staging)?;
        // The most recently used last; the oldest goes.
        self.kept_tables.push(texels);
        if self.kept_tables.len() > KEPT_TABLES {
            self.kept_tables.remove(0);
        }
        self.particle_table = particle;
        self.medium_table = medium;
        // Their places in the order `record_upload` indexes.
        let images = self.images();
        let at = |table: &Image| images.iter().position(|i| std::ptr::eq(*i, table));
        let uploads = [(&self.particle_table, p), (&self.medium_table, m)]
            .into_iter()
            .filter_map(|(table, offset)| Some((at(table)?, vec![(offset, table.desc.extent)])))
            .collect();
        Ok(PendingUpload::new(staging.into_buffer(ctx)?, uploads))
    }

    /// Makes the bricks and the occupied cells anew for `tf` and for a render that refracts or
    /// not (`refraction`: where η changes counts): they live in host-visible memory, nothing
    /// is copied in. A render without refraction reads no gradient volume, so one made
    /// before (the viewer's switch) stays for when refraction is switched on again.
    fn replace_occupancy(
        &mut self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        refraction: bool,
    ) -> Result<(), GpuError> {
        let (bricks, cells) = self.untouched.occupancy(tf, refraction);
        self.bricks = Buffer::new_storage_from(ctx, "bricks", bytemuck::cast_slice(&bricks.flags))?;
        self.brick_dims = bricks.dims;
        self.occupancy = cells;
        self.half_bricks = self.untouched.half_occupancy(ctx, tf, refraction)?;
        Ok(())
    }

    /// Brings the textures up to date with other transfer functions whose η is the same (the
    /// gradient volume stays), at `sample_distance`, and stages what changed: the
    /// pre-integrated tables, the bricks and the occupied cells (`refraction`: of a render
    /// that refracts). The volume, the orientation volume, the gradient volume and the
    /// environment stay: on the CT head they are about 130 MB to make and copy, which every
    /// edit in the viewer's editor paid before.
    fn replace_transfer(
        &mut self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        sample_distance: f32,
        refraction: bool,
    ) -> Result<PendingUpload, GpuError> {
        self.replace_transfer_with(ctx, tf, TableTexels::new(tf, sample_distance), refraction)
    }

    /// [`SceneTextures::replace_transfer`] with the tables' texels made already.
    fn replace_transfer_with(
        &mut self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        texels: TableTexels,
        refraction: bool,
    ) -> Result<PendingUpload, GpuError> {
        self.replace_occupancy(ctx, tf, refraction)?;
        // Tables of the old transfer functions are of no use any more.
        self.kept_tables.clear();
        self.put_tables(ctx, texels)
    }

    /// Brings the textures up to date with transfer functions of another η: the gradient
    /// volume (and its half level where there is one) is made again from `refraction`'s
    /// source, else from `volume`'s samples under `window`, then [`SceneTextures::replace_transfer`]
    /// does the rest. The volume and orientation volumes and the environment stay: on the CT
    /// head they are about half of what a new scene makes and copies.
    #[allow(clippy::too_many_arguments)]
    fn replace_eta(
        &mut self,
        ctx: &Arc<Context>,
        volume: &Volume,
        window: [f32; 2],
        refraction: EtaSource<'_>,
        tf: &TransferFunctions,
        sample_distance: f32,
        levels: Resolutions,
        kept_staging: Option<Arc<Buffer>>,
    ) -> Result<PendingUpload, GpuError> {
        // Without the full level, the half level's values kept from the upload serve.
        let kept = match (&self.untouched.half, levels.full, refraction.0) {
            (Some(h), false, None) => h.values.as_deref(),
            _ => None,
        };
        let (samples, own_half) = match (refraction.0, kept) {
            (None, None) => {
                let samples = volume.normalized_u16(window);
                let half = half_of(&samples, volume.dims, levels.half);
                (samples, half)
            }
            _ => (Vec::new(), None),
        };
        let samples_half = kept.or(own_half.as_deref());
        // The tables beside the gradient volume (the edit changes both).
        let bricks = self.untouched.brick_ranges.cells();
        let (g, table_texels) = rayon::join(
            || Refracting::new(&samples, samples_half, volume.dims, bricks, refraction, &tf.eta, levels),
            || TableTexels::new(tf, sample_distance),
        );
        // The old gradient volume's images serve again where they are what new ones would be;
        // a placeholder texel holds the place until the new image is in it.
        let placeholder = Image::new(
            ctx,
            ImageDesc::sampled("gradient volume", Format::R16G16B16A16_SFLOAT, [1, 1, 1], true, 1),
        )?;
        let old = std::mem::replace(&mut self.gradient, placeholder);
        let mut staged = Staged {
            pool: [Some(old), self.half[1].take()].into_iter().flatten().collect(),
            ..Staged::default()
        };
        let made_half = staged.volume(
            ctx,
            "gradient volume",
            Format::R16G16B16A16_SFLOAT,
            g.extent,
            g.texels,
            g.half,
        )?;
        let Staged {
            staging,
            uploads,
            images,
            ..
        } = staged;
        let mut images = images.into_iter();
        self.gradient = images.next().ok_or_else(missing)?;
        self.half[1] = if made_half { images.next() } else { None };
        self.untouched.refracting = Some(g.bending);
        if let Some(h) = self.untouched.half.as_mut() {
            h.refracting = g.half_bending;
        }
        // The staged images' places among all the textures'.
        let placed = [Some(&self.gradient), self.half[1].as_ref()];
        let all = self.images();
        let uploads = uploads
            .into_iter()
            .map(|(index, levels)| {
                let image = placed.get(index).copied().flatten().ok_or_else(missing)?;
                let at = all.iter().position(|i| std::ptr::eq(*i, image)).ok_or_else(missing)?;
                Ok((at, levels))
            })
            .collect::<Result<_, GpuError>>()?;
        let gradient = PendingUpload::new(staging.into_kept(ctx, kept_staging)?, uploads);
        Ok(gradient.and(self.replace_transfer_with(ctx, tf, table_texels, true)?))
    }

    /// Replaces the environment map with `env`'s and stages it; the rest stays.
    fn replace_environment(&mut self, ctx: &Arc<Context>, env: Option<&EnvMap>) -> Result<PendingUpload, GpuError> {
        let mut staging = Staging::default();
        let (image, levels) = env_image(ctx, env, &mut staging)?;
        self.env_levels = levels.len() as u32;
        self.env = image;
        let index = self
            .images()
            .iter()
            .position(|i| std::ptr::eq(*i, &self.env))
            .ok_or_else(missing)?;
        Ok(PendingUpload::new(staging.into_buffer(ctx)?, vec![(index, levels)]))
    }

    /// Bytes of device memory the textures and the brick flags hold.
    pub fn bytes(&self) -> u64 {
        self.images().iter().map(|i| i.bytes()).sum::<u64>()
            + self.bricks.bytes()
            + self.half_bricks.as_ref().map_or(0, |(b, _)| b.bytes())
    }

    /// The images in the order [`PendingUpload`] indexes them (the order of creation).
    fn images(&self) -> Vec<&Image> {
        let [h0, h1, h2] = &self.half;
        [Some(&self.volume), h0.as_ref(), Some(&self.gradient), h1.as_ref()]
            .into_iter()
            .chain([Some(&self.orientation), h2.as_ref()])
            .chain([Some(&self.particle_table), Some(&self.medium_table), Some(&self.env)])
            .flatten()
            .collect()
    }

    /// The bricks' buffer and the occupied cells for renders that sample the volumes at half
    /// resolution (`coarse`, where the level was made) or at full resolution.
    pub fn occupancy_for(&self, coarse: bool) -> (&Buffer, &Vec<Occupancy>) {
        // `half_bricks` is made exactly where the volume's half level is.
        match (&self.half_bricks, coarse) {
            (Some((bricks, cells)), true) => (bricks, cells),
            _ => (&self.bricks, &self.occupancy),
        }
    }

    /// The volume, gradient and orientation volumes the passes sample: at half resolution
    /// with `coarse` where there is one.
    pub fn sampled(&self, coarse: bool) -> [&Image; 3] {
        let mut out = [&self.volume, &self.gradient, &self.orientation];
        if coarse {
            for (o, h) in out.iter_mut().zip(&self.half) {
                if let Some(h) = h {
                    *o = h;
                }
            }
        }
        out
    }

    /// Records the copy of the staged contents into the textures. The recorder keeps the
    /// staging memory until the copy has executed, then it goes. Only the images staged are
    /// touched: the others keep their contents.
    pub fn record_upload<'r>(&'r self, rec: &mut Recorder<'r>, pending: PendingUpload) {
        let images = self.images();
        let staged: Vec<&Image> = pending
            .parts
            .iter()
            .flat_map(|(_, uploads)| uploads)
            .filter_map(|(index, _)| images.get(*index).copied())
            .collect();
        rec.init_layout(&staged);
        for (staging, uploads) in &pending.parts {
            for (index, levels) in uploads {
                if let Some(image) = images.get(*index) {
                    rec.upload(staging, image, levels);
                }
            }
        }
        rec.transfer_to_compute();
    }
}

/// What the scene textures were made from. The volumes are compared by identity and kept
/// alive here, so a freed volume's address cannot be mistaken for a new one.
pub struct TexturesKey {
    volume: Arc<Volume>,
    /// What the gradient volume is made from, where there is one. Kept textures may hold one
    /// that a render without refraction does not read.
    gradient: Option<GradientSource>,
    /// The render refracts: it reads the gradient volume, and the bricks and occupied cells
    /// count where η changes.
    refraction: bool,
    /// The orientation volume exists.
    orientation: bool,
    window: [f32; 2],
    tf: TransferFunctions,
    sample_distance: f32,
    environment: EnvSource,
    /// The volumes' resolution levels the textures have (or a render asks for).
    levels: Resolutions,
    /// The volume's axes as the textures lay them out (`ViewSetup::memory_axes`).
    axes: [usize; 3],
}

impl TexturesKey {
    /// What `prepared` needs, with the volumes' resolution `levels`.
    pub fn new(
        prepared: &super::PreparedScene,
        features: &super::Features,
        levels: Resolutions,
        axes: [usize; 3],
    ) -> Self {
        let gradient = features.refraction.then(|| GradientSource {
            scheme: features.gradient,
            eta: prepared.tf.eta.clone(),
            eta_volume: prepared.eta_volume.clone().filter(|_| features.eta_volume),
        });
        TexturesKey {
            volume: prepared.volume.clone(),
            gradient,
            refraction: features.refraction,
            orientation: !features.sampled_layers,
            window: prepared.window(),
            tf: prepared.tf.clone(),
            sample_distance: prepared.scene.quality.sample_distance,
            environment: EnvSource::of(&prepared.scene.environment),
            levels,
            axes,
        }
    }

    /// The same with the textures laying the volume's axes out as `axes`.
    pub fn with_axes(self, axes: [usize; 3]) -> Self {
        TexturesKey { axes, ..self }
    }

    /// What the environment map is made from.
    pub fn environment(&self) -> &EnvSource {
        &self.environment
    }

    /// The volumes' resolution levels asked for.
    pub fn levels(&self) -> Resolutions {
        self.levels
    }

    fn same(&self, other: &TexturesKey) -> bool {
        self.same_but_step(other) && self.sample_distance == other.sample_distance
    }

    /// The same but for the sample distance, on which only the pre-integrated tables depend.
    fn same_but_step(&self, other: &TexturesKey) -> bool {
        self.same_but_transfer(other) && self.tf == other.tf && self.refraction == other.refraction
    }

    /// The same but for whether the render refracts, where the textures hold the gradient
    /// volume it reads: only the bricks and occupied cells depend on it.
    fn same_but_refraction(&self, other: &TexturesKey) -> bool {
        self.same_but_transfer(other) && self.tf == other.tf && self.sample_distance == other.sample_distance
    }

    /// The same but for the transfer functions other than the η a gradient volume read is
    /// made from, the sample distance and whether the render refracts: what
    /// [`SceneTextures::replace_transfer`] brings up to date. Textures with a resolution
    /// level serve a key that does not ask for it.
    fn same_but_transfer(&self, other: &TexturesKey) -> bool {
        self.axes == other.axes && self.same_but_transfer_and_layout(other)
    }

    /// [`TexturesKey::same_but_transfer`] whatever the layout of the volume's axes.
    fn same_but_transfer_and_layout(&self, other: &TexturesKey) -> bool {
        self.same_but_eta_and_layout(other) && (!other.refraction || self.gradient == other.gradient)
    }

    /// The same but for the transfer functions, η included, the sample distance and the
    /// gradient volume: what [`SceneTextures::replace_eta`] brings up to date.
    fn same_but_eta(&self, other: &TexturesKey) -> bool {
        self.axes == other.axes && self.same_but_eta_and_layout(other)
    }

    /// [`TexturesKey::same_but_eta`] whatever the layout of the volume's axes.
    fn same_but_eta_and_layout(&self, other: &TexturesKey) -> bool {
        Arc::ptr_eq(&self.volume, &other.volume)
            && self.orientation == other.orientation
            && self.window == other.window
            && self.levels.serve(other.levels)
    }
}

/// What a gradient volume is made from: how it is reconstructed, η, and the η volume where
/// the objects have one (compared by identity, as the volume is).
#[derive(Clone)]
struct GradientSource {
    scheme: Gradient,
    eta: Curve,
    eta_volume: Option<Arc<Volume>>,
}

impl PartialEq for GradientSource {
    fn eq(&self, other: &Self) -> bool {
        let same_volume = match (&self.eta_volume, &other.eta_volume) {
            (Some(a), Some(b)) => Arc::ptr_eq(a, b),
            (None, None) => true,
            _ => false,
        };
        self.scheme == other.scheme && self.eta == other.eta && same_volume
    }
}

/// What the environment map's texels are made from. Its intensity and a background colour are
/// parameters of the passes: changing them (the viewer's sliders) keeps the map, and changing
/// the map keeps the volumes ([`CachedTextures::replace_environment`]).
#[derive(Clone, Debug, PartialEq)]
pub enum EnvSource {
    Studio,
    Image(std::path::PathBuf),
    /// A plain colour, which reads no map.
    None,
}

impl EnvSource {
    fn of(environment: &crate::scene::Environment) -> Self {
        use crate::scene::Environment as E;
        match environment {
            E::Studio { .. } => EnvSource::Studio,
            E::Image { path, .. } => EnvSource::Image(path.clone()),
            E::Color { .. } => EnvSource::None,
        }
    }
}

/// The occupied cells last grown, with whether they are the half-resolution level's and the
/// growth in cells of each grid, and their words for the shaders once asked for: successive
/// frames of a drag mostly ask for the same growth, and at the interactive level's coarse
/// planes and beams growing took tens of ms. Made anew for every frame, the words took a CPU
/// driver's frames of the CT head about as long as a few of its planes.
#[derive(Default)]
pub struct GrowthCache {
    kept: RefCell<Option<KeptGrowth>>,
}

struct KeptGrowth {
    coarse: bool,
    growth: Vec<[usize; 3]>,
    grown: Arc<Vec<Grown>>,
    words: Option<Arc<Vec<u32>>>,
}

impl GrowthCache {
    /// `occupancy` (the grids of the level `coarse` says) grown by `margin`
    /// (`Occupancy::grown`), kept while the growth in cells stays the same.
    pub fn grown(&self, occupancy: &[Occupancy], margin: [f32; 3], coarse: bool) -> Arc<Vec<Grown>> {
        let growth: Vec<[usize; 3]> = occupancy.iter().map(|o| o.growth(margin)).collect();
        let mut kept = self.kept.borrow_mut();
        if let Some(k) = kept.as_ref() {
            if k.coarse == coarse && k.growth == growth {
                return k.grown.clone();
            }
        }
        let grown = Arc::new(occupancy.iter().map(|o| o.grown(margin)).collect::<Vec<_>>());
        *kept = Some(KeptGrowth {
            coarse,
            growth,
            grown: grown.clone(),
            words: None,
        });
        grown
    }

    /// The grids [`GrowthCache::grown`] gives as the shaders read them: the first's words with
    /// the others merged in (`Grown::words`), kept with the grids. None without grids.
    pub fn words(&self, occupancy: &[Occupancy], margin: [f32; 3], coarse: bool) -> Option<Arc<Vec<u32>>> {
        let grown = self.grown(occupancy, margin, coarse);
        let mut kept = self.kept.borrow_mut();
        let words = &mut kept.as_mut()?.words;
        if words.is_none() {
            let (first, others) = grown.split_first()?;
            *words = Some(Arc::new(first.words(others)));
        }
        words.clone()
    }

    /// Forgets what it kept (the occupied cells changed).
    pub fn clear(&self) {
        self.kept.replace(None);
    }
}

/// Scene textures kept by the renderer between renders.
pub struct CachedTextures {
    key: TexturesKey,
    pub textures: SceneTextures,
    /// The upload commands have executed; until then (a render cancelled or failed before
    /// its first submission) the textures hold nothing and must not be reused. A `Cell`, so
    /// it can be set while the render's descriptor sets borrow the textures.
    uploaded: Cell<bool>,
    /// The occupied cells last grown ([`CachedTextures::grown`]).
    grown: GrowthCache,
    /// The staging buffer of the volumes' last upload where the render asked to keep it
    /// (`RenderRequest::keep_staging`), written again by the next where it is large enough.
    staging: Option<Arc<Buffer>>,
}

impl CachedTextures {
    /// The textures made for `key`, keeping `upload`'s staging buffer for the next.
    pub fn new(key: TexturesKey, textures: SceneTextures, upload: &PendingUpload) -> Self {
        CachedTextures {
            staging: upload.staging(),
            key,
            textures,
            uploaded: Cell::new(false),
            grown: GrowthCache::default(),
        }
    }

    /// The layout of the kept textures where, laid out so, they would serve `key` but for
    /// their tables or transfer functions (`VolumeLayout::Kept`).
    pub fn serves_but_layout(&self, key: &TexturesKey) -> Option<[usize; 3]> {
        let axes = self.key.axes;
        (self.uploaded.get() && self.key.same_but_transfer_and_layout(key)).then_some(axes)
    }

    pub fn matches(&self, key: &TexturesKey) -> bool {
        self.uploaded.get() && self.key.same(key)
    }

    /// Whether the textures differ from `key`'s only in the pre-integrated tables (another
    /// sample distance): [`CachedTextures::replace_tables`] brings them up to date.
    pub fn matches_but_tables(&self, key: &TexturesKey) -> bool {
        self.uploaded.get() && self.key.same_but_step(key)
    }

    /// New tables for `key`'s sample distance (the rest is kept); until the returned upload
    /// has executed ([`CachedTextures::uploaded`]) nothing matches.
    pub fn replace_tables(
        &mut self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        key: TexturesKey,
    ) -> Result<PendingUpload, GpuError> {
        let sample_distance = key.sample_distance;
        self.replace(key, |t| t.replace_tables(ctx, tf, sample_distance))
    }

    /// Brings the textures up to `key` with `update`; nothing matches until its upload has
    /// executed.
    fn replace(
        &mut self,
        key: TexturesKey,
        update: impl FnOnce(&mut SceneTextures) -> Result<PendingUpload, GpuError>,
    ) -> Result<PendingUpload, GpuError> {
        self.uploaded.set(false);
        let pending = update(&mut self.textures)?;
        // The volume images stay, with whatever levels they have, and so do the environment
        // map ([`CachedTextures::replace_environment`]) and a gradient volume that a render
        // without refraction does not read.
        let gradient = if key.refraction {
            key.gradient.clone()
        } else {
            self.key.gradient.take()
        };
        self.key = TexturesKey {
            levels: self.key.levels,
            environment: self.key.environment.clone(),
            gradient,
            ..key
        };
        Ok(pending)
    }

    /// Whether the textures differ from `key`'s only in whether the render refracts, and hold
    /// the gradient volume it reads if it does: [`CachedTextures::replace_occupancy`] brings
    /// them up to date.
    pub fn matches_but_refraction(&self, key: &TexturesKey) -> bool {
        self.uploaded.get() && self.key.same_but_refraction(key)
    }

    /// New bricks and occupied cells for `key`'s render, which refracts or not (the images
    /// are kept, nothing is copied in); until the returned upload has executed nothing
    /// matches.
    pub fn replace_occupancy(
        &mut self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        key: TexturesKey,
    ) -> Result<PendingUpload, GpuError> {
        self.grown.clear();
        let refraction = key.refraction;
        self.replace(key, |t| {
            t.replace_occupancy(ctx, tf, refraction)?;
            Ok(PendingUpload::none())
        })
    }

    /// Whether the textures differ from `key`'s only in what a transfer-function edit that
    /// keeps η changes (or switching refraction where they hold the gradient volume):
    /// [`CachedTextures::replace_transfer`] brings them up to date.
    pub fn matches_but_transfer(&self, key: &TexturesKey) -> bool {
        self.uploaded.get() && self.key.same_but_transfer(key)
    }

    /// New tables, bricks and occupied cells for `key`'s transfer functions and sample
    /// distance (the volume images are kept); until the returned upload has executed nothing
    /// matches.
    pub fn replace_transfer(
        &mut self,
        ctx: &Arc<Context>,
        tf: &TransferFunctions,
        key: TexturesKey,
    ) -> Result<PendingUpload, GpuError> {
        self.grown.clear();
        let (sample_distance, refraction) = (key.sample_distance, key.refraction);
        self.replace(key, |t| t.replace_transfer(ctx, tf, sample_distance, refraction))
    }

    /// Whether the environment map is the one `key` asks for. The other `matches` leave the
    /// map out: [`CachedTextures::replace_environment`] brings it up to date on its own.
    pub fn matches_environment(&self, environment: &EnvSource) -> bool {
        self.key.environment == *environment
    }

    /// A new environment map, `env`, made from `environment`; the rest is kept. Until the
    /// returned upload has executed nothing matches.
    pub fn replace_environment(
        &mut self,
        ctx: &Arc<Context>,
        env: Option<&EnvMap>,
        environment: EnvSource,
    ) -> Result<PendingUpload, GpuError> {
        self.uploaded.set(false);
        let pending = self.textures.replace_environment(ctx, env)?;
        self.key.environment = environment;
        Ok(pending)
    }

    /// Whether the textures differ from `key`'s only in the transfer functions, η among them,
    /// and the sample distance: [`CachedTextures::replace_eta`] brings them up to date.
    pub fn matches_but_eta(&self, key: &TexturesKey) -> bool {
        self.uploaded.get() && self.key.same_but_eta(key)
    }

    /// A new gradient volume, tables, bricks and occupied cells for `key`'s transfer
    /// functions (`SceneTextures::replace_eta`; `volume` laid out as the textures lay it out);
    /// until the returned upload has executed nothing matches.
    pub fn replace_eta(
        &mut self,
        ctx: &Arc<Context>,
        volume: &Volume,
        refraction: EtaSource<'_>,
        tf: &TransferFunctions,
        key: TexturesKey,
    ) -> Result<PendingUpload, GpuError> {
        self.grown.clear();
        // The gradient volume at the levels `key` asks for: without the full level where it
        // does not (the viewer's coarse levels), which the textures then lack as a whole.
        let levels = Resolutions {
            full: key.levels.full,
            half: self.key.levels.half,
        };
        let (window, sample_distance) = (key.window, key.sample_distance);
        let kept = self.staging.take();
        let pending = self.replace(key, |t| {
            t.replace_eta(ctx, volume, window, refraction, tf, sample_distance, levels, kept)
        })?;
        self.key.levels = levels;
        self.staging = pending.staging();
        Ok(pending)
    }

    /// The staging buffer kept for the next upload of volumes, given up.
    pub fn take_staging(&mut self) -> Option<Arc<Buffer>> {
        self.staging.take()
    }

    /// Whether the textures were made from `key`'s volume, its axes laid out the same way.
    pub fn same_volume_and_layout(&self, key: &TexturesKey) -> bool {
        Arc::ptr_eq(&self.key.volume, &key.volume) && self.key.axes == key.axes
    }

    /// The volume images (the volume, gradient and orientation volumes and their half
    /// levels), for new textures to take where they are what a new image would be, and the
    /// extremes of the volume's values they hold.
    pub fn into_volume_images(self) -> (Vec<Image>, RawSet) {
        let t = self.textures;
        let images = [Some(t.volume), Some(t.gradient), Some(t.orientation)]
            .into_iter()
            .chain(t.half)
            .flatten()
            .collect();
        (images, t.raw)
    }

    /// The textures' occupied cells grown by `margin` (`GrowthCache::grown`).
    pub fn grown(&self, margin: [f32; 3], coarse: bool) -> Arc<Vec<Grown>> {
        self.grown.grown(self.textures.occupancy_for(coarse).1, margin, coarse)
    }

    /// Their words for the shaders (`GrowthCache::words`).
    pub fn grown_words(&self, margin: [f32; 3], coarse: bool) -> Option<Arc<Vec<u32>>> {
        self.grown.words(self.textures.occupancy_for(coarse).1, margin, coarse)
    }

    /// Called after a submission that contained the upload has completed.
    pub fn uploaded(&self) {
        self.uploaded.set(true);
    }
}

fn missing() -> GpuError {
    GpuError::Allocation {
        what: "scene textures".into(),
        message: "internal: texture list out of order".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::super::occupancy::{Occupancy, CELL};

    #[test]
    fn the_growth_cache_gives_the_words_of_the_growth_asked_for() {
        // Two grids over the same box (the volume's cells and a coarser one), each with an
        // occupied cell: the words kept for one margin must not serve another whose growth in
        // cells differs, and must come back when it does not.
        let grid = |cells: [usize; 3], at: [usize; 3]| {
            let mut flags = vec![false; cells.iter().product()];
            flags[(at[2] * cells[1] + at[1]) * cells[0] + at[0]] = true;
            Occupancy {
                flags,
                cells,
                voxels: cells.map(|c| c * CELL),
                edge: CELL,
            }
        };
        let occupancy = [grid([8, 6, 5], [3, 2, 2]), grid([4, 3, 3], [0, 2, 1])];
        let fresh = |margin: [f32; 3]| {
            let grown: Vec<_> = occupancy.iter().map(|o| o.grown(margin)).collect();
            grown[0].words(&grown[1..])
        };
        let cache = super::GrowthCache::default();
        let (near, far) = ([0.05; 3], [0.3; 3]);
        assert_ne!(occupancy[0].growth(near), occupancy[0].growth(far));
        for margin in [near, far, far, near] {
            let words = cache.words(&occupancy, margin, false).expect("two grids");
            assert_eq!(*words, fresh(margin), "{margin:?}");
        }
        // The same growth kept: the same words, not made again.
        let a = cache.words(&occupancy, near, false).unwrap();
        let b = cache.words(&occupancy, [0.051; 3], false).unwrap();
        assert_eq!(occupancy[0].growth(near), occupancy[0].growth([0.051; 3]));
        assert!(std::sync::Arc::ptr_eq(&a, &b));
        // Another level makes them anew.
        assert!(!std::sync::Arc::ptr_eq(
            &a,
            &cache.words(&occupancy, near, true).unwrap()
        ));
        // A transfer-function edit changes the occupied cells but not their growth: after a
        // clear the words are those of the cells given, not of the cells kept.
        let edited = [grid([8, 6, 5], [6, 4, 1]), grid([4, 3, 3], [3, 0, 2])];
        assert_eq!(edited[0].growth(near), occupancy[0].growth(near));
        let kept = cache.words(&occupancy, near, false).unwrap();
        cache.clear();
        let anew = cache.words(&edited, near, false).unwrap();
        let grown: Vec<_> = edited.iter().map(|o| o.grown(near)).collect();
        assert_eq!(*anew, grown[0].words(&grown[1..]));
        assert_ne!(*anew, *kept);
    }

    /// A ramp of values along each axis in turn, over a volume with odd sides (so that a half
    /// level's texel spans a little more than two voxels) and η linear in the value: the half
    /// levels of the gradient and orientation volumes, made from the half level's values, give
    /// the full levels' per-voxel differences inside the volume, which is what the passes read
    /// at either level. Made alone (the viewer's coarse levels), the half level is the same to
    /// the bit, and the full level is a placeholder texel.
    #[test]
    fn the_half_levels_scale_as_the_full_levels_and_need_not_wait_for_them() {
        use super::{half_orientation, half_texel_voxels, Refracting, Resolutions};
        use crate::render::coarse::{half_dims, half_level};
        use crate::render::layers::orientation_volume;
        use crate::scene::Gradient;
        let dims = [21, 19, 17];
        let half = half_dims(dims);
        let voxels = half_texel_voxels(dims);
        assert!(voxels.iter().all(|&v| v > 2.0), "{voxels:?}");
        let eta = crate::transfer::Curve {
            points: vec![[0.0, 1.0], [1.0, 1.5]],
        };
        let spacing = [0.5, 0.5, 0.8];
        for axis in 0..3 {
            // 2000 of 65535 a voxel: a texel of the full level.
            let samples: Vec<u16> = (0..dims.iter().product::<usize>())
                .map(|i| {
                    let at = [i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])];
                    (5000 + 2000 * at[axis]) as u16
                })
                .collect();
            let samples_half = half_level(&samples, dims);
            let make = |levels| {
                Refracting::new(
                    &samples,
                    Some(&samples_half),
                    dims,
                    [3, 3, 3],
                    (None, Gradient::Central),
                    &eta,
                    levels,
                )
            };
            let both = make(Resolutions { full: true, half: true });
            let alone = make(Resolutions {
                full: false,
                half: true,
            });
            let (texels, extent) = both.half.clone().expect("a half level");
            assert_eq!(extent, half.map(|n| n as u32));
            assert_eq!(
                alone.half.as_ref().map(|h| &h.0),
                Some(&texels),
                "axis {axis}: made alone"
            );
            assert_eq!((alone.extent, alone.texels.len()), ([1, 1, 1], 1), "a placeholder");
            assert_eq!(
                alone.bending.0,
                alone.half_bending.as_ref().unwrap().0,
                "the half level's flags stand in"
            );
            // Inside, two voxels from every face at the full level and one at the half.
            let inner = |d: [usize; 3], m: usize| {
                (0..d.iter().product::<usize>()).filter(move |&i| {
                    let at = [i % d[0], i / d[0] % d[1], i / (d[0] * d[1])];
                    (0..3).all(|a| at[a] >= m && at[a] + m < d[a])
                })
            };
            // Twice the derivative per voxel: 2 · 2000/65535 · 0.5 of η.
            let expected = 2.0 * 2000.0 / 65535.0 * 0.5;
            // Relative: along an odd side of n voxels the half level's last texel covers part
            // of a voxel, and the box filter's means of the ramp lie at positions whose
            // central differences are off the texels' span by up to 1/n² (0.35 % at 17); f16
            // rounding adds 2⁻¹¹, the means' 16-bit rounding half a unit of a difference of
            // over 8000 (6·10⁻⁵).
            let tolerance = 1.0 / (dims[axis] * dims[axis]) as f32 + 1e-3;
            for (name, d, t) in [("full", dims, &both.texels), ("half", half, &texels)] {
                for i in inner(d, 1) {
                    let g = t[i][axis].to_f32();
                    assert!(
                        (g - expected).abs() < tolerance * expected,
                        "{name} axis {axis} texel {i}: {g}"
                    );
                }
            }
            // The orientation volume likewise, with the half level's spacing.
            let reach = 1.2;
            let full = orientation_volume(&samples, dims, spacing, reach);
            let coarse = half_orientation(&samples_half, dims, spacing, reach);
            // Central differences too: twice the derivative per voxel.
            let per_voxel = 2.0 * 2000.0 * crate::render::layers::ORIENTATION_SCALE / 65535.0;
            for (name, d, t) in [("full", dims, &full), ("half", half, &coarse)] {
                for i in inner(d, 3) {
                    let g = t[i][axis] as f32;
                    // As above, and the SNORM texels' rounding (half a unit).
                    assert!(
                        (g - per_voxel).abs() < tolerance * per_voxel + 0.5,
                        "orientation {name} axis {axis} texel {i}: {g}"
                    );
                }
            }
        }
    }

    #[test]
    fn halves_saturate_instead_of_overflowing() {
        let bytes = super::halves([1.0f32, 1e6, 65504.0].into_iter());
        let back: Vec<f32> = bytes
            .chunks(2)
            .map(|b| half::f16::from_le_bytes([b[0], b[1]]).to_f32())
            .collect();
        assert_eq!(back, [1.0, 65504.0, 65504.0]);
    }
}
