//! Image error against the reference: relative L1 and RMSE in linear radiance, and the
//! distance between the brightest points (the caustic peak in scenes that have one).

use crate::render::RenderedImage;

/// Linear RGB pixels with their size.
#[derive(Clone, Debug)]
pub struct Linear {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f64; 3]>,
}

impl Linear {
    pub fn from_image(img: &RenderedImage) -> Linear {
        Linear {
            width: img.width,
            height: img.height,
            pixels: img
                .pixels
                .iter()
                .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
                .collect(),
        }
    }

    /// Box-filters to `width`×`height`, which must divide the size exactly (integer factor).
    pub fn downsample(&self, width: u32, height: u32) -> Option<Linear> {
        if width == 0 || height == 0 || self.width % width != 0 || self.height % height != 0 {
            return None;
        }
        let (fx, fy) = ((self.width / width) as usize, (self.height / height) as usize);
        if fx != fy {
            return None;
        }
        let f = fx;
        let mut pixels = vec![[0.0; 3]; (width * height) as usize];
        for y in 0..height as usize {
            for x in 0..width as usize {
                let mut s = [0.0; 3];
                for dy in 0..f {
                    for dx in 0..f {
                        let p = self.pixels[(y * f + dy) * self.width as usize + x * f + dx];
                        for c in 0..3 {
                            s[c] += p[c];
                        }
                    }
                }
                pixels[y * width as usize + x] = s.map(|v| v / (f * f) as f64);
            }
        }
        Some(Linear { width, height, pixels })
    }

    fn luminance(&self, x: i64, y: i64) -> f64 {
        let x = x.clamp(0, self.width as i64 - 1) as usize;
        let y = y.clamp(0, self.height as i64 - 1) as usize;
        let p = self.pixels[y * self.width as usize + x];
        0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]
    }

    /// Pixel position of the largest 3×3-averaged luminance (robust to single-pixel noise).
    pub fn peak(&self) -> (f64, f64) {
        let mut best = (0.0, 0.0, f64::MIN);
        for y in 0..self.height as i64 {
            for x in 0..self.width as i64 {
                let mut s = 0.0;
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        s += self.luminance(x + dx, y + dy);
                    }
                }
                if s > best.2 {
                    best = (x as f64, y as f64, s);
                }
            }
        }
        (best.0, best.1)
    }
}

/// Error of an image against the reference (at the reference's size).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageError {
    /// Σ|test − ref| / Σ|ref| over all pixels and channels.
    pub rel_l1: f64,
    /// Root mean square of test − ref over all pixels and channels.
    pub rmse: f64,
    /// Distance between the brightest points, in reference pixels.
    pub peak_px: f64,
}

/// Compares `test` (downsampled to the reference's size when larger) with `reference`.
pub fn compare(test: &Linear, reference: &Linear) -> Option<ImageError> {
    let test = if (test.width, test.height) == (reference.width, reference.height) {
        test.clone()
    } else {
        test.downsample(reference.width, reference.height)?
    };
    let (mut abs, mut norm, mut sq) = (0.0, 0.0, 0.0);
    for (t, r) in test.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let d = t[c] - r[c];
            abs += d.abs();
            norm += r[c].abs();
            sq += d * d;
        }
    }
    let n = (3 * reference.pixels.len()) as f64;
    let (tp, rp) = (test.peak(), reference.peak());
    Some(ImageError {
        rel_l1: abs / norm.max(1e-30),
        rmse: (sq / n).sqrt(),
        peak_px: ((tp.0 - rp.0).powi(2) + (tp.1 - rp.1).powi(2)).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> f64) -> Linear {
        let pixels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| [f(x, y); 3])
            .collect();
        Linear {
            width: w,
            height: h,
            pixels,
        }
    }

    #[test]
    fn identical_images_have_no_error_and_a_wrong_one_a_large_error() {
        let spot = |cx: f64| {
            move |x: u32, y: u32| 0.2 + 3.0 * (-((x as f64 - cx).powi(2) + (y as f64 - 8.0).powi(2)) / 4.0).exp()
        };
        let reference = image(16, 16, spot(5.0));
        let same = compare(&reference, &reference).unwrap();
        assert_eq!((same.rel_l1, same.rmse, same.peak_px), (0.0, 0.0, 0.0));
        // The caustic moved by 6 pixels: a large error in every measure.
        let wrong = compare(&image(16, 16, spot(11.0)), &reference).unwrap();
        assert!(
            wrong.rel_l1 > 0.5 && wrong.rmse > 0.3 && (wrong.peak_px - 6.0).abs() < 1e-9,
            "{wrong:?}"
        );
        // A black image is 100% wrong.
        assert!((compare(&image(16, 16, |_, _| 0.0), &reference).unwrap().rel_l1 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn larger_images_are_box_filtered_to_the_reference_size() {
        let fine = image(32, 32, |x, _| if x % 2 == 0 { 1.0 } else { 0.0 });
        let flat = image(16, 16, |_, _| 0.5);
        let e = compare(&fine, &flat).unwrap();
        assert!(e.rel_l1 < 1e-12 && e.rmse < 1e-12);
        assert!(
            compare(&image(24, 24, |_, _| 0.5), &flat).is_none(),
            "non-integer factors are refused"
        );
    }
}
