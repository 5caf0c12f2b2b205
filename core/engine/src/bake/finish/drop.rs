//! Model only what the scene requires: which layers a stack keeps.
//!
//! Two kinds of layers are left out. Layers no path reached (a region never seen from
//! another, a basis pair no light connects) are all zero and never stored. With an error
//! budget ε > 0, layers whose *worst-case* contribution is negligible go too: for a layer l
//! with radiance L_l, the largest weight any material can give it is W_l, the product along
//! its path of the largest coefficient each slot can take (Kd, Ks ∈ [0, 1], ns anywhere in
//! the region's range; the fixed region counts 1), so its contribution to any relit image is
//! at most B_l = W_l·√c·‖L_l‖ (c = 3 for grey layers, whose RGB weight spreads over three
//! channels). Layers are dropped smallest B_l first while Σ B_l ≤ ε·‖I₀‖, I₀ the image at
//! the bake-time materials; by the triangle inequality the relit error of *any* edit is then
//! at most ε·‖I₀‖. The error dropping actually costs at the bake-time materials is measured
//! and reported beside the bound.

use serde::Serialize;

use crate::bake::prepare::context::{BakeContext, RegionModel};
use crate::brdf::RegionBasis;
use crate::bssrdf::region_slot_coefficients;
use crate::layer_key::{LayerKey, PathVertex};
use crate::scene::Scene;
use crate::{Result, Rgb};

/// A baked layer before storage: f32 radiance, 1 or 3 interleaved channels.
pub struct RawLayer {
    pub key: LayerKey,
    pub channels: u32,
    pub data: Vec<f32>,
}

/// Layers kept and left out for one region.
#[derive(Clone, Debug, Serialize)]
pub struct RegionLayers {
    /// The region's name, or "fixed (R̂)" for all fixed regions together.
    pub region: String,
    pub stored: usize,
    /// Layers on this region's paths that no path reached.
    pub dropped_unreached: usize,
    /// Layers left out under the error budget.
    pub dropped_negligible: usize,
}

/// What the bake kept, and what leaving the rest out costs.
#[derive(Clone, Debug, Serialize)]
pub struct DropReport {
    /// The error budget ε (relative L2 of the relit image); 0 keeps every reached layer.
    pub budget: f64,
    /// Σ B_l / ‖I₀‖ of the layers left out under the budget: the bound on any edit's error.
    pub bound: f64,
    /// ‖Σ w_l L_l‖ / ‖I₀‖ over the layers left out, at the bake-time materials.
    pub cost_at_bake_materials: f64,
    /// Names of the layers left out under the budget.
    pub dropped: Vec<String>,
    pub regions: Vec<RegionLayers>,
}

/// A coefficient bound that keeps a layer whatever the budget.
const UNBOUNDED: f32 = 1e15;

/// Largest |coefficient| each slot of each editable region can take (editable order).
fn max_coefficients(ctx: &BakeContext) -> Vec<Vec<f32>> {
    let mut out = Vec::new();
    for (ri, region) in ctx.regions.iter().enumerate() {
        let RegionModel::Editable { basis, .. } = &region.model else {
            continue;
        };
        let RegionBasis::BlinnPhong(basis) = basis else {
            // No bound is derived for a Principled basis' coefficients yet: a bound this
            // large keeps every layer of the region (a product of two stays finite in f32).
            out.push(vec![UNBOUNDED; region.slot_count as usize]);
            continue;
        };
        let n = basis.count();
        let cfg = basis.config();
        let mut spec = vec![0.0f32; n];
        let mut c = vec![0.0f32; n];
        for k in 0..=256 {
            let ns = cfg.ns_min * (cfg.ns_max / cfg.ns_min).powf(k as f32 / 256.0);
            basis.spec_coefficients(ns, &mut c);
            for (m, v) in spec.iter_mut().zip(&c) {
                *m = m.max(v.abs());
            }
        }
        let textured = region.slot_count as usize > n;
        let mut slots: Vec<f32> = spec.clone();
        // Kd ≤ 1 on the diffuse slot; with the constant in the specular fit, Ks·c₀ adds to it
        // (untextured) or has its own last slot (textured).
        slots[0] = if textured { 1.0 } else { 1.0 + spec[0] };
        if textured {
            slots.push(spec[0]);
        }
        if let Some(t) = &ctx.translucent[ri] {
            // The eye-diffuse slot is bounded like the diffuse one; subsurface layers are
            // never left out (their coefficients are not bounded by a simple product).
            slots.push(slots[0]);
            slots.extend(std::iter::repeat_n(1e30f32, t.basis.count()));
        }
        out.push(slots);
    }
    out
}

/// The product along `key`'s path of `per_slot` for slot vertices and `other` for the
/// tail-edit vertices (a part, a tail term); the fixed vertex counts `one`.
fn path_product<T: Copy>(
    key: &LayerKey,
    per_slot: &[Vec<T>],
    one: T,
    mul: impl Fn(T, T) -> T,
    other: impl Fn(&PathVertex) -> T,
) -> T {
    key.path.iter().fold(one, |w, v| match (v.slot(), v) {
        (_, PathVertex::Fixed) => w,
        (Some((region, basis)), _) => mul(w, per_slot[region as usize][basis as usize]),
        (None, v) => mul(w, other(v)),
    })
}

/// Per editable region, the largest scale each part (diffuse, glossy) can take against the
/// bake-time materials: Kd and Ks are at most 1, so a part scales by at most one over its
/// bake-time Kd or Ks (the smallest channel; the glossy energy the relight reads off the lobe
/// coefficients follows Ks), capped at 10³ (a part nearly absent at bake time keeps its
/// layers unless they are negligible even so).
fn max_part_scales(ctx: &BakeContext) -> Vec<[f32; 2]> {
    ctx.regions
        .iter()
        .filter(|r| matches!(r.model, RegionModel::Editable { .. }))
        .map(|r| {
            let (kd, ks) = match &r.frozen {
                crate::bake::path::surface_brdf::SurfaceBrdf::BlinnPhong(m) => (m.kd, m.ks),
                _ => ([0.0; 3], [0.0; 3]),
            };
            [kd, ks].map(|k| {
                let least = k.iter().copied().fold(f32::INFINITY, f32::min);
                if least > 0.0 {
                    (1.0 / least).clamp(1.0, 1e3)
                } else {
                    1e3
                }
            })
        })
        .collect()
}

/// The largest |weight| factor of a tail-edit vertex given each part's largest scale.
fn tail_vertex_bound(v: &PathVertex, scales: &[[f32; 2]]) -> f32 {
    let s = |region: u16| {
        scales
            .get(region as usize)
            .copied()
            .unwrap_or([UNBOUNDED; 2])
    };
    match *v {
        PathVertex::Part { region, part } => s(region)[part as usize & 1],
        PathVertex::TailEdit {
            region,
            diffuse,
            glossy,
            bounce,
        } => {
            let [d, g] = s(region);
            let b = match bounce {
                0 => d,
                1 => g,
                _ => 1.0,
            };
            (b * d.powi(diffuse as i32) * g.powi(glossy as i32)).clamp(1.0, UNBOUNDED)
        }
        _ => 1.0,
    }
}

/// The tint of the light group of `key` (see [`crate::stack::StackHeader::group_tint`]).
fn key_tint(ctx: &BakeContext, key: &LayerKey) -> Rgb {
    ctx.lights.groups[key.light_group.saturating_sub(1) as usize].tint
}

/// Slot coefficients of the editable regions' bake-time materials.
fn bake_time_coefficients(ctx: &BakeContext, scene: &Scene) -> Result<Vec<Vec<Rgb>>> {
    ctx.regions
        .iter()
        .zip(&scene.regions)
        .zip(&ctx.translucent)
        .filter_map(|((r, s), t)| match &r.model {
            RegionModel::Editable { basis, .. } => Some(region_slot_coefficients(
                basis,
                r.slot_count as usize > basis.count(),
                t.as_ref().map(|t| (&*t.basis, &t.info)),
                &s.material,
            )),
            RegionModel::Fixed { .. } => None,
        })
        .collect()
}

/// Per layer of `keys`, its weight in the image at the scene's bake-time materials (the
/// product of its slots' coefficients, times its light group's tint).
pub fn bake_time_weights(ctx: &BakeContext, scene: &Scene, keys: &[LayerKey]) -> Result<Vec<Rgb>> {
    let coefs = bake_time_coefficients(ctx, scene)?;
    Ok(keys
        .iter()
        .map(|key| {
            // At the bake-time materials every part scale is 1: a part weighs 1 and a
            // tail-edit term 0.
            let tail = |v: &PathVertex| match v {
                PathVertex::TailEdit { .. } => Rgb::ZERO,
                _ => Rgb::ONE,
            };
            path_product(key, &coefs, Rgb::ONE, |a, b| a * b, tail) * key_tint(ctx, key)
        })
        .collect())
}

/// A reached layer as the dropping sees it: its key, its channels as a whole (1: grey) and
/// the L2 norm of its radiance over the frame (of the stored channels).
pub struct LayerNorm {
    pub key: LayerKey,
    pub channels: u32,
    pub norm: f64,
}

/// Which of `layers` to leave out under `budget` (see the module docs), `reference` being
/// ‖I₀‖, the norm of the image at the bake-time materials; and the bound Σ B_l / ‖I₀‖ of
/// those left out.
pub fn choose_negligible(
    ctx: &BakeContext,
    layers: &[LayerNorm],
    reference: f64,
    budget: f64,
) -> (Vec<bool>, f64) {
    let mut leave = vec![false; layers.len()];
    let mut bound = 0.0f64;
    if budget > 0.0 && reference > 0.0 {
        let maxima = max_coefficients(ctx);
        let part_scales = max_part_scales(ctx);
        let mut order: Vec<(f64, usize)> = layers
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let w = path_product(
                    &l.key,
                    &maxima,
                    1.0f32,
                    |a, b| a * b,
                    |v| tail_vertex_bound(v, &part_scales),
                ) as f64;
                let spread = if l.channels == 1 { 3f64.sqrt() } else { 1.0 };
                (
                    w * key_tint(ctx, &l.key).max_element() as f64 * spread * l.norm,
                    i,
                )
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (b, i) in order {
            if (bound * reference + b) > budget * reference {
                break;
            }
            bound += b / reference;
            leave[i] = true;
        }
    }
    (leave, bound)
}

/// The report of what was kept and left out: `cost` is ‖Σ w_l L_l‖ / ‖I₀‖ over the layers
/// left out at the bake-time materials.
pub fn drop_report(
    ctx: &BakeContext,
    kept: &[LayerKey],
    dropped: &[LayerKey],
    unreached: &[LayerKey],
    budget: f64,
    bound: f64,
    cost: f64,
) -> DropReport {
    let holds = |key: &LayerKey, region: Option<u16>| match region {
        Some(r) => key.contains_region(r),
        None => key.path.contains(&PathVertex::Fixed),
    };
    let mut regions = Vec::new();
    let mut targets: Vec<(String, Option<u16>)> = ctx
        .regions
        .iter()
        .filter_map(|r| match &r.model {
            RegionModel::Editable { index, .. } => Some((r.name.clone(), Some(*index))),
            RegionModel::Fixed { .. } => None,
        })
        .collect();
    if ctx
        .regions
        .iter()
        .any(|r| matches!(r.model, RegionModel::Fixed { .. }))
    {
        targets.push(("fixed (R̂)".into(), None));
    }
    for (name, region) in targets {
        regions.push(RegionLayers {
            region: name,
            stored: kept.iter().filter(|k| holds(k, region)).count(),
            dropped_unreached: unreached.iter().filter(|k| holds(k, region)).count(),
            dropped_negligible: dropped.iter().filter(|k| holds(k, region)).count(),
        });
    }
    DropReport {
        budget,
        bound,
        cost_at_bake_materials: cost,
        dropped: dropped.iter().map(|k| k.layer_name()).collect(),
        regions,
    }
}
