//! Small measurements for comparing images of light (a GPU light buffer against the exact
//! plane irradiance, a render against the reference): relative L1 over a region, power inside
//! a radius, the brightest point, azimuthal variation at a fixed radius, and the width of a
//! shadow edge. Pure functions on one channel; texel centres at integer coordinates.

use glam::DVec2;

use crate::scene::RenderedImage;

/// One channel of an image, row-major, texel (x, y) centred at (x, y).
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f64>,
}

impl ScalarImage {
    pub fn from_fn(width: usize, height: usize, f: impl Fn(usize, usize) -> f64) -> ScalarImage {
        let data = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        ScalarImage { width, height, data }
    }

    /// Channel `c` of a rendered image (a light buffer from `--debug-view light`, an image).
    pub fn from_image(img: &RenderedImage, c: usize) -> ScalarImage {
        ScalarImage {
            width: img.width as usize,
            height: img.height as usize,
            data: img.pixels.iter().map(|p| p[c] as f64).collect(),
        }
    }

    pub fn at(&self, x: usize, y: usize) -> f64 {
        self.data[y * self.width + x]
    }

    /// Bilinear value at continuous texel coordinates, clamped to the edge texels.
    pub fn sample(&self, p: DVec2) -> f64 {
        let clamp = |v: f64, n: usize| v.clamp(0.0, (n - 1) as f64);
        let (x, y) = (clamp(p.x, self.width), clamp(p.y, self.height));
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let row = |y: usize| self.at(x0, y) * (1.0 - fx) + self.at(x1, y) * fx;
        row(y0) * (1.0 - fy) + row(y1) * fy
    }

    /// The image moved by whole texels, `fill` where nothing moved in (for checking that a
    /// comparison notices a shifted result).
    pub fn shifted(&self, dx: i64, dy: i64, fill: f64) -> ScalarImage {
        ScalarImage::from_fn(self.width, self.height, |x, y| {
            let (sx, sy) = (x as i64 - dx, y as i64 - dy);
            if sx < 0 || sy < 0 || sx >= self.width as i64 || sy >= self.height as i64 {
                fill
            } else {
                self.at(sx as usize, sy as usize)
            }
        })
    }
}

/// A rectangle of texels: x in [x0, x1), y in [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    pub x0: usize,
    pub y0: usize,
    pub x1: usize,
    pub y1: usize,
}

impl Region {
    pub fn all(img: &ScalarImage) -> Region {
        Region {
            x0: 0,
            y0: 0,
            x1: img.width,
            y1: img.height,
        }
    }

    /// The texels whose centres lie within `half` (texels) of `centre` along both axes.
    pub fn square(img: &ScalarImage, centre: DVec2, half: f64) -> Region {
        let lo = |c: f64| (c - half).ceil().max(0.0) as usize;
        let hi = |c: f64, n: usize| ((c + half).floor() + 1.0).clamp(0.0, n as f64) as usize;
        Region {
            x0: lo(centre.x),
            y0: lo(centre.y),
            x1: hi(centre.x, img.width),
            y1: hi(centre.y, img.height),
        }
    }

    fn texels(self) -> impl Iterator<Item = (usize, usize)> {
        (self.y0..self.y1).flat_map(move |y| (self.x0..self.x1).map(move |x| (x, y)))
    }
}

/// Σ|test − reference| / Σ|reference| over `region`; `None` when the sizes differ or the
/// reference is zero there.
pub fn relative_l1(test: &ScalarImage, reference: &ScalarImage, region: Region) -> Option<f64> {
    if (test.width, test.height) != (reference.width, reference.height) {
        return None;
    }
    let (mut diff, mut norm) = (0.0, 0.0);
    for (x, y) in region.texels() {
        let r = reference.at(x, y);
        diff += (test.at(x, y) - r).abs();
        norm += r.abs();
    }
    (norm > 0.0).then_some(diff / norm)
}

/// Σ of the values over `region` (power on a plane, in texel areas × the value's unit).
pub fn total(img: &ScalarImage, region: Region) -> f64 {
    region.texels().map(|(x, y)| img.at(x, y)).sum()
}

/// Sub-samples per texel edge for the disc's coverage of a texel.
const COVERAGE_SAMPLES: usize = 8;

/// Σ value × (fraction of the texel inside the disc of `radius` texels about `centre`): the
/// power inside a circle, in texel areas × the value's unit. Coverage from 8×8 sub-samples
/// per texel (a texel cut by the circle is counted to within 1/64 of its area).
pub fn power_inside(img: &ScalarImage, centre: DVec2, radius: f64) -> f64 {
    let n = COVERAGE_SAMPLES;
    let r2 = radius * radius;
    let mut sum = 0.0;
    let region = Region::square(img, centre, radius + 1.0);
    for (x, y) in region.texels() {
        let near = DVec2::new(
            (centre.x - x as f64).abs().max(0.5) - 0.5,
            (centre.y - y as f64).abs().max(0.5) - 0.5,
        );
        if near.length_squared() > r2 {
            continue;
        }
        let mut inside = 0usize;
        for j in 0..n {
            for i in 0..n {
                let p = DVec2::new(
                    x as f64 - 0.5 + (i as f64 + 0.5) / n as f64,
                    y as f64 - 0.5 + (j as f64 + 0.5) / n as f64,
                );
                inside += ((p - centre).length_squared() <= r2) as usize;
            }
        }
        sum += img.at(x, y) * inside as f64 / (n * n) as f64;
    }
    sum
}

/// The brightest texel and a sub-texel estimate of the maximum's position (a parabola through
/// the texel and its two neighbours along each axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    pub x: usize,
    pub y: usize,
    pub value: f64,
    pub position: DVec2,
}

pub fn peak(img: &ScalarImage) -> Peak {
    let (mut best, mut at) = (f64::NEG_INFINITY, (0, 0));
    for y in 0..img.height {
        for x in 0..img.width {
            if img.at(x, y) > best {
                best = img.at(x, y);
                at = (x, y);
            }
        }
    }
    let (x, y) = at;
    let vertex = |a: f64, b: f64, c: f64| {
        let d = a - 2.0 * b + c;
        if d < 0.0 {
            (0.5 * (a - c) / d).clamp(-0.5, 0.5)
        } else {
            0.0
        }
    };
    let dx = if x > 0 && x + 1 < img.width {
        vertex(img.at(x - 1, y), best, img.at(x + 1, y))
    } else {
        0.0
    };
    let dy = if y > 0 && y + 1 < img.height {
        vertex(img.at(x, y - 1), best, img.at(x, y + 1))
    } else {
        0.0
    };
    Peak {
        x,
        y,
        value: best,
        position: DVec2::new(x as f64 + dx, y as f64 + dy),
    }
}

/// Largest relative deviation from their mean of `samples` bilinear values on the circle of
/// `radius` texels about `centre`: max |v − mean| / mean. 0 for a rotationally symmetric
/// image (to interpolation error); a four-fold star of ±a reads a.
pub fn azimuthal_variation(img: &ScalarImage, centre: DVec2, radius: f64, samples: usize) -> f64 {
    let values: Vec<f64> = (0..samples.max(1))
        .map(|k| {
            let phi = std::f64::consts::TAU * k as f64 / samples.max(1) as f64;
            img.sample(centre + DVec2::new(phi.cos(), phi.sin()) * radius)
        })
        .collect();
    let mean = values.iter().sum::<f64>() / values.len() as f64;
    if mean == 0.0 {
        return 0.0;
    }
    values.iter().map(|v| (v - mean).abs()).fold(0.0, f64::max) / mean.abs()
}

/// Largest relative deviation from their mean of the light in `sectors` equal sectors of the
/// annulus between `r0` and `r1` texels about `centre`, each the mean of bilinear samples on
/// a polar lattice (16 radii × 8 angles per sector), so that every sector weighs the same
/// area whatever the texel grid: rings cancel, a star or a grid does not (a four-fold star
/// of ±a reads 0.64–0.90 a in 16 sectors, depending on its phase). Less sensitive to sampling noise than
/// [`azimuthal_variation`] on one circle.
pub fn sector_variation(img: &ScalarImage, centre: DVec2, r0: f64, r1: f64, sectors: usize) -> f64 {
    const RADII: usize = 16;
    const ANGLES: usize = 8;
    let sectors = sectors.max(1);
    let sums: Vec<f64> = (0..sectors)
        .map(|k| {
            let mut sum = 0.0;
            for i in 0..RADII {
                // Samples weighted by radius: equal area per sample.
                let r = r0 + (r1 - r0) * (i as f64 + 0.5) / RADII as f64;
                for j in 0..ANGLES {
                    let phi = std::f64::consts::TAU * (k as f64 + (j as f64 + 0.5) / ANGLES as f64) / sectors as f64;
                    sum += r * img.sample(centre + DVec2::new(phi.cos(), phi.sin()) * r);
                }
            }
            sum
        })
        .collect();
    let mean = sums.iter().sum::<f64>() / sectors as f64;
    if mean == 0.0 {
        return 0.0;
    }
    sums.iter().map(|s| (s - mean).abs()).fold(0.0, f64::max) / mean.abs()
}

/// The 10–90% width (texels) of an edge crossed by the line from `from` to `to`: the profile
/// is sampled bilinearly at `samples` points, its two ends are taken as the levels on either
/// side, and the width is the distance between the first crossings of 10% and 90% of the
/// step, interpolated linearly. `None` if the ends do not differ or a level is not crossed.
pub fn edge_width(img: &ScalarImage, from: DVec2, to: DVec2, samples: usize) -> Option<f64> {
    let n = samples.max(2);
    let profile: Vec<f64> = (0..n)
        .map(|k| img.sample(from.lerp(to, k as f64 / (n - 1) as f64)))
        .collect();
    let (a, b) = (profile[0], profile[n - 1]);
    if (b - a).abs() <= 1e-12 * a.abs().max(b.abs()) {
        return None;
    }
    let first_crossing = |level: f64| -> Option<f64> {
        let target = a + level * (b - a);
        profile.windows(2).enumerate().find_map(|(k, w)| {
            let (p, q) = ((w[0] - target) * (b - a).signum(), (w[1] - target) * (b - a).signum());
            (p < 0.0 && q >= 0.0).then(|| k as f64 + p / (p - q))
        })
    };
    let (t10, t90) = (first_crossing(0.1)?, first_crossing(0.9)?);
    Some((t90 - t10).abs() / (n - 1) as f64 * (to - from).length())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gaussian(w: usize, h: usize, c: DVec2, sigma: f64, amplitude: f64) -> ScalarImage {
        ScalarImage::from_fn(w, h, |x, y| {
            let d = DVec2::new(x as f64, y as f64) - c;
            amplitude * (-d.length_squared() / (2.0 * sigma * sigma)).exp()
        })
    }

    #[test]
    fn relative_l1_is_zero_for_the_same_image_and_counts_differences_over_the_region() {
        let a = ScalarImage::from_fn(8, 8, |x, _| 1.0 + x as f64);
        assert_eq!(relative_l1(&a, &a, Region::all(&a)), Some(0.0));
        let b = ScalarImage::from_fn(8, 8, |x, y| 1.0 + x as f64 + if x == 0 && y == 0 { 2.0 } else { 0.0 });
        // One texel off by 2 over Σ(1 + x) = 8·36 = 288.
        let all = relative_l1(&b, &a, Region::all(&a)).unwrap();
        assert!((all - 2.0 / 288.0).abs() < 1e-15, "{all}");
        let away = Region {
            x0: 1,
            y0: 0,
            x1: 8,
            y1: 8,
        };
        assert_eq!(relative_l1(&b, &a, away), Some(0.0));
        assert!(relative_l1(&ScalarImage::from_fn(4, 8, |_, _| 1.0), &a, Region::all(&a)).is_none());
    }

    #[test]
    fn square_regions_hold_the_texels_whose_centres_are_inside() {
        let img = ScalarImage::from_fn(16, 16, |_, _| 1.0);
        let r = Region::square(&img, DVec2::new(7.5, 7.5), 3.0);
        assert_eq!((r.x0, r.x1, r.y0, r.y1), (5, 11, 5, 11));
        let clipped = Region::square(&img, DVec2::new(1.0, 14.0), 4.0);
        assert_eq!((clipped.x0, clipped.x1, clipped.y0, clipped.y1), (0, 6, 10, 16));
    }

    #[test]
    fn power_inside_a_radius_matches_the_disc_area() {
        let ones = ScalarImage::from_fn(64, 64, |_, _| 1.0);
        for (c, r) in [(DVec2::new(31.5, 31.5), 10.0), (DVec2::new(30.2, 33.7), 6.3)] {
            let p = power_inside(&ones, c, r);
            let area = std::f64::consts::PI * r * r;
            // Coverage of the ~2πr cut texels to 1/64 of a texel each, errors partly cancelling
            // along the circle: bound 0.5%.
            assert!((p - area).abs() < 0.005 * area, "r {r}: {p} vs {area}");
        }
        // A Gaussian spot: 1 − e^{−r²/2σ²} of its total inside r.
        let g = gaussian(64, 64, DVec2::new(32.0, 31.0), 3.0, 1.0);
        let total = total(&g, Region::all(&g));
        let inside = power_inside(&g, DVec2::new(32.0, 31.0), 6.0) / total;
        let exact = 1.0 - (-36.0f64 / 18.0).exp();
        // Texel sampling of a σ = 3 Gaussian: ~1e-3.
        assert!((inside - exact).abs() < 5e-3, "{inside} vs {exact}");
    }

    #[test]
    fn the_peak_is_found_to_a_fraction_of_a_texel() {
        let c = DVec2::new(10.3, 7.6);
        let p = peak(&gaussian(24, 16, c, 2.0, 5.0));
        assert_eq!((p.x, p.y), (10, 8));
        // A parabola through three samples of a σ = 2 Gaussian: within 0.1 texel.
        assert!((p.position - c).length() < 0.1, "{:?}", p.position);
        assert!((p.value - 5.0).abs() < 0.3);
    }

    #[test]
    fn azimuthal_variation_reads_a_star_and_not_a_disc() {
        let c = DVec2::new(31.5, 31.5);
        let round = ScalarImage::from_fn(64, 64, |x, y| {
            let d = DVec2::new(x as f64, y as f64) - c;
            1.0 + (-d.length_squared() / 200.0).exp()
        });
        let star = ScalarImage::from_fn(64, 64, |x, y| {
            let d = DVec2::new(x as f64, y as f64) - c;
            (1.0 + (-d.length_squared() / 200.0).exp()) * (1.0 + 0.1 * (4.0 * d.y.atan2(d.x)).cos())
        });
        let r = azimuthal_variation(&round, c, 12.0, 64);
        let s = azimuthal_variation(&star, c, 12.0, 64);
        // Bilinear interpolation of a smooth radial profile: < 1%; the star's ±10% in full,
        // less the bilinear smoothing of a 4-fold pattern at radius 12 (~2%).
        assert!(r < 0.01, "round {r}");
        assert!((s - 0.1).abs() < 0.01, "star {s}");
    }

    #[test]
    fn sector_variation_reads_a_star_and_not_a_disc() {
        let c = DVec2::new(31.5, 31.5);
        let profile = |d: DVec2| 0.2 + (-d.length_squared() / 60.0).exp();
        let round = ScalarImage::from_fn(64, 64, |x, y| profile(DVec2::new(x as f64, y as f64) - c));
        // Peaks on the sectors' centres (φ = 11.25° + k·90°).
        let star = ScalarImage::from_fn(64, 64, |x, y| {
            let d = DVec2::new(x as f64, y as f64) - c;
            profile(d) * (1.0 + 0.1 * (4.0 * (d.y.atan2(d.x) - std::f64::consts::PI / 16.0)).cos())
        });
        let r = sector_variation(&round, c, 4.0, 12.0, 16);
        let s = sector_variation(&star, c, 4.0, 12.0, 16);
        // Bilinear interpolation of a smooth radial profile: < 1% (the texel grid's square
        // symmetry shows only through interpolation); the star's ±10% times the mean of
        // cos 4φ over a sector, sin(π/4)/(π/4) = 0.90, less ~1% of bilinear smoothing.
        assert!(r < 0.01, "round {r}");
        assert!((s - 0.09).abs() < 0.005, "star {s}");
    }

    #[test]
    fn edge_width_of_a_linear_ramp_is_eight_tenths_of_it() {
        // From 0.2 to 1.0 over 10 texels along x: bilinear sampling reproduces the ramp, so the
        // 10–90% width is 0.8 × 10 exactly, in either direction and along a slanted line.
        let ramp = ScalarImage::from_fn(64, 8, |x, _| 0.2 + 0.8 * ((x as f64 - 20.0) / 10.0).clamp(0.0, 1.0));
        let w = edge_width(&ramp, DVec2::new(5.0, 4.0), DVec2::new(45.0, 4.0), 401).unwrap();
        assert!((w - 8.0).abs() < 1e-9, "{w}");
        let back = edge_width(&ramp, DVec2::new(45.0, 4.0), DVec2::new(5.0, 4.0), 401).unwrap();
        assert!((back - 8.0).abs() < 1e-9, "{back}");
        // A line at 30° to the edge's normal crosses it over 10 / cos 30°.
        let (a, b) = (
            DVec2::new(8.0, 0.5),
            DVec2::new(42.0, 0.5 + 34.0 * 30f64.to_radians().tan()),
        );
        let tall = ScalarImage::from_fn(64, 32, |x, _| 0.2 + 0.8 * ((x as f64 - 20.0) / 10.0).clamp(0.0, 1.0));
        let slanted = edge_width(&tall, a, b, 801).unwrap();
        let expected = 8.0 / 30f64.to_radians().cos();
        assert!((slanted - expected).abs() < 1e-6, "{slanted} vs {expected}");
        assert!(edge_width(&ramp, DVec2::new(0.0, 4.0), DVec2::new(10.0, 4.0), 11).is_none());
    }
}
