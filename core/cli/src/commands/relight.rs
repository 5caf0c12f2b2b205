//! `relume relight STACK.exr --materials M.json -o OUT.exr`

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use relume_engine::image_io::{write_png_srgb, write_rgba_exr};
use relume_engine::materials::{
    load_materials, resolve_light_gains, resolve_materials, MaterialsFile,
};
use relume_engine::scene::{file::load_scene, hash::scene_hash};
use relume_engine::stack::{
    bases::StackBases, exr_file::check_scene_hash, tiled::file::read_tiled,
};
use relume_engine::RelumeError;
use relume_gpu::{DevicePreference, GpuError, Relighter};
use serde_json::json;

/// `--device`: where the relight runs.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum Device {
    /// A real GPU if there is one; the CPU for a software adapter (lavapipe) or none.
    Auto,
    /// The best adapter, software ones included; an error if there is none.
    Gpu,
    /// The CPU loop.
    Cpu,
}

impl Device {
    pub fn preference(self) -> DevicePreference {
        match self {
            Device::Auto => DevicePreference::Auto,
            Device::Gpu => DevicePreference::Gpu,
            Device::Cpu => DevicePreference::Cpu,
        }
    }
}

/// As the command line's error: `--device gpu` failures say that `auto` would fall back.
pub fn device_error(device: Device, e: GpuError) -> RelumeError {
    match (device, e) {
        (_, GpuError::Engine(e)) => e,
        (Device::Gpu, e) => RelumeError::invalid(
            "--device gpu",
            format!("{e}; --device auto falls back to the CPU"),
        ),
        (_, e) => e.into_relume(),
    }
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
    /// Relight device: auto takes a real GPU and otherwise the CPU (the summary says why).
    #[arg(long, value_enum, default_value = "auto")]
    pub device: Device,
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    let mut inputs: Vec<(&std::path::Path, &str)> = vec![(&args.stack, "the stack")];
    if let Some(m) = &args.materials {
        inputs.push((m, "the materials file"));
    }
    if let Some(s) = &args.scene {
        inputs.push((s, "the scene"));
    }
    let mut outputs: Vec<(&std::path::Path, &str)> = vec![(&args.output, "the image")];
    if let Some(p) = &args.png {
        outputs.push((p, "the PNG"));
    }
    relume_engine::output_path::check_outputs(&outputs, &inputs)?;
    let t = Instant::now();
    let stack = read_tiled(&args.stack)?;
    let load_seconds = t.elapsed().as_secs_f64();
    if let Some(scene_path) = &args.scene {
        check_scene_hash(&stack.header, &scene_hash(&load_scene(scene_path)?))?;
    }
    let edits = match &args.materials {
        Some(p) => load_materials(p)?,
        None => MaterialsFile::default(),
    };
    let materials = resolve_materials(&stack.header.regions, &edits)?;
    let gains = resolve_light_gains(&stack.header, &edits)?;
    let bases = StackBases::from_header(&stack.header)?;
    let coefs = bases.coefficients(&materials)?;
    // Exponents outside a region's baked ns range: relit with the nearest one, and said so.
    let editable_names: Vec<&str> = stack
        .header
        .regions
        .iter()
        .filter(|r| r.editable)
        .map(|r| r.name.as_str())
        .collect();
    let warnings: Vec<String> = bases
        .out_of_range(&materials)
        .iter()
        .map(|w| w.message(editable_names.get(w.region).copied().unwrap_or("?")))
        .collect();
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let (width, height) = (stack.header.width, stack.header.height);
    let mut relighter = Relighter::new(Arc::new(stack), args.device.preference())
        .map_err(|e| device_error(args.device, e))?;
    let t = Instant::now();
    let mut image = relighter
        .relight(&coefs)
        .map_err(|e| device_error(args.device, e))?
        .to_vec();
    if let Some(gains) = &gains {
        image = relighter
            .set_light_group_gains(gains)
            .map_err(|e| device_error(args.device, e))?
            .to_vec();
    }
    // After the relight: in auto mode a GPU failure moves it to the CPU.
    let device = relighter.device();
    let device_reason = relighter.device_reason().to_string();
    let relight_ms = t.elapsed().as_secs_f64() * 1e3;
    // An image with inf or NaN pixels is refused, not written as if it were right.
    relume_engine::relight::check_finite_image(&image, width)?;
    write_rgba_exr(&args.output, width, height, &image)?;
    if let Some(png) = &args.png {
        write_png_srgb(png, width, height, &image, args.exposure)?;
    }
    if args.json {
        super::print_json(&json!({
            "command": "relight",
            "device": device.to_string(),
            "device_reason": device_reason,
            "output": args.output,
            "width": width,
            "height": height,
            "load_seconds": load_seconds,
            "relight_ms": relight_ms,
            "warnings": warnings,
        }));
    } else {
        println!(
            "relit {width}×{height} on the {} in {relight_ms:.2} ms → {} ({device_reason})",
            device.to_string().to_uppercase(),
            args.output.display()
        );
    }
    Ok(())
}
