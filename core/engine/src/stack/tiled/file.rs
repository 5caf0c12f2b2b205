//! The tiled stack as one OpenEXR file: stack format version
//! [`STACK_FORMAT_VERSION_TILED`].
//!
//! Layout (three parts, scanlines, ZIP16 by default — [`StackCompression`] —, written
//! atomically like the dense file; each chunk is made from the stack when the compressor,
//! which works on several chunks at once, asks for it, so writing holds the stack once):
//! - part `tiles`: one pixel per stack tile (`tiles_x × tiles_y`), channel `entries` (u32):
//!   how many layers the tile holds — a map of the stack's sparsity that any EXR viewer
//!   shows. It carries the Relume attributes, named as in the dense file
//!   ([`ATTR_HEADER`] with format version 2, [`ATTR_FORMAT_VERSION`] = 2,
//!   [`ATTR_SCENE_HASH`], [`ATTR_LAYERS`]: `[{name, channels, scale}, …]` per layer id).
//! - part `entries`: the entry tables of all tiles back to back in raster order, one pixel
//!   per entry, row-major in rows of up to [`ROW_WIDTH`] pixels (the last row padded with
//!   zeros); channels `layer`, `channels`, `scale` (the f32's bits) and `offset`, all u32.
//! - part `values`: the values of all tiles back to back, in rows of up to [`ROW_WIDTH`],
//!   channel `value`, f16 or f32 per the stack's precision.
//!
//! Version 3 (a stack with lattice entries, [`super::lattice`]; a stack without any is still
//! written as version 2, which older readers read) adds:
//! - to part `tiles`, channel `lattice` (u32): the tile's lattice step in pixels, 0 when
//!   the tile has no segment map;
//! - to part `entries`, channel `segments` (u32): the entry's segment mask, 0 for a
//!   per-pixel entry (a lattice entry's values are its coefficients);
//! - a fourth part `segments`: the segment maps of the tiles with a lattice, back to back
//!   in raster order, one pixel per tile pixel (row-major inside the tile), channel
//!   `segment` (u32), in rows of up to [`ROW_WIDTH`]. The nodes each segment stores follow
//!   from its map and are not written.
//!
//! Reading validates before trusting: the part and channel layout, every claimed size
//! against the file's length and the memory budget before decoding, the entry count and
//! value count the tables imply against the parts, then everything [`validate`] checks.
//! Errors are the dense reader's: `StackForeign`, `StackVersion`, `StackTruncated`,
//! `StackFormat` with a message naming what is wrong.

use std::fs::File;
use std::io::{BufReader, Seek, SeekFrom};
use std::path::Path;

use exr::block::writer::ChunksWriter as _;
use exr::prelude::{self as x, ReadChannels as _, ReadLayers as _};
use serde::{Deserialize, Serialize};

use super::lattice::TileLattice;
use super::layout::{
    StackTile, TileLayer, TileValues, TiledLayerInfo, TiledStack, STACK_FORMAT_VERSION_TILED,
};
use super::validate::{format_err, validate};
use crate::error::{RelumeError, Result};
use crate::image_io::write_atomic_checked;
use crate::layer_key::LayerKey;
use crate::progress::Progress;
use crate::stack::exr_file::{
    attributes_in_name_order, map_exr_err, read_stack, text_attr, CancellableWriter,
    ATTR_FORMAT_VERSION, ATTR_HEADER, ATTR_LAYERS, ATTR_SCENE_HASH, MAX_COMPRESSION_RATIO,
};
use crate::stack::{Precision, StackHeader, STACK_FORMAT_VERSION};

/// Longest row of the `entries` and `values` parts: wide enough that a big stack is a few
/// hundred thousand rows, narrow enough that padding the last row costs nothing.
pub const ROW_WIDTH: usize = 4096;

const PART_TILES: &str = "tiles";
const PART_ENTRIES: &str = "entries";
const PART_VALUES: &str = "values";
const PART_SEGMENTS: &str = "segments";
const CHANNEL_COUNT: &str = "entries";
const CHANNEL_STEP: &str = "lattice";
/// The entry channels, sorted by name as EXR stores them (version 2; version 3 adds
/// [`CHANNEL_MASK`], which sorts last).
const ENTRY_CHANNELS: [&str; 4] = ["channels", "layer", "offset", "scale"];
const CHANNEL_MASK: &str = "segments";
const CHANNEL_VALUE: &str = "value";
const CHANNEL_SEGMENT: &str = "segment";
/// The version of the layout without lattice entries.
const VERSION_WITHOUT_LATTICE: u32 = 2;

/// One entry of the layers attribute.
#[derive(Serialize, Deserialize)]
struct LayerEntry {
    name: String,
    channels: u8,
    scale: f32,
}

/// Width and height of a part holding `n` values in rows of up to [`ROW_WIDTH`] (at least
/// one pixel: an EXR part is never empty).
fn rows_for(n: usize) -> (usize, usize) {
    let width = n.clamp(1, ROW_WIDTH);
    (width, n.div_ceil(width).max(1))
}

/// How the writer compresses the parts' chunks (all lossless). The bake writes with
/// [`StackCompression::default`]; the others are kept to measure against it
/// (`tests/stack_write.rs`, docs/scale.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StackCompression {
    /// Deflate over blocks of 16 scanlines.
    #[default]
    Zip16,
    /// Deflate per scanline.
    Zip1,
    /// Run-length encoding.
    Rle,
    /// Wavelet and Huffman coding over blocks of 32 scanlines.
    Piz,
    Uncompressed,
}

impl StackCompression {
    fn exr(self) -> x::Compression {
        match self {
            StackCompression::Zip16 => x::Compression::ZIP16,
            StackCompression::Zip1 => x::Compression::ZIP1,
            StackCompression::Rle => x::Compression::RLE,
            StackCompression::Piz => x::Compression::PIZ,
            StackCompression::Uncompressed => x::Compression::Uncompressed,
        }
    }
}

/// How a stack file is encoded: its compression, and whether its chunks are compressed on
/// several threads at once (the file is the same either way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteOptions {
    pub compression: StackCompression,
    pub parallel: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            compression: StackCompression::default(),
            parallel: true,
        }
    }
}

/// The header of one part: scanlines in increasing order, `channels` sorted by name as EXR
/// stores them.
fn part_header(
    name: &str,
    size: (usize, usize),
    image_size: (usize, usize),
    other: std::collections::HashMap<x::Text, x::AttributeValue>,
    channels: &[(&str, x::SampleType)],
    compression: StackCompression,
) -> exr::meta::header::Header {
    let mut list: Vec<x::ChannelDescription> = channels
        .iter()
        .map(|(n, t)| {
            x::ChannelDescription::new(x::Text::from_slice_unchecked(n.as_bytes()), *t, false)
        })
        .collect();
    list.sort_by(|a, b| a.name.cmp(&b.name));
    let mut header =
        exr::meta::header::Header::new(x::Text::from(name), size, list.into_iter().collect())
            .with_encoding(
                compression.exr(),
                exr::meta::BlockDescription::ScanLines,
                x::LineOrder::Increasing,
            );
    header.own_attributes = x::LayerAttributes {
        layer_name: Some(x::Text::from(name)),
        software_name: Some(x::Text::from_slice_unchecked(
            concat!("Relume ", env!("CARGO_PKG_VERSION")).as_bytes(),
        )),
        other,
        ..Default::default()
    };
    header.shared_attributes = x::ImageAttributes::with_size(image_size);
    header
}

/// The stack's values as the `values` part's flat sample sequence (all tiles' values back
/// to back, then zeros up to the padded part), read in ranges without copying it whole.
struct ValueSequence<'a> {
    tiles: &'a [StackTile],
    /// Index of each tile's first value in the sequence, and the total at the end.
    starts: Vec<usize>,
}

impl<'a> ValueSequence<'a> {
    /// The sequence of the tiles' values stored at `precision` (a tile at the other
    /// precision, which only the unchecked writer lets through, adds none).
    fn new(tiles: &'a [StackTile], precision: Precision) -> Self {
        let mut starts = Vec::with_capacity(tiles.len() + 1);
        let mut at = 0;
        starts.push(0);
        for t in tiles {
            at += match (&t.values, precision) {
                (TileValues::F16(v), Precision::F16) => v.len(),
                (TileValues::F32(v), Precision::F32) => v.len(),
                _ => 0,
            };
            starts.push(at);
        }
        ValueSequence { tiles, starts }
    }

    /// Appends the native-endian bytes of values `from..from + n` (f16 or f32, zero past
    /// the end) to `out`.
    fn append(&self, from: usize, n: usize, precision: Precision, out: &mut Vec<u8>) {
        let total = *self.starts.last().unwrap_or(&0);
        let mut at = from;
        let end = from + n;
        let mut tile = self.starts.partition_point(|s| *s <= at).saturating_sub(1);
        while at < end.min(total) {
            while self.starts[tile + 1] <= at {
                tile += 1;
            }
            let (lo, hi) = (
                at - self.starts[tile],
                end.min(self.starts[tile + 1]) - self.starts[tile],
            );
            match (&self.tiles[tile].values, precision) {
                (TileValues::F16(v), Precision::F16) => {
                    out.extend(v[lo..hi].iter().flat_map(|h| h.to_bits().to_ne_bytes()))
                }
                (TileValues::F32(v), Precision::F32) => {
                    out.extend(v[lo..hi].iter().flat_map(|f| f.to_ne_bytes()))
                }
                // Not reached: such a tile spans no values.
                _ => {}
            }
            at += hi - lo;
        }
        let zero_bytes = match precision {
            Precision::F16 => 2,
            Precision::F32 => 4,
        };
        out.resize(out.len() + (end - at) * zero_bytes, 0);
    }
}

/// Writes `stack` to `path` (see the module doc) atomically — temp file, fsync, rename —
/// and returns the bytes written. The stack is validated first ([`validate`]); an invalid
/// one gives [`RelumeError::StackFormat`] and touches no file.
pub fn write_tiled(path: &Path, stack: &TiledStack) -> Result<u64> {
    write_tiled_cancellable(path, stack, &Progress::new())
}

/// [`write_tiled`] that stops with [`RelumeError::Cancelled`] when `progress` is
/// cancelled before the rename, leaving an existing file at `path` as it was.
pub fn write_tiled_cancellable(
    path: &Path,
    stack: &TiledStack,
    progress: &Progress,
) -> Result<u64> {
    write_tiled_with(path, stack, WriteOptions::default(), progress)
}

/// [`write_tiled_cancellable`] with the encoding `options` (to measure them against the
/// default).
pub fn write_tiled_with(
    path: &Path,
    stack: &TiledStack,
    options: WriteOptions,
    progress: &Progress,
) -> Result<u64> {
    progress.check()?;
    validate(path, stack)?;
    encode(path, stack, options, progress)
}

/// Writes `stack` as [`write_tiled`] does but without [`validate`]: for the reader's
/// tests and fuzzers, which need files whose tables lie. Not for stacks meant to be read.
#[doc(hidden)]
pub fn write_tiled_unchecked(path: &Path, stack: &TiledStack) -> Result<u64> {
    encode(path, stack, WriteOptions::default(), &Progress::new())
}

fn encode(
    path: &Path,
    stack: &TiledStack,
    options: WriteOptions,
    progress: &Progress,
) -> Result<u64> {
    let with_lattice = stack.tiles.iter().any(|t| t.lattice.is_some());
    let version = if with_lattice {
        STACK_FORMAT_VERSION_TILED
    } else {
        VERSION_WITHOUT_LATTICE
    };
    // The file's header says the layout it is written in; a header claiming another
    // version (only the unchecked writer gets one) is written as it is, for the reader's
    // tests.
    let h = &StackHeader {
        format_version: if stack.header.format_version == STACK_FORMAT_VERSION_TILED {
            version
        } else {
            stack.header.format_version
        },
        ..stack.header.clone()
    };
    let header_json = serde_json::to_string(h)
        .map_err(|e| format_err(path, format!("header does not serialise: {e}")))?;
    if serde_json::from_str::<StackHeader>(&header_json)
        .ok()
        .as_ref()
        != Some(h)
    {
        return Err(format_err(
            path,
            "header does not round-trip through JSON (a non-finite number in it?)",
        ));
    }
    let layers: Vec<LayerEntry> = stack
        .layers
        .iter()
        .map(|l| LayerEntry {
            name: l.key.layer_name(),
            channels: l.channels,
            scale: l.scale,
        })
        .collect();
    let layers_json = serde_json::to_string(&layers)
        .map_err(|e| format_err(path, format!("layer list does not serialise: {e}")))?;

    let entry_count = stack.entry_count();
    let value_count: usize = stack.tiles.iter().map(|t| t.values.len()).sum();
    let entry_size = rows_for(entry_count);
    let value_size = rows_for(value_count);
    let mut counts: Vec<u32> = stack.tiles.iter().map(|t| t.entries.len() as u32).collect();
    // A validated stack has exactly this many tiles; the unchecked writer must not hand
    // the encoder a part of another size.
    counts.resize(stack.tile_count(), 0);
    let mut steps: Vec<u32> = stack
        .tiles
        .iter()
        .map(|t| t.lattice.as_ref().map_or(0, |l| l.step()))
        .collect();
    steps.resize(stack.tile_count(), 0);
    let mut table: [Vec<u32>; 5] = Default::default();
    for column in &mut table {
        column.reserve_exact(entry_size.0 * entry_size.1);
    }
    for e in stack
        .tiles
        .iter()
        .take(stack.tile_count())
        .flat_map(|t| &t.entries)
    {
        let [channels, layer, offset, scale, segments] = &mut table;
        channels.push(e.channels as u32);
        layer.push(e.layer);
        offset.push(e.offset);
        scale.push(e.scale.to_bits());
        segments.push(e.segments);
    }
    let maps: Vec<u32> = stack
        .tiles
        .iter()
        .take(stack.tile_count())
        .filter_map(|t| t.lattice.as_ref())
        .flat_map(|l| l.segments().iter().map(|&s| s as u32))
        .collect();
    let map_size = rows_for(maps.len());
    let mut maps = maps;
    maps.resize(map_size.0 * map_size.1, 0);
    for column in &mut table {
        column.resize(entry_size.0 * entry_size.1, 0);
    }
    let values = ValueSequence::new(&stack.tiles, h.precision);
    let value_type = match h.precision {
        Precision::F16 => x::SampleType::F16,
        Precision::F32 => x::SampleType::F32,
    };

    let text = |s: &str| x::AttributeValue::Text(x::Text::from_slice_unchecked(s.as_bytes()));
    // In name order, so the same stack gives the same bytes.
    let other = attributes_in_name_order(vec![
        (x::Text::from(ATTR_HEADER), text(&header_json)),
        (
            x::Text::from(ATTR_FORMAT_VERSION),
            x::AttributeValue::I32(version as i32),
        ),
        (x::Text::from(ATTR_SCENE_HASH), text(&h.scene_hash)),
        (x::Text::from(ATTR_LAYERS), text(&layers_json)),
    ]);

    let image_size = (h.width as usize, h.height as usize);
    let tiles_size = (stack.tiles_x() as usize, stack.tiles_y() as usize);
    let mut tile_channels = vec![(CHANNEL_COUNT, x::SampleType::U32)];
    let mut entry_channels: Vec<(&str, x::SampleType)> = ENTRY_CHANNELS
        .iter()
        .map(|n| (*n, x::SampleType::U32))
        .collect();
    if with_lattice {
        tile_channels.push((CHANNEL_STEP, x::SampleType::U32));
        entry_channels.push((CHANNEL_MASK, x::SampleType::U32));
    }
    let mut headers: exr::meta::Headers = [
        part_header(
            PART_TILES,
            tiles_size,
            image_size,
            other,
            &tile_channels,
            options.compression,
        ),
        part_header(
            PART_ENTRIES,
            entry_size,
            image_size,
            Default::default(),
            &entry_channels,
            options.compression,
        ),
        part_header(
            PART_VALUES,
            value_size,
            image_size,
            Default::default(),
            &[(CHANNEL_VALUE, value_type)],
            options.compression,
        ),
    ]
    .into_iter()
    .collect();
    if with_lattice {
        headers.push(part_header(
            PART_SEGMENTS,
            map_size,
            image_size,
            Default::default(),
            &[(CHANNEL_SEGMENT, x::SampleType::U32)],
            options.compression,
        ));
    }
    let u32_rows = |columns: &[&[u32]], width: usize, y: usize, lines: usize, out: &mut Vec<u8>| {
        for line in y..y + lines {
            for column in columns {
                out.extend(
                    column[line * width..(line + 1) * width]
                        .iter()
                        .flat_map(|v| v.to_ne_bytes()),
                );
            }
        }
    };
    let [channels, layer, offset, scale, segments] = &table;
    // Columns in the order EXR stores a part's channels (sorted by name, see the constants).
    let tile_columns: Vec<&[u32]> = if with_lattice {
        vec![&counts, &steps]
    } else {
        vec![&counts]
    };
    let entry_columns: Vec<&[u32]> = if with_lattice {
        vec![channels, layer, offset, scale, segments]
    } else {
        vec![channels, layer, offset, scale]
    };
    // Each block's bytes are made from the stack when the compressor asks for them: the
    // values are never copied whole, and at most a few blocks per thread are in flight.
    let block_bytes = |index: exr::block::BlockIndex| -> Vec<u8> {
        let (y, lines) = (index.pixel_position.y(), index.pixel_size.y());
        let mut out = Vec::new();
        match index.layer {
            0 => u32_rows(&tile_columns, tiles_size.0, y, lines, &mut out),
            1 => u32_rows(&entry_columns, entry_size.0, y, lines, &mut out),
            2 => values.append(
                y * value_size.0,
                lines * value_size.0,
                h.precision,
                &mut out,
            ),
            _ => u32_rows(&[&maps], map_size.0, y, lines, &mut out),
        }
        out
    };
    progress.check()?;
    write_atomic_checked(
        path,
        |w| {
            let writer = CancellableWriter { inner: w, progress };
            exr::block::write(writer, headers, true, |meta, chunks| {
                let blocks = meta.collect_ordered_block_data(block_bytes);
                // (A writer that takes the chunks by value, as the compressors want.)
                let chunks = chunks.on_progress(|_| {});
                if options.parallel {
                    chunks.compress_all_blocks_parallel(&meta, blocks)
                } else {
                    chunks.compress_all_blocks_sequential(&meta, blocks)
                }
            })
            .map_err(|e| match e {
                _ if progress.is_cancelled() => RelumeError::Cancelled,
                x::Error::Io(io) => RelumeError::io(path, io),
                other => format_err(path, format!("OpenEXR write failed: {other}")),
            })
        },
        || progress.check(),
    )
}

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
        super::layout::tiles_along(header.width) as usize,
        super::layout::tiles_along(header.height) as usize,
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
        let rect = super::layout::tile_rect(header.width, header.height, t);
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
