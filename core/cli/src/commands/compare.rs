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
    #[arg(long)]
    pub json: bool,
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
    let d = compare_rgb(&a, &b, 3)?;
    if args.json {
        super::print_json(
            &json!({"command": "compare", "rel_l2": d.rel_l2, "rmse": d.rmse, "max_abs": d.max_abs, "pixels": d.pixels}),
        );
    } else {
        println!(
            "relative L2 {:.6} %, RMSE {:.6e}, max abs {:.6e} over {} pixels",
            d.rel_l2 * 100.0,
            d.rmse,
            d.max_abs,
            d.pixels
        );
    }
    Ok(())
}
