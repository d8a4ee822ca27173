//! The bench's plots (PNG), drawn with the `image` crate: log–log axes, one colour per scene.
//! Error against time rings and joins each scene's Pareto front; time against work joins
//! each scene's points and draws, dashed, the line proportional cost would follow from its
//! smallest size.
//! Text uses a built-in 5×7 font.

use std::path::Path;

use image::{Rgb, RgbImage};

/// One series: a scene's (time, error) points.
pub struct Series<'a> {
    pub name: &'a str,
    pub points: Vec<(f64, f64)>,
}

/// How a plot joins each series' points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Join {
    /// The Pareto front (no other point both faster and more accurate), ringed and joined.
    ParetoFront,
    /// Every point in order of x, with a dashed line of slope 1 from the point of least x:
    /// where y would be if it grew in proportion to x.
    Proportional,
}

const WIDTH: u32 = 960;
const HEIGHT: u32 = 600;
const LEFT: i64 = 90;
const RIGHT: i64 = 240;
const TOP: i64 = 50;
const BOTTOM: i64 = 70;
const PALETTE: [[u8; 3]; 8] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
];

/// Indices of the points no other point beats in both time and error, sorted by time.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut front: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let (t, e) = points[i];
            !points
                .iter()
                .enumerate()
                .any(|(j, &(tj, ej))| j != i && tj <= t && ej <= e && (tj < t || ej < e))
        })
        .collect();
    front.sort_by(|&a, &b| points[a].0.total_cmp(&points[b].0));
    front
}

fn glyph(c: char) -> [u8; 7] {
    match c {
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '1' => [0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F],
        '3' => [0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E],
        '4' => [0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02],
        '5' => [0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E],
        '6' => [0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E],
        '7' => [0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E],
        '9' => [0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C],
        'a' => [0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F],
        'b' => [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x1E],
        'c' => [0x00, 0x00, 0x0E, 0x10, 0x10, 0x11, 0x0E],
        'd' => [0x01, 0x01, 0x0D, 0x13, 0x11, 0x11, 0x0F],
        'e' => [0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E],
        'f' => [0x06, 0x09, 0x08, 0x1C, 0x08, 0x08, 0x08],
        'g' => [0x00, 0x0F, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'h' => [0x10, 0x10, 0x16, 0x19, 0x11, 0x11, 0x11],
        'i' => [0x04, 0x00, 0x0C, 0x04, 0x04, 0x04, 0x0E],
        'j' => [0x02, 0x00, 0x06, 0x02, 0x02, 0x12, 0x0C],
        'k' => [0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12],
        'l' => [0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'm' => [0x00, 0x00, 0x1A, 0x15, 0x15, 0x11, 0x11],
        'n' => [0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11],
        'o' => [0x00, 0x00, 0x0E, 0x11, 0x11, 0x11, 0x0E],
        'p' => [0x00, 0x00, 0x1E, 0x11, 0x1E, 0x10, 0x10],
        'q' => [0x00, 0x00, 0x0D, 0x13, 0x0F, 0x01, 0x01],
        'r' => [0x00, 0x00, 0x16, 0x19, 0x10, 0x10, 0x10],
        's' => [0x00, 0x00, 0x0E, 0x10, 0x0E, 0x01, 0x1E],
        't' => [0x08, 0x08, 0x1C, 0x08, 0x08, 0x09, 0x06],
        'u' => [0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x0D],
        'v' => [0x00, 0x00, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'w' => [0x00, 0x00, 0x11, 0x11, 0x15, 0x15, 0x0A],
        'x' => [0x00, 0x00, 0x11, 0x0A, 0x04, 0x0A, 0x11],
        'y' => [0x00, 0x00, 0x11, 0x11, 0x0F, 0x01, 0x0E],
        'z' => [0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F],
        // Capitals of their own where the small letter would read wrong: "GPU" (a small g
        // reads like a 9 in 5×7 without descenders), "Monte Carlo", "L1".
        'C' => [0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E],
        'G' => [0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'M' => [0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C],
        '-' => [0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '/' => [0x01, 0x01, 0x02, 0x04, 0x08, 0x10, 0x10],
        ':' => [0x00, 0x0C, 0x0C, 0x00, 0x0C, 0x0C, 0x00],
        ',' => [0x00, 0x00, 0x00, 0x00, 0x0C, 0x04, 0x08],
        '%' => [0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03],
        '=' => [0x00, 0x00, 0x1F, 0x00, 0x1F, 0x00, 0x00],
        c if c.is_ascii_uppercase() => glyph(c.to_ascii_lowercase()),
        _ => [0; 7],
    }
}

struct Canvas(RgbImage);

impl Canvas {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && x < WIDTH as i64 && y < HEIGHT as i64 {
            self.0.put_pixel(x as u32, y as u32, Rgb(c));
        }
    }

    fn line(&mut self, a: (i64, i64), b: (i64, i64), c: [u8; 3]) {
        self.stroke(a, b, c, |_| true);
    }

    /// A line drawn 6 pixels on, 4 off.
    fn dashed(&mut self, a: (i64, i64), b: (i64, i64), c: [u8; 3]) {
        self.stroke(a, b, c, |k| k % 10 < 6);
    }

    /// The pixels of the line from a to b, one per step along its longer axis, where `on`
    /// says so of the step's index.
    fn stroke(&mut self, (x0, y0): (i64, i64), (x1, y1): (i64, i64), c: [u8; 3], on: impl Fn(i64) -> bool) {
        let steps = (x1 - x0).abs().max((y1 - y0).abs()).max(1);
        for k in (0..=steps).filter(|&k| on(k)) {
            let t = k as f64 / steps as f64;
            let x = (x0 as f64 + (x1 - x0) as f64 * t).round() as i64;
            let y = (y0 as f64 + (y1 - y0) as f64 * t).round() as i64;
            self.put(x, y, c);
        }
    }

    fn disc(&mut self, cx: i64, cy: i64, r: i64, c: [u8; 3]) {
        for y in -r..=r {
            for x in -r..=r {
                if x * x + y * y <= r * r {
                    self.put(cx + x, cy + y, c);
                }
            }
        }
    }

    fn ring(&mut self, cx: i64, cy: i64, r: i64, c: [u8; 3]) {
        for y in -r - 1..=r + 1 {
            for x in -r - 1..=r + 1 {
                let d = ((x * x + y * y) as f64).sqrt();
                if (d - r as f64).abs() < 1.0 {
                    self.put(cx + x, cy + y, c);
                }
            }
        }
    }

    /// Text at scale 2 (10×14 pixels per character plus spacing), top-left at (x, y).
    fn text(&mut self, x: i64, y: i64, s: &str, c: [u8; 3]) {
        for (i, ch) in s.chars().enumerate() {
            let g = glyph(ch);
            for (row, bits) in g.iter().enumerate() {
                for col in 0..5 {
                    if bits & (0x10 >> col) != 0 {
                        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            self.put(x + i as i64 * 12 + col * 2 + dx, y + row as i64 * 2 + dy, c);
                        }
                    }
                }
            }
        }
    }
}

fn text_width(s: &str) -> i64 {
    s.chars().count() as i64 * 12
}

/// Decade range [10^a, 10^b] covering `values`.
fn decades(values: impl Iterator<Item = f64>) -> (i32, i32) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return (0, 1);
    }
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    (a, b.max(a + 1))
}

fn tick_label(exp: i32) -> String {
    if exp >= 0 {
        format!("{}", 10f64.powi(exp))
    } else {
        format!("{:.*}", (-exp) as usize, 10f64.powi(exp))
    }
}

/// A point of a plot, (x, y).
type Point = (f64, f64);

/// The positive points of a series in order of x, and for `Join::Proportional` the ends of
/// its line of slope 1: from its first point to the last point's x.
fn proportional(points: &[Point]) -> (Vec<Point>, Option<(Point, Point)>) {
    let mut sorted: Vec<Point> = points.iter().copied().filter(|p| p.0 > 0.0 && p.1 > 0.0).collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let guide = match (sorted.first(), sorted.last()) {
        (Some(&a), Some(&b)) if b.0 > a.0 => Some((a, (b.0, a.1 * b.0 / a.0))),
        _ => None,
    };
    (sorted, guide)
}

/// A colour halfway to white.
fn pale(c: [u8; 3]) -> [u8; 3] {
    c.map(|v| ((v as u16 + 255) / 2) as u8)
}

/// Writes the plot of y against x to `path`, each series joined as `join` says (error
/// against time: `Join::ParetoFront`).
pub fn write(path: &Path, series: &[Series], x_label: &str, y_label: &str, join: Join) -> Result<(), String> {
    let mut c = Canvas(RgbImage::from_pixel(WIDTH, HEIGHT, Rgb([255, 255, 255])));
    // Per series with `Join::Proportional`: its points in order of x and its dashed line.
    let lines: Vec<_> = series
        .iter()
        .map(|s| (join == Join::Proportional).then(|| proportional(&s.points)))
        .collect();
    let all = || {
        series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .chain(lines.iter().flatten().filter_map(|(_, guide)| guide.map(|g| g.1)))
    };
    let (x0, x1) = decades(all().map(|p| p.0));
    let (y0, y1) = decades(all().map(|p| p.1));
    let (pw, ph) = (
        (WIDTH as i64 - LEFT - RIGHT) as f64,
        (HEIGHT as i64 - TOP - BOTTOM) as f64,
    );
    let px = |t: f64| LEFT + ((t.log10() - x0 as f64) / (x1 - x0) as f64 * pw).round() as i64;
    let py = |e: f64| TOP + ((y1 as f64 - e.log10()) / (y1 - y0) as f64 * ph).round() as i64;
    let (grid, axis, ink) = ([225, 225, 225], [60, 60, 60], [20, 20, 20]);
    // Grid at 1, 2, 5 × each decade; labels at decades.
    for k in x0..=x1 {
        for m in [1.0, 2.0, 5.0] {
            let v = m * 10f64.powi(k);
            if v <= 10f64.powi(x1) {
                let x = px(v);
                c.line((x, TOP), (x, TOP + ph as i64), grid);
            }
        }
        let label = tick_label(k);
        c.text(
            px(10f64.powi(k)) - text_width(&label) / 2,
            TOP + ph as i64 + 8,
            &label,
            ink,
        );
    }
    for k in y0..=y1 {
        for m in [1.0, 2.0, 5.0] {
            let v = m * 10f64.powi(k);
            if v <= 10f64.powi(y1) {
                let y = py(v);
                c.line((LEFT, y), (LEFT + pw as i64, y), grid);
            }
        }
        let label = tick_label(k);
        c.text(LEFT - 8 - text_width(&label), py(10f64.powi(k)) - 7, &label, ink);
    }
    c.line((LEFT, TOP), (LEFT, TOP + ph as i64), axis);
    c.line((LEFT, TOP + ph as i64), (LEFT + pw as i64, TOP + ph as i64), axis);
    c.text(
        LEFT + (pw as i64 - text_width(x_label)) / 2,
        HEIGHT as i64 - 28,
        x_label,
        ink,
    );
    c.text(LEFT, TOP - 30, y_label, ink);
    for (i, s) in series.iter().enumerate() {
        let colour = PALETTE[i % PALETTE.len()];
        match join {
            Join::ParetoFront => {
                let front = pareto_front(&s.points);
                for w in front.windows(2) {
                    let (a, b) = (s.points[w[0]], s.points[w[1]]);
                    c.line((px(a.0), py(a.1)), (px(b.0), py(b.1)), colour);
                }
                for &k in &front {
                    let (t, e) = s.points[k];
                    if t > 0.0 && e > 0.0 {
                        c.ring(px(t), py(e), 7, colour);
                    }
                }
            }
            Join::Proportional => {
                let (sorted, guide) = lines[i].as_ref().expect("computed for Join::Proportional");
                if let Some((a, b)) = *guide {
                    c.dashed((px(a.0), py(a.1)), (px(b.0), py(b.1)), pale(colour));
                }
                for w in sorted.windows(2) {
                    c.line((px(w[0].0), py(w[0].1)), (px(w[1].0), py(w[1].1)), colour);
                }
            }
        }
        for &(t, e) in &s.points {
            if t > 0.0 && e > 0.0 {
                c.disc(px(t), py(e), 3, colour);
            }
        }
        let ly = TOP + 10 + i as i64 * 24;
        let lx = WIDTH as i64 - RIGHT + 20;
        c.disc(lx + 5, ly + 7, 5, colour);
        c.text(lx + 18, ly, s.name, ink);
    }
    let ly = TOP + 10 + series.len() as i64 * 24 + 10;
    let lx = WIDTH as i64 - RIGHT + 20;
    match join {
        Join::ParetoFront => {
            c.ring(lx + 5, ly + 7, 7, ink);
            c.text(lx + 18, ly, "pareto front", ink);
        }
        Join::Proportional => {
            c.dashed((lx - 4, ly + 7), (lx + 14, ly + 7), pale(ink));
            c.text(lx + 18, ly, "proportional", ink);
        }
    }
    c.0.save(path).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_proportional_line_runs_from_the_least_x_with_slope_one() {
        let (sorted, guide) = proportional(&[(40.0, 9.0), (10.0, 4.0), (20.0, 5.0), (0.0, 1.0)]);
        // The point at x = 0 has no place on log axes; the rest in order of x.
        assert_eq!(sorted, vec![(10.0, 4.0), (20.0, 5.0), (40.0, 9.0)]);
        // Four times the x, four times the first point's y.
        assert_eq!(guide, Some(((10.0, 4.0), (40.0, 16.0))));
        assert_eq!(proportional(&[(3.0, 1.0)]).1, None);
    }

    #[test]
    fn the_capitals_of_the_labels_are_their_own_glyphs() {
        // "GPU ms" drawn with the small letters read like "9pu ms": each capital the labels
        // use has a glyph of its own, unlike the small letter's and every digit's.
        for c in ['C', 'G', 'L', 'M', 'P', 'U'] {
            let g = glyph(c);
            assert_ne!(g, [0; 7], "{c} has no glyph");
            assert_ne!(g, glyph(c.to_ascii_lowercase()), "{c} is drawn as its small letter");
            for d in '0'..='9' {
                assert_ne!(g, glyph(d), "{c} is drawn as {d}");
            }
        }
    }

    #[test]
    fn pareto_front_keeps_only_undominated_points() {
        let points = [(1.0, 0.5), (2.0, 0.2), (3.0, 0.3), (4.0, 0.1), (2.0, 0.25)];
        assert_eq!(pareto_front(&points), vec![0, 1, 3]);
    }
}
