//! Structural checks of a [`TiledStack`]: the same on write and on read, so that a file the
//! writer accepted always reads back, and so that the relight can index without checks.

use std::collections::HashSet;
use std::path::Path;

use super::layout::{TileValues, TiledStack, STACK_FORMAT_VERSION_TILED};
use crate::error::{RelumeError, Result};

pub(crate) fn format_err(path: &Path, message: impl Into<String>) -> RelumeError {
    RelumeError::StackFormat {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Checks everything the relight and the file rely on; `path` only names the file in
/// errors (empty for a stack in memory). In order: format version, size, unique layer
/// names with 1 or 3 channels and a finite scale > 0, the tile count the size needs, and
/// per tile: values in the header's precision, a lattice (when there is one) of the tile's
/// size, entries with layer ids in range and strictly increasing, 1 or 3 channels, a finite
/// scale > 0, a lattice entry's segments within the tile's lattice, offsets packed back to
/// back from 0 and covering the values exactly, every value finite. (A lattice's own map —
/// ids, step — was checked when it was made: [`super::lattice::TileLattice::new`].)
pub fn validate(path: &Path, stack: &TiledStack) -> Result<()> {
    let h = &stack.header;
    if h.format_version != STACK_FORMAT_VERSION_TILED {
        return Err(format_err(
            path,
            format!(
                "header has format version {}; a tiled stack has {STACK_FORMAT_VERSION_TILED}",
                h.format_version
            ),
        ));
    }
    crate::scene::Resolution {
        width: h.width,
        height: h.height,
    }
    .validate("stack resolution")
    .map_err(|e| format_err(path, e.to_string()))?;
    let mut names = HashSet::new();
    for info in &stack.layers {
        let name = info.key.layer_name();
        if info.channels != 1 && info.channels != 3 {
            return Err(format_err(
                path,
                format!(
                    "layer {name} has {} channels; a layer has 1 (grey) or 3 (RGB)",
                    info.channels
                ),
            ));
        }
        if !(info.scale.is_finite() && info.scale > 0.0) {
            return Err(format_err(
                path,
                format!(
                    "layer {name} has scale {}; a scale is finite and > 0",
                    info.scale
                ),
            ));
        }
        if !names.insert(name) {
            return Err(format_err(
                path,
                format!("layer {} appears twice", info.key.layer_name()),
            ));
        }
    }
    if stack.tiles.len() != stack.tile_count() {
        return Err(format_err(
            path,
            format!(
                "{} tiles; {}×{} pixels need {}×{} tiles of {}",
                stack.tiles.len(),
                h.width,
                h.height,
                stack.tiles_x(),
                stack.tiles_y(),
                super::STACK_TILE
            ),
        ));
    }
    for (t, tile) in stack.tiles.iter().enumerate() {
        let rect = stack.tile_rect(t);
        if tile.values.precision() != h.precision {
            return Err(format_err(
                path,
                format!(
                    "tile {t} holds {:?} values in a stack of precision {:?}",
                    tile.values.precision(),
                    h.precision
                ),
            ));
        }
        if let Some(l) = &tile.lattice {
            if l.size() != (rect.width, rect.height) {
                return Err(format_err(
                    path,
                    format!(
                        "tile {t} has a lattice over {:?} pixels; the tile is {}×{}",
                        l.size(),
                        rect.width,
                        rect.height
                    ),
                ));
            }
        }
        let mut next_offset = 0u64;
        let mut previous: Option<u32> = None;
        for (k, e) in tile.entries.iter().enumerate() {
            let at = || format!("tile {t}, entry {k} (layer {})", e.layer);
            if e.layer as usize >= stack.layers.len() {
                return Err(format_err(
                    path,
                    format!(
                        "{}: layer id out of range ({} layers)",
                        at(),
                        stack.layers.len()
                    ),
                ));
            }
            if previous.is_some_and(|p| p >= e.layer) {
                return Err(format_err(
                    path,
                    format!("{}: layers not strictly increasing", at()),
                ));
            }
            previous = Some(e.layer);
            if e.channels != 1 && e.channels != 3 {
                return Err(format_err(
                    path,
                    format!("{}: {} channels; 1 (grey) or 3 (RGB)", at(), e.channels),
                ));
            }
            if e.channels > stack.layers[e.layer as usize].channels {
                return Err(format_err(
                    path,
                    format!("{}: RGB values of a grey layer", at()),
                ));
            }
            if !(e.scale.is_finite() && e.scale > 0.0) {
                return Err(format_err(
                    path,
                    format!("{}: scale {}; a scale is finite and > 0", at(), e.scale),
                ));
            }
            if e.offset as u64 != next_offset {
                return Err(format_err(
                    path,
                    format!(
                        "{}: values start at {}; the entries before end at {next_offset}",
                        at(),
                        e.offset
                    ),
                ));
            }
            if e.segments != 0 {
                let Some(lattice) = &tile.lattice else {
                    return Err(format_err(
                        path,
                        format!("{}: a lattice entry in a tile without a segment map", at()),
                    ));
                };
                if lattice.coefficient_count(e.segments, e.channels).is_none() {
                    return Err(format_err(
                        path,
                        format!(
                            "{}: covers segments {:#x}; the tile has {}",
                            at(),
                            e.segments,
                            lattice.segment_count()
                        ),
                    ));
                }
            }
            next_offset += tile.value_count(e, rect.pixels()) as u64;
            if next_offset > u32::MAX as u64 {
                return Err(format_err(
                    path,
                    format!("{}: a tile holds more than 2³² values", at()),
                ));
            }
        }
        if tile.values.len() as u64 != next_offset {
            return Err(format_err(
                path,
                format!(
                    "tile {t} holds {} values; its entries need {next_offset}",
                    tile.values.len()
                ),
            ));
        }
        let non_finite = match &tile.values {
            TileValues::F16(v) => v.iter().position(|s| !s.is_finite()),
            TileValues::F32(v) => v.iter().position(|s| !s.is_finite()),
        };
        if let Some(i) = non_finite {
            return Err(format_err(
                path,
                format!(
                    "tile {t} has a non-finite value ({}) at {i}",
                    tile.values.get(i)
                ),
            ));
        }
    }
    Ok(())
}
