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

use crate::bake::context::{BakeContext, RegionModel};
use crate::bssrdf::region_slot_coefficients;
use crate::layer_key::{LayerKey, PathVertex};
use crate::scene::Scene;
use crate::Rgb;

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

/// Largest |coefficient| each slot of each editable region can take (editable order).
fn max_coefficients(ctx: &BakeContext) -> Vec<Vec<f32>> {
    let mut out = Vec::new();
    for (ri, region) in ctx.regions.iter().enumerate() {
        let RegionModel::Editable { basis, .. } = &region.model else {
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

fn path_product<T: Copy>(
    key: &LayerKey,
    per_slot: &[Vec<T>],
    one: T,
    mul: impl Fn(T, T) -> T,
) -> T {
    key.path.iter().fold(one, |w, v| match v.slot() {
        None => w,
        Some((region, basis)) => mul(w, per_slot[region as usize][basis as usize]),
    })
}

fn norm(data: &[f32]) -> f64 {
    data.iter()
        .map(|v| (*v as f64) * (*v as f64))
        .sum::<f64>()
        .sqrt()
}

/// Adds `w·layer` into the RGB image `acc`.
fn accumulate(acc: &mut [f64], layer: &RawLayer, w: Rgb) {
    let w = [w.x as f64, w.y as f64, w.z as f64];
    if layer.channels == 1 {
        for (px, v) in acc.chunks_exact_mut(3).zip(&layer.data) {
            for c in 0..3 {
                px[c] += w[c] * *v as f64;
            }
        }
    } else {
        for (i, v) in layer.data.iter().enumerate() {
            acc[i] += w[i % 3] * *v as f64;
        }
    }
}

/// The tint of the light group of `key` (see [`crate::stack::StackHeader::group_tint`]).
fn key_tint(ctx: &BakeContext, key: &LayerKey) -> Rgb {
    ctx.lights.groups[key.light_group.saturating_sub(1) as usize].tint
}

/// Slot coefficients of the editable regions' bake-time materials.
fn bake_time_coefficients(ctx: &BakeContext, scene: &Scene) -> Vec<Vec<Rgb>> {
    let coefs = ctx
        .regions
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
        .collect();
    coefs
}

/// The relit image (RGB, f64) of `layers` at the scene's bake-time materials.
pub fn bake_time_image(ctx: &BakeContext, scene: &Scene, layers: &[RawLayer]) -> Vec<f64> {
    let coefs = bake_time_coefficients(ctx, scene);
    let pixels = (ctx.resolution.width * ctx.resolution.height) as usize;
    let mut image = vec![0.0f64; pixels * 3];
    for layer in layers {
        accumulate(
            &mut image,
            layer,
            path_product(&layer.key, &coefs, Rgb::ONE, |a, b| a * b) * key_tint(ctx, &layer.key),
        );
    }
    image
}

/// Leaves out the layers whose worst-case contribution fits in `budget` (see the module
/// docs) and reports, per region, what was kept, unreached and left out. `full` is
/// [`bake_time_image`] of `layers`.
pub fn drop_negligible(
    ctx: &BakeContext,
    scene: &Scene,
    layers: Vec<RawLayer>,
    full: &[f64],
    unreached: &[LayerKey],
    budget: f64,
) -> (Vec<RawLayer>, DropReport) {
    let pixels = (ctx.resolution.width * ctx.resolution.height) as usize;
    let bake_coefs = bake_time_coefficients(ctx, scene);
    let weight = |key: &LayerKey| {
        path_product(key, &bake_coefs, Rgb::ONE, |a, b| a * b) * key_tint(ctx, key)
    };
    let reference = full.iter().map(|v| v * v).sum::<f64>().sqrt();

    let mut kept = layers;
    let mut dropped: Vec<RawLayer> = Vec::new();
    let mut bound = 0.0f64;
    if budget > 0.0 && reference > 0.0 {
        let maxima = max_coefficients(ctx);

        let mut order: Vec<(f64, usize)> = kept
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let w = path_product(&l.key, &maxima, 1.0f32, |a, b| a * b) as f64;
                let spread = if l.channels == 1 { 3f64.sqrt() } else { 1.0 };
                (
                    w * key_tint(ctx, &l.key).max_element() as f64 * spread * norm(&l.data),
                    i,
                )
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut leave = vec![false; kept.len()];
        for (b, i) in order {
            if (bound * reference + b) > budget * reference {
                break;
            }
            bound += b / reference;
            leave[i] = true;
        }
        let mut k = Vec::new();
        for (i, l) in kept.into_iter().enumerate() {
            if leave[i] {
                dropped.push(l);
            } else {
                k.push(l);
            }
        }
        kept = k;
    }
    let mut lost = vec![0.0f64; pixels * 3];
    for layer in &dropped {
        accumulate(&mut lost, layer, weight(&layer.key));
    }
    let cost = if reference > 0.0 {
        lost.iter().map(|v| v * v).sum::<f64>().sqrt() / reference
    } else {
        0.0
    };

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
            stored: kept.iter().filter(|l| holds(&l.key, region)).count(),
            dropped_unreached: unreached.iter().filter(|k| holds(k, region)).count(),
            dropped_negligible: dropped.iter().filter(|l| holds(&l.key, region)).count(),
        });
    }
    let report = DropReport {
        budget,
        bound,
        cost_at_bake_materials: cost,
        dropped: dropped.iter().map(|l| l.key.layer_name()).collect(),
        regions,
    };
    (kept, report)
}
