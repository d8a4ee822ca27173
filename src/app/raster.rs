//! A small CPU painter for egui's tessellated meshes, drawing into the window's pixel buffer.
//!
//! Why on the CPU: the renderer already hands back its image in host memory (the same
//! `RenderedImage` `caustica render` writes), so the viewer presents with a plain pixel buffer
//! (softbuffer) instead of a second, graphics-capable Vulkan path with a swapchain. The panel
//! is a few thousand small triangles, cheap next to the volume render even on lavapipe.
//! egui colours are premultiplied sRGB; blending happens in sRGB space, as egui expects.

use std::collections::HashMap;

use egui::epaint::textures::TexturesDelta;
use egui::epaint::{ClippedPrimitive, ImageData, Primitive, TextureId, Vertex};

/// An RGBA8 texture, premultiplied sRGB.
struct Texture {
    size: [usize; 2],
    pixels: Vec<[u8; 4]>,
}

/// A frame buffer of `0x00RRGGBB` pixels (softbuffer's format) and the egui textures.
#[derive(Default)]
pub struct Painter {
    textures: HashMap<TextureId, Texture>,
}

/// Pixels of the target: `width × height`, row-major, `0x00RRGGBB`.
pub struct Target<'a> {
    pub pixels: &'a mut [u32],
    pub width: usize,
    pub height: usize,
}

impl Painter {
    pub fn update_textures(&mut self, delta: &TexturesDelta) {
        for (id, d) in delta.set.iter().flat_map(|(id, ds)| ds.iter().map(move |d| (id, d))) {
            let ImageData::Color(img) = &d.image;
            let src: Vec<[u8; 4]> = img.pixels.iter().map(|c| c.to_array()).collect();
            match d.pos {
                None => {
                    self.textures.insert(
                        *id,
                        Texture {
                            size: img.size,
                            pixels: src,
                        },
                    );
                }
                Some([x0, y0]) => {
                    let Some(t) = self.textures.get_mut(id) else { continue };
                    for y in 0..img.size[1] {
                        for x in 0..img.size[0] {
                            let (tx, ty) = (x0 + x, y0 + y);
                            if tx < t.size[0] && ty < t.size[1] {
                                t.pixels[ty * t.size[0] + tx] = src[y * img.size[0] + x];
                            }
                        }
                    }
                }
            }
        }
    }

    pub fn free_textures(&mut self, delta: &TexturesDelta) {
        for id in &delta.free {
            self.textures.remove(id);
        }
    }

    /// Paints `primitives` (in points) over `target`, `pixels_per_point` pixels per point.
    pub fn paint(&self, target: &mut Target<'_>, primitives: &[ClippedPrimitive], pixels_per_point: f32) {
        for p in primitives {
            let Primitive::Mesh(mesh) = &p.primitive else { continue };
            let Some(tex) = self.textures.get(&mesh.texture_id) else {
                continue;
            };
            let clip = [
                (p.clip_rect.min.x * pixels_per_point).round().max(0.0) as usize,
                (p.clip_rect.min.y * pixels_per_point).round().max(0.0) as usize,
                ((p.clip_rect.max.x * pixels_per_point).round().max(0.0) as usize).min(target.width),
                ((p.clip_rect.max.y * pixels_per_point).round().max(0.0) as usize).min(target.height),
            ];
            if clip[0] >= clip[2] || clip[1] >= clip[3] {
                continue;
            }
            for tri in mesh.indices.chunks_exact(3) {
                let v = |i: u32| mesh.vertices.get(i as usize);
                if let (Some(a), Some(b), Some(c)) = (v(tri[0]), v(tri[1]), v(tri[2])) {
                    triangle(target, tex, clip, pixels_per_point, [a, b, c]);
                }
            }
        }
    }
}

/// Edge function: twice the signed area of (a, b, p).
fn edge(a: [f32; 2], b: [f32; 2], p: [f32; 2]) -> f32 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Top-left fill rule for a counter-clockwise-normalised triangle: pixels exactly on a shared
/// edge belong to one triangle only, so translucent meshes are not blended twice there.
fn is_top_left(a: [f32; 2], b: [f32; 2]) -> bool {
    let d = [b[0] - a[0], b[1] - a[1]];
    (d[1] == 0.0 && d[0] < 0.0) || d[1] > 0.0
}

fn triangle(target: &mut Target<'_>, tex: &Texture, clip: [usize; 4], ppp: f32, v: [&Vertex; 3]) {
    let mut p = v.map(|v| [v.pos.x * ppp, v.pos.y * ppp]);
    let mut verts = v;
    let area = edge(p[0], p[1], p[2]);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    if area < 0.0 {
        p.swap(1, 2);
        verts.swap(1, 2);
    }
    let area = area.abs();
    let min_x = (p
        .iter()
        .map(|q| q[0])
        .fold(f32::INFINITY, f32::min)
        .floor()
        .max(clip[0] as f32)) as usize;
    let min_y = (p
        .iter()
        .map(|q| q[1])
        .fold(f32::INFINITY, f32::min)
        .floor()
        .max(clip[1] as f32)) as usize;
    let max_x = (p.iter().map(|q| q[0]).fold(f32::NEG_INFINITY, f32::max).ceil()).min(clip[2] as f32) as usize;
    let max_y = (p.iter().map(|q| q[1]).fold(f32::NEG_INFINITY, f32::max).ceil()).min(clip[3] as f32) as usize;
    let top_left = [
        is_top_left(p[1], p[2]),
        is_top_left(p[2], p[0]),
        is_top_left(p[0], p[1]),
    ];
    let colors = verts.map(|v| v.color.to_array().map(|c| c as f32));
    let uniform_color = colors[0] == colors[1] && colors[1] == colors[2];
    let (tw, th) = (tex.size[0] as f32, tex.size[1] as f32);
    for y in min_y..max_y {
        let row = y * target.width;
        for x in min_x..max_x {
            let c = [x as f32 + 0.5, y as f32 + 0.5];
            let w = [edge(p[1], p[2], c), edge(p[2], p[0], c), edge(p[0], p[1], c)];
            let inside = (0..3).all(|k| w[k] > 0.0 || (w[k] == 0.0 && top_left[k]));
            if !inside {
                continue;
            }
            let b = w.map(|wk| wk / area);
            let color = if uniform_color {
                colors[0]
            } else {
                std::array::from_fn(|k| colors[0][k] * b[0] + colors[1][k] * b[1] + colors[2][k] * b[2])
            };
            let u = verts[0].uv.x * b[0] + verts[1].uv.x * b[1] + verts[2].uv.x * b[2];
            let vv = verts[0].uv.y * b[0] + verts[1].uv.y * b[1] + verts[2].uv.y * b[2];
            let tx = ((u * tw) as usize).min(tex.size[0] - 1);
            let ty = ((vv * th) as usize).min(tex.size[1] - 1);
            let t = tex.pixels[ty * tex.size[0] + tx];
            // Vertex colour × texel, both premultiplied: the source, over the destination.
            let src: [f32; 4] = std::array::from_fn(|k| color[k] * t[k] as f32 / 255.0);
            let dst = &mut target.pixels[row + x];
            let d = [(*dst >> 16) & 255, (*dst >> 8) & 255, *dst & 255].map(|c| c as f32);
            let keep = 1.0 - src[3] / 255.0;
            let o: [u32; 3] = std::array::from_fn(|k| (src[k] + d[k] * keep + 0.5).clamp(0.0, 255.0) as u32);
            *dst = (o[0] << 16) | (o[1] << 8) | o[2];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use egui::epaint::{Color32, Mesh, Pos2, Rect};

    fn painter_with_white() -> Painter {
        let mut p = Painter::default();
        p.textures.insert(
            TextureId::default(),
            Texture {
                size: [1, 1],
                pixels: vec![[255; 4]],
            },
        );
        p
    }

    #[test]
    fn fills_a_rectangle_once_with_blending() {
        let painter = painter_with_white();
        let mut px = vec![0x00_20_40_60u32; 16 * 16];
        let mut target = Target {
            pixels: &mut px,
            width: 16,
            height: 16,
        };
        // Half-transparent red (premultiplied) over a 8×8 square made of two triangles.
        let mut mesh = Mesh::default();
        mesh.add_colored_rect(
            Rect::from_min_max(Pos2::new(4.0, 4.0), Pos2::new(12.0, 12.0)),
            Color32::from_rgba_premultiplied(128, 0, 0, 128),
        );
        let prim = ClippedPrimitive {
            clip_rect: Rect::from_min_max(Pos2::ZERO, Pos2::new(16.0, 16.0)),
            primitive: Primitive::Mesh(mesh),
        };
        painter.paint(&mut target, &[prim], 1.0);
        let keep = 1.0 - 128.0 / 255.0;
        let expect = |c: f32, add: f32| (add + c * keep + 0.5) as u32;
        let inside = (expect(0x20 as f32, 128.0) << 16) | (expect(0x40 as f32, 0.0) << 8) | expect(0x60 as f32, 0.0);
        let mut covered = 0;
        for (i, v) in px.iter().enumerate() {
            let (x, y) = (i % 16, i / 16);
            if (4..12).contains(&x) && (4..12).contains(&y) {
                assert_eq!(*v, inside, "({x}, {y}) blended exactly once");
                covered += 1;
            } else {
                assert_eq!(*v, 0x00_20_40_60, "({x}, {y}) untouched");
            }
        }
        assert_eq!(covered, 64);
    }

    #[test]
    fn clip_rect_limits_painting() {
        let painter = painter_with_white();
        let mut px = vec![0u32; 8 * 8];
        let mut target = Target {
            pixels: &mut px,
            width: 8,
            height: 8,
        };
        let mut mesh = Mesh::default();
        mesh.add_colored_rect(Rect::from_min_max(Pos2::ZERO, Pos2::new(8.0, 8.0)), Color32::WHITE);
        let prim = ClippedPrimitive {
            clip_rect: Rect::from_min_max(Pos2::ZERO, Pos2::new(4.0, 8.0)),
            primitive: Primitive::Mesh(mesh),
        };
        painter.paint(&mut target, &[prim], 1.0);
        assert_eq!(px.iter().filter(|v| **v == 0xFF_FF_FF).count(), 32);
        assert_eq!(px[7], 0);
    }
}
