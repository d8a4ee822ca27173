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

/// How EXR output is encoded: the exr crate's default (RLE in 64×64 tiles), with the tiles
/// in increasing order. Its default order is whatever its parallel compression finishes
/// first, so the same image gave files that differed from run to run.
pub const EXR_ENCODING: exr::image::Encoding = exr::image::Encoding {
    line_order: exr::meta::attribute::LineOrder::Increasing,
    ..exr::image::Encoding::FAST_LOSSLESS
};

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

    /// Writes PNG (sRGB, 8 bit) or EXR (linear, 32-bit float; [`EXR_ENCODING`]) by the file
    /// extension.
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
                use exr::prelude::*;
                let w = self.width as usize;
                let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
                    let p = self.pixels[y * w + x];
                    (p[0], p[1], p[2], p[3])
                });
                Image::from_encoded_channels((w, self.height as usize), EXR_ENCODING, channels)
                    .write()
                    .to_file(path)
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

    #[test]
    fn exr_files_of_the_same_image_are_the_same_bytes() {
        // Many tiles (64×64 each) with varied content, so that parallel compression has
        // blocks to finish in any order; the file keeps them in increasing order.
        let (w, h) = (300u32, 260u32);
        let img = RenderedImage {
            width: w,
            height: h,
            pixels: (0..w * h)
                .map(|i| {
                    let v = ((i * 2654435761) % 1000) as f32 / 100.0;
                    [v, (i % 7) as f32, 1.0 / (1.0 + v), 1.0]
                })
                .collect(),
        };
        let dir = std::env::temp_dir().join(format!("caustica-exr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let paths: Vec<_> = (0..4).map(|i| dir.join(format!("{i}.exr"))).collect();
        for p in &paths {
            img.save(p).unwrap();
        }
        let meta = exr::meta::MetaData::read_from_file(&paths[0], false).unwrap();
        assert_eq!(meta.headers[0].line_order, exr::meta::attribute::LineOrder::Increasing);
        let first = std::fs::read(&paths[0]).unwrap();
        for p in &paths[1..] {
            assert!(
                std::fs::read(p).unwrap() == first,
                "{} differs from the first file",
                p.display()
            );
        }
        let back = exr::prelude::read_first_rgba_layer_from_file(
            &paths[0],
            |size, _| vec![[0f32; 4]; size.width() * size.height()],
            move |px: &mut Vec<[f32; 4]>, pos, (r, g, b, a): (f32, f32, f32, f32)| {
                px[pos.y() * w as usize + pos.x()] = [r, g, b, a];
            },
        );
        let _ = std::fs::remove_dir_all(&dir);
        let back = back.unwrap();
        assert!(
            back.layer_data.channel_data.pixels == img.pixels,
            "the pixels read back differ"
        );
    }
}
