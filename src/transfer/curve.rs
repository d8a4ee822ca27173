//! Piecewise-linear control-point curves (opacity, η) and colour ramps (particle, medium).

use serde::{Deserialize, Serialize};

use super::TransferError;

/// Interpolates `points` (sorted by x, each `[x, values...]`) at `x`, component `k`.
fn interpolate<const N: usize>(points: &[[f32; N]], x: f32, k: usize) -> f32 {
    let Some(first) = points.first() else { return 0.0 };
    if x <= first[0] {
        return first[k];
    }
    for w in points.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        if x < b[0] {
            let span = b[0] - a[0];
            // A zero span is a step: take the right-hand value.
            let t = if span > 0.0 { (x - a[0]) / span } else { 1.0 };
            return a[k] + (b[k] - a[k]) * t;
        }
    }
    points[points.len() - 1][k]
}

fn check_x<const N: usize>(function: &'static str, points: &[[f32; N]]) -> Result<(), TransferError> {
    if points.is_empty() {
        return Err(TransferError::Empty { function });
    }
    let mut last = f32::NEG_INFINITY;
    for (index, p) in points.iter().enumerate() {
        let invalid = |message: String| TransferError::Invalid {
            function,
            index,
            message,
        };
        if p.iter().any(|v| !v.is_finite()) {
            return Err(invalid("values must be finite numbers".into()));
        }
        if !(0.0..=1.0).contains(&p[0]) {
            return Err(invalid(format!("x = {} is outside [0, 1]", p[0])));
        }
        if p[0] < last {
            return Err(invalid(format!("x = {} is decreasing (previous x = {last})", p[0])));
        }
        last = p[0];
    }
    Ok(())
}

/// A scalar curve: `[[x, y], ...]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Curve {
    pub points: Vec<[f32; 2]>,
}

impl Curve {
    pub fn constant(y: f32) -> Self {
        Curve { points: vec![[0.0, y]] }
    }

    pub fn eval(&self, x: f32) -> f32 {
        interpolate(&self.points, x, 1)
    }

    pub fn is_constant(&self) -> bool {
        self.points.windows(2).all(|w| w[0][1] == w[1][1])
    }

    pub(super) fn validate(&self, function: &'static str, range: [f32; 2]) -> Result<(), TransferError> {
        check_x(function, &self.points)?;
        for (index, p) in self.points.iter().enumerate() {
            if p[1] < range[0] || p[1] > range[1] {
                return Err(TransferError::Invalid {
                    function,
                    index,
                    message: format!("value {} is outside [{}, {}]", p[1], range[0], range[1]),
                });
            }
        }
        Ok(())
    }
}

/// A colour gradient: `[[x, r, g, b], ...]` with channels in [0, 1].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ColorRamp {
    pub points: Vec<[f32; 4]>,
}

impl ColorRamp {
    pub fn constant(rgb: [f32; 3]) -> Self {
        ColorRamp {
            points: vec![[0.0, rgb[0], rgb[1], rgb[2]]],
        }
    }

    pub fn eval(&self, x: f32) -> [f32; 3] {
        [
            interpolate(&self.points, x, 1),
            interpolate(&self.points, x, 2),
            interpolate(&self.points, x, 3),
        ]
    }

    pub(super) fn validate(&self, function: &'static str) -> Result<(), TransferError> {
        check_x(function, &self.points)?;
        for (index, p) in self.points.iter().enumerate() {
            if p[1..].iter().any(|c| !(0.0..=1.0).contains(c)) {
                return Err(TransferError::Invalid {
                    function,
                    index,
                    message: format!("colour {:?} has a channel outside [0, 1]", &p[1..]),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_and_clamps() {
        let c = Curve {
            points: vec![[0.2, 1.0], [0.6, 2.0]],
        };
        assert_eq!(c.eval(0.0), 1.0);
        assert!((c.eval(0.4) - 1.5).abs() < 1e-6);
        assert_eq!(c.eval(1.0), 2.0);
        assert!(!c.is_constant());
    }

    #[test]
    fn steps_take_right_value() {
        let c = Curve {
            points: vec![[0.0, 0.0], [0.5, 0.0], [0.5, 1.0]],
        };
        assert_eq!(c.eval(0.5), 1.0);
        assert_eq!(c.eval(0.49), 0.0);
    }
}
