// Shared declarations of every caustica pass: parameters, bindings, feature switches and
// helpers. Prepended to each pass file before compilation.
//
// Coordinates: "view space" has the camera at the origin, x right, y down, z forward (depth).
// Plane i lies at z = plane.x + i * plane.y. Pixel (u, v) of plane i is the point where the
// straight primary ray through the pixel's centre meets that plane; continuous pixel
// coordinates `t` have the centre of pixel u at t = u (see `unproject` / `project`).

// Feature switches, resolved by naga before SPIR-V is written (one pipeline per combination).
override REFRACTION: bool = true;           // η varies: bend light and view rays
override MEDIUM: bool = true;               // medium colour is not white: coloured light and M per view ray
override LIGHT_FILTER: bool = true;         // soft light (a cone source)
override INTENSITY_CORRECTION: bool = true; // backward transport: intensity law S_{i-1}/S_i (caustics)
override SPECULAR: bool = true;             // Cook–Torrance highlight at index changes
override CLIP: bool = false;                // clip plane zeroes opacity
override ORTHOGRAPHIC: bool = false;
override BEAMS: bool = true;                // light transport: forward beams (true) or backward lookups
override F32_STATE: bool = false;           // light, colour and medium state in 32-bit floats
override DEBUG_VIEW: u32 = 0u;              // 0 image, 1 light, 2 light direction, 3 concentration, 4 medium
override SCATTER: bool = false;             // multiple scattering, spread mode (beams without refraction)
override ACC_IMAGE: bool = false;           // the deposited light is read through light_acc_tex
override SAMPLED_LAYERS: bool = false;      // no orientation volume: the layers' gradient from six samples
// Safeguards switched off, one bit each (SG_* below). Always 0 in renders; tests set single
// bits to show that each safeguard is needed. Constant-folded like the features above.
override SAFEGUARDS_OFF: u32 = 0u;

// Every clamp and epsilon of the shaders has a bit here (see README, "Numerical safeguards").
const SG_LIGHT_MIN_Z: u32 = 1u;          // light directions keep z >= MIN_LIGHT_DIR_Z
const SG_VIEW_MIN_Z: u32 = 2u;           // view rays leave the sweep below MIN_VIEW_DIR_Z
const SG_INTENSITY_RATIO: u32 = 4u;      // backward: per-plane clamp of the intensity-law ratio
const SG_CONCENTRATION: u32 = 8u;        // light never exceeds max_concentration × the source
const SG_FOLD: u32 = 16u;                // backward: no further concentration where the map folds
const SG_MAX_RADIANCE: u32 = 64u;        // accumulated colour <= MAX_RADIANCE
const SG_FRESNEL_STEP: u32 = 128u;       // FRESNEL_MIN_RELATIVE_STEP
const SG_GGX_ALPHA: u32 = 256u;          // MIN_GGX_ALPHA
const SG_SEGMENT_OPACITY: u32 = 512u;    // MIN_SEGMENT_OPACITY
const SG_GRADIENT_LENGTH: u32 = 1024u;   // MIN_GRADIENT_LENGTH
const SG_DIRECTION_LENGTH: u32 = 2048u;  // MIN_DIRECTION_LENGTH
const SG_SATURATION: u32 = 4096u;        // beams: accumulated light stops at ACC_SATURATED

// Invocations per side of the square tiles of pixels and light-grid cells that workgroups
// work on, and that are listed, skipped and ended as one (`Pass::TILE` and `Pass::CPU_TILE`
// in render/shaders.rs: the render picks one).
override TILE: u32 = 8u;

// Planes back along its light line from which a view sample reads the beams' power: those in
// a voxel at the render's sample distance, 1 to 8 (`Specialisation` in state.rs). A constant, so
// that the loops over them have a fixed count: a CPU driver runs a loop whose count is only
// known when the shader runs as a loop (the plain view pass was a sixth slower with one
// segment counted that way), and one it can unroll as straight code.
override BACK_PLANES: u32 = 1u;

// The listed light tiles are stepped over a view pass's planes in one dispatch (`light_groups`
// in beams.wgsl; `Specialisation` in state.rs). A constant rather than a flag of the
// parameters: a CPU driver runs both sides of a branch a workgroup takes, and the edge light
// pass's one-plane step beside the groups' took a ninth of a plain frame's light.
override LIGHT_GROUPS: bool = false;

// The light tiles each plane steps are listed on the device (`light_tiles_listed` in
// beams.wgsl): the light pass's entry point then lists them instead of stepping the light
// window's, which it would otherwise also run, masked, in every listing.
override LIGHT_LISTS: bool = false;

// The soft light's tiles next to tiles not started yet or ended are stepped at the edge
// instead of from the plane's half of the state (`halves_hold_state` in beams.wgsl): the same
// light, for the tests that compare the two. A constant, as LIGHT_GROUPS is.
override LIGHT_EDGE_STEPS: bool = false;

fn guarded(bit: u32) -> bool {
    return (SAFEGUARDS_OFF & bit) == 0u;
}

// Below this length a direction vector counts as zero and is not normalised (0/0 = NaN).
const MIN_DIRECTION_LENGTH: f32 = 1e-12;
// Segments whose reference opacity is below this are rescaled linearly in length: the ratio
// of the two opacities would be 0/0 for a fully transparent segment.
const MIN_SEGMENT_OPACITY: f32 = 1e-6;
// Index changes per voxel below this give no surface normal, so no highlight and no
// renormalisation of the ray direction: normalising them would divide by zero. Per voxel, not
// per view unit, so that the image does not depend on the unit of length.
const MIN_GRADIENT_LENGTH: f32 = 1e-6;

// Whether ∇η (per view unit) is long enough to have a direction (MIN_GRADIENT_LENGTH).
fn has_normal(grad_length: f32) -> bool {
    let voxel = P.plane.y / P.plane.w; // one voxel (the smallest spacing) in view units
    return grad_length * voxel > MIN_GRADIENT_LENGTH;
}
// Largest accumulated radiance in the colour buffer: a quarter of the 16-bit float maximum
// (65504), so that the final blend with the environment cannot overflow in f16 either.
// Reached only by sums of sharp highlights (roughness near 0 at many index steps).
const MAX_RADIANCE: f32 = 16384.0;
// Floor of the tracked concentration (backward transport): ratios below 1 (light spreading
// out) shrink it by up to max_intensity_ratio per plane, and it must not underflow to 0
// before the budget divides by it.
const MIN_CONCENTRATION: f32 = 1e-6;

fn safe_normalize(v: vec3<f32>) -> vec3<f32> {
    if (guarded(SG_DIRECTION_LENGTH)) {
        return v / max(length(v), MIN_DIRECTION_LENGTH);
    }
    return v / length(v);
}

struct Params {
    volume_from_view: mat4x4<f32>,   // view-space point -> volume texture coordinates [0,1]^3
    gradient_to_view: mat4x4<f32>,   // gradient texture (η per volume texel) -> η per view unit
    world_from_view: mat4x4<f32>,    // rotation only: view direction -> environment direction
    clip_plane: vec4<f32>,           // view space; opacity is zero where dot(xyz, p) + w > 0
    projection: vec4<f32>,           // fx, fy, cx, cy (pixels); ortho: pixel = f * p + c
    plane: vec4<f32>,                // z of plane 0, Δs (view units), plane count, Δs in voxels
    light_dir: vec4<f32>,            // initial propagation direction (unit, z > 0); w: softness (tan of the cone's half-angle)
    light_color: vec4<f32>,          // rgb radiance of the light; w: max intensity ratio per plane (backward)
    shading: vec4<f32>,              // specular intensity, roughness, termination opacity, environment intensity
    size: vec4<f32>,                 // width, height, 1/width, 1/height
    texel: vec4<f32>,                // 1 / volume dims (xyz), η outside the volume (w)
    background: vec4<f32>,           // rgb background when there is no environment map; w: 1 = use env map
    limits: vec4<f32>,               // min light dir z, min view dir z, max light value, env map mip count
    budget: vec4<f32>,               // x: max concentration (light / source light); y: interface half-width (view units); z: light tiles' margin around the box (view units); w: 1 when the value outside the volume is clear
    beam_origin: vec4<f32>,          // beams: plane-0 pixel coords of cell (0, 0)'s corner (xy), stride (z), plane-0 cell area / pixel area (w)
    beam_grid: vec4<u32>,            // light grid: width, height, tiles in x, workgroups
    rect: vec4<u32>,                 // pixels whose rays can meet the volume: x0, y0, x1, y1 (half-open)
    tiles: vec4<u32>,                // view tiles in x, view workgroups, workgroups per dispatch row (all passes), light channels
    culling: vec4<u32>,              // bricks along x, y, z; bits: view tiles listed per plane (1), light tiles unseen end (2), empty view tiles skipped (4)
    light_box: vec4<f32>,            // beams: texture units per view unit along each axis at most (xyz); w unused (LIGHT_LISTS)
    sweep: vec4<u32>,                // planes of the beams' front power kept (x), regions of a beam's power record (y; 0: in pairs), slots of deposited light (z), with refraction log2 of the beams' slots per image row (w, `beam_slot`)
    deposits: vec4<u32>,             // atlas of deposited light: words per row (x), per layer (y: a channel of a slot); zw unused
}

struct Immediates {
    plane_index: u32,
    seed: u32,
    // View pass: the planes its rays advance (dispatches plane_index - view_steps + 1 ..=
    // plane_index); tiles pass: those of the next view pass (0: it lists no view tiles).
    view_steps: u32,
    // The view pass's number in the sweep: it reads list view_list % 3 of `tile_lists`, the
    // tiles pass after it writes the next.
    view_list: u32,
}

// Params is a read-only storage buffer, not a uniform buffer: lavapipe specialises a shader on
// the values of uniforms that decide branches ("uniform inlining") and compiles a new variant
// whenever a uniform or push-constant buffer is bound again, which cost ~3 ms per plane.
// Storage-buffer loads are never inlined. For the same reason no branch may depend on the
// push constants alone (see `dispatch_plane`).
@group(0) @binding(0) var<storage, read> params: Params;
// Every entry point copies `params` into P before anything else (`P = params;`) and the rest
// of the code reads P. A CPU driver loads a storage buffer once for all invocations only
// where no branch or loop encloses the load; inside one it loads it invocation by invocation,
// with a bounds check each time, and the parameters are read inside branches everywhere
// (a matrix per volume lookup). The copy at the top of the entry point is one load per field;
// on lavapipe it took 40 % off a full-effects frame of the CT head, with the same bits.
var<private> P: Params;
@group(0) @binding(1) var volume_tex: texture_3d<f32>;
@group(0) @binding(2) var linear_clamp: sampler;      // clamp-to-edge, tables
@group(0) @binding(3) var volume_sampler: sampler;    // clamp-to-border (0 outside)
// ∇η (xyz, η per volume texel, central differences of η_tf applied per voxel) and η − η
// outside the volume (w), so that the zero border is the ambient medium.
@group(0) @binding(4) var gradient_tex: texture_3d<f32>;
// The value's gradient per volume texel (central differences over the interface half-width
// along the volume's axes, per voxel, in units of 1/32767; w 0): the view's layers
// (`layer_ratio`).
@group(0) @binding(7) var orientation_tex: texture_3d<f32>;
@group(0) @binding(5) var particle_table: texture_2d<f32>;   // rgb: premultiplied colour, a: τ_α
@group(0) @binding(6) var medium_table: texture_2d<f32>;     // rgb: τ_m, a: τ_α
@group(0) @binding(8) var env_tex: texture_2d<f32>;
@group(0) @binding(9) var env_sampler: sampler;

// View rays, a texel per pixel, updated in place; images rather than buffers for the reason
// given at `beam_state`. `view_rays`: layer VIEW_AUX v.z, the data value, the plane the ray is
// on plus one (0 once ended), η; layer VIEW_RAY with refraction x, y on the plane, v.x, v.y.
// `view_shade`: the composited colour and opacity (VIEW_COLOR), the light at the ray's
// position, the front end of its next segment (VIEW_LIGHT), with the medium its rgb
// transmittance (VIEW_MEDIUM); f16 rgba in one layer each, or with F32_STATE f32 in two.
@group(0) @binding(10) var view_rays: texture_storage_2d_array<rgba32float, read_write>;
@group(0) @binding(12) var view_shade: texture_storage_2d_array<rg32uint, read_write>;
const VIEW_AUX: i32 = 0;
const VIEW_RAY: i32 = 1;
const VIEW_COLOR: u32 = 0u;
const VIEW_LIGHT: u32 = 1u;
const VIEW_MEDIUM: u32 = 2u;

// Forward beams: two texels per beam of the beam_grid.x × beam_grid.y grid at its slot
// (`beam_slot`), one per half (plane parity), side by side (`beam_pair_texel`): layer 0
// holds v.z, the data value, the shadow depth and the plane stored on (`BEAM_AUX`), layer 1
// with refraction x, y on the plane and v.x, v.y (`BEAM_POS`). Where the halves hold every
// beam's state (`power_in_aux`), the aux texel's first and last words hold the beam's f16
// power instead of v.z and the plane (`aux_power_words`). An image, not a buffer: a CPU driver
// fetches texels for all invocations at once, while it loads a storage buffer inside a
// branch invocation by invocation and component by component (the neighbours' records are
// read inside one).
@group(0) @binding(14) var beam_state: texture_storage_2d_array<rgba32float, read_write>;
// Beam ij's slot in the beams' images (x: the slot in its row, y: the row). With refraction
// the TILE × TILE beams of a light tile one after another, row by row, and the tiles in order,
// row by row over the grid, 2^P.sweep.w slots to an image row (`Layout::beam_row_shift` in
// state.rs): a workgroup steps a tile, so its loads and stores run through whole cache lines,
// one after another from tile to tile. With the grid's rows as the image's, a tile's beams lie
// in TILE rows a row pitch apart, and on a CPU driver the refracted light pass took 1–11 %
// longer (pairs of renders of the CT head at 256² and 512²). Without refraction the grid's
// rows are the image's: there the light pass is no faster in tile order, while the view's
// bilinear reads of the power, four slots a sample, cost 2.6 % more instructions.
fn beam_slot(ij: vec2<u32>) -> vec2<u32> {
    if (!REFRACTION) {
        return ij;
    }
    let tile = ij / TILE;
    let inner = ij % TILE;
    let s = ((tile.y * P.beam_grid.z + tile.x) * TILE + inner.y) * TILE + inner.x;
    return vec2<u32>(s & ((1u << P.sweep.w) - 1u), s >> P.sweep.w);
}

// The texel of beam ij in `beam_state`, `beam_power` and `beam_scatter` for `half` (0 or 1)
// of a pair of halves or regions: the two side by side along x. A step reads a beam's texel
// of one half and writes the other's, which then shares its cache line: the read has just
// brought the line in. In separate layers, megabytes apart, the store found a line last
// touched two planes before, and on a CPU driver, which stores lane by lane, those misses
// took a tenth of the refracted light pass.
fn beam_pair_texel(ij: vec2<u32>, half: u32) -> vec2<i32> {
    let s = beam_slot(ij);
    return vec2<i32>(vec2<u32>(2u * s.x + half, s.y));
}
// The beams' rgb power (relative to a plane-0 cell) by region (`load_beam_power`): regions 0
// and 1 the halves, from 2 on the power before the segment to a plane (`front_power_region`);
// a record of them per beam, or in pairs (`beam_power_texel`).
@group(0) @binding(16) var beam_power: texture_storage_2d_array<rg32uint, read_write>;
// Light deposited on the planes in turn (fixed point, see `ACC_SCALE`; `acc_level`).
@group(0) @binding(17) var<storage, read_write> light_acc: array<atomic<u32>>;
// With `ACC_IMAGE`: the same memory as `light_acc`, a linear image whose layers are its
// slots' channels, which the view reads (a 1×1 placeholder otherwise).
@group(0) @binding(35) var light_acc_tex: texture_storage_2d_array<r32uint, read>;

// Backward transport: a ring of three planes of light (rgb; w: shadow depth) and directions
// (v = η·direction; w: concentration).
@group(0) @binding(18) var<storage, read_write> back_light: array<u32>;
@group(0) @binding(19) var<storage, read_write> back_dir: array<vec4<f32>>;

@group(0) @binding(20) var<storage, read_write> image_out: array<vec4<f32>>;
// Per plane: the tiles of the light grid that can still reach the image (origin tile x, y,
// tiles per row, workgroups), computed on the CPU.
@group(0) @binding(21) var<storage, read> light_window: array<vec4<u32>>;
// Empty-space skipping (render/bricks.rs): per 8³ brick, 1 if anything in it absorbs or shows
// or, with refraction, η changes in it.
@group(0) @binding(22) var<storage, read> bricks: array<u32>;
// Per tile of the rect: view rays still alive (and VIEW_TILE_BENT).
@group(0) @binding(23) var<storage, read_write> view_tiles: array<atomic<u32>>;
// Set in a view tile's count once one of its rays has been bent (or started in a medium): its
// rays may then be anywhere, so the tile is stepped on every plane while any is alive.
const VIEW_TILE_BENT: u32 = 0x80000000u;
// A ring of three lists of the view tiles a plane needs, and their indirect dispatch
// arguments (x, y, z; x counts the tiles).
@group(0) @binding(24) var<storage, read_write> tile_lists: array<u32>;
@group(0) @binding(25) var<storage, read_write> tile_args: array<atomic<u32>>;
// Spread mode (SCATTER): per data value (the pre-integration tables' lattice) the albedo ω
// and the anisotropy g; per beam and half of the ping-pong pair, side by side
// (`beam_pair_texel`), SCATTER_LAYERS texels in layers 0 to 4 (beams.wgsl): the scattered
// power (rgb) and the lag of all its light behind the beam (s − E[z], view units); the spread
// moments (1 − P₂, C, R; `transfer::scattering::SpreadMoments`) and the scattering optical
// depth along its path; the state of the face its light entered by (`spread_entry`); two of
// the fourth moment.
@group(0) @binding(26) var<storage, read> scatter_table: array<vec4<f32>>;
@group(0) @binding(27) var beam_scatter: texture_storage_2d_array<rgba32float, read_write>;

// Beams with light tiles listed per plane (`light_tiles_listed`), per tile of the light grid:
// computed on the CPU (`light_tiles::spans`), the first plane on which one of its beams,
// carried straight, is within the margin of a cell where the light can change (x; NEVER if
// none), the smallest of those over it and its eight neighbours (y: the plane from which it is
// stepped) and, without refraction, the last plane on which one of its beams is within that
// margin (z; 0 with refraction); the plane from which it is no longer stepped (NEVER while it
// is); with refraction, the last plane on which one of its bent beams could still come within
// the margin of the volume's box; per parity of a view pass and plane of it two lists of the
// tiles the plane steps (LIGHT_LISTED and LIGHT_EDGE in beams.wgsl, `light_list_slot`), and
// their indirect dispatch arguments (x, y, z; x counts the tiles).
@group(0) @binding(28) var<storage, read> light_start: array<vec4<u32>>;
@group(0) @binding(29) var<storage, read_write> light_end: array<atomic<u32>>;
@group(0) @binding(30) var<storage, read_write> light_alive: array<atomic<u32>>;
@group(0) @binding(31) var<storage, read_write> light_lists: array<u32>;
@group(0) @binding(32) var<storage, read_write> light_args: array<atomic<u32>>;
// Beams with refraction and light tiles listed (`occupancy::Grown::words`): the cells within
// the view's reading margin and a straight beam's deposit reach of a cell where the light can
// change, where the beams deposit. A header (cells along x, y, z; that deposit reach in view
// units as f32 bits; the padding before cell 0; cells per texture unit as f32 bits) and one
// word per cell; cells along x 0: every beam deposits.
@group(0) @binding(33) var<storage, read> deposit_cells: array<u32>;
// Its header, copied by the light passes' entry points (`copy_deposit_header`, as `P`): word
// by word, not in a loop, whose body would be control flow around the loads again.
var<private> deposit_header: array<u32, 12>;

fn copy_deposit_header() {
    deposit_header[0] = deposit_cells[0];
    deposit_header[1] = deposit_cells[1];
    deposit_header[2] = deposit_cells[2];
    deposit_header[3] = deposit_cells[3];
    deposit_header[4] = deposit_cells[4];
    deposit_header[5] = deposit_cells[5];
    deposit_header[6] = deposit_cells[6];
    deposit_header[8] = deposit_cells[8];
    deposit_header[9] = deposit_cells[9];
    deposit_header[10] = deposit_cells[10];
}
// Beams whose light only falls (`dark_tiles_end` in beams.wgsl), per tile of the light grid:
// the last plane on which one of its beams carried light.
@group(0) @binding(34) var<storage, read_write> light_lit: array<atomic<u32>>;

var<immediate> I: Immediates;

// The plane of this dispatch. The push constant passes through the workgroup id (z is always
// 0) so that no branch depends on a push constant alone (see the note on `P`).
fn dispatch_plane(wg: vec3<u32>) -> u32 {
    return I.plane_index + wg.z;
}

fn load_view_aux(px: vec2<u32>) -> vec4<f32> {
    return textureLoad(view_rays, vec2<i32>(px), VIEW_AUX);
}

fn store_view_aux(px: vec2<u32>, v: vec4<f32>) {
    textureStore(view_rays, vec2<i32>(px), VIEW_AUX, v);
}

fn load_view_ray(px: vec2<u32>) -> vec4<f32> {
    return textureLoad(view_rays, vec2<i32>(px), VIEW_RAY);
}

fn store_view_ray(px: vec2<u32>, v: vec4<f32>) {
    textureStore(view_rays, vec2<i32>(px), VIEW_RAY, v);
}

// Pixel px's rgba `item` of `view_shade` (VIEW_COLOR, VIEW_LIGHT, VIEW_MEDIUM).
fn load_view_shade(px: vec2<u32>, item: u32) -> vec4<f32> {
    if (F32_STATE) {
        let a = textureLoad(view_shade, vec2<i32>(px), i32(2u * item)).xy;
        let b = textureLoad(view_shade, vec2<i32>(px), i32(2u * item + 1u)).xy;
        return bitcast<vec4<f32>>(vec4<u32>(a, b));
    }
    let a = textureLoad(view_shade, vec2<i32>(px), i32(item)).xy;
    return vec4<f32>(unpack2x16float(a.x), unpack2x16float(a.y));
}

fn store_view_shade(px: vec2<u32>, item: u32, v: vec4<f32>) {
    if (F32_STATE) {
        let u = bitcast<vec4<u32>>(v);
        textureStore(view_shade, vec2<i32>(px), i32(2u * item), vec4<u32>(u.xy, 0u, 0u));
        textureStore(view_shade, vec2<i32>(px), i32(2u * item + 1u), vec4<u32>(u.zw, 0u, 0u));
        return;
    }
    textureStore(view_shade, vec2<i32>(px), i32(item), vec4<u32>(pack2x16float(v.xy), pack2x16float(v.zw), 0u, 0u));
}

// Beam ij's power in region `region` of `beam_power`: f16 rgb in one layer, or with
// F32_STATE f32 rgb in two (r, g and b). Each beam's regions side by side along x, a record
// per beam (P.sweep.y regions), or where such records would make the image too wide
// (P.sweep.y 0), regions 2r and 2r + 1 side by side in the layers of pair r
// (`beam_pair_texel`). In records, a step's store of the power before its segment
// (`front_power_region`) shares the cache line of the half it reads and writes; in pairs it
// found a line last touched a ring's length of planes before. Where the halves hold every
// beam's state (`power_in_aux`), the halves' power (regions 0 and 1) is kept in the beam's aux
// texel instead, and `beam_power` holds only the regions after them (`power_slot` in
// beams.wgsl).
fn beam_power_texel(ij: vec2<u32>, region: u32) -> vec2<i32> {
    if (P.sweep.y > 0u) {
        let s = beam_slot(ij);
        return vec2<i32>(vec2<u32>(P.sweep.y * s.x + region, s.y));
    }
    return beam_pair_texel(ij, region % 2u);
}

// The layer of region `region` in `beam_power` (f16; with F32_STATE the first of two).
fn beam_power_layer(region: u32) -> u32 {
    if (P.sweep.y > 0u) {
        return 0u;
    }
    return region / 2u;
}

// The power `beam_power` holds for beam ij at slot `slot`, the place of a region in the image
// (`power_slot` in beams.wgsl; `load_beam_power`, `store_beam_power` and `update_beam_power`
// there take a beam's region and find its power wherever it is kept).
fn load_power_texel(slot: u32, ij: vec2<u32>) -> vec3<f32> {
    let t = beam_power_texel(ij, slot);
    let layer = beam_power_layer(slot);
    if (F32_STATE) {
        let a = textureLoad(beam_power, t, i32(2u * layer)).xy;
        let b = textureLoad(beam_power, t, i32(2u * layer + 1u)).x;
        return vec3<f32>(bitcast<f32>(a.x), bitcast<f32>(a.y), bitcast<f32>(b));
    }
    let a = textureLoad(beam_power, t, i32(layer)).xy;
    return vec4<f32>(unpack2x16float(a.x), unpack2x16float(a.y)).rgb;
}

// Beam power v as the words `beam_power` holds it: f16 rgb packed in two (the third 0), or
// with F32_STATE the bits of each f32.
fn beam_power_words(v: vec3<f32>) -> vec3<u32> {
    if (F32_STATE) {
        return bitcast<vec3<u32>>(v);
    }
    return vec3<u32>(pack2x16float(v.xy), pack2x16float(vec2<f32>(v.z, 0.0)), 0u);
}

// Writes power v at slot `slot` of beam ij (`load_power_texel`).
fn store_power_texel(slot: u32, ij: vec2<u32>, v: vec3<f32>) {
    store_beam_power_words(beam_power_texel(ij, slot), beam_power_layer(slot), beam_power_words(v));
}

// Writes the words w (`beam_power_words`) at texel t of layer `layer` (`beam_power_texel`,
// `beam_power_layer`).
fn store_beam_power_words(t: vec2<i32>, layer: u32, w: vec3<u32>) {
    if (F32_STATE) {
        textureStore(beam_power, t, i32(2u * layer), vec4<u32>(w.xy, 0u, 0u));
        textureStore(beam_power, t, i32(2u * layer + 1u), vec4<u32>(w.z, 0u, 0u, 0u));
        return;
    }
    textureStore(beam_power, t, i32(layer), vec4<u32>(w.xy, 0u, 0u));
}

// As `store_power_texel`, but the texels are written only where their bits change: a CPU
// driver stores a texel lane by lane and word by word, and a beam's power often stays as it
// was (full in clear air, zero in a deep shadow), where the region's texel already holds it.
// The words that are read (`load_power_texel`) end up the same either way; the load costs
// little (gathered for all lanes).
fn update_power_texel(slot: u32, ij: vec2<u32>, v: vec3<f32>) {
    let t = beam_power_texel(ij, slot);
    let layer = beam_power_layer(slot);
    let w = beam_power_words(v);
    var changed: bool;
    if (F32_STATE) {
        changed = any(textureLoad(beam_power, t, i32(2u * layer)).xy != w.xy)
            || textureLoad(beam_power, t, i32(2u * layer + 1u)).x != w.z;
    } else {
        changed = any(textureLoad(beam_power, t, i32(layer)).xy != w.xy);
    }
    if (changed) {
        store_beam_power_words(t, layer, w);
    }
}

fn load_back_light(i: u32) -> vec4<f32> {
    if (F32_STATE) {
        let b = i * 4u;
        return vec4<f32>(bitcast<f32>(back_light[b]), bitcast<f32>(back_light[b + 1u]),
                         bitcast<f32>(back_light[b + 2u]), bitcast<f32>(back_light[b + 3u]));
    }
    let b = i * 2u;
    return vec4<f32>(unpack2x16float(back_light[b]), unpack2x16float(back_light[b + 1u]));
}

fn store_back_light(i: u32, v: vec4<f32>) {
    if (F32_STATE) {
        let b = i * 4u;
        back_light[b] = bitcast<u32>(v.x);
        back_light[b + 1u] = bitcast<u32>(v.y);
        back_light[b + 2u] = bitcast<u32>(v.z);
        back_light[b + 3u] = bitcast<u32>(v.w);
        return;
    }
    let b = i * 2u;
    back_light[b] = pack2x16float(v.xy);
    back_light[b + 1u] = pack2x16float(v.zw);
}

fn plane_z(i: u32) -> f32 {
    return P.plane.x + f32(i) * P.plane.y;
}

fn image_size() -> vec2<i32> {
    return vec2<i32>(i32(P.size.x), i32(P.size.y));
}

fn pixel_index(p: vec2<u32>) -> u32 {
    return p.y * u32(P.size.x) + p.x;
}

// Point on the plane at depth z seen through continuous pixel coordinates `t`.
fn unproject(t: vec2<f32>, z: f32) -> vec3<f32> {
    let ndc = (t + vec2<f32>(0.5) - P.projection.zw) / P.projection.xy;
    if (ORTHOGRAPHIC) {
        return vec3<f32>(ndc, z);
    }
    return vec3<f32>(ndc * z, z);
}

// Henyey–Greenstein phase function relative to isotropic scattering, as
// `transfer::scattering::hg_relative` (the spread and lattice modes' views); exactly 1 for
// g = 0.
fn hg_relative(cos_theta: f32, g: f32) -> f32 {
    let d = 1.0 + g * g - 2.0 * g * cos_theta;
    return (1.0 - g * g) / (d * sqrt(d));
}

// Continuous pixel coordinates of a view-space point (inverse of `unproject`).
// The perspective division needs no guard: every point projected lies on a plane of the
// sweep (p.z = a plane's z, to rounding; MIN_LIGHT_DIR_Z and MIN_VIEW_DIR_Z keep the steps
// onto it finite), and planes start at z_first >= NEAR_PLANE x radius > 0 (scene/view.rs). The
// rounding is a few ulp of Δs (<= 32 radii) and of z: ~1e-5 radii, far below NEAR_PLANE x
// radius, and it scales with the scene, so p.z > 0 at any spacing. A fixed floor such as 1e-6
// view units would instead move planes nearer than that: micrometre voxels given in metres
// would render differently from the same voxels given in voxels (tests/extremes/,
// camera_inside_a_microscopic_volume).
fn project(p: vec3<f32>) -> vec2<f32> {
    var xy = p.xy;
    if (!ORTHOGRAPHIC) {
        xy = p.xy / p.z;
    }
    return xy * P.projection.xy + P.projection.zw - vec2<f32>(0.5);
}

// Area of a pixel's footprint on the plane at depth z (view units²).
fn pixel_area(z: f32) -> f32 {
    let a = 1.0 / (P.projection.x * P.projection.y);
    if (ORTHOGRAPHIC) {
        return a;
    }
    return a * z * z;
}

// Direction of the straight primary ray through continuous pixel coordinates `t` (unit).
fn primary_dir(t: vec2<f32>) -> vec3<f32> {
    if (ORTHOGRAPHIC) {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    return normalize(unproject(t, 1.0));
}

fn in_rect(p: vec2<i32>) -> bool {
    return p.x >= i32(P.rect.x) && p.y >= i32(P.rect.y) && p.x < i32(P.rect.z) && p.y < i32(P.rect.w);
}

fn volume_coord(p: vec3<f32>) -> vec3<f32> {
    return (P.volume_from_view * vec4<f32>(p, 1.0)).xyz;
}

// Data value (transfer-function domain) at a view-space point; 0 outside the volume.
fn sample_value(p: vec3<f32>) -> f32 {
    return textureSampleLevel(volume_tex, volume_sampler, volume_coord(p), 0.0).r;
}

// The data value's gradient at p from central differences h either side along each view
// axis (per 2h view units: only its direction is used).
fn value_gradient(p: vec3<f32>, h: f32) -> vec3<f32> {
    return vec3<f32>(
        sample_value(p + vec3<f32>(h, 0.0, 0.0)) - sample_value(p - vec3<f32>(h, 0.0, 0.0)),
        sample_value(p + vec3<f32>(0.0, h, 0.0)) - sample_value(p - vec3<f32>(0.0, h, 0.0)),
        sample_value(p + vec3<f32>(0.0, 0.0, h)) - sample_value(p - vec3<f32>(0.0, 0.0, h)),
    );
}

struct Index {
    eta: f32,          // refractive index
    grad: vec3<f32>,   // ∇η in view space (per view unit)
}

// Refractive index and its gradient at a view-space point: one trilinear fetch of the
// gradient volume (precomputed when the transfer functions change).
fn index_at(p: vec3<f32>) -> Index {
    let g = textureSampleLevel(gradient_tex, volume_sampler, volume_coord(p), 0.0);
    let m = mat3x3<f32>(P.gradient_to_view[0].xyz, P.gradient_to_view[1].xyz, P.gradient_to_view[2].xyz);
    return Index(g.w + P.texel.w, m * g.xyz);
}

// The unit vector of v = η·direction with its magnitude set to η while keeping the component
// tangential to the interface (normal ∇η): Snell's law for any step size. Where the
// tangential part alone exceeds η (total internal reflection) the normal part changes sign:
// the ray is reflected.
fn snell_renormalise(v: vec3<f32>, ix: Index) -> vec3<f32> {
    let gl = length(ix.grad);
    if (!has_normal(gl)) {
        return v;
    }
    let n = ix.grad / gl;
    let vn = dot(v, n);
    let vt = v - vn * n;
    let t2 = dot(vt, vt);
    let e2 = ix.eta * ix.eta;
    if (t2 >= e2) {
        return vt - vn * n;
    }
    return vt + sign_or_one(vn) * sqrt(e2 - t2) * n;
}

fn sign_or_one(x: f32) -> f32 {
    if (x < 0.0) {
        return -1.0;
    }
    return 1.0;
}

// The direction v = η·d a ray travelling along `d` (unit, outside the volume where the index
// is η_outside) has after entering the index `eta` through a face parallel to the planes:
// Snell's law keeps the component along the planes (the paper's init v = η·d does not).
fn entering(d: vec3<f32>, eta: f32) -> vec3<f32> {
    let t = d.xy * P.texel.w;
    let t2 = dot(t, t);
    return vec3<f32>(t, sqrt(max(eta * eta - t2, 0.0)));
}

// Unit propagation direction with z bounded away from 0: light may not turn back or travel
// inside a plane (the sweep only moves forward).
fn light_direction(v: vec3<f32>) -> vec3<f32> {
    var d = safe_normalize(v);
    let min_z = P.limits.x;
    if (d.z < min_z && guarded(SG_LIGHT_MIN_Z)) {
        let side = safe_normalize(vec3<f32>(d.xy, 0.0)).xy;
        d = vec3<f32>(side * sqrt(1.0 - min_z * min_z), min_z);
    }
    return d;
}

// Where the straight line through p along d (d.z > 0) crosses the plane at depth z. Every
// straight step from plane to plane, of light and of view rays, takes this one arithmetic, so
// that steps taken one at a time in different passes land on the same bits.
fn straight_to(p: vec3<f32>, d: vec3<f32>, z: f32) -> vec3<f32> {
    return p + d * ((z - p.z) / d.z);
}

// Where the unrefracted light through plane-0 point `p0` crosses the plane at depth z.
fn unrefracted(p0: vec3<f32>, z: f32) -> vec3<f32> {
    return straight_to(p0, P.light_dir.xyz, z);
}

// The light grid: plane-0 cells (stride pixels wide, origin beam_origin.xy in pixel-edge
// coordinates) carried along the unrefracted light; beams start at their centres.
fn grid_cells() -> u32 {
    return P.beam_grid.x * P.beam_grid.y;
}

// Centre of the cell at continuous cell coordinates `c` (cell (i, j) at c = (i, j)) on the
// plane at depth z.
fn grid_point(c: vec2<f32>, z: f32) -> vec3<f32> {
    let t = P.beam_origin.xy + (c + vec2<f32>(0.5)) * P.beam_origin.z - vec2<f32>(0.5);
    return unrefracted(unproject(t, P.plane.x), z);
}

// Continuous cell coordinates of a view-space point (inverse of `grid_point`).
fn grid_coords(p: vec3<f32>) -> vec2<f32> {
    let p0 = p - P.light_dir.xyz * ((p.z - P.plane.x) / P.light_dir.z);
    return (project(p0) + vec2<f32>(0.5) - P.beam_origin.xy) / P.beam_origin.z - vec2<f32>(0.5);
}

// Light arriving at a point: relative to the source (fluence for the image), and the
// direction it travels (unit) for highlights.
struct LightSample {
    color: vec3<f32>,
    dir: vec3<f32>,
}

// Whether the slab between depths za and zb seen through the pixels [lo, hi) (pixel-edge
// coordinates) meets a brick that absorbs or shows: the box around the slab's eight corners,
// one voxel wider (trilinear sampling), in bricks. Conservative: a box over more than 64
// bricks counts as visible.
fn slab_visible(lo: vec2<f32>, hi: vec2<f32>, za: f32, zb: f32) -> bool {
    let dims = vec3<f32>(1.0) / P.texel.xyz;
    var vmin = vec3<f32>(1e30);
    var vmax = vec3<f32>(-1e30);
    for (var c = 0u; c < 8u; c++) {
        let t = vec2<f32>(select(lo.x, hi.x, (c & 1u) == 1u), select(lo.y, hi.y, (c & 2u) == 2u)) - vec2<f32>(0.5);
        let z = select(za, zb, (c & 4u) == 4u);
        let v = volume_coord(unproject(t, z)) * dims;
        vmin = min(vmin, v);
        vmax = max(vmax, v);
    }
    return bricks_visible(vmin, vmax);
}

// Whether the box [vmin, vmax] (voxels) meets a brick that absorbs or shows, one voxel wider
// (trilinear sampling). Conservative: a box over more than 64 bricks counts as visible.
fn bricks_visible(vmin: vec3<f32>, vmax: vec3<f32>) -> bool {
    let dims = vec3<f32>(1.0) / P.texel.xyz;
    if (any(vmax < vec3<f32>(-1.0)) || any(vmin > dims + vec3<f32>(1.0))) {
        return false;
    }
    let nb = vec3<i32>(P.culling.xyz);
    let b0 = clamp(vec3<i32>(floor((vmin - vec3<f32>(1.0)) / 8.0)), vec3<i32>(0), nb - vec3<i32>(1));
    let b1 = clamp(vec3<i32>(floor((vmax + vec3<f32>(1.0)) / 8.0)), vec3<i32>(0), nb - vec3<i32>(1));
    let span = b1 - b0 + vec3<i32>(1);
    if (span.x * span.y * span.z > 64) {
        return true;
    }
    for (var z = b0.z; z <= b1.z; z++) {
        for (var y = b0.y; y <= b1.y; y++) {
            for (var x = b0.x; x <= b1.x; x++) {
                if (bricks[u32((z * nb.y + y) * nb.x + x)] != 0u) {
                    return true;
                }
            }
        }
    }
    return false;
}

// Pre-integrated segment from value a (front) to value b (back), length `ratio` × Δs.
// Returns premultiplied colour (rgb) and opacity (a) of the particles.
fn segment_particles(a: f32, b: f32, ratio: f32, clipped: bool) -> vec4<f32> {
    if (clipped) {
        return vec4<f32>(0.0);
    }
    let e = textureSampleLevel(particle_table, linear_clamp, table_uv(a, b), 0.0);
    let alpha_ds = 1.0 - exp(-e.a);
    let alpha = 1.0 - exp(-e.a * ratio);
    // Rescale the premultiplied colour with the opacity of the longer or shorter segment.
    var scale = ratio;
    if (alpha_ds > MIN_SEGMENT_OPACITY || !guarded(SG_SEGMENT_OPACITY)) {
        scale = alpha / alpha_ds;
    }
    return vec4<f32>(e.rgb * scale, alpha);
}

// The medium table's entry for a segment from value a to value b: τ_m per channel and τ_α,
// per sample distance.
fn medium_entry(a: f32, b: f32) -> vec4<f32> {
    return textureSampleLevel(medium_table, linear_clamp, table_uv(a, b), 0.0);
}

// Medium transmittance of the segment.
fn segment_medium(a: f32, b: f32, ratio: f32) -> vec3<f32> {
    return exp(-medium_entry(a, b).rgb * ratio);
}

// Where to split a segment whose value is v0 at the front, vm halfway and v1 at the back, and
// the value there: (fraction of the segment in front of the split, value). Pre-integration
// takes the value as linear between the samples it is given; a thin feature whose peak (or
// trough) falls between two samples would lose it, and its opacity would depend on where the
// samples land (woodgrain on thin sheets). When the middle sample is the extreme of the three,
// the parabola through them locates the extremum, and the segment is split there; otherwise
// halfway.
fn segment_split(v0: f32, vm: f32, v1: f32) -> vec2<f32> {
    let b = 4.0 * vm - 3.0 * v0 - v1;
    let c = 2.0 * (v0 + v1) - 4.0 * vm;
    let extreme = (vm > max(v0, v1) || vm < min(v0, v1)) && abs(c) > 1e-6;
    if (!extreme) {
        return vec2<f32>(0.5, vm);
    }
    // c and b have opposite signs here, so the extremum lies inside (0, 1).
    let t = clamp(-b / (2.0 * c), 0.0, 1.0);
    return vec2<f32>(t, clamp(v0 - b * b / (4.0 * c), 0.0, 1.0));
}

// A segment split at `split` (segment_split): its particles, front part over back part.
fn split_particles(a: f32, split: vec2<f32>, b: f32, ratio: f32, clipped: bool) -> vec4<f32> {
    let front = segment_particles(a, split.y, ratio * split.x, clipped);
    let back = segment_particles(split.y, b, ratio * (1.0 - split.x), clipped);
    let through = 1.0 - front.a;
    return vec4<f32>(front.rgb + through * back.rgb, 1.0 - through * (1.0 - back.a));
}

// Medium transmittance of a segment split at `split`.
fn split_medium(a: f32, split: vec2<f32>, b: f32, ratio: f32) -> vec3<f32> {
    return segment_medium(a, split.y, ratio * split.x) * segment_medium(split.y, b, ratio * (1.0 - split.x));
}

// What a segment from value a through m (halfway) to b lets through: (1 − α)·m (Eq. 9), the
// particles' and the medium's optical depths summed from one lookup per part (the medium
// table holds τ_α beside τ_m), as `split_particles` and `split_medium` would give them.
fn segment_transmittance(a: f32, m: f32, b: f32, ratio: f32, clipped: bool) -> vec3<f32> {
    let split = segment_split(a, m, b);
    let front = medium_entry(a, split.y);
    let back = medium_entry(split.y, b);
    let w = vec2<f32>(split.x, 1.0 - split.x) * ratio;
    var tau = vec3<f32>(select(front.a * w.x + back.a * w.y, 0.0, clipped));
    if (MEDIUM) {
        tau += front.rgb * w.x + back.rgb * w.y;
    }
    return exp(-tau);
}

fn table_uv(a: f32, b: f32) -> vec2<f32> {
    let n = f32(textureDimensions(particle_table).x);
    return (clamp(vec2<f32>(a, b), vec2<f32>(0.0), vec2<f32>(1.0)) * (n - 1.0) + 0.5) / n;
}

fn is_clipped(p: vec3<f32>) -> bool {
    if (CLIP) {
        return dot(P.clip_plane.xyz, p) + P.clip_plane.w > 0.0;
    }
    return false;
}

// Integer hash (PCG-style); deterministic, so two renders give identical bytes.
fn hash(x: u32) -> u32 {
    var v = x * 747796405u + 2891336453u;
    v = ((v >> ((v >> 28u) + 4u)) ^ v) * 277803737u;
    return (v >> 22u) ^ v;
}

fn random01(texel: vec2<u32>, plane: u32) -> f32 {
    let h = hash(texel.x ^ hash(texel.y ^ hash(plane ^ I.seed)));
    return f32(h & 0xffffu) / 65536.0;
}
