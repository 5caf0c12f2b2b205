//! The loop over the entries of a tile whose lattice has one segment (most tiles of a
//! compressed stack): every lattice entry covers that segment, so the tile's grey lattice
//! entries are summed as the loop meets them, the segment's node rows held in registers by
//! [`EntryKernels::grey_stream`], instead of gathered first and summed segment by segment
//! after the loop ([`super::add_entries`]). Per-pixel grey entries are gathered as there;
//! RGB entries (rare) are gathered and added after the grey lattice entries, into rows of
//! their own, so the order of additions into every accumulator is the one of
//! [`super::add_entries`] and the image the same, bit for bit.

use super::gathered::Gathered;
use crate::relight::ahead::Ahead;
use crate::relight::kernels::{EntryKernels, GreyEntry, RgbEntry, Sample};
use crate::relight::tile_accumulators::TileAccumulators;
use crate::stack::tiled::{StackTile, TileLattice, TileLayer};
use crate::Rgb;

/// [`super::add_entries`] for a tile whose lattice (`lattice`) has one segment.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn add_entries_one_segment<'t, K: EntryKernels, S: Sample>(
    kernels: K,
    tile: &'t StackTile,
    lattice: &TileLattice,
    values: &[S],
    pixels: usize,
    entries: impl Iterator<Item = Option<(&'t TileLayer, Rgb)>>,
    acc: &mut TileAccumulators,
    ahead: Ahead,
) -> bool {
    acc.forget_rgb();
    let mut grey = std::mem::take(&mut acc.grey);
    let mut rgb = std::mem::take(&mut acc.rgb_entries);
    acc.clear_nodes(lattice);
    let seg = acc.segment(0);
    let nodes = seg.nodes;
    let lattice_bytes = nodes * std::mem::size_of::<S>();
    let stream = OneSegmentStream {
        entries,
        grey: Gathered::new(&mut grey, tile.entries.len()),
        rgb: Gathered::new(&mut rgb, tile.entries.len()),
        ahead,
        lattice_bytes,
        added: false,
        lattice_added: false,
    };
    let OneSegmentStream {
        mut ahead,
        added,
        lattice_added,
        ..
    } = kernels.grey_stream(seg.r, seg.g, seg.b, values, nodes, stream);
    for e in rgb.iter().filter(|e| e.lattice) {
        kernels.rgb(seg.rgb, &values[e.start..], 3 * nodes, e.weight);
    }
    for e in rgb.iter().filter(|e| !e.lattice) {
        if !acc.rgb_used() {
            acc.clear_rgb(pixels);
        }
        kernels.rgb(&mut acc.rgb, &values[e.start..], 3 * pixels, e.weight);
    }
    acc.rgb_entries = rgb;
    acc.finish_grey(kernels, values, pixels, grey, added, &mut ahead);
    if lattice_added {
        acc.expand_nodes(kernels, lattice);
    }
    added
}

/// The loop over the entries of a tile with one segment, as the iterator of its grey
/// lattice entries that [`EntryKernels::grey_stream`] sums: the other entries are gathered
/// on the way. A type of its own rather than a closure, so that `next` is inlined into the
/// kernel's loop (a call there would spill the kernel's register accumulators).
struct OneSegmentStream<'a, I> {
    entries: I,
    grey: Gathered<'a, GreyEntry>,
    rgb: Gathered<'a, RgbEntry>,
    ahead: Ahead,
    /// Bytes of one grey lattice entry's values.
    lattice_bytes: usize,
    /// Whether any entry, any lattice entry was met that is not skipped.
    added: bool,
    lattice_added: bool,
}

impl<'t, I: Iterator<Item = Option<(&'t TileLayer, Rgb)>>> Iterator for OneSegmentStream<'_, I> {
    type Item = Option<(usize, [f32; 3])>;

    /// The next entry: `Some((start, weight × scale))` for a grey lattice entry, `None` for
    /// one gathered or skipped.
    #[inline(always)]
    fn next(&mut self) -> Option<Option<(usize, [f32; 3])>> {
        let Some((e, w)) = self.entries.next()? else {
            return Some(None);
        };
        self.added = true;
        let weight = (w * e.scale).to_array();
        let start = e.offset as usize;
        if e.segments != 0 && e.channels == 1 {
            // A grey lattice entry (most entries): its row in the table and its values
            // reported read at once.
            self.lattice_added = true;
            self.ahead
                .read(std::mem::size_of::<TileLayer>() + self.lattice_bytes);
            return Some(Some((start, weight)));
        }
        self.ahead.read(std::mem::size_of::<TileLayer>());
        if e.segments == 0 {
            if e.channels == 1 {
                self.grey.push(GreyEntry { start, weight });
            } else {
                self.rgb.push(RgbEntry {
                    start,
                    weight,
                    lattice: false,
                });
            }
            return Some(None);
        }
        self.lattice_added = true;
        self.rgb.push(RgbEntry {
            start,
            weight,
            lattice: true,
        });
        Some(None)
    }
}
