//! `relume merge PART_0 … PART_N-1 -o STACK`: the last task of a farm bake. Checks that the
//! partial stacks belong to one bake and cover its samples once, reads them side by side tile
//! by tile, sums each tile in the bake's canonical order, finalises with the one-machine
//! bake's streaming finish (average, grey detection, denoiser, layer dropping, header) and
//! writes the stack atomically with its writer: the file is the one-machine bake's, byte for
//! byte (docs/farm.md).
//! Its peak memory is forecast from the parts' headers and held to `--memory-budget-mb`
//! before any part's body is read, as a bake's is.

use std::path::PathBuf;

use relume_engine::bake::farm::partial::read_partial_header;
use relume_engine::bake::farm::partition::merge_files;
use relume_engine::scene::file::load_scene;
use relume_engine::stack::tiled::file::write_tiled_cancellable;
use relume_engine::RelumeError;
use serde_json::json;

use crate::progress_bar::with_progress;

#[derive(clap::Args)]
pub struct Args {
    /// The partial stacks (`relume bake --partition i/N` outputs), in any order.
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// Output stack (OpenEXR), written atomically.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The scene file [default: the one the partitions read, as recorded in the parts].
    /// Its hash must be the parts'.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Worker threads (0: all cores); the result does not depend on it.
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Memory the merge may plan to use at its peak, in MiB; a merge whose forecast (from
    /// the parts' headers) exceeds it is refused before any part is read [default: 80 % of
    /// the available memory].
    #[arg(long)]
    pub memory_budget_mb: Option<f64>,
    /// Print one JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    use relume_engine::output_path::check_outputs;
    let output = [(args.output.as_path(), "the output")];
    let mut inputs: Vec<(&std::path::Path, &str)> = args
        .parts
        .iter()
        .map(|p| (p.as_path(), "a partial stack"))
        .collect();
    if let Some(s) = &args.scene {
        inputs.push((s, "the scene"));
    }
    // The parts first (before any is read), then the scene files they record.
    check_outputs(&output, &inputs)?;
    let budget = crate::options::budget_from_mib(args.memory_budget_mb)?;
    let headers = args
        .parts
        .iter()
        .map(|p| read_partial_header(p))
        .collect::<Result<Vec<_>, _>>()?;
    let recorded: Vec<(&std::path::Path, &str)> = headers
        .iter()
        .filter_map(|h| h.scene_path.as_deref())
        .map(|p| (p, "the scene recorded in the partial stacks"))
        .collect();
    check_outputs(&output, &recorded)?;
    let scene_path = match (&args.scene, headers.first()) {
        (Some(s), _) => s.clone(),
        (None, Some(header)) => header.scene_path.clone().ok_or_else(|| {
            RelumeError::invalid("--scene", "the parts record no scene file: give --scene")
        })?,
        (None, None) => return Err(RelumeError::invalid("partial stacks", "none given")),
    };
    let scene = load_scene(&scene_path)?;
    let output = args.output.clone();
    let threads = args.threads;
    let count = args.parts.len();
    let paths = args.parts.clone();
    let (stack, report, bytes) = with_progress("merging", move |p| {
        let (stack, report) = merge_files(&scene, &paths, threads, budget, &p)?;
        let bytes = write_tiled_cancellable(&output, &stack, &p)?;
        Ok::<_, RelumeError>((stack, report, bytes))
    })?;
    if args.json {
        super::print_json(&json!({
            "command": "merge",
            "output": args.output,
            "parts": count,
            "file_bytes": bytes,
            "layers": stack.layers.len(),
            "spp": stack.header.spp,
            "merge_seconds": report.seconds,
            "report": report,
        }));
    } else {
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
        println!(
            "merged {count} parts: {} spp, {} layers ({} grey, {} RGB), merge {:.2} s, {:.1} MB → {}",
            stack.header.spp,
            stack.layers.len(),
            report.layers_grey,
            report.layers_rgb,
            report.seconds,
            bytes as f64 / 1e6,
            args.output.display()
        );
    }
    Ok(())
}
