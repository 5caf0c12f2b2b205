//! `relume bake SCENE -o STACK.exr`

use std::path::PathBuf;

use relume_engine::bake::bake;
use relume_engine::scene::file::load_scene;
use relume_engine::stack::exr_file::write_stack;
use relume_engine::RelumeError;
use serde_json::json;

use crate::options::BakeOptions;
use crate::progress_bar::with_progress;

#[derive(clap::Args)]
pub struct Args {
    /// Scene file (relume-scene JSON).
    pub scene: PathBuf,
    /// Output stack (OpenEXR). Written atomically, only when the bake completes.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub options: BakeOptions,
    /// Print one JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    let scene = load_scene(&args.scene)?;
    let settings = args.options.settings()?;
    let (stack, report) = with_progress("baking", move |p| bake(&scene, &settings, &p))?;
    let t = std::time::Instant::now();
    let bytes = write_stack(&args.output, &stack)?;
    let write_seconds = t.elapsed().as_secs_f64();
    if args.json {
        super::print_json(&json!({
            "command": "bake",
            "output": args.output,
            "file_bytes": bytes,
            "write_seconds": write_seconds,
            "layers": stack.layers.len(),
            "report": report,
        }));
    } else {
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
        println!(
            "baked {}×{} in {:.2} s ({:.2} Mrays/s): {} layers ({} grey, {} RGB, {} empty dropped), {:.1} MB → {}",
            report.width,
            report.height,
            report.seconds,
            report.rays_per_second / 1e6,
            stack.layers.len(),
            report.layers_grey,
            report.layers_rgb,
            report.layers_empty,
            bytes as f64 / 1e6,
            args.output.display()
        );
    }
    Ok(())
}
