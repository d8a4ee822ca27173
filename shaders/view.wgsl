// View rays (Section 4.3): one per pixel of the rect that meets the volume, advanced forward
// from plane to plane (Eq. 8), composited with the Oddy–Willis model (Eq. 14).

fn light_at(k: u32, p: vec3<f32>) -> LightSample {
    if (BEAMS) {
        return beams_light_at(k, p);
    }
    return backward_light_at(k, p);
}

// The light arriving at a view sample p on plane k (value: the data value there). With beams,
// the last segment's attenuation is taken along p's own light line (beams.wgsl).
fn light_through(k: u32, p: vec3<f32>, value: f32) -> vec3<f32> {
    if (BEAMS && !REFRACTION) {
        return budgeted(beams_unscattered_through(k, p, value));
    }
    if (BEAMS) {
        return beams_light_through(k, p, value);
    }
    return light_at(k, p).color;
}

// The ray's position on plane k (view space).
fn view_position(px: vec2<u32>, k: u32) -> vec3<f32> {
    if (REFRACTION) {
        return vec3<f32>(load_view_ray(px).xy, plane_z(k));
    }
    return unproject(vec2<f32>(px), plane_z(k));
}

// The rect tile of pixel px.
fn pixel_tile(px: vec2<u32>) -> u32 {
    let t = (px - P.rect.xy) / TILE;
    return t.y * P.tiles.x + t.x;
}

fn view_init(px: vec2<u32>) {
    if (!in_rect(vec2<i32>(px))) {
        return;
    }
    atomicAdd(&view_tiles[pixel_tile(px)], 1u);
    let t = vec2<f32>(px);
    let x = unproject(t, P.plane.x);
    let d = primary_dir(t);
    var v = d * P.texel.w;
    var eta = P.texel.w;
    if (REFRACTION) {
        let ix = index_at(x);
        eta = ix.eta;
        v = entering(d, eta);
        store_view_ray(px, vec4<f32>(x.xy, v.xy));
        if (eta != P.texel.w) {
            atomicOr(&view_tiles[pixel_tile(px)], VIEW_TILE_BENT);
        }
    }
    // z of aux: the plane the ray is on, plus one (0 once it has ended); w: η where the ray is
    // (the front of its next segment).
    store_view_aux(px, vec4<f32>(v.z, sample_value(x), 1.0, eta));
    store_view_shade(px, VIEW_COLOR, vec4<f32>(0.0));
    if (MEDIUM) {
        store_view_shade(px, VIEW_MEDIUM, vec4<f32>(1.0));
    }
}

// The light at the ray's start on plane 0, once plane 0's light is complete.
fn view_first_light(px: vec2<u32>) {
    let x = view_position(px, 0u);
    let value = load_view_aux(px).y;
    var light: vec3<f32>;
    if (SCATTER) {
        light = spread_seen(0u, x, -primary_dir(vec2<f32>(px)), value);
    } else if (LBM) {
        light = lbm_seen(light_at(0u, x).color, -primary_dir(vec2<f32>(px)), value);
    } else {
        light = light_at(0u, x).color;
    }
    store_view_shade(px, VIEW_LIGHT, vec4<f32>(light, 0.0));
}

// h(x) = (1 − e^−x) / x, h(0) = 1: the mean of e^−u over u in [0, x].
fn mean_exp(x: vec3<f32>) -> vec3<f32> {
    let series = 1.0 - x * (0.5 - x / 6.0);
    return select((1.0 - exp(-x)) / x, series, abs(x) < vec3<f32>(1e-3));
}

// The diffuse light seen by a segment's particles, whose light is l0 at the front and l1 at
// the back and whose opacity is alpha. Where the light falls along the segment it is taken to
// fall with the optical depth the view ray meets (the particles that shade a surface also
// shadow it): with T the segment's optical depth and Λ the light's fall in optical depths,
// the particles see l0 · h(T + Λ) / h(T). Deep in an opaque layer whose light falls k times as
// fast as the view's transmittance this is l0 / (1 + k), the Lommel–Seeliger law, wherever in
// the segment the layer starts (woodgrain). Where the value has a direction (`layer`, k from
// the layer's orientation) Λ = k·T; the segment's ends alone misjudge it: where the light at
// the back has gone out, ln(l0 / l1) is only a bound, and T, pre-integrated from values taken
// as linear between samples, falls short of a thin sheet's sharp core (T ≈ 3 where finer
// steps find 20), so side-lit sheets came out too dark on some rows of samples and too
// bright on others. Elsewhere Λ = ln(l0 / l1), the trapezoid rule's limit on a clear segment.
// Where the light rises (out of a shadow, into a caustic) it is linear along the segment,
// weighted by where the particles are (their centroid: 1/2 on a clear segment, 1/T on an
// opaque one).
fn segment_light(l0: vec3<f32>, l1: vec3<f32>, alpha: f32, layer: f32) -> vec3<f32> {
    let t = -log(max(1.0 - alpha, 1e-7));
    // The light's own fall, bounded where l1 underflows: e^−14 ≈ 1e-6 of the front.
    var fall = clamp(log(max(l0, vec3<f32>(1e-30)) / max(l1, vec3<f32>(1e-30))), vec3<f32>(0.0), vec3<f32>(14.0));
    if (layer > 0.0) {
        // e^−80: nothing of the front's light is left.
        fall = vec3<f32>(min(layer * t, 80.0));
    }
    let falling = l0 * mean_exp(vec3<f32>(t) + fall) / mean_exp(vec3<f32>(t));
    var centroid = 0.5;
    if (t > 1e-3) {
        centroid = 1.0 / t - 1.0 / (exp(t) - 1.0);
    }
    let rising = mix(l0, l1, centroid);
    return select(falling, rising, l1 >= l0);
}

// How much faster the light falls than the view's transmittance in a layered medium (a
// surface, a sheet) around p: |n·v| / |n·l| for the layer's normal n, the value's gradient
// from central differences over the interface half-width (the same reach along every axis),
// one fetch of the orientation volume (render/layers.rs). Negative where the value does not
// change (no layer to orient).
fn layer_ratio(p: vec3<f32>, dir: vec3<f32>) -> f32 {
    let m = mat3x3<f32>(P.gradient_to_view[0].xyz, P.gradient_to_view[1].xyz, P.gradient_to_view[2].xyz);
    var g: vec3<f32>;
    if (SAMPLED_LAYERS) {
        g = m * sampled_orientation(volume_coord(p));
    } else {
        g = m * textureSampleLevel(orientation_tex, volume_sampler, volume_coord(p), 0.0).xyz;
    }
    let along_view = abs(dot(g, dir));
    let along_light = abs(dot(g, P.light_dir.xyz));
    if (along_light == 0.0) {
        return select(-1.0, 1e30, along_view > 0.0);
    }
    return along_view / along_light;
}

// What the orientation volume holds at volume coordinates c, where the device has no room
// for it: the central differences over the interface half-width h along each volume axis
// (h / extent in texture units: h times the length of the axis's row of volume_from_view),
// per reach in voxels. Differences of blended samples rather than blended differences, so
// a little sharper than the volume's.
fn sampled_orientation(c: vec3<f32>) -> vec3<f32> {
    let m = P.volume_from_view;
    var d = vec3<f32>(0.0);
    for (var a = 0; a < 3; a++) {
        let reach = P.budget.y * length(vec3<f32>(m[0][a], m[1][a], m[2][a]));
        var o = vec3<f32>(0.0);
        o[a] = reach;
        let diff = textureSampleLevel(volume_tex, volume_sampler, c + o, 0.0).r - textureSampleLevel(volume_tex, volume_sampler, c - o, 0.0).r;
        d[a] = diff * P.texel[a] / reach;
    }
    return d;
}

// Where along a segment (fraction from its front) its index change is centred, from η at the
// front, the middle and the end taken as piecewise linear: where η passes halfway between
// its ends, or, where it turns back (a ray grazing an interface), the middle of the half that
// changes more.
fn interface_position(e0: f32, em: f32, e1: f32) -> f32 {
    let d0 = em - e0;
    let d1 = e1 - em;
    if (d0 * d1 < 0.0) {
        return select(0.75, 0.25, abs(d0) > abs(d1));
    }
    let half = 0.5 * (d0 + d1);
    if (abs(d0) >= abs(half) && abs(d0) > 0.0) {
        return 0.5 * half / d0;
    }
    if (abs(d1) > 0.0) {
        return 0.5 + 0.5 * (half - d0) / d1;
    }
    return 0.5;
}

// The unit direction that v = η·d (η where it was taken) has in the index `eta` across a
// layered interface with normal n: the component along the interface is kept (Snell), the
// normal one takes the rest of |v| = eta, on the same side (none where the part along the
// interface alone exceeds eta: total internal reflection).
fn in_medium(v: vec3<f32>, n: vec3<f32>, eta: f32) -> vec3<f32> {
    let vn = dot(v, n);
    let t = v - vn * n;
    return safe_normalize(t + sign_or_one(vn) * sqrt(max(eta * eta - dot(t, t), 0.0)) * n);
}

// The Cook–Torrance highlight of the index interface(s) that a segment from x0 (index e0)
// to x1 (index e1) crosses along `dir`, lit by `light` (the light at its front end, on the
// side the view ray comes from). It does not depend on where the planes fall:
// - the interface is evaluated where the segment's index change is centred, not at an end: an
//   end beyond the interface has no normal and sees only part of the index step;
// - Fresnel comes from the index on both sides of the interface along its normal, counted
//   once per interface: each segment adds its share of the index change across it (its total
//   variation, so that a ray grazing an interface counts both crossings, as finer segments
//   would);
// - the view ray and the light are taken as they travel in front of the interface (their
//   components along it are unchanged through it, Snell): a ray already bent halfway through
//   the ramp would see the narrow lobe elsewhere. The light's direction is the source's,
//   carried into that medium across an interface parallel to this one. The direction the
//   beams deposit is not used: next to an interface it mixes beams already kicked by it,
//   by a whole step at Δs = 1, which moved the lobe (and the energy) with Δs.
fn segment_highlight(x0: vec3<f32>, x1: vec3<f32>, e0: f32, e1: f32, dir: vec3<f32>, light: vec3<f32>) -> vec3<f32> {
    let em = index_at(0.5 * (x0 + x1)).eta;
    let crossed = abs(em - e0) + abs(e1 - em);
    let xc = mix(x0, x1, interface_position(e0, em, e1));
    let ix = index_at(xc);
    let gl = length(ix.grad);
    if (!has_normal(gl) && guarded(SG_GRADIENT_LENGTH)) {
        return vec3<f32>(0.0);
    }
    let up = ix.grad / gl;
    let h = P.budget.y;
    let eta_hi = index_at(xc + h * up).eta;
    let eta_lo = index_at(xc - h * up).eta;
    var n1 = eta_lo;
    var n2 = eta_hi;
    if (dot(dir, up) < 0.0) {
        n1 = eta_hi;
        n2 = eta_lo;
    }
    // The index change across the interface is at least the gradient's over the half-width
    // (has_normal bounds it away from 0).
    let share = clamp(crossed / max(abs(eta_hi - eta_lo), gl * h), 0.0, 1.0);
    let view = -in_medium(dir * e0, up, n1);
    let light_dir = in_medium(P.light_dir.xyz * P.texel.w, up, n1);
    var n = up;
    if (dot(n, view) < 0.0) {
        n = -n;
    }
    let f = fresnel_dielectric(dot(n, view), n1, n2);
    return P.shading.x * share * f * cook_torrance(n, -light_dir, view, P.shading.y) * light * P.light_color.rgb;
}

// Whether a ray at p going along v is outside the volume's box, more than a voxel and a half
// beyond a face (what trilinear sampling of the value and the gradient reaches), and moving
// away from it, where nothing shows, absorbs or bends (P.budget.w: the value outside the
// volume is clear): a straight line leaving a box never comes back to it.
fn left_for_good(p: vec3<f32>, v: vec3<f32>) -> bool {
    if (P.budget.w == 0.0) {
        return false;
    }
    let q = volume_coord(p);
    let dq = (P.volume_from_view * vec4<f32>(v, 0.0)).xyz;
    let m = 1.5 * P.texel.xyz;
    let below = q < -m & dq <= vec3<f32>(0.0);
    let above = q > vec3<f32>(1.0) + m & dq >= vec3<f32>(0.0);
    return any(below | above);
}

// A view ray's state between two planes, as `view_rays` and `view_shade` keep it.
struct ViewRay {
    aux: vec4<f32>,     // v.z, data value, the plane it is on plus one (0 once ended), η (VIEW_AUX)
    ray: vec4<f32>,     // with refraction: x, y on the plane, v.x, v.y (VIEW_RAY)
    color: vec4<f32>,   // composited colour and opacity
    medium: vec3<f32>,  // medium transmittance (MEDIUM)
    light: vec3<f32>,   // light at its position, the front of its next segment
}

fn load_view(px: vec2<u32>) -> ViewRay {
    var r: ViewRay;
    r.aux = load_view_aux(px);
    if (REFRACTION) {
        r.ray = load_view_ray(px);
    }
    r.color = load_view_shade(px, VIEW_COLOR);
    r.medium = vec3<f32>(1.0);
    if (MEDIUM) {
        r.medium = load_view_shade(px, VIEW_MEDIUM).rgb;
    }
    r.light = load_view_shade(px, VIEW_LIGHT).rgb;
    return r;
}

// Stores the ray's state r, whose state was `before`: the colour, the medium's transmittance
// and the light only where they changed (they stay put across empty space and clear medium,
// the light full in clear air and zero deep in a shadow; a CPU driver stores each word of a
// texel lane by lane, which is most of what a view step costs there). What was loaded is
// what a store of the same values would write back. The comparison is on the bits: a float
// comparison is false for a NaN, which would then never reach the image and hide the fault
// that made it.
fn store_view(px: vec2<u32>, r: ViewRay, before: ViewRay) {
    store_view_aux(px, r.aux);
    if (REFRACTION) {
        store_view_ray(px, r.ray);
    }
    if (any(bitcast<vec4<u32>>(r.color) != bitcast<vec4<u32>>(before.color))) {
        store_view_shade(px, VIEW_COLOR, r.color);
    }
    if (MEDIUM && any(bitcast<vec3<u32>>(r.medium) != bitcast<vec3<u32>>(before.medium))) {
        store_view_shade(px, VIEW_MEDIUM, vec4<f32>(r.medium, 1.0));
    }
    if (any(bitcast<vec3<u32>>(r.light) != bitcast<vec3<u32>>(before.light))) {
        store_view_shade(px, VIEW_LIGHT, vec4<f32>(r.light, 0.0));
    }
}

// One segment from plane k-1 to plane k of pixel px's ray (in rect tile `tile`).
fn view_step(px: vec2<u32>, k: u32, tile: u32) {
    let before = load_view(px);
    if (before.aux.z <= 0.0) {
        return;
    }
    var r = before;
    _ = view_segment(px, k, tile, &r, ray_start(before, k));
    store_view(px, r, before);
}

// Whether a view pass may advance its rays over several planes (`view_steps`; `view_planes` in
// state.rs): where the light they read stays where the light pass left it (the beams' power
// kept per plane without refraction, their deposits in a ring of as many slots with it; not
// the spread mode's scattered light; the image or the medium view). A separate function from
// `view_step`: a CPU driver runs a loop's control for every plane even when it is one.
fn view_spans_planes() -> bool {
    return BEAMS && !SCATTER && (DEBUG_VIEW == 0u || DEBUG_VIEW == 4u);
}

// The segments from plane k0-1 to plane k1 of pixel px's ray, its state kept in the
// invocation between them.
fn view_steps(px: vec2<u32>, k0: u32, k1: u32, tile: u32) {
    let before = load_view(px);
    if (before.aux.z <= 0.0) {
        return;
    }
    var r = before;
    var start = ray_start(before, k0);
    for (var k = k0; k <= k1; k++) {
        if (!view_segment(px, k, tile, &r, start)) {
            break;
        }
        start = r.ray.xy;
    }
    store_view(px, r, before);
}

// With refraction, where ray r stands on plane k-1, the start of its segment to plane k (the
// plane it was stored on, or later): a ray skipped on the planes before (its tile was in
// empty space, unbent) is carried straight on from where it was stored, plane by plane with
// the arithmetic of the segments it skipped, so that it lands where stepping would have put
// it, to the bit, whichever planes were skipped (one jump rounds differently, and refraction
// at a grazing rim amplifies that). Once per view pass, before its segments: a loop whose
// count is only known when the shader runs costs a CPU driver every time it is met, even
// when it runs no step (see BACK_PLANES).
fn ray_start(r: ViewRay, k: u32) -> vec2<f32> {
    var x = r.ray.xy;
    if (REFRACTION) {
        let dir = safe_normalize(vec3<f32>(r.ray.zw, r.aux.x));
        for (var j = u32(r.aux.z) - 1u; j + 1u < k; j++) {
            x = straight_to(vec3<f32>(x, plane_z(j)), dir, plane_z(j + 1u)).xy;
        }
    }
    return x;
}

// The ray ends (it is counted out of its tile).
fn end_ray(r: ptr<function, ViewRay>, tile: u32) {
    (*r).aux.z = 0.0;
    atomicSub(&view_tiles[tile], 1u);
}

// One segment from plane k-1 to plane k of the ray r of pixel px, which with refraction starts
// at `start` on plane k-1 (`ray_start`); false once it has ended.
fn view_segment(px: vec2<u32>, k: u32, tile: u32, r: ptr<function, ViewRay>, start: vec2<f32>) -> bool {
    var aux = (*r).aux;
    // A ray skipped on the planes before (its tile was in empty space) has no fresh front
    // value or light: its last segment was empty, so the end's value and light stand in for
    // them (the segment contributes nothing either way).
    let skipped = u32(aux.z) != k;
    let ds = P.plane.y;
    let z = plane_z(k);
    var x0 = unproject(vec2<f32>(px), plane_z(k - 1u));
    var v = primary_dir(vec2<f32>(px));
    if (REFRACTION) {
        x0 = vec3<f32>(start, plane_z(k - 1u));
        v = vec3<f32>((*r).ray.zw, aux.x);
    }
    let dir = safe_normalize(v);
    if (dir.z < P.limits.y && guarded(SG_VIEW_MIN_Z)) {
        // The ray turned (nearly) parallel to the planes or back toward the camera: it leaves
        // the sweep here and keeps its direction for the environment lookup.
        end_ray(r, tile);
        return false;
    }
    // Eq. 8 position update, ending on the next plane (Algorithm 1, line 32).
    let x1 = straight_to(x0, dir, z);
    let value1 = sample_value(x1);
    let value0 = select(aux.y, value1, skipped);
    let ratio = length(x1 - x0) / ds;
    let clipped = is_clipped(0.5 * (x0 + x1));
    let split = segment_split(value0, sample_value(0.5 * (x0 + x1)), value1);
    let s = split_particles(value0, split, value1, ratio, clipped);
    var light1: vec3<f32>;
    if (SCATTER) {
        // What the particles scatter toward the viewer (beams.wgsl, spread mode).
        light1 = spread_seen(k, x1, -dir, value1);
    } else if (LBM) {
        // Single scattering through the phase function; the lattice's light below.
        light1 = lbm_seen(light_through(k, x1, value1), -dir, value1);
    } else {
        light1 = light_through(k, x1, value1);
    }
    let l0 = select((*r).light, light1, skipped);
    // The layer is oriented where the segment's particles begin: halfway to its peak (a
    // sheet's core, where the value has no slope) or to its middle.
    var layer = -1.0;
    if (any(light1 < l0) && s.a > 0.0) {
        layer = layer_ratio(mix(x0, x1, 0.5 * split.x), dir);
    }
    var i_d = s.rgb * segment_light(l0, light1, s.a, layer) * P.light_color.rgb;
    if (LBM) {
        // Multiply scattered light from the illumination grid (lbm_view.wgsl), isotropic.
        i_d += s.rgb * lbm_in_scattering(0.5 * (x0 + x1), split.y) * P.light_color.rgb;
    }
    var color = (*r).color;
    var medium = (*r).medium;
    var ix = Index(P.texel.w, vec3<f32>(0.0));
    if (REFRACTION) {
        ix = index_at(x1);
        if (any(ix.grad != vec3<f32>(0.0))) {
            atomicOr(&view_tiles[tile], VIEW_TILE_BENT);
        }
    }
    var i_s = vec3<f32>(0.0);
    if (SPECULAR) {
        i_s = segment_highlight(x0, x1, aux.w, ix.eta, dir, l0);
    }
    // Eq. 14 (Oddy–Willis compositing).
    let transparency = 1.0 - color.a;
    color = vec4<f32>(color.rgb + transparency * medium * (i_d + i_s), color.a + transparency * s.a);
    if (guarded(SG_MAX_RADIANCE)) {
        color = vec4<f32>(min(color.rgb, vec3<f32>(MAX_RADIANCE)), color.a);
    }
    if (MEDIUM) {
        medium *= split_medium(value0, split, value1, ratio);
    }
    if (REFRACTION) {
        // Eq. 8 direction update: v += Δs ∇η along the segment, |v| = η (Snell).
        v = snell_renormalise(v + ratio * ds * ix.grad, ix);
        (*r).ray = vec4<f32>(x1.xy, v.xy);
        aux.x = v.z;
        aux.w = ix.eta;
    }
    aux.y = value1;
    aux.z = f32(k + 1u);
    (*r).aux = aux;
    (*r).color = color;
    (*r).medium = medium;
    (*r).light = light1;
    // Early termination once nothing behind can show through, or once a refracted ray has
    // left the volume for good (it keeps its direction for the environment).
    let through = (1.0 - color.a) * max(medium.r, max(medium.g, medium.b));
    if (through < 1.0 - P.shading.z || (REFRACTION && left_for_good(x1, v))) {
        end_ray(r, tile);
        return false;
    }
    return true;
}
