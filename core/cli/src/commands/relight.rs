//! `relume relight STACK.exr --materials M.json -o OUT.exr`

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use relume_denoise::oidn::{DeviceChoice, LibrarySearch};
use relume_denoise::{DenoiseMode, DenoiseReport, FeatureImages, ShownImage};
use relume_engine::features::{albedo_of, PixelFeatures, FEATURE_SAMPLES_PER_AXIS};
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

/// `--denoise`: what is done to the relit image before it is written.
#[derive(Clone, Copy, clap::ValueEnum)]
pub enum Denoise {
    Oidn,
    Linear,
    None,
}

impl Denoise {
    pub fn mode(self) -> DenoiseMode {
        match self {
            Denoise::Oidn => DenoiseMode::Oidn,
            Denoise::Linear => DenoiseMode::Linear,
            Denoise::None => DenoiseMode::None,
        }
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
    /// What is written: oidn (the relit image through OpenImageDenoise, with albedo and
    /// normal features when --scene is given; the linear image, with a note, when OIDN is
    /// not found: set RELUME_OIDN_LIBRARY to its file or folder), linear (the relit image of
    /// the stack's bake-time-denoised layers) or none (the relit image as summed).
    #[arg(long, value_enum, default_value = "oidn")]
    pub denoise: Denoise,
    /// Seconds of refinement after the relight (needs --scene): bounces past the second
    /// vertex traced again with the edited materials and the difference added (lobe-shape
    /// edits, regions edited together; nothing to do for one-bounce stacks or the bake-time
    /// materials). 0: the relit image as it is.
    #[arg(long, default_value_t = 0.0)]
    pub refine: f64,
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
    let start = Instant::now();
    let stack = read_tiled(&args.stack)?;
    let load_seconds = start.elapsed().as_secs_f64();
    let scene = match &args.scene {
        Some(scene_path) => {
            let scene = load_scene(scene_path)?;
            check_scene_hash(&stack.header, &scene_hash(&scene))?;
            Some(scene)
        }
        None => None,
    };
    let edits = match &args.materials {
        Some(p) => load_materials(p)?,
        None => MaterialsFile::default(),
    };
    let materials = resolve_materials(&stack.header.regions, &edits)?;
    let gains = resolve_light_gains(&stack.header, &edits)?;
    let t = Instant::now();
    let bases = StackBases::from_header(&stack.header)?;
    let coefs = bases.coefficients(&materials)?;
    let bases_seconds = t.elapsed().as_secs_f64();
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
    let header = (args.refine > 0.0).then(|| stack.header.clone());
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
    // From opening the stack to the first relit image: what a user waits for after a load.
    let first_image_seconds = start.elapsed().as_secs_f64();
    // An image with inf or NaN pixels is refused, not written as if it were right.
    relume_engine::relight::check_finite_image(&image, width)?;
    let refine = match header {
        Some(header) => Some(refine(
            &mut image,
            &header,
            scene.as_ref(),
            &materials,
            gains.as_deref(),
            args.refine,
        )?),
        None => None,
    };
    if let Some(r) = &refine {
        eprintln!("{}", r.summary());
    }
    let (shown, denoise) = shown_image(
        &image,
        (width, height),
        args.denoise.mode(),
        scene.as_ref(),
        &materials,
    )?;
    if denoise.ran != denoise.asked {
        eprintln!("note: {}", denoise.summary());
    }
    write_rgba_exr(&args.output, width, height, &shown)?;
    if let Some(png) = &args.png {
        write_png_srgb(png, width, height, &shown, args.exposure)?;
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
            "bases_seconds": bases_seconds,
            "relight_ms": relight_ms,
            "first_image_seconds": first_image_seconds,
            "denoise": denoise_json(&denoise),
            "refine": refine.as_ref().map(|r| json!({
                "needed": r.needed,
                "passes": r.passes,
                "bake_samples": r.bake_samples,
                "setup_seconds": r.setup_seconds,
                "seconds": r.seconds,
            })),
            "warnings": warnings,
        }));
    } else {
        println!(
            "relit {width}×{height} on the {} in {relight_ms:.2} ms, shown: {} → {} ({device_reason})",
            device.to_string().to_uppercase(),
            denoise.summary(),
            args.output.display()
        );
    }
    Ok(())
}

/// What `--refine` did.
struct RefineRun {
    needed: bool,
    passes: u32,
    bake_samples: u32,
    setup_seconds: f64,
    seconds: f64,
}

impl RefineRun {
    fn summary(&self) -> String {
        if self.needed {
            format!(
                "refined: {} passes of the bake's {} samples per pixel in {:.1} s (set-up {:.1} s)",
                self.passes, self.bake_samples, self.seconds, self.setup_seconds
            )
        } else {
            "refined: nothing to refine (one bounce, or the bake-time materials)".into()
        }
    }
}

/// `--refine`: the tail of this edit traced for `seconds` and its correction added to `image`.
fn refine(
    image: &mut [f32],
    header: &relume_engine::stack::StackHeader,
    scene: Option<&relume_engine::scene::Scene>,
    materials: &[relume_engine::brdf::MaterialSpec],
    gains: Option<&[relume_engine::Rgb]>,
    seconds: f64,
) -> Result<RefineRun, RelumeError> {
    let Some(scene) = scene else {
        return Err(RelumeError::invalid(
            "--refine",
            "needs --scene: the refinement traces the scene",
        ));
    };
    if !seconds.is_finite() {
        return Err(RelumeError::invalid(
            "--refine",
            format!("{seconds} seconds"),
        ));
    }
    let t = Instant::now();
    let refiner = relume_engine::refine::TailRefiner::for_stack(scene, header, 0)?;
    let mut r = refiner.start(materials, gains)?;
    let setup_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    if r.is_needed() {
        refiner.refine_for(
            &mut r,
            seconds,
            u32::MAX,
            &relume_engine::progress::Progress::new(),
        )?;
        refiner.add_to(&r, image)?;
        relume_engine::relight::check_finite_image(image, header.width)?;
    }
    Ok(RefineRun {
        needed: r.is_needed(),
        passes: r.passes(),
        bake_samples: refiner.bake_samples(),
        setup_seconds,
        seconds: t.elapsed().as_secs_f64(),
    })
}

/// The image written: the relit one under `mode`, with the scene's pixel features (traced
/// here, the albedo from the current `materials`) when OIDN runs and the scene is given.
pub fn shown_image(
    image: &[f32],
    (width, height): (u32, u32),
    mode: DenoiseMode,
    scene: Option<&relume_engine::scene::Scene>,
    materials: &[relume_engine::brdf::MaterialSpec],
) -> Result<(Vec<f32>, DenoiseReport), RelumeError> {
    let mut shown = ShownImage::new(LibrarySearch::with_dirs(vec![]), DeviceChoice::Default);
    // Features only for an OIDN that is there (tracing them costs primary rays).
    let oidn_ready = mode == DenoiseMode::Oidn && shown.oidn().is_ok();
    let traced = match (oidn_ready, scene) {
        (true, Some(scene)) => {
            let t = Instant::now();
            let f = PixelFeatures::trace(scene, width, height, FEATURE_SAMPLES_PER_AXIS)?;
            let albedo = albedo_of(&f, materials)?;
            Some((f, albedo, t.elapsed().as_secs_f64() * 1e3))
        }
        _ => None,
    };
    let features = match &traced {
        Some((f, albedo, _)) => FeatureImages::Clean {
            albedo,
            normal: f.normal(),
        },
        None => FeatureImages::Missing(
            "pass --scene (the scene file baked) for albedo and normals".into(),
        ),
    };
    let (image, mut report) = shown.show(image, width, height, mode, features)?;
    if let Some((_, _, ms)) = traced {
        report.milliseconds += ms;
    }
    Ok((image.into_owned(), report))
}

/// The report's JSON: asked, ran, note, features, device, library, version, ms.
pub fn denoise_json(r: &DenoiseReport) -> serde_json::Value {
    json!({
        "asked": r.asked.as_str(),
        "ran": r.ran.as_str(),
        "note": r.note,
        "features": r.features,
        "device": r.device,
        "library": r.library,
        "version": r.version,
        "quality": r.quality.map(|q| q.as_str()),
        "negative_values": r.negative_values,
        "ms": r.milliseconds,
        "summary": r.summary(),
    })
}
