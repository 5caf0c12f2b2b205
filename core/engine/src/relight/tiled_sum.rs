//! The CPU relight sum over a [`TiledStack`]: `image = Σ weight · layer`, reading only the
//! layers each tile holds.
//!
//! The image layout is the dense relighter's ([`super::CpuRelighter::image`]): RGBA f32,
//! rows top-down, alpha 1. Tile rows run in parallel: each owns 16 image rows, handed out
//! with `par_chunks_mut`. Per tile, grey entries accumulate into planar R, G, B tiles and
//! RGB entries into an interleaved RGB tile with the dense relighter's kernels
//! ([`Kernels`]: f16 converted in registers or in small chunks, fused multiply-adds), and
//! the two are added into the image at the end — per pixel the same order of additions as
//! the dense sum, so both agree to rounding.
//!
//! Lattice entries ([`crate::stack::tiled::lattice`]) are summed in the lattice: each adds
//! weight × its coefficients into per-segment node accumulators (cost ∝ its coefficients,
//! not the tile's pixels), and the tile's nodes are expanded to pixels once, into the RGB
//! accumulators, before they are added to the image. The lattice is linear, so this equals
//! the relight of the same entries expanded to pixels ([`TiledStack::to_dense`]) to
//! rounding.

use half::slice::HalfFloatSliceExt;
use rayon::prelude::*;

use super::kernels::Kernels;
use super::layer_weight;
use crate::stack::tiled::{StackTile, TileValues, TiledStack, STACK_TILE};
use crate::{RelumeError, Result, Rgb};

/// Values per tile and channel.
const TILE_PIXELS: usize = (STACK_TILE * STACK_TILE) as usize;

/// Every layer's weight for `coefs[region][basis]`: [`layer_weight`] times the factor of
/// the layer's light group (`group_factors`, as [`super::group_factors`] gives for the
/// dense stack). Errors when a key names an editable region or basis outside `coefs` or a
/// light group outside `group_factors`.
pub fn layer_weights(
    stack: &TiledStack,
    coefs: &[Vec<Rgb>],
    group_factors: &[Rgb],
) -> Result<Vec<Rgb>> {
    stack
        .layers
        .iter()
        .map(|info| {
            let name = || info.key.layer_name();
            for v in &info.key.path {
                if let Some((r, b)) = v.slot() {
                    if coefs.get(r as usize).is_none_or(|c| b as usize >= c.len()) {
                        return Err(RelumeError::invalid(
                            format!("layer {}", name()),
                            format!("region {r}, basis {b} has no coefficient"),
                        ));
                    }
                }
            }
            let factor = group_factors
                .get(info.key.light_group as usize)
                .ok_or_else(|| RelumeError::IndexOutOfRange {
                    what: format!("light group of layer {}", name()),
                    index: info.key.light_group as u64,
                    len: group_factors.len(),
                })?;
            Ok(layer_weight(&info.key, coefs) * *factor)
        })
        .collect()
}

fn check_shapes(stack: &TiledStack, weights_len: usize, out: &[f32]) -> Result<()> {
    let (w, h) = (stack.header.width as usize, stack.header.height as usize);
    if weights_len != stack.layers.len() {
        return Err(RelumeError::invalid(
            "tiled relight weights",
            format!("{weights_len} weights for {} layers", stack.layers.len()),
        ));
    }
    if out.len() != w * h * 4 {
        return Err(RelumeError::invalid(
            "tiled relight image",
            format!("{} floats; {w}×{h} RGBA needs {}", out.len(), w * h * 4),
        ));
    }
    if stack.tiles.len() != stack.tile_count() {
        return Err(RelumeError::invalid(
            "tiled stack",
            format!(
                "{} tiles; its size needs {}",
                stack.tiles.len(),
                stack.tile_count()
            ),
        ));
    }
    Ok(())
}

/// Full relight: `out` (RGBA, see the module doc) becomes `Σ weights[l] · layer l` with
/// alpha 1. `weights` are per layer id, without the entries' scales (as
/// [`layer_weights`] gives them); a zero weight skips the layer's entries.
///
/// # Panics
/// If the stack's tables do not fit its values — impossible for a stack that passed
/// [`crate::stack::tiled::validate::validate`], as every constructor and the reader check.
pub fn full(stack: &TiledStack, weights: &[Rgb], out: &mut [f32]) -> Result<()> {
    full_with(stack, weights, out, Kernels::detect())
}

/// [`full`] with the inner loops of `kernels`.
pub(crate) fn full_with(
    stack: &TiledStack,
    weights: &[Rgb],
    out: &mut [f32],
    kernels: Kernels,
) -> Result<()> {
    check_shapes(stack, weights.len(), out)?;
    sum(stack, out, true, kernels, |tile, add| {
        for (k, e) in tile.entries.iter().enumerate() {
            let w = weights[e.layer as usize];
            if w != Rgb::ZERO {
                add(k, w);
            }
        }
    });
    Ok(())
}

/// Incremental relight: adds `delta · layer` to `out` for each `(layer id, delta)` of
/// `changed` (the change of those layers' weights since `out` was summed), reading only
/// their entries. Errors on a layer id out of range; panics as [`full`] does.
pub fn incremental(stack: &TiledStack, changed: &[(u32, Rgb)], out: &mut [f32]) -> Result<()> {
    incremental_with(stack, changed, out, Kernels::detect())
}

/// [`incremental`] with the inner loops of `kernels`.
pub(crate) fn incremental_with(
    stack: &TiledStack,
    changed: &[(u32, Rgb)],
    out: &mut [f32],
    kernels: Kernels,
) -> Result<()> {
    check_shapes(stack, stack.layers.len(), out)?;
    let mut changed: Vec<(u32, Rgb)> = changed
        .iter()
        .copied()
        .filter(|(_, d)| *d != Rgb::ZERO)
        .collect();
    if let Some((l, _)) = changed
        .iter()
        .find(|(l, _)| *l as usize >= stack.layers.len())
    {
        return Err(RelumeError::IndexOutOfRange {
            what: "changed layer of a tiled relight".into(),
            index: *l as u64,
            len: stack.layers.len(),
        });
    }
    // Layer order, as the full sum adds them.
    changed.sort_by_key(|(l, _)| *l);
    sum(stack, out, false, kernels, |tile, add| {
        for (l, delta) in &changed {
            if let Ok(k) = tile.entries.binary_search_by_key(l, |e| e.layer) {
                add(k, *delta);
            }
        }
    });
    Ok(())
}

/// Per-tile accumulators: planar R, G, B for grey entries, interleaved RGB for RGB ones.
struct Accumulators {
    r: [f32; TILE_PIXELS],
    g: [f32; TILE_PIXELS],
    b: [f32; TILE_PIXELS],
    rgb: [f32; 3 * TILE_PIXELS],
    /// Per segment, per lattice node, RGB: the tile's lattice entries summed.
    nodes: Vec<f32>,
    /// Scratch: an f16 lattice entry's coefficients as f32.
    coefficients: Vec<f32>,
}

/// Runs `select(tile, add)` for every tile, where `add(entry, weight)` adds
/// `weight · entry` into the tile's accumulators, then adds the accumulators into `out`
/// (after setting it to (0, 0, 0, 1) when `reset`; without `reset`, a tile where nothing
/// was added is left untouched).
fn sum<F>(stack: &TiledStack, out: &mut [f32], reset: bool, kernels: Kernels, select: F)
where
    F: Fn(&StackTile, &mut dyn FnMut(usize, Rgb)) + Sync,
{
    let width = stack.header.width as usize;
    let tiles_x = stack.tiles_x() as usize;
    let band = (STACK_TILE as usize * width * 4).max(4);
    out.par_chunks_mut(band).enumerate().for_each(|(ty, rows)| {
        let mut acc = Box::new(Accumulators {
            r: [0.0; TILE_PIXELS],
            g: [0.0; TILE_PIXELS],
            b: [0.0; TILE_PIXELS],
            rgb: [0.0; 3 * TILE_PIXELS],
            nodes: Vec::new(),
            coefficients: Vec::new(),
        });
        for tx in 0..tiles_x {
            let index = ty * tiles_x + tx;
            let tile = &stack.tiles[index];
            let rect = stack.tile_rect(index);
            let n = rect.pixels();
            let acc = &mut *acc;
            acc.r[..n].fill(0.0);
            acc.g[..n].fill(0.0);
            acc.b[..n].fill(0.0);
            acc.rgb[..3 * n].fill(0.0);
            let node_floats = tile
                .lattice
                .as_ref()
                .map_or(0, |l| l.segment_count() * l.node_count() * 3);
            acc.nodes.clear();
            acc.nodes.resize(node_floats, 0.0);
            let mut added = false;
            let mut lattice_added = false;
            select(tile, &mut |k, w| {
                added = true;
                let e = tile.entries[k];
                let w = (w * e.scale).to_array();
                let start = e.offset as usize;
                if e.segments != 0 {
                    lattice_added = true;
                    let lattice = tile
                        .lattice
                        .as_ref()
                        .expect("validated: a lattice entry's tile has a lattice");
                    let nodes = &mut acc.nodes;
                    let count = tile.value_count(&e, n);
                    match &tile.values {
                        TileValues::F16(v) => {
                            // Converted in one slice call (SIMD where the CPU has it), not
                            // one coefficient at a time.
                            acc.coefficients.resize(count, 0.0);
                            v[start..start + count].convert_to_f32_slice(&mut acc.coefficients);
                            let c = &acc.coefficients;
                            lattice.accumulate(nodes, e.segments, e.channels, c, w)
                        }
                        TileValues::F32(v) => lattice.accumulate(
                            nodes,
                            e.segments,
                            e.channels,
                            &v[start..start + count],
                            w,
                        ),
                    }
                } else if e.channels == 1 {
                    let (r, g, b) = (&mut acc.r[..n], &mut acc.g[..n], &mut acc.b[..n]);
                    match &tile.values {
                        TileValues::F16(v) => {
                            kernels.add_grey_planar(r, g, b, &v[start..start + n], w)
                        }
                        TileValues::F32(v) => {
                            kernels.add_grey_planar(r, g, b, &v[start..start + n], w)
                        }
                    }
                } else {
                    let rgb = &mut acc.rgb[..3 * n];
                    match &tile.values {
                        TileValues::F16(v) => {
                            kernels.add_rgb_interleaved(rgb, &v[start..start + 3 * n], w)
                        }
                        TileValues::F32(v) => {
                            kernels.add_rgb_interleaved(rgb, &v[start..start + 3 * n], w)
                        }
                    }
                }
            });
            if !reset && !added {
                continue;
            }
            if lattice_added {
                if let Some(lattice) = &tile.lattice {
                    lattice.expand(&acc.nodes, &mut acc.rgb[..3 * n]);
                }
            }
            let tw = rect.width as usize;
            for dy in 0..rect.height as usize {
                let row = &mut rows[(dy * width + rect.x0 as usize) * 4..][..tw * 4];
                for (dx, px) in row.chunks_exact_mut(4).enumerate() {
                    let i = dy * tw + dx;
                    if reset {
                        px.copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
                    }
                    px[0] += acc.r[i] + acc.rgb[3 * i];
                    px[1] += acc.g[i] + acc.rgb[3 * i + 1];
                    px[2] += acc.b[i] + acc.rgb[3 * i + 2];
                }
            }
        }
    });
}
