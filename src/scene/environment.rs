//! Environment maps: the built-in studio, equirectangular image files, and their mip chain.

use std::path::Path;

use crate::scene::Environment;

/// An equirectangular RGB image (y up; u = longitude, v = colatitude) with its mip chain.
pub struct EnvMap {
    /// Level 0 first; each level is (width, height, linear RGBA pixels).
    pub levels: Vec<(u32, u32, Vec<[f32; 4]>)>,
    pub intensity: f32,
}

#[derive(Debug, thiserror::Error)]
pub enum EnvError {
    #[error("cannot read environment image {path}: {message}")]
    Read { path: String, message: String },
}

impl crate::Classify for EnvError {
    fn exit_class(&self) -> crate::ExitClass {
        crate::ExitClass::Input // an unreadable environment image
    }
}

/// Studio: bright sky gradient above a grey checkered floor with a soft horizon.
fn studio(width: u32, height: u32) -> Vec<[f32; 4]> {
    let mut px = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        let theta = (y as f32 + 0.5) / height as f32 * std::f32::consts::PI;
        let up = theta.cos();
        for x in 0..width {
            let phi = (x as f32 + 0.5) / width as f32 * std::f32::consts::TAU;
            let c = if up > 0.0 {
                let t = up.powf(0.6);
                [0.85 - 0.45 * t, 0.88 - 0.33 * t, 0.95 - 0.1 * t]
            } else {
                // Floor: checker in longitude and in distance (cot of the angle below horizon).
                let dist = (-up).max(0.02).recip();
                let check = ((phi * 8.0 / std::f32::consts::TAU).floor() as i32 + (dist.ln() * 3.0).floor() as i32) & 1;
                let base = if check == 0 { 0.32 } else { 0.22 };
                let fade = (-up * 8.0).min(1.0);
                let horizon = 0.6;
                let v = horizon + (base - horizon) * fade;
                [v, v * 0.97, v * 0.93]
            };
            px.push([c[0], c[1], c[2], 1.0]);
        }
    }
    px
}

fn mip_chain(width: u32, height: u32, base: Vec<[f32; 4]>) -> Vec<(u32, u32, Vec<[f32; 4]>)> {
    let mut levels = vec![(width, height, base)];
    while let Some((w, h, prev)) = levels.last().map(|(w, h, p)| (*w, *h, p)) {
        if w == 1 && h == 1 {
            break;
        }
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let mut next = Vec::with_capacity((nw * nh) as usize);
        for y in 0..nh {
            for x in 0..nw {
                let mut s = [0.0f32; 4];
                let mut n = 0.0;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (sx, sy) = ((x * 2 + dx).min(w - 1), (y * 2 + dy).min(h - 1));
                    let p = prev[(sy * w + sx) as usize];
                    for c in 0..4 {
                        s[c] += p[c];
                    }
                    n += 1.0;
                }
                next.push(s.map(|v| v / n));
            }
        }
        levels.push((nw, nh, next));
    }
    levels
}

fn load_image(path: &Path) -> Result<(u32, u32, Vec<[f32; 4]>), EnvError> {
    let err = |message: String| EnvError::Read {
        path: path.display().to_string(),
        message,
    };
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        let img = exr::prelude::read_first_rgba_layer_from_file(
            path,
            |res, _| (res.width(), vec![[0.0f32; 4]; res.width() * res.height()]),
            |(w, px), pos, (r, g, b, a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = [r, g, b, a],
        )
        .map_err(|e| err(e.to_string()))?;
        let size = img.layer_data.size;
        let (_, px) = img.layer_data.channel_data.pixels;
        return finite((size.width() as u32, size.height() as u32, px)).map_err(err);
    }
    let img = image::open(path).map_err(|e| err(format!("{e} ({SUPPORTED})")))?;
    // Float images (Radiance HDR) hold linear radiance; 8- and 16-bit ones are sRGB encoded,
    // and the renderer works in linear radiance.
    let linear = matches!(
        img,
        image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
    );
    let img = img.to_rgba32f();
    let (w, h) = img.dimensions();
    let px: Vec<[f32; 4]> = if linear {
        img.pixels().map(|p| [p[0], p[1], p[2], 1.0]).collect()
    } else {
        img.pixels()
            .map(|p| [srgb_to_linear(p[0]), srgb_to_linear(p[1]), srgb_to_linear(p[2]), 1.0])
            .collect()
    };
    finite((w, h, px)).map_err(err)
}

/// The image as read, or why not: NaN or infinite pixels (of either float format).
fn finite(image: (u32, u32, Vec<[f32; 4]>)) -> Result<(u32, u32, Vec<[f32; 4]>), String> {
    if image.2.iter().flatten().any(|v| !v.is_finite()) {
        return Err("contains NaN or infinite pixels".into());
    }
    Ok(image)
}

/// The environment image formats, for error messages.
const SUPPORTED: &str = "supported: OpenEXR (.exr) and Radiance HDR (.hdr), linear; PNG, sRGB";

pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl EnvMap {
    /// None for a plain background colour.
    pub fn for_scene(env: &Environment) -> Result<Option<EnvMap>, EnvError> {
        match env {
            Environment::Color { .. } => Ok(None),
            Environment::Studio { intensity } => Ok(Some(EnvMap {
                levels: mip_chain(512, 256, studio(512, 256)),
                intensity: *intensity,
            })),
            Environment::Image { path, intensity } => {
                let (w, h, px) = load_image(path)?;
                Ok(Some(EnvMap {
                    levels: mip_chain(w, h, px),
                    intensity: *intensity,
                }))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radiance_hdr_images_are_read_as_linear_radiance() {
        // A 2×1 Radiance HDR (RGBE: an 8-bit mantissa per channel, so values within 1/128 of
        // their exponent's step) next to the same values as a PNG, which are sRGB encoded.
        let dir = std::env::temp_dir().join(format!("caustica-env-hdr-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let values = [image::Rgb([0.25f32, 1.0, 6.0]), image::Rgb([0.5, 0.125, 2.0])];
        let path = dir.join("sky.hdr");
        let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        image::codecs::hdr::HdrEncoder::new(file).encode(&values, 2, 1).unwrap();
        let (w, h, px) = load_image(&path).expect("hdr");
        assert_eq!((w, h), (2, 1));
        for (p, v) in px.iter().zip(&values) {
            for c in 0..3 {
                assert!((p[c] - v[c]).abs() <= v[c] / 64.0, "{p:?} vs {v:?}");
            }
        }
        // An 8-bit PNG's 188 is sRGB: about 0.5 in linear radiance.
        let png = dir.join("sky.png");
        image::RgbImage::from_pixel(2, 1, image::Rgb([188, 188, 188]))
            .save(&png)
            .unwrap();
        let (_, _, px) = load_image(&png).expect("png");
        assert!((px[0][0] - 0.5).abs() < 0.01, "{:?}", px[0]);
        // Anything else names the formats that are read.
        let bad = dir.join("sky.tga");
        std::fs::write(&bad, b"not an image").unwrap();
        let message = load_image(&bad).unwrap_err().to_string();
        assert!(
            message.contains("sky.tga") && message.contains("Radiance HDR"),
            "{message}"
        );
        // A float image with a NaN pixel is refused, naming the problem.
        let nan = dir.join("nan.exr");
        exr::prelude::write_rgba_file(&nan, 2, 1, |x, _| {
            (if x == 1 { f32::NAN } else { 0.5 }, 0.5f32, 0.5f32, 1.0f32)
        })
        .unwrap();
        let message = load_image(&nan).unwrap_err().to_string();
        assert!(
            message.contains("nan.exr") && message.contains("NaN or infinite"),
            "{message}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn mip_chain_preserves_mean_and_ends_at_one_texel() {
        let base = studio(64, 32);
        let mean: f32 = base.iter().map(|p| p[0]).sum::<f32>() / base.len() as f32;
        let chain = mip_chain(64, 32, base);
        let (w, h, last) = chain.last().unwrap();
        assert_eq!((*w, *h), (1, 1));
        assert_eq!(chain.len(), 7);
        assert!((last[0][0] - mean).abs() < 1e-4);
    }
}
