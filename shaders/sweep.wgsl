// One plane of the sweep (Algorithm 1, lines 5–37). Plane k is two dispatches that need no
// barrier between them: `light_main` moves the light from plane k-1 to plane k, `view_main`
// moves the view rays one plane behind, from k-2 to k-1, so that both ends of their segment
// have complete light. Light lives in a ring of three planes. They are separate dispatches,
// not two branches of one: a CPU driver runs every branch a workgroup's invocations take.
// Where the light stays where the light pass left it (beams without refraction keep each
// plane's power in a ring of `sweep.x` planes), plane k's `view_main` may instead move the
// rays over the planes since the last view pass, up to k-1 (`view_steps`), keeping their
// state in the invocation between planes; the planes in between have no view pass.

@compute @workgroup_size(TILE * TILE, 1, 1)
fn light_main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    P = params;
    copy_deposit_header();
    let k = dispatch_plane(wg);
    if (BEAMS && light_tiles_listed()) {
        // With light tiles listed this pass is not the light's: after a view pass over
        // several planes, once `tiles_main` has ended the tiles that end, it lists those
        // that go on for each of the next pass's planes, k+1 ..= k+view_steps (one
        // invocation per light tile).
        let t = (wg.y * P.tiles.z + wg.x) * TILE * TILE + li;
        list_light_tile_planes(t, k + 1u, k + I.view_steps, (I.view_list + 1u) % 2u);
        return;
    }
    // The cells that can still reach the image on this plane or a later one: a window of
    // the light grid, in tiles (`light_windows` in state.rs).
    let window = light_window[k];
    let group = wg.y * P.tiles.z + wg.x;
    if (group >= window.w) {
        return;
    }
    let tile = window.xy + vec2<u32>(group % window.z, group / window.z);
    let ij = tile * TILE + vec2<u32>(li % TILE, li / TILE);
    if (BEAMS) {
        beams_step(ij, k, tile.y * P.beam_grid.z + tile.x, LIGHT_WINDOW);
    } else {
        backward_step(ij, k);
    }
}

// Beams with light tiles listed: the tiles of list `list` (LIGHT_LISTED or LIGHT_EDGE) for
// plane k, the plane view_steps of the view pass view_list, one per workgroup (indirect,
// `list_light_tile`).
fn light_listed(wg: vec3<u32>, li: u32, list: u32) {
    let t = light_list_tile(wg, list);
    beams_step(light_tile_beam(t, li), dispatch_plane(wg), t, list);
}

// The light tile of workgroup wg in list `list` (LIGHT_LISTED or LIGHT_EDGE) of the plane
// view_steps of the view pass view_list.
fn light_list_tile(wg: vec3<u32>, list: u32) -> u32 {
    let group = wg.y * P.tiles.z + wg.x;
    let slot = light_list_slot(I.view_list % 2u, I.view_steps, list - LIGHT_LISTED);
    return light_lists[slot * P.beam_grid.w + group];
}

// Beam `li` (row by row) of light tile t.
fn light_tile_beam(t: u32, li: u32) -> vec2<u32> {
    let tile = vec2<u32>(t % P.beam_grid.z, t / P.beam_grid.z);
    return tile * TILE + vec2<u32>(li % TILE, li / TILE);
}

@compute @workgroup_size(TILE * TILE, 1, 1)
fn light_listed_main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    P = params;
    copy_deposit_header();
    light_listed(wg, li, LIGHT_LISTED);
}

@compute @workgroup_size(TILE * TILE, 1, 1)
fn light_edge_main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    P = params;
    copy_deposit_header();
    if (light_groups()) {
        // No edge list: the tiles listed for planes k ..= k + view_steps - 1 (the first
        // list of the view pass's parity), each stepped over those planes.
        let k = dispatch_plane(wg);
        let group = wg.y * P.tiles.z + wg.x;
        let t = light_lists[light_list_slot(I.view_list % 2u, 0u, 0u) * P.beam_grid.w + group];
        let last = min(k + I.view_steps - 1u, u32(P.plane.z) - 1u);
        beams_steps(light_tile_beam(t, li), k, last, t);
        return;
    }
    if (halves_hold_state()) {
        // No tile is stepped at the edge: the edge list holds the tiles that end on this
        // plane, whose beams keep their last state in both halves.
        freeze_beam(light_tile_beam(light_list_tile(wg, LIGHT_EDGE), li), dispatch_plane(wg));
        return;
    }
    light_listed(wg, li, LIGHT_EDGE);
}

// Pixel of invocation `li` of rect tile `tile`.
fn tile_pixel(tile: u32, li: u32) -> vec2<u32> {
    return P.rect.xy + vec2<u32>(tile % P.tiles.x, tile / P.tiles.x) * TILE + vec2<u32>(li % TILE, li / TILE);
}

@compute @workgroup_size(TILE * TILE, 1, 1)
fn view_main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    P = params;
    copy_lbm_grid();
    let k = dispatch_plane(wg);
    // Without refraction a view pass may advance its rays over several planes, whose light
    // is complete (`view_steps`): their state stays in the invocation, not in a dispatch each.
    let steps = I.view_steps + wg.z;
    let group = wg.y * P.tiles.z + wg.x;
    var tile = group;
    if (k >= 2u && (P.culling.w & 1u) == 1u) {
        // Only the tiles listed for this pass were dispatched (indirect).
        tile = tile_lists[(I.view_list % 3u) * P.tiles.y + group];
    } else if (group >= P.tiles.y) {
        return;
    }
    let px = tile_pixel(tile, li);
    if (!in_rect(vec2<i32>(px))) {
        return;
    }
    if (DEBUG_VIEW == 1u || DEBUG_VIEW == 2u || DEBUG_VIEW == 3u) {
        return; // light diagnostics need no view rays
    }
    if (k == 1u) {
        view_first_light(px);
    } else if (k >= 2u && view_spans_planes()) {
        view_steps(px, k - steps, k - 1u, tile);
    } else if (k >= 2u) {
        view_step(px, k - 1u, tile);
    }
}

// Per rect tile, one invocation each (a workgroup whose invocations have nothing to do still
// costs its launch on a CPU driver: at 256², 1024 of them per plane took a tenth of a plain
// render; the slot the next plane deposits into is cleared by a buffer fill): after a view
// pass, the tile is listed for the next one (which advances the rays over the next
// I.view_steps planes) if it needs it: a ray alive whose next segments (or the one after,
// so that a ray is stepped onto the plane before it has something to composite) meet a
// visible brick (with refraction, or one where η changes) along the rays' primary lines. Rays
// once bent can be anywhere: their tile (VIEW_TILE_BENT) only needs a ray alive. Written while
// plane k runs, so a tile whose last ray dies on plane k may be listed once more (its
// invocations then find nothing to do); with refraction a barrier makes plane k's bends seen.
@compute @workgroup_size(TILE * TILE, 1, 1)
fn tiles_main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    P = params;
    let k = dispatch_plane(wg);
    let group = wg.y * P.tiles.z + wg.x;
    let t = group * TILE * TILE + li;
    if (t >= P.tiles.y) {
        if (BEAMS && light_tiles_listed()) {
            // After a view pass, the workgroups after the view tiles' list the light tiles of
            // the next one's planes, k+1 ..= k+next, one per invocation (plane k's light is
            // complete: a barrier separates this pass from it), in the lists of its parity.
            // The other parity's lists (the pass just done) start empty.
            let lt = t - P.tiles.y;
            let next = I.view_steps + wg.z;
            if (next == 0u) {
                return;
            }
            if (lt < 2u * LIST_PLANES) {
                atomicStore(&light_args[light_list_slot(I.view_list % 2u, lt / 2u, lt % 2u) * 3u], 0u);
            }
            let parity = (I.view_list + 1u) % 2u;
            // The ends, written once (a CPU driver runs every branch a workgroup takes, so a
            // call in each would test the tile as many times).
            let goes_on = light_tile_goes_on(lt, k + 1u, k + next);
            if (halves_hold_state() && !goes_on && lt < P.beam_grid.w
                && atomicLoad(&light_end[lt]) == k + 1u) {
                // Ended from plane k+1 on: its state copied to the other half on that plane
                // (`freeze_beam`, the edge pass).
                append_light_tile(lt, light_list_slot(parity, 0u, 1u));
            }
            if (light_groups()) {
                // One list: a dispatch steps the tiles over all the planes.
                if (goes_on) {
                    append_light_tile(lt, light_list_slot(parity, 0u, 0u));
                }
            } else if (next == 1u && goes_on) {
                // One plane: listed with its ends. For several, the lists per plane read the
                // neighbours' ends (`light_main`).
                list_going_light_tile(lt, k + 1u, parity);
            }
        }
        return;
    }
    let next = I.view_steps + wg.z;
    if ((P.culling.w & 1u) == 0u || next == 0u) {
        return;
    }
    if (t == 0u) {
        // The list after next starts empty (its last reader was the view pass before).
        atomicStore(&tile_args[((I.view_list + 2u) % 3u) * 3u], 0u);
    }
    let rays = atomicLoad(&view_tiles[t]);
    if ((rays & ~VIEW_TILE_BENT) == 0u) {
        return;
    }
    // Rays not bent yet are on their primary lines: empty bricks there can be skipped (with
    // refraction the bricks also count where η changes), unless the render steps them all.
    if ((rays & VIEW_TILE_BENT) == 0u && (P.culling.w & 4u) != 0u) {
        let lo = vec2<f32>(P.rect.xy + vec2<u32>(t % P.tiles.x, t / P.tiles.x) * TILE);
        let last = u32(P.plane.z) - 1u;
        let za = plane_z(min(k - 1u, last));
        let zb = plane_z(min(k + next, last));
        if (!slab_visible(lo, lo + vec2<f32>(f32(TILE)), za, zb)) {
            return;
        }
    }
    let list = (I.view_list + 1u) % 3u;
    let slot = atomicAdd(&tile_args[list * 3u], 1u);
    tile_lists[list * P.tiles.y + slot] = t;
}
