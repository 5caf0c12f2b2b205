//! `relume info STACK.exr`: what a stack file holds — its size, layers listed and stored,
//! tile entries, stored bytes against the dense layout's — as text or JSON.

use std::path::Path;

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
    }
    Ok(())
}
