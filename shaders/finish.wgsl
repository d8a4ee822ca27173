// Final pass: environment lookup with the bent view direction and Oddy–Willis blending
// (Section 4.4), or one of the diagnostic buffers.

// Final direction of the view ray of pixel p (unit, view space).
fn final_dir(p: vec2<i32>) -> vec3<f32> {
    let c = clamp(p, vec2<i32>(0), image_size() - vec2<i32>(1));
    if (REFRACTION && in_rect(c)) {
        let px = vec2<u32>(c);
        return normalize(vec3<f32>(load_view_ray(px).zw, load_view_aux(px).x));
    }
    return primary_dir(vec2<f32>(c));
}

fn env_dir(d: vec3<f32>) -> vec3<f32> {
    return normalize((P.world_from_view * vec4<f32>(d, 0.0)).xyz);
}

// Equirectangular lookup (y up). The mip level follows the angle between neighbouring rays,
// which refraction can make large: without it the background turns to noise. The neighbours
// are the next pixel, or the previous one on the last row and column (a clamped neighbour
// would be the pixel itself: footprint 0, the finest level, aliasing).
fn environment(p: vec2<i32>) -> vec3<f32> {
    if (P.background.w < 0.5) {
        return P.background.rgb;
    }
    let size = image_size();
    let d = env_dir(final_dir(p));
    var sx = 1;
    if (p.x + 1 >= size.x) {
        sx = -1;
    }
    var sy = 1;
    if (p.y + 1 >= size.y) {
        sy = -1;
    }
    var angle = 0.0;
    if (size.x > 1) {
        angle = max(angle, acos(clamp(dot(d, env_dir(final_dir(p + vec2<i32>(sx, 0)))), -1.0, 1.0)));
    }
    if (size.y > 1) {
        angle = max(angle, acos(clamp(dot(d, env_dir(final_dir(p + vec2<i32>(0, sy)))), -1.0, 1.0)));
    }
    let width = f32(textureDimensions(env_tex).x);
    // Footprint: environment texels between neighbouring rays. Up to one texel the full
    // resolution is right, and the branch keeps log2 inside its domain (x > 0) without an
    // epsilon: parallel rays (an orthographic camera without refraction) give exactly 0, where
    // log2 is -inf or undefined (WGSL and SPIR-V leave it open) and clamp() of that would be
    // device-specific. A NaN footprint fails the comparison and takes level 0 too.
    let footprint = angle * width / 6.2831853;
    var lod = 0.0;
    if (footprint > 1.0) {
        lod = min(log2(footprint), P.limits.w - 1.0);
    }
    let uv = vec2<f32>(atan2(d.x, -d.z) / 6.2831853 + 0.5, acos(clamp(d.y, -1.0, 1.0)) / 3.14159265);
    return textureSampleLevel(env_tex, env_sampler, uv, lod).rgb * P.shading.w;
}

// Light on plane k at pixel p, for the diagnostic views: what was deposited there (beams) or
// the light grid at the pixel's point.
fn debug_light(k: u32, p: vec2<u32>) -> LightSample {
    let x = unproject(vec2<f32>(p), plane_z(k));
    if (BEAMS && !REFRACTION) {
        // Unrefracted beams keep their cells: the light there, as irradiance on the plane
        // (the source's direction throughout).
        return beams_light_at(k, x);
    }
    if (BEAMS) {
        // What was deposited on the pixel (each level at the pixel's centre), and the
        // unobstructed light beyond the traced beams.
        var l = LightSample(vec3<f32>(0.0), P.light_dir.xyz);
        if (in_rect(vec2<i32>(p))) {
            l = deposited_at(deposit_slot(k), vec2<f32>(p));
            if (deposits_direction() && dot(l.dir, l.dir) > 0.0) {
                l.dir = normalize(l.dir);
            } else {
                l.dir = P.light_dir.xyz;
            }
        }
        l.color = budgeted(l.color + vec3<f32>(outside_fraction(vec2<f32>(p), beam_region_outside(k))));
        return l;
    }
    let g = grid_bilinear(k % 3u, grid_coords(x));
    var dir = P.light_dir.xyz;
    if (REFRACTION) {
        dir = light_direction(g.dir.xyz);
    }
    var c = g.light.rgb;
    if (DEBUG_VIEW == 1u) {
        // Irradiance on the plane, relative to the source's.
        c *= dir.z / P.light_dir.z;
    }
    if (DEBUG_VIEW == 3u) {
        c = vec3<f32>(g.dir.w);
    }
    return LightSample(c, dir);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(global_invocation_id) gid: vec3<u32>) {
    P = params;
    let size = image_size();
    if (i32(gid.x) >= size.x || i32(gid.y) >= size.y) {
        return;
    }
    let k = dispatch_plane(wg);
    let p = vec2<i32>(gid.xy);
    var out = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    var color = vec4<f32>(0.0);
    var medium = vec3<f32>(1.0);
    if (in_rect(p)) {
        color = load_view_shade(gid.xy, VIEW_COLOR);
        if (MEDIUM) {
            medium = load_view_shade(gid.xy, VIEW_MEDIUM).rgb;
        }
    }
    switch DEBUG_VIEW {
        case 1u: {
            // The light itself (the source's colour and intensity included), as before.
            out = vec4<f32>(debug_light(k, gid.xy).color * P.light_color.rgb, 1.0);
        }
        case 2u: {
            out = vec4<f32>(debug_light(k, gid.xy).dir * 0.5 + 0.5, 1.0);
        }
        case 3u: {
            // Concentration of the light (beams: the fluence; backward: the product of the
            // intensity ratios); 1 shows as 0.5.
            out = vec4<f32>(0.5 * debug_light(k, gid.xy).color, 1.0);
        }
        case 4u: {
            out = vec4<f32>(medium, 1.0);
        }
        default: {
            let env = environment(p);
            out = vec4<f32>(color.rgb + (1.0 - color.a) * medium * env, 1.0);
        }
    }
    image_out[pixel_index(gid.xy)] = out;
}
