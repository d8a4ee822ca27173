//! The plane trace through lenses against exact answers: power conservation, the ball lens's
//! paraxial focus, Snell's law; and the GPU light-buffer criteria against a wrong result.

use glam::{DVec2, DVec3};

use super::graded_ball::to_sphere;
use super::measure::{self, Region, ScalarImage};
use super::medium::{Medium, Optics, VolumeMedium};
use super::plane_light::{self, PlaneSettings, PlaneView};
use super::plane_tests::{axis_view, axis_view_at, light, settings, tf, volume};

#[test]
fn non_absorbing_lenses_conserve_power_through_every_plane() {
    // A weak index bump (η up to 1.08, Gaussian σ = 5 voxels) focuses light a little without
    // sending any out of the frame: the frame's power stays that of the unobstructed light
    // while the axis brightens. A glass ball (n = 1.5) sends light out of the frame, but
    // the net power through the whole plane stays what was launched.
    let bump = volume([40; 3], |p| (-p.length_squared() / 50.0).exp());
    let clear = tf(vec![[0.0, 1.0], [1.0, 1.08]], vec![[0.0, 0.0]]);
    let medium = VolumeMedium::new(&bump, [0.0, 1.0], &clear);
    // The frame reaches 12 voxels beyond the volume: all light that passed the bump lands in it.
    let view = axis_view(64, 64, 1.0);
    let planes = [0.0, 10.0, 19.0, 30.0];
    let l = plane_light::trace(&medium, &light(DVec3::Z, 0.0), &view, &planes, &settings(4, 0.25), None).unwrap();
    for p in &l.planes {
        let frame = p.power_in_frame[1] / (64.0 * 64.0);
        let peak = p.texels.iter().map(|t| t[1]).fold(0.0, f64::max);
        eprintln!("bump: z = {}: frame power {frame:.12}, peak {peak:.3}", p.z);
        // Deposits are exact partitions of each ray's power, and the rays at the frame's edge
        // pass outside the volume: rounding only.
        assert!((frame - 1.0).abs() < 1e-9, "z = {}: frame power {frame}", p.z);
        assert_eq!(p.power_backward, [0.0; 3]);
    }
    let peak = l.planes[3].texels.iter().map(|t| t[1]).fold(0.0, f64::max);
    assert!(peak > 1.3, "the bump must focus for the test to mean anything: {peak}");

    // The glass ball's graded rim (1.5 voxels) bends some light by more than 90°: it leaves
    // toward the camera and never reaches the planes behind. Every plane in front of the ball
    // sees it cross back; the net power through every plane is what was launched less that.
    let (ball, glass) = super::tests::ball_volume(32, 8.0, 1.5);
    let medium = VolumeMedium::new(&ball, [0.0, 1.0], &glass);
    let view = axis_view(32, 32, 1.0);
    let planes = [-20.0, 20.0, 40.0];
    let l = plane_light::trace(&medium, &light(DVec3::Z, 0.0), &view, &planes, &settings(4, 0.25), None).unwrap();
    let back = l.power_escaped_backward[1];
    let lost = l.power_lost[1];
    eprintln!(
        "ball: {:.3}% of the launched power escaped backward, {:.3}% trapped",
        100.0 * back / l.power_launched,
        100.0 * lost / l.power_launched
    );
    assert!(back > 0.0, "the test must cover light turned back");
    for p in &l.planes {
        // Behind the bounds (z > 16.5) nothing turned back or trapped arrives; in front,
        // what turned back crosses again, backward.
        let expected = if p.z > 0.0 {
            l.power_launched - back - lost
        } else {
            l.power_launched - back
        };
        let error = (p.power_crossing[1] - expected).abs() / l.power_launched;
        eprintln!("ball: z = {}: net crossing off by {error:.1e}", p.z);
        // Every ray is followed to its end: rounding only.
        assert!(error < 1e-12, "z = {}: net crossing off by {error}", p.z);
    }
}

/// A glass ball (index `n`, radius `r`, surface graded over ±`w` by a quintic smoothstep, so
/// that ∇η and its derivative are continuous and RK4 keeps its order through it) behind an
/// opaque screen at z = `stop_z` with a hole of radius `hole` on the axis; all analytic.
struct BallBehindStop {
    n: f64,
    r: f64,
    w: f64,
    stop_z: f64,
    hole: f64,
    half: DVec3,
}

const STOP_HALF_THICKNESS: f64 = 0.25;

impl BallBehindStop {
    fn in_stop_slab(&self, p: DVec3) -> bool {
        (p.z - self.stop_z).abs() < STOP_HALF_THICKNESS
    }
}

impl Medium for BallBehindStop {
    fn eta(&self, p: DVec3) -> f64 {
        let t = ((self.r + self.w - p.length()) / (2.0 * self.w)).clamp(0.0, 1.0);
        1.0 + (self.n - 1.0) * t * t * t * (t * (6.0 * t - 15.0) + 10.0)
    }
    fn grad_eta(&self, p: DVec3) -> DVec3 {
        let d = p.length();
        if (d - self.r).abs() < self.w {
            let t = (self.r + self.w - d) / (2.0 * self.w);
            -p / d * (self.n - 1.0) * 30.0 * t * t * (1.0 - t) * (1.0 - t) / (2.0 * self.w)
        } else {
            DVec3::ZERO
        }
    }
    fn optics(&self, p: DVec3) -> Optics {
        let blocked = self.in_stop_slab(p) && p.truncate().length() > self.hole;
        Optics {
            tau_alpha: if blocked { 1e3 } else { 0.0 },
            ..Optics::default()
        }
    }
    fn bounds(&self) -> (DVec3, DVec3) {
        (-self.half, self.half)
    }
    fn voxel_length(&self) -> f64 {
        1.0
    }
    fn uniform_for(&self, p: DVec3, d: DVec3) -> Option<f64> {
        let shell = (p.length() - self.r).abs() < self.w;
        if shell || self.in_stop_slab(p) {
            return None;
        }
        let mut t = to_sphere(p, d, self.r - self.w).min(to_sphere(p, d, self.r + self.w));
        for z in [self.stop_z - STOP_HALF_THICKNESS, self.stop_z + STOP_HALF_THICKNESS] {
            let s = (z - p.z) / d.z;
            if s > 0.0 {
                t = t.min(s);
            }
        }
        Some(t.min(2.0 * self.half.max_element()))
    }
}

#[test]
fn ball_lens_focuses_paraxial_light_at_n_r_over_2_n_minus_1() {
    // Paraxial light (a hole of 0.1 R in front of the ball) focuses nR/(2(n−1)) = 1.5 R behind
    // the centre. Behind the ball every ray is straight, so the spot's mean square radius is
    // exactly quadratic in depth (the box footprints and texels add a constant): the vertex
    // of a parabola fitted over ±3 voxels is where the spot is smallest.
    let (n, r) = (1.5, 12.8);
    let medium = BallBehindStop {
        n,
        r,
        w: 0.1,
        stop_z: -r - 1.0,
        hole: 0.1 * r,
        half: DVec3::new(r + 1.0, r + 1.0, r + 2.0),
    };
    let paraxial = n * r / (2.0 * (n - 1.0));
    let texel = 0.05;
    let view = axis_view(48, 48, texel);
    let planes: Vec<f64> = (0..=12).map(|k| paraxial - 3.0 + 0.5 * k as f64).collect();
    let s = PlaneSettings {
        rays_per_texel: 2,
        step_voxels: 0.01,
        ..PlaneSettings::default()
    };
    let l = plane_light::trace(&medium, &light(DVec3::Z, 0.0), &view, &planes, &s, None).unwrap();
    let ms: Vec<f64> = l
        .planes
        .iter()
        .map(|p| {
            let (mut m0, mut m2) = (0.0, 0.0);
            for y in 0..48 {
                for x in 0..48 {
                    let c = DVec2::new(x as f64 - 23.5, y as f64 - 23.5) * texel;
                    let e = p.texels[y * 48 + x][1];
                    m0 += e;
                    m2 += e * c.length_squared();
                }
            }
            m2 / m0
        })
        .collect();
    // Least squares ms = a + b t + c t², t = z − paraxial.
    let mut m = [[0.0f64; 4]; 3];
    for (z, v) in planes.iter().zip(&ms) {
        let t = z - paraxial;
        let row = [1.0, t, t * t];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            m[i][3] += row[i] * v;
        }
    }
    let [_, b, c] = solve3(m);
    let focus = paraxial - b / (2.0 * c);
    eprintln!(
        "paraxial focus: exact {paraxial:.3}, plane trace {focus:.3} ({:+.2}%); RMS spot radius {:.3} at the ends, {:.3} at the middle plane",
        100.0 * (focus / paraxial - 1.0),
        ms[0].sqrt(),
        ms[6].sqrt()
    );
    // The 0.1 R hole leaves spherical aberration: its marginal rays cross 0.2% short (single
    // rays traced to convergence: 19.200 at 0.05 R, 19.160 at 0.1 R), and the smallest RMS
    // spot lies between. Bound 0.3%.
    assert!(
        (focus - paraxial).abs() < 0.003 * paraxial,
        "focus at {focus}, paraxial {paraxial}"
    );
    assert!(ms[0] > 4.0 * ms[6] && ms[12] > 4.0 * ms[6], "no clear focus: {ms:?}");
}

/// Solves a 3×3 system given as augmented rows (Gaussian elimination with partial pivoting).
fn solve3(mut m: [[f64; 4]; 3]) -> [f64; 3] {
    for col in 0..3 {
        let pivot = (col..3)
            .max_by(|&a, &b| m[a][col].abs().total_cmp(&m[b][col].abs()))
            .unwrap();
        m.swap(col, pivot);
        for row in col + 1..3 {
            let f = m[row][col] / m[col][col];
            for k in col..4 {
                m[row][k] -= f * m[col][k];
            }
        }
    }
    let mut x = [0.0; 3];
    for row in (0..3).rev() {
        let rest: f64 = (row + 1..3).map(|k| m[row][k] * x[k]).sum();
        x[row] = (m[row][3] - rest) / m[row][row];
    }
    x
}

/// η from `n1` (z < −w) to `n2` (z > w), smoothstep in between, and an opaque screen around
/// a hole of radius `hole` at z = `screen_z`.
struct InterfaceBehindPinhole {
    n1: f64,
    n2: f64,
    w: f64,
    screen_z: f64,
    hole: f64,
    half: DVec3,
}

impl Medium for InterfaceBehindPinhole {
    fn eta(&self, p: DVec3) -> f64 {
        let s = ((p.z + self.w) / (2.0 * self.w)).clamp(0.0, 1.0);
        self.n1 + (self.n2 - self.n1) * s * s * (3.0 - 2.0 * s)
    }
    fn grad_eta(&self, p: DVec3) -> DVec3 {
        let s = ((p.z + self.w) / (2.0 * self.w)).clamp(0.0, 1.0);
        let ds = if p.z.abs() < self.w { 1.0 / (2.0 * self.w) } else { 0.0 };
        DVec3::new(0.0, 0.0, (self.n2 - self.n1) * 6.0 * s * (1.0 - s) * ds)
    }
    fn optics(&self, p: DVec3) -> Optics {
        let blocked = (p.z - self.screen_z).abs() < STOP_HALF_THICKNESS && p.truncate().length() > self.hole;
        Optics {
            tau_alpha: if blocked { 1e3 } else { 0.0 },
            ..Optics::default()
        }
    }
    fn bounds(&self) -> (DVec3, DVec3) {
        (-self.half, self.half)
    }
    fn voxel_length(&self) -> f64 {
        1.0
    }
}

/// Power-weighted mean x of a plane's light, or of the light missing from it (`shadow`),
/// over the texels whose centres lie within `window` of (`around`, 0).
fn centroid_x(p: &plane_light::PlaneIrradiance, view: &PlaneView, shadow: bool, around: f64, window: f64) -> f64 {
    let (mut m0, mut m1) = (0.0, 0.0);
    for y in 0..p.height as usize {
        for x in 0..p.width as usize {
            let e = p.texels[y * p.width as usize + x][1];
            let w = if shadow { 1.0 - e } else { e };
            let at = view.point_on_plane(DVec2::new(x as f64, y as f64), p.z);
            if (at.x - around).abs() > window || at.y.abs() > window {
                continue;
            }
            m0 += w;
            m1 += w * at.x;
        }
    }
    m1 / m0
}

#[test]
fn light_refracts_at_snells_angle() {
    // A pencil of light through a pinhole at 30° incidence onto an interface 1 → 1.5: its
    // centroid moves along the refracted direction behind the interface.
    let a = 30f64.to_radians();
    let snell = (a.sin() / 1.5).asin();
    let medium = InterfaceBehindPinhole {
        n1: 1.0,
        n2: 1.5,
        w: 0.5,
        screen_z: -3.0,
        hole: 1.0,
        // Wide in x, so that rays entering through a side face (which the medium does not
        // refract there) stay out of the frame.
        half: DVec3::new(40.0, 3.0, 12.0),
    };
    let view = axis_view(128, 16, 0.25);
    let dir = DVec3::new(a.sin(), 0.0, a.cos());
    let l = plane_light::trace(&medium, &light(dir, 0.0), &view, &[2.0, 10.0], &settings(1, 0.05), None).unwrap();
    let (x0, x1) = (
        centroid_x(&l.planes[0], &view, false, 0.0, 100.0),
        centroid_x(&l.planes[1], &view, false, 0.0, 100.0),
    );
    let angle = ((x1 - x0) / 8.0).atan();
    eprintln!(
        "pinhole beam 1 → 1.5 at 30°: {:.4}° (Snell {:.4}°)",
        angle.to_degrees(),
        snell.to_degrees()
    );
    // η sin θ is conserved in a z-only field, and the steps keep the tangential part of v
    // exactly; with one ray per texel centroids are exact (see below). Rounding only.
    assert!(
        (angle - snell).abs().to_degrees() < 1e-6,
        "{} vs {}",
        angle.to_degrees(),
        snell.to_degrees()
    );

    // A volume filled with η = 1.1 to its edge (value 0.5 = glass, value 1 = an opaque cube
    // that casts a shadow): the index step at the box face, half a voxel outside the last
    // voxel centres, is seen in full.
    let vol = volume([56, 48, 40], |p| {
        if p.x.abs() < 2.0 && p.y.abs() < 2.0 && (p.z + 14.0).abs() < 2.0 {
            1.0
        } else {
            0.5
        }
    });
    let glass = tf(
        vec![[0.0, 1.0], [0.5, 1.1], [1.0, 1.1]],
        vec![[0.0, 0.0], [0.75, 0.0], [0.75, 1.0]],
    );
    let medium = VolumeMedium::new(&vol, [0.0, 1.0], &glass);
    let snell = (a.sin() / 1.1).asin();
    // Quarter-voxel texels over both shadows (x from 0.25 to 18.25, |y| < 3), one ray per
    // texel: every ray deposits over exactly one texel's area, which keeps first moments
    // (the overlap with two texels is linear in the position), so centroids are exact.
    let view = axis_view_at(72, 24, 0.25, DVec2::new(9.25, 0.0));
    let l = plane_light::trace(
        &medium,
        &light(dir, 0.0),
        &view,
        &[-4.0, 12.0],
        &settings(1, 0.25),
        None,
    )
    .unwrap();
    // Away from the light that entered or leaves through the volume's side faces (x = ±28).
    // The faces parallel to the light (y = ±24) guide a thin sheet of it inward: the
    // half-voxel border where the edge voxels blend with the zero outside is a graded-index
    // layer. Those sheets cross the middle only beyond these planes.
    let (x0, x1) = (
        centroid_x(&l.planes[0], &view, true, 0.0, 100.0),
        centroid_x(&l.planes[1], &view, true, 0.0, 100.0),
    );
    eprintln!(
        "shadow centres {x0:.4}, {x1:.4} (Snell: {:.4}, {:.4})",
        10.0 * snell.tan(),
        26.0 * snell.tan()
    );
    let angle = ((x1 - x0) / 16.0).atan();
    eprintln!(
        "shadow of a cube inside η = 1.1 to the volume's edge, light at 30°: {:.4}° (Snell {:.4}°)",
        angle.to_degrees(),
        snell.to_degrees()
    );
    // The shadow translates with the refracted light; its centroid is exact, and so is the
    // tangential part of v across the face's ramp (see `rk4::step_on_shell`): rounding only.
    assert!(
        (angle - snell).abs().to_degrees() < 1e-6,
        "{} vs {}",
        angle.to_degrees(),
        snell.to_degrees()
    );
}

#[test]
fn the_comparison_passes_a_converged_trace_and_fails_a_shifted_or_wrong_one() {
    // The light behind a glass ball (n = 1.5, R = 8) at 1.5 R, as the GPU will be checked:
    // relative L1 over [−1.5 R, 1.5 R]², power inside r < R, the brightest point. The same
    // trace at other settings must pass what a shifted or wrong one fails.
    let r = 8.0;
    let (ball, glass) = super::tests::ball_volume(32, r, 1.5);
    let medium = VolumeMedium::new(&ball, [0.0, 1.0], &glass);
    let view = axis_view(32, 32, 1.0);
    let plane = [1.5 * r];
    let run = |rays, step| {
        plane_light::trace(
            &medium,
            &light(DVec3::Z, 0.0),
            &view,
            &plane,
            &settings(rays, step),
            None,
        )
        .unwrap()
        .planes[0]
            .channel(1)
    };
    let truth = run(6, 0.25);
    let centre = DVec2::splat(15.5);
    let region = Region::square(&truth, centre, 1.5 * r);
    let judge = |test: &ScalarImage| {
        let l1 = measure::relative_l1(test, &truth, region).unwrap();
        let power = measure::power_inside(test, centre, r) / measure::power_inside(&truth, centre, r);
        let moved = (measure::peak(test).position - measure::peak(&truth).position).length();
        (l1, power, moved)
    };
    let passes = |(l1, power, moved): (f64, f64, f64)| l1 <= 0.10 && (power - 1.0).abs() <= 0.03 && moved <= 1.0;
    // Against 32² rays per texel and 1/16-voxel steps the trace converges like 1/rays per
    // texel edge and with the step: relative L1 3.5%, 1.5%, 0.85% at 4², 8², 16² (steps ¼).
    for (rays, step) in [(3, 0.25), (4, 0.5)] {
        let e = judge(&run(rays, step));
        eprintln!(
            "{rays}² rays per texel, step {step}: rel. L1 {:.4}, power inside R {:.4}, peak moved {:.2} texels",
            e.0, e.1, e.2
        );
        assert!(passes(e), "{rays} rays, step {step}: {e:?}");
    }
    let shifted = judge(&truth.shifted(1, 0, 1.0));
    let (wrong_ball, wrong_glass) = super::tests::ball_volume(32, r, 1.4);
    let wrong_medium = VolumeMedium::new(&wrong_ball, [0.0, 1.0], &wrong_glass);
    let wrong = plane_light::trace(
        &wrong_medium,
        &light(DVec3::Z, 0.0),
        &view,
        &plane,
        &settings(4, 0.25),
        None,
    )
    .unwrap();
    let wrong = judge(&wrong.planes[0].channel(1));
    eprintln!("shifted by one texel: {shifted:.4?}; n = 1.4 instead of 1.5: {wrong:.4?}");
    assert!(!passes(shifted), "a result shifted by one texel passed: {shifted:?}");
    assert!(!passes(wrong), "a lens of the wrong index passed: {wrong:?}");
}
