//! `relume bake SCENE -o STACK.exr`

use std::path::PathBuf;

use relume_engine::bake::to_file::{bake_to_file, BakedFile};
use relume_engine::scene::file::load_scene;
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
    /// Bake progressively in this many passes of doubling samples, ending at --spp: after
    /// each pass the output is a complete, usable stack (replaced atomically).
    #[arg(long, default_value_t = 1)]
    pub passes: u32,
    /// Print one JSON summary on stdout.
    #[arg(long)]
    pub json: bool,
    /// Print the bake's memory forecast (layers reached by a probe trace, peak and stack
    /// bytes, the budget) and exit without baking.
    #[arg(long)]
    pub estimate_only: bool,
    /// Farm: bake only eye samples [i·spp/N, (i+1)·spp/N) and write a partial stack (sums,
    /// not averages) for `relume merge` (docs/farm.md).
    #[arg(long, value_name = "i/N", conflicts_with_all = ["guide_only", "passes"])]
    pub partition: Option<String>,
    /// Farm: run only the guide pass and write it (the task the partitions depend on).
    #[arg(long, conflicts_with = "passes")]
    pub guide_only: bool,
    /// Farm: the guide file of `--guide-only` for a `--partition` of a guided bake.
    #[arg(long, requires = "partition")]
    pub guide: Option<PathBuf>,
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    let mut inputs: Vec<(&std::path::Path, &str)> = vec![(&args.scene, "the scene")];
    if let Some(g) = &args.guide {
        inputs.push((g, "the guide file"));
    }
    relume_engine::output_path::check_outputs(&[(&args.output, "the output")], &inputs)?;
    let scene = load_scene(&args.scene)?;
    let rss_before_bake = relume_engine::memory::current_rss_bytes();
    let settings = args.options.settings(scene.resolution)?;
    if args.estimate_only {
        let budget = relume_engine::memory::budget_bytes(settings.memory_budget);
        let passes = args.passes as usize;
        // Under the same Ctrl-C handler as a bake: the forecast stops within an eye sample.
        let estimate = with_progress("estimating", move |p| {
            relume_engine::bake::prepare::estimate::estimate_bake(&scene, &settings, passes, &p)
        })?;
        super::print_json(&json!({
            "command": "bake --estimate-only",
            "estimate": estimate,
            "budget_bytes": budget,
            "fits": budget.is_none_or(|b| estimate.peak_bytes <= b),
        }));
        return Ok(());
    }
    if args.guide_only {
        return super::farm::guide_only(scene, settings, &args.output, args.json);
    }
    if let Some(p) = &args.partition {
        let guide = args.guide.clone();
        return super::farm::partition(
            scene,
            args.scene.clone(),
            settings,
            p,
            guide,
            &args.output,
            args.json,
        );
    }
    let output = args.output.clone();
    let quiet = args.json;
    let passes = args.passes;
    let baked = with_progress("baking", move |p| {
        bake_to_file(&scene, &settings, passes, &output, &p, |pass, _| {
            if !quiet && pass.estimated_rel_error.is_some() {
                eprintln!(
                    "pass {}: {} spp at {:.1} s, estimated noise {:.3} % → {}",
                    pass.pass,
                    pass.spp,
                    pass.seconds,
                    pass.estimated_rel_error.unwrap_or(0.0) * 100.0,
                    output.display()
                );
            }
        })
    })?;
    let BakedFile {
        stack,
        report,
        passes: pass_reports,
        file_bytes: bytes,
        write_seconds,
        ..
    } = baked;
    if args.json {
        super::print_json(&json!({
            "command": "bake",
            "output": args.output,
            "file_bytes": bytes,
            "write_seconds": write_seconds,
            "layers": stack.layers.len(),
            "passes": pass_reports,
            "report": report,
            "rss_before_bake_bytes": rss_before_bake,
            "peak_rss_bytes": relume_engine::memory::peak_rss_bytes(),
        }));
    } else {
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
        if let Some(e) = &report.estimate {
            eprintln!(
                "estimate before the bake: {} of {} possible layers, peak {}, stack {}",
                e.layers_reached,
                e.layers_possible,
                relume_engine::memory::human_bytes(e.peak_bytes),
                relume_engine::memory::human_bytes(e.stack_bytes)
            );
            for r in &e.editable {
                eprintln!(
                    "  editable \"{}\": ns [{:.3}, {:.0}] (roughness [{:.2}, {:.2}]) → {} bases, {} slots (worst lobe {:.2} %)",
                    r.region,
                    r.ns_range[0],
                    r.ns_range[1],
                    r.roughness_range[0],
                    r.roughness_range[1],
                    r.bases,
                    r.slots,
                    r.max_rel_l2 * 100.0
                );
            }
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
