//! The render image in the window: packed to the surface's `0x00RRGGBB` pixels and copied
//! into the viewport, 1:1 at full quality and bilinearly scaled for coarse levels.

use crate::render::{linear_to_srgb, RenderedImage};

/// What the window shows of the render: the last accepted frame as `0x00RRGGBB`.
pub(super) struct Shown {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) pixels: Vec<u32>,
}

/// The same conversion as `RenderedImage::to_srgb8`, packed for the surface.
pub(super) fn pack(image: &RenderedImage) -> Shown {
    let q = |c: f32| (linear_to_srgb(c) * 255.0 + 0.5) as u32;
    Shown {
        width: image.width,
        height: image.height,
        pixels: image
            .pixels
            .iter()
            .map(|p| (q(p[0]) << 16) | (q(p[1]) << 8) | q(p[2]))
            .collect(),
    }
}

/// Copies `img` into the viewport `vp` = [x, y, w, h] of the buffer: 1:1 when the sizes
/// match (the full-quality frame, pixel for pixel), else bilinearly scaled (coarse levels).
pub(super) fn blit(buffer: &mut [u32], bw: usize, bh: usize, img: &Shown, vp: [u32; 4]) {
    let [x0, y0, w, h] = vp.map(|v| v as usize);
    if w == 0 || h == 0 || img.width == 0 || img.height == 0 {
        return;
    }
    let (iw, ih) = (img.width as usize, img.height as usize);
    let (x1, y1) = ((x0 + w).min(bw), (y0 + h).min(bh));
    if (iw, ih) == (w, h) {
        for y in y0..y1 {
            let src = &img.pixels[(y - y0) * iw..(y - y0) * iw + (x1 - x0)];
            buffer[y * bw + x0..y * bw + x1].copy_from_slice(src);
        }
        return;
    }
    // Texel centres: pixel centre (x + 0.5) maps to (x + 0.5) * iw / w - 0.5 in the image.
    let coord = |p: usize, n_out: usize, n_in: usize| {
        let f = ((p as f32 + 0.5) * n_in as f32 / n_out as f32 - 0.5).clamp(0.0, (n_in - 1) as f32);
        let i = (f as usize).min(n_in.saturating_sub(2));
        (i, (i + 1).min(n_in - 1), f - i as f32)
    };
    let xs: Vec<_> = (x0..x1).map(|x| coord(x - x0, w, iw)).collect();
    let ch = |p: u32, k: u32| ((p >> k) & 255) as f32;
    for y in y0..y1 {
        let (ya, yb, ty) = coord(y - y0, h, ih);
        let (ra, rb) = (&img.pixels[ya * iw..(ya + 1) * iw], &img.pixels[yb * iw..(yb + 1) * iw]);
        for (x, &(xa, xb, tx)) in (x0..x1).zip(&xs) {
            let mut out = 0u32;
            for k in [16, 8, 0] {
                let top = ch(ra[xa], k) * (1.0 - tx) + ch(ra[xb], k) * tx;
                let bottom = ch(rb[xa], k) * (1.0 - tx) + ch(rb[xb], k) * tx;
                out |= ((top * (1.0 - ty) + bottom * ty + 0.5) as u32).min(255) << k;
            }
            buffer[y * bw + x] = out;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blit_copies_exactly_at_full_size_and_interpolates_when_scaled() {
        let img = Shown {
            width: 2,
            height: 1,
            pixels: vec![0x00_00_00_00, 0x00_FF_FF_FF],
        };
        let mut buf = vec![7u32; 4 * 3];
        blit(&mut buf, 4, 3, &img, [1, 1, 2, 1]);
        assert_eq!(buf, vec![7, 7, 7, 7, 7, 0, 0xFF_FF_FF, 7, 7, 7, 7, 7]);
        let mut buf = vec![7u32; 4];
        blit(&mut buf, 4, 1, &img, [0, 0, 4, 1]);
        // Pixel centres 0.5..3.5 map to image x -0.25, 0.25, 0.75, 1.25 (clamped to [0, 1]).
        let grey = |v: u32| (v << 16) | (v << 8) | v;
        assert_eq!(buf, vec![0, grey(64), grey(191), grey(255)]);
    }
}
