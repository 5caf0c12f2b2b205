//! The CPU relight sum over a [`TiledStack`]: `image = Σ weight · layer`, reading only the
//! layers each tile holds.
//!
//! The image layout is the dense relighter's ([`super::CpuRelighter::image`]): RGBA f32,
//! rows top-down, alpha 1. Tile rows run in parallel: each owns 16 image rows, handed out
//! with `par_chunks_mut`. Per tile, grey entries accumulate into planar R, G, B tiles and
//! RGB entries into an interleaved RGB tile ([`TileAccumulators`]) with the kernels of
//! [`super::kernels`] (f16 converted in registers or in small chunks, fused multiply-adds),
//! and the two are added into the image at the end — per pixel the same order of additions
//! as the dense sum, so both agree to rounding. Grey per-pixel entries are gathered and
//! summed a few per pass over the rows (`EntryKernels::grey_rows`).
//!
//! A tile's values are not read front to back (per-pixel entries in groups, lattice entries
//! segment by segment), which the hardware prefetchers follow poorly, so the loads waited
//! on memory. A full sum therefore walks the next tile's values with prefetches while it
//! sums the current tile, paced by what the current tile's loops read (`super::ahead`). An
//! incremental one reads little of each tile: an edit of one region, whose entries are
//! listed per tile (`super::region_entries`), asks at once for the next tile's listed values and
//! pixels; the other incremental sums fetch nothing ahead.
//!
//! Lattice entries ([`crate::stack::tiled::lattice`]) are summed in the lattice: each adds
//! weight × its coefficients into per-segment node accumulators (cost ∝ its coefficients,
//! not the tile's pixels; one contiguous run per covered segment). RGB ones are added as
//! they come; grey ones (most of them) are gathered and summed segment by segment, the
//! segment's node rows held in registers across the entries. The tile's nodes are then
//! expanded to pixels once, into the planar accumulators, before they are added to the
//! image. The lattice is linear, so this equals the relight of the same entries expanded
//! to pixels ([`TiledStack::to_dense`]) to rounding.
//!
//! In a tile whose lattice has one segment (most tiles), the grey lattice entries are not
//! gathered: they are summed as the loop over the entries meets them (`one_segment`), the
//! same additions in the same order.
//!
//! A tile holds hundreds of small entries at many editable materials, so what an entry
//! costs besides its values matters as much as the values: the sum of a tile (its entries,
//! then the image add) is one function per implementation of the kernels and sample type,
//! the kernels inlined into it (compiled with AVX2 where that is the implementation, and
//! with AVX-512F and VL besides for the kernels with 512-bit steps and 32 registers),
//! with no dynamic dispatch or precision match per entry, and nothing called inside the
//! loops that keep accumulators in registers (a call would have them spilled).

use rayon::prelude::*;

mod gathered;
mod one_segment;

use gathered::Gathered;
use one_segment::add_entries_one_segment;

use super::ahead::{fetch_range, Ahead};
use super::kernels::{EntryKernels, GreyEntry, Kernels, PendingEntry, Portable, Sample};
use super::layer_weight;
use super::region_entries::RegionEntries;
use super::tile_accumulators::TileAccumulators;
use super::tile_output::TileOutputKernels;
use crate::stack::tiled::{StackTile, TileLayer, TileRect, TileValues, TiledStack, STACK_TILE};
use crate::{RelumeError, Result, Rgb};

/// Every layer's weight for `coefs[region][basis]`: [`layer_weight`] times the factor of
/// the layer's light group (`group_factors`, as [`super::group_factors`] gives for the
/// dense stack). Errors when a key names an editable region or basis outside `coefs` or a
/// light group outside `group_factors`.
pub fn layer_weights(
    stack: &TiledStack,
    coefs: &[Vec<Rgb>],
    group_factors: &[Rgb],
) -> Result<Vec<Rgb>> {
    let scales = if super::part_scales::has_tail_edits(stack.layers.iter().map(|l| &l.key)) {
        let mut scales = super::part_scales::PartScales::for_header(&stack.header)?;
        scales.set(coefs);
        scales.scales().to_vec()
    } else {
        Vec::new()
    };
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
            Ok(layer_weight(&info.key, coefs, &scales) * *factor)
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
    sum(
        stack,
        out,
        true,
        kernels,
        &PerLayerTable { factors: weights },
    );
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
    if changed.len() < DENSE_CHANGE_SHARE * stack.layers.len() / 100 {
        sum(
            stack,
            out,
            false,
            kernels,
            &SearchedLayers { changed: &changed },
        );
        return Ok(());
    }
    // A layer changed twice adds both deltas, as the search would find its entry twice.
    let mut deltas: Vec<Rgb> = crate::memory::try_zeroed(stack.layers.len(), "relight deltas")?;
    for (l, d) in &changed {
        deltas[*l as usize] += *d;
    }
    sum(
        stack,
        out,
        false,
        kernels,
        &PerLayerTable { factors: &deltas },
    );
    Ok(())
}

/// [`incremental`] of an edit of one region: adds `deltas[layer] · layer` for the entries
/// `entries` lists in each tile (the region's layers' entries; a zero delta is skipped),
/// without walking the tables. The same additions in the same order as [`incremental`] with
/// those layers and deltas.
pub(crate) fn incremental_listed(
    stack: &TiledStack,
    entries: &RegionEntries,
    deltas: &[Rgb],
    out: &mut [f32],
    kernels: Kernels,
) -> Result<()> {
    check_shapes(stack, deltas.len(), out)?;
    sum(
        stack,
        out,
        false,
        kernels,
        &ListedEntries { entries, deltas },
    );
    Ok(())
}

/// Share of the stack's layers (in %) from which an incremental sum looks each entry's
/// layer up in a table of deltas instead of searching each changed layer in each tile: the
/// tile's table is then walked once, as the full sum walks it, rather than searched once per
/// changed layer.
const DENSE_CHANGE_SHARE: usize = 5;

/// Which of a tile's entries a sum adds, and with what weight. An iterator rather than a
/// callback, so the entry loop's body stays in the function compiled for the kernels (a
/// closure is a function of its own, and not always inlined).
trait EntrySelection: Sync {
    /// Asks the memory for the values that summing tile `index` (`tile`, `pixels` pixels)
    /// will read, at once, while the tile before it is summed; whether it asked for any. By
    /// default nothing is asked.
    #[inline(always)]
    fn fetch(&self, _index: usize, _tile: &StackTile, _pixels: usize) -> bool {
        false
    }
    /// Whether [`entries`](Self::entries) has an item for every entry of the tile (a table
    /// walk) rather than for a few looked up.
    const WALKS_EVERY_ENTRY: bool;
    /// One item per candidate entry of `tile`, in entry order: `Some((entry, weight))` for one
    /// to add, `None` for one skipped. Skipped entries are items rather than filtered out so
    /// that the loops over them stay one loop: a filter nests a loop inside the entry loop,
    /// around which the compiler spills the kernels' register accumulators.
    fn entries<'t>(
        &'t self,
        index: usize,
        tile: &'t StackTile,
    ) -> impl Iterator<Item = Option<(&'t TileLayer, Rgb)>> + 't;
}

/// Every entry whose layer has a non-zero factor in a per-layer table: the weights for a
/// full sum, or the weight deltas (0 for an unchanged layer) for an incremental sum of many
/// layers, where walking the tile's table beats a search per changed layer.
struct PerLayerTable<'a> {
    factors: &'a [Rgb],
}

impl EntrySelection for PerLayerTable<'_> {
    const WALKS_EVERY_ENTRY: bool = true;
    #[inline(always)]
    fn entries<'t>(
        &'t self,
        _index: usize,
        tile: &'t StackTile,
    ) -> impl Iterator<Item = Option<(&'t TileLayer, Rgb)>> + 't {
        tile.entries.iter().map(|e| {
            let f = self.factors[e.layer as usize];
            (f != Rgb::ZERO).then_some((e, f))
        })
    }
}

/// An incremental sum of few layers: the entries of the changed layers (sorted by layer,
/// non-zero deltas), found by binary search in the tile's sorted table.
struct SearchedLayers<'a> {
    changed: &'a [(u32, Rgb)],
}

impl EntrySelection for SearchedLayers<'_> {
    const WALKS_EVERY_ENTRY: bool = false;
    #[inline(always)]
    fn entries<'t>(
        &'t self,
        _index: usize,
        tile: &'t StackTile,
    ) -> impl Iterator<Item = Option<(&'t TileLayer, Rgb)>> + 't {
        self.changed.iter().map(|(l, delta)| {
            let k = tile.entries.binary_search_by_key(l, |e| e.layer).ok()?;
            Some((&tile.entries[k], *delta))
        })
    }
}

/// An edit of one region: the entries its layers have in each tile, listed once per region
/// ([`RegionEntries`]), with the per-layer weight changes.
struct ListedEntries<'a> {
    entries: &'a RegionEntries,
    deltas: &'a [Rgb],
}

impl EntrySelection for ListedEntries<'_> {
    const WALKS_EVERY_ENTRY: bool = false;
    fn fetch(&self, index: usize, tile: &StackTile, pixels: usize) -> bool {
        let (base, size) = (tile.values.address(), tile.values.sample_bytes());
        let listed = self.entries.of_tile(index);
        for &k in listed {
            let e = &tile.entries[usize::from(k)];
            let n = tile.value_count(e, pixels);
            fetch_range(base + e.offset as usize * size, n * size);
        }
        !listed.is_empty()
    }
    #[inline(always)]
    fn entries<'t>(
        &'t self,
        index: usize,
        tile: &'t StackTile,
    ) -> impl Iterator<Item = Option<(&'t TileLayer, Rgb)>> + 't {
        self.entries.of_tile(index).iter().map(|&k| {
            let e = &tile.entries[usize::from(k)];
            let d = self.deltas[e.layer as usize];
            (d != Rgb::ZERO).then_some((e, d))
        })
    }
}

/// Adds the selected entries of every tile into its accumulators, then the accumulators
/// into `out` (after setting it to (0, 0, 0, 1) when `reset`; without `reset`, a tile where
/// nothing was added is left untouched).
fn sum<Sel: EntrySelection>(
    stack: &TiledStack,
    out: &mut [f32],
    reset: bool,
    kernels: Kernels,
    select: &Sel,
) {
    let width = stack.header.width as usize;
    let tiles_x = stack.tiles_x() as usize;
    let band = (STACK_TILE as usize * width * 4).max(4);
    out.par_chunks_mut(band).enumerate().for_each(|(ty, rows)| {
        let mut acc = TileAccumulators::new();
        for tx in 0..tiles_x {
            let index = ty * tiles_x + tx;
            let tile = &stack.tiles[index];
            let rect = stack.tile_rect(index);
            // A full sum reads (nearly) all of the next tile's values: fetch them while this
            // tile is summed, paced. An edit's sum reads a few of them, scattered: the
            // selection asks for those it knows without a search (a region's listed
            // entries), at once, and then for the next tile's pixels it adds to. (The next
            // tile is the next tile row's first at the end of a row, which this worker
            // usually sums next.)
            let ahead = match stack.tiles.get(index + 1) {
                Some(next) if reset => Ahead::over(&next.values, tile_bytes(tile)),
                Some(next) => {
                    let next_rect = stack.tile_rect(index + 1);
                    if select.fetch(index + 1, next, next_rect.pixels()) && tx + 1 < tiles_x {
                        for dy in 0..next_rect.height as usize {
                            let at = &rows[(dy * width + next_rect.x0 as usize) * 4..];
                            let row_bytes = next_rect.width as usize * 16;
                            fetch_range(at.as_ptr() as usize, row_bytes);
                        }
                    }
                    Ahead::default()
                }
                _ => Ahead::default(),
            };
            let image = TileImage {
                index,
                rect,
                width,
                reset,
                rows,
            };
            sum_tile(kernels, tile, select, &mut acc, ahead, image);
        }
        kernels.end_of_band();
    });
}

/// A tile's pixels in the image: `rows` are its tile row's image rows (RGBA, `width`
/// pixels each); `reset`: they are set to (0, 0, 0, 1) before the tile's sum is added.
struct TileImage<'a> {
    /// The tile's index in the stack.
    index: usize,
    rect: TileRect,
    width: usize,
    reset: bool,
    rows: &'a mut [f32],
}

/// Sums the selected entries of `tile` into `acc` and adds that into its pixels of the
/// image, with the loops compiled for `kernels` and the tile's sample type.
fn sum_tile<Sel: EntrySelection>(
    kernels: Kernels,
    tile: &StackTile,
    select: &Sel,
    acc: &mut TileAccumulators,
    ahead: Ahead,
    image: TileImage,
) {
    match (kernels, &tile.values) {
        (Kernels::Portable, TileValues::F16(v)) => {
            sum_tile_with(Portable, tile, v, select, acc, ahead, image)
        }
        (Kernels::Portable, TileValues::F32(v)) => {
            sum_tile_with(Portable, tile, v, select, acc, ahead, image)
        }
        // SAFETY: an `Avx2` exists only where the CPU has AVX2, FMA and F16C.
        #[cfg(target_arch = "x86_64")]
        (Kernels::Avx2(k), TileValues::F16(v)) => unsafe {
            avx2::sum_tile(k, tile, v, select, acc, ahead, image)
        },
        #[cfg(target_arch = "x86_64")]
        (Kernels::Avx2(k), TileValues::F32(v)) => unsafe {
            avx2::sum_tile(k, tile, v, select, acc, ahead, image)
        },
        // SAFETY: an `Avx512` is made only where the CPU also has AVX-512F and VL.
        #[cfg(target_arch = "x86_64")]
        (Kernels::Avx512(k), TileValues::F16(v)) => unsafe {
            avx2::sum_tile_wide(k, tile, v, select, acc, ahead, image)
        },
        #[cfg(target_arch = "x86_64")]
        (Kernels::Avx512(k), TileValues::F32(v)) => unsafe {
            avx2::sum_tile_wide(k, tile, v, select, acc, ahead, image)
        },
    }
}

/// [`sum_tile`] for one implementation of the kernels and sample type.
#[inline(always)]
fn sum_tile_with<K: EntryKernels, S: Sample, Sel: EntrySelection>(
    kernels: K,
    tile: &StackTile,
    values: &[S],
    select: &Sel,
    acc: &mut TileAccumulators,
    ahead: Ahead,
    image: TileImage,
) {
    let pixels = image.rect.pixels();
    // A tile nothing selects (most tiles of an edit's incremental sum) costs nothing, not
    // even a look at its lattice, unless the selection walks the tile's whole table anyway
    // (a full sum, or an edit of many layers): then the entry loop walks it once, without a
    // look for a first entry ahead of it, and a tile where it adds nothing is left as is.
    let added = if Sel::WALKS_EVERY_ENTRY {
        add_entries(
            kernels,
            tile,
            values,
            pixels,
            select.entries(image.index, tile),
            acc,
            ahead,
        )
    } else {
        let mut entries = select.entries(image.index, tile);
        match entries.by_ref().flatten().next() {
            Some(first) => {
                let entries = std::iter::once(Some(first)).chain(entries);
                add_entries(kernels, tile, values, pixels, entries, acc, ahead)
            }
            None => false,
        }
    };
    if added {
        acc.fold_rgb(pixels);
        add_to_image(
            kernels,
            acc,
            image.rect,
            image.width,
            image.reset,
            image.rows,
        );
    } else if image.reset {
        clear_image(kernels, image.rect, image.width, image.rows);
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Ahead, EntrySelection, Sample, StackTile, TileAccumulators, TileImage};
    use crate::relight::kernels::{Avx2, Avx512};

    /// [`super::add_entries`] with the AVX2 kernels, compiled with those features so the
    /// kernels inline into the entry loop.
    ///
    /// # Safety
    /// The CPU has AVX2, FMA and F16C.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn sum_tile<S: Sample, Sel: EntrySelection>(
        kernels: Avx2,
        tile: &StackTile,
        values: &[S],
        select: &Sel,
        acc: &mut TileAccumulators,
        ahead: Ahead,
        image: TileImage,
    ) {
        super::sum_tile_with(kernels, tile, values, select, acc, ahead, image)
    }

    /// [`sum_tile`] with the kernels that take 512-bit steps, compiled with AVX-512F and
    /// AVX-512VL as well, for those steps and 32 vector registers
    /// ([`crate::relight::kernels::Kernels::Avx512`]).
    ///
    /// # Safety
    /// The CPU has AVX2, FMA, F16C, AVX-512F and AVX-512VL.
    #[target_feature(enable = "avx2,fma,f16c,avx512f,avx512vl")]
    pub(super) unsafe fn sum_tile_wide<S: Sample, Sel: EntrySelection>(
        kernels: Avx512,
        tile: &StackTile,
        values: &[S],
        select: &Sel,
        acc: &mut TileAccumulators,
        ahead: Ahead,
        image: TileImage,
    ) {
        super::sum_tile_with(kernels, tile, values, select, acc, ahead, image)
    }
}

/// Bytes a full sum of `tile` reads: its values and its entry table.
fn tile_bytes(tile: &StackTile) -> usize {
    tile.values.bytes() + std::mem::size_of_val(&tile.entries[..])
}

/// The entry loop of one tile: each of `entries` (`(entry index, weight)`, as
/// [`EntrySelection::entries`] gives them) times its weight and scale into the per-pixel or
/// node accumulators, then the nodes expanded to pixels. The planar rows are set by the grey
/// entries' sum (zeroed when there are none) and the RGB row is zeroed at the first RGB
/// entry, so a tile without RGB entries never touches the RGB row.
#[inline(always)]
fn add_entries<'t, K: EntryKernels, S: Sample>(
    kernels: K,
    tile: &'t StackTile,
    values: &[S],
    pixels: usize,
    entries: impl Iterator<Item = Option<(&'t TileLayer, Rgb)>>,
    acc: &mut TileAccumulators,
    mut ahead: Ahead,
) -> bool {
    if let Some(lattice) = tile.lattice.as_ref().filter(|l| l.segment_count() == 1) {
        return add_entries_one_segment(
            kernels, tile, lattice, values, pixels, entries, acc, ahead,
        );
    }
    let mut added = false;
    let mut lattice_added = false;
    acc.forget_rgb();
    // Grey per-pixel entries are gathered, then summed a few per pass over the rows; grey
    // lattice entries (most of a compressed stack's entries) are gathered, then summed per
    // segment with that segment's rows in registers.
    let mut grey = std::mem::take(&mut acc.grey);
    let mut pending = std::mem::take(&mut acc.pending);
    let mut pending_segments = 0u32;
    let mut grey_in = Gathered::new(&mut grey, tile.entries.len());
    let mut pending_in = Gathered::new(&mut pending, tile.entries.len());
    for (e, w) in entries.flatten() {
        ahead.read(std::mem::size_of::<TileLayer>());
        added = true;
        let w = (w * e.scale).to_array();
        let start = e.offset as usize;
        if e.segments == 0 {
            if e.channels == 1 {
                grey_in.push(GreyEntry { start, weight: w });
            } else {
                if !acc.rgb_used() {
                    acc.clear_rgb(pixels);
                }
                kernels.rgb(&mut acc.rgb, &values[start..], 3 * pixels, w);
            }
            continue;
        }
        if !lattice_added {
            let lattice = tile
                .lattice
                .as_ref()
                .expect("validated: a lattice entry's tile has a lattice");
            acc.clear_nodes(lattice);
            lattice_added = true;
        }
        if e.channels == 1 {
            pending_in.push(PendingEntry {
                cursor: start,
                segments: e.segments,
                weight: w,
            });
            pending_segments |= e.segments;
            continue;
        }
        let mut at = start;
        let mut bits = e.segments;
        while bits != 0 {
            let s = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let seg = acc.segment(s);
            kernels.rgb(seg.rgb, &values[at..], 3 * seg.nodes, w);
            at += 3 * seg.nodes;
        }
    }
    let mut bits = pending_segments;
    while bits != 0 {
        let s = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        let seg = acc.segment(s);
        kernels.grey_many(
            seg.r,
            seg.g,
            seg.b,
            values,
            seg.nodes,
            1 << s,
            &mut pending,
            &mut ahead,
        );
    }
    acc.pending = pending;
    acc.finish_grey(kernels, values, pixels, grey, added, &mut ahead);
    if lattice_added {
        if let Some(lattice) = &tile.lattice {
            acc.expand_nodes(kernels, lattice);
        }
    }
    added
}

/// Adds a tile's planar sums (with the RGB sums folded in: [`TileAccumulators::fold_rgb`])
/// into its pixels of `rows` (the tile row's image rows).
#[inline(always)]
fn add_to_image<K: TileOutputKernels>(
    kernels: K,
    acc: &TileAccumulators,
    rect: TileRect,
    width: usize,
    reset: bool,
    rows: &mut [f32],
) {
    let tw = rect.width as usize;
    for dy in 0..rect.height as usize {
        let row = &mut rows[(dy * width + rect.x0 as usize) * 4..][..tw * 4];
        let i0 = dy * tw;
        let (r, g, b) = (
            &acc.r[i0..i0 + tw],
            &acc.g[i0..i0 + tw],
            &acc.b[i0..i0 + tw],
        );
        kernels.image_row(row, r, g, b, reset);
    }
}

/// Sets a tile's pixels of `rows` to (0, 0, 0, 1).
#[inline(always)]
fn clear_image<K: TileOutputKernels>(kernels: K, rect: TileRect, width: usize, rows: &mut [f32]) {
    const ZERO: [f32; STACK_TILE as usize] = [0.0; STACK_TILE as usize];
    let tw = rect.width as usize;
    for dy in 0..rect.height as usize {
        let row = &mut rows[(dy * width + rect.x0 as usize) * 4..][..tw * 4];
        kernels.image_row(row, &ZERO[..tw], &ZERO, &ZERO, true);
    }
}
