//! Plain image files (relit images, textures, environments) and the one atomic-write helper
//! that every file Relume writes goes through.
//!
//! - [`write_atomic`]: temp file in the target's directory, fsync, rename. A crash or an
//!   error never leaves a half-written file under the target name, and an existing target
//!   stays untouched until the new file is complete (the stack writer uses it too).
//! - [`write_rgba_exr`] / [`read_rgb_exr`]: scene-linear float images (ZIP, lossless).
//! - [`write_png_srgb`]: 8-bit sRGB previews.
//! - [`compare_rgb`]: the error metrics the tests and the CLI report (relative L2 is the
//!   figure the design's accuracy targets are stated in).

use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use exr::prelude::{self as x, ReadChannels as _, ReadLayers as _, WritableImage as _};

use crate::error::{RelumeError, Result};

/// Sequence number of temp files made by this process, so two writes of the same target
/// from two threads never share a temp file.
static TEMP_SEQ: AtomicU64 = AtomicU64::new(0);

/// The temp file used while writing `path`: `.<name>.tmp-<pid>-<seq>` in the same directory
/// (same file system, so the final rename is atomic; hidden, so file browsers ignore it).
fn temp_path_for(path: &Path) -> Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| {
        RelumeError::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "the path names no file"),
        )
    })?;
    let seq = TEMP_SEQ.fetch_add(1, Ordering::Relaxed);
    let tmp_name = format!(
        ".{}.tmp-{}-{}",
        name.to_string_lossy(),
        std::process::id(),
        seq
    );
    Ok(match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.join(tmp_name),
        _ => PathBuf::from(tmp_name),
    })
}

/// Whether process `pid` is still running: `/proc/<pid>` exists (Linux). Elsewhere every
/// process counts as alive, so no temp file is ever removed by mistake.
fn process_alive(pid: u32) -> bool {
    if !Path::new("/proc/self").exists() {
        return true;
    }
    Path::new(&format!("/proc/{pid}")).exists()
}

/// Removes the temp files a killed writer of `path` left behind (`.<name>.tmp-<pid>-<seq>`
/// whose `pid` is no longer running). Best effort: a file that cannot be removed stays.
/// Returns how many were removed.
pub fn remove_stale_temp_files(path: &Path) -> usize {
    let Some(name) = path.file_name() else {
        return 0;
    };
    let prefix = format!(".{}.tmp-", name.to_string_lossy());
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Ok(entries) = fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let file_name = file_name.to_string_lossy();
        let Some(rest) = file_name.strip_prefix(&prefix) else {
            continue;
        };
        let Some(pid) = rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if pid != std::process::id() && !process_alive(pid) && fs::remove_file(entry.path()).is_ok()
        {
            removed += 1;
        }
    }
    removed
}

/// Writes a file atomically and returns its size in bytes.
///
/// `write` fills a buffered temp file in the target's directory; the temp file is then
/// flushed, fsynced and renamed over `path` (and the directory fsynced, best effort, so the
/// rename itself survives a power cut). On any error — from `write`, the flush, the fsync or
/// the rename — the temp file is removed and an existing `path` is left as it was.
/// A missing or read-only directory gives [`RelumeError::Io`] naming `path`.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<u64>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<()>,
{
    write_atomic_checked(path, write, || Ok(()))
}

/// [`write_atomic`] with `before_rename` asked last, after the data is on disk and before
/// the rename: an error from it (a cancel, say) removes the temp file and leaves `path` as
/// it was. Stale temp files of dead writers of `path` are removed first
/// ([`remove_stale_temp_files`]). An existing `path` that is not a regular file (a device,
/// FIFO, socket or directory) is refused before anything is written
/// ([`crate::output_path::refuse_non_regular_output`]).
pub fn write_atomic_checked<F, C>(path: &Path, write: F, before_rename: C) -> Result<u64>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<()>,
    C: FnOnce() -> Result<()>,
{
    // The rename would replace a device, FIFO or socket with a regular file: refused.
    crate::output_path::refuse_non_regular_output(path)?;
    remove_stale_temp_files(path);
    let tmp = temp_path_for(path)?;
    let file = OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(&tmp)
        .map_err(|e| RelumeError::io(path, e))?;
    let result = (|| -> Result<u64> {
        // 1 MiB buffer: exr and png issue many small writes; fewer syscalls.
        let mut w = BufWriter::with_capacity(1 << 20, file);
        write(&mut w)?;
        w.flush().map_err(|e| RelumeError::io(path, e))?;
        let file = w
            .into_inner()
            .map_err(|e| RelumeError::io(path, e.into_error()))?;
        file.sync_all().map_err(|e| RelumeError::io(path, e))?;
        let bytes = file.metadata().map_err(|e| RelumeError::io(path, e))?.len();
        drop(file);
        before_rename()?;
        fs::rename(&tmp, path).map_err(|e| RelumeError::io(path, e))?;
        Ok(bytes)
    })();
    match result {
        Ok(bytes) => {
            #[cfg(unix)]
            if let Some(dir) = path.parent() {
                let dir = if dir.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    dir
                };
                if let Ok(d) = File::open(dir) {
                    let _ = d.sync_all();
                }
            }
            Ok(bytes)
        }
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            Err(e)
        }
    }
}

fn image_err(path: &Path, message: impl Into<String>) -> RelumeError {
    RelumeError::Image {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Checks that `data` holds `width × height × channels` values and returns the pixel count.
fn check_len(path: &Path, width: u32, height: u32, channels: usize, len: usize) -> Result<usize> {
    if width == 0 || height == 0 {
        return Err(image_err(path, format!("size {width}×{height} is empty")));
    }
    let pixels = width as usize * height as usize;
    if len != pixels * channels {
        return Err(image_err(
            path,
            format!(
                "{len} values given for {width}×{height} pixels × {channels} channels (expected {})",
                pixels * channels
            ),
        ));
    }
    Ok(pixels)
}

/// Writes a scene-linear RGBA image (`rgba` interleaved, rows top to bottom) as an f32
/// OpenEXR, one part, scanlines, ZIP (lossless), atomically. Values are stored as given,
/// non-finite ones included (an image writer does not judge its pixels).
pub fn write_rgba_exr(path: &Path, width: u32, height: u32, rgba: &[f32]) -> Result<()> {
    let pixels = check_len(path, width, height, 4, rgba.len())?;
    let channel = |name: &str, c: usize| {
        let v: Vec<f32> = (0..pixels).map(|p| rgba[p * 4 + c]).collect();
        x::AnyChannel::new(name, x::FlatSamples::F32(v))
    };
    let channels = x::AnyChannels::sort(x::SmallVec::from_vec(vec![
        channel("R", 0),
        channel("G", 1),
        channel("B", 2),
        channel("A", 3),
    ]));
    let layer = x::Layer::new(
        (width as usize, height as usize),
        x::LayerAttributes::default(),
        x::Encoding {
            compression: x::Compression::ZIP16,
            blocks: x::Blocks::ScanLines,
            line_order: x::LineOrder::Increasing,
        },
        channels,
    );
    let image = x::Image::from_layer(layer);
    write_atomic(path, |w| {
        image
            .write()
            .to_buffered(w)
            .map_err(|e| image_err(path, format!("OpenEXR write failed: {e}")))
    })?;
    Ok(())
}

/// Reads an OpenEXR image as scene-linear RGB (interleaved f32, rows top to bottom) and
/// returns `(width, height, rgb)`; the size is that of the chosen part's data window.
///
/// Channels are grouped by their prefix (everything before the last `.`, so Blender's
/// `ViewLayer.Combined.R` belongs to `ViewLayer.Combined`). The first group with R, G and B
/// is used — the unprefixed group first, then the others in the file's (sorted) order, part
/// by part; failing that, the first group with a `Y` channel, copied to R, G and B.
/// A missing or unreadable file gives [`RelumeError::Io`]; anything else
/// [`RelumeError::Image`] naming the path and the problem.
pub fn read_rgb_exr(path: &Path) -> Result<(u32, u32, Vec<f32>)> {
    let file = File::open(path).map_err(|e| RelumeError::io(path, e))?;
    let image = x::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::BufReader::new(file))
        .map_err(|e| match e {
            x::Error::Io(io) => RelumeError::io(path, io),
            other => image_err(path, format!("not a readable OpenEXR image: {other}")),
        })?;

    // (part, prefix) groups: find R,G,B first, then Y.
    let split = |name: &str| -> (String, String) {
        match name.rfind('.') {
            Some(i) => (name[..i].to_string(), name[i + 1..].to_string()),
            None => (String::new(), name.to_string()),
        }
    };
    for want_rgb in [true, false] {
        for layer in &image.layer_data {
            let mut prefixes: Vec<String> = layer
                .channel_data
                .list
                .iter()
                .map(|c| split(&c.name.to_string()).0)
                .collect();
            prefixes.sort();
            prefixes.dedup(); // "" sorts first: the unprefixed group wins
            for prefix in prefixes {
                let find = |suffix: &str| {
                    layer.channel_data.list.iter().find(|c| {
                        let (p, s) = split(&c.name.to_string());
                        p == prefix && s == suffix
                    })
                };
                let picked: Option<[&x::AnyChannel<x::FlatSamples>; 3]> = if want_rgb {
                    match (find("R"), find("G"), find("B")) {
                        (Some(r), Some(g), Some(b)) => Some([r, g, b]),
                        _ => None,
                    }
                } else {
                    find("Y").map(|y| [y, y, y])
                };
                let Some(chs) = picked else { continue };
                let (w, h) = (layer.size.width(), layer.size.height());
                let n = w * h;
                let cols: Vec<Vec<f32>> = chs
                    .iter()
                    .map(|c| c.sample_data.values_as_f32().collect())
                    .collect();
                if cols.iter().any(|c| c.len() != n) {
                    return Err(image_err(
                        path,
                        "a channel has a sample count other than width × height",
                    ));
                }
                let rgb: Vec<f32> = cols[0]
                    .iter()
                    .zip(&cols[1])
                    .zip(&cols[2])
                    .flat_map(|((&r, &g), &b)| [r, g, b])
                    .collect();
                return Ok((w as u32, h as u32, rgb));
            }
        }
    }
    let names: Vec<String> = image
        .layer_data
        .iter()
        .flat_map(|l| l.channel_data.list.iter().map(|c| c.name.to_string()))
        .collect();
    Err(image_err(
        path,
        format!(
            "no layer has R, G, B or Y channels (channels: {})",
            names.join(", ")
        ),
    ))
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1): linear below 0.0031308
/// (slope 12.92), else 1.055·v^(1/2.4) − 0.055. Input clamped to [0, 1]; NaN gives 0.
#[inline]
pub fn srgb_oetf(v: f32) -> f32 {
    if v.is_nan() || v <= 0.0 {
        return 0.0;
    }
    if v >= 1.0 {
        return 1.0; // the formula gives 0.99999994 in f32
    }
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes scene-linear RGBA as an 8-bit sRGB PNG (RGBA, sRGB chunk set), atomically.
/// RGB is multiplied by 2^`exposure`, clamped to [0, 1] and sRGB-encoded; alpha is clamped
/// and stored linearly (PNG alpha is never gamma-encoded). NaN becomes 0, +∞ full white.
pub fn write_png_srgb(
    path: &Path,
    width: u32,
    height: u32,
    rgba: &[f32],
    exposure: f32,
) -> Result<()> {
    check_len(path, width, height, 4, rgba.len())?;
    if !exposure.is_finite() {
        return Err(RelumeError::invalid(
            "exposure",
            format!("{exposure} is not finite"),
        ));
    }
    let gain = exposure.exp2();
    let to_u8 = |v: f32| (v * 255.0 + 0.5) as u8; // v in [0, 1]
    let bytes: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|p| {
            let a = if p[3].is_nan() {
                0.0
            } else {
                p[3].clamp(0.0, 1.0)
            };
            [
                to_u8(srgb_oetf(p[0] * gain)),
                to_u8(srgb_oetf(p[1] * gain)),
                to_u8(srgb_oetf(p[2] * gain)),
                to_u8(a),
            ]
        })
        .collect();
    write_atomic(path, |w| {
        let png_err = |e: png::EncodingError| image_err(path, format!("PNG write failed: {e}"));
        let mut enc = png::Encoder::new(w, width, height);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = enc.write_header().map_err(png_err)?;
        writer.write_image_data(&bytes).map_err(png_err)?;
        writer.finish().map_err(png_err)
    })?;
    Ok(())
}

/// Differences between an image and a reference, over the RGB channels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageDiff {
    /// ‖a − b‖₂ / ‖b‖₂ (b the reference); 0 when both are zero, +∞ when only b is.
    pub rel_l2: f64,
    /// Root mean square of a − b over all RGB values.
    pub rmse: f64,
    /// Largest |a − b| of any RGB value.
    pub max_abs: f64,
    /// Number of pixels compared.
    pub pixels: u64,
}

/// Compares image `a` against the reference `b`, both interleaved with `channels` values per
/// pixel (3 = RGB, 4 = RGBA whose alpha is ignored). Sums are in f64, so a 4096² image loses
/// nothing to rounding. Errors: another channel count, different or partial lengths, or a
/// non-finite value (named by image, pixel and channel).
pub fn compare_rgb(a: &[f32], b: &[f32], channels: usize) -> Result<ImageDiff> {
    if channels != 3 && channels != 4 {
        return Err(RelumeError::invalid(
            "image comparison",
            format!("{channels} channels per pixel; expected 3 (RGB) or 4 (RGBA)"),
        ));
    }
    if a.len() != b.len() {
        return Err(RelumeError::invalid(
            "image comparison",
            format!(
                "sizes differ: {} values against {} in the reference",
                a.len(),
                b.len()
            ),
        ));
    }
    if !a.len().is_multiple_of(channels) {
        return Err(RelumeError::invalid(
            "image comparison",
            format!(
                "{} values is not a whole number of {channels}-channel pixels",
                a.len()
            ),
        ));
    }
    let (mut d2, mut b2, mut max_abs) = (0.0f64, 0.0f64, 0.0f64);
    for (i, (pa, pb)) in a
        .chunks_exact(channels)
        .zip(b.chunks_exact(channels))
        .enumerate()
    {
        for c in 0..3 {
            for (img, v) in [("image", pa[c]), ("reference", pb[c])] {
                if !v.is_finite() {
                    return Err(RelumeError::NonFinite {
                        what: format!("{img} being compared, pixel {i}, channel {c} ({v})"),
                    });
                }
            }
            let d = pa[c] as f64 - pb[c] as f64;
            d2 += d * d;
            b2 += pb[c] as f64 * pb[c] as f64;
            max_abs = max_abs.max(d.abs());
        }
    }
    let pixels = (a.len() / channels) as u64;
    let rel_l2 = if b2 > 0.0 {
        (d2 / b2).sqrt()
    } else if d2 == 0.0 {
        0.0
    } else {
        f64::INFINITY
    };
    let rmse = if pixels > 0 {
        (d2 / (pixels as f64 * 3.0)).sqrt()
    } else {
        0.0
    };
    Ok(ImageDiff {
        rel_l2,
        rmse,
        max_abs,
        pixels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every writer goes through `write_atomic`, which asks the same rule: a FIFO stays a
    /// FIFO and nothing is written.
    #[cfg(unix)]
    #[test]
    fn the_atomic_write_refuses_a_fifo_and_leaves_it() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let mut called = false;
        let e = write_atomic(&fifo, |_| {
            called = true;
            Ok(())
        })
        .unwrap_err();
        assert!(e.to_string().contains("is a FIFO (named pipe)"), "{e}");
        assert!(!called, "refused before writing");
        let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
        assert!(kind.is_fifo());
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no temp file"
        );
    }
}
