// Backward light transport (the paper's semi-Lagrangian scheme, Algorithm 1 lines 6–18): the
// light arriving at each cell of plane k is looked up on plane k-1 where its ray left it.
// The cells form the light grid: plane-0 cells carried along the unrefracted light, so light
// that is not refracted maps cell to cell with no resampling blur, and the grid covers the
// volume's shadow beyond the image (occluders outside the view shadow what is inside it).

// Area of a cell on any plane (cells are carried along a fixed direction), view units².
fn cell_area() -> f32 {
    return P.beam_origin.z * P.beam_origin.z * pixel_area(P.plane.x);
}

fn in_grid(c: vec2<i32>) -> bool {
    return c.x >= 0 && c.y >= 0 && c.x < i32(P.beam_grid.x) && c.y < i32(P.beam_grid.y);
}

struct GridLight {
    light: vec4<f32>,   // rgb intensity; w: shadow depth
    dir: vec4<f32>,     // v = η·direction; w: concentration S_0/S_i
}

// Unobstructed light (beyond the grid): the source itself.
fn source_light() -> GridLight {
    return GridLight(vec4<f32>(1.0, 1.0, 1.0, P.plane.x), vec4<f32>(P.light_dir.xyz * P.texel.w, 1.0));
}

fn grid_texel(slot: u32, c: vec2<i32>) -> GridLight {
    if (!in_grid(c)) {
        return source_light();
    }
    let i = slot * grid_cells() + u32(c.y) * P.beam_grid.x + u32(c.x);
    var d = vec4<f32>(P.light_dir.xyz * P.texel.w, 1.0);
    if (REFRACTION || INTENSITY_CORRECTION) {
        d = back_dir[i];
    }
    return GridLight(load_back_light(i), d);
}

// Bilinear lookup at continuous cell coordinates. Averaged directions are rescaled to the
// mean length of the four: a plain average of directions that differ is shorter than any of
// them and would over-bend at the next index step.
fn grid_bilinear(slot: u32, c: vec2<f32>) -> GridLight {
    let lo = floor(c);
    let f = c - lo;
    let a = vec2<i32>(lo);
    let t00 = grid_texel(slot, a);
    let t10 = grid_texel(slot, a + vec2<i32>(1, 0));
    let t01 = grid_texel(slot, a + vec2<i32>(0, 1));
    let t11 = grid_texel(slot, a + vec2<i32>(1, 1));
    let light = mix(mix(t00.light, t10.light, f.x), mix(t01.light, t11.light, f.x), f.y);
    var dir = mix(mix(t00.dir, t10.dir, f.x), mix(t01.dir, t11.dir, f.x), f.y);
    if (REFRACTION) {
        let mean_len = mix(mix(length(t00.dir.xyz), length(t10.dir.xyz), f.x),
                           mix(length(t01.dir.xyz), length(t11.dir.xyz), f.x), f.y);
        dir = vec4<f32>(safe_normalize(dir.xyz) * mean_len, dir.w);
    }
    return GridLight(light, dir);
}

// Light arriving at `lp` on plane k-1 (slot), filtered for soft light with the three-sample
// elliptical kernel of Patel et al. (incremental convolution): taps on a circle of radius
// `radius` perpendicular to the light, projected along it onto the plane. The rotation
// changes from plane to plane (golden angle), not from cell to cell, so it adds no noise.
fn gather(slot: u32, lp: vec3<f32>, d: vec3<f32>, radius: f32, k: u32) -> GridLight {
    if (!LIGHT_FILTER || radius <= 0.0) {
        return grid_bilinear(slot, grid_coords(lp));
    }
    var up = vec3<f32>(0.0, 1.0, 0.0);
    if (abs(d.y) > 0.9) {
        up = vec3<f32>(1.0, 0.0, 0.0);
    }
    let a1 = normalize(cross(d, up));
    let a2 = cross(d, a1);
    let phi = f32(k) * 2.3999632;
    var sum = GridLight(vec4<f32>(0.0), vec4<f32>(0.0));
    var len = 0.0;
    for (var n = 0u; n < 3u; n++) {
        let angle = phi + f32(n) * 2.0943951;
        let o = radius * (cos(angle) * a1 + sin(angle) * a2);
        let on_plane = o - d * (o.z / d.z);
        let g = grid_bilinear(slot, grid_coords(lp + on_plane));
        sum.light += g.light / 3.0;
        sum.dir += g.dir / 3.0;
        len += length(g.dir.xyz) / 3.0;
    }
    if (REFRACTION) {
        sum.dir = vec4<f32>(safe_normalize(sum.dir.xyz) * len, sum.dir.w);
    }
    return sum;
}

// Where the light arriving at cell c of plane k (depth z) left plane k-1, following the
// stored direction backward.
fn backward_point(c: vec2<i32>, z: f32, read: u32) -> vec3<f32> {
    let cc = clamp(c, vec2<i32>(0), vec2<i32>(P.beam_grid.xy) - vec2<i32>(1));
    var d = P.light_dir.xyz;
    if (REFRACTION) {
        d = light_direction(back_dir[read * grid_cells() + u32(cc.y) * P.beam_grid.x + u32(cc.x)].xyz);
    }
    return grid_point(vec2<f32>(c), z) - d * (P.plane.y / d.z);
}

fn backward_init(ij: vec2<u32>) {
    if (ij.x >= P.beam_grid.x || ij.y >= P.beam_grid.y) {
        return;
    }
    let index = ij.y * P.beam_grid.x + ij.x;
    let x = grid_point(vec2<f32>(ij), P.plane.x);
    var v = P.light_dir.xyz * P.texel.w;
    if (REFRACTION) {
        v = entering(P.light_dir.xyz, index_at(x).eta);
    }
    store_back_light(index, vec4<f32>(1.0, 1.0, 1.0, P.plane.x));
    if (REFRACTION || INTENSITY_CORRECTION) {
        back_dir[index] = vec4<f32>(v, 1.0);
    }
}

// One cell from plane k-1 to plane k (Eqs. 9, 10, 12, 13).
fn backward_step(ij: vec2<u32>, k: u32) {
    if (ij.x >= P.beam_grid.x || ij.y >= P.beam_grid.y) {
        return;
    }
    let index = ij.y * P.beam_grid.x + ij.x;
    let read = (k - 1u) % 3u;
    let write = k % 3u;
    let n = grid_cells();
    let z = plane_z(k);
    let ds = P.plane.y;
    let c = vec2<i32>(ij);
    let x = grid_point(vec2<f32>(ij), z);

    // Algorithm 1 line 8, with the direction at the foot point rather than at the cell: the
    // stored direction gives a first foot point, the direction found there the second.
    var d = P.light_dir.xyz;
    if (REFRACTION) {
        d = light_direction(back_dir[read * n + index].xyz);
        let first = x - d * (ds / d.z);
        d = light_direction(grid_bilinear(read, grid_coords(first)).dir.xyz);
    }
    let lp = x - d * (ds / d.z);
    let l = ds / d.z;
    // Soft light: a cone source blurs a shadow edge by softness × the distance from where the
    // light was lost; the kernel's variance per axis (radius²/2) must grow by
    // softness²·D·ℓ/2 per segment, so the radius is softness·sqrt(D·ℓ), whatever Δs.
    let own = load_back_light(read * n + index);
    let dist = max(z - own.w, 0.0);
    let radius = P.light_dir.w * sqrt(dist * l);
    let incoming = gather(read, lp, d, radius, k);

    var intensity = 1.0;
    var concentration = incoming.dir.w;
    if (INTENSITY_CORRECTION) {
        // Eq. 13 with central differences between neighbouring cells; the parallelogram area
        // |∂p/∂u × ∂p/∂v| is what |∂p/∂u||∂p/∂v| approximates.
        let du = (backward_point(c + vec2<i32>(1, 0), z, read) - backward_point(c - vec2<i32>(1, 0), z, read)) * 0.5;
        let dv = (backward_point(c + vec2<i32>(0, 1), z, read) - backward_point(c - vec2<i32>(0, 1), z, read)) * 0.5;
        let jacobian = cross(du, dv);
        // Eq. 12: I_i = S_{i-1} / S_i (the cells have the same area on every plane).
        var ratio = length(jacobian) / cell_area();
        if (guarded(SG_INTENSITY_RATIO)) {
            let max_ratio = P.light_color.w;
            ratio = clamp(ratio, 1.0 / max_ratio, max_ratio);
        }
        // Cell axes map to plane axes with positive orientation until neighbouring rays
        // cross: a fold of the backward map, i.e. a focus was passed. There the light would
        // spread again, which a backward scheme cannot represent; at least it must not
        // concentrate further.
        if (jacobian.z * P.light_dir.z <= 0.0 && guarded(SG_FOLD)) {
            ratio = min(ratio, 1.0);
        }
        if (guarded(SG_CONCENTRATION)) {
            // Power budget: no more than max_concentration × the source light anywhere.
            ratio = min(ratio, P.budget.x / max(concentration, MIN_CONCENTRATION));
        }
        intensity = ratio;
        concentration = max(concentration * ratio, MIN_CONCENTRATION);
    }
    let value_lp = sample_value(lp);
    let value_x = sample_value(x);
    let mid = sample_value(0.5 * (lp + x));
    let transmit = segment_transmittance(value_lp, mid, value_x, l / ds, is_clipped(0.5 * (lp + x)));
    // Eq. 9: L_i = L_{i-1} I_i (1 - α) m.
    var light = max(incoming.light.rgb * intensity * transmit, vec3<f32>(0.0));
    // Shadow depth: where, weighted by the light lost, the light was lost.
    var shadow = incoming.light.w;
    let before = max(1.0 - max(incoming.light.r, max(incoming.light.g, incoming.light.b)), 0.0);
    let lost = max(max(incoming.light.r - light.r, incoming.light.g - light.g), incoming.light.b - light.b);
    if (lost > 0.0) {
        shadow = (shadow * before + 0.5 * (lp.z + z) * lost) / (before + lost);
    }
    var v = incoming.dir.xyz;
    if (REFRACTION) {
        // Eq. 10: ld_i = ld_{i-1} + Δs ∇η along the segment, with |v| = η by Snell's law.
        let ix = index_at(x);
        let v_new = snell_renormalise(v + l * ix.grad, ix);
        if (INTENSITY_CORRECTION) {
            // The intensity law tracks the irradiance on the planes; where the direction
            // bends, the same irradiance crosses the plane in a beam of another cross-section.
            let cos_old = light_direction(v).z;
            let cos_new = light_direction(v_new).z;
            light *= cos_old / cos_new;
        }
        v = v_new;
    }
    if (INTENSITY_CORRECTION && guarded(SG_CONCENTRATION)) {
        // The budget as a hard bound: bilinear weights and rounding cannot lift the light
        // above source × concentration (the two are gathered with the same weights).
        light = min(light, vec3<f32>(concentration));
    }
    store_back_light(write * n + index, vec4<f32>(light, shadow));
    if (REFRACTION || INTENSITY_CORRECTION) {
        back_dir[write * n + index] = vec4<f32>(v, concentration);
    }
}

// Light arriving at the view-space point p on plane k: bilinear over the light grid.
fn backward_light_at(k: u32, p: vec3<f32>) -> LightSample {
    let g = grid_bilinear(k % 3u, grid_coords(p));
    var dir = P.light_dir.xyz;
    if (REFRACTION) {
        dir = light_direction(g.dir.xyz);
    }
    return LightSample(g.light.rgb, dir);
}
