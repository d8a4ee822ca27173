// Shared declarations of every caustica pass: parameters, bindings, feature switches and
// helpers. Prepended to each pass file before compilation.
//
// Coordinates: "view space" has the camera at the origin, x right, y down, z forward (depth).
// Plane i lies at z = plane.x + i * plane.y. Buffer texel (u, v) on plane i is the point where
// the straight primary ray of pixel (u, v) meets that plane.

// Feature switches, resolved by naga before SPIR-V is written (one pipeline per combination).
override REFRACTION: bool = true;           // η varies: bend light and view rays
override MEDIUM: bool = true;               // medium colour is not white: track M per view ray
override LIGHT_FILTER: bool = true;         // incremental convolution (soft light)
override INTENSITY_CORRECTION: bool = true; // intensity law S_{i-1}/S_i (caustics)
override SPECULAR: bool = true;             // Cook–Torrance highlight at index changes
override CLIP: bool = false;                // clip plane zeroes opacity
override ETA_VOLUME: bool = false;          // η from a second volume
override ORTHOGRAPHIC: bool = false;
override DEBUG_VIEW: u32 = 0u;              // finish pass: 0 image, 1 light, 2 light direction, 3 concentration, 4 medium
override GRADIENT: u32 = 0u;                // gradient reconstruction: 0 central differences, 1 forward differences
// Safeguards switched off, one bit each (SG_* below). Always 0 in renders; tests set single
// bits to show that each safeguard is needed. Constant-folded like the features above.
override SAFEGUARDS_OFF: u32 = 0u;

// Every clamp and epsilon of the shaders has a bit here (see README, "Numerical safeguards").
const SG_LIGHT_MIN_Z: u32 = 1u;          // light directions keep z >= MIN_LIGHT_DIR_Z
const SG_VIEW_MIN_Z: u32 = 2u;           // view rays leave the sweep below MIN_VIEW_DIR_Z
const SG_INTENSITY_RATIO: u32 = 4u;      // per-plane clamp of the intensity-law ratio
const SG_CONCENTRATION: u32 = 8u;        // light never exceeds max_concentration × the source
const SG_FOLD: u32 = 16u;                // no further concentration where the backward map folds
const SG_MAX_LIGHT: u32 = 32u;           // stored light <= MAX_LIGHT_VALUE
const SG_MAX_RADIANCE: u32 = 64u;        // accumulated colour <= MAX_RADIANCE
const SG_FRESNEL_STEP: u32 = 128u;       // FRESNEL_MIN_RELATIVE_STEP
const SG_GGX_ALPHA: u32 = 256u;          // MIN_GGX_ALPHA
const SG_SEGMENT_OPACITY: u32 = 512u;    // MIN_SEGMENT_OPACITY
const SG_GRADIENT_LENGTH: u32 = 1024u;   // MIN_GRADIENT_LENGTH
const SG_DIRECTION_LENGTH: u32 = 2048u;  // MIN_DIRECTION_LENGTH

fn guarded(bit: u32) -> bool {
    return (SAFEGUARDS_OFF & bit) == 0u;
}

// Below this length a direction vector counts as zero and is not normalised (0/0 = NaN).
const MIN_DIRECTION_LENGTH: f32 = 1e-12;
// Segments whose reference opacity is below this are rescaled linearly in length: the ratio
// of the two opacities would be 0/0 for a fully transparent segment.
const MIN_SEGMENT_OPACITY: f32 = 1e-6;
// Gradients shorter than this (data value per view unit) give no surface normal, so no
// highlight: normalising them would divide by zero in homogeneous regions.
const MIN_GRADIENT_LENGTH: f32 = 1e-6;
// Largest accumulated radiance in the colour buffer: a quarter of the 16-bit float maximum
// (65504), so that the final blend with the environment cannot overflow in f16 either.
// Reached only by sums of sharp highlights (roughness near 0 at many index steps).
const MAX_RADIANCE: f32 = 16384.0;
// Floor of the tracked concentration: ratios below 1 (light spreading out) shrink it by up to
// max_intensity_ratio per plane, and it must not underflow to 0 before the budget divides by it.
const MIN_CONCENTRATION: f32 = 1e-6;

fn safe_normalize(v: vec3<f32>) -> vec3<f32> {
    if (guarded(SG_DIRECTION_LENGTH)) {
        return v / max(length(v), MIN_DIRECTION_LENGTH);
    }
    return v / length(v);
}

struct Params {
    volume_from_view: mat4x4<f32>,   // view-space point -> volume texture coordinates [0,1]^3
    gradient_to_view: mat4x4<f32>,   // central differences (per texel) -> view-space gradient
    world_from_view: mat4x4<f32>,    // rotation only: view direction -> environment direction
    clip_plane: vec4<f32>,           // view space; opacity is zero where dot(xyz, p) + w > 0
    projection: vec4<f32>,           // fx, fy, cx, cy (pixels); ortho: pixel = f * p + c
    plane: vec4<f32>,                // z of plane 0, Δs (view units), plane count, Δs in voxels
    light_dir: vec4<f32>,            // initial propagation direction (unit, z > 0); w: filter radius per plane (view units)
    light_color: vec4<f32>,          // rgb radiance of the light; w: max intensity ratio per plane
    shading: vec4<f32>,              // specular intensity, roughness, termination opacity, environment intensity
    size: vec4<f32>,                 // width, height, 1/width, 1/height
    texel: vec4<f32>,                // 1 / volume dims (xyz), eta table size (w)
    background: vec4<f32>,           // rgb background when there is no environment map; w: 1 = use env map
    limits: vec4<f32>,               // min light dir z, min view dir z, max light value, env map mip count
    budget: vec4<f32>,               // x: max concentration (light / source light); yzw: unused
}

struct Immediates {
    plane_index: u32,
    seed: u32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var volume_tex: texture_3d<f32>;
@group(0) @binding(2) var linear_clamp: sampler;      // clamp-to-edge, tables
@group(0) @binding(3) var volume_sampler: sampler;    // clamp-to-border (0 outside)
@group(0) @binding(4) var eta_volume_tex: texture_3d<f32>;
@group(0) @binding(5) var particle_table: texture_2d<f32>;   // rgb: premultiplied colour, a: τ_α
@group(0) @binding(6) var medium_table: texture_2d<f32>;     // rgb: τ_m
@group(0) @binding(7) var eta_table: texture_2d<f32>;        // r: η(x), size x 1
@group(0) @binding(8) var env_tex: texture_2d<f32>;
@group(0) @binding(9) var env_sampler: sampler;

// Read side of the ping-pong buffers (state at plane i-1).
@group(0) @binding(10) var light_in: texture_2d<f32>;
@group(0) @binding(11) var light_dir_in: texture_2d<f32>;
@group(0) @binding(12) var view_pos_in: texture_2d<f32>;
@group(0) @binding(13) var view_dir_in: texture_2d<f32>;
@group(0) @binding(14) var color_in: texture_2d<f32>;
@group(0) @binding(15) var medium_in: texture_2d<f32>;
// Write side (state at plane i). Light, colour and medium are stored at the scene's
// precision: `ColourState` is rgba16float as written here, and the renderer gives this one
// alias rgba32float for `precision = "f32"` (`ShaderSource::set_storage_format`; WGSL has no
// override for a texel format).
alias ColourState = texture_storage_2d<rgba16float, write>;
@group(0) @binding(16) var light_out: ColourState;
@group(0) @binding(17) var light_dir_out: texture_storage_2d<rgba32float, write>;
@group(0) @binding(18) var view_pos_out: texture_storage_2d<rgba32float, write>;
@group(0) @binding(19) var view_dir_out: texture_storage_2d<rgba32float, write>;
@group(0) @binding(20) var color_out: ColourState;
@group(0) @binding(21) var medium_out: ColourState;
@group(0) @binding(22) var image_out: texture_storage_2d<rgba32float, write>;

var<immediate> I: Immediates;

fn plane_z(i: u32) -> f32 {
    return P.plane.x + f32(i) * P.plane.y;
}

fn buffer_size() -> vec2<i32> {
    return vec2<i32>(i32(P.size.x), i32(P.size.y));
}

// Point on the plane at depth z seen through the centre of texel `t` (continuous texel coords).
fn unproject(t: vec2<f32>, z: f32) -> vec3<f32> {
    let ndc = (t + vec2<f32>(0.5) - P.projection.zw) / P.projection.xy;
    if (ORTHOGRAPHIC) {
        return vec3<f32>(ndc, z);
    }
    return vec3<f32>(ndc * z, z);
}

// Continuous texel coordinates of a view-space point (inverse of `unproject`).
// The perspective division needs no guard: every point projected lies on a plane of the
// sweep (p.z = z_prev or z, to rounding; MIN_LIGHT_DIR_Z and MIN_VIEW_DIR_Z keep the steps
// onto it finite), and planes start at z_first >= NEAR_PLANE x radius > 0 (scene/view.rs). The
// rounding is a few ulp of Δs (<= 32 radii), of the light filter's offsets (<= MAX_SOFTNESS x
// Δs) and of z: ~1e-5 radii, far below NEAR_PLANE x radius, and it scales with the scene, so
// p.z > 0 at any spacing. A fixed floor such as 1e-6 view units would instead move planes
// nearer than that: micrometre voxels given in metres would render differently from the same
// voxels given in voxels (tests/extremes/, camera_inside_a_microscopic_volume).
fn project(p: vec3<f32>) -> vec2<f32> {
    var xy = p.xy;
    if (!ORTHOGRAPHIC) {
        xy = p.xy / p.z;
    }
    return xy * P.projection.xy + P.projection.zw - vec2<f32>(0.5);
}

// Direction of the straight primary ray through texel `t` (unit length).
fn primary_dir(t: vec2<f32>) -> vec3<f32> {
    if (ORTHOGRAPHIC) {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    return normalize(unproject(t, 1.0));
}

fn inside(t: vec2<f32>) -> bool {
    let s = P.size.xy;
    return t.x >= -0.5 && t.y >= -0.5 && t.x <= s.x - 0.5 && t.y <= s.y - 0.5;
}

// Bilinear fetch with manual weights, so that every buffer format filters the same way on
// every device. Returns `outside` beyond the buffer (the unobstructed light).
fn bilinear(tex: texture_2d<f32>, t: vec2<f32>, outside: vec4<f32>) -> vec4<f32> {
    if (!inside(t)) {
        return outside;
    }
    let lo = floor(t);
    let f = t - lo;
    let maxc = buffer_size() - vec2<i32>(1);
    let a = clamp(vec2<i32>(lo), vec2<i32>(0), maxc);
    let b = clamp(vec2<i32>(lo) + vec2<i32>(1), vec2<i32>(0), maxc);
    let v00 = textureLoad(tex, vec2<i32>(a.x, a.y), 0);
    let v10 = textureLoad(tex, vec2<i32>(b.x, a.y), 0);
    let v01 = textureLoad(tex, vec2<i32>(a.x, b.y), 0);
    let v11 = textureLoad(tex, vec2<i32>(b.x, b.y), 0);
    return mix(mix(v00, v10, f.x), mix(v01, v11, f.x), f.y);
}

fn volume_coord(p: vec3<f32>) -> vec3<f32> {
    return (P.volume_from_view * vec4<f32>(p, 1.0)).xyz;
}

// Data value (transfer-function domain) at a view-space point; 0 outside the volume.
fn sample_value(p: vec3<f32>) -> f32 {
    return textureSampleLevel(volume_tex, volume_sampler, volume_coord(p), 0.0).r;
}

fn eta_of(x: f32) -> f32 {
    let n = P.texel.w;
    let t = clamp(x, 0.0, 1.0) * (n - 1.0);
    let i = u32(floor(t));
    let j = min(i + 1u, u32(n) - 1u);
    let a = textureLoad(eta_table, vec2<u32>(i, 0u), 0).r;
    let b = textureLoad(eta_table, vec2<u32>(j, 0u), 0).r;
    return mix(a, b, t - f32(i));
}

fn eta_source_value(uvw: vec3<f32>) -> f32 {
    if (ETA_VOLUME) {
        return textureSampleLevel(eta_volume_tex, volume_sampler, uvw, 0.0).r;
    }
    return textureSampleLevel(volume_tex, volume_sampler, uvw, 0.0).r;
}

// Refractive index at a view-space point.
fn eta_at(p: vec3<f32>) -> f32 {
    return eta_of(eta_source_value(volume_coord(p)));
}

struct Gradients {
    value: vec3<f32>,  // ∇f in view space (data value per view unit)
    eta: vec3<f32>,    // ∇η in view space, from η_tf applied to the neighbours (central differences)
}

// Differences one voxel apart. ∇η applies η_tf to each neighbour before differencing, so
// steps in η_tf produce the right jump instead of the zero a chain rule would give.
// GRADIENT 0: central differences (6 lookups, second order). GRADIENT 1: forward differences
// (3 lookups + the centre, first order: the gradient of the point half a voxel ahead on each
// axis); doubled to match the central-difference scaling of `gradient_to_view`.
fn gradients(p: vec3<f32>, want_value: bool) -> Gradients {
    let c = volume_coord(p);
    var dv = vec3<f32>(0.0);
    var de = vec3<f32>(0.0);
    var centre_eta = 0.0;
    var centre_value = 0.0;
    if (GRADIENT == 1u) {
        let s = eta_source_value(c);
        centre_eta = eta_of(s);
        centre_value = s;
        if (ETA_VOLUME && want_value) {
            centre_value = textureSampleLevel(volume_tex, volume_sampler, c, 0.0).r;
        }
    }
    for (var k = 0; k < 3; k++) {
        var h = vec3<f32>(0.0);
        h[k] = P.texel[k];
        let ep = eta_source_value(c + h);
        if (GRADIENT == 1u) {
            de[k] = 2.0 * (eta_of(ep) - centre_eta);
            if (want_value) {
                var vp = ep;
                if (ETA_VOLUME) {
                    vp = textureSampleLevel(volume_tex, volume_sampler, c + h, 0.0).r;
                }
                dv[k] = 2.0 * (vp - centre_value);
            }
        } else {
            let em = eta_source_value(c - h);
            de[k] = eta_of(ep) - eta_of(em);
            if (want_value) {
                if (ETA_VOLUME) {
                    dv[k] = textureSampleLevel(volume_tex, volume_sampler, c + h, 0.0).r
                          - textureSampleLevel(volume_tex, volume_sampler, c - h, 0.0).r;
                } else {
                    dv[k] = ep - em;
                }
            }
        }
    }
    let m = mat3x3<f32>(P.gradient_to_view[0].xyz, P.gradient_to_view[1].xyz, P.gradient_to_view[2].xyz);
    return Gradients(m * dv, m * de);
}

// Pre-integrated segment from value a (front) to value b (back), length `ratio` × Δs.
// Returns premultiplied colour (rgb) and opacity (a) of the particles.
fn segment_particles(a: f32, b: f32, ratio: f32, clipped: bool) -> vec4<f32> {
    if (clipped) {
        return vec4<f32>(0.0);
    }
    let e = textureSampleLevel(particle_table, linear_clamp, table_uv(a, b), 0.0);
    let alpha_ds = 1.0 - exp(-e.a);
    let alpha = 1.0 - exp(-e.a * ratio);
    // Rescale the premultiplied colour with the opacity of the longer or shorter segment.
    var scale = ratio;
    if (alpha_ds > MIN_SEGMENT_OPACITY || !guarded(SG_SEGMENT_OPACITY)) {
        scale = alpha / alpha_ds;
    }
    return vec4<f32>(e.rgb * scale, alpha);
}

// Medium transmittance of the segment.
fn segment_medium(a: f32, b: f32, ratio: f32) -> vec3<f32> {
    let tau = textureSampleLevel(medium_table, linear_clamp, table_uv(a, b), 0.0).rgb;
    return exp(-tau * ratio);
}

fn table_uv(a: f32, b: f32) -> vec2<f32> {
    let n = f32(textureDimensions(particle_table).x);
    return (clamp(vec2<f32>(a, b), vec2<f32>(0.0), vec2<f32>(1.0)) * (n - 1.0) + 0.5) / n;
}

fn is_clipped(p: vec3<f32>) -> bool {
    if (CLIP) {
        return dot(P.clip_plane.xyz, p) + P.clip_plane.w > 0.0;
    }
    return false;
}

// Integer hash (PCG-style) for the per-texel random rotation of the filter kernel;
// deterministic, so two renders give identical bytes.
fn hash(x: u32) -> u32 {
    var v = x * 747796405u + 2891336453u;
    v = ((v >> ((v >> 28u) + 4u)) ^ v) * 277803737u;
    return (v >> 22u) ^ v;
}

fn random01(texel: vec2<u32>, plane: u32) -> f32 {
    let h = hash(texel.x ^ hash(texel.y ^ hash(plane ^ I.seed)));
    return f32(h & 0xffffu) / 65536.0;
}
