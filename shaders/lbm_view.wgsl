// The view's side of the lattice-Boltzmann mode (`lbm.wgsl`): the multiply scattered light
// that the lattice left in the illumination grid, seen as isotropic in-scattering.

override LBM: bool = false;  // quality.multiple_scattering = "lbm" and the particles scatter

// Mirrors `LbmGrid` in src/render/lbm.rs: cells along x, y, z; volume texture coordinates to
// cell coordinates per axis; then the scattered fluence per cell (x fastest).
struct LbmGrid {
    dims: vec4<u32>,
    scale: vec4<f32>,
    fluence: array<f32>,
}

@group(0) @binding(40) var<storage, read> lbm_grid: LbmGrid;
// Its dimensions and scale, copied by the view pass's entry point (`copy_lbm_grid`, as `P`).
var<private> lbm_dims: vec4<u32>;
var<private> lbm_scale: vec4<f32>;

fn copy_lbm_grid() {
    if (LBM) {
        lbm_dims = lbm_grid.dims;
        lbm_scale = lbm_grid.scale;
    }
}
// Per data value: σ_t per voxel, albedo ω, anisotropy g, unused (as in lbm.wgsl).
@group(0) @binding(41) var<storage, read> lbm_albedo: array<vec4<f32>>;

fn lbm_cell(c: vec3<i32>) -> f32 {
    let d = vec3<i32>(lbm_dims.xyz);
    let k = clamp(c, vec3<i32>(0), d - 1);
    return lbm_grid.fluence[u32((k.z * d.y + k.y) * d.x + k.x)];
}

// ω and g at a data value (the table's entries interpolated linearly, as the lattice's).
fn lbm_coefficients(value: f32) -> vec2<f32> {
    let n = arrayLength(&lbm_albedo);
    let x = clamp(value, 0.0, 1.0) * f32(n - 1u);
    let i = min(u32(x), n - 2u);
    return mix(lbm_albedo[i].yz, lbm_albedo[i + 1u].yz, x - f32(i));
}

// The unscattered light `light` as a particle of data value `value` sends it into the direction
// `toward` (unit), relative to isotropic scattering: the fraction ω it scatters through the
// Henyey–Greenstein phase function (single scattering), the rest shaded as without scattering
// (the spread mode's `spread_seen` does the same with its unscattered part).
fn lbm_seen(light: vec3<f32>, toward: vec3<f32>, value: f32) -> vec3<f32> {
    let c = lbm_coefficients(value);
    return light * mix(1.0, hg_relative(dot(P.light_dir.xyz, toward), c.y), clamp(c.x, 0.0, 1.0));
}

// ω(value) times the scattered fluence at the view-space point p (trilinear between cell
// centres, clamped at the grid's faces), relative to the light's irradiance.
fn lbm_in_scattering(p: vec3<f32>, value: f32) -> f32 {
    let g = volume_coord(p) * lbm_scale.xyz - 0.5;
    let c = vec3<i32>(floor(g));
    let t = g - floor(g);
    let x00 = mix(lbm_cell(c), lbm_cell(c + vec3<i32>(1, 0, 0)), t.x);
    let x10 = mix(lbm_cell(c + vec3<i32>(0, 1, 0)), lbm_cell(c + vec3<i32>(1, 1, 0)), t.x);
    let x01 = mix(lbm_cell(c + vec3<i32>(0, 0, 1)), lbm_cell(c + vec3<i32>(1, 0, 1)), t.x);
    let x11 = mix(lbm_cell(c + vec3<i32>(0, 1, 1)), lbm_cell(c + vec3<i32>(1, 1, 1)), t.x);
    let phi = mix(mix(x00, x10, t.y), mix(x01, x11, t.y), t.z);
    return lbm_coefficients(value).x * phi;
}
