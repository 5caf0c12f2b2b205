//! Making a [`TiledStack`]: from a dense stack (bit-exact, and back), or tile by tile from
//! f32 radiance ([`TiledStackBuilder`], for a bake that finalises its tiles as it goes).

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use half::f16;
use rayon::prelude::*;

use super::lattice::TileLattice;
use super::layout::{
    tile_rect, tiles_along, StackTile, TileLayer, TileRect, TileValues, TiledLayerInfo, TiledStack,
    STACK_FORMAT_VERSION_TILED,
};
use super::validate::{format_err, validate};
use crate::error::{RelumeError, Result};
use crate::layer_key::LayerKey;
use crate::stack::{
    Layer, LayerSamples, Precision, StackHeader, TransferStack, STACK_FORMAT_VERSION,
};

/// A stored sample whose bit pattern tells zero (and equality) exactly: the tiled stack
/// drops only values whose bits are all zero and merges RGB to grey only where the three
/// channels have the same bits, so converting back restores every bit (−0 included).
trait Bits: Copy + Send + Sync {
    fn bits(self) -> u32;
}
impl Bits for f16 {
    fn bits(self) -> u32 {
        self.to_bits() as u32
    }
}
impl Bits for f32 {
    fn bits(self) -> u32 {
        self.to_bits()
    }
}

/// Indices into a dense layer's samples of the pixels of `rect`, row-major.
fn rect_pixels(rect: TileRect, width: u32) -> impl Iterator<Item = usize> {
    (rect.y0..rect.y0 + rect.height).flat_map(move |y| {
        (rect.x0..rect.x0 + rect.width).map(move |x| y as usize * width as usize + x as usize)
    })
}

/// How layer samples `v` (`channels` interleaved) appear in `rect`: `None` when every bit is
/// zero there, else the channels the tile needs (1 when an RGB layer is grey throughout).
fn tile_channels<T: Bits>(v: &[T], channels: usize, rect: TileRect, width: u32) -> Option<u8> {
    let mut non_zero = false;
    let mut grey = true;
    for p in rect_pixels(rect, width) {
        let px = &v[p * channels..(p + 1) * channels];
        non_zero |= px.iter().any(|s| s.bits() != 0);
        if channels == 3 {
            grey &= px[0].bits() == px[1].bits() && px[1].bits() == px[2].bits();
        }
    }
    non_zero.then_some(if grey { 1 } else { channels as u8 })
}

/// Appends the values of `rect` from dense samples `v` (`channels` interleaved), keeping
/// `keep` channels (1: the first of each pixel).
fn copy_rect<T: Bits>(
    out: &mut Vec<T>,
    v: &[T],
    channels: usize,
    keep: usize,
    rect: TileRect,
    width: u32,
) {
    for p in rect_pixels(rect, width) {
        out.extend_from_slice(&v[p * channels..p * channels + keep]);
    }
}

/// One tile of `dense`: an entry per layer with a non-zero bit there.
fn dense_tile(dense: &TransferStack, rect: TileRect) -> StackTile {
    let width = dense.header.width;
    let mut entries = Vec::new();
    let mut values = TileValues::empty(dense.header.precision);
    for (l, layer) in dense.layers.iter().enumerate() {
        let c = layer.channels as usize;
        let offset = values.len() as u32;
        let stored = match (&layer.samples, &mut values) {
            (LayerSamples::F16(v), TileValues::F16(out)) => tile_channels(v, c, rect, width)
                .inspect(|&keep| copy_rect(out, v, c, keep as usize, rect, width)),
            (LayerSamples::F32(v), TileValues::F32(out)) => tile_channels(v, c, rect, width)
                .inspect(|&keep| copy_rect(out, v, c, keep as usize, rect, width)),
            _ => unreachable!("precisions checked by from_dense"),
        };
        if let Some(channels) = stored {
            entries.push(TileLayer {
                layer: l as u32,
                channels,
                scale: layer.scale,
                offset,
                segments: 0,
            });
        }
    }
    StackTile {
        entries,
        values,
        lattice: None,
    }
}

impl TiledStack {
    /// The tiled form of `dense`: per tile an entry for every layer with a non-zero value
    /// there (stored grey where an RGB layer's three channels are equal throughout the
    /// tile), values and scale copied bit for bit — no re-quantisation. Layer ids are the
    /// dense layer order; a layer that is zero everywhere stays listed.
    ///
    /// Errors ([`RelumeError::StackFormat`]): a layer with other than 1 or 3 channels, a
    /// sample count that is not width × height × channels, samples not in the header's
    /// precision, or anything [`validate`] refuses (a non-finite value or scale, a
    /// duplicate layer name).
    pub fn from_dense(dense: &TransferStack) -> Result<TiledStack> {
        let no_path = Path::new("");
        let h = &dense.header;
        let pixels = h.width as usize * h.height as usize;
        for layer in &dense.layers {
            let name = layer.key.layer_name();
            if layer.channels != 1 && layer.channels != 3 {
                return Err(format_err(
                    no_path,
                    format!("layer {name} has {} channels", layer.channels),
                ));
            }
            if layer.samples.len() != pixels * layer.channels as usize {
                return Err(format_err(
                    no_path,
                    format!(
                        "layer {name} has {} samples; {}×{}×{} expected",
                        layer.samples.len(),
                        h.width,
                        h.height,
                        layer.channels
                    ),
                ));
            }
            let precision = match layer.samples {
                LayerSamples::F16(_) => Precision::F16,
                LayerSamples::F32(_) => Precision::F32,
            };
            if precision != h.precision {
                return Err(format_err(
                    no_path,
                    format!(
                        "layer {name} holds {precision:?} samples in a stack of precision {:?}",
                        h.precision
                    ),
                ));
            }
        }
        let count = tiles_along(h.width) as usize * tiles_along(h.height) as usize;
        let tiles = (0..count)
            .into_par_iter()
            .map(|t| dense_tile(dense, tile_rect(h.width, h.height, t)))
            .collect();
        let stack = TiledStack {
            header: StackHeader {
                format_version: STACK_FORMAT_VERSION_TILED,
                ..h.clone()
            },
            layers: dense
                .layers
                .iter()
                .map(|l| TiledLayerInfo {
                    key: l.key.clone(),
                    channels: l.channels as u8,
                    scale: l.scale,
                })
                .collect(),
            tiles,
        };
        validate(no_path, &stack)?;
        Ok(stack)
    }

    /// The dense stack (header with the dense format version, layers in id order): exactly
    /// the stack [`from_dense`](Self::from_dense) was given. An entry whose scale differs
    /// from its layer's (a [`TiledStackBuilder`] stack) is re-quantised to the layer's
    /// scale, and a lattice entry is evaluated at every pixel and quantised likewise (the
    /// reference a relight of the lattice is tested against). This expands every layer to
    /// a full frame: for tests and callers of the dense layout only.
    pub fn to_dense(&self) -> Result<TransferStack> {
        let h = &self.header;
        let pixels = h.width as usize * h.height as usize;
        let mut layers = crate::memory::try_with_capacity(self.layers.len(), "dense layers")?;
        for info in &self.layers {
            let n = pixels * info.channels as usize;
            let what = "a dense layer";
            layers.push(Layer {
                key: info.key.clone(),
                channels: info.channels as u32,
                scale: info.scale,
                samples: match h.precision {
                    Precision::F16 => LayerSamples::F16(crate::memory::try_zeroed(n, what)?),
                    Precision::F32 => LayerSamples::F32(crate::memory::try_zeroed(n, what)?),
                },
            });
        }
        let mut expanded = Vec::new();
        for (t, tile) in self.tiles.iter().enumerate() {
            let rect = self.tile_rect(t);
            for e in &tile.entries {
                let layer: &mut Layer = &mut layers[e.layer as usize];
                let (lc, ec) = (layer.channels as usize, e.channels as usize);
                if e.segments != 0 {
                    expand_lattice_entry(tile, e, rect, &mut expanded)?;
                    let ratio = e.scale / layer.scale;
                    for (i, p) in rect_pixels(rect, h.width).enumerate() {
                        for c in 0..lc {
                            let v = expanded[i * ec + c.min(ec - 1)] * ratio;
                            match &mut layer.samples {
                                LayerSamples::F16(d) => d[p * lc + c] = f16::from_f32(v),
                                LayerSamples::F32(d) => d[p * lc + c] = v,
                            }
                        }
                    }
                    continue;
                }
                let same_scale = e.scale.to_bits() == layer.scale.to_bits();
                let ratio = e.scale / layer.scale;
                for (i, p) in rect_pixels(rect, h.width).enumerate() {
                    for c in 0..lc {
                        let src = e.offset as usize + i * ec + c.min(ec - 1);
                        let dst = p * lc + c;
                        match (&mut layer.samples, &tile.values) {
                            (LayerSamples::F16(d), TileValues::F16(s)) => {
                                d[dst] = if same_scale {
                                    s[src]
                                } else {
                                    f16::from_f32(s[src].to_f32() * ratio)
                                }
                            }
                            (LayerSamples::F32(d), TileValues::F32(s)) => {
                                d[dst] = if same_scale { s[src] } else { s[src] * ratio }
                            }
                            _ => {
                                return Err(format_err(
                                    Path::new(""),
                                    format!("tile {t} is not in the stack's precision"),
                                ))
                            }
                        }
                    }
                }
            }
        }
        Ok(TransferStack {
            header: StackHeader {
                format_version: STACK_FORMAT_VERSION,
                ..h.clone()
            },
            layers,
        })
    }
}

/// One layer's radiance over one tile, as a bake hands it to [`TiledStackBuilder::insert`].
#[derive(Clone, Copy, Debug)]
pub struct TileRadiance<'a> {
    /// Layer id (position in the builder's layer list).
    pub layer: u32,
    /// 1 (grey) or 3 (RGB interleaved).
    pub channels: u8,
    /// The tile's pixels row-major, `channels` per pixel, unscaled radiance.
    pub radiance: &'a [f32],
}

/// One layer's lattice coefficients over one tile ([`super::lattice`]), as a bake hands
/// them to [`TiledStackBuilder::insert_with_lattice`].
#[derive(Clone, Copy, Debug)]
pub struct TileCoefficients<'a> {
    /// Layer id (position in the builder's layer list).
    pub layer: u32,
    /// 1 (grey) or 3 (RGB interleaved).
    pub channels: u8,
    /// The segments covered (bit `s`: segment `s`); not 0.
    pub segments: u32,
    /// Per covered segment in id order, per node it stores, `channels` values (unscaled
    /// radiance coefficients).
    pub coefficients: &'a [f32],
}

/// Where a layer's values for one tile come from.
enum Source<'a> {
    Pixels(&'a [f32]),
    Lattice(&'a TileCoefficients<'a>),
}

/// Collects a [`TiledStack`] tile by tile from threads finishing tiles in any order.
/// Each tile is quantised on insertion, so only finished tiles in their stored form and
/// the tiles in flight are in memory.
pub struct TiledStackBuilder {
    header: StackHeader,
    layers: Vec<(LayerKey, u8)>,
    tiles: Vec<Mutex<Option<StackTile>>>,
    /// Values handed in that were not finite, stored as 0 ([`Self::non_finite_zeroed`]).
    non_finite: AtomicU64,
}

impl TiledStackBuilder {
    /// A builder for a stack with `header` (size and precision; its format version is set
    /// to the tiled one) and `layers` (key and channels, 1 or 3, per layer id).
    pub fn new(header: StackHeader, layers: Vec<(LayerKey, u8)>) -> Result<TiledStackBuilder> {
        crate::scene::Resolution {
            width: header.width,
            height: header.height,
        }
        .validate("stack resolution")?;
        if let Some((key, c)) = layers.iter().find(|(_, c)| *c != 1 && *c != 3) {
            return Err(RelumeError::invalid(
                format!("layer {}", key.layer_name()),
                format!("{c} channels; a layer has 1 (grey) or 3 (RGB)"),
            ));
        }
        let count = tiles_along(header.width) as usize * tiles_along(header.height) as usize;
        Ok(TiledStackBuilder {
            header: StackHeader {
                format_version: STACK_FORMAT_VERSION_TILED,
                ..header
            },
            layers,
            tiles: (0..count).map(|_| Mutex::new(None)).collect(),
            non_finite: AtomicU64::new(0),
        })
    }

    /// How many values given to [`insert`](Self::insert) or
    /// [`insert_with_lattice`](Self::insert_with_lattice) so far were NaN or infinite and
    /// were stored as 0. The stages before the builder keep their values finite, so this
    /// is the count of what slipped past them; a bake reports it.
    pub fn non_finite_zeroed(&self) -> u64 {
        self.non_finite.load(Ordering::Relaxed)
    }

    /// Quantises and stores tile `tile` (raster order): an entry per layer of `layers`
    /// with a non-zero value (stored grey where RGB channels are equal), each with its own
    /// scale — f16: the largest magnitude maps to 2¹⁴ as in [`Layer::from_f32`]; f32: 1.
    ///
    /// A NaN or infinite value is stored as 0 and counted ([`Self::non_finite_zeroed`]).
    ///
    /// Errors: a tile index out of range or inserted before, a layer id out of range or
    /// given twice, channels other than 1 or the layer's, a radiance length other than
    /// pixels × channels.
    pub fn insert(&self, tile: usize, layers: &[TileRadiance]) -> Result<()> {
        self.insert_with_lattice(tile, layers, None, &[])
    }

    /// [`insert`](Self::insert) with lattice entries besides the per-pixel ones: `fitted`
    /// are coefficients over `lattice` (the tile's segment map), quantised like per-pixel
    /// values (f16: the largest coefficient maps to 2¹⁴). A layer is given in `layers` or
    /// in `fitted`, not both. The tile keeps `lattice` only when a lattice entry is stored.
    ///
    /// Errors: those of [`insert`](Self::insert), and for `fitted` a missing lattice or
    /// one of another size than the tile, a mask naming a segment the lattice lacks, a
    /// coefficient count other than the mask's nodes × channels.
    pub fn insert_with_lattice(
        &self,
        tile: usize,
        layers: &[TileRadiance],
        lattice: Option<TileLattice>,
        fitted: &[TileCoefficients],
    ) -> Result<()> {
        let slot = self
            .tiles
            .get(tile)
            .ok_or_else(|| RelumeError::IndexOutOfRange {
                what: "tile of the stack".into(),
                index: tile as u64,
                len: self.tiles.len(),
            })?;
        let rect = tile_rect(self.header.width, self.header.height, tile);
        if let Some(l) = &lattice {
            if l.size() != (rect.width, rect.height) {
                return Err(RelumeError::invalid(
                    format!("lattice of tile {tile}"),
                    format!(
                        "covers {:?} pixels; the tile is {}×{}",
                        l.size(),
                        rect.width,
                        rect.height
                    ),
                ));
            }
        }
        let mut order: Vec<(u32, u8, Source)> = layers
            .iter()
            .map(|r| (r.layer, r.channels, Source::Pixels(r.radiance)))
            .chain(
                fitted
                    .iter()
                    .map(|f| (f.layer, f.channels, Source::Lattice(f))),
            )
            .collect();
        order.sort_by_key(|(layer, _, _)| *layer);
        let mut entries = Vec::with_capacity(order.len());
        let mut values = TileValues::empty(self.header.precision);
        let mut previous = None;
        for (layer, given_channels, source) in order {
            let what = || format!("layer {layer} of tile {tile}");
            let Some((_, layer_channels)) = self.layers.get(layer as usize) else {
                return Err(RelumeError::IndexOutOfRange {
                    what: what(),
                    index: layer as u64,
                    len: self.layers.len(),
                });
            };
            if previous == Some(layer) {
                return Err(RelumeError::invalid(what(), "given twice"));
            }
            previous = Some(layer);
            if given_channels != 1 && given_channels != *layer_channels {
                return Err(RelumeError::invalid(
                    what(),
                    format!("{given_channels} channels for a layer of {layer_channels}"),
                ));
            }
            let c = given_channels as usize;
            let (data, segments) = match source {
                Source::Pixels(radiance) => {
                    if radiance.len() != rect.pixels() * c {
                        return Err(RelumeError::invalid(
                            what(),
                            format!(
                                "{} values; {} pixels × {c} channels expected",
                                radiance.len(),
                                rect.pixels()
                            ),
                        ));
                    }
                    (radiance, 0)
                }
                Source::Lattice(f) => {
                    let expected = lattice
                        .as_ref()
                        .and_then(|l| l.coefficient_count(f.segments, f.channels));
                    if expected != Some(f.coefficients.len()) {
                        return Err(RelumeError::invalid(
                            what(),
                            format!(
                                "{} lattice coefficients over segments {:#x}; the tile's lattice needs {expected:?}",
                                f.coefficients.len(),
                                f.segments
                            ),
                        ));
                    }
                    (f.coefficients, f.segments)
                }
            };
            // The last guard before the file: a value no stage should have let through is
            // stored as 0 and counted (the bake reports it), never the reason a bake is lost.
            let zeroed;
            let data = if data.iter().any(|v| !v.is_finite()) {
                zeroed = finite_or_zero(data, &self.non_finite);
                &zeroed[..]
            } else {
                data
            };
            if data.iter().all(|&v| v == 0.0) {
                continue;
            }
            let grey = segments == 0
                && c == 3
                && data.chunks_exact(3).all(|p| p[0] == p[1] && p[1] == p[2]);
            let channels = if grey { 1 } else { c };
            let offset = values.len() as u32;
            let kept = data.chunks_exact(c).flat_map(|p| &p[..channels]);
            let scale = match &mut values {
                TileValues::F32(out) => {
                    out.extend(kept);
                    1.0
                }
                TileValues::F16(out) => {
                    let max_abs = data.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                    let scale = f16_scale(max_abs);
                    if scale > 0.0 {
                        // The inverse in f64: for a subnormal scale 1/scale overflows f32
                        // (and 0 × inf would store NaN), while in f64 it is exact enough
                        // that every stored value stays within f16's range.
                        let inv = 1.0 / scale as f64;
                        out.extend(kept.map(|v| f16::from_f64(*v as f64 * inv)));
                    }
                    scale
                }
            };
            if scale == 0.0 {
                // Radiance so small that its scale underflows f32: nothing a relight could show.
                continue;
            }
            entries.push(TileLayer {
                layer,
                channels: channels as u8,
                scale,
                offset,
                segments,
            });
        }
        let lattice = lattice.filter(|_| entries.iter().any(|e| e.segments != 0));
        // The values grew as they came; the stack keeps them for the rest of the bake, so
        // they give back what the growth over-allocated.
        entries.shrink_to_fit();
        values.shrink_to_fit();
        let mut slot = slot.lock().unwrap_or_else(|p| p.into_inner());
        if slot.is_some() {
            return Err(RelumeError::invalid(
                format!("tile {tile}"),
                "inserted twice",
            ));
        }
        *slot = Some(StackTile {
            entries,
            values,
            lattice,
        });
        Ok(())
    }

    /// The stack, once every tile was inserted. A layer's own scale (what
    /// [`TiledStack::to_dense`] quantises to) is the largest of its entries' (1 when it has
    /// none, and always for f32).
    pub fn finish(self) -> Result<TiledStack> {
        let mut tiles = Vec::with_capacity(self.tiles.len());
        for (t, slot) in self.tiles.into_iter().enumerate() {
            match slot.into_inner().unwrap_or_else(|p| p.into_inner()) {
                Some(tile) => tiles.push(tile),
                None => {
                    return Err(RelumeError::invalid(
                        "tiled stack",
                        format!("tile {t} was never inserted"),
                    ))
                }
            }
        }
        let mut scales = vec![0.0f32; self.layers.len()];
        for tile in &tiles {
            for e in &tile.entries {
                let s = &mut scales[e.layer as usize];
                *s = s.max(e.scale);
            }
        }
        let stack = TiledStack {
            header: self.header,
            layers: self
                .layers
                .into_iter()
                .zip(scales)
                .map(|((key, channels), scale)| TiledLayerInfo {
                    key,
                    channels,
                    scale: if scale > 0.0 { scale } else { 1.0 },
                })
                .collect(),
            tiles,
        };
        validate(Path::new(""), &stack)?;
        Ok(stack)
    }
}

/// A lattice entry's values (before its scale) at every pixel of its tile, into `out`.
fn expand_lattice_entry(
    tile: &StackTile,
    e: &TileLayer,
    rect: TileRect,
    out: &mut Vec<f32>,
) -> Result<()> {
    let bad = || {
        format_err(
            Path::new(""),
            format!("a lattice entry of layer {} does not fit its tile", e.layer),
        )
    };
    let lattice = tile.lattice.as_ref().ok_or_else(bad)?;
    let count = lattice
        .coefficient_count(e.segments, e.channels)
        .ok_or_else(bad)?;
    if e.offset as usize + count > tile.values.len() || lattice.size() != (rect.width, rect.height)
    {
        return Err(bad());
    }
    out.clear();
    out.resize(rect.pixels() * e.channels as usize, 0.0);
    let start = e.offset as usize;
    lattice.reconstruct(e.segments, e.channels, |i| tile.values.get(start + i), out);
    Ok(())
}

/// The f16 scale of an entry whose largest magnitude is `max_abs` (finite): that magnitude
/// maps to 2¹⁴, leaving f16's range (65504) room for the rounding of a subnormal scale;
/// 0 when the scale underflows f32 (the entry is below anything a relight can show).
pub(crate) fn f16_scale(max_abs: f32) -> f32 {
    max_abs / 16384.0
}

/// `data` with every NaN or infinite value replaced by 0, adding how many to `count`.
fn finite_or_zero(data: &[f32], count: &AtomicU64) -> Vec<f32> {
    let mut zeroed = 0u64;
    let out = data
        .iter()
        .map(|&v| {
            if v.is_finite() {
                v
            } else {
                zeroed += 1;
                0.0
            }
        })
        .collect();
    count.fetch_add(zeroed, Ordering::Relaxed);
    out
}
