// Forward light transport: one beam per cell of the light grid carries position, direction
// v = η·d and power from plane to plane and deposits its power onto each plane over its
// footprint. Rays may cross (a focus is passed and the light spreads again), light is never
// resampled, and power is conserved: every beam deposits all it carries.
//
// Integration: leapfrog in depth. A beam stores v half a step ahead; it drifts straight to
// the next plane (`drift`, no volume fetch), so a neighbour's new position follows from its
// stored state alone, then gets the kick v += ℓ ∇η at its new position (Eq. 8 with the
// segment's path length ℓ), with |v| set to η along ∇η (Snell's law at any step size).

// Fixed-point scale of the deposited light: 2^17 per unit of relative irradiance, so the
// unsaturated range [0, 2^31) holds 16384 (MAX_LIGHT_VALUE) with 7.6e-6 resolution.
const ACC_SCALE: f32 = 131072.0;
// Accumulated values at or above this count as saturated (SG_SATURATION): one add is at most
// ACC_SCALE (a beam carries one plane-0 cell of power), so 2^31 of headroom cannot wrap.
const ACC_SATURATED: u32 = 2147483648u;

// Beams deposit their direction of travel too for the direction view only (highlights take
// the source's direction carried through the surface, view.wgsl `segment_highlight`).
fn deposits_direction() -> bool {
    return DEBUG_VIEW == 2u;
}

fn beam_count() -> u32 {
    return P.beam_grid.x * P.beam_grid.y;
}

// Plane-0 pixel coordinates (edges: pixel u spans [u, u + 1)) of the centre of beam (i, j).
fn beam_cell_centre(ij: vec2<u32>) -> vec2<f32> {
    return P.beam_origin.xy + (vec2<f32>(ij) + vec2<f32>(0.5)) * P.beam_origin.z;
}

struct Beam {
    pos: vec3<f32>,     // on the plane
    v: vec3<f32>,       // η·direction, half a step ahead
    value: f32,         // data value at pos (front of the next segment)
    shadow: f32,        // depth where the light it lost was lost (loss-weighted), for soft light
    power: vec3<f32>,   // relative to one plane-0 cell of unobstructed light
    plane: u32,         // the plane it was stored on (light tiles listed: not always the last)
}

const BEAM_AUX: u32 = 0u;
const BEAM_POS: u32 = 1u;

// Beam ij's texel of layer `layer` (BEAM_AUX or BEAM_POS) in half `half` of `beam_state`.
fn beam_texel(ij: vec2<u32>, layer: u32, half: u32) -> vec4<f32> {
    return textureLoad(beam_state, beam_pair_texel(ij, half), i32(layer));
}

fn store_beam_texel(ij: vec2<u32>, layer: u32, half: u32, v: vec4<f32>) {
    textureStore(beam_state, beam_pair_texel(ij, half), i32(layer), v);
}

// The same texel's words: with the power in the aux texel (`power_in_aux`) two of them are
// f16 pairs, which the image holds as they are (it is read and written without arithmetic).
// An image of 32-bit integer texels would say so in its type, but lavapipe loads and stores
// those with more instructions: full effects at 128² counted 1.5 % more in all.
fn beam_words(ij: vec2<u32>, layer: u32, half: u32) -> vec4<u32> {
    return bitcast<vec4<u32>>(beam_texel(ij, layer, half));
}

fn store_beam_words(ij: vec2<u32>, layer: u32, half: u32, w: vec4<u32>) {
    store_beam_texel(ij, layer, half, bitcast<vec4<f32>>(w));
}

// Beam ij's power in region `region` (`beam_power_texel`): with the power in the aux texel
// (`power_in_aux`) the halves' (regions 0 and 1) from there, else from `beam_power`.
// `load_beam` and `load_neighbour` call it beside their own load of the aux texel, which the
// compiler merges with this one: handing it the words they loaded instead counted 0.6 % more
// instructions on lavapipe (the soft light's compare scene at 256²).
fn load_beam_power(region: u32, ij: vec2<u32>) -> vec3<f32> {
    if (power_in_aux() && region < 2u) {
        return aux_power(beam_words(ij, BEAM_AUX, region));
    }
    return load_power_texel(power_slot(region), ij);
}

// Where region `region` of a beam's power lies in `beam_power`: with the halves' power in the
// aux texel (`power_in_aux`) the image holds only the regions after them, from its first
// (`Layout::power_regions` in state.rs). `load_beam_power`, `store_beam_power` and
// `update_beam_power` map every region through it.
fn power_slot(region: u32) -> u32 {
    if (power_in_aux()) {
        return region - 2u;
    }
    return region;
}

// Writes beam ij's power in region `region` of `beam_power` (not a half's where the aux texel
// holds it: `store_beam` writes that).
fn store_beam_power(region: u32, ij: vec2<u32>, v: vec3<f32>) {
    store_power_texel(power_slot(region), ij, v);
}

// As `store_beam_power`, where the bits change (`update_power_texel`).
fn update_beam_power(region: u32, ij: vec2<u32>, v: vec3<f32>) {
    update_power_texel(power_slot(region), ij, v);
}

// Power p as the aux texel's first and last words hold it (`power_in_aux`): r and g in one
// f16 pair, b in the upper half of the other. The image holds them as they are: a texel of
// 32-bit floats is loaded and stored without conversion, and the words meet no arithmetic as
// f32, which is where subnormals (what they are where g or b is zero or nearly) may be
// flushed. As f32 neither is ever a NaN (that needs an f16 NaN in the upper half). On
// lavapipe every bit is kept: the same images to the byte.
fn aux_power_words(p: vec3<f32>) -> vec2<u32> {
    return vec2<u32>(pack2x16float(p.rg), pack2x16float(vec2<f32>(0.0, p.b)));
}

// The power an aux texel's words w hold (`aux_power_words`).
fn aux_power(w: vec4<u32>) -> vec3<f32> {
    return vec3<f32>(unpack2x16float(w.x), unpack2x16float(w.w).y);
}

fn load_beam(ij: vec2<u32>, half: u32, z: f32) -> Beam {
    let aux = beam_texel(ij, BEAM_AUX, half);
    var b: Beam;
    if (REFRACTION) {
        let a = beam_texel(ij, BEAM_POS, half);
        b.pos = vec3<f32>(a.xy, z);
        b.v = vec3<f32>(a.zw, aux.x);
    } else {
        let p0 = unproject(beam_cell_centre(ij) - vec2<f32>(0.5), P.plane.x);
        b.pos = unrefracted(p0, z);
        b.v = P.light_dir.xyz * P.texel.w;
    }
    b.value = aux.y;
    b.shadow = aux.z;
    b.power = load_beam_power(half, ij);
    if (!power_in_aux()) {
        b.plane = u32(aux.w);
    }
    return b;
}

// ---------------------------------------------------------------------------------------
// Light tiles listed for each plane (after each view pass for the next one's planes:
// `light_tile_goes_on` and `list_light_tile`, run by `tiles_main` in sweep.wgsl): a tile
// of beams is stepped only from shortly before one of its beams (or a neighbouring tile's)
// comes within a margin of a cell where particles absorb or show or η changes
// (`occupancy.rs`) until none of them can any more. Outside those cells nothing attenuates or
// bends a beam, so a tile not yet stepped holds the beams' initial state carried straight,
// and one no longer stepped keeps the state of its last plane, from where it is carried
// straight as well. The margin covers what the view reads around a sample (the deposits'
// reach, a view segment either side, trilinear sampling), so that the light where particles
// are is the same as with every beam stepped.

const NEVER: u32 = 0xffffffffu;

fn light_tiles_listed() -> bool {
    return LIGHT_LISTS;
}

// The tile of the light grid of beam ij.
fn beam_tile(ij: vec2<u32>) -> u32 {
    let t = ij / TILE;
    return t.y * P.beam_grid.z + t.x;
}

// Beam ij on plane `plane` (>= 1) when it was never stepped: its state from `beams_init`
// carried straight. The tile starts being stepped before any of its beams comes within the
// margin, so until then the beam is in front of the volume (index and value those outside
// it). With `exact` it is drifted one plane at a time as `beams_step` would have, to the bit
// (for the tile's own first step); else in one go (a neighbour's, for a footprint outside
// the margin).
fn pre_entry_beam(ij: vec2<u32>, plane: u32, exact: bool) -> Beam {
    var b: Beam;
    let z0 = P.plane.x;
    b.v = P.light_dir.xyz * P.texel.w;
    var p = unproject(beam_cell_centre(ij) - vec2<f32>(0.5), z0);
    let z = plane_z(plane);
    if (REFRACTION) {
        // As `beams_init` with η outside the volume (the gradient volume's border is 0).
        b.v = entering(P.light_dir.xyz, 0.0 + P.texel.w);
        let d = light_direction(b.v);
        let steps = select(0u, plane, exact);
        for (var j = 1u; j <= steps; j++) {
            p = straight_to(vec3<f32>(p.xy, plane_z(j - 1u)), d, plane_z(j));
        }
        if (!exact) {
            p = straight_to(p, d, z);
        }
    }
    b.pos = vec3<f32>(p.xy, z);
    b.plane = plane;
    b.value = 0.0;
    b.shadow = z0;
    b.power = vec3<f32>(1.0);
    if (REFRACTION && safe_normalize(b.v).z < P.limits.x && guarded(SG_LIGHT_MIN_Z)) {
        b.power = vec3<f32>(0.0); // as the first step's kick leaves it
    }
    return b;
}

// Beam ij's state on plane `plane`, which with light tiles listed may have been stored on an
// earlier plane (`load_stored_beam`).
fn load_beam_at(ij: vec2<u32>, plane: u32, exact: bool) -> Beam {
    var b = load_beam(ij, plane % 2u, plane_z(plane));
    if (light_tiles_listed() && b.plane != plane) {
        b = load_stored_beam(ij, plane, exact);
    }
    return b;
}

// Beam ij's state on plane `plane` (>= 1) when its tile was not stepped on it: the newer of the
// two halves carried straight from its plane (the tile is no longer stepped), or, if that is
// plane 0, `pre_entry_beam` (never stepped).
fn load_stored_beam(ij: vec2<u32>, plane: u32, exact: bool) -> Beam {
    // A tile is stepped from its start on (`light_start.y`): one that starts after `plane` was
    // never stepped, and its half of the next plane may be being written by its first step
    // while this reads it (a texel is stored word by word on a CPU driver).
    if (light_tiles_listed() && light_start[beam_tile(ij)].y > plane) {
        return pre_entry_beam(ij, plane, exact);
    }
    var half = plane % 2u;
    var stored = u32(beam_texel(ij, BEAM_AUX, half).w);
    // The other half may be being written on the plane after (a tile that starts there): only
    // a plane before counts.
    let other = u32(beam_texel(ij, BEAM_AUX, 1u - half).w);
    if (other > stored && other < plane) {
        half = 1u - half;
        stored = other;
    }
    if (stored == 0u) {
        return pre_entry_beam(ij, plane, exact);
    }
    // Unrefracted beams keep their cells: their position follows from the plane alone.
    var z = plane_z(plane);
    if (REFRACTION) {
        z = plane_z(stored);
    }
    var b = load_beam(ij, half, z);
    if (REFRACTION) {
        b.pos = vec3<f32>(drift(b.pos, b.v, plane_z(plane)).xy, plane_z(plane));
    }
    b.plane = plane;
    return b;
}

// The footprint of a beam at p whose cell is spanned by du and dv, in plane pixels: the cell's
// extent along each image axis (its second moments kept).
fn footprint(p: vec3<f32>, du: vec3<f32>, dv: vec3<f32>) -> vec2<f32> {
    let pu = project(p + du) - project(p);
    let pv = project(p + dv) - project(p);
    return vec2<f32>(length(vec2<f32>(pu.x, pv.x)), length(vec2<f32>(pu.y, pv.y)));
}

// How far around a beam's position (view units, on its plane at depth z) its deposit on the
// pyramid and the view's bilinear reads of it reach, for a footprint w (`footprint`): half the
// footprint, plus a texel of its level and one of the reads' (`deposit`, `deposited_at`).
fn deposit_reach(z: f32, w: vec2<f32>) -> f32 {
    let widest = max(w.x, w.y);
    let m = min(u32(max(ceil(log2(max(widest, 1.0))), 0.0)), acc_levels() - 1u);
    return (0.5 * widest + 2.0 * f32(1u << m)) * sqrt(pixel_area(z));
}

// Whether light tile `t` (x, y in tiles) is in the window of plane k (`light_windows` in
// state.rs): without refraction, light outside it cannot reach the image any more.
fn in_light_window(t: vec2<u32>, k: u32) -> bool {
    let w = light_window[k];
    let r = vec2<i32>(t) - vec2<i32>(w.xy);
    return r.x >= 0 && r.y >= 0 && r.x < i32(w.z) && u32(r.y) * w.z + u32(r.x) < w.w;
}

// Whether a light tile whose beams have all gone dark can stop being stepped: where nothing
// bends the light, exchanges it between beams (the soft light) or scatters it, a beam's
// power only falls, so one that carries none never will again, and a beam's step reads no
// other beam. Its power on the planes the view reads back stays 0 (`light_lit`).
fn dark_tiles_end() -> bool {
    return BEAMS && !REFRACTION && !LIGHT_FILTER && !SCATTER && !LBM;
}

// Whether a light tile whose light no view ray still alive can read (`light_tile_unseen`) can
// stop being stepped: where beams keep their cells (nothing bends them) and carry only the
// unscattered light.
fn unseen_tiles_end() -> bool {
    return BEAMS && !REFRACTION && !SCATTER && !LBM;
}

// Whether the listed light tiles are stepped over several planes per dispatch
// (`beams_steps`): where a beam's step reads no other beam (`dark_tiles_end`) and the view
// reads only the power the beams keep per plane (the image and the medium view), a tile's
// beams take all the planes up to the next view pass in one dispatch, their state kept in
// the invocation between planes, and the tiles are listed once per view pass. A dispatch
// that has work wakes a CPU driver's threads: this is one dispatch of the light and one
// listing per view pass instead of one of each per plane.
fn light_groups() -> bool {
    return LIGHT_GROUPS && dark_tiles_end() && (DEBUG_VIEW == 0u || DEBUG_VIEW == 4u);
}

// The lists of light tiles a plane steps (`light_lists`, their indirect arguments
// `light_args`): per parity of the view pass whose planes they step, per plane of the pass
// (at most LIST_PLANES), the tiles whose beams and all they read were stepped on the plane
// before (LIGHT_LISTED) and the others (LIGHT_EDGE). They are written after each view pass
// for the next one's planes, so that the planes in between need no listing dispatch (a
// dispatch that has work wakes a CPU driver's threads).
const LIST_PLANES: u32 = 8u;

fn light_list_slot(parity: u32, offset: u32, list: u32) -> u32 {
    return (parity * LIST_PLANES + offset) * 2u + list;
}

fn append_light_tile(t: u32, slot: u32) {
    let i = atomicAdd(&light_args[slot * 3u], 1u);
    light_lists[slot * P.beam_grid.w + i] = t;
}

// Tile i (0 ..= 8, row by row) of the 3 × 3 light tiles around and including tile t, or NEVER
// beyond the grid.
fn light_tile_around(t: u32, i: u32) -> u32 {
    let tx = P.beam_grid.z;
    let q = vec2<i32>(vec2<u32>(t % tx, t / tx)) + vec2<i32>(i32(i % 3u) - 1, i32(i / 3u) - 1);
    if (q.x < 0 || q.y < 0 || q.x >= i32(tx) || u32(q.y) * tx + u32(q.x) >= P.beam_grid.w) {
        return NEVER;
    }
    return u32(q.y) * tx + u32(q.x);
}

// Whether light tile t's beams are to be stepped on the planes k ..= last (k >= 1), which
// are listed together (a view pass's): from the plane its beams or a neighbouring tile's may
// come within the margin of a cell where the light can change (`light_start`), until neither
// it nor a neighbour has a beam left that can come within it (`light_start.z`, or
// `light_alive` from plane k-1's step) or it leaves the window; then never again
// (`light_end`, written here). A tile keeps being stepped while a neighbour is, so that the
// beams near the box read their neighbours' footprints and light exactly as with every beam
// stepped. A tile that goes on is stepped on all of the planes from its start: what would
// have ended it on one of the later ones (its beams past the cells where the light changes,
// its light gone dark, unseen or out of the window) ends it at the next listing instead, and
// the steps in between write the light it already had, or light that nothing that shows
// reads.
fn light_tile_goes_on(t: u32, k: u32, last: u32) -> bool {
    let n = P.beam_grid.w;
    let tx = P.beam_grid.z;
    if (t >= n || k >= u32(P.plane.z)) {
        return false;
    }
    let start = light_start[t].y;
    if (last < start || atomicLoad(&light_end[t]) != NEVER) {
        return false;
    }
    // Dark for good: stepped without light on the planes whose power the view reads back
    // (`front_power_region`) and on the last two (the power on the plane).
    let held = max(P.sweep.x, 2u);
    if (dark_tiles_end() && k > start + held && atomicLoad(&light_lit[t]) + held < k) {
        atomicStore(&light_end[t], k);
        return false;
    }
    // Unseen for good: no view ray left alive can read its light on this plane or a later one
    // (from plane 2 on: plane 1's tiles are listed while the view rays are being counted).
    // Tested every UNSEEN_TEST_PLANES planes, or at each listing of several (a view pass's,
    // so a tile ends up to its planes less one late): the test walks the tile's light to the
    // last plane, and on every plane it was two fifths of the listing pass (soft light, CT
    // head, 512²), while a tile ending up to three planes late is stepped 1.6 % more often.
    if (unseen_tiles_end() && (P.culling.w & 2u) != 0u && k >= 2u
        && (k % UNSEEN_TEST_PLANES == 0u || last > k) && light_tile_unseen(t, k)) {
        atomicStore(&light_end[t], k);
        return false;
    }
    var stepped = k == start;
    for (var i = 0u; i < 9u; i++) {
        let u = light_tile_around(t, i);
        if (u != NEVER) {
            let s = light_start[u];
            // Not finished: its beams are still to come near an occupied cell, or one that
            // was stepped on plane k-1 can still come within the margin (without refraction
            // s.z, the last plane of its straight beams; with it `light_alive`).
            if (s.x != NEVER && (s.y >= k || max(atomicLoad(&light_alive[u]), s.z) >= k - 1u)) {
                stepped = true;
            }
        }
    }
    if (!stepped || !in_light_window(vec2<u32>(t % tx, t / tx), k)) {
        atomicStore(&light_end[t], k);
        return false;
    }
    return true;
}

// Whether every beam's state on plane k-1 is in half (k-1) % 2 of `beam_state` and
// `beam_power` whether or not its tile was stepped on that plane, so that every listed tile
// is stepped as `LIGHT_LISTED`: where beams keep their cells (nothing bends them) and read
// their neighbours' light (the soft light). A tile not stepped yet holds `beams_init`'s state
// in both halves, the state it would have had (`pre_entry_beam`: nothing changes a beam in
// front of the volume); a tile that ends has its last state copied to the other half
// (`freeze_beam`), the state `load_stored_beam` finds for it. On a CPU driver the second
// light dispatch of a plane, the tiles at the edge's, then has work only on the planes where
// tiles end. `LIGHT_EDGE_STEPS` steps those tiles at the edge instead, with the same light.
fn halves_hold_state() -> bool {
    return BEAMS && LIGHT_FILTER && !REFRACTION && !SCATTER && !LBM && !LIGHT_EDGE_STEPS;
}

// Whether a beam's power on the plane (the halves' regions 0 and 1 of `beam_power`) is kept
// in the first and last words of its aux texel, whose v.z and plane nothing reads where the
// halves hold every beam's state: a beam's step then reads its own state and each of its four
// neighbours' with one texel load instead of two, and stores its state with one. On lavapipe
// the soft light's light pass of the CT head took about 6 % less (medians of alternating
// renders at 256² and 512²), with 2 % fewer instructions, and `beam_power` is two regions
// smaller (`power_slot`). The f16 power fits in two words; the F32_STATE power, three words,
// stays in `beam_power`.
fn power_in_aux() -> bool {
    return halves_hold_state() && !F32_STATE;
}

// Beam ij of a light tile that ends from plane k on (`halves_hold_state`; listed for
// `LIGHT_EDGE` on plane k by `tiles_main`): its state of plane k-1, its last step, copied to
// the other half, which the light passes of plane k+1 on read. Nothing writes the tile's beams
// any more, and on plane k the other tiles' steps read only the half it copies from. One
// invocation per beam: the listing's one per tile would copy a tile's beams in turn, which
// took a CPU driver about 25 ms at 512².
fn freeze_beam(ij: vec2<u32>, k: u32) {
    if (ij.x >= P.beam_grid.x || ij.y >= P.beam_grid.y) {
        return;
    }
    let last = (k - 1u) % 2u;
    store_beam_words(ij, BEAM_AUX, 1u - last, beam_words(ij, BEAM_AUX, last));
    if (!power_in_aux()) {
        store_beam_power(1u - last, ij, load_beam_power(last, ij));
    }
}

// Whether light tile t's beams and all they read were stepped on plane k-1, the tile being
// stepped on plane k (on plane 1 every beam read is plane 0's, stored for all), or hold that
// plane's state all the same (`halves_hold_state`); else it is listed for `LIGHT_EDGE`.
// Where a beam's step reads no other beam (`dark_tiles_end`), its own tile's steps are all
// that count. The ends read are those of the listing before plane k, or (an end written
// meanwhile for another tile, when listing for plane k itself) k.
fn light_tile_current(t: u32, k: u32) -> bool {
    if (halves_hold_state()) {
        return true;
    }
    var current = k == 1u || k != light_start[t].y;
    if (k == 1u || dark_tiles_end()) {
        return current;
    }
    for (var i = 0u; i < 9u; i++) {
        let u = light_tile_around(t, i);
        if (u != NEVER) {
            current = current && light_start[u].y <= k - 1u && atomicLoad(&light_end[u]) > k - 1u;
        }
    }
    return current;
}

// Lists light tile t for plane k (>= 1) alone, in the lists of `parity` (the first plane of
// the view pass): its ends and its list in one dispatch.
fn list_light_tile(t: u32, k: u32, parity: u32) {
    if (light_tile_goes_on(t, k, k)) {
        list_going_light_tile(t, k, parity);
    }
}

// Lists light tile t, which goes on (`light_tile_goes_on`), for plane k alone, in the lists of
// `parity`: with the tiles stepped on plane k-1, or at the edge.
fn list_going_light_tile(t: u32, k: u32, parity: u32) {
    append_light_tile(t, light_list_slot(parity, 0u, select(1u, 0u, light_tile_current(t, k))));
}

// Lists light tile t for the planes k ..= last of a view pass, in the lists of `parity`,
// once `light_tile_goes_on` has written the ends (a dispatch before: the lists read the
// neighbours' ends), a list per plane from its start.
fn list_light_tile_planes(t: u32, k: u32, last: u32, parity: u32) {
    if (t >= P.beam_grid.w || k >= u32(P.plane.z) || atomicLoad(&light_end[t]) != NEVER) {
        return;
    }
    let end = min(last, u32(P.plane.z) - 1u);
    for (var j = max(k, light_start[t].y); j <= end; j++) {
        append_light_tile(t, light_list_slot(parity, j - k, select(1u, 0u, light_tile_current(t, j))));
    }
}

// Beams around a light tile whose light must be unseen too before the tile ends, with the
// soft light (`light_tile_unseen`): the side of the tiles it was measured with, whatever the
// side the render's tiles have.
const SOFT_UNSEEN_RING: u32 = 8u;

// Planes between two tests of a light tile for `light_tile_unseen` (a tile unseen on one plane
// stays unseen: ending it a few planes late only steps it more).
const UNSEEN_TEST_PLANES: u32 = 4u;

// Whether no view ray still alive can use the light of light tile t on plane k or a later
// one, where beams keep their cells (`unseen_tiles_end`). A view sample at pixel px on plane
// k' reads the power of the cells around its own light line (`beams_unscattered_through`: a
// lookup back along the light lands on the same cells), bilinearly: those of the tile and
// the one beyond them on each side. Carried along the light from plane k to the last, those
// cells cover a strip of the image and a prism of the volume, taken in pieces of up to half
// the strip's width of drift on the image (at least a view tile's): a piece is seen where a
// view tile with a ray alive meets its box on the image and a brick that absorbs or shows
// meets its box in the volume (one plane longer at each end: the view segments on either
// side of a plane use its light).
// Rays only end (nothing bends them), so a tile once unseen stays unseen; a ray that ended on
// a plane whose view pass has not run yet still counts.
fn light_tile_unseen(t: u32, k: u32) -> bool {
    let tx = P.beam_grid.z;
    let c0 = vec2<f32>(vec2<u32>(t % tx, t / tx) * TILE);
    let s = P.beam_origin.z;
    // With the soft light a beam also reads its neighbours' light: the tile ends only where
    // the SOFT_UNSEEN_RING beams around it are unseen too, so that what an ended tile's
    // frozen light passes on reaches seen light only by diffusing across that many beams
    // stepped on. That is small rather than nothing: measured, the images keep their bits
    // (tests/reference.rs, the CT head's soft light in 8 bits).
    var around = 1.0;
    if (LIGHT_FILTER) {
        around += f32(SOFT_UNSEEN_RING);
    }
    // Plane-0 pixel coordinates (as `grid_point`) of the centres of cells c0 − around and
    // c0 + TILE − 1 + around.
    let lo = P.beam_origin.xy + (c0 - vec2<f32>(around - 0.5)) * s - vec2<f32>(0.5);
    let hi = P.beam_origin.xy + (c0 + vec2<f32>(f32(TILE) + around - 0.5)) * s - vec2<f32>(0.5);
    let last = u32(P.plane.z) - 1u;
    let za = plane_z(min(k, last));
    let zb = plane_z(last);
    let z0 = P.plane.x;
    let mid = unproject(0.5 * (lo + hi), z0);
    let drift = length(project(unrefracted(mid, zb)) - project(unrefracted(mid, za)));
    // A piece drifts at most half the box's width (and at least a tile): its box is then at
    // most half again as wide as the strip's cross-section. Shorter pieces end a few more
    // tiles (1.5 % fewer tile steps with the soft light's wide box) for up to four times the
    // boxes walked, which costs the listing more than the steps they save.
    let pieces = clamp(u32(ceil(drift / max(f32(TILE), 0.5 * (hi.x - lo.x)))), 1u, 64u);
    let dims = vec3<f32>(1.0) / P.texel.xyz;
    for (var i = 0u; i < pieces; i++) {
        let z1 = mix(za, zb, f32(i) / f32(pieces));
        let z2 = mix(za, zb, f32(i + 1u) / f32(pieces));
        var bmin = vec2<f32>(3.4e38);
        var bmax = vec2<f32>(-3.4e38);
        var vmin = vec3<f32>(3.4e38);
        var vmax = vec3<f32>(-3.4e38);
        for (var c = 0u; c < 8u; c++) {
            let corner = vec2<f32>(select(lo.x, hi.x, (c & 1u) == 1u), select(lo.y, hi.y, (c & 2u) == 2u));
            let p0 = unproject(corner, z0);
            let q = project(unrefracted(p0, select(z1, z2, (c & 4u) == 4u)));
            bmin = min(bmin, q);
            bmax = max(bmax, q);
            // The particles that use this light: the view segments on either side of the
            // planes, one plane further each way.
            let v = volume_coord(unrefracted(p0, select(z1 - P.plane.y, z2 + P.plane.y, (c & 4u) == 4u))) * dims;
            vmin = min(vmin, v);
            vmax = max(vmax, v);
        }
        // A pixel of slack for rounding. Light where nothing absorbs or shows is used by no
        // view ray, however many are alive there (rays in the empty space around the volume).
        if (view_rays_within(bmin - vec2<f32>(1.0), bmax + vec2<f32>(1.0)) && bricks_visible(vmin, vmax)) {
            return false;
        }
    }
    return true;
}

// Whether a view tile with a ray alive holds a pixel (centres at integers) within [lo, hi].
fn view_rays_within(lo: vec2<f32>, hi: vec2<f32>) -> bool {
    let r0 = vec2<f32>(P.rect.xy);
    let r1 = vec2<f32>(P.rect.zw) - vec2<f32>(1.0);
    let a = max(ceil(lo), r0);
    let b = min(floor(hi), r1);
    if (any(a > b)) {
        return false;
    }
    let t0 = (vec2<u32>(a) - P.rect.xy) / TILE;
    let t1 = (vec2<u32>(b) - P.rect.xy) / TILE;
    for (var y = t0.y; y <= t1.y; y++) {
        for (var x = t0.x; x <= t1.x; x++) {
            if ((atomicLoad(&view_tiles[y * P.tiles.x + x]) & ~VIEW_TILE_BENT) != 0u) {
                return true;
            }
        }
    }
    return false;
}

// Whether a beam at p travelling along d (unit) is within the margin of the volume's box, plus
// `extra` (view units), or will come within it: the ray against the box in texture
// coordinates (slabs; light_box.xyz: texture units per view unit along each axis at most).
fn reaches_box(p: vec3<f32>, d: vec3<f32>, extra: f32) -> bool {
    let q = volume_coord(p);
    let dq = (P.volume_from_view * vec4<f32>(d, 0.0)).xyz;
    let margin = P.light_box.xyz * (P.budget.z + extra);
    let lo = -margin;
    let hi = vec3<f32>(1.0) + margin;
    var t0 = 0.0;
    var t1 = 3.4e38;
    var hit = true;
    for (var a = 0u; a < 3u; a++) {
        if (abs(dq[a]) < 1e-20) {
            hit = hit && q[a] >= lo[a] && q[a] <= hi[a];
        } else {
            let ta = (lo[a] - q[a]) / dq[a];
            let tb = (hi[a] - q[a]) / dq[a];
            t0 = max(t0, min(ta, tb));
            t1 = min(t1, max(ta, tb));
        }
    }
    return hit && t0 <= t1;
}

// Stores beam ij's state on plane `plane` in half `half` (the plane in aux.w: with light
// tiles listed a beam not stepped on a plane is found in the other half, or not at all).
// Unrefracted beams' power is written only where its bits change (`update_beam_power`);
// refracted beams are stepped where they bend or absorb, and their power changes on most of
// their steps. Where the halves hold every beam's state of their plane (`halves_hold_state`)
// nothing reads aux.w, and aux is not written either unless v.z, the data value or the shadow
// depth changes: its plane is then the last one on which they changed. With the power in the
// aux texel (`power_in_aux`), the texel is written where any of its words changes.
fn store_beam(ij: vec2<u32>, half: u32, plane: u32, b: Beam) {
    let aux = vec4<f32>(b.v.z, b.value, b.shadow, f32(plane));
    if (REFRACTION) {
        store_beam_texel(ij, BEAM_POS, half, vec4<f32>(b.pos.xy, b.v.xy));
        store_beam_texel(ij, BEAM_AUX, half, aux);
        store_beam_power(half, ij, b.power);
        return;
    }
    if (power_in_aux()) {
        // Written only where its bits change, as below.
        let p = aux_power_words(b.power);
        let w = vec4<u32>(p.x, bitcast<u32>(b.value), bitcast<u32>(b.shadow), p.y);
        if (any(beam_words(ij, BEAM_AUX, half) != w)) {
            store_beam_words(ij, BEAM_AUX, half, w);
        }
        return;
    }
    if (!halves_hold_state()
        || any(bitcast<vec3<u32>>(beam_texel(ij, BEAM_AUX, half).xyz) != bitcast<vec3<u32>>(aux.xyz))) {
        store_beam_texel(ij, BEAM_AUX, half, aux);
    }
    update_beam_power(half, ij, b.power);
}

// Position on the plane at depth z of a beam last seen at `pos` with direction `v`: the
// straight segment (drift) of the leapfrog step.
fn drift(pos: vec3<f32>, v: vec3<f32>, z: f32) -> vec3<f32> {
    return straight_to(pos, light_direction(v), z);
}

// Deposited light is a pyramid of ACC_LEVELS levels per plane: level m has texels of 2^m
// pixels. A beam deposits on the level where its footprint is at most one texel wide, onto
// the 2 × 2 texels it overlaps, so every beam costs the same whatever it spreads over; the
// light at a point is the sum of the levels' bilinear lookups.
const ACC_LEVELS: u32 = 3u;
// The spread mode's pyramid (only scattered light, which spreads further): texels of up to
// 2^(SCATTER_LEVELS-1) pixels.
const SCATTER_LEVELS: u32 = 7u;
// The spread mode's texels per beam and half of `beam_scatter`: the scattered light and its
// lag, the second moments, the entry state, and two of the fourth moment (`spread_step`).
const SCATTER_LAYERS: u32 = 5u;

fn acc_levels() -> u32 {
    if (SCATTER) {
        return SCATTER_LEVELS;
    }
    return ACC_LEVELS;
}

// Level m holds the texels of 2^m × 2^m pixels that cover a pixel of the rect (nothing is
// deposited or read beyond it), stored from the first of them (`level_first`): its size.
fn level_size(m: u32) -> vec2<u32> {
    return ((P.rect.zw - vec2<u32>(1u)) >> vec2<u32>(m)) - level_first(m) + vec2<u32>(1u);
}

// Level m's first texel that covers a pixel of the rect (texel q spans pixels q·2^m ..
// (q + 1)·2^m), which is stored first.
fn level_first(m: u32) -> vec2<u32> {
    return P.rect.xy >> vec2<u32>(m);
}

// Offset of level m within a plane of the pyramid packed level after level, in texels. The
// loops here run over every level but the last, those beyond m left out: a fixed count,
// which a CPU driver unrolls (see BACK_PLANES).
fn level_offset(m: u32) -> u32 {
    var o = 0u;
    for (var j = 0u; j + 1u < acc_levels(); j++) {
        if (j < m) {
            let s = level_size(j);
            o += s.x * s.y;
        }
    }
    return o;
}

// Where level m lies in the atlas of a plane of the pyramid with `ACC_IMAGE`: level 0 at its
// corner, the coarser levels stacked in a column to its right (`atlas_size` in state.rs).
fn level_origin(m: u32) -> vec2<u32> {
    if (m == 0u) {
        return vec2<u32>(0u);
    }
    var y = 0u;
    for (var j = 1u; j + 1u < acc_levels(); j++) {
        if (j < m) {
            y += level_size(j).y;
        }
    }
    return vec2<u32>(level_size(0u).x, y);
}

// The slot of the ring of deposited light (`light_acc`) that plane k deposits onto: P.sweep.z
// slots, the planes a view pass reads and two more (`deposit_slots` in state.rs).
fn deposit_slot(k: u32) -> u32 {
    return k % P.sweep.z;
}

// Level m of a plane of the deposited light in `light_acc`, where each channel of each slot
// is a layer of P.deposits.y words: the word of its first texel in a layer and the words
// from one of its rows to the next. Packed level after level, or with `ACC_IMAGE` in the
// atlas of the image `light_acc_tex` over the same words (rows of P.deposits.x words, layer
// slot × channels + channel), whose texel `origin` is its first. Texels are addressed by their
// place in the level (`level_first`: `first` lies at its start).
struct AccLevel {
    start: u32,
    row: u32,
    origin: vec2<u32>,
    first: vec2<u32>,
}

fn acc_level(m: u32) -> AccLevel {
    if (ACC_IMAGE) {
        let o = level_origin(m);
        return AccLevel(o.y * P.deposits.x + o.x, P.deposits.x, o, level_first(m));
    }
    return AccLevel(level_offset(m), level_size(m).x, vec2<u32>(0u), level_first(m));
}

// Index in `light_acc` of channel ch of texel q (one that covers a pixel of the rect) of level
// l of light slot `slot` (a channel's words lie a layer after the one before's).
fn acc_index(slot: u32, ch: u32, l: AccLevel, q: vec2<u32>) -> u32 {
    return (slot * P.tiles.w + ch) * P.deposits.y + l.start + (q.y - l.first.y) * l.row + (q.x - l.first.x);
}

// Index of the first channel of texel q of level m of light slot `slot`.
fn acc_texel(slot: u32, m: u32, q: vec2<u32>) -> u32 {
    return acc_index(slot, 0u, acc_level(m), q);
}

// Whether texel q of level m covers any pixel of the rect (the only texels a level holds).
fn level_texel_in_rect(m: u32, q: vec2<i32>) -> bool {
    let s = i32(1u << m);
    let lo = q * s;
    let hi = lo + vec2<i32>(s);
    return q.x >= 0 && q.y >= 0 && hi.x > i32(P.rect.x) && hi.y > i32(P.rect.y)
        && lo.x < i32(P.rect.z) && lo.y < i32(P.rect.w);
}

fn add_light(texel: u32, amount: vec3<f32>, weight: f32, direction: vec3<f32>, dither: f32) {
    var n_colour = 1u;
    if (MEDIUM) {
        n_colour = 3u;
    }
    for (var ch = 0u; ch < n_colour; ch++) {
        let q = u32(amount[ch] * weight * ACC_SCALE + dither);
        if (q > 0u) {
            let old = atomicAdd(&light_acc[texel + ch * P.deposits.y], q);
            if (old + q >= ACC_SATURATED && guarded(SG_SATURATION)) {
                atomicMin(&light_acc[texel + ch * P.deposits.y], ACC_SATURATED);
            }
        }
    }
    if (deposits_direction()) {
        // Power-weighted directions (two's complement) for the highlights.
        let s = amount[0] * weight * ACC_SCALE;
        for (var ch = 0u; ch < 3u; ch++) {
            let q = i32(round(direction[ch] * s));
            if (q != 0) {
                atomicAdd(&light_acc[texel + (n_colour + ch) * P.deposits.y], bitcast<u32>(q));
            }
        }
    }
}

// Adds `amount` (relative irradiance × pixels) to light slot `slot` over the axis-aligned box
// of edges `w` (pixels) centred at `c` (continuous pixel coordinates, pixel u spans
// [u, u + 1)): each texel of the box's level gets the fraction of the box it overlaps, so a
// beam's power is deposited exactly once. Texels that cover no pixel of the rect (never
// read) get nothing.
//
// The box is at least `w_min` wide (the beam's own cell, at most a pixel): beams converging
// to less than that apart would otherwise bin their power pixel by pixel, and beams that far
// apart resolve no finer; the box reconstructs what they sample (against the exact light
// behind a ball lens: relative L1 at 1.25 R 0.086 instead of 0.146, and the on-axis maximum
// on the exact trace's plane). No wider than the cell, so that the grid's edge beams keep
// their power inside the grid's region.
fn deposit(slot: u32, c: vec2<f32>, w_in: vec2<f32>, w_min: f32, amount: vec3<f32>, direction: vec3<f32>, seed: u32) {
    var w = max(w_in, vec2<f32>(w_min));
    let widest = max(w.x, w.y);
    // Footprints within 1e-4 of a level's texel stay on that level: straight beams
    // one texel apart have footprints of 1 ± rounding, and beams that went to the next level
    // for the rounding alone spread their light over twice the texels in rows and columns.
    let m = min(u32(max(ceil(log2(max(widest * (1.0 - 1e-4), 1.0))), 0.0)), acc_levels() - 1u);
    let s = f32(1u << m);
    // Wider than the level's texels (by that 1e-4, or beyond the coarsest level: light
    // spread over more than 2^(levels-1) pixels by one beam) the box is split between two
    // texels all the same: its power stays whole, only its spread is narrower.
    let wl = min(w / s, vec2<f32>(1.0));
    let cl = c / s;
    let lo = cl - 0.5 * wl;
    let hi = cl + 0.5 * wl;
    let q0 = floor(lo);
    // The box spans at most two texels per axis: the share of the first, the rest the second.
    let first = clamp((min(hi, q0 + vec2<f32>(1.0)) - lo) / wl, vec2<f32>(0.0), vec2<f32>(1.0));
    // Level texels hold the light averaged over their s² pixels.
    let a = amount / (s * s);
    // The level's first texel and row length, once for the four.
    let level = acc_level(m);
    let base = acc_index(slot, 0u, level, level.first);
    let row = level.row;
    for (var n = 0u; n < 4u; n++) {
        let o = vec2<u32>(n & 1u, n >> 1u);
        let q = vec2<i32>(q0) + vec2<i32>(o);
        let wx = select(first.x, 1.0 - first.x, o.x == 1u);
        let wy = select(first.y, 1.0 - first.y, o.y == 1u);
        let weight = wx * wy;
        if (weight > 0.0 && level_texel_in_rect(m, q)) {
            // Unbiased rounding: a deterministic dither per beam and texel.
            let h = hash(seed ^ (u32(q.x) * 73856093u) ^ (u32(q.y) * 19349663u));
            let local = vec2<u32>(q) - level.first;
            add_light(base + local.y * row + local.x, a, weight, direction, f32(h & 0xffffu) / 65536.0);
        }
    }
}

// One channel of the deposited light at texel q of level l of slot `slot`: an image load
// with `ACC_IMAGE` (which a CPU driver gathers for all invocations at once), else an atomic
// load (which it makes invocation by invocation).
fn acc_channel(slot: u32, ch: u32, l: AccLevel, q: vec2<u32>) -> u32 {
    if (ACC_IMAGE) {
        return textureLoad(light_acc_tex, vec2<i32>(l.origin + q - l.first), i32(slot * P.tiles.w + ch)).x;
    }
    return atomicLoad(&light_acc[acc_index(slot, ch, l, q)]);
}

// Light and direction sums at texel q of level l of slot `slot` (saturated sums read as the
// cap).
fn acc_load(slot: u32, l: AccLevel, q: vec2<u32>) -> LightSample {
    var c = vec3<f32>(f32(min(acc_channel(slot, 0u, l, q), ACC_SATURATED)));
    if (MEDIUM) {
        c.g = f32(min(acc_channel(slot, 1u, l, q), ACC_SATURATED));
        c.b = f32(min(acc_channel(slot, 2u, l, q), ACC_SATURATED));
    }
    var dir = vec3<f32>(0.0);
    if (deposits_direction()) {
        var nc = 1u;
        if (MEDIUM) {
            nc = 3u;
        }
        dir = vec3<f32>(
            f32(bitcast<i32>(acc_channel(slot, nc, l, q))),
            f32(bitcast<i32>(acc_channel(slot, nc + 1u, l, q))),
            f32(bitcast<i32>(acc_channel(slot, nc + 2u, l, q))));
    }
    return LightSample(c / ACC_SCALE, dir);
}

// The deposited light at continuous pixel coordinates t (pixel centres at integers): the sum
// over the pyramid's levels of their bilinear lookups. A tap beyond the texels that cover the
// rect takes the nearest that does (clamped to the edge): nothing is deposited beyond them,
// and reading 0 there darkened the light within half a level texel of the rect's edge (a
// quarter of it along the frame's edges in the light views, where the rect is the frame).
//
// Every view sample reads twelve texels here, so the levels' offsets are summed as it goes
// and the taps need no test: the clamped ones all cover pixels of the rect (a CPU driver runs
// each loop and branch for every invocation).
fn deposited_at(slot: u32, t: vec2<f32>) -> LightSample {
    var sum = LightSample(vec3<f32>(0.0), vec3<f32>(0.0));
    // Level m (`acc_level`), moved on as the levels go.
    var l = acc_level(0u);
    for (var m = 0u; m < acc_levels(); m++) {
        let size = level_size(m);
        if (!ACC_IMAGE) {
            l.row = size.x;
        }
        let s = i32(1u << m);
        l.first = level_first(m);
        let first = vec2<i32>(l.first);
        let last = first + vec2<i32>(size) - vec2<i32>(1);
        let tl = (t + vec2<f32>(0.5)) / f32(s) - vec2<f32>(0.5);
        let lo = floor(tl);
        let f = tl - lo;
        for (var n = 0u; n < 4u; n++) {
            let o = vec2<u32>(n & 1u, n >> 1u);
            let w = select(1.0 - f.x, f.x, o.x == 1u) * select(1.0 - f.y, f.y, o.y == 1u);
            let q = vec2<u32>(clamp(vec2<i32>(lo) + vec2<i32>(o), first, last));
            let light = acc_load(slot, l, q);
            sum.color += w * light.color;
            sum.dir += w * light.dir;
        }
        if (ACC_IMAGE) {
            if (m == 0u) {
                l.origin.x = size.x;
            } else {
                l.origin.y += size.y;
            }
        } else {
            l.start += size.x * size.y;
        }
    }
    return sum;
}

// The part of plane-0 cell power a beam deposits on plane z, per unit of its footprint: the
// cell's area over a pixel's area on that plane (both in view units²). For the image the
// light is fluence (what particles scatter: irradiance over the beam's cosine, relative to
// the source's); the light debug view shows irradiance on the plane.
fn deposit_scale(z: f32, d: vec3<f32>) -> f32 {
    var s = P.beam_origin.w * pixel_area(P.plane.x) / pixel_area(z);
    if (DEBUG_VIEW != 1u) {
        s *= P.light_dir.z / max(d.z, P.limits.x);
    }
    return s;
}

// Whether a view sample may read what a beam at p deposits up to `reach` (view units) around
// it: p is in a cell of `deposit_cells` (every cell within the view's reading margin and a
// straight beam's reach of one where the light can change), or its deposit reaches further
// than that. Elsewhere no view sample composites anything or carries the light on to a
// segment that does, as long as no view segment crosses more than the margin's three steps
// sideways between two planes (`light_tiles::margins`). Refraction can turn a ray at a rim
// further than that before it leaves the sweep: such a segment reads the light at its back
// end up to 50 steps from its particles, where beams may not have deposited (one pixel of
// the CT head at 256², by 0.0002).
fn deposit_read(p: vec3<f32>, reach: f32) -> bool {
    let size = vec3<u32>(deposit_header[0], deposit_header[1], deposit_header[2]);
    if (size.x == 0u || reach > bitcast<f32>(deposit_header[3])) {
        return true;
    }
    let offset = vec3<f32>(f32(deposit_header[4]), f32(deposit_header[5]), f32(deposit_header[6]));
    let per_unit = vec3<f32>(bitcast<f32>(deposit_header[8]), bitcast<f32>(deposit_header[9]), bitcast<f32>(deposit_header[10]));
    let g = floor(volume_coord(p) * per_unit + offset);
    if (any(g < vec3<f32>(0.0)) || any(g >= vec3<f32>(size))) {
        return false;
    }
    let c = vec3<u32>(g);
    return deposit_cells[12u + (c.z * size.y + c.y) * size.x + c.x] != 0u;
}

// Deposits a beam on plane k with its footprint w (`footprint` of the cell spanned by its
// neighbours' positions: half the distance to each neighbour on either side, in plane-k
// pixels), which reaches `reach` around it (`deposit_reach`).
fn deposit_beam(k: u32, b: Beam, w: vec2<f32>, reach: f32, seed: u32) {
    if (max(b.power.r, max(b.power.g, b.power.b)) <= 0.0 || !deposit_read(b.pos, reach)) {
        return;
    }
    let c = project(b.pos) + vec2<f32>(0.5);
    let d = light_direction(b.v);
    // The beam's cell on this plane, unrefracted (plane-0 pixels scale with depth in
    // perspective).
    let cell = P.beam_origin.z * sqrt(pixel_area(P.plane.x) / pixel_area(b.pos.z));
    deposit(deposit_slot(k), c, w, min(cell, 1.0), b.power * deposit_scale(b.pos.z, d), d, seed);
}

// Beam (i, j) at plane 0: unobstructed light entering the sweep, deposited for the first
// view step.
fn beams_init(ij: vec2<u32>) {
    if (ij.x >= P.beam_grid.x || ij.y >= P.beam_grid.y) {
        return;
    }
    let index = ij.y * P.beam_grid.x + ij.x;
    var b: Beam;
    let z0 = P.plane.x;
    b.pos = unproject(beam_cell_centre(ij) - vec2<f32>(0.5), z0);
    b.value = sample_value(b.pos);
    b.v = P.light_dir.xyz * P.texel.w;
    if (REFRACTION) {
        let ix = index_at(b.pos);
        b.v = entering(P.light_dir.xyz, ix.eta);
    }
    b.shadow = z0;
    b.power = vec3<f32>(1.0);
    // Both halves: with light tiles listed, a beam found on plane 0 in both was never stepped.
    store_beam(ij, 0u, 0u, b);
    store_beam(ij, 1u, 0u, b);
    if (!REFRACTION) {
        // The view looks up every cell's light (and the power before the segment): cells
        // outside the volume's box may not be stepped, and what it reads there (where no
        // particle is) must at least be finite.
        store_beam_power(front_power_region(0u), ij, b.power);
        store_beam_power(front_power_region(1u), ij, b.power);
    }
    if (SCATTER) {
        for (var j = 0; j < i32(SCATTER_LAYERS); j++) {
            textureStore(beam_scatter, beam_pair_texel(ij, 0u), j, vec4<f32>(0.0));
        }
    }
    if (!REFRACTION) {
        return;
    }
    // The cell itself is the footprint on plane 0.
    let s = P.beam_origin.z;
    let du = unproject(vec2<f32>(s, 0.0), z0) - unproject(vec2<f32>(0.0), z0);
    let dv = unproject(vec2<f32>(0.0, s), z0) - unproject(vec2<f32>(0.0), z0);
    let w = footprint(b.pos, du, dv);
    deposit_beam(0u, b, w, deposit_reach(b.pos.z, w), hash(index ^ 0x5bd1e995u));
}

// What a beam needs of a neighbour (i, j) on the previous plane: its position drifted to
// plane z (w: 1 inside the grid, 0 beyond: then the rest is unset), its power and its shadow
// depth. Each of its buffers is read once, for the footprint and the soft light alike.
struct Neighbour {
    pos: vec4<f32>,
    power: vec3<f32>,
    shadow: f32,
}

fn load_neighbour(ij: vec2<i32>, plane: u32, z: f32, own_tile: u32, current: bool) -> Neighbour {
    var o: Neighbour;
    if (ij.x < 0 || ij.y < 0 || ij.x >= i32(P.beam_grid.x) || ij.y >= i32(P.beam_grid.y)) {
        o.pos = vec4<f32>(0.0);
        return o;
    }
    var b: Beam;
    if (current) {
        // Only the fields a neighbour gives (its power only for the soft light).
        let aux = beam_texel(vec2<u32>(ij), BEAM_AUX, plane % 2u);
        if (REFRACTION) {
            let a = beam_texel(vec2<u32>(ij), BEAM_POS, plane % 2u);
            b.pos = vec3<f32>(a.xy, plane_z(plane));
            b.v = vec3<f32>(a.zw, aux.x);
        }
        b.shadow = aux.z;
        if (LIGHT_FILTER) {
            b.power = load_beam_power(plane % 2u, vec2<u32>(ij));
        }
    } else {
        // Within the beam's own tile, a neighbour not stepped yet starts with it: drifted to
        // the bit as it will be.
        b = load_beam_at(vec2<u32>(ij), plane, beam_tile(vec2<u32>(ij)) == own_tile);
    }
    if (REFRACTION) {
        o.pos = vec4<f32>(drift(b.pos, b.v, z), 1.0);
    } else {
        // Unrefracted beams keep their cells: only the light is read.
        o.pos = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    o.shadow = b.shadow;
    if (LIGHT_FILTER) {
        o.power = b.power;
    }
    return o;
}

// The cell's edge along one grid axis: the vector to the nearer of the beam's two
// neighbours on that axis. Where the light spreads evenly both are alike (the central
// difference); where neighbouring rays scatter apart (a noisy index field, a fold) the far
// one says nothing about this beam's cell, and taking it would smear light over it.
fn cell_axis(p: vec3<f32>, minus: vec4<f32>, plus: vec4<f32>) -> vec3<f32> {
    let a = plus.xyz - p;
    let b = p - minus.xyz;
    if (minus.w > 0.0 && plus.w > 0.0) {
        if (dot(a, a) < dot(b, b)) {
            return a;
        }
        return b;
    }
    if (plus.w > 0.0) {
        return a;
    }
    if (minus.w > 0.0) {
        return b;
    }
    return vec3<f32>(0.0);
}

// Soft light: power diffuses between neighbouring beams so that a shadow edge cast at depth
// `shadow` is blurred like the penumbra of a cone source of half-angle atan(softness): a
// uniform disc of radius D·softness at distance D, whose variance per axis grows by
// softness²·D·ℓ/2 over a segment of length ℓ, whatever the plane distance.
fn diffuse(b: Beam, nb_power: array<vec3<f32>, 4>, nb_shadow: vec4<f32>, spacing: vec4<f32>, z: f32, l: f32) -> vec4<f32> {
    let soft = P.light_dir.w;
    var flux = vec3<f32>(0.0);
    var shadow_sum = 0.0;
    var deficit_sum = 0.0;
    let own_deficit = max(1.0 - max(b.power.r, max(b.power.g, b.power.b)), 0.0);
    for (var k = 0u; k < 4u; k++) {
        let power = nb_power[k];
        let od = max(1.0 - max(power.r, max(power.g, power.b)), 0.0);
        // The blur grows from where the light was lost: the shadow depth of whichever of the
        // two beams lost more.
        var depth = b.shadow;
        if (od > own_deficit) {
            depth = nb_shadow[k];
        }
        let dist = max(z - depth, 0.0);
        let variance = soft * soft * dist * l * 0.5;
        let s2 = max(spacing[k] * spacing[k], 1e-12);
        // Explicit diffusion is stable for weights up to 1/4 per neighbour (four of them).
        let w = min(variance / (2.0 * s2), 0.25);
        flux += w * (power - b.power);
        shadow_sum += od * nb_shadow[k];
        deficit_sum += od;
    }
    var shadow = b.shadow;
    if (deficit_sum + own_deficit > 0.0) {
        shadow = (shadow_sum + own_deficit * b.shadow) / (deficit_sum + own_deficit);
    }
    return vec4<f32>(flux, shadow);
}

// How `beams_step` finds the beams it reads; a constant at each entry point, so that a CPU
// driver, which runs every branch a workgroup takes, compiles only what that pass needs.
// Every tile of the light window is stepped on every plane.
const LIGHT_WINDOW: u32 = 0u;
// Light tiles listed (`list_light_tile`) whose beams and neighbours were all stepped on the
// plane before.
const LIGHT_LISTED: u32 = 1u;
// Light tiles listed that start being stepped, or have a neighbour tile that was not stepped
// on the plane before: beams are found wherever they were stored (`load_beam_at`).
const LIGHT_EDGE: u32 = 2u;

// Beam b's segment from x0 to its position on plane z (b.pos): its power attenuated by the
// particles and the medium along it, its shadow depth moved to where, weighted by the power
// lost, the light was lost, and the data value at its end. Returns the segment's length.
fn attenuate(b: ptr<function, Beam>, x0: vec3<f32>, z: f32) -> f32 {
    let p = (*b).pos;
    let l = length(p - x0);
    let value = sample_value(p);
    let front = (*b).power;
    var power = front;
    if (max(power.r, max(power.g, power.b)) > 0.0) {
        let mid = sample_value(0.5 * (x0 + p));
        power *= segment_transmittance((*b).value, mid, value, l / P.plane.y, is_clipped(0.5 * (x0 + p)));
    }
    let loss = max(front.r - power.r, max(front.g - power.g, front.b - power.b));
    let deficit = max(1.0 - max(power.r, max(power.g, power.b)), 0.0);
    if (loss > 0.0 && deficit > 0.0) {
        let before = max(deficit - loss, 0.0);
        (*b).shadow = ((*b).shadow * before + 0.5 * (x0.z + z) * loss) / (before + loss);
    }
    (*b).power = power;
    (*b).value = value;
    return l;
}

// One beam from plane k-1 to plane k: drift, attenuation over the segment, soft light,
// deposit on plane k, kick (Eq. 8 and Snell at the new position). `tile`: ij's light tile;
// `mode`: LIGHT_WINDOW, LIGHT_LISTED or LIGHT_EDGE.
fn beams_step(ij: vec2<u32>, k: u32, tile: u32, mode: u32) {
    if (ij.x >= P.beam_grid.x || ij.y >= P.beam_grid.y) {
        return;
    }
    let index = ij.y * P.beam_grid.x + ij.x;
    let z = plane_z(k);
    let current = mode != LIGHT_EDGE;
    var b: Beam;
    if (current) {
        b = load_beam(ij, (k - 1u) % 2u, plane_z(k - 1u));
    } else {
        b = load_beam_at(ij, k - 1u, true);
    }
    let x0 = b.pos;
    b.pos = drift(b.pos, b.v, z);
    let d = light_direction(b.v);
    let lost_before = b.power;
    let value_front = b.value;
    let l = attenuate(&b, x0, z);

    // Neighbours on plane k: their drift needs only their stored state.
    let gi = vec2<i32>(ij);
    var du: vec3<f32>;
    var dv: vec3<f32>;
    var nb: array<Neighbour, 4>;
    // The power before this segment's attenuation (with the soft light's exchange), which the
    // view attenuates along its own light line (`beams_unscattered_through`, `beams_light_through`).
    var front = lost_before;
    if (REFRACTION || LIGHT_FILTER) {
        nb[0] = load_neighbour(gi - vec2<i32>(1, 0), k - 1u, z, tile, current);
        nb[1] = load_neighbour(gi + vec2<i32>(1, 0), k - 1u, z, tile, current);
        nb[2] = load_neighbour(gi - vec2<i32>(0, 1), k - 1u, z, tile, current);
        nb[3] = load_neighbour(gi + vec2<i32>(0, 1), k - 1u, z, tile, current);
    }
    if (REFRACTION) {
        du = cell_axis(b.pos, nb[0].pos, nb[1].pos);
        dv = cell_axis(b.pos, nb[2].pos, nb[3].pos);
    } else {
        let s = P.beam_origin.z;
        let z0 = P.plane.x;
        du = unproject(vec2<f32>(s, 0.0), z0) - unproject(vec2<f32>(0.0), z0);
        dv = unproject(vec2<f32>(0.0, s), z0) - unproject(vec2<f32>(0.0), z0);
    }

    if (LIGHT_FILTER) {
        // The neighbours' power after their own attenuation is not known yet; their power on
        // the previous plane lags the exchange by one segment, which the variance per step
        // (≪ the spacing²) makes negligible. Beyond the grid a beam is its own neighbour (no
        // exchange).
        var nb_power: array<vec3<f32>, 4>;
        var nb_shadow: vec4<f32>;
        var spacing: vec4<f32>;
        for (var n = 0u; n < 4u; n++) {
            if (nb[n].pos.w == 0.0) {
                nb_power[n] = b.power;
                nb_shadow[n] = b.shadow;
                spacing[n] = 1.0;
                continue;
            }
            nb_power[n] = nb[n].power;
            nb_shadow[n] = nb[n].shadow;
            if (n < 2u) {
                spacing[n] = length(du);
            } else {
                spacing[n] = length(dv);
            }
        }
        let f = diffuse(b, nb_power, nb_shadow, spacing, z, l);
        b.power = max(b.power + f.xyz, vec3<f32>(0.0));
        front = max(front + f.xyz, vec3<f32>(0.0));
        b.shadow = f.w;
    }

    if (!REFRACTION) {
        update_beam_power(front_power_region(k), ij, front);
    } else if (refracted_power_ring()) {
        store_beam_power(front_power_region(k), ij, front);
        // Not stepped on plane k-1 (read before this step stores its own state).
        let fresh = !current && u32(beam_texel(ij, BEAM_AUX, (k - 1u) % 2u).w) != k - 1u;
        if (fresh) {
            // The beam's first step: before it nothing had changed its power (its tile is
            // stepped from where its light can change), so it had this on the planes its
            // deposits reach back to. (A tile stays `LIGHT_EDGE` while a neighbour is not
            // stepped; its beams keep their history then.)
            for (var j = 1u; j < BACK_PLANES; j++) {
                if (j < k) {
                    store_beam_power(front_power_region(k - j), ij, front);
                }
            }
        }
    }
    if (SCATTER) {
        spread_step(ij, index, k, b, lost_before, x0, value_front, du, dv);
    }
    // How far the deposit of the footprint on plane k reaches (the kick below turns the beam,
    // it does not move it).
    var reach = 0.0;
    if (REFRACTION) {
        let w = footprint(b.pos, du, dv);
        reach = deposit_reach(b.pos.z, w);
        var deposited = b;
        if (deposits_front_power()) {
            deposited.power = front;
            if (refracted_power_ring() && max(front.r, max(front.g, front.b)) > 0.0) {
                // The power it had a voxel back, before its last m segments
                // (`beams_light_through`); none once it has left the sweep (turned back by
                // total internal reflection: its light is not carried on).
                let m = min(BACK_PLANES, k);
                deposited.power = load_beam_power(front_power_region(k + 1u - m), ij);
            }
        }
        deposit_beam(k, deposited, w, reach, hash(index ^ hash(k ^ 0x5bd1e995u)));
        let ix = index_at(b.pos);
        // Kick with the segment's path length (Eq. 8: v += Δs ∇η along the path).
        b.v = snell_renormalise(b.v + l * ix.grad, ix);
        if (safe_normalize(b.v).z < P.limits.x && guarded(SG_LIGHT_MIN_Z)) {
            // Turned back toward the light (total internal reflection) or into the plane: it
            // leaves the sweep, which only moves away from the light; nothing behind gets it.
            b.power = vec3<f32>(0.0);
        }
    }
    store_beam(ij, k % 2u, k, b);
    if (dark_tiles_end() && mode != LIGHT_WINDOW && max(front.r, max(front.g, front.b)) > 0.0) {
        atomicMax(&light_lit[tile], k);
    }
    if (REFRACTION && mode != LIGHT_WINDOW) {
        // A bent beam's end is found here; a straight one's on the CPU (`light_start.z`).
        if (reaches_box(b.pos, light_direction(b.v), reach)) {
            atomicStore(&light_alive[tile], k);
        }
    }
}

// Beam ij of listed light tile `tile` stepped on the planes a ..= last (`light_groups`): the
// steps `beams_step` takes for this variant one dispatch per plane, with the state carried
// in the invocation between planes. A beam keeps its cell, so its position on each plane
// follows from the plane, and its power goes through the rounding of the stored state
// (f16 unless F32_STATE) after every plane as it would between dispatches: the same light
// to the bit.
fn beams_steps(ij: vec2<u32>, a: u32, last: u32, tile: u32) {
    if (ij.x >= P.beam_grid.x || ij.y >= P.beam_grid.y) {
        return;
    }
    let start = light_start[tile].y;
    let first = max(a, start);
    if (first > last) {
        return;
    }
    var b: Beam;
    if (first == 1u || first != start) {
        b = load_beam(ij, (first - 1u) % 2u, plane_z(first - 1u));
    } else {
        b = load_beam_at(ij, first - 1u, true);
    }
    let p0 = unproject(beam_cell_centre(ij) - vec2<f32>(0.5), P.plane.x);
    var lit = 0u;
    for (var k = first; k <= last; k++) {
        if (k > first) {
            b.pos = unrefracted(p0, plane_z(k - 1u));
        }
        let z = plane_z(k);
        let x0 = b.pos;
        b.pos = drift(b.pos, b.v, z);
        let front = b.power;
        _ = attenuate(&b, x0, z);
        update_beam_power(front_power_region(k), ij, front);
        if (max(front.r, max(front.g, front.b)) > 0.0) {
            lit = k;
        }
        if (!F32_STATE) {
            b.power = vec4<f32>(unpack2x16float(pack2x16float(b.power.rg)), unpack2x16float(pack2x16float(vec2<f32>(b.power.b, 0.0)))).rgb;
        }
    }
    store_beam(ij, last % 2u, last, b);
    if (lit > 0u) {
        atomicMax(&light_lit[tile], lit);
    }
}

// The power budget (quality.max_concentration): a safeguard for extreme scenes; beams
// conserve power, so physically valid ones stay far below it.
fn budgeted(c: vec3<f32>) -> vec3<f32> {
    if (guarded(SG_CONCENTRATION)) {
        return min(c, vec3<f32>(P.budget.x));
    }
    return c;
}

// Power of beam cell c kept in region `region` of the power buffer (k % 2: on plane k;
// `front_power_region(k)`: before its segment to plane k), or the unobstructed source beyond
// the grid (light that is not refracted: beams keep their cells, so their power is the light
// there).
fn beam_cell_power(region: u32, c: vec2<i32>) -> vec3<f32> {
    if (c.x < 0 || c.y < 0 || c.x >= i32(P.beam_grid.x) || c.y >= i32(P.beam_grid.y)) {
        return vec3<f32>(1.0);
    }
    return load_beam_power(region, vec2<u32>(c));
}

// Without refraction: a bilinear lookup at p of the beams' cells' power in `region`.
fn beam_cells_at(region: u32, p: vec3<f32>) -> vec3<f32> {
    let g = grid_coords(p);
    let lo = floor(g);
    let f = g - lo;
    let a = vec2<i32>(lo);
    return mix(mix(beam_cell_power(region, a), beam_cell_power(region, a + vec2<i32>(1, 0)), f.x),
               mix(beam_cell_power(region, a + vec2<i32>(0, 1)), beam_cell_power(region, a + vec2<i32>(1, 1)), f.x), f.y);
}

// Without refraction: the light the beams carry unscattered at p on plane k.
fn beams_unscattered_at(k: u32, p: vec3<f32>) -> vec3<f32> {
    return beam_cells_at(k % 2u, p);
}

// Without refraction, the power each beam had on plane k-1 (before its segment to plane k) is
// kept beside its power on plane k, for `beams_unscattered_through`: for the last P.sweep.x
// planes, as many as a view pass advances its rays over and reads back (BACK_PLANES), plus the
// one being written. With refraction, where a voxel spans several planes
// (`refracted_power_ring`), each beam keeps its own for the planes of a voxel, and deposits
// the power it had that far back.
fn front_power_region(k: u32) -> u32 {
    return 2u + k % P.sweep.x;
}

// Whether refracted beams keep their power of the planes before (the image and the medium
// view, where a voxel spans several planes).
fn refracted_power_ring() -> bool {
    return REFRACTION && deposits_front_power() && BACK_PLANES > 1u;
}

// The light's last m segments to p (value: the data value there; m at most BACK_PLANES),
// along the source's direction back to the plane m planes before: their transmittance, with
// the segment function the beams use, and where the line crosses that plane. The loop runs
// BACK_PLANES times, the segments beyond m left out: a fixed count (see BACK_PLANES).
struct LightLine {
    transmittance: vec3<f32>,
    start: vec3<f32>,
}

fn light_line(p: vec3<f32>, value: f32, m: u32) -> LightLine {
    let back = P.light_dir.xyz * (P.plane.y / P.light_dir.z);
    var t = vec3<f32>(1.0);
    var q = p;
    var vq = value;
    for (var j = 0u; j < BACK_PLANES; j++) {
        if (j < m) {
            let b = q - back;
            let vb = sample_value(b);
            let mid = 0.5 * (b + q);
            t *= segment_transmittance(vb, sample_value(mid), vq, 1.0 / P.light_dir.z, is_clipped(mid));
            q = b;
            vq = vb;
        }
    }
    return LightLine(t, q);
}

// Without refraction: the light arriving at p on plane k (value: the data value there), with
// the attenuation of the last voxel of its way taken along p's own light line: the beams'
// power on plane k-m (m = BACK_PLANES, the planes in a voxel) where that line crosses it
// (bilinear over the same cells), times the transmittance from there to p, segment by
// segment. The beams' power on plane k is the same product at their cell centres, and
// bilinear between them it is wrong next to a surface that passes between two beams: a point
// just above the surface gets some of the light of the beam below it, one just under it some
// of the beam above, so a surface lit from the side is banded and too bright or too dark
// wherever the beams fall across it. A voxel back the light line is clear of most of that
// surface whatever the plane distance: a side-lit opaque slab is as bright as the
// Lommel–Seeliger law says within 14% at Δs = ¼ (20% one plane back; tests/steps.rs).
fn beams_unscattered_through(k: u32, p: vec3<f32>, value: f32) -> vec3<f32> {
    let m = min(BACK_PLANES, k);
    let line = light_line(p, value, m);
    return beam_cells_at(front_power_region(k + 1u - m), line.start) * line.transmittance;
}

// Whether the beams deposit their power from before the segment that ends on the plane (the
// image and the medium view, whose view rays attenuate it along their own light line:
// `beams_light_through`) or the power on the plane (the light views show it).
fn deposits_front_power() -> bool {
    return DEBUG_VIEW == 0u || DEBUG_VIEW == 4u;
}

// With refraction: the light arriving at p on plane k (value: the data value there). The beams
// deposited the power they had before their last m segments, m = BACK_PLANES (the planes in a
// voxel; `deposits_front_power`, `refracted_power_ring`), and those segments' attenuation is
// taken here along p's own light line, as `beams_unscattered_through` does without
// refraction: one plane back, at Δs = ¼, the beams next to a surface lit from the side still
// straddle it and the fine render's grounds were banded. The line runs along the source's
// direction, which is the light's outside refracting media (inside them, where it is not,
// the transmittance is near 1 unless the medium is also opaque).
fn beams_light_through(k: u32, p: vec3<f32>, value: f32) -> vec3<f32> {
    return beams_light_at(k, p).color * light_line(p, value, min(BACK_PLANES, k)).transmittance;
}

// Light arriving at the view-space point p on plane k (fluence relative to the source, and
// the power-weighted direction of travel). Without refraction the beams never leave their
// cells of the light grid, so the light is a bilinear lookup of their power; with refraction
// it is what they deposited, bilinear over the pixels, plus the unobstructed light outside
// the traced beams.
fn beams_light_at(k: u32, p: vec3<f32>) -> LightSample {
    if (!REFRACTION) {
        var c = beams_unscattered_at(k, p);
        if (SCATTER) {
            c += beams_scattered_at(k, p);
        }
        return LightSample(budgeted(c), P.light_dir.xyz);
    }
    let t = project(p);
    let deposited = deposited_at(deposit_slot(k), t);
    var color = deposited.color;
    var dir = deposited.dir;
    // Unobstructed light where no beam is traced (outside the volume's shadow), box-filtered
    // per pixel like the deposits and interpolated the same way.
    let outside = beam_region_outside(k);
    let lo = floor(t);
    let f = t - lo;
    for (var n = 0u; n < 4u; n++) {
        let o = vec2<u32>(n & 1u, n >> 1u);
        let w = select(1.0 - f.x, f.x, o.x == 1u) * select(1.0 - f.y, f.y, o.y == 1u);
        color += vec3<f32>(w * outside_fraction(lo + vec2<f32>(o), outside));
    }
    if (deposits_direction()) {
        if (dot(dir, dir) > 0.0) {
            dir = normalize(dir);
        } else {
            dir = P.light_dir.xyz;
        }
    } else {
        dir = P.light_dir.xyz;
    }
    return LightSample(budgeted(color), dir);
}

// The rect (pixel edges x0, y0, x1, y1 on plane k) that the traced beams cover when nothing
// deflects them: the beam grid's cells carried along the light.
fn beam_region_outside(k: u32) -> vec4<f32> {
    let z0 = P.plane.x;
    let z = plane_z(k);
    let e0 = P.beam_origin.xy;
    let e1 = e0 + vec2<f32>(P.beam_grid.xy) * P.beam_origin.z;
    let a = project(unrefracted(unproject(e0 - vec2<f32>(0.5), z0), z)) + vec2<f32>(0.5);
    let b = project(unrefracted(unproject(e1 - vec2<f32>(0.5), z0), z)) + vec2<f32>(0.5);
    return vec4<f32>(min(a, b), max(a, b));
}

// Fraction of pixel q (spanning [q, q + 1) in pixel-edge coordinates) outside the rect r.
fn outside_fraction(q: vec2<f32>, r: vec4<f32>) -> f32 {
    let ox = max(min(q.x + 1.0, r.z) - max(q.x, r.x), 0.0);
    let oy = max(min(q.y + 1.0, r.w) - max(q.y, r.y), 0.0);
    return 1.0 - ox * oy;
}

// ---------------------------------------------------------------------------------------
// Multiple scattering, spread mode (Premoze et al. 2004). The beam's power is the light that
// has not scattered (sharp: shadows, caustics). What the particles take out of it is split by
// the albedo ω into absorbed and scattered light; each beam carries its scattered light on,
// losing only what the medium absorbs, as a cloud about its path whose spread follows the
// exact moment equations of the transport (`transfer::scattering::SpreadMoments`) with the
// local scattering b = ω·extinction and anisotropy g. On each plane the cloud is deposited
// onto a pyramid of SCATTER_LEVELS levels with the cloud's variance.

// ω (x) and g (y) at data value v, linear between the table's entries.
fn scatter_coefficients(v: f32) -> vec2<f32> {
    return scatter_entry(v).xy;
}

// The scattering table's entry at data value v, linear between its entries
// (`transfer::scattering::scattering_table`).
fn scatter_entry(v: f32) -> vec4<f32> {
    let n = arrayLength(&scatter_table);
    let t = clamp(v, 0.0, 1.0) * f32(n - 1u);
    let i = min(u32(t), n - 2u);
    let f = t - f32(i);
    return mix(scatter_table[i], scatter_table[i + 1u], f);
}

// (1 − e^−x) / x, 1 at 0: the mean of e^−u over u in [0, x] (x may be negative).
fn spread_mean_exp(x: f32) -> f32 {
    if (abs(x) < 1e-3) {
        return 1.0 - x * (0.5 - x / 6.0);
    }
    return (1.0 - exp(-x)) / x;
}

// C = E[r⊥·d⊥] after a path t from (1 − P₂ = q0, C = c0) with y1 = k₁t, y2 = k₂t (k₁ = b(1 − g),
// k₂ = b(1 − g²)): the exact solution of dC/ds = (2/3)(1 − P₂) − k₁C with P₂ = (1 − q0)e^(−k₂s).
fn spread_cross(q0: f32, c0: f32, y1: f32, y2: f32, t: f32) -> f32 {
    let e1 = exp(-y1);
    return c0 * e1 + (2.0 / 3.0) * t * (spread_mean_exp(y1) - (1.0 - q0) * e1 * spread_mean_exp(y2 - y1));
}

// The moments (1 − P₂, C, R, ∫b ds) advanced over a path h with scattering optical depth bh and
// anisotropy g: 1 − P₂ and C exactly, R = R + 2∫C by Simpson's rule on the exact C (C is
// smooth on the scale 1/k₁, and a segment is a small part of it; the closed form of R would
// cancel to nothing in f32).
fn spread_moments(m: vec4<f32>, bh: f32, g: f32, h: f32) -> vec4<f32> {
    let y1 = bh * (1.0 - g);
    let y2 = bh * (1.0 - g * g);
    let q = m.x * exp(-y2) + y2 * spread_mean_exp(y2);
    let c_mid = spread_cross(m.x, m.y, 0.5 * y1, 0.5 * y2, 0.5 * h);
    let c_end = spread_cross(m.x, m.y, y1, y2, h);
    let r = m.z + (h / 3.0) * (m.y + 4.0 * c_mid + c_end);
    return vec4<f32>(q, c_end, r, m.w + bh);
}

// Adds `amount` at the point c (continuous pixel coordinates, pixel u spans [u, u + 1)) to
// level m of slot `slot`, split over the 2 × 2 texels around it so that the level's bilinear
// lookup keeps its centre. Returns nothing; see `spread_variance` for the spread it leaves.
fn deposit_point(slot: u32, m: u32, c: vec2<f32>, amount: vec3<f32>, seed: u32) {
    let s = f32(1u << m);
    let cl = c / s - vec2<f32>(0.5);
    let q0 = floor(cl);
    let f = cl - q0;
    let a = amount / (s * s);
    for (var n = 0u; n < 4u; n++) {
        let o = vec2<u32>(n & 1u, n >> 1u);
        let q = vec2<i32>(q0) + vec2<i32>(o);
        let weight = select(1.0 - f.x, f.x, o.x == 1u) * select(1.0 - f.y, f.y, o.y == 1u);
        if (weight > 0.0 && level_texel_in_rect(m, q)) {
            let h = hash(seed ^ (u32(q.x) * 73856093u) ^ (u32(q.y) * 19349663u) ^ (m * 83492791u));
            add_light(acc_texel(slot, m, vec2<u32>(q)), a, weight, P.light_dir.xyz, f32(h & 0xffffu) / 65536.0);
        }
    }
}

// Variance per axis (pixels², averaged over the two axes) of what `deposit_point` leaves on
// level m as the pyramid reads it back: the split's own f(1 − f)s² plus the bilinear tent's
// s²/6.
fn spread_variance(m: u32, c: vec2<f32>) -> f32 {
    let s = f32(1u << m);
    let f = fract(c / s - vec2<f32>(0.5));
    let split = 0.5 * (f.x * (1.0 - f.x) + f.y * (1.0 - f.y));
    return s * s * (split + 1.0 / 6.0);
}

// Deposits a cloud of light with variance `variance` per axis (pixels²) centred at c: split
// between the two adjacent levels whose deposits bracket the variance, in the proportion
// that gives it (a mixture's variance is the weighted mean of its parts'). Below level 0's
// least it is level 0's; beyond the coarsest level's, the coarsest level's (narrower).
fn deposit_cloud(slot: u32, c: vec2<f32>, variance: f32, amount: vec3<f32>, seed: u32) {
    var lo = 0u;
    var beta = 0.0;
    var v_lo = spread_variance(0u, c);
    if (variance > v_lo) {
        lo = SCATTER_LEVELS - 1u;
        for (var m = 0u; m + 1u < SCATTER_LEVELS; m++) {
            let v_hi = spread_variance(m + 1u, c);
            if (variance <= v_hi) {
                lo = m;
                beta = (variance - v_lo) / (v_hi - v_lo);
                break;
            }
            v_lo = v_hi;
        }
    }
    if (beta < 1.0) {
        deposit_point(slot, lo, c, amount * (1.0 - beta), seed);
    }
    if (beta > 0.0) {
        deposit_point(slot, lo + 1u, c, amount * beta, seed ^ 0x9e3779b9u);
    }
}

// The fourth moment across the beam, F = E[|r⊥|⁴], which shapes the deposited cloud
// (`transfer::scattering::SpreadMoments` gives its equations): with u = d⊥, M = E[(r⊥·u)|u|²],
// H = E[(r⊥·u)²], K = E[|r⊥|²|u|²], G = E[|r⊥|²(r⊥·u)] and k_l = b(1 − g^l),
//
//   dM/ds = E[|u|⁴] + (4/5)(k₃ − k₁)C − k₃M,  dH/ds = 2M + (k₂/3)R − k₂H,
//   dK/ds = 2M + (2k₂/3)R − k₂K,  dG/ds = 2H + K − k₁G,  dF/ds = 4G,
//
// E[|u|⁴] = (8/15)(1 − (10/7)P₂ + (3/7)P₄). Kept per beam: (1 − P₄, M, H, K) and (G, F).
struct Fourth {
    q4: f32,
    m: f32,
    h: f32,
    k: f32,
    g: f32,
    f: f32,
    c: f32,  // C and R, integrated alongside (the second moments kept are `spread_moments`')
    r: f32,
}

// The exact step over t of dy/dt = s − ky with s held, for k = k₁, k₂, k₃ (x, y, z): y·e + s·w
// with e = e^(−kt) and w = t·(1 − e^(−kt))/(kt).
struct Relaxation {
    e: vec3<f32>,
    w: vec3<f32>,
}

fn relaxation(k: vec3<f32>, t: f32) -> Relaxation {
    let e = exp(-k * t);
    var r: Relaxation;
    r.e = e;
    for (var i = 0; i < 3; i++) {
        r.w[i] = t * spread_mean_exp_of(k[i] * t, e[i]);
    }
    return r;
}

// y advanced by the relaxation r with the rates at `at` held (P₂ and P₄ there); k = (k₁, k₂,
// k₃).
fn fourth_relaxed(y: Fourth, at: Fourth, p2: f32, p4: f32, k: vec3<f32>, r: Relaxation, t: f32) -> Fourth {
    let sine2 = (2.0 / 3.0) * (1.0 - p2);
    let sine4 = (8.0 / 15.0) * (1.0 - (10.0 / 7.0) * p2 + (3.0 / 7.0) * p4);
    var o = y;
    o.c = y.c * r.e.x + sine2 * r.w.x;
    o.r = y.r + 2.0 * at.c * t;
    o.m = y.m * r.e.z + (sine4 + 0.8 * (k.z - k.x) * at.c) * r.w.z;
    o.h = y.h * r.e.y + (2.0 * at.m + (k.y / 3.0) * at.r) * r.w.y;
    o.k = y.k * r.e.y + (2.0 * at.m + (2.0 * k.y / 3.0) * at.r) * r.w.y;
    o.g = y.g * r.e.x + (2.0 * at.h + at.k) * r.w.x;
    o.f = y.f + 4.0 * at.g * t;
    return o;
}

// The fourth-moment state y advanced over a path h with scattering optical depth bh and
// anisotropy g, from 1 − P₂ = q0: exponential midpoint steps (second order; stable at any
// optical depth, where the moments relax to the rates they are driven at) of at most one
// relaxation length, 4 at most; P₂ and P₄ exact.
fn spread_fourth(y0: Fourth, q0: f32, bh: f32, g: f32, h: f32) -> Fourth {
    var y = y0;
    if (h <= 0.0) {
        return y;
    }
    let b = bh / h;
    let g2 = g * g;
    let k = b * vec3<f32>(1.0 - g, 1.0 - g2, 1.0 - g2 * g);
    let k4 = b * (1.0 - g2 * g2);
    let n = u32(clamp(ceil(max(max(k.x, k.y), max(k.z, k4)) * h), 1.0, 4.0));
    let dt = h / f32(n);
    let half_step = relaxation(k, 0.5 * dt);
    let whole = relaxation(k, dt);
    // P₂ and P₄ at the start and the middle of each step.
    var p2 = 1.0 - q0;
    var p4 = 1.0 - y0.q4;
    let e4 = exp(-0.5 * k4 * dt);
    for (var i = 0u; i < n; i++) {
        let mid = fourth_relaxed(y, y, p2, p4, k, half_step, 0.5 * dt);
        p2 *= half_step.e.y;
        p4 *= e4;
        y = fourth_relaxed(y, mid, p2, p4, k, whole, dt);
        p2 *= half_step.e.y;
        p4 *= e4;
    }
    y.q4 = 1.0 - p4;
    return y;
}

// The two parts of a cloud of kurtosis `kurtosis` (E[|r|⁴] / (2E[|r|²]²)): (share, variance
// relative to the cloud's) of its core (xy) and wings (zw); `transfer::scattering::
// core_and_wings`, with CLOUD_CORE_SHARE 0.5.
fn spread_cloud_parts(kurtosis: f32) -> vec4<f32> {
    let excess = kurtosis - 1.0;
    if (!(excess > 0.0)) {
        return vec4<f32>(0.5, 1.0, 0.5, 1.0);
    }
    let f = max(0.5, 1.0 - 1.0 / kurtosis);
    let core = max(1.0 - sqrt(excess * (1.0 - f) / f), 0.0);
    return vec4<f32>(f, core, 1.0 - f, (1.0 - f * core) / (1.0 - f));
}

// Light scattered back out of the face a beam entered by. Besides the transverse moments the
// beam carries the longitudinal ones of its light: with w = s − z the lag of a photon behind
// the beam (w' = 1 − μ),
//
//   dE[wμ]/ds = P₁ − (1 + 2P₂)/3 − k₁E[wμ],  dE[w²]/ds = 2(E[w] − E[wμ]),
//
// (E[w] is the lag; `SpreadMoments` mirrors them), the path since the medium began and the
// cosine θ between the light and the normal of the face where it began. The scattered light's
// depth below that face is then (path − E[w])·cos θ with variance Var[w]·cos²θ + (transverse
// variance)·sin²θ (over the scattered fraction); the part of the cloud that a Gaussian of
// those puts behind the face has left the medium there. Free transport puts behind the face
// only the photons that are outside now, not those that crossed it and came back in, so this
// is the least the face reflects.

// (1 − e^−x) / x from ex = e^−x (`spread_mean_exp` without a second exponential).
fn spread_mean_exp_of(x: f32, ex: f32) -> f32 {
    if (abs(x) < 1e-3) {
        return 1.0 - x * (0.5 - x / 6.0);
    }
    return (1.0 - ex) / x;
}

// E[wμ] after a path t from d0, with y1 = k₁t, y2 = k₂t, e1 = e^−y1, e21 = e^−(y2 − y1) and
// P₁ = p1·e^(−k₁s), P₂ = p2·e^(−k₂s) along it: the exact solution,
// d0·e1 + t·(p1·e1 − mean_exp(y1)/3 − (2/3)·p2·e1·mean_exp(y2 − y1)).
fn wmu_after(d0: f32, p1: f32, p2: f32, y1: f32, y2: f32, e1: f32, e21: f32, t: f32) -> f32 {
    let m1 = spread_mean_exp_of(y1, e1);
    let m21 = spread_mean_exp_of(y2 - y1, e21);
    return d0 * e1 + t * (p1 * e1 - m1 / 3.0 - (2.0 / 3.0) * p2 * e1 * m21);
}

// The entry state (path since the medium began, cos θ at the face, E[wμ], E[w²]) advanced
// over a path h with scattering optical depth bh and anisotropy g, from the moments m and lag
// w before it; p1 = P₁ before it, lag the lag after it.
fn spread_entry(e: vec4<f32>, m: vec4<f32>, w: f32, lag: f32, p1: f32, bh: f32, g: f32, h: f32) -> vec4<f32> {
    let y1 = bh * (1.0 - g);
    let y2 = bh * (1.0 - g * g);
    let p2 = 1.0 - m.x;
    // E[wμ] exactly; E[w²] by Simpson's rule on E[w] − E[wμ] (E[w] exact).
    let e1_half = exp(-0.5 * y1);
    let e21_half = exp(-0.5 * (y2 - y1));
    let d_mid = wmu_after(e.z, p1, p2, 0.5 * y1, 0.5 * y2, e1_half, e21_half, 0.5 * h);
    let d_end = wmu_after(e.z, p1, p2, y1, y2, e1_half * e1_half, e21_half * e21_half, h);
    let w_mid = w + 0.5 * h * (1.0 - p1 * spread_mean_exp_of(0.5 * y1, e1_half));
    let w2 = e.w + (h / 3.0) * ((w - e.z) + 4.0 * (w_mid - d_mid) + (lag - d_end));
    return vec4<f32>(e.x + h, e.y, d_end, w2);
}

// |cos θ| between the light and the normal of the medium's face at p (the data value's
// gradient); 1 where the value has no gradient there (the medium fades in).
fn entry_cosine(p: vec3<f32>) -> f32 {
    let grad = value_gradient(p, P.plane.y);
    let len = length(grad);
    if (len < 1e-6) {
        return 1.0;
    }
    return abs(dot(grad, P.light_dir.xyz)) / len;
}

// Φ(−x), the normal distribution's tail beyond x (Bowling et al. 2009's logistic fit to the
// normal CDF, error below 1.4e-4).
fn normal_tail(x: f32) -> f32 {
    return 1.0 / (1.0 + exp(clamp(1.5976 * x + 0.070566 * x * x * x, -80.0, 80.0)));
}

// The fraction of the scattered light behind the face its beam entered by (moments m, lag
// w, entry state e; frac = 1 − e^−m.w, the part of the light that has scattered).
fn spread_behind(m: vec4<f32>, w: f32, e: vec4<f32>, frac: f32) -> f32 {
    if (frac < 1e-6) {
        return 0.0;
    }
    let mean_w = w / frac;
    let var_w = max(e.w / frac - mean_w * mean_w, 0.0);
    let var_t = 0.5 * m.z / frac;
    let c = e.y;
    let depth = (e.x - mean_w) * c;
    let var_n = var_w * c * c + var_t * (1.0 - c * c);
    if (var_n <= 0.0) {
        return select(0.0, 1.0, depth < 0.0);
    }
    return normal_tail(depth / sqrt(var_n));
}

// Light that leaves through the medium's sides. Free transport spreads a beam's cloud as if
// the medium went on around it; where it ends across the beam, what reaches the edge leaves
// (a convex medium does not take it back) and what stays is thinned next to the edge, as a
// diffusion's light is next to a boundary that absorbs it (the method of images). The cloud
// is taken as its Gaussian cut where the medium ends along the two axes across the light
// (the edge's distance found by a few samples along each of the four directions, up to 2.5
// standard deviations); what lies beyond leaves, as through the lit face, and what stays is
// deposited with the cut Gaussian's mean and variance: moved away from the edge and
// narrowed. Only while the cloud's centre is in the medium: once it has left through the
// far face, the cloud is light on its way out and goes on as it is. The data's own box is not
// an edge: a medium that reaches it (a slab, tissue the scan cut) goes on beyond it here.

// Whether the particles at p scatter: the value, taken within the data's box, is nearer to
// table entries where opacity and albedo are above 0 than to others
// (`transfer::scattering::scattering_table`).
fn scatters_at(p: vec3<f32>) -> bool {
    let c = clamp(volume_coord(p), 0.5 * P.texel.xyz, vec3<f32>(1.0) - 0.5 * P.texel.xyz);
    return scatter_entry(textureSampleLevel(volume_tex, volume_sampler, c, 0.0).r).z > 0.5;
}

// Distances (in standard deviations) along a direction at which the medium's edge is looked
// for; beyond the last there is taken to be none.
const EDGE_STEPS: array<f32, 4> = array<f32, 4>(0.5, 1.0, 1.5, 2.5);
const NO_EDGE: f32 = 8.0;

// The distance, in standard deviations sigma, from `centre` along `dir` to where the
// scattering medium ends: halfway between the last step inside and the first outside (the
// steps scaled by `jitter`), or NO_EDGE where the last step is inside (tested first: deep
// in a medium one sample per direction; a gap narrower than the steps goes unseen). The
// steps' scale is dithered per beam and plane: a distance that jumped from beam to beam by a
// step's width would draw contours in the light they deposit, where dithered it is noise
// that the overlapping clouds average out.
fn edge_distance(centre: vec3<f32>, dir: vec3<f32>, sigma: f32, jitter: f32) -> f32 {
    if (scatters_at(centre + dir * (EDGE_STEPS[3] * jitter * sigma))) {
        return NO_EDGE;
    }
    var inside = 0.0;
    for (var j = 0u; j < 3u; j++) {
        let t = EDGE_STEPS[j] * jitter;
        if (!scatters_at(centre + dir * (t * sigma))) {
            return 0.5 * (inside + t);
        }
        inside = t;
    }
    return 0.5 * (inside + EDGE_STEPS[3] * jitter);
}

// The unit normal distribution restricted to [lo, hi]: its mass, mean and variance.
fn cut_normal(lo: f32, hi: f32) -> vec3<f32> {
    let mass = max(normal_tail(-hi) - normal_tail(-lo), 1e-6);
    let pdf_lo = 0.39894228 * exp(-0.5 * lo * lo);
    let pdf_hi = 0.39894228 * exp(-0.5 * hi * hi);
    let mean = (pdf_lo - pdf_hi) / mass;
    let variance = max(1.0 + (lo * pdf_lo - hi * pdf_hi) / mass - mean * mean, 0.0);
    return vec3<f32>(mass, mean, variance);
}

// A cloud about `centre` with variance sigma² per axis across the light, cut where the
// medium ends along each axis: the share of it within the medium, that part's variance
// relative to sigma² (the mean over the two axes) and its mean's shift.
struct CutCloud {
    kept: f32,
    variance: f32,
    shift: vec3<f32>,
}

fn cut_cloud(centre: vec3<f32>, sigma: f32, jitter: f32) -> CutCloud {
    var cloud = CutCloud(1.0, 1.0, vec3<f32>(0.0));
    let d = P.light_dir.xyz;
    // Two axes across the light.
    var e1 = cross(d, vec3<f32>(0.0, 1.0, 0.0));
    if (dot(e1, e1) < 1e-6) {
        e1 = cross(d, vec3<f32>(1.0, 0.0, 0.0));
    }
    e1 = normalize(e1);
    let e2 = cross(d, e1);
    var variance = 0.0;
    for (var a = 0u; a < 2u; a++) {
        let axis = select(e1, e2, a == 1u);
        let cut = cut_normal(-edge_distance(centre, -axis, sigma, jitter), edge_distance(centre, axis, sigma, jitter));
        cloud.kept *= cut.x;
        cloud.shift += axis * (cut.y * sigma);
        variance += 0.5 * cut.z;
    }
    cloud.variance = variance;
    return cloud;
}

// One segment of the spread mode for beam `index`, whose unscattered power went from
// `u_before` to b.power over the segment from x0 to b.pos (front value `value_front`, back
// value b.value); deposits its scattered light on plane k. du, dv: the beam's cell.
fn spread_step(ij: vec2<u32>, index: u32, k: u32, b: Beam, u_before: vec3<f32>, x0: vec3<f32>, value_front: f32, du: vec3<f32>, dv: vec3<f32>) {
    // This beam's texels of plane k-1's half (read) and of plane k's (written).
    let t = beam_pair_texel(ij, (k - 1u) % 2u);
    let tw = beam_pair_texel(ij, k % 2u);
    let a = textureLoad(beam_scatter, t, 0);
    var scattered = a.rgb;
    let l = length(b.pos - x0);
    let ratio = l / P.plane.y;
    let mid = 0.5 * (x0 + b.pos);
    let split = segment_split(value_front, sample_value(mid), b.value);
    let alpha = split_particles(value_front, split, b.value, ratio, is_clipped(mid)).a;
    var t_medium = vec3<f32>(1.0);
    if (MEDIUM) {
        t_medium = split_medium(value_front, split, b.value, ratio);
    }
    let tau = -log(max(1.0 - alpha, 1e-30));
    let sc = scatter_coefficients(split.y);
    let albedo = clamp(sc.x, 0.0, 1.0);
    let m_before = textureLoad(beam_scatter, t, 1);
    let e_before = textureLoad(beam_scatter, t, 2);
    let m = spread_moments(m_before, albedo * tau, sc.y, l);
    let f_before = textureLoad(beam_scatter, t, 3);
    let gf_before = textureLoad(beam_scatter, t, 4);
    let fourth = spread_fourth(Fourth(f_before.x, f_before.y, f_before.z, f_before.w, gf_before.x, gf_before.y, m_before.y, m_before.z), m_before.x, albedo * tau, sc.y, l);
    // The lag of all the light behind the beam, s − E[z]: it grows by ∫(1 − P₁) over the
    // segment, P₁ = e^{−(1−g)∫b} at the local g (exact where g is constant).
    let y1 = (1.0 - sc.y) * albedo * tau;
    let p1 = exp(-(1.0 - sc.y) * m_before.w);
    let lag = a.w + l * (1.0 - p1 * spread_mean_exp(y1));
    let frac = m.w * spread_mean_exp(m.w);
    // The scattered light's own spread per axis: R is that of all the light, whose
    // unscattered part 1 − (1 − e^−∫b) stays on the axis. Its centroid lags behind the beam
    // by lag / (1 − e^−∫b) (the unscattered part is on the beam).
    let spread = 0.5 * m.z / max(frac, 1e-12);
    let behind = lag / max(frac, 1e-12);
    var centre = b.pos - P.light_dir.xyz * behind;
    var e = e_before;
    var left = 0.0;
    // The share of the cloud beyond the medium's sides so far (`cut_cloud`).
    let outside_before = gf_before.z;
    var outside = outside_before;
    var narrowing = 1.0;
    if (m.w > 0.0) {
        e = spread_entry(e_before, m_before, a.w, lag, p1, albedo * tau, sc.y, l);
        if (m_before.w <= 0.0) {
            e.y = entry_cosine(mid);
        }
        // The part of the cloud that crossed back out through the face it entered by since
        // the last plane leaves the medium (a fraction of what the cloud held).
        let behind_before = spread_behind(m_before, a.w, e_before, m_before.w * spread_mean_exp(m_before.w));
        let behind_now = spread_behind(m, lag, e, frac);
        left = max(behind_now - behind_before, 0.0) / max(1.0 - behind_before, 1e-6);
        // What reached beyond the sides since the last plane leaves too; the rest is
        // deposited as the cut cloud.
        if (frac > 1e-6 && scatters_at(centre)) {
            // Step scales from 0.75 to 1.25 (`edge_distance`).
            let jitter = 0.75 + 0.5 * f32(hash(index ^ hash(k ^ 0x68e31da4u)) & 0xffffu) / 65536.0;
            let cut = cut_cloud(centre, sqrt(spread), jitter);
            outside = max(1.0 - cut.kept, outside_before);
            left = 1.0 - (1.0 - left) * (1.0 - (outside - outside_before) / max(1.0 - outside_before, 1e-6));
            centre += cut.shift;
            narrowing = cut.variance;
        }
    }
    // Scattered light goes on losing only what is absorbed: (1 − ω) of the extinction, and
    // the medium; the unscattered light gives it ω of what the particles took.
    scattered = scattered * (1.0 - left) * exp(-(1.0 - albedo) * tau) * t_medium + u_before * alpha * albedo * t_medium;
    textureStore(beam_scatter, tw, 0, vec4<f32>(scattered, lag));
    textureStore(beam_scatter, tw, 1, m);
    textureStore(beam_scatter, tw, 2, e);
    textureStore(beam_scatter, tw, 3, vec4<f32>(fourth.q4, fourth.m, fourth.h, fourth.k));
    textureStore(beam_scatter, tw, 4, vec4<f32>(fourth.g, fourth.f, outside, 0.0));
    if (max(scattered.r, max(scattered.g, scattered.b)) <= 0.0) {
        return;
    }
    // Deposited at the centroid seen along the view axis, with the spread in pixels² on this
    // plane (a pixel's side there: sqrt(pixel_area)) plus the cell's own box footprint.
    let c = project(vec3<f32>(centre.xy, b.pos.z)) + vec2<f32>(0.5);
    let pu = project(b.pos + du) - project(b.pos);
    let pv = project(b.pos + dv) - project(b.pos);
    let cell = (dot(pu, pu) + dot(pv, pv)) / 24.0;
    // The cloud as a core and wings with its second and fourth moments (the scattered
    // light's: F·frac / (2R²)), each with the cell's footprint.
    let kurtosis = fourth.f * frac / max(2.0 * m.z * m.z, 1e-30);
    let parts = spread_cloud_parts(kurtosis);
    let amount = scattered * deposit_scale(b.pos.z, P.light_dir.xyz);
    let seed = hash(index ^ hash(k ^ 0x27d4eb2fu));
    let v = narrowing * spread / pixel_area(b.pos.z);
    if (parts.y == parts.w) {
        deposit_cloud(deposit_slot(k), c, v + cell, amount, seed);
    } else {
        deposit_cloud(deposit_slot(k), c, parts.y * v + cell, amount * parts.x, seed);
        deposit_cloud(deposit_slot(k), c, parts.w * v + cell, amount * parts.z, seed ^ 0x85ebca6bu);
    }
}

// The scattered light on plane k at the view-space point p (fluence relative to the source).
fn beams_scattered_at(k: u32, p: vec3<f32>) -> vec3<f32> {
    return deposited_at(deposit_slot(k), project(p)).color;
}

// The light a particle at p on plane k sends into the direction `toward` (unit), relative to
// isotropic scattering: the unscattered part of `total` (all the light there) through the
// phase function at the particle's g for the fraction ω it scatters (single scattering), the
// rest shaded as without scattering (the colour transfer function's diffuse particles); the
// scattered part as it is (multiply scattered light is near-isotropic).
// Spread mode runs without refraction, so `beams_light_at` is the cells' light plus the
// scattered light; each is read once here (the deposits are atomics, which a compiler may not
// merge with the same reads elsewhere).
fn spread_seen(k: u32, p: vec3<f32>, toward: vec3<f32>, value: f32) -> vec3<f32> {
    let s = beams_scattered_at(k, p);
    let total = budgeted(beams_unscattered_through(k, p, value) + s);
    let sc = scatter_coefficients(value);
    let phase = mix(1.0, hg_relative(dot(P.light_dir.xyz, toward), sc.y), clamp(sc.x, 0.0, 1.0));
    return max(total - s, vec3<f32>(0.0)) * phase + s;
}
