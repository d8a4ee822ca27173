//! Rendered images and how they are written: 8-bit sRGB PNG or linear float EXR.

use std::path::Path;

/// A rendered image in linear radiance, row 0 at the top.
#[derive(Clone, Debug)]
pub struct RenderedImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 4]>,
}

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("cannot write {path}: {message}")]
    Write { path: String, message: String },
    #[error("unknown output format for {0} (use .png or .exr)")]
    Format(String),
}

impl crate::Classify for OutputError {
    fn exit_class(&self) -> crate::ExitClass {
        crate::ExitClass::Input // an output path that cannot be written
    }
}

pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.0031308 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

impl RenderedImage {
    /// Adds `other` (the same size) pixel by pixel.
    pub fn add(&mut self, other: &RenderedImage) {
        for (a, p) in self.pixels.iter_mut().zip(&other.pixels) {
            for c in 0..4 {
                a[c] += p[c];
            }
        }
    }

    /// The image with every channel multiplied by `s`.
    pub fn scaled(&self, s: f32) -> RenderedImage {
        RenderedImage {
            width: self.width,
            height: self.height,
            pixels: self.pixels.iter().map(|p| p.map(|v| v * s)).collect(),
        }
    }

    /// 8-bit sRGB bytes (RGBA), values above 1 clipped.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| {
                let q = |c: f32| (linear_to_srgb(c) * 255.0 + 0.5) as u8;
                [q(p[0]), q(p[1]), q(p[2]), 255]
            })
            .collect()
    }

    /// Writes PNG (sRGB, 8 bit) or EXR (linear, 32-bit float) by the file extension.
    pub fn save(&self, path: &Path) -> Result<(), OutputError> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_default();
        let err = |message: String| OutputError::Write {
            path: path.display().to_string(),
            message,
        };
        match ext.as_str() {
            "png" => image::save_buffer(path, &self.to_srgb8(), self.width, self.height, image::ColorType::Rgba8)
                .map_err(|e| err(e.to_string())),
            "exr" => {
                let w = self.width as usize;
                exr::prelude::write_rgba_file(path, w, self.height as usize, |x, y| {
                    let p = self.pixels[y * w + x];
                    (p[0], p[1], p[2], p[3])
                })
                .map_err(|e| err(e.to_string()))
            }
            _ => Err(OutputError::Format(path.display().to_string())),
        }
    }

    /// Bilinear rescale to `width`×`height` (pixel centres aligned), for renders made at a
    /// reduced size. Bilinear weights are convex, so bounds on the values carry over.
    pub fn resized(&self, width: u32, height: u32) -> RenderedImage {
        let (sw, sh) = (self.width as usize, self.height as usize);
        let at = |x: usize, y: usize| self.pixels[y.min(sh - 1) * sw + x.min(sw - 1)];
        let mut pixels = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            let fy = ((y as f32 + 0.5) * sh as f32 / height as f32 - 0.5).max(0.0);
            let (y0, ty) = (fy.floor() as usize, fy.fract());
            for x in 0..width {
                let fx = ((x as f32 + 0.5) * sw as f32 / width as f32 - 0.5).max(0.0);
                let (x0, tx) = (fx.floor() as usize, fx.fract());
                let mut p = [0.0f32; 4];
                for (c, v) in p.iter_mut().enumerate() {
                    let top = at(x0, y0)[c] * (1.0 - tx) + at(x0 + 1, y0)[c] * tx;
                    let bottom = at(x0, y0 + 1)[c] * (1.0 - tx) + at(x0 + 1, y0 + 1)[c] * tx;
                    *v = top * (1.0 - ty) + bottom * ty;
                }
                pixels.push(p);
            }
        }
        RenderedImage { width, height, pixels }
    }

    /// Counts of non-finite and negative channel values (rgb).
    pub fn count_invalid(&self) -> (usize, usize) {
        let rgb = self.pixels.iter().flat_map(|p| &p[..3]);
        let non_finite = rgb.clone().filter(|v| !v.is_finite()).count();
        let negative = rgb.filter(|v| **v < 0.0).count();
        (non_finite, negative)
    }

    pub fn max_value(&self) -> f32 {
        self.pixels.iter().flat_map(|p| &p[..3]).fold(0.0f32, |m, v| m.max(*v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resizing_stays_within_the_values_and_keeps_flat_regions() {
        let img = RenderedImage {
            width: 2,
            height: 2,
            pixels: vec![[0.0; 4], [1.0; 4], [2.0; 4], [4.0; 4]],
        };
        let big = img.resized(5, 3);
        assert_eq!((big.width, big.height, big.pixels.len()), (5, 3, 15));
        assert!(big.pixels.iter().flatten().all(|v| (0.0..=4.0).contains(v)));
        assert_eq!(
            big.pixels[0][0], 0.0,
            "corner texel centres map onto the source corners"
        );
        assert_eq!(big.pixels[14][0], 4.0);
        let flat = RenderedImage {
            width: 3,
            height: 1,
            pixels: vec![[0.5; 4]; 3],
        };
        assert!(flat.resized(7, 2).pixels.iter().flatten().all(|v| *v == 0.5));
    }
}
