//! Transfer functions interpolated point by point. Two functions with the same number of
//! control points blend each point (position and value), so a feature slides from one place
//! to the other. With different counts both are first given points at the positions of
//! either (points that do not change the function: a step keeps its two sides), then
//! blended the same way, which is the pointwise blend of the two functions.

use crate::transfer::{ColorRamp, Curve, TransferFunctions};

/// `a` at `w` = 0, `b` at `w` = 1 (both exactly), the point-by-point blend between.
pub fn blend_transfer(a: &TransferFunctions, b: &TransferFunctions, w: f64) -> TransferFunctions {
    if w == 0.0 {
        return a.clone();
    }
    if w == 1.0 {
        return b.clone();
    }
    TransferFunctions {
        name: None,
        opacity: Curve {
            points: blend_points(&a.opacity.points, &b.opacity.points, w),
        },
        color: ColorRamp {
            points: blend_points(&a.color.points, &b.color.points, w),
        },
        eta: Curve {
            points: blend_points(&a.eta.points, &b.eta.points, w),
        },
        medium: ColorRamp {
            points: blend_points(&a.medium.points, &b.medium.points, w),
        },
        albedo: blend_optional(&a.albedo, &b.albedo, w),
        anisotropy: blend_optional(&a.anisotropy, &b.anisotropy, w),
    }
}

/// An optional curve (albedo, anisotropy) blended as the others; a missing one is 0
/// everywhere, and two missing ones stay missing.
fn blend_optional(a: &Option<Curve>, b: &Option<Curve>, w: f64) -> Option<Curve> {
    if a.is_none() && b.is_none() {
        return None;
    }
    let zero = Curve::constant(0.0);
    let (a, b) = (a.as_ref().unwrap_or(&zero), b.as_ref().unwrap_or(&zero));
    Some(Curve {
        points: blend_points(&a.points, &b.points, w),
    })
}

fn blend_points<const N: usize>(a: &[[f32; N]], b: &[[f32; N]], w: f64) -> Vec<[f32; N]> {
    let (a, b) = if a.len() == b.len() {
        (a.to_vec(), b.to_vec())
    } else {
        let xs = union_positions(a, b);
        (on_positions(a, &xs), on_positions(b, &xs))
    };
    a.iter()
        .zip(&b)
        .map(|(p, q)| {
            std::array::from_fn(|k| {
                let (p, q) = (p[k] as f64, q[k] as f64);
                // Exact at the ends and never outside [p, q], so valid points stay valid.
                ((1.0 - w) * p + w * q).clamp(p.min(q), p.max(q)) as f32
            })
        })
        .collect()
}

/// Which side of a position: a step (two points at one x) has different values on each.
#[derive(Clone, Copy, PartialEq)]
enum Side {
    Left,
    Right,
}

/// The distinct positions of both functions, each with the sides it needs: two when either
/// function steps there, else one.
fn union_positions<const N: usize>(a: &[[f32; N]], b: &[[f32; N]]) -> Vec<(f32, Side)> {
    let mut xs: Vec<f32> = a.iter().chain(b).map(|p| p[0]).collect();
    xs.sort_by(f32::total_cmp);
    xs.dedup();
    let steps = |f: &[[f32; N]], x: f32| value_at(f, x, Side::Left) != value_at(f, x, Side::Right);
    xs.into_iter()
        .flat_map(|x| {
            if steps(a, x) || steps(b, x) {
                vec![(x, Side::Left), (x, Side::Right)]
            } else {
                vec![(x, Side::Right)]
            }
        })
        .collect()
}

fn on_positions<const N: usize>(f: &[[f32; N]], xs: &[(f32, Side)]) -> Vec<[f32; N]> {
    xs.iter().map(|&(x, side)| value_at(f, x, side)).collect()
}

/// The point of `f` at `x`: from the left, the first point there (the limit of the segment
/// that ends there); from the right, the last one (what evaluation returns); between points,
/// linear interpolation as in `transfer::Curve::eval`; past the ends, the end points held.
fn value_at<const N: usize>(f: &[[f32; N]], x: f32, side: Side) -> [f32; N] {
    let at_x: Vec<&[f32; N]> = f.iter().filter(|p| p[0] == x).collect();
    let pick = match side {
        Side::Left => at_x.first(),
        Side::Right => at_x.last(),
    };
    let mut out = match pick {
        Some(p) => **p,
        None => match f.windows(2).find(|w| w[0][0] < x && x < w[1][0]) {
            Some(w) => {
                let t = (x - w[0][0]) / (w[1][0] - w[0][0]);
                std::array::from_fn(|k| w[0][k] + (w[1][k] - w[0][k]) * t)
            }
            None if f.first().is_some_and(|p| x < p[0]) => f[0],
            None => f[f.len() - 1],
        },
    };
    out[0] = x;
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tf(opacity: Vec<[f32; 2]>, color: Vec<[f32; 4]>) -> TransferFunctions {
        TransferFunctions {
            name: Some("k".into()),
            opacity: Curve { points: opacity },
            color: ColorRamp { points: color },
            eta: Curve::constant(1.0),
            medium: ColorRamp::constant([1.0; 3]),
            albedo: None,
            anisotropy: None,
        }
    }

    #[test]
    fn ends_are_the_keys_and_equal_counts_move_points() {
        let a = tf(vec![[0.25, 0.0], [0.5, 0.5]], vec![[0.0, 1.0, 1.0, 1.0]]);
        let b = tf(vec![[0.5, 0.0], [0.75, 1.0]], vec![[0.0, 0.0, 0.5, 1.0]]);
        assert_eq!(blend_transfer(&a, &b, 0.0), a);
        assert_eq!(blend_transfer(&a, &b, 1.0), b);
        let mid = blend_transfer(&a, &b, 0.5);
        assert_eq!(mid.opacity.points, vec![[0.375, 0.0], [0.625, 0.75]]);
        assert_eq!(mid.color.points, vec![[0.0, 0.5, 0.75, 1.0]]);
        mid.validate().unwrap();
    }

    /// With different counts the blend is the pointwise blend of the two functions: checked
    /// against evaluating both at many x, steps included.
    #[test]
    fn different_counts_blend_the_functions_pointwise() {
        let a = tf(
            vec![[0.0, 0.0], [0.4, 0.0], [0.4, 0.8], [1.0, 0.2]],
            vec![[0.0, 1.0, 1.0, 1.0]],
        );
        let b = tf(
            vec![[0.2, 0.1], [0.9, 0.6]],
            vec![[0.0, 1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 1.0]],
        );
        let w = 0.25;
        let mid = blend_transfer(&a, &b, w);
        mid.validate().unwrap();
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            let expect = (1.0 - w as f32) * a.opacity.eval(x) + w as f32 * b.opacity.eval(x);
            // f32 interpolation of points that were themselves interpolated: a few ulp.
            assert!((mid.opacity.eval(x) - expect).abs() < 1e-6, "x = {x}");
            let (ca, cb, cm) = (a.color.eval(x), b.color.eval(x), mid.color.eval(x));
            for k in 0..3 {
                let expect = (1.0 - w as f32) * ca[k] + w as f32 * cb[k];
                assert!((cm[k] - expect).abs() < 1e-6, "x = {x} channel {k}");
            }
        }
        // The step of `a` survives as a step (scaled), not as a ramp.
        assert!(mid.opacity.eval(0.4) - mid.opacity.eval(0.3999) > 0.5);
    }
}
