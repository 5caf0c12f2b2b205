//! The tiled stack file's writer: the parts' headers and chunks made from the stack as the
//! compressor asks for them, written atomically (see [`super`] for the layout).

use std::path::Path;

use exr::block::writer::ChunksWriter as _;
use exr::prelude as x;

use crate::error::{RelumeError, Result};
use crate::image_io::write_atomic_checked;
use crate::progress::Progress;
use crate::stack::exr_file::{
    attributes_in_name_order, CancellableWriter, ATTR_FORMAT_VERSION, ATTR_HEADER, ATTR_LAYERS,
    ATTR_SCENE_HASH,
};
use crate::stack::tiled::layout::{StackTile, TileValues, TiledStack, STACK_FORMAT_VERSION_TILED};
use crate::stack::tiled::validate::{format_err, validate};
use crate::stack::{Precision, StackHeader};

use super::parts::{
    rows_for, LayerEntry, CHANNEL_COUNT, CHANNEL_MASK, CHANNEL_SEGMENT, CHANNEL_STEP,
    CHANNEL_VALUE, ENTRY_CHANNELS, PART_ENTRIES, PART_SEGMENTS, PART_TILES, PART_VALUES,
    VERSION_WITHOUT_LATTICE,
};

/// How the writer compresses the parts' chunks (all lossless). The bake writes with
/// [`StackCompression::default`]; the others are kept to measure against it
/// (`tests/engine/stack_write.rs`, docs/scale.md).
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
