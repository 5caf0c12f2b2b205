//! `relume compare A.exr B.exr`: B is the reference.

use std::path::PathBuf;

use relume_engine::image_io::{compare_rgb, read_rgb_exr};
use relume_engine::RelumeError;
use serde_json::json;

#[derive(clap::Args)]
pub struct Args {
    pub a: PathBuf,
    /// The reference image.
    pub b: PathBuf,
    /// Compare the means of N×N-pixel tiles instead of pixels (the tile error the docs
    /// quote against Cycles: it leaves out most of both images' pixel noise).
    #[arg(long, value_name = "N")]
    pub tiles: Option<u32>,
    #[arg(long)]
    pub json: bool,
}

/// The means of `n`×`n` tiles of an RGB image (partial tiles at the right and bottom edges
/// averaged over the pixels they have).
fn tile_means(rgb: &[f32], width: u32, height: u32, n: u32) -> (u32, u32, Vec<f32>) {
    let (tw, th) = (width.div_ceil(n), height.div_ceil(n));
    let mut sums = vec![0.0f64; (tw * th * 3) as usize];
    let mut counts = vec![0u32; (tw * th) as usize];
    for y in 0..height {
        for x in 0..width {
            let t = ((y / n) * tw + x / n) as usize;
            let p = ((y * width + x) * 3) as usize;
            for c in 0..3 {
                sums[t * 3 + c] += rgb[p + c] as f64;
            }
            counts[t] += 1;
        }
    }
    let means = sums
        .iter()
        .enumerate()
        .map(|(i, s)| (s / counts[i / 3] as f64) as f32)
        .collect();
    (tw, th, means)
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    let (wa, ha, a) = read_rgb_exr(&args.a)?;
    let (wb, hb, b) = read_rgb_exr(&args.b)?;
    if (wa, ha) != (wb, hb) {
        return Err(RelumeError::invalid(
            "compare",
            format!("sizes differ: {wa}×{ha} against {wb}×{hb}"),
        ));
    }
    let (a, b) = match args.tiles {
        Some(0) => return Err(RelumeError::invalid("--tiles", "must be at least 1 pixel")),
        Some(n) => (tile_means(&a, wa, ha, n).2, tile_means(&b, wb, hb, n).2),
        None => (a, b),
    };
    let d = compare_rgb(&a, &b, 3)?;
    // A's mean over B's (all RGB values): how much brighter or darker, apart from the noise.
    let sum = |v: &[f32]| v.iter().map(|x| *x as f64).sum::<f64>();
    let mean_ratio = sum(&a) / sum(&b);
    if args.json {
        super::print_json(&json!({
            "command": "compare",
            "rel_l2": d.rel_l2,
            "rmse": d.rmse,
            "max_abs": d.max_abs,
            "pixels": d.pixels,
            "tiles": args.tiles,
            "mean_ratio": if mean_ratio.is_finite() { Some(mean_ratio) } else { None },
        }));
    } else {
        println!(
            "relative L2 {:.6} %, RMSE {:.6e}, max abs {:.6e}, mean ratio {mean_ratio:.5} over {} {}",
            d.rel_l2 * 100.0,
            d.rmse,
            d.max_abs,
            d.pixels,
            if args.tiles.is_some() { "tiles" } else { "pixels" }
        );
    }
    Ok(())
}
