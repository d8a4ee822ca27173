// Optics helpers: dielectric Fresnel reflectance and the Cook–Torrance specular term.

// Unpolarised Fresnel reflectance for light going from index n1 into n2 at incidence cosine
// cos_i. Exactly 0 when n1 == n2, so homogeneous regions have no highlight; 1 under total
// internal reflection.
// Index steps below this relative size count as no interface. Interpolating a constant η
// table can leave a last-bit difference, and with n1 > n2 by one ulp the total-internal-
// reflection branch would turn grazing rays into perfect mirrors.
const FRESNEL_MIN_RELATIVE_STEP: f32 = 1e-5;

fn fresnel_dielectric(cos_i: f32, n1: f32, n2: f32) -> f32 {
    if (abs(n1 - n2) <= FRESNEL_MIN_RELATIVE_STEP * max(n1, n2) && guarded(SG_FRESNEL_STEP)) {
        return 0.0;
    }
    let c = clamp(cos_i, 0.0, 1.0);
    let eta = n1 / n2;
    let sin_t2 = eta * eta * (1.0 - c * c);
    if (sin_t2 >= 1.0) {
        return 1.0;
    }
    let cos_t = sqrt(1.0 - sin_t2);
    let rs = (n1 * c - n2 * cos_t) / (n1 * c + n2 * cos_t);
    let rp = (n1 * cos_t - n2 * c) / (n1 * cos_t + n2 * c);
    return 0.5 * (rs * rs + rp * rp);
}

// Smallest GGX width α = roughness². At α = 0 the distribution is 0/0 at the highlight's
// centre; 1e-3 keeps its peak 1/(2π α³) ≈ 1.6e8 finite in 32-bit floats (MAX_RADIANCE bounds
// what accumulates from it).
const MIN_GGX_ALPHA: f32 = 1e-3;

// Cook–Torrance with a GGX distribution and Smith-Schlick geometry. `n`, `l` (towards the
// light) and `v` (towards the viewer) are unit vectors; returns the BRDF times cos(n, l)
// without the Fresnel factor.
fn cook_torrance(n: vec3<f32>, l: vec3<f32>, v: vec3<f32>, roughness: f32) -> f32 {
    let nl = dot(n, l);
    let nv = dot(n, v);
    if (nl <= 0.0 || nv <= 0.0) {
        return 0.0;
    }
    let h = normalize(l + v);
    let nh = max(dot(n, h), 0.0);
    var a = roughness * roughness;
    if (guarded(SG_GGX_ALPHA)) {
        a = max(a, MIN_GGX_ALPHA);
    }
    let a2 = a * a;
    let denom = nh * nh * (a2 - 1.0) + 1.0;
    let d = a2 / (3.14159265 * denom * denom);
    let k = a * 0.5;
    let g = (nl / (nl * (1.0 - k) + k)) * (nv / (nv * (1.0 - k) + k));
    return d * g / (4.0 * nv);
}
