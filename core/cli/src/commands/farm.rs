//! The farm side of `relume bake`: `--guide-only` (the guide pass as a file, the first task
//! of a farm job) and `--partition i/N` (one sample range, written as a partial stack that
//! `relume merge` sums; written tile by tile as it is traced). See docs/farm.md.

use std::path::{Path, PathBuf};

use relume_engine::bake::farm::guide_file::{build_guide, read_guide, write_guide};
use relume_engine::bake::farm::partition::{bake_partition, Partition};
use relume_engine::bake::BakeSettings;
use relume_engine::scene::Scene;
use relume_engine::RelumeError;
use serde_json::json;

use crate::progress_bar::with_progress;

/// `relume bake SCENE --guide-only -o GUIDE`.
pub fn guide_only(
    scene: Scene,
    settings: BakeSettings,
    output: &Path,
    json_out: bool,
) -> Result<(), RelumeError> {
    let start = std::time::Instant::now();
    let out = output.to_path_buf();
    let (bytes, hash, field) = with_progress("guide pass", move |p| {
        let field = build_guide(&scene, &settings, &p)?;
        let (bytes, hash) = write_guide(&out, &scene, &settings, field.as_ref())?;
        Ok::<_, RelumeError>((bytes, hash, field.map(|f| (f.rays, f.coverage()))))
    })?;
    let seconds = start.elapsed().as_secs_f64();
    if json_out {
        super::print_json(&json!({
            "command": "bake --guide-only",
            "output": output,
            "file_bytes": bytes,
            "guide_hash": hash,
            "guided": field.is_some(),
            "rays": field.map(|f| f.0),
            "seconds": seconds,
        }));
    } else {
        match field {
            Some((rays, (used, tiles))) => println!(
                "guide pass in {seconds:.2} s ({rays} rays, trees in {used} of {tiles} tiles), {bytes} bytes → {}",
                output.display()
            ),
            None => println!(
                "these settings do not sample guided: wrote an empty guide ({bytes} bytes) → {}",
                output.display()
            ),
        }
    }
    Ok(())
}

/// `relume bake SCENE --partition i/N [--guide GUIDE] -o PART`.
pub fn partition(
    scene: Scene,
    scene_path: PathBuf,
    settings: BakeSettings,
    partition: &str,
    guide: Option<PathBuf>,
    output: &Path,
    json_out: bool,
) -> Result<(), RelumeError> {
    let part = Partition::parse(partition)?;
    let guide = guide.map(|g| read_guide(&g)).transpose()?;
    let out = output.to_path_buf();
    let (header, warnings, bytes) = with_progress("baking partition", move |p| {
        bake_partition(&scene, Some(&scene_path), &settings, part, guide, &out, &p)
    })?;
    if json_out {
        super::print_json(&json!({
            "command": "bake --partition",
            "output": output,
            "file_bytes": bytes,
            "partition": header.partition,
            "samples": header.samples,
            "spp": header.spp,
            "blocks": header.blocks.len(),
            "layers_reached": header.layers_reached,
            "tile_entries": header.tile_entries,
            "rays": header.rays,
            "seconds": header.seconds,
            "warnings": warnings,
        }));
    } else {
        for w in &warnings {
            eprintln!("warning: {w}");
        }
        println!(
            "partition {}/{}: samples [{}, {}) of {} in {:.2} s, {} block(s), {:.1} MB → {}",
            header.partition[0],
            header.partition[1],
            header.samples[0],
            header.samples[1],
            header.spp,
            header.seconds,
            header.blocks.len(),
            bytes as f64 / 1e6,
            output.display()
        );
    }
    Ok(())
}
