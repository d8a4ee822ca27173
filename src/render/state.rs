//! The sweep itself: state buffers, the per-plane dispatches and read-back (Algorithm 1).
//!
//! One dispatch per plane k moves the light from plane k-1 to plane k (beams or backward
//! lookups, on the light grid) and the view rays one plane behind, from k-2 to k-1, so both
//! ends of a view segment have their light. Light lives in a ring of three planes; view rays
//! are updated in place. Where the light a view ray reads stays where the light pass left it
//! (the beams' power per plane without refraction, their deposits with it), one view pass
//! advances the rays over several planes (`Layout::view_planes`), and the light of that many
//! planes is kept.

use std::io::IsTerminal;
use std::sync::Arc;

use ash::vk;
use glam::Mat4;

use crate::gpu::{
    AliasedBuffer, Buffer, ComputePipeline, Context, DescriptorSet, GpuError, Image, ImageDesc, LinearLayout, Recorder,
    Resource, Timestamps,
};

use super::light_tiles::{self, NEVER};
use super::shaders::Pass;
use super::upload::{CachedTextures, RawSet, Resolutions, SceneTextures, TexturesKey};
use super::{
    background, DebugView, Features, Immediates, Params, PreparedScene, RenderError, RenderOutput, RenderRequest,
    RenderStats, RenderedImage,
};
use crate::scene::view::{
    light_direction, BeamGrid, PixelRect, ViewSetup, VoxelCap, MAX_LIGHT_VALUE, MIN_LIGHT_DIR_Z, MIN_VIEW_DIR_Z,
};
use crate::scene::{LightTransport, Precision};

/// Planes recorded per submission at most: keeps each submission short (progress,
/// responsiveness, watchdogs) while the per-submission overhead stays negligible.
const PLANES_PER_SUBMIT: u32 = 128;
/// Texel updates per submission at most (planes × pixels), so that one submission stays far
/// below the fence timeout (`gpu::FENCE_TIMEOUT`) even at the device's largest image on a CPU
/// driver: 2^24 texels take about 5 s on lavapipe on two cores.
const TEXELS_PER_SUBMIT: u64 = 1 << 24;
/// Pixel-planes per submission of a cancellable render (between 1 and 8 planes): a view
/// change stops it within about one plane of a 1024×768 image.
const PIXEL_PLANES_PER_SUBMIT_CANCELLABLE: u32 = 1 << 20;
/// Planes a view pass advances its rays over where it can take several (`Layout::view_planes`).
pub(super) const VIEW_PLANES_PER_PASS: u32 = 8;
/// Lists of light tiles kept at once (`light_lists`, `light_list_slot` in beams.wgsl): per
/// parity of the view pass whose planes they step, per plane of the pass, two.
const LIGHT_LISTS: u32 = 2 * VIEW_PLANES_PER_PASS * 2;

/// The slot of the list of light tiles for the plane `offset` planes into a view pass of
/// parity `parity` (`light_list_slot` in beams.wgsl).
fn light_list_slot(parity: u32, offset: u32, list: u32) -> u64 {
    ((parity * VIEW_PLANES_PER_PASS + offset) * 2 + list) as u64
}
/// Bytes the light of the planes a view pass spans may take: the beams' power, eight planes
/// up to 1024²; refracted beams' deposits, eight planes up to the viewer's full level
/// (644×768) and at 1024² eight where the light is grey, six where the medium colours it
/// (rgb; five where a CPU driver reads them through an image, whose atlas is a seventh
/// larger: `atlas_size`), for a volume that covers the frame (the deposits cover the rect
/// its rays can reach: seven planes through the image for the CT head's 1023×773 pixels at
/// 1024²). The deposits are one storage buffer, and 128 MiB is the least storage buffer range
/// Vulkan allows a device. A view pass per plane loads and stores every ray's record on every
/// plane: with 48 MiB (one plane per pass at 1024² in rgb, four at 644×768) the CT head's
/// view passes took 19–20 s at 1024² against 10.4 s with five planes per pass, and 6.0–6.3 s
/// against 5.5–5.9 s at 644×768 with eight.
const VIEW_RING_BYTES: u64 = 128 << 20;
/// The spread mode's texels per beam in each half of `beam_scatter` (`SCATTER_LAYERS` in
/// beams.wgsl).
const SCATTER_LAYERS: u32 = 5;
/// Largest workgroup count along one dispatch axis that every Vulkan device accepts.
const MAX_GROUPS_PER_ROW: u32 = 65535;
/// Planes of light kept at once (the ring of `sweep.wgsl`) where each view pass reads one; the
/// backward transport's light, the lists of view tiles.
const LIGHT_RING: u64 = 3;
/// Half-width of an index interface for the Fresnel term, in voxels: the gradient volume's
/// central differences spread a step over two voxels, trilinear sampling over one more.
const INTERFACE_HALF_WIDTH_VOXELS: f32 = 1.5;

/// The interface half-width in world units: [`INTERFACE_HALF_WIDTH_VOXELS`] of the finest
/// spacing, the same reach along every axis (the Fresnel term's, and the orientation
/// volume's differences).
pub(super) fn interface_half_width(spacing: [f32; 3]) -> f32 {
    INTERFACE_HALF_WIDTH_VOXELS * spacing.iter().copied().fold(f32::INFINITY, f32::min)
}

fn cols(m: Mat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d()
}

/// Tiles of side `tile` along `n` pixels or light-grid cells.
fn tiles(n: u32, tile: u32) -> u32 {
    n.div_ceil(tile)
}

/// Light channels per deposited pixel: rgb when the medium colours the light (else one grey
/// value), plus a direction when the direction view shows it.
fn light_channels(features: &Features, debug: DebugView) -> u32 {
    let colour = if features.medium { 3 } else { 1 };
    let direction = debug == DebugView::LightDirection;
    colour + if direction { 3 } else { 0 }
}

struct Layout {
    grid: BeamGrid,
    /// The side of the tiles of pixels and beams (`Specialisation::tile`).
    tile: u32,
    beam_groups: u32,
    view_tiles_x: u32,
    view_groups: u32,
    channels: u32,
    /// The view tiles each plane needs are listed on the device and dispatched indirectly
    /// (one row of workgroups: at most MAX_GROUPS_PER_ROW tiles).
    lists: bool,
    /// The light tiles each plane steps are listed on the device and dispatched indirectly
    /// (`light_tiles_listed` in beams.wgsl); else every tile of the plane's light window is.
    light_lists: bool,
    /// Listed light tiles whose light no view ray still alive can read stop being stepped
    /// (`light_tile_unseen` in beams.wgsl).
    unseen_light_ends: bool,
    /// Listed view tiles whose rays, not yet bent, meet no visible brick on a pass's planes
    /// are not stepped (`tiles_main` in sweep.wgsl).
    skip_empty_view_tiles: bool,
    /// Planes each view pass advances its rays over (`view_main` in sweep.wgsl): several
    /// where the light they read stays where the light pass left it (the beams' power kept
    /// per plane without refraction, their deposits with it), one otherwise.
    view_planes: u32,
    /// Slots of the ring of deposited light (`light_acc`; `deposit_slot` in beams.wgsl): the
    /// planes a view pass reads, the one the light pass beside it deposits onto, and the
    /// next, cleared meanwhile.
    deposit_slots: u32,
    /// The listed light tiles are stepped over the planes up to the next view pass in one
    /// dispatch, and listed once per view pass (`light_groups` in beams.wgsl): beams that read
    /// no other beam, for the image and the medium view.
    light_groups: bool,
    /// The beams are refracted (they deposit their light).
    refraction: bool,
    /// Where a plane of the deposited light lies in `light_acc` (`ACC_LEVELS` levels, or the
    /// spread mode's `SCATTER_LEVELS`).
    deposits: DepositLayout,
    /// With `Features::deposit_image`: the size of the atlas the levels lie in.
    atlas: (u32, u32),
    /// Planes back along its light line from which a view sample reads the beams' power
    /// (`beams_unscattered_through` and `beams_light_through` in beams.wgsl): those in a
    /// voxel.
    back_planes: u32,
    /// The device's widest image side (`power_records`, `beam_row_shift`).
    max_image_side: u32,
    /// Keep the beams' power in pairs of regions even where records fit
    /// (`RenderRequest::power_in_pairs`).
    power_in_pairs: bool,
    /// The halves' power is kept in the beams' aux texels (`power_in_aux`): `beam_power`
    /// holds only the power before each segment.
    power_in_aux: bool,
}

impl Layout {
    fn new(view: &ViewSetup, grid: BeamGrid, channels: u32, tile: u32) -> Layout {
        let view_tiles_x = tiles(view.rect.width(), tile);
        let view_groups = view_tiles_x * tiles(view.rect.height(), tile);
        Layout {
            grid,
            tile,
            beam_groups: tiles(grid.width, tile) * tiles(grid.height, tile),
            view_tiles_x,
            view_groups,
            channels,
            lists: view_groups <= MAX_GROUPS_PER_ROW,
            light_lists: false,
            unseen_light_ends: true,
            skip_empty_view_tiles: true,
            view_planes: 1,
            deposit_slots: LIGHT_RING as u32,
            light_groups: false,
            refraction: false,
            deposits: DepositLayout::default(),
            atlas: (0, 0),
            back_planes: 1,
            max_image_side: u32::MAX,
            power_in_pairs: false,
            power_in_aux: false,
        }
    }
}

/// Levels of the pyramid the beams deposit their light on (`ACC_LEVELS` in beams.wgsl).
pub const ACC_LEVELS: u32 = 3;

/// Levels of the spread mode's pyramid of scattered light (`SCATTER_LEVELS` in beams.wgsl).
pub const SCATTER_LEVELS: u32 = 7;

/// A side of a state image holding `n` texels: `n`, or the next side that is not a power of
/// two where the device's largest side `max` allows it. llvmpipe compiles a variant of a
/// shader for each combination of its images' sides being powers of two or not, on the
/// variant's first dispatch: in the viewer, a light grid of 64 rows after one of 65
/// recompiled the light shaders in the middle of a drag (a frame of 1.3–2.4 s instead of
/// 0.3 s on the CT head). The extra row or column is never read.
fn image_side(n: u32, max: u32) -> u32 {
    let mut side = n.max(1);
    while side.is_power_of_two() && side < max {
        side += 1;
    }
    side
}

/// Where a plane of the pyramid of deposited light lies in `light_acc`: each channel of each
/// slot a layer of `layer_words` words, its levels packed one after the other, or with
/// `Features::deposit_image` in an atlas (`atlas_size`) of rows of `row_words` words, as the
/// image over the same memory lays them out (`acc_level` in beams.wgsl).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct DepositLayout {
    /// Words from one row of the atlas to the next (0: packed).
    row_words: u64,
    /// Words from one layer to the next.
    layer_words: u64,
}

impl DepositLayout {
    /// The levels of the pyramid of `levels` levels over `rect` packed.
    fn packed(rect: &PixelRect, levels: u32) -> Self {
        DepositLayout {
            row_words: 0,
            layer_words: pyramid_texels(rect, levels),
        }
    }

    /// The atlas laid out as an image's layout says (4-byte texels).
    fn image(layout: LinearLayout) -> Self {
        DepositLayout {
            row_words: layout.row_pitch / 4,
            layer_words: layout.array_pitch / 4,
        }
    }

    /// Bytes of one slot of `channels` channels.
    fn slot_bytes(&self, channels: u32) -> u64 {
        self.layer_words * channels as u64 * 4
    }
}

/// Texels of level m of the deposit pyramid along one axis of the rect's pixels lo..hi: those
/// whose 2^m pixels meet it (`level_size` in beams.wgsl; one for an empty rect). Nothing is
/// deposited or read beyond the rect, where the volume's rays cannot reach.
fn level_span(lo: u32, hi: u32, m: u32) -> u32 {
    if hi <= lo {
        return 1;
    }
    ((hi - 1) >> m) - (lo >> m) + 1
}

/// Width and height of level m of the deposit pyramid over `rect`.
fn level_dims(rect: &PixelRect, m: u32) -> (u32, u32) {
    (level_span(rect.x0, rect.x1, m), level_span(rect.y0, rect.y1, m))
}

/// Texels of one plane of the deposit pyramid of `levels` levels over `rect`.
fn pyramid_texels(rect: &PixelRect, levels: u32) -> u64 {
    (0..levels)
        .map(|m| {
            let (w, h) = level_dims(rect, m);
            w as u64 * h as u64
        })
        .sum()
}

/// Width and height of the atlas of the pyramid of `levels` levels (at least two) over `rect`:
/// level 0 at its corner, the coarser levels stacked in a column to its right, as wide as
/// level 1 (`level_origin` in beams.wgsl). About a seventh more texels than the pyramid (3/2
/// of level 0's against 21/16: the column's lower quarter is mostly empty).
fn atlas_size(rect: &PixelRect, levels: u32) -> (u32, u32) {
    let (w0, h0) = level_dims(rect, 0);
    let column: u32 = (1..levels).map(|m| level_dims(rect, m).1).sum();
    (w0 + level_dims(rect, 1).0, h0.max(column))
}

/// Largest number of layers the deposit ring's image can need: the most slots (a view pass's
/// planes and two more) times the most channels (rgb light and a direction).
const MAX_DEPOSIT_LAYERS: u32 = (VIEW_PLANES_PER_PASS + 2) * 6;

/// Whether a render of `req` with `features` reads the deposited light through an image over
/// `light_acc` (`Features::deposit_image`): on a CPU driver that can read such a linear
/// image of the atlas's size, where the beams deposit.
pub(super) fn deposit_image(ctx: &Context, features: &Features, req: &RenderRequest) -> bool {
    if !ctx.is_cpu() || !deposit_ring(features) {
        return false;
    }
    // The rect is not known yet: the whole frame's atlas, which holds any rect's.
    let (w, h) = atlas_size(&PixelRect::frame(req.width, req.height), deposit_levels(features));
    AliasedBuffer::supported(ctx, vk::Format::R32_UINT, w, h, MAX_DEPOSIT_LAYERS)
}

/// Levels of the pyramid of deposited light: the spread mode's scattered light spreads
/// further (`acc_levels` in beams.wgsl).
fn deposit_levels(features: &Features) -> u32 {
    if features.scatter {
        SCATTER_LEVELS
    } else {
        ACC_LEVELS
    }
}

/// Whether the beams keep the halves' power in their aux texels rather than in `beam_power`
/// (`power_in_aux` in beams.wgsl, from the same overrides: beams that keep their cells and
/// exchange light, the soft light, with every beam's state in the halves and f16 state).
/// `beam_power` then holds only the power before each segment, 2 regions fewer: the soft
/// light's state for the CT head of `compare.sh` 12.1 → 10.9 MiB at 256², 47.6 → 45.8 MiB at
/// 1024².
fn power_in_aux(features: &Features, precision: Precision, light_edge_steps: bool) -> bool {
    features.transport == LightTransport::Beams
        && features.light_filter
        && !features.refraction
        && !features.scatter
        && !features.lbm
        && !light_edge_steps
        && precision != Precision::F32
}

/// Whether the beams deposit their light in the ring `light_acc` (refraction, the spread
/// mode's scattered light).
fn deposit_ring(features: &Features) -> bool {
    features.transport == LightTransport::Beams && (features.refraction || features.scatter)
}

impl Layout {
    /// Planes of the beams' power before their segment kept at once: those a view pass reads
    /// (its own planes and `back_planes` - 1 before them) and the one the light pass beside
    /// it writes; refracted beams read only their own, `back_planes` back, to deposit it.
    fn front_planes(&self) -> u32 {
        let read = if self.refraction { 1 } else { self.view_planes };
        read + self.back_planes
    }

    /// Regions of the beams' power (`load_beam_power` in beams.wgsl): the two halves, and
    /// the power before the segment to each of the planes kept (`front_planes`), but for
    /// refracted beams that deposit what they carry on the plane (a voxel is one plane).
    /// Where the aux texels hold the halves' power (`power_in_aux`), only the planes kept
    /// (`power_slot` in beams.wgsl).
    fn power_regions(&self) -> u32 {
        if self.refraction && self.back_planes == 1 {
            2
        } else if self.power_in_aux {
            self.front_planes()
        } else {
            2 + self.front_planes()
        }
    }

    /// The regions of a beam's power laid side by side along x, a record per beam
    /// (`beam_power_texel` in common.wgsl), where a row of records (with refraction, a row
    /// of a tile's: `beam_rows`) fits the device's widest image; else 0, the regions in pairs.
    fn power_records(&self) -> u32 {
        let regions = self.power_regions();
        let fits = if self.refraction {
            self.beam_rows(regions).is_some()
        } else {
            image_side(regions.saturating_mul(self.grid.width), self.max_image_side) <= self.max_image_side
        };
        if !self.power_in_pairs && fits {
            regions
        } else {
            0
        }
    }

    /// The exponent of the slots per row of the beams' images with `texels` texels per slot
    /// (`beam_rows`), None where none fits.
    fn beam_rows(&self, texels: u32) -> Option<u32> {
        beam_rows(self.beam_slots(), self.tile, texels, self.max_image_side)
    }

    /// Slots in the beams' images: the light tiles' beams.
    fn beam_slots(&self) -> u64 {
        self.beam_groups as u64 * (self.tile * self.tile) as u64
    }

    /// The exponent of the beams' slots per image row (`beam_rows`) for the widest of their
    /// images, `Params::sweep` w.
    fn beam_row_shift(&self) -> u32 {
        self.beam_rows(self.power_records().max(2))
            .unwrap_or_else(|| tile_row_shift(self.tile))
    }

    /// Width and height of an image of the beams with `texels` texels per slot: with
    /// refraction in the beams' slots (`beam_row_shift`), else a row per row of the grid.
    fn beam_image(&self, texels: u32) -> [u32; 2] {
        if !self.refraction {
            return [texels * self.grid.width, self.grid.height];
        }
        let shift = self.beam_row_shift();
        [texels << shift, self.beam_slots().div_ceil(1 << shift) as u32]
    }
}

/// Slots of beams per row of the beams' images, as a power of two's exponent (`beam_slot` in
/// common.wgsl: the `tile` × `tile` beams of a light tile one after another, the tiles in
/// order, `slots` in all), with `texels` texels per slot (the power's records, or 2 for the
/// halves side by side): of the rows from a tile's beams to all of them whose image has sides
/// up to `max`, the one nearest the square root of the slots, so that the last row's unused
/// slots are few against all of them; None where none fits.
fn beam_rows(slots: u64, tile: u32, texels: u32, max: u32) -> Option<u32> {
    let fits = |n: u64| n <= max as u64 && image_side(n as u32, max) <= max;
    let least = tile_row_shift(tile);
    let most = slots.next_power_of_two().trailing_zeros().max(least);
    let square = most.div_ceil(2);
    (least..=most)
        .filter(|&shift| fits((texels as u64) << shift) && fits(slots.div_ceil(1 << shift)))
        .min_by_key(|&shift| shift.abs_diff(square))
}

/// The exponent of the shortest row of the beams' slots: one that holds a `tile` × `tile`
/// light tile's beams.
fn tile_row_shift(tile: u32) -> u32 {
    (tile * tile).next_power_of_two().trailing_zeros()
}

/// The planes in one voxel at `sample_distance` (voxels per plane), at most 8: how far back
/// along its light line a view sample reads the beams.
fn back_planes(sample_distance: f32) -> u32 {
    ((1.0 / sample_distance.max(1e-6)) - 1e-4).ceil().clamp(1.0, 8.0) as u32
}

/// Light-tile steps of a sweep with light tiles listed: each tile is stepped from the plane
/// its span starts (`light_start.y`) until the plane its end was written on (`light_end`;
/// NEVER: to the last plane).
fn tile_steps(spans: &[[u32; 4]], ends: &[u32], planes: u32) -> u64 {
    spans
        .iter()
        .zip(ends)
        .filter(|(s, _)| s[1] != NEVER)
        .map(|(s, &end)| end.min(planes).saturating_sub(s[1]) as u64)
        .sum()
}

/// Workgroups of the tiles pass for `view_groups` rect tiles and `light_tiles` light tiles to
/// list: one invocation per rect tile, then one per light tile (a workgroup whose invocations
/// have nothing to do still costs its launch on a CPU driver). Where light tiles are listed,
/// the first `2 * VIEW_PLANES_PER_PASS` invocations after the rect tiles' also empty the
/// lists of the pass just done (`tiles_main`), so there are at least that many, however few
/// light tiles there are: a list left as it was kept the tiles of two passes before, and
/// stepped them again.
fn tile_groups(view_groups: u32, light_tiles: u32, tile: u32) -> u32 {
    let light = if light_tiles > 0 {
        light_tiles.max(2 * VIEW_PLANES_PER_PASS)
    } else {
        0
    };
    (view_groups + light).div_ceil(tile * tile)
}

/// With pass timings, a timestamp after a pass of the plane (`RenderStats::pass_ms`); the
/// next one is `stamps`.
fn pass_stamp<'r>(r: &mut Recorder<'r>, ts: &'r Timestamps, stamps: &mut u32, pass_timings: bool) {
    if pass_timings {
        r.timestamp(ts, *stamps);
        *stamps += 1;
    }
}

/// Workgroups of a dispatch laid out in rows of `MAX_GROUPS_PER_ROW` (the shaders linearise
/// them with the same width).
fn groups(n: u32) -> [u32; 3] {
    [n.clamp(1, MAX_GROUPS_PER_ROW), n.div_ceil(MAX_GROUPS_PER_ROW).max(1), 1]
}

/// Tiles of the light grid each plane needs (origin tile x, y, tiles per row, workgroups):
/// the cells whose light can still reach the image's rect on this plane or a later one. Light
/// that is not refracted travels along the light direction, so that is the rect carried
/// back along it to plane 0, from this plane and from the last one (in between it sweeps
/// linearly), 16 cells wider for the neighbours a cell reads (two tiles of `Pass::TILE`,
/// whatever the side of the render's tiles). Refracted light can turn back toward the rect
/// from anywhere: then every plane needs the whole grid.
fn light_windows(view: &ViewSetup, grid: &BeamGrid, light: glam::Vec3, refraction: bool, tile: u32) -> Vec<[u32; 4]> {
    let (tx, ty) = (tiles(grid.width, tile), tiles(grid.height, tile));
    let full = [0, 0, tx, tx * ty];
    if refraction {
        return vec![full; view.planes as usize + 1];
    }
    let z0 = view.z_first;
    let z_last = view.plane_z(view.planes - 1);
    let r = view.rect;
    let corners = [(r.x0, r.y0), (r.x1, r.y0), (r.x0, r.y1), (r.x1, r.y1)];
    let cell = |z: f32, (x, y): (u32, u32)| {
        let p = view.point_at(glam::Vec2::new(x as f32, y as f32), z);
        let p0 = view.pixel_of(p - light * ((p.z - z0) / light.z));
        (p0 - glam::Vec2::new(grid.x0, grid.y0)) / grid.stride
    };
    let last: Vec<glam::Vec2> = corners.iter().map(|c| cell(z_last, *c)).collect();
    (0..=view.planes)
        .map(|k| {
            let z = view.plane_z(k.min(view.planes - 1));
            let (lo, hi) = corners.iter().map(|c| cell(z, *c)).chain(last.iter().copied()).fold(
                (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY)),
                |(lo, hi), p| (lo.min(p), hi.max(p)),
            );
            let margin = 2 * Pass::TILE as i64;
            let clamp = |v: f32, n: u32| (v as i64).clamp(0, n as i64) as u32;
            let (x0, y0) = (
                clamp(lo.x.floor() - margin as f32, grid.width) / tile,
                clamp(lo.y.floor() - margin as f32, grid.height) / tile,
            );
            let (x1, y1) = (
                tiles(clamp(hi.x.ceil() + margin as f32, grid.width), tile),
                tiles(clamp(hi.y.ceil() + margin as f32, grid.height), tile),
            );
            let (w, h) = (x1.saturating_sub(x0), y1.saturating_sub(y0));
            [x0, y0, w.max(1), w * h]
        })
        .collect()
}

fn make_params(
    prepared: &PreparedScene,
    view: &ViewSetup,
    layout: &Layout,
    env_levels: u32,
    brick_dims: [u32; 3],
    light_box: [f32; 4],
    light_margin: f32,
) -> Params {
    let scene = &prepared.scene;
    let vol = &prepared.volume;
    let ld = light_direction(&scene.light);
    let l = &scene.light;
    let clip = scene
        .clip
        .as_ref()
        .map(|c| view.clip_plane(c.normal, c.offset).to_array())
        .unwrap_or([0.0, 0.0, 0.0, -1.0]);
    let env_intensity = match &scene.environment {
        crate::scene::Environment::Studio { intensity } | crate::scene::Environment::Image { intensity, .. } => {
            *intensity
        }
        crate::scene::Environment::Color { .. } => 1.0,
    };
    let rotation = Mat4::from_mat3(glam::Mat3::from_mat4(view.world_from_view));
    // The voxels along the textures' axes.
    let dims = view.in_memory_order(vol.dims);
    let g = &layout.grid;
    let r = view.rect;
    Params {
        volume_from_view: cols(view.volume_from_view()),
        gradient_to_view: cols(view.gradient_to_view(view.in_memory_order(vol.spacing))),
        world_from_view: cols(rotation),
        clip_plane: clip,
        projection: view.projection,
        plane: [
            view.z_first,
            view.step,
            view.planes as f32,
            scene.quality.sample_distance,
        ],
        light_dir: [ld.x, ld.y, ld.z, l.softness],
        light_color: [
            l.color[0] * l.intensity,
            l.color[1] * l.intensity,
            l.color[2] * l.intensity,
            scene.quality.max_intensity_ratio,
        ],
        shading: [
            scene.shading.specular,
            scene.shading.roughness,
            scene.quality.termination_opacity,
            env_intensity,
        ],
        size: [
            view.width as f32,
            view.height as f32,
            1.0 / view.width as f32,
            1.0 / view.height as f32,
        ],
        texel: [
            1.0 / dims[0] as f32,
            1.0 / dims[1] as f32,
            1.0 / dims[2] as f32,
            super::gradient::ambient_eta(&prepared.tf.eta),
        ],
        background: background(&scene.environment),
        limits: [MIN_LIGHT_DIR_Z, MIN_VIEW_DIR_Z, MAX_LIGHT_VALUE, env_levels as f32],
        budget: [
            scene.quality.max_concentration(),
            interface_half_width(vol.spacing),
            light_margin,
            f32::from(u8::from(super::bricks::clear_outside(&prepared.tf))),
        ],
        beam_origin: [g.x0, g.y0, g.stride, g.stride * g.stride],
        beam_grid: [g.width, g.height, tiles(g.width, layout.tile), layout.beam_groups],
        rect: [r.x0, r.y0, r.x1, r.y1],
        tiles: [
            layout.view_tiles_x,
            layout.view_groups,
            MAX_GROUPS_PER_ROW,
            layout.channels,
        ],
        culling: [
            brick_dims[0],
            brick_dims[1],
            brick_dims[2],
            u32::from(layout.lists)
                | u32::from(layout.unseen_light_ends) << 1
                | u32::from(layout.skip_empty_view_tiles) << 2,
        ],
        light_box,
        sweep: [
            layout.front_planes(),
            layout.power_records(),
            layout.deposit_slots,
            layout.beam_row_shift(),
        ],
        deposits: [
            layout.deposits.row_words as u32,
            layout.deposits.layer_words as u32,
            0,
            0,
        ],
    }
}

fn progress_bar(show: bool, planes: u64) -> Option<indicatif::ProgressBar> {
    if !show || !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(planes);
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} planes {pos}/{len} {wide_bar} {eta}") {
        bar.set_style(style);
    }
    Some(bar)
}

/// The state buffers and images of one render, by binding name (`shaders/common.wgsl`); those
/// the scene does not need are 16-byte placeholders (1×1 images).
struct State {
    /// `light_acc_tex`: the image over `light_acc`'s memory that the view reads with
    /// `Features::deposit_image`, else a 1×1 placeholder. Dropped before the buffers.
    acc_image: Image,
    buffers: Vec<(&'static str, Buffer)>,
    /// The beams' and view rays' state from plane to plane: 2D array images, a texel per beam
    /// or pixel, so that what a shader reads of it inside a branch (a beam's neighbours, the
    /// power the view looks up, a ray's own record) is a texel fetch, which a CPU driver
    /// gathers for all invocations at once; it loads a storage buffer there invocation by
    /// invocation and component by component.
    images: Vec<(&'static str, Image)>,
    /// Bytes of the buffers and images the scene needs (the output image excluded).
    bytes: u64,
}

impl State {
    fn new(
        ctx: &Arc<Context>,
        view: &ViewSetup,
        layout: &Layout,
        features: &Features,
        precision: Precision,
    ) -> Result<State, GpuError> {
        let pixels = view.width as u64 * view.height as u64;
        let cells = layout.grid.count();
        let rgba = precision.rgba_bytes();
        let beams = features.transport == LightTransport::Beams;
        let refraction = features.refraction;
        let back_dir = !beams && (refraction || features.intensity_correction);
        let deposits = deposit_ring(features);
        let layers = layout.deposit_slots * layout.channels;
        let sizes: [(&str, u64, bool); 12] = [
            ("light_acc", layers as u64 * layout.deposits.layer_words * 4, deposits),
            ("back_light", LIGHT_RING * cells * rgba, !beams),
            ("back_dir", LIGHT_RING * cells * 16, back_dir),
            ("image_out", pixels * 16, true),
            ("view_tiles", layout.view_groups as u64 * 4, true),
            ("tile_lists", LIGHT_RING * layout.view_groups as u64 * 4, layout.lists),
            ("tile_args", LIGHT_RING * 12, true),
            ("light_end", layout.beam_groups as u64 * 4, layout.light_lists),
            ("light_alive", layout.beam_groups as u64 * 4, layout.light_lists),
            ("light_lit", layout.beam_groups as u64 * 4, layout.light_lists),
            (
                "light_lists",
                LIGHT_LISTS as u64 * layout.beam_groups as u64 * 4,
                layout.light_lists,
            ),
            ("light_args", LIGHT_LISTS as u64 * 12, true),
        ];
        let mut buffers = Vec::new();
        let mut bytes = 0;
        let mut acc_image = None;
        for (name, size, needed) in sizes {
            let size = if needed { size.max(16) } else { 16 };
            if needed && name != "image_out" {
                bytes += size;
            }
            let buffer = if name == "light_acc" && needed && features.deposit_image {
                let (w, h) = layout.atlas;
                let aliased = AliasedBuffer::new(ctx, name, vk::Format::R32_UINT, w, h, layers)?;
                if DepositLayout::image(aliased.layout) != layout.deposits {
                    return Err(GpuError::Format(
                        vk::Format::R32_UINT,
                        "the deposited light's image (its layout changed with its layers)",
                    ));
                }
                acc_image = Some(aliased.image);
                aliased.buffer
            } else {
                Buffer::new_storage(ctx, name, size)?
            };
            buffers.push((name, buffer));
        }
        let acc_image = match acc_image {
            Some(image) => image,
            None => Image::new(
                ctx,
                ImageDesc::storage_2d_array("light_acc_tex placeholder", vk::Format::R32_UINT, 1, 1, 1),
            )?,
        };
        // The per-plane state that the shaders read inside branches: images, layers as
        // `shaders/common.wgsl` describes them. The beams lie in slots, a light tile's one
        // after another (`Layout::beam_row_shift`), a beam's texels of the two halves of a pair
        // side by side along x (`beam_pair_texel`). The beams' records: v.z, data value, shadow
        // depth and plane in the two halves, and with refraction position and v.xy. Their power
        // by region (the two halves, and each beam's power on the planes before: the view reads
        // the unrefracted beams', refracted ones deposit theirs a voxel back; the halves' not
        // where the aux texels hold it, `power_in_aux`), f16 rgb in one layer or f32 in two: a
        // record of a beam's regions side by side, or where a row of
        // records (with refraction, of a tile's) is too wide, two regions to a layer
        // (`Layout::power_records`). The spread mode's five texels per beam and half. The view
        // rays' aux and (with refraction) position and direction; their colour, light and
        // (with the medium) its transmittance, f16 in one layer each or f32 in two.
        let regions = layout.power_regions();
        let records = layout.power_records();
        let words = if precision == Precision::F32 { 2 } else { 1 };
        // A beam's texels of the two halves of a pair side by side (`beam_pair_texel`), at its
        // slot (`beam_slot`).
        let pairs = layout.beam_image(2);
        let pixels_2d = [view.width, view.height];
        let (rgba32f, rg32u) = (vk::Format::R32G32B32A32_SFLOAT, vk::Format::R32G32_UINT);
        let image_specs: [(&str, vk::Format, [u32; 2], u32, bool); 5] = [
            ("beam_state", rgba32f, pairs, if refraction { 2 } else { 1 }, beams),
            if records > 0 {
                ("beam_power", rg32u, layout.beam_image(records), words, beams)
            } else {
                ("beam_power", rg32u, pairs, regions.div_ceil(2) * words, beams)
            },
            ("beam_scatter", rgba32f, pairs, SCATTER_LAYERS, features.scatter),
            ("view_rays", rgba32f, pixels_2d, if refraction { 2 } else { 1 }, true),
            (
                "view_shade",
                rg32u,
                pixels_2d,
                (2 + u32::from(features.medium)) * words,
                true,
            ),
        ];
        let mut images = Vec::new();
        let max = ctx.limits().max_image_dimension2_d;
        for (name, format, size, layers, needed) in image_specs {
            let (size, layers) = if needed { (size, layers) } else { ([1, 1], 1) };
            let (w, h) = (image_side(size[0], max), image_side(size[1], max));
            let image = Image::new(ctx, ImageDesc::storage_2d_array(name, format, w, h, layers))?;
            if needed {
                bytes += image.bytes();
            }
            images.push((name, image));
        }
        Ok(State {
            acc_image,
            buffers,
            images,
            bytes,
        })
    }

    fn get(&self, name: &str) -> Result<&Buffer, RenderError> {
        self.buffers
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, b)| b)
            .ok_or_else(|| RenderError::Setup(format!("internal: no state buffer {name}")))
    }
}

/// The pipelines of one render: the sweep's passes (`Pass::ALL` in order), and the lattice's
/// when the scene uses it.
pub(super) struct Passes<'a> {
    /// Gives the sweep's pipelines; asked once everything else of the render is set up, so
    /// that they can be compiled meanwhile.
    pub sweep: Box<dyn FnOnce() -> Result<[Arc<ComputePipeline>; 7], RenderError> + 'a>,
    /// The view and light grid, and what the sweep's pipelines were specialised for (`plan`).
    pub plan: Plan,
    pub lbm: Option<&'a super::lbm::Pipelines>,
}

/// The view a render sweeps and its light grid, and the light's direction (view space), from
/// the scene and the request.
fn view_and_grid(
    prepared: &PreparedScene,
    req: &RenderRequest,
    features: &Features,
) -> Result<(ViewSetup, BeamGrid, glam::Vec3), RenderError> {
    let scene = &prepared.scene;
    let vol = &prepared.volume;
    let mut view = ViewSetup::new(scene, vol.dims, vol.spacing, req.width, req.height).map_err(RenderError::Setup)?;
    view.shift_planes(req.jitter[0]).map_err(RenderError::Setup)?;
    if matches!(
        req.debug_view,
        DebugView::Light | DebugView::LightDirection | DebugView::Intensity
    ) {
        // The light views show the plane across the whole frame, not only where view rays can
        // meet the volume (refracted beams deposit only within the rect).
        view.rect = crate::scene::view::PixelRect::frame(req.width, req.height);
    }
    if req.volume_layout != super::VolumeLayout::Stored && !features.lbm {
        // The lattice-Boltzmann mode's grid follows the volume's axes as stored.
        view.memory_axes = view.memory_axes_for_view();
    }
    let light = light_direction(&scene.light);
    let deposits = features.transport == LightTransport::Beams && features.refraction;
    // Beams that carry only the unscattered light: at most one per voxel where they keep
    // their cells (no refraction), a few where they are bent.
    let voxel_cap = if features.transport != LightTransport::Beams || features.scatter || features.lbm {
        None
    } else if features.refraction {
        Some(VoxelCap::REFRACTED)
    } else {
        Some(VoxelCap::UNREFRACTED)
    };
    let grid = view
        .beam_grid(light, scene.quality.beams_per_texel, !deposits, voxel_cap)
        .shifted(req.jitter[1], req.jitter[2]);
    Ok((view, grid, light))
}

/// What a render's sweep pipelines are specialised for (overrides of the shaders), from the
/// scene and the request: known before `run`, which the pipelines are compiled beside
/// (`plan`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(super) struct Specialisation {
    /// The side of the tiles the sweep works in (the `TILE` override): `Pass::CPU_TILE` on a
    /// CPU driver where the rect's tiles and the light grid's of that side each fit one row
    /// of workgroups (the lists are dispatched as one), else `Pass::TILE`.
    pub tile: u32,
    /// The planes back along its light line from which a view sample reads the beams' power
    /// (the `BACK_PLANES` override; `Layout::back_planes`): those in a voxel at the scene's
    /// sample distance. Only view samples read back (the light views show the power on the
    /// plane): 1 for them and for the backward transport, and no ring of refracted beams'
    /// power.
    pub back_planes: u32,
    /// The light tiles each plane steps are listed on the device (the `LIGHT_LISTS`
    /// override; `Layout::light_lists`).
    pub light_lists: bool,
    /// The listed light tiles are stepped over a view pass's planes in one dispatch (the
    /// `LIGHT_GROUPS` override; `Layout::light_groups`).
    pub light_groups: bool,
    /// The soft light's tiles next to tiles not started or ended are stepped at the edge (the
    /// `LIGHT_EDGE_STEPS` override; `RenderRequest::light_edge_steps`).
    pub light_edge_steps: bool,
}

/// A render's view and light grid and the specialisation of its sweep, worked out before
/// the pipelines are compiled (`run` takes them).
pub(super) struct Plan {
    pub spec: Specialisation,
    /// The view, the light grid and the light's direction (`view_and_grid`), or why there
    /// are none, which `run` reports after its own checks of the request.
    geometry: Result<(ViewSetup, BeamGrid, glam::Vec3), RenderError>,
}

/// The plan of a render of `req` (a request without a view gets the GPU's tiles and no light
/// lists, and `run` says why).
pub(super) fn plan(ctx: &Context, prepared: &PreparedScene, req: &RenderRequest, features: &Features) -> Plan {
    let back_planes = if features.transport == LightTransport::Beams && !diagnoses_light(req) {
        back_planes(prepared.scene.quality.sample_distance)
    } else {
        1
    };
    let mut spec = Specialisation {
        tile: Pass::TILE,
        back_planes,
        light_lists: false,
        light_groups: false,
        light_edge_steps: req.light_edge_steps,
    };
    if req.width == 0 || req.height == 0 {
        let geometry = Err(RenderError::Setup("an empty image has no view".into()));
        return Plan { spec, geometry };
    }
    let geometry = view_and_grid(prepared, req, features);
    if let Ok((view, grid, _)) = &geometry {
        let t = Pass::CPU_TILE;
        let fits = |w: u32, h: u32| tiles(w, t) as u64 * tiles(h, t) as u64 <= MAX_GROUPS_PER_ROW as u64;
        if ctx.is_cpu()
            && !req.gpu_tiles
            && fits(view.rect.width(), view.rect.height())
            && fits(grid.width, grid.height)
        {
            spec.tile = t;
        }
        let beam_groups = tiles(grid.width, spec.tile) * tiles(grid.height, spec.tile);
        spec.light_lists = light_lists(prepared, req, features, beam_groups);
        spec.light_groups = light_groups(spec.light_lists, req, features);
    }
    Plan { spec, geometry }
}

/// Whether the light tiles each plane steps are listed on the device (`Layout::light_lists`):
/// beams are stepped only near the volume's box where nothing outside it absorbs and the
/// image is all that is shown (the light diagnostics show the light outside the box too); the
/// spread mode's clouds reach further than the margin.
fn light_lists(prepared: &PreparedScene, req: &RenderRequest, features: &Features, beam_groups: u32) -> bool {
    features.transport == LightTransport::Beams
        && !features.scatter
        && matches!(req.debug_view, DebugView::Image | DebugView::Medium)
        && super::bricks::clear_outside(&prepared.tf)
        && beam_groups <= MAX_GROUPS_PER_ROW
}

/// Whether the listed light tiles are stepped over a view pass's planes in one dispatch
/// (`Layout::light_groups`; `light_groups` in beams.wgsl, `dark_tiles_end` there for these
/// views).
fn light_groups(lists: bool, req: &RenderRequest, features: &Features) -> bool {
    lists && !req.per_plane_light && !features.refraction && !features.light_filter && !features.lbm
}

/// Whether the request shows the light on one plane (the light views: no view rays).
fn diagnoses_light(req: &RenderRequest) -> bool {
    matches!(
        req.debug_view,
        DebugView::Light | DebugView::LightDirection | DebugView::Intensity
    )
}

pub(super) fn run(
    ctx: &Arc<Context>,
    prepared: &PreparedScene,
    req: &RenderRequest,
    features: Features,
    precision: Precision,
    passes: Passes,
    cache: &mut Option<CachedTextures>,
) -> Result<RenderOutput, RenderError> {
    let Passes { sweep, plan, lbm } = passes;
    let spec = plan.spec;
    let (w, h) = (req.width, req.height);
    let max_2d = ctx.limits().max_image_dimension2_d;
    if w == 0 || h == 0 || w > max_2d || h > max_2d {
        return Err(RenderError::Setup(format!(
            "image size {w}×{h} must be between 1×1 and {max_2d}×{max_2d} on this device"
        )));
    }
    let vol = &prepared.volume;
    let scene = &prepared.scene;
    if scene.quality.multiple_scattering == crate::scene::MultipleScattering::Spread && !features.scatter {
        return Err(RenderError::Setup(
            "quality.multiple_scattering = \"spread\" runs without refraction only: this scene refracts \
             (set quality.refraction = \"off\" or multiple_scattering = \"none\")"
                .into(),
        ));
    }
    let (mut view, grid, light) = plan.geometry?;
    let diagnoses_light = diagnoses_light(req);
    let planes_run = if req.debug_view == DebugView::Image || req.debug_view == DebugView::Medium {
        view.planes
    } else {
        1 + (req.debug_depth.clamp(0.0, 1.0) * (view.planes - 1) as f32).round() as u32
    };
    let tile = spec.tile;
    let mut layout = Layout::new(&view, grid, light_channels(&features, req.debug_view), tile);
    layout.max_image_side = max_2d;
    layout.power_in_pairs = req.power_in_pairs;
    layout.back_planes = spec.back_planes;
    let windows = light_windows(&view, &grid, light, features.refraction, tile);
    layout.light_lists = spec.light_lists;
    layout.light_groups = spec.light_groups;
    layout.unseen_light_ends = !req.keep_unseen_light;
    layout.skip_empty_view_tiles = !req.step_empty_view_tiles;
    layout.refraction = features.refraction;
    layout.power_in_aux = power_in_aux(&features, precision, spec.light_edge_steps);
    let levels = deposit_levels(&features);
    layout.deposits = DepositLayout::packed(&view.rect, levels);
    if features.deposit_image {
        let (w, h) = atlas_size(&view.rect, levels);
        let image = AliasedBuffer::layout(ctx, vk::Format::R32_UINT, w, h, MAX_DEPOSIT_LAYERS)
            .ok_or_else(|| RenderError::Setup("internal: the deposited light's image is not supported".into()))?;
        layout.atlas = (w, h);
        layout.deposits = DepositLayout::image(image);
    }
    // View rays advance over several planes per pass where the light they read stays where
    // the light pass left it (as `view_spans_planes` in view.wgsl: the beams' power kept per
    // plane without refraction, their deposits with it; not the spread mode's scattered
    // light) and their tiles are listed: as many as `VIEW_RING_BYTES` of the beams' power
    // or of deposit slots holds. A pass per plane stores a refracted ray's whole record on
    // every plane, and a CPU driver stores texels word by word.
    if features.transport == LightTransport::Beams
        && !features.scatter
        && layout.lists
        && matches!(req.debug_view, DebugView::Image | DebugView::Medium)
    {
        let fit = if features.refraction {
            // The slots the pass reads, plus the one being deposited onto and the next.
            let slot_bytes = layout.deposits.slot_bytes(layout.channels);
            (VIEW_RING_BYTES / slot_bytes.max(1)).saturating_sub(2) as u32
        } else {
            let plane_bytes = grid.count() * precision.rgba_bytes();
            (VIEW_RING_BYTES / plane_bytes.max(1)).saturating_sub(layout.back_planes as u64) as u32
        };
        layout.view_planes = match req.view_planes {
            0 => fit.clamp(1, VIEW_PLANES_PER_PASS),
            n => n.min(VIEW_PLANES_PER_PASS),
        };
        if features.refraction {
            layout.deposit_slots = layout.view_planes + 2;
        }
    }
    let window = prepared.window();
    // Scene textures are kept between renders while what they hold is unchanged (an
    // interactive view changes mostly the camera and light).
    let coarse = scene.quality.volume_level > 0;
    // A render that reads only the half level makes only it: the viewer's coarse levels
    // after a change of the data window or of η (on the CT head about a third of the frame's
    // time); the next level at full resolution makes the full level then. The viewer's
    // first frame makes both: its shaders compile beside the upload, which hides it, where
    // the first level at full resolution would wait for it. A volume after it (another time
    // step, another file) is made at the half level alone.
    let first = cache.is_none();
    let levels = Resolutions {
        full: !coarse || (req.keep_coarse_volume && first),
        half: coarse || req.keep_coarse_volume,
    };
    let mut key = TexturesKey::new(prepared, &features, levels, view.memory_axes);
    if req.volume_layout == super::VolumeLayout::Kept {
        if let Some(axes) = cache.as_ref().and_then(|c| c.serves_but_layout(&key)) {
            view.memory_axes = axes;
            key = key.with_axes(axes);
        }
    }
    let environment = key.environment().clone();
    // The textures lay the volumes out as suits the view (`ViewSetup::memory_axes`).
    fn in_layout(v: &crate::volume::Volume, axes: [usize; 3]) -> std::borrow::Cow<'_, crate::volume::Volume> {
        if axes == [0, 1, 2] {
            std::borrow::Cow::Borrowed(v)
        } else {
            std::borrow::Cow::Owned(v.with_axes(axes))
        }
    }
    let eta_in_layout = |axes| match (&prepared.eta_volume, features.eta_volume) {
        (Some(v), true) => Some(in_layout(v.as_ref(), axes)),
        _ => None,
    };
    let mut pending = None;
    match cache.as_mut() {
        Some(c) if c.matches(&key) => {}
        Some(c) if c.matches_but_refraction(&key) => {
            // Refraction switched off, or on again where the gradient volume it reads was
            // kept: new bricks and cells, nothing copied in.
            pending = Some(c.replace_occupancy(ctx, &prepared.tf, key)?);
        }
        Some(c) if c.matches_but_tables(&key) => {
            // Another sample distance only (the viewer's levels): new tables, the rest kept.
            pending = Some(c.replace_tables(ctx, &prepared.tf, key)?);
        }
        Some(c) if c.matches_but_transfer(&key) => {
            // Other transfer functions with the same η (the editor): new tables, bricks and
            // cells; the volume images are kept.
            pending = Some(c.replace_transfer(ctx, &prepared.tf, key)?);
        }
        Some(c) if features.refraction && c.matches_but_eta(&key) => {
            // Another η (the editor): the gradient volume is made again, and the tables,
            // bricks and cells; the volume and orientation volumes are kept.
            let laid_out = in_layout(vol, view.memory_axes);
            let eta_laid_out = eta_in_layout(view.memory_axes);
            let eta_source = eta_laid_out.as_deref().map(|v| (v, v.value_range));
            pending = Some(c.replace_eta(ctx, &laid_out, (eta_source, features.gradient), &prepared.tf, key)?);
        }
        _ => {
            // The old textures go before the new are allocated, but for a staging buffer kept
            // and, where they are of the same volume laid out the same way (another data
            // window), the volume images, which the new take where they are what a new image
            // would be, and the extremes of the volume's values, which the new map through
            // their window.
            // Renders that keep the staging buffer for the next upload of volumes (the
            // viewer) make the extremes with the first upload of a volume too, so that its
            // first change of the data window maps them already.
            let fresh = || (Vec::new(), req.keep_staging.then(RawSet::default));
            let (staging, (reuse, raw)) = match cache.take() {
                Some(mut c) => {
                    let staging = c.take_staging();
                    let reuse = if c.same_volume_and_layout(&key) {
                        let (images, raw) = c.into_volume_images();
                        (images, Some(raw))
                    } else {
                        fresh()
                    };
                    (staging, reuse)
                }
                None => (None, fresh()),
            };

            let axes = view.memory_axes;
            let laid_out = in_layout(vol, axes);
            let eta_laid_out = eta_in_layout(axes);
            let eta_source = eta_laid_out.as_deref().map(|v| (v, v.value_range));
            let (textures, upload) = SceneTextures::upload(
                ctx,
                &laid_out,
                window,
                !features.sampled_layers,
                features.refraction.then_some((eta_source, features.gradient)),
                &prepared.tf,
                scene.quality.sample_distance,
                prepared.env.as_ref(),
                key.levels(),
                staging,
                reuse,
                raw,
            )?;
            *cache = Some(CachedTextures::new(key, textures, &upload));
            pending = Some(upload);
        }
    }
    if let Some(c) = cache.as_mut().filter(|_| !req.keep_staging) {
        // The staging buffer goes once its copy has executed.
        drop(c.take_staging());
    }
    if let Some(c) = cache.as_mut().filter(|c| !c.matches_environment(&environment)) {
        // Another environment map (a switch of image, or to the studio): the volumes stay.
        let env = c.replace_environment(ctx, prepared.env.as_ref(), environment)?;
        pending = Some(match pending {
            Some(p) => p.and(env),
            None => env,
        });
    }
    let upload_bytes = pending.as_ref().map_or(0, |p| p.bytes());
    let cached = cache
        .as_ref()
        .ok_or_else(|| RenderError::Setup("internal: scene textures missing".into()))?;
    // Without a grid of cells to read, every beam deposits (`deposit_read` in beams.wgsl).
    let mut deposit_cells = vec![0u32; 12];
    let (light_box, light_margin, spans) = if layout.light_lists {
        // A view sample reads the beams `back_planes` - 1 planes further back along its light
        // line than the plane before it.
        let back = (layout.back_planes - 1) as f32 * view.step / light.z.max(1e-6);
        let (every, straight) =
            light_tiles::margins(&view, &grid, scene.quality.sample_distance, features.refraction, back);
        let scale = light_tiles::texture_scale(&view);
        // The occupied cells grown by what a view sample reads and a straight beam's deposit
        // reach (`straight`).
        let grown = cached.grown(scale.map(|s| s * straight), coarse);
        // Bent beams end where the device finds they can no longer reach the box
        // (`light_alive`); the straight lines' last planes do not bound them.
        let spans = light_tiles::spans(&view, &grid, light, &grown, !features.refraction, tile);
        if features.refraction {
            // A beam deposits only where a view sample can read it: in those cells; a beam
            // whose deposit reaches further (spread by refraction) always deposits.
            if let Some(words) = cached.grown_words(scale.map(|s| s * straight), coarse) {
                deposit_cells = words.as_ref().clone();
                deposit_cells[3] = (straight - every).to_bits();
            }
        }
        ([scale[0], scale[1], scale[2], 0.0], every, spans)
    } else {
        ([0.0; 4], 0.0, vec![[NEVER, NEVER, 0, 0]; 2])
    };
    let lbm_light = match lbm {
        Some(p) => Some(super::lbm::solve_for_scene(
            ctx,
            p,
            prepared,
            &view,
            cached,
            pending.take(),
            light,
        )?),
        None => None,
    };
    let lbm_unused = super::lbm::unused(ctx)?;
    let (lbm_grid, lbm_table) = match &lbm_light {
        Some(l) => (&l.grid, &l.table),
        None => (&lbm_unused.0, &lbm_unused.1),
    };

    let params = Buffer::new_storage_from(
        ctx,
        "params",
        bytemuck::bytes_of(&make_params(
            prepared,
            &view,
            &layout,
            cached.textures.env_levels,
            cached.textures.brick_dims,
            light_box,
            light_margin,
        )),
    )?;
    let state = State::new(ctx, &view, &layout, &features, precision)?;
    let window_buffer = Buffer::new_storage_from(ctx, "light windows", bytemuck::cast_slice(&windows))?;
    let start_buffer = Buffer::new_storage_from(ctx, "light tile spans", bytemuck::cast_slice(&spans))?;
    let deposit_buffer = Buffer::new_storage_from(ctx, "deposit cells", bytemuck::cast_slice(&deposit_cells))?;
    // ω and g per data value for the spread mode (a placeholder entry pair otherwise).
    let table = if features.scatter {
        crate::transfer::scattering::scattering_table(&prepared.tf)
    } else {
        vec![[0.0; 4]; 2]
    };
    let scatter_table = Buffer::new_storage_from(ctx, "scatter table", bytemuck::cast_slice(&table))?;
    let bytes = w as u64 * h as u64 * 16;
    let mut readback = Buffer::new_readback(ctx, "output readback", bytes)?;
    // Where the light tiles stopped being stepped, for the count of their steps.
    let mut ends_readback = if layout.light_lists {
        let size = state.get("light_end")?.size;
        Some(Buffer::new_readback(ctx, "light tile ends readback", size)?)
    } else {
        None
    };
    // A timestamp at the start of each submission and at its end, and with pass timings
    // after each plane's light, view and listing passes (`RenderStats::pass_ms`).
    let ts = Timestamps::new(ctx, 2 + 3 * PLANES_PER_SUBMIT)?;

    let pipelines = sweep()?;
    // One descriptor set per shader file: the sweep's passes (sweep.wgsl) share theirs, which
    // a recorder binds once for all of them (`Recorder::dispatch`): on a CPU driver binding a
    // set hands every one of its resources to the shader again, at each dispatch.
    let (init_set, sweep_set, finish_set) = (0, 1, 2);
    let mut sets = Vec::new();
    for p in [&pipelines[0], &pipelines[1], &pipelines[4]] {
        let mut set = DescriptorSet::new(ctx, p, &p.label)?;
        let t = &cached.textures;
        let [volume_tex, gradient_tex, orientation_tex] = t.sampled(coarse);
        let mut writes = vec![
            ("params", Resource::Buffer(&params)),
            ("volume_tex", Resource::Image(volume_tex)),
            ("linear_clamp", Resource::Sampler(&t.linear_clamp)),
            ("volume_sampler", Resource::Sampler(&t.volume_sampler)),
            ("gradient_tex", Resource::Image(gradient_tex)),
            ("orientation_tex", Resource::Image(orientation_tex)),
            ("particle_table", Resource::Image(&t.particle_table)),
            ("medium_table", Resource::Image(&t.medium_table)),
            ("env_tex", Resource::Image(&t.env)),
            ("env_sampler", Resource::Sampler(&t.env_sampler)),
            ("light_window", Resource::Buffer(&window_buffer)),
            ("light_start", Resource::Buffer(&start_buffer)),
            ("deposit_cells", Resource::Buffer(&deposit_buffer)),
            ("scatter_table", Resource::Buffer(&scatter_table)),
            ("bricks", Resource::Buffer(t.occupancy_for(coarse).0)),
            ("lbm_grid", Resource::Buffer(lbm_grid)),
            ("lbm_albedo", Resource::Buffer(lbm_table)),
        ];
        for (name, buffer) in &state.buffers {
            writes.push((*name, Resource::Buffer(buffer)));
        }
        for (name, image) in &state.images {
            writes.push((*name, Resource::Image(image)));
        }
        writes.push(("light_acc_tex", Resource::Image(&state.acc_image)));
        set.write(&writes)?;
        sets.push(set);
    }

    // Everything the commands use is created above: the recorders borrow it.
    let mut rec = Recorder::new(ctx, "render: upload and init")?;
    if let Some(upload) = pending {
        cached.textures.record_upload(&mut rec, upload);
    }
    let mut images: Vec<&Image> = state.images.iter().map(|(_, i)| i).collect();
    images.push(&state.acc_image);
    rec.init_layout(&images);
    rec.fill(state.get("light_acc")?, 0);
    rec.fill(state.get("view_tiles")?, 0);
    rec.fill(state.get("tile_args")?, 0);
    rec.fill(state.get("light_end")?, NEVER);
    rec.fill(state.get("light_alive")?, 0);
    rec.fill(state.get("light_lit")?, 0);
    rec.fill(state.get("light_args")?, 0);
    let tile_args = state.get("tile_args")?;
    let light_args = state.get("light_args")?;
    // The tiles pass also lists the next plane's light tiles, one per invocation after the
    // view tiles'.
    let tile_groups = tile_groups(
        layout.view_groups,
        if layout.light_lists { layout.beam_groups } else { 0 },
        tile,
    );
    let finish_groups = [w.div_ceil(Pass::FINISH_TILE), h.div_ceil(Pass::FINISH_TILE), 1];
    // Beams that deposit their light (refraction, the spread mode) fill a ring of slots, one
    // per plane: each is cleared before the plane that deposits into it.
    let light_acc = state.get("light_acc")?;
    let deposit_slot_bytes = deposit_ring(&features).then_some(layout.deposits.slot_bytes(layout.channels));
    let texels_per_plane = (layout.grid.count() + view.rect.width() as u64 * view.rect.height() as u64).max(1);
    let planes_per_submit = (TEXELS_PER_SUBMIT / texels_per_plane).clamp(1, PLANES_PER_SUBMIT as u64) as u32;
    let push = |plane: u32, view_steps: u32, view_list: u32| Immediates {
        plane_index: plane,
        seed: 0x9e37_79b9,
        view_steps,
        view_list,
    };
    rec.dispatch(
        &pipelines[0],
        &sets[init_set],
        bytemuck::bytes_of(&push(0, 0, 0)),
        groups(layout.beam_groups + layout.view_groups),
    )?;
    rec.compute_to_compute();
    // Dispatch k moves the light to plane k and the view rays to plane k-1: the image needs
    // one dispatch more than there are planes, the light diagnostics stop at their plane.
    let dispatches = if req.debug_view == DebugView::Image || req.debug_view == DebugView::Medium {
        planes_run
    } else {
        planes_run - 1
    };
    let bar = progress_bar(req.progress, dispatches as u64);
    if let Some(p) = &req.sweep_progress {
        p.set(0, dispatches);
    }
    let mut gpu_ms = lbm_light.as_ref().map_or(0.0, |l| l.stats.gpu_ms);
    let mut pass_ms = [0.0; 4];
    // Dispatch k's view pass, if it has one, advances the rays to plane k-1 from the plane the
    // pass before left them on: the first two one plane each, then `view_planes` at a time,
    // the last whatever is left.
    let view_pass = |k: u32| k <= 2 || (k - 2) % layout.view_planes == 0 || k == dispatches;
    let next_view_pass = |k: u32| (k + 1..=dispatches).find(|&j| view_pass(j));
    let mut view_passes = 0u32;
    let mut light_passes = 0u32;
    let mut recorded = 0u32;
    let mut last_view = 0u32;
    let mut plane = 1u32;
    let mut rec = Some(rec);
    let chunk = if req.cancel.is_some() {
        (PIXEL_PLANES_PER_SUBMIT_CANCELLABLE as u64 / texels_per_plane).clamp(1, 8) as u32
    } else {
        planes_per_submit
    };
    loop {
        if req
            .cancel
            .as_ref()
            .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
        {
            return Err(RenderError::Cancelled);
        }
        let mut r = match rec.take() {
            Some(r) => r,
            None => Recorder::new(ctx, "render: planes")?,
        };
        r.reset_timestamps(&ts);
        r.timestamp(&ts, 0);
        let mut stamps = 1;
        let end = (plane + chunk).min(dispatches + 1);
        while plane < end {
            let light_push = push(plane, 0, 0);
            let p = bytemuck::bytes_of(&light_push);
            let window = windows[plane as usize][3];
            if plane < view.planes && layout.light_groups {
                // The planes up to the next view pass in one dispatch, from the first after
                // the last pass (the edge pass's entry point, list 0 of the pass's parity).
                if plane == last_view + 1 {
                    let group_end = next_view_pass(plane - 1).unwrap_or(dispatches);
                    let last = group_end.min(view.planes - 1);
                    let g = push(plane, last + 1 - plane, view_passes);
                    let offset = light_list_slot(view_passes % 2, 0, 0) * 12;
                    r.dispatch_indirect(
                        &pipelines[6],
                        &sets[sweep_set],
                        bytemuck::bytes_of(&g),
                        light_args,
                        offset,
                    )?;
                    light_passes += 1;
                }
            } else if plane < view.planes && layout.light_lists {
                // The listed tiles, then those at the edge of the stepped ones: the lists of
                // this plane of the view pass, written after the pass before.
                let in_pass = plane - last_view - 1;
                let lp = push(plane, in_pass, view_passes);
                for (list, pass) in [(0, 5), (1, 6)] {
                    let offset = light_list_slot(view_passes % 2, in_pass, list) * 12;
                    r.dispatch_indirect(
                        &pipelines[pass],
                        &sets[sweep_set],
                        bytemuck::bytes_of(&lp),
                        light_args,
                        offset,
                    )?;
                }
                light_passes += 1;
            } else if plane < view.planes && window > 0 {
                r.dispatch(&pipelines[1], &sets[sweep_set], p, groups(window))?;
                light_passes += 1;
            }
            pass_stamp(&mut r, &ts, &mut stamps, req.pass_timings);
            let view_now = !diagnoses_light && view_pass(plane);
            if view_now {
                let v = push(plane, plane - last_view, view_passes);
                let p = bytemuck::bytes_of(&v);
                if plane >= 2 && layout.lists {
                    let offset = (view_passes as u64 % LIGHT_RING) * 12;
                    r.dispatch_indirect(&pipelines[2], &sets[sweep_set], p, tile_args, offset)?;
                } else {
                    r.dispatch(&pipelines[2], &sets[sweep_set], p, groups(layout.view_groups))?;
                }
            }
            pass_stamp(&mut r, &ts, &mut stamps, req.pass_timings);
            // Clears the ring for the next plane's deposits and, after a view pass, lists the
            // next one's view tiles and the light tiles of its planes, from this plane's beams:
            // the tiles pass ends the light tiles that end and, for a single plane, lists the
            // others; for several, a second pass lists them per plane (it reads the
            // neighbours' ends). With light groups one list takes all the planes.
            let next_steps = match (view_now, next_view_pass(plane)) {
                (true, Some(next)) => next - plane,
                _ => 0,
            };
            let lists_light = layout.light_lists && next_steps > 0;
            if next_steps > 0 && (lists_light || features.refraction) {
                // The light tiles read the plane's light; the view tiles its rays' bends.
                r.compute_to_compute();
            }
            if next_steps > 0 {
                let t = push(plane, next_steps, view_passes);
                r.dispatch(
                    &pipelines[3],
                    &sets[sweep_set],
                    bytemuck::bytes_of(&t),
                    groups(tile_groups),
                )?;
            }
            if lists_light && !layout.light_groups && next_steps > 1 {
                r.compute_to_compute();
                let t = push(plane, next_steps, view_passes);
                let light_tile_groups = layout.beam_groups.div_ceil(tile * tile);
                r.dispatch(
                    &pipelines[1],
                    &sets[sweep_set],
                    bytemuck::bytes_of(&t),
                    groups(light_tile_groups),
                )?;
            }
            if view_now {
                view_passes += 1;
                last_view = plane;
            }
            if let Some(bytes) = deposit_slot_bytes {
                // Plane j deposits into the slot plane j-S used (S slots: the view planes and
                // two more), whose last reader was a view dispatch before it (which reads at
                // most `view_planes` planes back from j-1). After a view pass, the slots of the
                // next one's planes (their last reader was this pass or one before), in one or
                // two fills; without view passes (the light views) plane k+1's.
                let planes = if diagnoses_light { 1 } else { next_steps as u64 };
                let slots = layout.deposit_slots as u64;
                let mut j = plane as u64 + 1;
                while j <= plane as u64 + planes {
                    let slot = j % slots;
                    let n = (planes - (j - plane as u64 - 1)).min(slots - slot);
                    r.fill_range(light_acc, slot * bytes, n * bytes, 0)?;
                    j += n;
                }
            }
            r.compute_to_indirect();
            pass_stamp(&mut r, &ts, &mut stamps, req.pass_timings);
            plane += 1;
        }
        let last = plane > dispatches;
        if last {
            r.dispatch(
                &pipelines[4],
                &sets[finish_set],
                bytemuck::bytes_of(&push(planes_run - 1, 0, 0)),
                finish_groups,
            )?;
            r.compute_to_transfer();
            r.copy_buffer(state.get("image_out")?, &mut readback, bytes);
            if let Some(readback) = ends_readback.as_mut() {
                let ends = state.get("light_end")?;
                r.copy_buffer(ends, readback, ends.size);
            }
        }
        r.timestamp(&ts, stamps);
        stamps += 1;
        recorded += r.dispatches();
        r.submit_and_wait()?;
        cached.uploaded();
        // With pass timings: light, view and listing per plane, then the finish pass: the last
        // interval (nothing before the last submission's end). Else the submission whole.
        let intervals = ts.read_first_ms(stamps)?;
        let finish = intervals.len() - 1;
        for (i, ms) in intervals.iter().enumerate() {
            if req.pass_timings {
                let pass = if i == finish { 3 } else { i % 3 };
                pass_ms[pass] += ms;
            }
            gpu_ms += ms;
        }
        if let Some(b) = &bar {
            b.set_position((plane - 1) as u64);
        }
        if let Some(p) = &req.sweep_progress {
            p.set(plane - 1, dispatches);
        }
        if last {
            if let Some(b) = bar {
                b.finish_and_clear();
            }
            let light_steps = match &ends_readback {
                Some(b) => {
                    let e: Vec<u32> = bytemuck::pod_collect_to_vec(b.read()?);
                    Some(tile_steps(&spans, &e, view.planes))
                }
                None => None,
            };
            let bytes = readback.read()?;
            let pixels: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(bytes);
            return Ok(RenderOutput {
                image: RenderedImage {
                    width: w,
                    height: h,
                    pixels,
                },
                stats: RenderStats {
                    features,
                    planes: view.planes,
                    planes_run,
                    gpu_ms,
                    pass_ms,
                    ms_per_plane: (gpu_ms - lbm_light.as_ref().map_or(0.0, |l| l.stats.gpu_ms))
                        / planes_run.max(1) as f64,
                    state_bytes: state.bytes,
                    upload_bytes,
                    light_grid: [layout.grid.width, layout.grid.height],
                    light_cell_pixels: layout.grid.stride,
                    view_passes,
                    view_planes: layout.view_planes,
                    light_passes,
                    dispatches: recorded,
                    light_steps,
                    tile: layout.tile,
                    rect: [view.rect.width(), view.rect.height()],
                    precision,
                    reductions: Vec::new(),
                    lbm: lbm_light.as_ref().map(|l| Box::new(l.stats.clone())),
                    volume_axes: (view.memory_axes != [0, 1, 2]).then_some(view.memory_axes.map(|a| a as u8)),
                    // Memory figures are filled in by `Renderer::render`.
                    ..RenderStats::default()
                },
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::view::PixelRect;

    #[test]
    fn pyramid_levels_match_the_shader() {
        for line in [
            format!("const ACC_LEVELS: u32 = {}u;", super::ACC_LEVELS),
            format!("const SCATTER_LEVELS: u32 = {}u;", super::SCATTER_LEVELS),
        ] {
            assert!(
                crate::render::shaders::BEAMS.contains(&line),
                "beams.wgsl lacks '{line}'"
            );
        }
    }

    fn rect(x0: u32, y0: u32, x1: u32, y1: u32) -> PixelRect {
        PixelRect { x0, y0, x1, y1 }
    }

    #[test]
    fn a_pyramid_plane_is_a_third_larger_than_the_rect() {
        // 64² + 32² + 16² texels.
        assert_eq!(
            super::pyramid_texels(&PixelRect::frame(64, 64), super::ACC_LEVELS),
            4096 + 1024 + 256
        );
        assert_eq!(
            super::pyramid_texels(&PixelRect::frame(5, 3), super::ACC_LEVELS),
            15 + 6 + 2
        );
        // A rect away from the corner: a level holds the texels that meet it, which may be one
        // more per axis than its side halved. Pixels 3..8 × 2..3: texels 1..3 × 1..1 of level
        // 1, 0..1 × 0..0 of level 2.
        assert_eq!(super::pyramid_texels(&rect(3, 2, 8, 3), super::ACC_LEVELS), 5 + 3 + 2);
        // The CT head in the viewer's portrait viewport (644×580 of 644×768): about a quarter
        // fewer texels than the frame's.
        let frame = super::pyramid_texels(&PixelRect::frame(644, 768), super::ACC_LEVELS);
        let head = super::pyramid_texels(&rect(0, 94, 644, 674), super::ACC_LEVELS);
        assert!(head * 100 < frame * 76, "{head} of {frame}");
    }

    #[test]
    fn the_deposit_atlas_holds_the_levels_side_by_side() {
        // Level 0 (64²) beside a column of 32² over 16².
        assert_eq!(
            super::atlas_size(&PixelRect::frame(64, 64), super::ACC_LEVELS),
            (96, 64)
        );
        // Odd sides round up: 5×3, then 3×2 over 2×1; the column (3 rows) is as tall as
        // level 0.
        assert_eq!(super::atlas_size(&PixelRect::frame(5, 3), super::ACC_LEVELS), (8, 3));
        // Seven levels of 1×1 stack six rows beside a one-row level 0.
        assert_eq!(
            super::atlas_size(&PixelRect::frame(1, 1), super::SCATTER_LEVELS),
            (2, 6)
        );
        // Every level fits (the shader's `level_origin`): level 0 and the column's rows, each
        // no wider than level 1; and a rect's atlas fits in its frame's (`deposit_image`
        // checks the frame's before the rect is known).
        let rects = [
            (64, 64, rect(0, 0, 64, 64)),
            (643, 769, rect(0, 0, 643, 769)),
            (643, 769, rect(1, 95, 642, 674)),
            (100, 7, rect(3, 1, 99, 6)),
            (1, 1, rect(0, 0, 1, 1)),
            (9, 9, rect(4, 4, 4, 4)),
        ];
        for (w, h, r) in rects {
            for levels in [super::ACC_LEVELS, super::SCATTER_LEVELS] {
                let (aw, ah) = super::atlas_size(&r, levels);
                let (w0, h0) = super::level_dims(&r, 0);
                let w1 = super::level_dims(&r, 1).0;
                let rows: u32 = (1..levels).map(|m| super::level_dims(&r, m).1).sum();
                assert!(rows <= ah && h0 <= ah && w0 + w1 == aw);
                assert!((1..levels).all(|m| super::level_dims(&r, m).0 <= w1));
                // Each level holds every texel that meets the rect.
                for m in 0..levels {
                    let (lw, lh) = super::level_dims(&r, m);
                    if r.x1 > r.x0 {
                        assert_eq!((r.x0 >> m) + lw - 1, (r.x1 - 1) >> m);
                        assert_eq!((r.y0 >> m) + lh - 1, (r.y1 - 1) >> m);
                    }
                }
                // So it has room for every texel of the pyramid.
                assert!(aw as u64 * ah as u64 >= super::pyramid_texels(&r, levels));
                let (fw, fh) = super::atlas_size(&PixelRect::frame(w, h), levels);
                assert!(aw <= fw && ah <= fh, "{aw}×{ah} beyond {fw}×{fh}");
            }
        }
    }

    #[test]
    fn the_beams_rows_hold_every_slot_within_the_devices_sides() {
        let max = 16384;
        for (slots, tile, texels) in [
            (16u64, 4u32, 2u32),
            (97 * 85 * 16, 4, 2),
            (97 * 85 * 16, 4, 11),
            (137 * 120 * 64, 8, 18),
            (512 * 512 * 16, 4, 2),
            (400 * 400 * 16, 4, 18),
        ] {
            let shift = super::beam_rows(slots, tile, texels, max).expect("a layout fits");
            let (row, rows) = (1u64 << shift, slots.div_ceil(1 << shift));
            // Every slot has a texel, a row holds a whole tile, and both sides fit the device
            // once they are kept off powers of two.
            assert!(rows * row >= slots && row >= (tile * tile) as u64);
            let width = (texels as u64 * row) as u32;
            assert!(super::image_side(width, max) <= max && super::image_side(rows as u32, max) <= max);
            // Unused slots only in the last row, which is short against all of them: at most
            // twice the square root, unless the device's sides ask for longer rows.
            let unused = rows * row - slots;
            assert!(unused < row, "{slots} {tile} {texels}");
            let shorter_fits =
                super::image_side(slots.div_ceil(row / 2) as u32, max) <= max && slots.div_ceil(row / 2) <= max as u64;
            assert!(
                row * row <= 4 * slots || row == (tile * tile) as u64 || !shorter_fits,
                "{slots} {tile} {texels}"
            );
        }
        // A row of one tile's records wider than the device allows: no layout (pairs instead).
        assert_eq!(super::beam_rows(1 << 20, 8, 300, 16384), None);
        // Too many slots for any row and column of the device's sides.
        assert_eq!(super::beam_rows(1 << 30, 4, 2, 16384), None);
    }

    #[test]
    fn state_image_sides_are_never_powers_of_two() {
        // Each side holds its texels and is the smallest that is not a power of two, up to the
        // device's largest side, which stays as it is.
        let max = 16384;
        for n in (0..=4100u32).chain(16370..=max) {
            let side = super::image_side(n, max);
            assert!(side >= n.max(1) && side <= max.max(n), "{n} -> {side}");
            assert!(!side.is_power_of_two() || side == max, "{n} -> {side}");
            assert!((n.max(1)..side).all(|m| m.is_power_of_two()), "{n} -> {side}");
        }
        assert_eq!(
            (
                super::image_side(64, max),
                super::image_side(65, max),
                super::image_side(1, max)
            ),
            (65, 65, 3)
        );
        assert_eq!(super::image_side(max, max), max);
    }
}
