//! `relume reference SCENE --materials M.json -o REF.exr`

use std::path::PathBuf;

use relume_engine::bake::reference::{render_reference, ReferenceBrdf};
use relume_engine::image_io::{write_png_srgb, write_rgba_exr};
use relume_engine::materials::{load_materials, resolve_materials, MaterialsFile};
use relume_engine::scene::file::load_scene;
use relume_engine::stack::RegionInfo;
use relume_engine::RelumeError;
use serde_json::json;

use crate::options::BakeOptions;
use crate::progress_bar::with_progress;

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum BrdfArg {
    /// The true Blinn–Phong BRDF: relit − reference is the basis error.
    True,
    /// The basis reconstruction: relit − reference is only storage rounding.
    Projected,
}

#[derive(clap::Args)]
pub struct Args {
    pub scene: PathBuf,
    #[arg(long)]
    pub materials: Option<PathBuf>,
    #[arg(short, long)]
    pub output: PathBuf,
    #[arg(long)]
    pub png: Option<PathBuf>,
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f32,
    #[arg(long, value_enum, default_value = "true")]
    pub brdf: BrdfArg,
    #[command(flatten)]
    pub options: BakeOptions,
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    let mut inputs: Vec<(&std::path::Path, &str)> = vec![(&args.scene, "the scene")];
    if let Some(m) = &args.materials {
        inputs.push((m, "the materials file"));
    }
    let mut outputs: Vec<(&std::path::Path, &str)> = vec![(&args.output, "the image")];
    if let Some(p) = &args.png {
        outputs.push((p, "the PNG"));
    }
    relume_engine::output_path::check_outputs(&outputs, &inputs)?;
    let scene = load_scene(&args.scene)?;
    let settings = args.options.settings(scene.resolution)?;
    let edits = match &args.materials {
        Some(p) => load_materials(p)?,
        None => MaterialsFile::default(),
    };
    let infos: Vec<RegionInfo> = scene
        .regions
        .iter()
        .map(|r| RegionInfo::from_region(r, None))
        .collect();
    let materials: Vec<_> = resolve_materials(&infos, &edits)?
        .iter()
        .map(|m| m.to_blinn_phong())
        .collect();
    let brdf = match args.brdf {
        BrdfArg::True => ReferenceBrdf::True,
        BrdfArg::Projected => ReferenceBrdf::Projected,
    };
    let t = std::time::Instant::now();
    let image = with_progress("reference", move |p| {
        render_reference(&scene, &settings, &materials, brdf, &p)
    })?;
    let seconds = t.elapsed().as_secs_f64();
    write_rgba_exr(&args.output, image.width, image.height, &image.rgba)?;
    if let Some(png) = &args.png {
        write_png_srgb(png, image.width, image.height, &image.rgba, args.exposure)?;
    }
    if args.json {
        super::print_json(
            &json!({"command": "reference", "output": args.output, "seconds": seconds, "width": image.width, "height": image.height}),
        );
    } else {
        println!(
            "reference {}×{} in {seconds:.2} s → {}",
            image.width,
            image.height,
            args.output.display()
        );
    }
    Ok(())
}
