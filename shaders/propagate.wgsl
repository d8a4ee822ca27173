// One plane of the sweep (Algorithm 1, lines 5–37): light is integrated backward from plane
// i-1 to plane i (semi-Lagrangian), view rays forward from plane i-1 to plane i.

// Where the light arriving at texel `texel` of plane i (depth z) left plane i-1 (Algorithm 1,
// line 8): follow the stored (unfiltered) light direction backward.
fn backward_point(texel: vec2<i32>, z: f32) -> vec3<f32> {
    let c = clamp(texel, vec2<i32>(0), buffer_size() - vec2<i32>(1));
    var d = P.light_dir.xyz;
    if (REFRACTION) {
        d = light_direction(textureLoad(light_dir_in, c, 0).xyz);
    }
    return unproject(vec2<f32>(texel), z) - d * (P.plane.y / d.z);
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

// Area of the texel footprint on the plane at depth z (view units²).
fn texel_area(z: f32) -> f32 {
    let a = 1.0 / (P.projection.x * P.projection.y);
    if (ORTHOGRAPHIC) {
        return a;
    }
    return a * z * z;
}

struct Light {
    color: vec4<f32>,
    dir: vec4<f32>,
}

// Light colour and direction arriving at `lp` on plane i-1, filtered with the three-sample
// elliptical kernel of Patel et al. (incremental convolution, randomly rotated per texel and
// plane): a disc of radius r perpendicular to the light, projected along it onto the plane.
fn gather_light(lp: vec3<f32>, d: vec3<f32>, eta_mag: f32, texel: vec2<u32>, plane: u32) -> Light {
    let outside_c = vec4<f32>(P.light_color.rgb, 0.0);
    let outside_d = vec4<f32>(P.light_dir.xyz * eta_mag, 1.0);
    let radius = P.light_dir.w;
    if (!LIGHT_FILTER || radius <= 0.0) {
        let uv = project(lp);
        var ld = outside_d;
        if (REFRACTION) {
            ld = bilinear(light_dir_in, uv, outside_d);
        }
        return Light(bilinear(light_in, uv, outside_c), ld);
    }
    var up = vec3<f32>(0.0, 1.0, 0.0);
    if (abs(d.y) > 0.9) {
        up = vec3<f32>(1.0, 0.0, 0.0);
    }
    let a1 = normalize(cross(d, up));
    let a2 = cross(d, a1);
    let phi = random01(texel, plane) * 6.2831853;
    var c = vec4<f32>(0.0);
    var ld = vec4<f32>(0.0);
    for (var k = 0u; k < 3u; k++) {
        let angle = phi + f32(k) * 2.0943951;
        let o = radius * (cos(angle) * a1 + sin(angle) * a2);
        // Project the offset along the light direction back onto the plane.
        let on_plane = o - d * (o.z / d.z);
        let uv = project(lp + on_plane);
        c += bilinear(light_in, uv, outside_c);
        if (REFRACTION) {
            ld += bilinear(light_dir_in, uv, outside_d);
        } else {
            ld += outside_d;
        }
    }
    return Light(c / 3.0, ld / 3.0);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = buffer_size();
    if (i32(gid.x) >= size.x || i32(gid.y) >= size.y) {
        return;
    }
    let plane = I.plane_index;
    let texel = vec2<i32>(gid.xy);
    let t = vec2<f32>(gid.xy);
    let z = plane_z(plane);
    let z_prev = plane_z(plane - 1u);
    let ds = P.plane.y;
    let x = unproject(t, z);
    let value_x = sample_value(x);
    let light_prev = textureLoad(light_in, texel, 0);

    // ---- Light propagation (Eqs. 9, 10, 12, 13) ----
    var ld_raw = vec4<f32>(P.light_dir.xyz, 1.0);
    var d = P.light_dir.xyz;
    if (REFRACTION) {
        ld_raw = textureLoad(light_dir_in, texel, 0);
        d = light_direction(ld_raw.xyz);
    }
    let lp = x - d * (ds / d.z);
    let light_ratio = 1.0 / d.z; // segment length over Δs
    let incoming = gather_light(lp, d, length(ld_raw.xyz), gid.xy, plane);

    var intensity = 1.0;
    // How much the light has been concentrated since it entered: Eq. 12 applied along the
    // path, S_0 / S_i, the product of the intensity ratios (gathered like the light itself;
    // 1 for the unobstructed light).
    var concentration = incoming.dir.w;
    if (INTENSITY_CORRECTION) {
        // Eq. 13 with central differences between neighbouring texels; the parallelogram area
        // |∂p/∂u × ∂p/∂v| is what |∂p/∂u||∂p/∂v| approximates.
        let du = (backward_point(texel + vec2<i32>(1, 0), z) - backward_point(texel - vec2<i32>(1, 0), z)) * 0.5;
        let dv = (backward_point(texel + vec2<i32>(0, 1), z) - backward_point(texel - vec2<i32>(0, 1), z)) * 0.5;
        let jacobian = cross(du, dv);
        // Eq. 12: I_i = S_{i-1} / S_i.
        var ratio = length(jacobian) / texel_area(z);
        if (guarded(SG_INTENSITY_RATIO)) {
            let max_ratio = P.light_color.w;
            ratio = clamp(ratio, 1.0 / max_ratio, max_ratio);
        }
        // Texel axes map to plane axes with positive orientation (z of u × v > 0) until
        // neighbouring rays cross: a fold of the backward map, i.e. a focus was passed. There
        // the light would spread again, which a backward scheme cannot represent; at least it
        // must not concentrate further.
        if (jacobian.z <= 0.0 && guarded(SG_FOLD)) {
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
    let seg = segment_particles(value_lp, value_x, light_ratio, is_clipped(0.5 * (lp + x)));
    var transmit = vec3<f32>(1.0 - seg.a);
    if (MEDIUM) {
        transmit *= segment_medium(value_lp, value_x, light_ratio);
    }
    // Eq. 9: L_i = L_{i-1} I_i (1 - α) m.
    var light_new = max(incoming.color.rgb * intensity * transmit, vec3<f32>(0.0));
    if (INTENSITY_CORRECTION && guarded(SG_CONCENTRATION)) {
        // The budget as a hard bound: bilinear weights and rounding cannot lift the light
        // above source × concentration (the two are gathered with the same weights).
        light_new = min(light_new, P.light_color.rgb * concentration);
    }
    if (guarded(SG_MAX_LIGHT)) {
        // Bounded so 16-bit storage cannot overflow.
        light_new = min(light_new, vec3<f32>(P.limits.z));
    }
    textureStore(light_out, texel, vec4<f32>(light_new, value_x));

    if (REFRACTION) {
        // Eq. 10: ld_i = ld_{i-1} + Δs ∇η, with the actual path length of the segment.
        let g = gradients(x, false);
        let ld_new = incoming.dir.xyz + ds * light_ratio * g.eta;
        textureStore(light_dir_out, texel, vec4<f32>(ld_new, concentration));
    }

    // ---- View ray propagation (Eqs. 8 and 14) ----
    var vp = vec4<f32>(unproject(t, z_prev), light_prev.w);
    // w of the view direction: 1 while the ray is alive.
    var vd = vec4<f32>(primary_dir(t), textureLoad(view_dir_in, texel, 0).w);
    if (REFRACTION) {
        vp = textureLoad(view_pos_in, texel, 0);
        vd = textureLoad(view_dir_in, texel, 0);
    }
    var color = textureLoad(color_in, texel, 0);
    var medium = vec3<f32>(1.0);
    if (MEDIUM) {
        medium = textureLoad(medium_in, texel, 0).rgb;
    }
    if (vd.w > 0.0) {
        let dir = safe_normalize(vd.xyz);
        if (dir.z < P.limits.y && guarded(SG_VIEW_MIN_Z)) {
            // The ray turned (nearly) parallel to the planes or back toward the camera: it leaves
            // the sweep here and keeps its direction for the environment lookup.
            vd.w = 0.0;
        } else {
            var next = x;
            var value_next = value_x;
            if (REFRACTION) {
                // Eq. 8 position update, ending on the next plane (Algorithm 1, line 32).
                next = vp.xyz + dir * ((z - vp.z) / dir.z);
                value_next = sample_value(next);
            }
            let ratio = length(next - vp.xyz) / ds;
            let s = segment_particles(vp.w, value_next, ratio, is_clipped(0.5 * (vp.xyz + next)));
            // Diffuse light arriving where the segment starts (Algorithm 1, line 25).
            let uv = project(vp.xyz);
            let i_d = bilinear(light_in, uv, vec4<f32>(P.light_color.rgb, 0.0)).rgb;
            var i_s = vec3<f32>(0.0);
            var g = Gradients(vec3<f32>(0.0), vec3<f32>(0.0));
            if (REFRACTION) {
                g = gradients(next, SPECULAR);
            }
            if (SPECULAR) {
                let gl = length(g.value);
                if (gl > MIN_GRADIENT_LENGTH || !guarded(SG_GRADIENT_LENGTH)) {
                    var n = -g.value / gl;
                    let v = -dir;
                    if (dot(n, v) < 0.0) {
                        n = -n;
                    }
                    var l_dir = P.light_dir.xyz;
                    if (REFRACTION) {
                        l_dir = bilinear(light_dir_in, uv, vec4<f32>(P.light_dir.xyz, 1.0)).xyz;
                    }
                    let l = -safe_normalize(l_dir);
                    // Fresnel from the index change between the planes (Section 4.3).
                    var eta_a = eta_of(vp.w);
                    var eta_b = eta_of(value_next);
                    if (ETA_VOLUME) {
                        eta_a = eta_at(vp.xyz);
                        eta_b = eta_at(next);
                    }
                    let f = fresnel_dielectric(dot(n, v), eta_a, eta_b);
                    i_s = P.shading.x * f * cook_torrance(n, l, v, P.shading.y) * i_d;
                }
            }
            // Eq. 14 (Oddy–Willis compositing).
            let transparency = 1.0 - color.a;
            color = vec4<f32>(color.rgb + transparency * medium * (s.rgb * i_d + i_s), color.a + transparency * s.a);
            if (guarded(SG_MAX_RADIANCE)) {
                color = vec4<f32>(min(color.rgb, vec3<f32>(MAX_RADIANCE)), color.a);
            }
            if (MEDIUM) {
                medium *= segment_medium(vp.w, value_next, ratio);
            }
            if (REFRACTION) {
                // Eq. 8 direction update: v += Δs ∇η.
                vd = vec4<f32>(vd.xyz + ds * ratio * g.eta, vd.w);
                vp = vec4<f32>(next, value_next);
            }
            // Early termination once nothing behind can show through.
            let through = (1.0 - color.a) * max(medium.r, max(medium.g, medium.b));
            if (through < 1.0 - P.shading.z) {
                vd.w = 0.0;
            }
        }
    }
    if (REFRACTION) {
        textureStore(view_pos_out, texel, vp);
        textureStore(view_dir_out, texel, vd);
    } else {
        // Without refraction only the alive flag matters; position and direction are implicit.
        textureStore(view_dir_out, texel, vd);
    }
    textureStore(color_out, texel, color);
    if (MEDIUM) {
        textureStore(medium_out, texel, vec4<f32>(medium, 1.0));
    }
}
