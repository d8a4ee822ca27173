// One plane of the sweep (Algorithm 1, lines 5–37). Plane k is two dispatches that need no
// barrier between them: `light_main` moves the light from plane k-1 to plane k, `view_main`
// moves the view rays one plane behind, from k-2 to k-1, so that both ends of their segment
// have complete light. Light lives in a ring of three planes. They are separate dispatches,
// not two branches of one: a CPU driver runs every branch a workgroup's invocations take.

@compute @workgroup_size(64, 1, 1)
fn light_main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let k = dispatch_plane(wg);
    // The cells that can still reach the image on this plane or a later one: a window of
    // the light grid, in tiles (`light_windows` in state.rs).
    let window = light_window[k];
    let group = wg.y * P.tiles.z + wg.x;
    if (group >= window.w) {
        return;
    }
    let tile = window.xy + vec2<u32>(group % window.z, group / window.z);
    let ij = tile * 8u + vec2<u32>(li % 8u, li / 8u);
    if (BEAMS) {
        beams_step(ij, k);
    } else {
        backward_step(ij, k);
    }
}

@compute @workgroup_size(64, 1, 1)
fn view_main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let k = dispatch_plane(wg);
    let group = wg.y * P.tiles.z + wg.x;
    if (group >= P.tiles.y) {
        return;
    }
    let px = P.rect.xy + vec2<u32>(group % P.tiles.x, group / P.tiles.x) * 8u + vec2<u32>(li % 8u, li / 8u);
    if (!in_rect(vec2<i32>(px))) {
        return;
    }
    if (BEAMS && REFRACTION) {
        // Plane k+1 deposits into the slot that plane k-2 used; its last reader was the view
        // dispatch of plane k-1.
        acc_clear((k + 1u) % 3u, px);
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
