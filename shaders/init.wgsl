// Initialisation (Algorithm 1, line 1): light and view rays on plane 0.

@compute @workgroup_size(TILE * TILE, 1, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    P = params;
    let group = wg.y * P.tiles.z + wg.x;
    let local = vec2<u32>(li % TILE, li / TILE);
    if (group < P.beam_grid.w) {
        let ij = vec2<u32>(group % P.beam_grid.z, group / P.beam_grid.z) * TILE + local;
        if (BEAMS) {
            beams_init(ij);
            if (light_tiles_listed() && li == 0u) {
                // Plane 1 is the first view pass's (parity 0).
                list_light_tile(group, 1u, 0u);
            }
        } else {
            backward_init(ij);
        }
        return;
    }
    let vg = group - P.beam_grid.w;
    if (vg == 0u) {
        // The lists' indirect arguments: one row of workgroups (x counts the tiles), shared
        // out over the workgroup's invocations, however many it has.
        for (var i = li; i < 4u * LIST_PLANES; i += TILE * TILE) {
            if (i < 3u) {
                atomicStore(&tile_args[i * 3u + 1u], 1u);
                atomicStore(&tile_args[i * 3u + 2u], 1u);
            }
            atomicStore(&light_args[i * 3u + 1u], 1u);
            atomicStore(&light_args[i * 3u + 2u], 1u);
        }
    }
    if (vg >= P.tiles.y) {
        return;
    }
    let px = P.rect.xy + vec2<u32>(vg % P.tiles.x, vg / P.tiles.x) * TILE + local;
    view_init(px);
}
