//! A path sink that relights as it goes: the light a path hands to each layer is multiplied
//! at once by that layer's weight for the current materials and lights, and summed — one
//! path's share of the relit image, as the stack would weigh it, with no stack kept.

use crate::bake::layout::{layer_key, DenseLayout};
use crate::bake::path::integrator::PathSink;
use crate::bake::prepare::context::BakeContext;
use crate::layer_key::PathVertex;
use crate::relight::{group_factors_of, layer_weight};
use crate::stack::StackHeader;
use crate::{RelumeError, Result, Rgb};

/// The weight of every dense layer of `ctx` (the bake's layout: per light group the world,
/// the slots, the slot pairs, the tail-edit layers) for the coefficients `coefs` (per
/// editable region, per slot), the part scales of the tail-edit layers and the light
/// groups' `gains`: [`layer_weight`] times the group's factor, the relight's arithmetic.
///
/// Errors when a layer names a coefficient `coefs` does not have or a light group `header`
/// does not have: the context was not laid out as the stack was.
pub fn dense_weights(
    ctx: &BakeContext,
    header: &StackHeader,
    coefs: &[Vec<Rgb>],
    part_scales: &[[Rgb; 2]],
    gains: Option<&[Rgb]>,
) -> Result<Vec<Rgb>> {
    let layers = ctx.lights.groups.len() * ctx.layers_per_group();
    let keys: Vec<_> = (0..layers).map(|i| layer_key(ctx, i)).collect();
    for key in &keys {
        for v in &key.path {
            if let PathVertex::Editable { region, basis }
            | PathVertex::Subsurface { region, basis } = *v
            {
                let known = coefs
                    .get(region as usize)
                    .is_some_and(|c| (basis as usize) < c.len());
                if !known {
                    return Err(RelumeError::invalid(
                        "scene",
                        format!(
                            "the scene lays out layer {} that the stack's bases do not \
                             have: it is not the scene the stack was baked from",
                            key.layer_name()
                        ),
                    ));
                }
            }
        }
    }
    let factors = group_factors_of(header, keys.iter(), gains)?;
    Ok(keys
        .iter()
        .map(|k| layer_weight(k, coefs, part_scales) * factors[k.light_group as usize])
        .collect())
}

/// Sums one path's light, each layer's times its weight ([`dense_weights`]).
pub struct WeightedSink<'a> {
    weights: &'a [Rgb],
    layout: DenseLayout,
    /// Whether the path hands over its tail-edit layers (the bake's model of the tail);
    /// not when the tail itself has the edited materials.
    tail_edits: bool,
    pub sum: Rgb,
    /// The eye hit (region, shading normal, position), for the correction's denoiser.
    pub eye: Option<(u32, glam::Vec3, glam::Vec3)>,
}

impl<'a> WeightedSink<'a> {
    pub fn new(ctx: &BakeContext, weights: &'a [Rgb], tail_edits: bool) -> Self {
        WeightedSink {
            weights,
            layout: DenseLayout::of(ctx),
            tail_edits,
            sum: Rgb::ZERO,
            eye: None,
        }
    }

    #[inline]
    fn add(&mut self, layer: usize, v: Rgb) {
        self.sum += self.weights[layer] * v;
    }
}

impl PathSink for WeightedSink<'_> {
    #[inline]
    fn world(&mut self, group: usize, v: Rgb) {
        self.add(self.layout.world(group), v);
    }
    #[inline]
    fn direct(&mut self, group: usize, slot: u32, v: Rgb) {
        self.add(self.layout.direct(group, slot), v);
    }
    #[inline]
    fn bounce(&mut self, group: usize, eye: u32, bounce: u32, v: Rgb) {
        self.add(self.layout.bounce(group, eye, bounce), v);
    }
    #[inline]
    fn eye_hit(&mut self, region: u32, normal: glam::Vec3, position: glam::Vec3) {
        self.eye = Some((region, normal, position));
    }
    #[inline]
    fn tail_edits(&self) -> bool {
        self.tail_edits
    }
    #[inline]
    fn tail_edit(&mut self, group: usize, eye: usize, region: usize, bin: usize, v: Rgb) {
        self.add(self.layout.tail_edit(group, eye, region, bin), v);
    }
}
