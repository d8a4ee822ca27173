// Multiple scattering by lattice-Boltzmann diffusion (Bernabei et al., Section III; the
// lattice-Boltzmann lighting of Geist et al. with six directions, D3Q6) on an illumination
// grid coarser than the volume. A module of its own: it runs before the sweep, which reads
// the fluence it leaves (`lbm_view.wgsl`).
//
// Units: lengths in voxels (the smallest spacing, the unit of the opacity curve); light
// relative to the source's irradiance. f_i is the scattered fluence a cell holds in direction
// i, so the cell's scattered fluence is Σ f_i.

// Mirrors `LbmParams` in src/render/lbm.rs.
struct LbmParams {
    grid: vec4<u32>,        // cells along x, y, z; sub-samples per cell edge
    volume: vec4<f32>,      // volume extent in voxels (x, y, z); cell edge in voxels
    to_light: vec4<f32>,    // unit direction toward the light (voxel space); march step in voxels
    table: vec4<f32>,       // entries of `lbm_table`; unused
}

@group(0) @binding(0) var<storage, read> lbm_params: LbmParams;
// Copied by each entry point before anything else and read from here (see `P` in
// common.wgsl: a CPU driver loads storage buffers invocation by invocation inside branches).
var<private> L: LbmParams;
@group(0) @binding(1) var volume_tex: texture_3d<f32>;
@group(0) @binding(2) var volume_sampler: sampler;   // clamp-to-border (0 outside)
// Per data value: σ_t per voxel, albedo ω, anisotropy g, unused.
@group(0) @binding(3) var<storage, read> lbm_table: array<vec4<f32>>;
// Per cell: source q (fluence per step, all six directions together), scattering s and
// absorption a per step (the collision's coefficients), deposited power (per voxel² of the
// cross-section, for the energy balance).
@group(0) @binding(4) var<storage, read_write> cells: array<vec4<f32>>;
// The six densities per cell (direction-major: f[i · cells + cell]), read and written in turn.
@group(0) @binding(5) var<storage, read> f_in: array<f32>;
@group(0) @binding(6) var<storage, read_write> f_out: array<f32>;
// Per cell after a step: fluence, its change over the step, what left the grid, what was absorbed.
@group(0) @binding(7) var<storage, read_write> measure: array<vec4<f32>>;
// Per cell: the mean cosine g of the light its particles scatter (weighted by what they
// scatter), which directs its source.
@group(0) @binding(8) var<storage, read_write> source_g: array<f32>;

const WG: u32 = 64u;
// Cells per unit time the lattice's light moves (see `deposit_main`).
const LATTICE_SPEED: f32 = 1.5;

fn cell_count() -> u32 {
    return L.grid.x * L.grid.y * L.grid.z;
}

fn cell_of(i: u32) -> vec3<u32> {
    return vec3<u32>(i % L.grid.x, (i / L.grid.x) % L.grid.y, i / (L.grid.x * L.grid.y));
}

fn coefficients(value: f32) -> vec4<f32> {
    let n = u32(L.table.x);
    let x = clamp(value, 0.0, 1.0) * f32(n - 1u);
    let i = min(u32(x), n - 2u);
    return mix(lbm_table[i], lbm_table[i + 1u], x - f32(i));
}

fn value_at(p: vec3<f32>) -> f32 {
    return textureSampleLevel(volume_tex, volume_sampler, p / L.volume.xyz, 0.0).r;
}

// Optical depth from p toward the light until the volume ends, one step per `L.to_light.w`
// voxels (midpoint rule).
fn depth_to_light(p: vec3<f32>) -> f32 {
    let d = L.to_light.xyz;
    // Distance to the box [0, extent] along d.
    let far = select((L.volume.xyz - p) / d, -p / d, d < vec3<f32>(0.0));
    let inf = vec3<f32>(3.0e38);
    let t_exit = min(min(select(inf, far, abs(d) > vec3<f32>(1e-6)).x, select(inf, far, abs(d) > vec3<f32>(1e-6)).y),
        select(inf, far, abs(d) > vec3<f32>(1e-6)).z);
    let h = L.to_light.w;
    let steps = u32(ceil(max(t_exit, 0.0) / h));
    var tau = 0.0;
    for (var k = 0u; k < steps; k++) {
        let t = min((f32(k) + 0.5) * h, t_exit);
        let len = min(h, t_exit - f32(k) * h);
        tau += coefficients(value_at(p + d * t)).x * len;
    }
    return tau;
}

// Light marching: the light scattered in each cell (Bernabei Fig. 4 with the attenuation
// multiplied, as Eq. for L_t says). Each of the cell's sub-samples (one per voxel at one cell
// per `grid.w` voxels) takes the light that reaches its front, removes the fraction
// 1 − e^{−σ_t h} over its length h along the light, and passes on the fraction ω of it.
@compute @workgroup_size(WG, 1, 1)
fn deposit_main(@builtin(global_invocation_id) id: vec3<u32>) {
    L = lbm_params;
    let i = id.x;
    if (i >= cell_count()) {
        return;
    }
    let c = vec3<f32>(cell_of(i));
    let n = L.grid.w;
    let edge = L.volume.w;
    let h = L.to_light.w;
    var scattered = 0.0;  // Σ ω T (1 − e^{−σ_t h}) / h: scattered power per volume
    var scattered_g = 0.0; // Σ of the same times g
    var sigma_s = 0.0;    // Σ reduced scattering σ_s (1 − g)
    var sigma_a = 0.0;
    var inside = 0.0;
    for (var k = 0u; k < n * n * n; k++) {
        let sub = vec3<f32>(f32(k % n), f32((k / n) % n), f32(k / (n * n))) + 0.5;
        let p = (c + sub / f32(n)) * edge;
        if (any(p > L.volume.xyz)) {
            continue;
        }
        inside += 1.0;
        let m = coefficients(value_at(p));
        let front = depth_to_light(p + L.to_light.xyz * (0.5 * h));
        let q = m.y * exp(-front) * (1.0 - exp(-m.x * h)) / h;
        scattered += q;
        scattered_g += q * m.z;
        sigma_s += m.x * m.y * (1.0 - m.z);
        sigma_a += m.x * (1.0 - m.y);
    }
    let w = 1.0 / max(inside, 1.0);
    // Per-step coefficients of the collision: the paper's Θ_ij (Eq. 5) with per-step values,
    // chosen so that the lattice solves the diffusion equation of the medium, with its
    // boundary condition:
    // - The lattice's light moves one cell per step at LATTICE_SPEED: isotropic light puts a
    //   sixth of its density on each axis direction, so a face lets through c/6 of the
    //   fluence per unit time where isotropic radiance lets through 1/4 (the Marshak
    //   condition φ = 2J at a face needs c = 3/2). A step lasts λ/c.
    // - a = σ_a λ/c is absorbed per step and leaves the lattice (the paper's rest density,
    //   which it would emit again, is dropped): a uniform medium holds the fluence Q/σ_a.
    // - The current decays by k = s + a per step (what keeps its direction, minus what turns
    //   back); a walk whose current survives with 1 − k per step diffuses with
    //   λ c (2 − k)/(6k) per unit time. Diffusion theory's 1/(3σ_t'), σ_t' = σ_a + σ_s(1 − g),
    //   gives k = 2u/(2 + u) with u = c σ_t' λ. s is capped where the weight staying on,
    //   1 − 5s/6 − a, would turn negative (cells thicker than about two transport mean free
    //   paths diffuse too fast).
    let step_time = edge / LATTICE_SPEED;
    let a = min(sigma_a * w * step_time, 1.0);
    let u = LATTICE_SPEED * (sigma_s + sigma_a) * w * edge;
    let s = clamp(2.0 * u / (2.0 + u) - a, 0.0, 1.2 * (1.0 - a));
    // Source per step: the power scattered per volume over one step's time (fluence units).
    cells[i] = vec4<f32>(scattered * w * step_time, s, a, scattered * w * edge * edge * edge);
    source_g[i] = select(0.0, scattered_g / scattered, scattered > 0.0);
}

const DIRS: array<vec3<i32>, 6> = array<vec3<i32>, 6>(
    vec3<i32>(1, 0, 0), vec3<i32>(-1, 0, 0),
    vec3<i32>(0, 1, 0), vec3<i32>(0, -1, 0),
    vec3<i32>(0, 0, 1), vec3<i32>(0, 0, -1),
);

fn inside_grid(c: vec3<i32>) -> bool {
    return all(c >= vec3<i32>(0)) && all(c < vec3<i32>(L.grid.xyz));
}

fn index_of(c: vec3<i32>) -> u32 {
    return (u32(c.z) * L.grid.y + u32(c.y)) * L.grid.x + u32(c.x);
}

// The share of a cell's source that goes into lattice direction `dir`: the deposited light is
// scattered once, by Henyey–Greenstein particles of mean cosine g, so its current is g times
// its fluence along the light's direction of travel l. Shares (1 + (3g/c) e_i·l)/6 hold that
// current (Σ_i share_i c e_i = g l); negative shares (g above c/3 about an axis) are clamped
// to 0 and the rest renormalised, which keeps the source and most of its current. g = 0: a
// sixth in every direction.
fn source_share(i: u32, dir: u32) -> f32 {
    let l = -L.to_light.xyz;
    let a = 3.0 * source_g[i] / LATTICE_SPEED;
    var total = 0.0;
    for (var j = 0u; j < 6u; j++) {
        total += max(1.0 + a * dot(vec3<f32>(DIRS[j]), l), 0.0);
    }
    return max(1.0 + a * dot(vec3<f32>(DIRS[dir]), l), 0.0) / total;
}

// The collision at a cell: Eq. 4–5 corrected, f'_i = (s/6) Σ_j f_j + (1 − s − a) f_i, plus
// the source's share in direction i (`source_share`).
fn collide(i: u32, dir: u32) -> f32 {
    let n = cell_count();
    var total = 0.0;
    for (var j = 0u; j < 6u; j++) {
        total += f_in[j * n + i];
    }
    let c = cells[i];
    return c.y / 6.0 * total + (1.0 - c.y - c.z) * f_in[dir * n + i] + c.x * source_share(i, dir);
}

// One step: collide, then stream each direction to the neighbour (Eq. 4); what streams out of
// the grid has left the medium.
@compute @workgroup_size(WG, 1, 1)
fn step_main(@builtin(global_invocation_id) id: vec3<u32>) {
    L = lbm_params;
    let i = id.x;
    let n = cell_count();
    if (i >= n) {
        return;
    }
    let c = vec3<i32>(cell_of(i));
    for (var d = 0u; d < 6u; d++) {
        let to = c + DIRS[d];
        if (inside_grid(to)) {
            f_out[d * n + index_of(to)] = collide(i, d);
        }
    }
}

// Per cell, with f_in the latest densities and f_out those of the step before: the fluence,
// its change, and what the step that made f_in from f_out sent out of the grid and absorbed.
// Then per step, source − leaving − absorbed = Σφₙ − Σφₙ₋₁ exactly, which the summed change
// bounds.
@compute @workgroup_size(WG, 1, 1)
fn measure_main(@builtin(global_invocation_id) id: vec3<u32>) {
    L = lbm_params;
    let i = id.x;
    let n = cell_count();
    if (i >= n) {
        return;
    }
    let c = vec3<i32>(cell_of(i));
    let coef = cells[i];
    var now = 0.0;
    var before = 0.0;
    for (var d = 0u; d < 6u; d++) {
        now += f_in[d * n + i];
        before += f_out[d * n + i];
    }
    var leaving = 0.0;
    for (var d = 0u; d < 6u; d++) {
        if (!inside_grid(c + DIRS[d])) {
            // The collision of the step before (`collide` on f_out).
            leaving += coef.y / 6.0 * before + (1.0 - coef.y - coef.z) * f_out[d * n + i] + coef.x * source_share(i, d);
        }
    }
    measure[i] = vec4<f32>(now, abs(now - before), leaving, coef.z * before);
}
