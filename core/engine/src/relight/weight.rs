//! The weight of a layer for the current materials and lights: the product of the
//! coefficients along its path signature, times the factor of its light group. These two
//! functions are the whole of the relight's arithmetic on weights; the CPU and the GPU
//! relighters both use them (through [`super::RelightBookkeeping`]).

use super::part_scales::tail_edit_factor;
use crate::layer_key::{LayerKey, PathVertex};
use crate::stack::{StackHeader, TransferStack};
use crate::{RelumeError, Result, Rgb};

/// The weight of a layer: the product of the coefficients along its path, per RGB channel.
/// A [`crate::layer_key::PathVertex::Fixed`] vertex contributes 1 (its BRDF was baked in), and the empty path
/// (the world seen directly, layer `World`) has weight 1. A [`crate::layer_key::PathVertex::Subsurface`] vertex
/// weighs like an editable one: its `basis` is the region's coefficient slot. The light group is not part of
/// the weight (see [`group_factors`]).
///
/// A tail-edit layer's [`crate::layer_key::PathVertex::Part`] vertex weighs the part's
/// scale (`part_scales[region][part]`, [`super::part_scales`]) and its
/// [`crate::layer_key::PathVertex::TailEdit`] vertex s_b·(s_d^i·s_g^j − 1)
/// ([`super::part_scales::tail_edit_factor`]); with no scale for a region (an empty
/// `part_scales`) a part weighs 1 and a tail edit 0: the frozen tail.
///
/// # Panics
/// If a vertex names a region or basis outside `coefs`; the relighters check shapes
/// ([`super::StackShape`]) before calling it.
pub fn layer_weight(key: &LayerKey, coefs: &[Vec<Rgb>], part_scales: &[[Rgb; 2]]) -> Rgb {
    let scales = |region: u16| {
        part_scales
            .get(region as usize)
            .copied()
            .unwrap_or([Rgb::ONE; 2])
    };
    key.path.iter().fold(Rgb::ONE, |w, v| match *v {
        PathVertex::Fixed => w,
        PathVertex::Editable { region, basis } | PathVertex::Subsurface { region, basis } => {
            w * coefs[region as usize][basis as usize]
        }
        PathVertex::Part { region, part } => w * scales(region)[(part & 1) as usize],
        PathVertex::TailEdit {
            region,
            diffuse,
            glossy,
            bounce,
        } => w * tail_edit_factor(scales(region), diffuse, glossy, bounce),
    })
}

/// The factor of every layer-key light group (index 0: all lights; g + 1: group g): the
/// colour factored out of its layers at bake time, times the group's live `gains` (one per
/// group of the header, unit when `None`). A layer's weight is
/// `layer_weight(key, coefs, part_scales) · factors[key.light_group]`.
///
/// Errors: not one gain per light group of the header (the groups are listed), a gain that
/// is not finite, a factor that is not a finite non-negative colour, a layer that names a
/// light group the header does not have.
pub fn group_factors(stack: &TransferStack, gains: Option<&[Rgb]>) -> Result<Vec<Rgb>> {
    group_factors_of(&stack.header, stack.layers.iter().map(|l| &l.key), gains)
}

/// [`group_factors`] for any layout: the header and every layer's key, in layer order.
pub fn group_factors_of<'a>(
    header: &StackHeader,
    mut keys: impl Iterator<Item = &'a LayerKey>,
    gains: Option<&[Rgb]>,
) -> Result<Vec<Rgb>> {
    if let Some(gains) = gains {
        let groups = &header.light_groups;
        if gains.len() != groups.len() {
            return Err(RelumeError::invalid(
                "light group gains",
                format!(
                    "{} gains for {} light groups ({})",
                    gains.len(),
                    groups.len(),
                    groups
                        .iter()
                        .map(|g| g.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        if let Some(g) = gains.iter().find(|g| !g.is_finite()) {
            return Err(RelumeError::NonFinite {
                what: format!("light group gain {g}"),
            });
        }
    }
    let mut factors = vec![Rgb::from(header.light_tint)];
    for (k, group) in header.light_groups.iter().enumerate() {
        factors.push(Rgb::from(group.tint) * gains.map_or(Rgb::ONE, |g| g[k]));
    }
    if let Some(bad) = factors
        .iter()
        .find(|t| !t.is_finite() || t.min_element() < 0.0)
    {
        return Err(RelumeError::StackFormat {
            path: Default::default(),
            message: format!("light group factor {bad} is not a finite non-negative colour"),
        });
    }
    if let Some(key) = keys.find(|k| k.light_group as usize >= factors.len()) {
        return Err(RelumeError::StackFormat {
            path: Default::default(),
            message: format!(
                "layer {} names light group {} of {}",
                key.layer_name(),
                key.light_group,
                header.light_groups.len()
            ),
        });
    }
    Ok(factors)
}
