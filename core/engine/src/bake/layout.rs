//! Where each path signature sits among a bake's dense layer indices, and back: the one
//! index arithmetic that the bake's tiles, the memory probe and the assembly share.

use crate::bake::prepare::context::BakeContext;
use crate::layer_key::{LayerKey, PathVertex, BOUNCE_ELSEWHERE};
use crate::options::LightGrouping;

/// Where each path signature sits among a bake's dense layer indices: per light group the
/// world, one layer per slot, one per (eye slot, bounce slot) pair ([`layer_key`] inverts
/// it). Every sink that keeps layers densely (the bake's tiles, the memory probe) uses it.
#[derive(Clone, Copy)]
pub(crate) struct DenseLayout {
    slots: usize,
    /// Layers per light group.
    per_group: usize,
    /// Editable regions and bins (monomials of the part scales) of the tail-edit layers.
    regions: usize,
    bins: usize,
}

impl DenseLayout {
    pub(crate) fn of(ctx: &BakeContext) -> Self {
        DenseLayout {
            slots: ctx.slot_count(),
            per_group: ctx.layers_per_group(),
            regions: ctx.editable_count(),
            bins: ctx.tail_edit_bins(),
        }
    }
    #[inline]
    pub(crate) fn world(self, group: usize) -> usize {
        group * self.per_group
    }
    #[inline]
    pub(crate) fn direct(self, group: usize, slot: u32) -> usize {
        group * self.per_group + 1 + slot as usize
    }
    #[inline]
    pub(crate) fn bounce(self, group: usize, eye: u32, bounce: u32) -> usize {
        let s = self.slots;
        group * self.per_group + 1 + s + eye as usize * s + bounce as usize
    }
    /// The tail-edit layer of `group` for eye part `eye` (0: the fixed region, 1 + 2r + p:
    /// part p of editable region r), tail region `region` and bin `bin` (the monomial
    /// [`crate::bake::path::tail_edits::pair_of`] of `bin + 1`).
    #[inline]
    pub(crate) fn tail_edit(self, group: usize, eye: usize, region: usize, bin: usize) -> usize {
        let s = self.slots;
        let base = 1 + s + s * s;
        let within = (eye * self.regions + region) * self.bins + bin;
        group * self.per_group + base + within
    }
}

/// The key of dense layer index `layer` for `ctx`'s slots and light groups (light group
/// g + 1 in the key when the bake keeps groups apart, 0 when all lights share the layers).
pub fn layer_key(ctx: &BakeContext, layer: usize) -> LayerKey {
    let per_group = ctx.layers_per_group();
    let group = layer / per_group;
    let mut key = path_key(ctx, layer % per_group);
    if ctx.settings.light_grouping != LightGrouping::All {
        key.light_group = group as u16 + 1;
    }
    key
}

fn path_key(ctx: &BakeContext, layer: usize) -> LayerKey {
    let s = ctx.slot_count();
    if layer == 0 {
        LayerKey::new(vec![])
    } else if layer <= s {
        LayerKey::new(vec![ctx.slot_vertex[layer - 1]])
    } else if layer < 1 + s + s * s {
        let pair = layer - 1 - s;
        LayerKey::new(vec![ctx.slot_vertex[pair / s], ctx.slot_vertex[pair % s]])
    } else {
        tail_edit_key(ctx, layer - 1 - s - s * s)
    }
}

/// The key of tail-edit layer number `within` (see [`DenseLayout::tail_edit`]).
fn tail_edit_key(ctx: &BakeContext, within: usize) -> LayerKey {
    let regions = ctx.editable_count();
    let bins = ctx.tail_edit_bins();
    let (diffuse, glossy) = crate::bake::path::tail_edits::pair_of(within % bins + 1);
    let rest = within / bins;
    let region = rest % regions;
    let eye = rest / regions;
    let eye_vertex = if eye == 0 {
        PathVertex::Fixed
    } else {
        PathVertex::Part {
            region: ((eye - 1) / 2) as u16,
            part: ((eye - 1) % 2) as u8,
        }
    };
    LayerKey::new(vec![
        eye_vertex,
        PathVertex::TailEdit {
            region: region as u16,
            diffuse: diffuse as u8,
            glossy: glossy as u8,
            bounce: BOUNCE_ELSEWHERE,
        },
    ])
}
