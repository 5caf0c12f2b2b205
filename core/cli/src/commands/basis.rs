//! `relume basis --ns-min A --ns-max B --bases N [--tolerance T]`

use relume_engine::brdf::{BasisConfig, BasisCount, BrdfBasis};
use relume_engine::RelumeError;

#[derive(clap::Args)]
pub struct Args {
    #[arg(long, default_value_t = 1.0)]
    pub ns_min: f32,
    #[arg(long, default_value_t = 200.0)]
    pub ns_max: f32,
    /// N_b, including the diffuse basis.
    #[arg(long, default_value_t = 6)]
    pub bases: u32,
    /// Pick the smallest N_b whose worst lobe error is at most this (overrides --bases).
    #[arg(long)]
    pub tolerance: Option<f32>,
    /// Specular lobes sampled over the range.
    #[arg(long, default_value_t = 200)]
    pub lobes: u32,
    /// (θi, θo, φ) grid, e.g. 30x30x60.
    #[arg(long, default_value = "30x30x60")]
    pub grid: String,
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: Args) -> Result<(), RelumeError> {
    let dims: Vec<u32> = args
        .grid
        .split(['x', 'X'])
        .map(|s| s.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| RelumeError::invalid("--grid", &args.grid))?;
    let [a, b, c] = dims[..] else {
        return Err(RelumeError::invalid(
            "--grid",
            format!("\"{}\" (expected e.g. 30x30x60)", args.grid),
        ));
    };
    let cfg = BasisConfig {
        ns_min: args.ns_min,
        ns_max: args.ns_max,
        lobes: args.lobes,
        grid: [a, b, c],
        count: match args.tolerance {
            Some(t) => BasisCount::Tolerance(t),
            None => BasisCount::Fixed(args.bases),
        },
        ..BasisConfig::default()
    };
    let basis = BrdfBasis::build(&cfg)?;
    let report = basis.error_report();
    if args.json {
        super::print_json(&report);
    } else {
        println!(
            "ns ∈ [{}, {}], {} bases: average relative L2 {:.4} %, max {:.4} % (at ns = {:.1})",
            report.ns_min,
            report.ns_max,
            report.bases,
            report.avg_rel_l2 * 100.0,
            report.max_rel_l2 * 100.0,
            report.worst_ns
        );
        for row in &report.per_count {
            println!(
                "  N_b = {:2}: avg {:.4} %, max {:.4} %",
                row.bases,
                row.avg_rel_l2 * 100.0,
                row.max_rel_l2 * 100.0
            );
        }
    }
    Ok(())
}
