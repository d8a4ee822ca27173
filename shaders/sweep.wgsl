// One plane of the sweep (Algorithm 1, lines 5–37), dispatch k: light from plane k-1 to
// plane k, and view rays one plane behind, from k-2 to k-1, so that both ends of their
// segment have complete light. Light lives in a ring of three planes.

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let k = dispatch_plane(wg);
    let group = wg.y * P.tiles.z + wg.x;
    let local = vec2<u32>(li % 8u, li / 8u);
    if (group < P.beam_grid.w) {
        if (k < u32(P.plane.z)) {
            let ij = vec2<u32>(group % P.beam_grid.z, group / P.beam_grid.z) * 8u + local;
            if (BEAMS) {
                beams_step(ij, k);
            } else {
                backward_step(ij, k);
            }
        }
        return;
    }
    let vg = group - P.beam_grid.w;
    if (vg >= P.tiles.y) {
        return;
    }
    let px = P.rect.xy + vec2<u32>(vg % P.tiles.x, vg / P.tiles.x) * 8u + local;
    if (!in_rect(vec2<i32>(px))) {
        return;
    }
    if (BEAMS) {
        // Plane k+1 deposits into the slot that plane k-2 used; its last reader was the view
        // step of the previous dispatch.
        let channels = P.tiles.w;
        let base = ((k + 1u) % 3u) * u32(P.size.x) * u32(P.size.y) * channels + pixel_index(px) * channels;
        for (var c = 0u; c < channels; c++) {
            atomicStore(&light_acc[base + c], 0u);
        }
    }
    if (DEBUG_VIEW == 1u || DEBUG_VIEW == 2u || DEBUG_VIEW == 3u) {
        return; // light diagnostics need no view rays
    }
    if (k == 1u) {
        view_first_light(px);
    } else if (k >= 2u) {
        view_step(px, k - 1u);
    }
}
