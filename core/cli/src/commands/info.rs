//! `relume info STACK.exr`: what a stack file holds — its size, layers listed and stored,
//! tile entries, stored bytes against the dense layout's, and what its tail-edit layers
//! cost — as text or JSON.

use std::path::Path;

use relume_engine::layer_key::PathVertex;
use relume_engine::stack::tiled::{file::read_tiled, STACK_TILE};
use relume_engine::RelumeError;
use serde_json::json;

/// Reads `path` (format 2 as stored, format 1 converted) and prints its figures.
pub fn run(path: &Path, json_out: bool) -> Result<(), RelumeError> {
    let file_bytes = std::fs::metadata(path)
        .map_err(|e| RelumeError::io(path, e))?
        .len();
    let stack = read_tiled(path)?;
    let h = &stack.header;
    let stored = stack.sample_bytes();
    let dense = stack.dense_sample_bytes();
    // The tail-edit layers (edits reaching bounces past the second vertex): how many are
    // stored and what they cost.
    let layer_bytes = stack.layer_bytes();
    let tail: Vec<usize> = stack
        .layers
        .iter()
        .enumerate()
        .filter(|(_, l)| {
            l.key
                .path
                .iter()
                .any(|v| matches!(v, PathVertex::TailEdit { .. }))
        })
        .map(|(i, _)| i)
        .filter(|&i| layer_bytes[i] > 0)
        .collect();
    let tail_bytes: usize = tail.iter().map(|&i| layer_bytes[i]).sum();
    let figures = json!({
        "command": "info",
        "path": path.display().to_string(),
        "width": h.width,
        "height": h.height,
        "precision": h.precision,
        "tile": STACK_TILE,
        "tiles": stack.tile_count(),
        "layers_possible": stack.layers.len(),
        "layers_stored": stack.stored_layer_count(),
        "tile_entries": stack.entry_count(),
        "stored_bytes": stored,
        "dense_equivalent_bytes": dense,
        "stored_over_dense": stored as f64 / dense.max(1) as f64,
        "memory_bytes": stack.memory_bytes(),
        "file_bytes": file_bytes,
        "editable_regions": h.regions.iter().filter(|r| r.editable).map(|r| &r.name).collect::<Vec<_>>(),
        "light_groups": h.light_groups.iter().map(|g| &g.name).collect::<Vec<_>>(),
        "bounces": h.bounces,
        "refine_bounces": h.refine_bounces(),
        "tail_edit_layers_stored": tail.len(),
        "tail_edit_bytes": tail_bytes,
    });
    if json_out {
        super::print_json(&figures);
    } else {
        println!("{}", path.display());
        println!(
            "  {}×{} px, {:?}, {} tiles of {STACK_TILE}×{STACK_TILE}",
            h.width,
            h.height,
            h.precision,
            stack.tile_count()
        );
        println!(
            "  layers: {} possible, {} stored; {} tile entries",
            stack.layers.len(),
            stack.stored_layer_count(),
            stack.entry_count()
        );
        println!(
            "  stored {:.2} MB of a dense-equivalent {:.2} MB ({:.1} %); in memory {:.2} MB; file {:.2} MB",
            stored as f64 / 1e6,
            dense as f64 / 1e6,
            100.0 * stored as f64 / dense.max(1) as f64,
            stack.memory_bytes() as f64 / 1e6,
            file_bytes as f64 / 1e6
        );
        if h.bounces >= 2 && tail.is_empty() {
            println!(
                "  {} bounces: later vertices with the bake-time materials; no tail-edit \
                 layers, so edits reach only the first two vertices (a stack from an older \
                 build, or with nothing editable)",
                h.bounces
            );
        } else if h.bounces >= 2 {
            println!(
                "  {} bounces: later vertices with the bake-time materials; {} tail-edit layers \
                 carry albedo edits to them ({:.2} MB, {:.1} % of the stored values)",
                h.bounces,
                tail.len(),
                tail_bytes as f64 / 1e6,
                100.0 * tail_bytes as f64 / stored.max(1) as f64
            );
        }
        if h.refine_bounces() > h.bounces {
            println!(
                "  baked {} of a cap of {} bounces (the bounce pre-pass left the rest out at \
                 the bake-time materials); `relight --refine` traces an edit to {}",
                h.bounces,
                h.refine_bounces(),
                h.refine_bounces()
            );
        }
    }
    Ok(())
}
