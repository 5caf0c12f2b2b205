//! A contact sheet: PNG frames shrunk into a grid, each captioned, with a title line —
//! the one picture to look at first after `scripts/demo.sh`.
//!
//! ```sh
//! cargo run --release -p relume-cli --example contact_sheet -- OUT.png \
//!     [--title TEXT] [--columns 5] [--tile 256] FRAME.png[=CAPTION]...
//! ```
//!
//! Frames are decoded with `png`, shrunk by an integer box filter to at most `--tile` pixels
//! wide, and the text is drawn with `plotters` in DejaVu Sans (bundled in core/cli/fonts,
//! the font of `relume report`'s chart).

use std::error::Error;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use plotters::style::FontStyle;

const FONT_BYTES: &[u8] = include_bytes!("../fonts/DejaVuSans.ttf");
const GAP: u32 = 8;
const CAPTION_H: u32 = 26;
const TITLE_H: u32 = 40;

struct Frame {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
    caption: String,
}

fn read_png(path: &Path) -> Result<(u32, u32, Vec<u8>), Box<dyn Error>> {
    let mut decoder = png::Decoder::new(std::io::BufReader::new(File::open(path)?));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info()?;
    let mut buf = vec![0; reader.output_buffer_size().ok_or("PNG too large")?];
    let info = reader.next_frame(&mut buf)?;
    let channels = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Indexed => return Err("indexed PNG after EXPAND".into()),
    };
    let rgb = buf[..info.buffer_size()]
        .chunks_exact(channels)
        .flat_map(|p| {
            if channels < 3 {
                [p[0], p[0], p[0]]
            } else {
                [p[0], p[1], p[2]]
            }
        })
        .collect();
    Ok((info.width, info.height, rgb))
}

/// Shrinks `rgb` (`w`×`h`) by the integer factor `k` (mean of each k×k box).
fn shrink(w: u32, h: u32, rgb: &[u8], k: u32) -> (u32, u32, Vec<u8>) {
    let (ow, oh) = (w / k, h / k);
    let mut out = Vec::with_capacity((ow * oh * 3) as usize);
    for oy in 0..oh {
        for ox in 0..ow {
            for c in 0..3 {
                let mut sum = 0u32;
                for y in oy * k..(oy + 1) * k {
                    for x in ox * k..(ox + 1) * k {
                        sum += rgb[((y * w + x) * 3 + c) as usize] as u32;
                    }
                }
                out.push(((sum + k * k / 2) / (k * k)) as u8);
            }
        }
    }
    (ow, oh, out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().ok_or(
        "usage: contact_sheet OUT.png [--title T] [--columns N] [--tile PX] FRAME.png[=CAPTION]...",
    )?);
    let (mut title, mut columns, mut tile) = (String::new(), 5u32, 256u32);
    let mut frames = Vec::new();
    while let Some(a) = args.next() {
        match a.as_str() {
            "--title" => title = args.next().ok_or("--title needs a value")?,
            "--columns" => columns = args.next().ok_or("--columns needs a value")?.parse()?,
            "--tile" => tile = args.next().ok_or("--tile needs a value")?.parse()?,
            _ => {
                let (path, caption) = a.split_once('=').unwrap_or((&a, ""));
                let (w, h, rgb) = read_png(Path::new(path)).map_err(|e| format!("{path}: {e}"))?;
                let (width, height, rgb) = shrink(w, h, &rgb, w.div_ceil(tile).max(1));
                frames.push(Frame {
                    width,
                    height,
                    rgb,
                    caption: caption.to_string(),
                });
            }
        }
    }
    if frames.is_empty() {
        return Err("no frames given".into());
    }
    let columns = columns.clamp(1, frames.len() as u32);
    let rows = (frames.len() as u32).div_ceil(columns);
    let cell_w = frames.iter().map(|f| f.width).max().unwrap_or(1);
    let cell_h = frames.iter().map(|f| f.height).max().unwrap_or(1) + CAPTION_H;
    let top = if title.is_empty() { GAP } else { TITLE_H };
    let width = columns * cell_w + (columns + 1) * GAP;
    let height = top + rows * cell_h + rows * GAP;
    let mut pixels = vec![255u8; (width * height * 3) as usize];
    // Frames, copied into their cells.
    for (i, f) in frames.iter().enumerate() {
        let (cx, cy) = (i as u32 % columns, i as u32 / columns);
        let (x0, y0) = (GAP + cx * (cell_w + GAP), top + cy * (cell_h + GAP));
        for y in 0..f.height {
            let src = &f.rgb[(y * f.width * 3) as usize..((y + 1) * f.width * 3) as usize];
            let at = (((y0 + y) * width + x0) * 3) as usize;
            pixels[at..at + src.len()].copy_from_slice(src);
        }
    }
    // Text.
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT_BYTES)
        .map_err(|_| "the bundled font could not be parsed")?;
    {
        let root = BitMapBackend::with_buffer(&mut pixels, (width, height)).into_drawing_area();
        let ink = RGBColor(20, 20, 20);
        if !title.is_empty() {
            root.draw(&Text::new(
                title.as_str(),
                (GAP as i32, 10),
                ("sans-serif", 20).into_font().color(&ink),
            ))?;
        }
        for (i, f) in frames.iter().enumerate() {
            let (cx, cy) = (i as u32 % columns, i as u32 / columns);
            let (x0, y0) = (GAP + cx * (cell_w + GAP), top + cy * (cell_h + GAP));
            root.draw(&Text::new(
                f.caption.as_str(),
                (x0 as i32 + 2, (y0 + f.height) as i32 + 5),
                ("sans-serif", 14).into_font().color(&ink),
            ))?;
        }
        root.present()?;
    }
    let mut enc = png::Encoder::new(BufWriter::new(File::create(&out)?), width, height);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    enc.write_header()?.write_image_data(&pixels)?;
    println!(
        "{} ({width}×{height}, {} frames)",
        out.display(),
        frames.len()
    );
    Ok(())
}
