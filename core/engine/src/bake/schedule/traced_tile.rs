//! One tile as the streaming bake ([`super::stream`]) holds it between tracing and
//! finalising: its pixels' eye features and, per layer with a non-zero sum there, the
//! averaged radiance — one channel where the layer is grey over the tile (equal R, G and B
//! at every pixel), else RGB. The grey form holds the same values (the first channel of
//! each pixel, which equals the other two) in a third of the bytes; the tiles in flight
//! are most of the bake's memory besides the stack.

use super::adaptive::{features_as_of_spp, trace_adaptive};
use super::tiles::Tile;
use super::trace::trace_tile_records;
use crate::bake::finish::denoise::FEATURE_STRIDE;
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::BakeContext;
use crate::bake::settings::AdaptiveSampling;
use crate::progress::Progress;
use crate::stack::tiled::TileRect;
use crate::{RelumeError, Result, Rgb};

/// One layer's averages over a traced tile: the tile's pixels row-major, `channels`
/// (1: grey, 3: RGB) interleaved.
pub(crate) struct TracedLayer {
    pub id: u32,
    pub channels: u8,
    pub data: Vec<f32>,
}

/// One traced tile: its non-zero layers (sorted by id) and its pixels' eye-feature records.
pub(crate) struct TracedTile {
    pub rect: TileRect,
    /// Eye samples per pixel it was traced with: the bake's `spp`, or fewer where adaptive
    /// sampling stopped it ([`super::adaptive`]).
    pub samples: u32,
    pub features: Vec<f32>,
    pub layers: Vec<TracedLayer>,
    /// Each pixel's [reach](crate::bake::finish::reach), the denoiser's one feature that
    /// costs rays: computed once per tile by the stream when it filters (empty until then),
    /// so the windows that overlap on a tile row do not trace it again.
    pub reach: Vec<f32>,
}

impl TracedTile {
    /// Bytes its features and layers hold.
    pub fn bytes(&self) -> usize {
        4 * (self.features.len() + self.layers.iter().map(|l| l.data.len()).sum::<usize>())
    }

    pub fn layer(&self, id: u32) -> Option<&TracedLayer> {
        self.layers
            .binary_search_by_key(&id, |l| l.id)
            .ok()
            .map(|i| &self.layers[i])
    }
}

pub(crate) fn rect_of(tile: &Tile) -> TileRect {
    TileRect {
        x0: tile.x0,
        y0: tile.y0,
        width: tile.width,
        height: tile.height,
    }
}

/// Traces all `spp` samples of `tile` (the canonical tree's root per pixel), or with
/// `adaptive` (its settings and the layers' bake-time weights) as many as
/// [`super::adaptive`] takes, and keeps the sparse averages.
pub(crate) fn trace_sparse(
    ctx: &BakeContext,
    brdf: &BasisBrdf,
    tile: &Tile,
    spp: u32,
    adaptive: Option<(AdaptiveSampling, &[Rgb])>,
    progress: &Progress,
    rays: &std::sync::atomic::AtomicU64,
) -> Result<TracedTile> {
    let (buf, samples) = match adaptive {
        None => (
            trace_tile_records(ctx, brdf, 1, true, tile, 0..spp, progress, rays)?
                .ok_or(RelumeError::Cancelled)?,
            spp,
        ),
        Some((settings, weights)) => {
            let t = trace_adaptive(ctx, brdf, tile, spp, settings, weights, progress, rays)?;
            (t.records, t.samples)
        }
    };
    let layer_count = ctx.layer_count();
    let record = layer_count * 3 + FEATURE_STRIDE;
    let tp = tile.pixels();
    let mut features =
        crate::memory::try_with_capacity(tp * FEATURE_STRIDE, "a tile's eye features")?;
    for p in 0..tp {
        let at = p * record + layer_count * 3;
        features.extend_from_slice(&buf[at..at + FEATURE_STRIDE]);
    }
    features_as_of_spp(&mut features, samples, spp);
    // Which layers are non-zero somewhere in the tile, in one pass over the records in
    // memory order (a layer's texels lie a whole record apart).
    let mut non_zero = vec![false; layer_count];
    for p in 0..tp {
        let texels = &buf[p * record..p * record + layer_count * 3];
        for (seen, texel) in non_zero.iter_mut().zip(texels.chunks_exact(3)) {
            *seen |= texel.iter().any(|v| *v != 0.0);
        }
    }
    let mut layers = Vec::new();
    for layer in (0..layer_count).filter(|l| non_zero[*l]) {
        layers.push(traced_layer(layer as u32, tp, samples, |p| {
            let at = p * record + layer * 3;
            [buf[at], buf[at + 1], buf[at + 2]]
        })?);
    }
    Ok(TracedTile {
        rect: rect_of(tile),
        samples,
        features,
        layers,
        reach: Vec::new(),
    })
}

/// One layer's averages over a tile of `tp` pixels from its per-pixel RGB `sums` of `spp`
/// samples: one channel when the averages are grey over the tile, else RGB. Shared by the
/// bake's own tiles and a farm merge's, so both hold the same bits.
pub(crate) fn traced_layer(
    id: u32,
    tp: usize,
    spp: u32,
    sums: impl Fn(usize) -> [f32; 3],
) -> Result<TracedLayer> {
    let inv_spp = 1.0 / spp as f32;
    let average = |p: usize| {
        let [r, g, b] = sums(p);
        [r * inv_spp, g * inv_spp, b * inv_spp]
    };
    // Grey by the averages' own comparison, as the stack's grey test makes it.
    let grey = (0..tp).all(|p| {
        let [r, g, b] = average(p);
        r == g && g == b
    });
    let channels = if grey { 1 } else { 3 };
    let mut data = crate::memory::try_with_capacity(tp * channels, "a tile's layer averages")?;
    for p in 0..tp {
        data.extend_from_slice(&average(p)[..channels]);
    }
    Ok(TracedLayer {
        id,
        channels: channels as u8,
        data,
    })
}

/// A tile finished from its summed samples (a farm merge's): `features` are the pixels'
/// feature sums, `layers` each layer's per-pixel RGB sums (sorted by id); layers zero over
/// the tile are left out, as [`trace_sparse`] leaves them.
pub(crate) fn traced_from_sums(
    rect: TileRect,
    features: Vec<f32>,
    layers: &[(u32, Vec<f32>)],
    spp: u32,
) -> Result<TracedTile> {
    let tp = rect.pixels();
    let mut out = Vec::new();
    for (id, sums) in layers {
        if sums.iter().any(|v| *v != 0.0) {
            out.push(traced_layer(*id, tp, spp, |p| {
                [sums[3 * p], sums[3 * p + 1], sums[3 * p + 2]]
            })?);
        }
    }
    Ok(TracedTile {
        rect,
        samples: spp,
        features,
        layers: out,
        reach: Vec::new(),
    })
}
