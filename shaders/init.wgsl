// Initialisation (Algorithm 1, line 1): light and view rays on plane 0.

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let group = wg.y * P.tiles.z + wg.x;
    let local = vec2<u32>(li % 8u, li / 8u);
    if (group < P.beam_grid.w) {
        let ij = vec2<u32>(group % P.beam_grid.z, group / P.beam_grid.z) * 8u + local;
        if (BEAMS) {
            beams_init(ij);
        } else {
            backward_init(ij);
        }
        return;
    }
    let vg = group - P.beam_grid.w;
    if (vg >= P.tiles.y) {
        return;
    }
    let px = P.rect.xy + vec2<u32>(vg % P.tiles.x, vg / P.tiles.x) * 8u + local;
    view_init(px);
}
