// Final pass: environment lookup with the bent view direction and Oddy–Willis blending
// (Section 4.4), or one of the diagnostic buffers.

fn env_dir_at(texel: vec2<i32>) -> vec3<f32> {
    let c = clamp(texel, vec2<i32>(0), buffer_size() - vec2<i32>(1));
    var d = primary_dir(vec2<f32>(c));
    if (REFRACTION) {
        d = textureLoad(view_dir_in, c, 0).xyz;
    }
    return normalize((P.world_from_view * vec4<f32>(d, 0.0)).xyz);
}

// Equirectangular lookup (y up). The mip level follows the angle between neighbouring rays,
// which refraction can make large: without it the background turns to noise.
fn environment(texel: vec2<i32>) -> vec3<f32> {
    if (P.background.w < 0.5) {
        return P.background.rgb;
    }
    let d = env_dir_at(texel);
    let dx = env_dir_at(texel + vec2<i32>(1, 0));
    let dy = env_dir_at(texel + vec2<i32>(0, 1));
    let angle = max(acos(clamp(dot(d, dx), -1.0, 1.0)), acos(clamp(dot(d, dy), -1.0, 1.0)));
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

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let size = buffer_size();
    if (i32(gid.x) >= size.x || i32(gid.y) >= size.y) {
        return;
    }
    let texel = vec2<i32>(gid.xy);
    var out = vec4<f32>(0.0, 0.0, 0.0, 1.0);
    var medium = vec3<f32>(1.0);
    if (MEDIUM) {
        medium = textureLoad(medium_in, texel, 0).rgb;
    }
    switch DEBUG_VIEW {
        case 1u: {
            out = vec4<f32>(textureLoad(light_in, texel, 0).rgb, 1.0);
        }
        case 2u: {
            var d = P.light_dir.xyz;
            if (REFRACTION) {
                d = normalize(textureLoad(light_dir_in, texel, 0).xyz);
            }
            out = vec4<f32>(d * 0.5 + 0.5, 1.0);
        }
        case 3u: {
            // Concentration of the light (product of the intensity ratios); 1 shows as 0.5.
            var ratio = 1.0;
            if (REFRACTION) {
                ratio = textureLoad(light_dir_in, texel, 0).w;
            }
            out = vec4<f32>(vec3<f32>(0.5 * ratio), 1.0);
        }
        case 4u: {
            out = vec4<f32>(medium, 1.0);
        }
        default: {
            let c = textureLoad(color_in, texel, 0);
            let env = environment(texel);
            out = vec4<f32>(c.rgb + (1.0 - c.a) * medium * env, 1.0);
        }
    }
    textureStore(image_out, texel, out);
}
