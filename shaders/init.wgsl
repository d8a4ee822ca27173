// Initialisation (Algorithm 1, line 1): the state on plane 0, before any segment is integrated.

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = buffer_size();
    if (i32(gid.x) >= size.x || i32(gid.y) >= size.y) {
        return;
    }
    let texel = vec2<i32>(gid.xy);
    let t = vec2<f32>(gid.xy);
    let z0 = plane_z(0u);
    let start = unproject(t, z0);
    let value = sample_value(start);
    // Light w: data value at the texel's point, the front value of the next segment when
    // view rays are straight.
    textureStore(light_out, texel, vec4<f32>(P.light_color.rgb, value));
    // Light direction: magnitude η, as for view rays; w: the concentration, 1 at the start.
    if (REFRACTION) {
        textureStore(light_dir_out, texel, vec4<f32>(P.light_dir.xyz * eta_at(start), 1.0));
    }
    let d = primary_dir(t);
    // View direction: v = η dx/ds (Eq. 7); w = 1 while the ray is alive.
    textureStore(view_dir_out, texel, vec4<f32>(d * eta_at(start), 1.0));
    if (REFRACTION) {
        // View position w: data value there, the front value of the next segment.
        textureStore(view_pos_out, texel, vec4<f32>(start, value));
    }
    textureStore(color_out, texel, vec4<f32>(0.0));
    if (MEDIUM) {
        textureStore(medium_out, texel, vec4<f32>(1.0));
    }
}
