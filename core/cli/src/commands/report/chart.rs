//! The report's chart: error against bake time on log–log axes, one line per scene (its
//! colour) through its presets (their marker shape), drawn with `plotters` into an RGB
//! buffer and written as PNG. Text is DejaVu Sans, bundled (core/cli/fonts) and rasterised
//! by plotters' `ab_glyph` feature, so no system font or fontconfig is needed.

use std::path::Path;
use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;

use relume_engine::image_io::write_atomic;
use relume_engine::RelumeError;

/// The font every label is drawn with (licence: core/cli/fonts/LICENSE-DejaVu.txt).
const FONT_BYTES: &[u8] = include_bytes!("../../../fonts/DejaVuSans.ttf");
/// The family name the font is registered under with plotters.
const FONT: &str = "sans-serif";

type Rgb8 = [u8; 3];

const INK: Rgb8 = [20, 20, 20];
const GRID: Rgb8 = [215, 215, 215];
const GRID_MINOR: Rgb8 = [238, 238, 238];
const TARGET: Rgb8 = [120, 120, 120];

/// Line colours (colour-blind-safe Okabe–Ito), one per series.
pub const COLOURS: [Rgb8; 6] = [
    [0, 114, 178],
    [213, 94, 0],
    [0, 158, 115],
    [204, 121, 167],
    [230, 159, 0],
    [86, 180, 233],
];

/// Marker shapes, one per point label (preset), in order of first appearance.
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

/// Width of the legend column right of the plot, in pixels.
const LEGEND_W: u32 = 190;

fn rgb(c: Rgb8) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

/// A failed drawing call (plotters' errors carry the backend's) as a `RelumeError`.
fn drawing_error(e: impl std::fmt::Display) -> RelumeError {
    RelumeError::invalid("chart", format!("drawing failed: {e}"))
}

/// Registers the bundled font with plotters, once per process.
fn register_font() -> Result<(), RelumeError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(RelumeError::invalid(
            "chart",
            "the bundled font (DejaVuSans.ttf) could not be parsed",
        ))
    }
}

/// An RGB image, rows top to bottom, and where the chart put its data points.
pub struct Canvas {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
    /// The pixel centre of every drawn data point, series by series (what the tests check).
    #[cfg_attr(not(test), allow(dead_code))]
    pub marks: Vec<(i32, i32)>,
}

impl Canvas {
    #[cfg(test)]
    pub fn get(&self, x: u32, y: u32) -> Rgb8 {
        let i = ((y * self.width + x) * 3) as usize;
        [self.pixels[i], self.pixels[i + 1], self.pixels[i + 2]]
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

/// The tick label of a decade value on a log axis.
fn tick_label(v: &f64) -> String {
    decade_label(v.log10().round() as i32)
}

/// Major ticks at 10^lo..=10^hi, minor grid lines at 2..9 × each decade.
fn ticks((lo, hi): (i32, i32)) -> (Vec<f64>, Vec<f64>) {
    let major = (lo..=hi).map(|e| 10f64.powi(e)).collect();
    let minor = (lo..hi)
        .flat_map(|e| (2..10).map(move |k| k as f64 * 10f64.powi(e)))
        .collect();
    (major, minor)
}

/// Draws `m` centred at `at` (pixels) on `area`.
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    at: (i32, i32),
    m: Marker,
    colour: RGBColor,
) -> Result<(), RelumeError> {
    let style = colour.filled();
    match m {
        Marker::Circle => area.draw(&Circle::new(at, 6, style)),
        Marker::Square => area.draw(&Rectangle::new(
            [(at.0 - 5, at.1 - 5), (at.0 + 5, at.1 + 5)],
            style,
        )),
        Marker::Triangle => area.draw(&TriangleMarker::new(at, 7, style)),
        Marker::Diamond => area.draw(&Polygon::new(
            vec![
                (at.0, at.1 - 7),
                (at.0 + 7, at.1),
                (at.0, at.1 + 7),
                (at.0 - 7, at.1),
            ],
            style,
        )),
    }
    .map_err(drawing_error)
}

impl Chart {
    /// The distinct point labels (presets) in order of first appearance: marker i is theirs.
    fn point_labels(&self) -> Vec<&str> {
        let mut labels: Vec<&str> = Vec::new();
        for (_, _, l) in self.series.iter().flat_map(|s| s.points.iter()) {
            if !labels.contains(&l.as_str()) {
                labels.push(l);
            }
        }
        labels
    }

    /// Draws the chart on a `width`×`height` canvas: the plot, and right of it a legend
    /// naming the scenes (colours) and presets (marker shapes), so no label sits in the plot
    /// where it could cover another.
    pub fn draw(&self, width: u32, height: u32) -> Result<Canvas, RelumeError> {
        register_font()?;
        let mut pixels = vec![255u8; (width as usize) * (height as usize) * 3];
        let mut marks = Vec::new();
        let labels = self.point_labels();
        let marker_of = |label: &str| {
            let i = labels.iter().position(|l| *l == label).unwrap_or(0);
            MARKERS[i % MARKERS.len()]
        };
        {
            let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
            let (plot, legend) = root.split_horizontally(width.saturating_sub(LEGEND_W));
            plot.draw(&Text::new(
                self.title.as_str(),
                (20, 12),
                (FONT, 24).into_font().color(&rgb(INK)),
            ))
            .map_err(drawing_error)?;
            plot.draw(&Text::new(
                self.subtitle.as_str(),
                (20, 44),
                (FONT, 14).into_font().color(&rgb(TARGET)),
            ))
            .map_err(drawing_error)?;

            let valid = |p: &&(f64, f64, String)| p.0 > 0.0 && p.1 > 0.0;
            let points = || {
                self.series
                    .iter()
                    .flat_map(|s| s.points.iter())
                    .filter(valid)
            };
            let xd = decades(points().map(|p| p.0));
            let yd = decades(
                points()
                    .map(|p| p.1)
                    .chain(self.target.as_ref().map(|t| t.0)),
            );
            let ((x_major, x_minor), (y_major, y_minor)) = (ticks(xd), ticks(yd));
            let x_range = (10f64.powi(xd.0)..10f64.powi(xd.1))
                .log_scale()
                .with_key_points(x_major)
                .with_light_points(x_minor);
            let y_range = (10f64.powi(yd.0)..10f64.powi(yd.1))
                .log_scale()
                .with_key_points(y_major)
                .with_light_points(y_minor);
            let mut chart = ChartBuilder::on(&plot)
                .margin_top(76)
                .margin_left(16)
                .margin_right(24)
                .margin_bottom(12)
                .x_label_area_size(56)
                .y_label_area_size(76)
                .build_cartesian_2d(x_range, y_range)
                .map_err(drawing_error)?;
            chart
                .configure_mesh()
                .x_desc(self.x_label.as_str())
                .y_desc(self.y_label.as_str())
                .x_label_formatter(&tick_label)
                .y_label_formatter(&tick_label)
                .label_style((FONT, 16).into_font().color(&rgb(INK)))
                .axis_desc_style((FONT, 18).into_font().color(&rgb(INK)))
                .axis_style(rgb(INK))
                .bold_line_style(rgb(GRID))
                .light_line_style(rgb(GRID_MINOR))
                .set_all_tick_mark_size(6)
                .draw()
                .map_err(drawing_error)?;

            if let Some((y, label)) = &self.target {
                let (x0, x1) = (10f64.powi(xd.0), 10f64.powi(xd.1));
                chart
                    .draw_series(DashedLineSeries::new(
                        [(x0, *y), (x1, *y)],
                        8,
                        6,
                        rgb(TARGET).stroke_width(1),
                    ))
                    .map_err(drawing_error)?;
                // Labelled at the left end, where the fastest bakes' errors are far above it.
                let at = chart.backend_coord(&(x0, *y));
                plot.draw(&Text::new(
                    label.as_str(),
                    (at.0 + 6, at.1 - 4),
                    (FONT, 14)
                        .into_font()
                        .color(&rgb(TARGET))
                        .pos(Pos::new(HPos::Left, VPos::Bottom)),
                ))
                .map_err(drawing_error)?;
            }

            // Lines first, then every marker on top of every line.
            for (i, s) in self.series.iter().enumerate() {
                let colour = rgb(COLOURS[i % COLOURS.len()]);
                chart
                    .draw_series(LineSeries::new(
                        s.points.iter().filter(valid).map(|p| (p.0, p.1)),
                        colour.stroke_width(3),
                    ))
                    .map_err(drawing_error)?;
            }
            for (i, s) in self.series.iter().enumerate() {
                let colour = rgb(COLOURS[i % COLOURS.len()]);
                for p in s.points.iter().filter(valid) {
                    let at = chart.backend_coord(&(p.0, p.1));
                    draw_marker(&plot, at, marker_of(&p.2), colour)?;
                    marks.push(at);
                }
            }

            // Legend: scenes by colour, then presets by shape.
            let text = |size| (FONT, size).into_font().color(&rgb(INK));
            let mut y = 90;
            legend
                .draw(&Text::new("scene", (8, y), text(17)))
                .map_err(drawing_error)?;
            y += 30;
            for (i, s) in self.series.iter().enumerate() {
                let colour = rgb(COLOURS[i % COLOURS.len()]);
                legend
                    .draw(&PathElement::new(
                        [(8, y + 9), (44, y + 9)],
                        colour.stroke_width(3),
                    ))
                    .map_err(drawing_error)?;
                legend
                    .draw(&Text::new(s.name.as_str(), (54, y), text(16)))
                    .map_err(drawing_error)?;
                y += 26;
            }
            y += 18;
            legend
                .draw(&Text::new("preset", (8, y), text(17)))
                .map_err(drawing_error)?;
            y += 30;
            for label in &labels {
                draw_marker(&legend, (26, y + 9), marker_of(label), rgb(TARGET))?;
                legend
                    .draw(&Text::new(*label, (54, y), text(16)))
                    .map_err(drawing_error)?;
                y += 26;
            }
            root.present().map_err(drawing_error)?;
        }
        Ok(Canvas {
            width,
            height,
            pixels,
            marks,
        })
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
        assert_eq!(tick_label(&0.1), "0.1");
        let (major, minor) = ticks((-1, 1));
        assert_eq!(major.len(), 3);
        assert_eq!(minor.len(), 16);
    }

    fn two_point_chart() -> Chart {
        Chart {
            title: "Title".into(),
            subtitle: "subtitle".into(),
            x_label: "bake time (s)".into(),
            y_label: "error (%)".into(),
            series: vec![
                Series {
                    name: "a".into(),
                    points: vec![(1.0, 1.0, "draft".into()), (10.0, 0.1, "final".into())],
                },
                Series {
                    name: "b".into(),
                    points: vec![(2.0, 0.5, "draft".into())],
                },
            ],
            target: Some((1.0, "1 % target".into())),
        }
    }

    #[test]
    fn draws_markers_where_the_data_are() {
        let canvas = two_point_chart().draw(800, 480).unwrap();
        assert_eq!(canvas.pixels.len(), 800 * 480 * 3);
        let m = &canvas.marks;
        assert_eq!(m.len(), 3);
        // x spans [1, 10] and y [0.1, 1]: the first point is the plot's top-left corner, the
        // second its bottom-right one; (2, 0.5) sits log10(2) of the way across and down.
        assert!(m[0].0 < m[1].0 && m[0].1 < m[1].1, "{m:?}");
        let frac_x = (m[2].0 - m[0].0) as f64 / (m[1].0 - m[0].0) as f64;
        let frac_y = (m[2].1 - m[0].1) as f64 / (m[1].1 - m[0].1) as f64;
        assert!((frac_x - 2f64.log10()).abs() < 0.01, "{frac_x}");
        assert!((frac_y - 2f64.log10()).abs() < 0.01, "{frac_y}");
        // Each marker is filled with its series' colour, the line between a's points crosses
        // the middle of the plot.
        assert_eq!(canvas.get(m[0].0 as u32, m[0].1 as u32), COLOURS[0]);
        assert_eq!(canvas.get(m[1].0 as u32, m[1].1 as u32), COLOURS[0]);
        assert_eq!(canvas.get(m[2].0 as u32, m[2].1 as u32), COLOURS[1]);
        let mid = ((m[0].0 + m[1].0) / 2, (m[0].1 + m[1].1) / 2);
        assert_eq!(canvas.get(mid.0 as u32, mid.1 as u32), COLOURS[0]);
        // Everything stays inside the plot, left of the legend column.
        assert!(m.iter().all(|p| p.0 > 0 && (p.0 as u32) < 800 - LEGEND_W));
    }

    #[test]
    fn draws_text_with_the_bundled_font() {
        let canvas = two_point_chart().draw(800, 480).unwrap();
        // The title's row band and the legend column hold anti-aliased dark glyph pixels
        // (grey levels between ink and white, which a bitmap font would not make).
        let band = |x0: u32, x1: u32, y0: u32, y1: u32| {
            let mut dark = 0;
            let mut grey = 0;
            for y in y0..y1 {
                for x in x0..x1 {
                    let [r, g, b] = canvas.get(x, y);
                    if r == g && g == b && r < 100 {
                        dark += 1;
                    } else if r == g && g == b && r > 120 && r < 230 {
                        grey += 1;
                    }
                }
            }
            (dark, grey)
        };
        let (dark, grey) = band(20, 200, 10, 40);
        assert!(dark > 50 && grey > 10, "title: {dark} dark, {grey} grey");
        let (dark, _) = band(800 - LEGEND_W + 50, 800, 110, 180);
        assert!(dark > 30, "legend: {dark} dark");
    }
}
