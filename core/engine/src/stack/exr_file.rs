//! The stack as one OpenEXR file, in the dense layout (format 1: every layer a full frame).
//!
//! Bakes write the tiled layout ([`crate::stack::tiled::file`]); this layout is what older
//! builds wrote. The reader is the format-1 converter's first step (the tiled reader turns
//! what it reads into a tiled stack); the writer is kept for tests, which make format-1
//! files and dense references with it.
//!
//! Layout (docs/design.md §3 "Stack file"):
//! - one part, scanlines, ZIP (16 lines per block). ZIP is lossless; the lossy codecs
//!   (B44, PXR24, DWA) are never used: they lose HDR edges. ZIP is slower to write than to
//!   read, which suits a file written once and loaded at every relight session, and it
//!   shrinks noise-free data several times (docs/measurements.md, "Figures that were in
//!   code comments").
//! - one channel per layer and colour, named Blender-style `Layer.Pass.Channel`:
//!   `{key.layer_name()}.Transfer.Y` for a grey layer, `.Transfer.R/G/B` for an RGB one, so
//!   Blender shows every layer in its compositor and image editor. Channels are sorted by
//!   name as EXR requires; the layer order of the stack is kept in `relume/layers`.
//! - samples stored raw (before the layer's `scale`), as F16 or F32 per the stack's precision.
//! - header attributes: `relume/format_version` (i32), `relume/header` (the [`StackHeader`]
//!   as JSON), `relume/scene_hash` (text, readable without parsing the JSON) and
//!   `relume/layers` (JSON list of `{name, channels, scale}` in stack order; serde writes an
//!   f32 in its shortest round-tripping form, so the scale comes back bit-exact).
//!   Texts are UTF-8 bytes (region names may be anything).
//!
//! Reading checks, in this order, and fails with a specific [`RelumeError`]:
//! missing file → `Io`; bytes missing anywhere (cut file) → `StackTruncated`; not an
//! OpenEXR file at all (wrong magic number) or an EXR without `relume/header` →
//! `StackForeign`; `relume/format_version` ≠ [`STACK_FORMAT_VERSION`] → `StackVersion`;
//! meta data that cannot be understood, a layer name that does not parse, a layer list
//! that does not match the channels, wrong sample types or counts, a non-finite sample or
//! scale → `StackFormat` (naming the layer); damaged compressed pixel data →
//! `StackTruncated`.

use std::collections::{BTreeMap, HashSet};
use std::fs::File;
use std::io::{BufReader, Seek, SeekFrom};
use std::path::Path;

use exr::prelude::{self as x, ReadChannels as _, ReadLayers as _, WritableImage as _};
use serde::{Deserialize, Serialize};

use super::{Layer, LayerSamples, StackHeader, TransferStack, STACK_FORMAT_VERSION};
use crate::error::{RelumeError, Result};
use crate::image_io::write_atomic_checked;
use crate::layer_key::LayerKey;
use crate::options::Precision;
use crate::progress::Progress;

/// Attribute: the [`StackHeader`] as JSON.
pub const ATTR_HEADER: &str = "relume/header";
/// Attribute: the stack format version (i32).
pub const ATTR_FORMAT_VERSION: &str = "relume/format_version";
/// Attribute: the scene hash (text), also inside the header.
pub const ATTR_SCENE_HASH: &str = "relume/scene_hash";
/// Attribute: the layers in stack order, JSON `[{name, channels, scale}, …]`.
pub const ATTR_LAYERS: &str = "relume/layers";
/// The pass part of every channel name (`Layer.Pass.Channel`).
pub const PASS: &str = "Transfer";

/// One entry of `relume/layers`.
#[derive(Serialize, Deserialize)]
struct LayerEntry {
    name: String,
    channels: u32,
    scale: f32,
}

fn format_err(path: &Path, message: impl Into<String>) -> RelumeError {
    RelumeError::StackFormat {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Channel-name suffixes of a layer with `channels` colours (1 = grey, 3 = RGB).
fn channel_suffixes(channels: u32) -> &'static [&'static str] {
    if channels == 1 {
        &["Y"]
    } else {
        &["R", "G", "B"]
    }
}

fn precision_of(samples: &LayerSamples) -> Precision {
    match samples {
        LayerSamples::F16(_) => Precision::F16,
        LayerSamples::F32(_) => Precision::F32,
    }
}

/// Index and value of the first non-finite sample, if any.
fn first_non_finite(samples: &LayerSamples) -> Option<(usize, f32)> {
    match samples {
        LayerSamples::F16(v) => v
            .iter()
            .position(|s| !s.is_finite())
            .map(|i| (i, v[i].to_f32())),
        LayerSamples::F32(v) => v.iter().position(|s| !s.is_finite()).map(|i| (i, v[i])),
    }
}

/// Checks one layer against the header: the same checks on write and on read, so a file
/// this module wrote always reads back.
fn check_layer(path: &Path, header: &StackHeader, layer: &Layer) -> Result<()> {
    let name = layer.key.layer_name();
    if layer.channels != 1 && layer.channels != 3 {
        return Err(format_err(
            path,
            format!(
                "layer {name} has {} channels; a layer has 1 (grey) or 3 (RGB)",
                layer.channels
            ),
        ));
    }
    if !(layer.scale.is_finite() && layer.scale > 0.0) {
        return Err(format_err(
            path,
            format!(
                "layer {name} has scale {}; a scale is finite and > 0",
                layer.scale
            ),
        ));
    }
    let expected = header.width as usize * header.height as usize * layer.channels as usize;
    if layer.samples.len() != expected {
        return Err(format_err(
            path,
            format!(
                "layer {name} has {} samples; {}×{} pixels × {} channels need {expected}",
                layer.samples.len(),
                header.width,
                header.height,
                layer.channels
            ),
        ));
    }
    if precision_of(&layer.samples) != header.precision {
        return Err(format_err(
            path,
            format!(
                "layer {name} holds {:?} samples in a stack of precision {:?}",
                precision_of(&layer.samples),
                header.precision
            ),
        ));
    }
    if let Some((i, v)) = first_non_finite(&layer.samples) {
        let c = layer.channels as usize;
        return Err(format_err(
            path,
            format!(
                "layer {name} has a non-finite sample ({v}) at pixel {}, channel {}",
                i / c,
                channel_suffixes(layer.channels)[i % c]
            ),
        ));
    }
    Ok(())
}

/// Checks what is written: the header round-trips through JSON (a NaN in the camera would
/// not), the size is not empty, there is at least one layer (EXR needs a channel), layer
/// names are unique, and every layer passes [`check_layer`].
fn validate_for_write(path: &Path, stack: &TransferStack) -> Result<String> {
    let h = &stack.header;
    if h.format_version != STACK_FORMAT_VERSION {
        return Err(format_err(
            path,
            format!(
                "header has format version {}; this build writes {STACK_FORMAT_VERSION}",
                h.format_version
            ),
        ));
    }
    if h.width == 0 || h.height == 0 {
        return Err(format_err(
            path,
            format!("size {}×{} is empty", h.width, h.height),
        ));
    }
    if stack.layers.is_empty() {
        return Err(format_err(
            path,
            "the stack has no layer (an OpenEXR file needs a channel)",
        ));
    }
    let json = serde_json::to_string(h)
        .map_err(|e| format_err(path, format!("header does not serialise: {e}")))?;
    match serde_json::from_str::<StackHeader>(&json) {
        Ok(back) if back == *h => {}
        _ => {
            return Err(format_err(
                path,
                "header does not round-trip through JSON (a non-finite number in it?)",
            ))
        }
    }
    let mut seen = HashSet::new();
    for layer in &stack.layers {
        if !seen.insert(layer.key.layer_name()) {
            return Err(format_err(
                path,
                format!("layer {} appears twice", layer.key.layer_name()),
            ));
        }
        check_layer(path, h, layer)?;
    }
    Ok(json)
}

/// Writes `stack` to `path` atomically (temp file, fsync, rename: see
/// [`crate::image_io::write_atomic`]) and returns the bytes written.
///
/// Everything is validated first (see [`check_layer`]: channels 1 or 3, scale finite > 0,
/// sample count = width × height × channels, sample type = header precision, all samples
/// finite, unique layer names, at least one layer, a header that round-trips through JSON):
/// an invalid stack gives [`RelumeError::StackFormat`] and touches no file. A missing or
/// read-only directory gives [`RelumeError::Io`]; an existing file at `path` survives any
/// failure.
pub fn write_stack(path: &Path, stack: &TransferStack) -> Result<u64> {
    write_stack_cancellable(path, stack, &Progress::new())
}

/// Passes writes through while `progress` is not cancelled; after a cancel every write
/// fails, which stops the OpenEXR encoder within one chunk. The error's kind is `Other`:
/// `Write::write_all` retries an `Interrupted` write forever, so a cancel that arrived in the
/// middle of one of the encoder's `write_all` calls would spin instead of stopping.
pub(crate) struct CancellableWriter<'a, W> {
    pub(crate) inner: W,
    pub(crate) progress: &'a Progress,
}

impl<W> CancellableWriter<'_, W> {
    fn check(&self) -> std::io::Result<()> {
        if self.progress.is_cancelled() {
            Err(std::io::Error::other(CANCELLED_WRITE))
        } else {
            Ok(())
        }
    }
}

/// The message of the I/O error a cancelled write ends with (mapped back to `Cancelled`).
const CANCELLED_WRITE: &str = "relume: write cancelled";

impl<W: std::io::Write> std::io::Write for CancellableWriter<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.check()?;
        self.inner.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

impl<W: std::io::Seek> std::io::Seek for CancellableWriter<'_, W> {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.check()?;
        self.inner.seek(pos)
    }
}

/// [`write_stack`] that stops when `progress` is cancelled — while encoding, or after the
/// data is on disk but before the rename — with [`RelumeError::Cancelled`], removing its
/// temp file and leaving an existing file at `path` byte for byte as it was. Once renamed,
/// the stack is written and a later cancel changes nothing.
pub fn write_stack_cancellable(
    path: &Path,
    stack: &TransferStack,
    progress: &Progress,
) -> Result<u64> {
    progress.check()?;
    let header_json = validate_for_write(path, stack)?;
    let h = &stack.header;
    let pixels = h.width as usize * h.height as usize;

    let entries: Vec<LayerEntry> = stack
        .layers
        .iter()
        .map(|l| LayerEntry {
            name: l.key.layer_name(),
            channels: l.channels,
            scale: l.scale,
        })
        .collect();
    let layers_json = serde_json::to_string(&entries)
        .map_err(|e| format_err(path, format!("layer list does not serialise: {e}")))?;

    // One EXR channel per layer colour: de-interleave.
    let mut list = x::SmallVec::<[x::AnyChannel<x::FlatSamples>; 4]>::new();
    for layer in &stack.layers {
        let name = layer.key.layer_name();
        let c = layer.channels as usize;
        for (k, suffix) in channel_suffixes(layer.channels).iter().enumerate() {
            let samples = match &layer.samples {
                LayerSamples::F16(v) => {
                    x::FlatSamples::F16((0..pixels).map(|p| v[p * c + k]).collect())
                }
                LayerSamples::F32(v) => {
                    x::FlatSamples::F32((0..pixels).map(|p| v[p * c + k]).collect())
                }
            };
            list.push(x::AnyChannel::new(
                x::Text::from_slice_unchecked(format!("{name}.{PASS}.{suffix}").as_bytes()),
                samples,
            ));
        }
    }
    let channels = x::AnyChannels::sort(list);

    let text = |s: &str| x::AttributeValue::Text(x::Text::from_slice_unchecked(s.as_bytes()));
    let other = attributes_in_name_order(vec![
        (x::Text::from(ATTR_HEADER), text(&header_json)),
        (
            x::Text::from(ATTR_FORMAT_VERSION),
            x::AttributeValue::I32(STACK_FORMAT_VERSION as i32),
        ),
        (x::Text::from(ATTR_SCENE_HASH), text(&h.scene_hash)),
        (x::Text::from(ATTR_LAYERS), text(&layers_json)),
    ]);
    let attributes = x::LayerAttributes {
        software_name: Some(x::Text::from_slice_unchecked(
            concat!("Relume ", env!("CARGO_PKG_VERSION")).as_bytes(),
        )),
        other,
        ..Default::default()
    };

    // Image::from_layer sets display window = data window = width × height at (0, 0), as
    // Blender expects of a render.
    let layer = x::Layer::new(
        (h.width as usize, h.height as usize),
        attributes,
        x::Encoding {
            compression: x::Compression::ZIP16,
            blocks: x::Blocks::ScanLines,
            line_order: x::LineOrder::Increasing,
        },
        channels,
    );
    let image = x::Image::from_layer(layer);
    progress.check()?;
    write_atomic_checked(
        path,
        |w| {
            let writer = CancellableWriter { inner: w, progress };
            image.write().to_buffered(writer).map_err(|e| match e {
                _ if progress.is_cancelled() => RelumeError::Cancelled,
                x::Error::Io(io) => RelumeError::io(path, io),
                other => format_err(path, format!("OpenEXR write failed: {other}")),
            })
        },
        || progress.check(),
    )
}

/// The message exr gives for an `UnexpectedEof` (it maps EOF to `Invalid`).
const EXR_EOF_MESSAGE: &str = "reference to missing bytes";

/// Maps an exr error. `in_pixels`: while decoding pixel data, where any invalid content
/// means damage; in the meta data only missing bytes mean truncation.
pub(crate) fn map_exr_err(path: &Path, e: x::Error, in_pixels: bool) -> RelumeError {
    let truncated = |m: String| RelumeError::StackTruncated {
        path: path.to_path_buf(),
        message: m,
    };
    match e {
        x::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            truncated(io.to_string())
        }
        x::Error::Io(io) => RelumeError::io(path, io),
        x::Error::Invalid(m) if m == EXR_EOF_MESSAGE => truncated(format!("bytes missing ({m})")),
        x::Error::Invalid(m) if m == "file identifier missing" => RelumeError::StackForeign {
            path: path.to_path_buf(),
            message: "not an OpenEXR file (wrong magic number)".into(),
        },
        x::Error::Invalid(m) if in_pixels => truncated(format!("pixel data: {m}")),
        x::Error::Invalid(m) => format_err(path, format!("invalid OpenEXR meta data: {m}")),
        x::Error::NotSupported(m) => format_err(path, format!("unsupported OpenEXR feature: {m}")),
        x::Error::Aborted => format_err(path, "reading was aborted"),
    }
}

/// Most draws [`attributes_in_name_order`] makes before it settles for another order (for
/// four attributes one draw in 24 iterates sorted; missing a million is beyond chance).
const MAX_ATTRIBUTE_DRAWS: usize = 1_000_000;

/// The Relume attributes `entries` as the map the exr crate writes, iterating in name order,
/// so that one stack always gives the same bytes. exr keeps custom attributes in a std
/// `HashMap` and writes them in its iteration order, which follows the map's random hash
/// keys; each new map draws new keys, so maps of the names are drawn until one iterates
/// sorted (about n! draws for n attributes), then filled with the values (which moves
/// nothing). A clone keeps the order, so exr's own copies write it too.
pub(crate) fn attributes_in_name_order(
    mut entries: Vec<(x::Text, x::AttributeValue)>,
) -> std::collections::HashMap<x::Text, x::AttributeValue> {
    entries.sort_by(|a, b| a.0.cmp(&b.0));
    let mut map = std::collections::HashMap::new();
    for _ in 0..MAX_ATTRIBUTE_DRAWS {
        map = entries
            .iter()
            .map(|(name, _)| (name.clone(), x::AttributeValue::I32(0)))
            .collect();
        if map.keys().eq(entries.iter().map(|(name, _)| name)) {
            break;
        }
    }
    for (name, value) in entries {
        map.insert(name, value);
    }
    map
}

fn attr_text<'a>(attrs: &'a x::LayerAttributes, name: &str) -> Option<&'a x::AttributeValue> {
    attrs.other.get(&x::Text::from(name))
}

/// Reads a text attribute as UTF-8.
pub(crate) fn text_attr(
    path: &Path,
    attrs: &x::LayerAttributes,
    name: &str,
) -> Result<Option<String>> {
    match attr_text(attrs, name) {
        None => Ok(None),
        Some(x::AttributeValue::Text(t)) => String::from_utf8(t.as_slice().to_vec())
            .map(Some)
            .map_err(|_| format_err(path, format!("attribute {name} is not UTF-8 text"))),
        Some(other) => Err(format_err(
            path,
            format!(
                "attribute {name} has type {:?}; expected text",
                other.kind_name()
            ),
        )),
    }
}

/// Header checks shared by [`read_stack_header`] and [`read_stack`], on the meta data.
fn header_from_meta(path: &Path, meta: &x::MetaData) -> Result<StackHeader> {
    let Some(part) = meta.headers.first() else {
        return Err(format_err(path, "the file has no part"));
    };
    let attrs = &part.own_attributes;
    let Some(header_json) = text_attr(path, attrs, ATTR_HEADER)? else {
        return Err(RelumeError::StackForeign {
            path: path.to_path_buf(),
            message: format!("an OpenEXR image without the {ATTR_HEADER} attribute"),
        });
    };
    let version = match attr_text(attrs, ATTR_FORMAT_VERSION) {
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
    // Before parsing the JSON: another version may lay it out differently.
    if version != STACK_FORMAT_VERSION as i32 {
        return Err(RelumeError::StackVersion {
            path: path.to_path_buf(),
            found: version.max(0) as u32,
            supported: STACK_FORMAT_VERSION,
        });
    }
    if meta.headers.len() != 1 {
        return Err(format_err(
            path,
            format!("{} parts; a stack file has one", meta.headers.len()),
        ));
    }
    let header: StackHeader = serde_json::from_str(&header_json).map_err(|e| {
        format_err(
            path,
            format!("attribute {ATTR_HEADER} is not a stack header: {e}"),
        )
    })?;
    if header.format_version != STACK_FORMAT_VERSION {
        return Err(format_err(
            path,
            format!(
                "{ATTR_HEADER} says format version {} but {ATTR_FORMAT_VERSION} says {version}",
                header.format_version
            ),
        ));
    }
    match text_attr(path, attrs, ATTR_SCENE_HASH)? {
        Some(hash) if hash == header.scene_hash => {}
        Some(hash) => {
            return Err(format_err(
                path,
                format!(
                    "{ATTR_SCENE_HASH} is {hash} but {ATTR_HEADER} says {}",
                    header.scene_hash
                ),
            ))
        }
        None => {
            return Err(format_err(
                path,
                format!("attribute {ATTR_SCENE_HASH} is missing"),
            ))
        }
    }
    let size = part.layer_size;
    if (size.width(), size.height()) != (header.width as usize, header.height as usize) {
        return Err(format_err(
            path,
            format!(
                "image is {}×{} but the header says {}×{}",
                size.width(),
                size.height(),
                header.width,
                header.height
            ),
        ));
    }
    Ok(header)
}

fn read_meta(path: &Path, reader: &mut BufReader<File>) -> Result<x::MetaData> {
    // pedantic = false: unknown or odd standard attributes of foreign files do not matter
    // here; every Relume attribute is checked below.
    x::MetaData::read_from_buffered(reader, false).map_err(|e| map_exr_err(path, e, false))
}

/// Reads only the meta data of a stack file (a few KiB, well under a millisecond: the
/// pixel data is not touched) and checks it: foreign, version, header JSON, scene-hash
/// attribute and image size. A file cut inside its pixel data passes here and fails in
/// [`read_stack`].
pub fn read_stack_header(path: &Path) -> Result<StackHeader> {
    let file = File::open(path).map_err(|e| RelumeError::io(path, e))?;
    let mut reader = BufReader::new(file);
    let meta = read_meta(path, &mut reader)?;
    header_from_meta(path, &meta)
}

/// Reads and validates a whole stack file (see the module doc for the checks and errors).
pub fn read_stack(path: &Path) -> Result<TransferStack> {
    let file = File::open(path).map_err(|e| RelumeError::io(path, e))?;
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let meta = read_meta(path, &mut reader)?;
    let header = header_from_meta(path, &meta)?;
    let attrs = &meta.headers[0].own_attributes;
    let layers_json = text_attr(path, attrs, ATTR_LAYERS)?
        .ok_or_else(|| format_err(path, format!("attribute {ATTR_LAYERS} is missing")))?;
    let entries: Vec<LayerEntry> = serde_json::from_str(&layers_json).map_err(|e| {
        format_err(
            path,
            format!("attribute {ATTR_LAYERS} is not a layer list: {e}"),
        )
    })?;

    // The channels the layer list implies, before decoding any pixel.
    let mut keys = Vec::with_capacity(entries.len());
    let mut expected: BTreeMap<String, (usize, usize)> = BTreeMap::new(); // channel → (layer, colour)
    for (i, e) in entries.iter().enumerate() {
        let key = LayerKey::parse(&e.name).ok_or_else(|| {
            format_err(
                path,
                format!("layer name {:?} is not a path signature", e.name),
            )
        })?;
        if e.channels != 1 && e.channels != 3 {
            return Err(format_err(
                path,
                format!(
                    "layer {} has {} channels; a layer has 1 (grey) or 3 (RGB)",
                    e.name, e.channels
                ),
            ));
        }
        for (k, s) in channel_suffixes(e.channels).iter().enumerate() {
            if expected
                .insert(format!("{}.{PASS}.{s}", e.name), (i, k))
                .is_some()
            {
                return Err(format_err(
                    path,
                    format!("layer {} appears twice in {ATTR_LAYERS}", e.name),
                ));
            }
        }
        keys.push(key);
    }
    let present: Vec<String> = meta.headers[0]
        .channels
        .list
        .iter()
        .map(|c| String::from_utf8_lossy(c.name.as_slice()).into_owned())
        .collect();
    for name in &present {
        if !expected.contains_key(name) {
            return Err(format_err(
                path,
                format!("channel {name} is in the file but no layer of {ATTR_LAYERS} has it"),
            ));
        }
    }
    if present.len() != expected.len() {
        let missing: Vec<&String> = expected.keys().filter(|n| !present.contains(n)).collect();
        return Err(format_err(
            path,
            format!("{ATTR_LAYERS} lists channels the file lacks: {missing:?}"),
        ));
    }

    check_claims_against_file(path, &header, &meta.headers[0], &reader)?;

    // Decode the pixels.
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
    let part = image
        .layer_data
        .into_iter()
        .next()
        .ok_or_else(|| format_err(path, "the file has no part"))?;

    let pixels = header.width as usize * header.height as usize;
    let mut layers: Vec<Layer> =
        crate::memory::try_with_capacity(entries.len(), "the stack's layers")?;
    for (e, key) in entries.iter().zip(keys) {
        let n = pixels * e.channels as usize;
        let what = "a layer of the stack";
        layers.push(Layer {
            key,
            channels: e.channels,
            scale: e.scale,
            samples: match header.precision {
                Precision::F16 => LayerSamples::F16(crate::memory::try_zeroed(n, what)?),
                Precision::F32 => LayerSamples::F32(crate::memory::try_zeroed(n, what)?),
            },
        });
    }
    for channel in part.channel_data.list {
        let name = String::from_utf8_lossy(channel.name.as_slice()).into_owned();
        let (li, k) = expected[&name];
        let layer = &mut layers[li];
        let c = layer.channels as usize;
        if channel.sample_data.len() != pixels {
            return Err(format_err(
                path,
                format!(
                    "channel {name} has {} samples; expected {pixels}",
                    channel.sample_data.len()
                ),
            ));
        }
        match (&mut layer.samples, channel.sample_data) {
            (LayerSamples::F16(dst), x::FlatSamples::F16(src)) => {
                for (p, v) in src.into_iter().enumerate() {
                    dst[p * c + k] = v;
                }
            }
            (LayerSamples::F32(dst), x::FlatSamples::F32(src)) => {
                for (p, v) in src.into_iter().enumerate() {
                    dst[p * c + k] = v;
                }
            }
            (_, other) => {
                let found = match other {
                    x::FlatSamples::F16(_) => "f16",
                    x::FlatSamples::F32(_) => "f32",
                    x::FlatSamples::U32(_) => "u32",
                };
                return Err(format_err(
                    path,
                    format!(
                        "channel {name} holds {found} samples in a stack of precision {:?}",
                        header.precision
                    ),
                ));
            }
        }
    }
    for layer in &layers {
        check_layer(path, &header, layer)?;
    }
    Ok(TransferStack { header, layers })
}

/// Most bytes of pixel data one byte of a compressed chunk can stand for: deflate (ZIP,
/// PXR24's second stage) peaks near 1032:1, RLE at 64:1, PIZ's run-length Huffman codes
/// below that; the margin covers chunk headers and PXR24's 24-to-32-bit widening.
pub(crate) const MAX_COMPRESSION_RATIO: u64 = 1400;

/// Checks what the header claims (image size, channels, sample types) against the file's
/// length *before* anything of that size is allocated: a few-KiB file that claims 16384²
/// pixels of 100 channels cannot hold them even at the best compression ratio, and decoding
/// it would preallocate gigabytes (an abort, killing Blender). Then checks the decoded size
/// against the memory budget ([`crate::memory::check_budget`]): decoding needs the file's
/// channels and the stack's layers at once, ≈ twice the pixel data.
fn check_claims_against_file(
    path: &Path,
    header: &StackHeader,
    part: &exr::meta::header::Header,
    reader: &BufReader<File>,
) -> Result<()> {
    crate::scene::Resolution {
        width: header.width,
        height: header.height,
    }
    .validate("stack resolution")
    .map_err(|e| format_err(path, e.to_string()))?;
    let file_len = reader
        .get_ref()
        .metadata()
        .map_err(|e| RelumeError::io(path, e))?
        .len();
    let bytes_per_pixel: u64 = part
        .channels
        .list
        .iter()
        .map(|c| match c.sample_type {
            x::SampleType::F16 => 2u64,
            x::SampleType::F32 | x::SampleType::U32 => 4,
        })
        .sum();
    let raw = crate::memory::checked_product(
        "the stack's pixel data",
        &[header.width as u64, header.height as u64, bytes_per_pixel],
    )?;
    let ratio = if part.compression == x::Compression::Uncompressed {
        1
    } else {
        MAX_COMPRESSION_RATIO
    };
    if raw > file_len.saturating_mul(ratio) {
        return Err(RelumeError::StackTruncated {
            path: path.to_path_buf(),
            message: format!(
                "its header claims {}×{} pixels of {} channels ({}), more than a file of {} can hold at any compression ratio",
                header.width,
                header.height,
                part.channels.list.len(),
                crate::memory::human_bytes(raw),
                crate::memory::human_bytes(file_len)
            ),
        });
    }
    crate::memory::check_budget(
        &format!("loading the stack {}", path.display()),
        raw.saturating_mul(2),
        None,
    )
}

/// Refuses a stack baked from another scene: [`RelumeError::StackStale`] when the header's
/// scene hash differs from `scene_hash` (the hash of the scene about to be relit).
pub fn check_scene_hash(header: &StackHeader, scene_hash: &str) -> Result<()> {
    if header.scene_hash == scene_hash {
        Ok(())
    } else {
        Err(RelumeError::StackStale {
            stack_hash: header.scene_hash.clone(),
            scene_hash: scene_hash.to_string(),
        })
    }
}

#[cfg(test)]
mod cancellable_writer_tests {
    use std::io::Write as _;
    use std::sync::mpsc;
    use std::time::Duration;

    use super::CancellableWriter;
    use crate::progress::Progress;

    /// A cancel must stop `write_all` (which the OpenEXR encoder uses), not make it retry: run
    /// on a thread so that a regression fails here instead of hanging the test run.
    #[test]
    fn a_cancelled_write_all_returns_an_error() {
        let (done, finished) = mpsc::channel();
        std::thread::spawn(move || {
            let progress = Progress::new();
            let mut sink = Vec::new();
            let mut writer = CancellableWriter {
                inner: &mut sink,
                progress: &progress,
            };
            writer.write_all(b"before").unwrap();
            progress.cancel();
            let result = writer.write_all(b"after");
            let _ = done.send((result.is_err(), sink.len()));
        });
        let (failed, written) = finished
            .recv_timeout(Duration::from_secs(20))
            .expect("write_all after a cancel did not return");
        assert!(failed, "a write after the cancel succeeded");
        assert_eq!(written, 6, "only the bytes before the cancel are written");
    }
}
