//! `relume`: bake a scene into a transfer stack, relight it, render references, compare
//! images, inspect the BRDF basis, and measure speed — for farms, tests and benchmarks.
//!
//! Every command prints a human summary, or one JSON object on stdout with `--json`.
//! Progress goes to stderr as a bar when stderr is a terminal. Ctrl-C cancels a bake
//! cleanly (no file is written). Errors exit with status 1 and a specific message; a command
//! line that does not parse exits with status 2 (clap's usage-error code).

mod commands;
mod options;
mod progress_bar;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "relume",
    version,
    about = "Bake global illumination once, relight materials in milliseconds"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake a scene file into a transfer stack (one OpenEXR file).
    Bake(commands::bake::Args),
    /// Merge the partial stacks of a farm bake (`bake --partition i/N`) into one stack,
    /// bit-identical to a one-machine bake.
    Merge(commands::merge::Args),
    /// Relight a stack with materials from a JSON file.
    Relight(commands::relight::Args),
    /// Render the same paths as a bake with given materials (true or projected BRDF).
    Reference(commands::reference::Args),
    /// Compare two images: relative L2, RMSE, max abs difference (B is the reference).
    Compare(commands::compare::Args),
    /// Build the BRDF basis and report its reconstruction error.
    Basis(commands::basis::Args),
    /// Bake every preset on the scenes and measure error against time: table and chart.
    Report(commands::report::Args),
    /// What a stack file holds: layers possible and stored, tile entries, stored bytes
    /// against the dense layout's.
    Info {
        stack: std::path::PathBuf,
        #[arg(long)]
        json: bool,
    },
    /// Benchmarks that print figures.
    #[command(subcommand)]
    Bench(commands::bench::Bench),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Bake(a) => commands::bake::run(a),
        Command::Merge(a) => commands::merge::run(a),
        Command::Relight(a) => commands::relight::run(a),
        Command::Reference(a) => commands::reference::run(a),
        Command::Compare(a) => commands::compare::run(a),
        Command::Basis(a) => commands::basis::run(a),
        Command::Report(a) => commands::report::run(a),
        Command::Info { stack, json } => commands::info::run(&stack, json),
        Command::Bench(b) => commands::bench::run(b),
    };
    if let Err(e) = result {
        eprintln!("relume: error: {e}");
        std::process::exit(1);
    }
}
