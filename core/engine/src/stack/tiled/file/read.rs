//! The tiled stack file's reader: every claimed size checked against the file and the
//! memory budget before anything is decoded (see [`super`] for the layout).

use std::fs::File;
use std::io::{BufReader, Seek, SeekFrom};
use std::path::Path;

use exr::prelude::{self as x, ReadChannels as _, ReadLayers as _};

use crate::error::{RelumeError, Result};
use crate::layer_key::LayerKey;
use crate::stack::exr_file::{
    map_exr_err, read_stack, text_attr, ATTR_FORMAT_VERSION, ATTR_HEADER, ATTR_LAYERS,
    ATTR_SCENE_HASH, MAX_COMPRESSION_RATIO,
};
use crate::stack::tiled::lattice::TileLattice;
use crate::stack::tiled::layout::{
    StackTile, TileLayer, TileValues, TiledLayerInfo, TiledStack, STACK_FORMAT_VERSION_TILED,
};
use crate::stack::tiled::validate::{format_err, validate};
use crate::stack::{Precision, StackHeader, STACK_FORMAT_VERSION};

use super::parts::{
    LayerEntry, CHANNEL_COUNT, CHANNEL_MASK, CHANNEL_SEGMENT, CHANNEL_STEP, CHANNEL_VALUE,
    ENTRY_CHANNELS, PART_ENTRIES, PART_SEGMENTS, PART_TILES, PART_VALUES, ROW_WIDTH,
    VERSION_WITHOUT_LATTICE,
};

fn part_name(h: &exr::meta::header::Header) -> String {
    h.own_attributes
        .layer_name
        .as_ref()
        .map(|n| String::from_utf8_lossy(n.as_slice()).into_owned())
        .unwrap_or_default()
}

/// Reads a stack file as a [`TiledStack`]: a version-3 or version-2 file as it is stored
/// (the stack's header then says [`STACK_FORMAT_VERSION_TILED`]); a version-1
/// (dense) file through the dense reader ([`read_stack`]) and [`TiledStack::from_dense`] —
/// that path holds the whole dense stack in memory once. Another version gives
/// [`RelumeError::StackVersion`] (a rebake).
pub fn read_tiled(path: &Path) -> Result<TiledStack> {
    let file = File::open(path).map_err(|e| RelumeError::io(path, e))?;
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let meta = x::MetaData::read_from_buffered(&mut reader, false)
        .map_err(|e| map_exr_err(path, e, false))?;
    let Some(first) = meta.headers.first() else {
        return Err(format_err(path, "the file has no part"));
    };
    let attrs = &first.own_attributes;
    let Some(header_json) = text_attr(path, attrs, ATTR_HEADER)? else {
        return Err(RelumeError::StackForeign {
            path: path.to_path_buf(),
            message: format!("an OpenEXR image without the {ATTR_HEADER} attribute"),
        });
    };
    let version = match attrs.other.get(&x::Text::from(ATTR_FORMAT_VERSION)) {
        Some(x::AttributeValue::I32(v)) => *v,
        Some(_) => {
            return Err(format_err(
                path,
                format!("attribute {ATTR_FORMAT_VERSION} is not an i32"),
            ))
        }
        None => {
            return Err(format_err(
                path,
                format!("attribute {ATTR_FORMAT_VERSION} is missing"),
            ))
        }
    };
    if version == STACK_FORMAT_VERSION as i32 {
        drop(reader);
        return TiledStack::from_dense(&read_stack(path)?).map_err(|e| with_path(e, path));
    }
    if version != STACK_FORMAT_VERSION_TILED as i32 && version != VERSION_WITHOUT_LATTICE as i32 {
        return Err(RelumeError::StackVersion {
            path: path.to_path_buf(),
            found: version.max(0) as u32,
            supported: STACK_FORMAT_VERSION_TILED,
        });
    }
    let version = version as u32;
    let mut header: StackHeader = serde_json::from_str(&header_json).map_err(|e| {
        format_err(
            path,
            format!("attribute {ATTR_HEADER} is not a stack header: {e}"),
        )
    })?;
    if header.format_version != version {
        return Err(format_err(
            path,
            format!(
                "{ATTR_HEADER} says format version {} but {ATTR_FORMAT_VERSION} says {version}",
                header.format_version
            ),
        ));
    }
    if text_attr(path, attrs, ATTR_SCENE_HASH)?.as_deref() != Some(&header.scene_hash) {
        return Err(format_err(
            path,
            format!("attribute {ATTR_SCENE_HASH} is missing or differs from {ATTR_HEADER}"),
        ));
    }
    crate::scene::Resolution {
        width: header.width,
        height: header.height,
    }
    .validate("stack resolution")
    .map_err(|e| format_err(path, e.to_string()))?;
    let layers_json = text_attr(path, attrs, ATTR_LAYERS)?
        .ok_or_else(|| format_err(path, format!("attribute {ATTR_LAYERS} is missing")))?;
    let layer_entries: Vec<LayerEntry> = serde_json::from_str(&layers_json).map_err(|e| {
        format_err(
            path,
            format!("attribute {ATTR_LAYERS} is not a layer list: {e}"),
        )
    })?;
    let mut layers = Vec::with_capacity(layer_entries.len());
    for e in layer_entries {
        let key = LayerKey::parse(&e.name).ok_or_else(|| {
            format_err(
                path,
                format!("layer name {:?} is not a path signature", e.name),
            )
        })?;
        layers.push(TiledLayerInfo {
            key,
            channels: e.channels,
            scale: e.scale,
        });
    }

    check_claims_against_file(path, &meta, &reader)?;
    check_layout(path, &header, &meta, version)?;
    header.format_version = STACK_FORMAT_VERSION_TILED;

    reader
        .seek(SeekFrom::Start(0))
        .map_err(|e| RelumeError::io(path, e))?;
    let image = x::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .pedantic()
        .from_buffered(reader)
        .map_err(|e| map_exr_err(path, e, true))?;
    let mut parts = image.layer_data.into_iter();
    let (Some(tiles_part), Some(entries_part), Some(values_part)) =
        (parts.next(), parts.next(), parts.next())
    else {
        return Err(format_err(path, "the file lost a part while decoding"));
    };
    let maps = match parts.next() {
        Some(p) => u32_channels(path, p)?.pop().unwrap_or_default(),
        None => Vec::new(),
    };
    let mut tile_columns = u32_channels(path, tiles_part)?.into_iter();
    let counts = tile_columns.next().unwrap_or_default();
    let steps = tile_columns.next().unwrap_or_else(|| vec![0; counts.len()]);
    let mut table = u32_channels(path, entries_part)?;
    if table.len() == ENTRY_CHANNELS.len() {
        table.push(vec![0; table.first().map_or(0, Vec::len)]);
    }
    let [channels, layer, offset, scale, segments] = <[Vec<u32>; 5]>::try_from(table)
        .map_err(|_| format_err(path, "the entries part lost a channel"))?;
    let values = values_part
        .channel_data
        .list
        .into_iter()
        .next()
        .map(|c| c.sample_data)
        .ok_or_else(|| format_err(path, "the values part has no channel"))?;

    let stack = assemble(
        path,
        header,
        layers,
        [&counts, &steps],
        [&channels, &layer, &offset, &scale, &segments],
        values,
        &maps,
    )?;
    validate(path, &stack)?;
    Ok(stack)
}

/// Puts `path` into an error raised without one (from a conversion in memory).
fn with_path(e: RelumeError, path: &Path) -> RelumeError {
    match e {
        RelumeError::StackFormat { message, .. } => format_err(path, message),
        other => other,
    }
}

fn u32_channels(
    path: &Path,
    part: x::Layer<x::AnyChannels<x::FlatSamples>>,
) -> Result<Vec<Vec<u32>>> {
    part.channel_data
        .list
        .into_iter()
        .map(|c| match c.sample_data {
            x::FlatSamples::U32(v) => Ok(v),
            _ => Err(format_err(path, "a table channel is not u32")),
        })
        .collect()
}

/// The parts, their names, sizes and channels, before any pixel is decoded.
fn check_layout(path: &Path, header: &StackHeader, meta: &x::MetaData, version: u32) -> Result<()> {
    let with_lattice = version != VERSION_WITHOUT_LATTICE;
    let names: Vec<String> = meta.headers.iter().map(part_name).collect();
    let mut want_names = vec![PART_TILES, PART_ENTRIES, PART_VALUES];
    if with_lattice {
        want_names.push(PART_SEGMENTS);
    }
    if names != want_names {
        return Err(format_err(
            path,
            format!(
                "parts {names:?}; a tiled stack of format version {version} has {want_names:?}"
            ),
        ));
    }
    let channels = |h: &exr::meta::header::Header| -> Vec<(String, x::SampleType)> {
        h.channels
            .list
            .iter()
            .map(|c| {
                (
                    String::from_utf8_lossy(c.name.as_slice()).into_owned(),
                    c.sample_type,
                )
            })
            .collect()
    };
    let value_type = match header.precision {
        Precision::F16 => x::SampleType::F16,
        Precision::F32 => x::SampleType::F32,
    };
    let u32s = |names: &[&str]| -> Vec<(String, x::SampleType)> {
        names
            .iter()
            .map(|n| (n.to_string(), x::SampleType::U32))
            .collect()
    };
    let expected = if with_lattice {
        let mut entry = ENTRY_CHANNELS.to_vec();
        entry.push(CHANNEL_MASK);
        vec![
            u32s(&[CHANNEL_COUNT, CHANNEL_STEP]),
            u32s(&entry),
            vec![(CHANNEL_VALUE.to_string(), value_type)],
            u32s(&[CHANNEL_SEGMENT]),
        ]
    } else {
        vec![
            u32s(&[CHANNEL_COUNT]),
            u32s(&ENTRY_CHANNELS),
            vec![(CHANNEL_VALUE.to_string(), value_type)],
        ]
    };
    for ((h, name), want) in meta.headers.iter().zip(&names).zip(&expected) {
        if channels(h) != *want {
            return Err(format_err(
                path,
                format!(
                    "part {name} has channels {:?}; expected {want:?}",
                    channels(h)
                ),
            ));
        }
        if h.deep {
            return Err(format_err(path, format!("part {name} is deep data")));
        }
    }
    let tiles = meta.headers[0].layer_size;
    let (tx, ty) = (
        crate::stack::tiled::layout::tiles_along(header.width) as usize,
        crate::stack::tiled::layout::tiles_along(header.height) as usize,
    );
    if (tiles.width(), tiles.height()) != (tx, ty) {
        return Err(format_err(
            path,
            format!(
                "part {PART_TILES} is {}×{}; {}×{} pixels need {tx}×{ty} tiles",
                tiles.width(),
                tiles.height(),
                header.width,
                header.height
            ),
        ));
    }
    Ok(())
}

/// What the parts claim against the file's length (no compression makes a few KiB into
/// gigabytes) and, decoded plus assembled (≈ twice the pixel data), against the memory
/// budget ([`crate::memory::check_budget`]), before anything of that size is allocated.
fn check_claims_against_file(
    path: &Path,
    meta: &x::MetaData,
    reader: &BufReader<File>,
) -> Result<()> {
    let file_len = reader
        .get_ref()
        .metadata()
        .map_err(|e| RelumeError::io(path, e))?
        .len();
    let mut raw = 0u64;
    for h in &meta.headers {
        let bytes_per_pixel: u64 = h
            .channels
            .list
            .iter()
            .map(|c| match c.sample_type {
                x::SampleType::F16 => 2u64,
                x::SampleType::F32 | x::SampleType::U32 => 4,
            })
            .sum();
        let part = crate::memory::checked_product(
            "the stack's pixel data",
            &[
                h.layer_size.width() as u64,
                h.layer_size.height() as u64,
                bytes_per_pixel,
            ],
        )?;
        let ratio = if h.compression == x::Compression::Uncompressed {
            1
        } else {
            MAX_COMPRESSION_RATIO
        };
        if part > file_len.saturating_mul(ratio) {
            return Err(RelumeError::StackTruncated {
                path: path.to_path_buf(),
                message: format!(
                    "its part {} claims {}×{} pixels ({}), more than a file of {} can hold at any compression ratio",
                    part_name(h),
                    h.layer_size.width(),
                    h.layer_size.height(),
                    crate::memory::human_bytes(part),
                    crate::memory::human_bytes(file_len)
                ),
            });
        }
        raw = raw.saturating_add(part);
    }
    crate::memory::check_budget(
        &format!("loading the stack {}", path.display()),
        raw.saturating_mul(2),
        None,
    )
}

/// The tiles from the decoded tables: counts per tile, the entry columns, the values.
/// Checks what slicing needs (counts and value totals against the parts, channels 1 or 3);
/// [`validate`] checks the rest.
fn assemble(
    path: &Path,
    header: StackHeader,
    layers: Vec<TiledLayerInfo>,
    [counts, steps]: [&[u32]; 2],
    [channels, layer, offset, scale, segments]: [&[u32]; 5],
    values: x::FlatSamples,
    maps: &[u32],
) -> Result<TiledStack> {
    let entry_total: u64 = counts.iter().map(|&c| c as u64).sum();
    let table_len = channels.len() as u64;
    if entry_total > table_len || table_len - entry_total >= ROW_WIDTH as u64 {
        return Err(format_err(
            path,
            format!(
                "the tiles count {entry_total} entries but part {PART_ENTRIES} holds {table_len}"
            ),
        ));
    }
    let value_len = values.len() as u64;
    let mut tiles: Vec<StackTile> =
        crate::memory::try_with_capacity(counts.len(), "the stack's tiles")?;
    let mut next_entry = 0usize;
    let mut next_value = 0u64;
    let mut next_map = 0usize;
    for (t, &count) in counts.iter().enumerate() {
        let rect = crate::stack::tiled::layout::tile_rect(header.width, header.height, t);
        let pixels = rect.pixels() as u64;
        let lattice = match steps.get(t).copied().unwrap_or(0) {
            0 => None,
            step => {
                let Some(ids) = maps.get(next_map..next_map + pixels as usize) else {
                    return Err(format_err(
                        path,
                        format!(
                            "tile {t}: its segment map needs ids up to {} but part {PART_SEGMENTS} holds {}",
                            next_map + pixels as usize,
                            maps.len()
                        ),
                    ));
                };
                next_map += pixels as usize;
                let ids = ids
                    .iter()
                    .map(|&id| u8::try_from(id))
                    .collect::<std::result::Result<Vec<u8>, _>>()
                    .map_err(|_| format_err(path, format!("tile {t}: a segment id beyond 255")))?;
                let lattice = TileLattice::new(step, rect.width, rect.height, ids)
                    .map_err(|m| format_err(path, format!("tile {t}: {m}")))?;
                Some(lattice)
            }
        };
        let mut entries = Vec::with_capacity(count as usize);
        let mut tile_values = 0u64;
        for k in next_entry..next_entry + count as usize {
            let c = channels[k];
            if c != 1 && c != 3 {
                return Err(format_err(
                    path,
                    format!("tile {t}: an entry has {c} channels; 1 (grey) or 3 (RGB)"),
                ));
            }
            let mask = segments[k];
            tile_values += if mask == 0 {
                pixels * c as u64
            } else {
                lattice
                    .as_ref()
                    .and_then(|l| l.coefficient_count(mask, c as u8))
                    .ok_or_else(|| {
                        format_err(
                            path,
                            format!(
                                "tile {t}: an entry covers segments {mask:#x}, which the tile's segment map lacks"
                            ),
                        )
                    })? as u64
            };
            entries.push(TileLayer {
                layer: layer[k],
                channels: c as u8,
                scale: f32::from_bits(scale[k]),
                offset: offset[k],
                segments: mask,
            });
        }
        next_entry += count as usize;
        let range = next_value..next_value + tile_values;
        if range.end > value_len {
            return Err(format_err(
                path,
                format!(
                    "tile {t}: its entries need values up to {} but part {PART_VALUES} holds {value_len}",
                    range.end
                ),
            ));
        }
        let range = range.start as usize..range.end as usize;
        let tile_values = match &values {
            x::FlatSamples::F16(v) => TileValues::F16(v[range.clone()].to_vec()),
            x::FlatSamples::F32(v) => TileValues::F32(v[range.clone()].to_vec()),
            x::FlatSamples::U32(_) => {
                return Err(format_err(path, format!("part {PART_VALUES} holds u32")))
            }
        };
        next_value = range.end as u64;
        tiles.push(StackTile {
            entries,
            values: tile_values,
            lattice,
        });
    }
    if maps.len() - next_map.min(maps.len()) >= ROW_WIDTH {
        return Err(format_err(
            path,
            format!(
                "the tiles' segment maps need {next_map} ids but part {PART_SEGMENTS} holds {}",
                maps.len()
            ),
        ));
    }
    if value_len - next_value >= ROW_WIDTH as u64 {
        return Err(format_err(
            path,
            format!(
                "the entries need {next_value} values but part {PART_VALUES} holds {value_len}"
            ),
        ));
    }
    Ok(TiledStack {
        header,
        layers,
        tiles,
    })
}
