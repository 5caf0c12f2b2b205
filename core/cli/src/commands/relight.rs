//! `relume relight STACK.exr --materials M.json -o OUT.exr`

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use relume_engine::image_io::{write_png_srgb, write_rgba_exr};
use relume_engine::materials::{load_materials, resolve_materials, MaterialsFile};
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{file::load_scene, hash::scene_hash};
use relume_engine::stack::{
    bases::StackBases,
    exr_file::{check_scene_hash, read_stack},
};
use relume_engine::RelumeError;
use serde_json::json;

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum Device {
    Cpu,
}

#[derive(clap::Args)]
pub struct Args {
    /// Transfer stack written by `relume bake`.
    pub stack: PathBuf,
    /// Materials JSON (relume-materials); regions not named keep their bake-time material.
    #[arg(long)]
    pub materials: Option<PathBuf>,
    /// Output image (OpenEXR, RGBA f32).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write an 8-bit sRGB PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Exposure (stops) for the PNG.
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
    /// Refuse the stack if it was baked from another version of this scene.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Relight device (the GPU relight is a separate issue).
    #[arg(long, value_enum, default_value = "cpu")]
    pub device: Device,
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    let t = Instant::now();
    let stack = read_stack(&args.stack)?;
    let load_seconds = t.elapsed().as_secs_f64();
    if let Some(scene_path) = &args.scene {
        check_scene_hash(&stack.header, &scene_hash(&load_scene(scene_path)?))?;
    }
    let edits = match &args.materials {
        Some(p) => load_materials(p)?,
        None => MaterialsFile::default(),
    };
    let materials = resolve_materials(&stack.header.regions, &edits)?;
    let bases = StackBases::from_header(&stack.header)?;
    let coefs = bases.coefficients(&materials)?;
    let (width, height) = (stack.header.width, stack.header.height);
    let mut relighter = CpuRelighter::new(Arc::new(stack))?;
    let t = Instant::now();
    let image = relighter.relight(&coefs)?.to_vec();
    let relight_ms = t.elapsed().as_secs_f64() * 1e3;
    write_rgba_exr(&args.output, width, height, &image)?;
    if let Some(png) = &args.png {
        write_png_srgb(png, width, height, &image, args.exposure)?;
    }
    if args.json {
        super::print_json(&json!({
            "command": "relight",
            "device": "cpu",
            "output": args.output,
            "width": width,
            "height": height,
            "load_seconds": load_seconds,
            "relight_ms": relight_ms,
        }));
    } else {
        println!(
            "relit {width}×{height} on the CPU in {relight_ms:.2} ms → {}",
            args.output.display()
        );
    }
    Ok(())
}
