//! The report's chart: error against bake time on log–log axes, one line per scene, points
//! labelled by preset, drawn into an RGB canvas with the built-in font and written as PNG.

use std::path::Path;

use relume_engine::image_io::write_atomic;
use relume_engine::RelumeError;

use super::font::{glyph, GLYPH_W};

type Rgb8 = [u8; 3];

const WHITE: Rgb8 = [255, 255, 255];
const BLACK: Rgb8 = [20, 20, 20];
const GRID: Rgb8 = [222, 222, 222];
const GRID_MINOR: Rgb8 = [240, 240, 240];
const TARGET: Rgb8 = [150, 150, 150];

/// Line colours (colour-blind-safe Okabe–Ito) and marker shapes, one per series.
const COLOURS: [Rgb8; 6] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
];

#[derive(Clone, Copy)]
enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
}
const MARKERS: [Marker; 4] = [
    Marker::Circle,
    Marker::Square,
    Marker::Triangle,
    Marker::Diamond,
];

/// An RGB image, rows top to bottom.
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
}

impl Canvas {
    pub fn new(width: u32, height: u32) -> Canvas {
        Canvas {
            width,
            height,
            pixels: WHITE.repeat((width * height) as usize),
        }
    }

    #[cfg(test)]
    pub fn get(&self, x: u32, y: u32) -> Rgb8 {
        let i = ((y * self.width + x) * 3) as usize;
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
    }

    fn set(&mut self, x: i64, y: i64, c: Rgb8) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let i = ((y as u32 * self.width + x as u32) * 3) as usize;
        self.pixels[i..i + 3].copy_from_slice(&c);
    }

    fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb8) {
        for y in y0.min(y1)..=y0.max(y1) {
            for x in x0.min(x1)..=x0.max(x1) {
                self.set(x, y, c);
            }
        }
    }

    /// A line `thickness` pixels wide (square pen); `dash` > 0 draws dashes of that length.
    fn line(&mut self, a: (f64, f64), b: (f64, f64), thickness: i64, dash: u32, c: Rgb8) {
        let steps = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as u32;
        let lo = -(thickness - 1) / 2;
        let hi = thickness / 2;
        for i in 0..=steps {
            if dash > 0 && (i / dash) % 2 == 1 {
                continue;
            }
            let t = i as f64 / steps as f64;
            let x = (a.0 + (b.0 - a.0) * t).round() as i64;
            let y = (a.1 + (b.1 - a.1) * t).round() as i64;
            self.rect(x + lo, y + lo, x + hi, y + hi, c);
        }
    }

    fn marker(&mut self, x: f64, y: f64, m: Marker, r: i64, c: Rgb8) {
        let (cx, cy) = (x.round() as i64, y.round() as i64);
        for dy in -r..=r {
            for dx in -r..=r {
                let inside = match m {
                    Marker::Circle => dx * dx + dy * dy <= r * r,
                    Marker::Square => dx.abs() < r && dy.abs() < r,
                    Marker::Diamond => dx.abs() + dy.abs() <= r,
                    // Apex up: the half-width grows from 0 at the top to r at the bottom.
                    Marker::Triangle => 2 * dx.abs() <= dy + r,
                };
                if inside {
                    self.set(cx + dx, cy + dy, c);
                }
            }
        }
    }

    /// Text with its top-left corner at (x, y), each font pixel `scale`² pixels.
    fn text(&mut self, x: i64, y: i64, s: &str, scale: i64, c: Rgb8) {
        let mut pen = x;
        for ch in s.chars() {
            let rows = glyph(ch);
            for (gy, row) in rows.iter().enumerate() {
                for gx in 0..GLYPH_W as i64 {
                    if row & (1 << (GLYPH_W as i64 - 1 - gx)) != 0 {
                        let px = pen + gx * scale;
                        let py = y + gy as i64 * scale;
                        self.rect(px, py, px + scale - 1, py + scale - 1, c);
                    }
                }
            }
            pen += (GLYPH_W as i64 + 1) * scale;
        }
    }

    /// Text rotated a quarter turn anticlockwise (read bottom to top), its baseline's start at
    /// (x, y): the string runs upwards from y.
    fn text_up(&mut self, x: i64, y: i64, s: &str, scale: i64, c: Rgb8) {
        let mut pen = y;
        for ch in s.chars() {
            let rows = glyph(ch);
            for (gy, row) in rows.iter().enumerate() {
                for gx in 0..GLYPH_W as i64 {
                    if row & (1 << (GLYPH_W as i64 - 1 - gx)) != 0 {
                        let px = x + gy as i64 * scale;
                        let py = pen - (gx + 1) * scale;
                        self.rect(px, py, px + scale - 1, py + scale - 1, c);
                    }
                }
            }
            pen -= (GLYPH_W as i64 + 1) * scale;
        }
    }

    /// Writes the canvas as an 8-bit RGB PNG, atomically.
    pub fn write_png(&self, path: &Path) -> Result<u64, RelumeError> {
        write_atomic(path, |w| {
            let err = |e: png::EncodingError| {
                RelumeError::invalid(
                    "chart",
                    format!("PNG write of {} failed: {e}", path.display()),
                )
            };
            let mut enc = png::Encoder::new(w, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
            let mut writer = enc.write_header().map_err(err)?;
            writer.write_image_data(&self.pixels).map_err(err)?;
            writer.finish().map_err(err)
        })
    }
}

/// Width in pixels of `s` drawn at `scale`.
fn text_width(s: &str, scale: i64) -> i64 {
    s.chars().count() as i64 * (GLYPH_W as i64 + 1) * scale - scale
}

/// One line of the chart: a scene, its points (x, y, label) in data units.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64, String)>,
}

/// What to draw.
pub struct Chart {
    pub title: String,
    pub subtitle: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// A dashed horizontal line at this y with its label (the preview target).
    pub target: Option<(f64, String)>,
}

/// A decade range [10^lo, 10^hi] covering `values` (and at least one decade).
fn decades(values: impl Iterator<Item = f64>) -> (i32, i32) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite() && *v > 0.0) {
        lo = lo.min(v.log10());
        hi = hi.max(v.log10());
    }
    if !lo.is_finite() {
        return (0, 1);
    }
    let (l, mut h) = (lo.floor() as i32, hi.ceil() as i32);
    if h <= l {
        h = l + 1;
    }
    (l, h)
}

/// "0.01", "0.1", "1", "10", "100", … for 10^e.
fn decade_label(e: i32) -> String {
    if e >= 0 {
        format!("{}", 10f64.powi(e) as u64)
    } else {
        format!("{:.*}", (-e) as usize, 10f64.powi(e))
    }
}

impl Chart {
    /// Draws the chart on a `width`×`height` canvas.
    pub fn draw(&self, width: u32, height: u32) -> Canvas {
        let mut c = Canvas::new(width, height);
        let (left, right, top, bottom) = (110i64, width as i64 - 230, 70i64, height as i64 - 80);
        let points = || self.series.iter().flat_map(|s| s.points.iter());
        let (xl, xh) = decades(points().map(|p| p.0));
        let (yl, yh) = decades(
            points()
                .map(|p| p.1)
                .chain(self.target.as_ref().map(|t| t.0)),
        );
        let px = |x: f64| {
            left as f64 + (x.log10() - xl as f64) / (xh - xl) as f64 * (right - left) as f64
        };
        let py = |y: f64| {
            bottom as f64 - (y.log10() - yl as f64) / (yh - yl) as f64 * (bottom - top) as f64
        };
        // Grid: minor lines at 2..9 × 10^e, major at the decades, with labels.
        for e in xl..xh {
            for k in 2..10 {
                let x = px(k as f64 * 10f64.powi(e)).round() as i64;
                c.rect(x, top, x, bottom, GRID_MINOR);
            }
        }
        for e in yl..yh {
            for k in 2..10 {
                let y = py(k as f64 * 10f64.powi(e)).round() as i64;
                c.rect(left, y, right, y, GRID_MINOR);
            }
        }
        for e in xl..=xh {
            let x = px(10f64.powi(e)).round() as i64;
            c.rect(x, top, x, bottom, GRID);
            c.rect(x, bottom, x, bottom + 6, BLACK);
            let label = decade_label(e);
            c.text(x - text_width(&label, 2) / 2, bottom + 12, &label, 2, BLACK);
        }
        for e in yl..=yh {
            let y = py(10f64.powi(e)).round() as i64;
            c.rect(left, y, right, y, GRID);
            c.rect(left - 6, y, left, y, BLACK);
            let label = decade_label(e);
            c.text(left - 12 - text_width(&label, 2), y - 7, &label, 2, BLACK);
        }
        // Frame.
        c.rect(left, top, right, top, BLACK);
        c.rect(left, bottom, right, bottom, BLACK);
        c.rect(left, top, left, bottom, BLACK);
        c.rect(right, top, right, bottom, BLACK);
        // Titles and axis labels.
        c.text(left, 16, &self.title, 2, BLACK);
        c.text(left, 42, &self.subtitle, 1, BLACK);
        let xw = text_width(&self.x_label, 2);
        c.text(
            (left + right) / 2 - xw / 2,
            bottom + 44,
            &self.x_label,
            2,
            BLACK,
        );
        let yw = text_width(&self.y_label, 2);
        c.text_up(24, (top + bottom) / 2 + yw / 2, &self.y_label, 2, BLACK);
        if let Some((y, label)) = &self.target {
            let yy = py(*y);
            c.line((left as f64, yy), (right as f64, yy), 1, 6, TARGET);
            c.text(
                right - text_width(label, 1) - 4,
                yy.round() as i64 - 11,
                label,
                1,
                TARGET,
            );
        }
        // Series: lines, then markers and their labels on top.
        for (i, s) in self.series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let pts: Vec<(f64, f64)> = s
                .points
                .iter()
                .filter(|p| p.0 > 0.0 && p.1 > 0.0)
                .map(|p| (px(p.0), py(p.1)))
                .collect();
            for w in pts.windows(2) {
                c.line(w[0], w[1], 3, 0, colour);
            }
        }
        for (i, s) in self.series.iter().enumerate() {
            let colour = COLOURS[i % COLOURS.len()];
            let marker = MARKERS[i % MARKERS.len()];
            for (x, y, label) in s.points.iter().filter(|p| p.0 > 0.0 && p.1 > 0.0) {
                let (x, y) = (px(*x), py(*y));
                c.marker(x, y, marker, 6, colour);
                c.text(
                    x.round() as i64 + 9,
                    y.round() as i64 - 14,
                    label,
                    1,
                    colour,
                );
            }
            // Legend.
            let ly = top + 10 + i as i64 * 30;
            let lx = right + 20;
            c.line(
                (lx as f64, ly as f64 + 7.0),
                (lx as f64 + 36.0, ly as f64 + 7.0),
                3,
                0,
                colour,
            );
            c.marker(lx as f64 + 18.0, ly as f64 + 7.0, marker, 6, colour);
            c.text(lx + 46, ly, &s.name, 2, BLACK);
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decades_cover_the_data() {
        assert_eq!(decades([0.5, 30.0].into_iter()), (-1, 2));
        assert_eq!(decades([1.0].into_iter()), (0, 1));
        assert_eq!(decades(std::iter::empty()), (0, 1));
        assert_eq!(decade_label(-2), "0.01");
        assert_eq!(decade_label(2), "100");
    }

    #[test]
    fn draws_markers_where_the_data_are() {
        let chart = Chart {
            title: "T".into(),
            subtitle: "s".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series {
                name: "a".into(),
                points: vec![(1.0, 1.0, "p".into()), (10.0, 0.1, "q".into())],
            }],
            target: Some((1.0, "1 %".into())),
        };
        let canvas = chart.draw(640, 400);
        // x spans [1, 10] and y [0.1, 1]: the first point is the plot's top-left corner, the
        // second its bottom-right one, the line between them crosses the centre.
        let (left, right, top, bottom) = (110u32, 640 - 230, 70u32, 400 - 80);
        assert_eq!(canvas.get(left, bottom - 20), BLACK, "frame");
        assert_eq!(canvas.get(right, top + 20), BLACK, "frame");
        assert_eq!(
            canvas.get(left + 2, top + 2),
            COLOURS[0],
            "first point (1, 1)"
        );
        assert_eq!(
            canvas.get(right - 2, bottom - 2),
            COLOURS[0],
            "second point (10, 0.1)"
        );
        assert_eq!(
            canvas.get((left + right) / 2, (top + bottom) / 2),
            COLOURS[0]
        );
    }
}
