//! The bake-time material at a path vertex: what the bake sees beyond the first bounce (the
//! frozen tail) and what Russian roulette steers by, for the bake, the reference render and
//! the bounce pre-pass alike. A leaf of the bake: the integrator and the three vertex BRDFs
//! ([`super::vertex_brdf`]) both read it.

use glam::{Vec2, Vec3};
use std::f32::consts::FRAC_1_PI;

use crate::bake::prepare::context::{BakeContext, PreparedRegion, RegionModel};
use crate::brdf::{blinn_phong::lobe, BlinnPhong};
use crate::Rgb;

#[inline]
pub(crate) fn cos_half_angle(n: Vec3, wi: Vec3, wo: Vec3) -> f32 {
    let h = (wi + wo).normalize_or_zero();
    n.dot(h)
}

#[inline]
pub(crate) fn albedo_at(region: &PreparedRegion, uv: Vec2) -> Rgb {
    match &region.texture {
        Some(t) => t.lookup(uv.x, uv.y),
        None => Rgb::ONE,
    }
}

/// The true Blinn–Phong value of `m` with the diffuse part scaled by `albedo`.
#[inline]
pub fn blinn_phong_value(m: &BlinnPhong, albedo: Rgb, cos_delta: f32) -> Rgb {
    Rgb::from(m.kd) * albedo * FRAC_1_PI
        + Rgb::from(m.ks) * lobe(m.ns as f64, cos_delta as f64) as f32
}

/// The bake-time BRDF value of scene region `region` (its [`PreparedRegion::frozen`]
/// material, the diffuse part times its albedo texture): what the bake sees at vertices
/// beyond the first bounce, and what picks Russian roulette there for bake and reference
/// alike.
#[inline]
pub fn frozen_value(ctx: &BakeContext, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb {
    let r = &ctx.regions[region as usize];
    r.frozen.value(albedo_at(r, uv), n, wi, wo)
}

/// The probability that a bounce along `wi` from region `region` is a glossy one at its
/// bake-time material ([`crate::bake::path::bounce_kinds`]): the glossy part of
/// [`frozen_value`] over the whole, by Cycles' own split of the material (not the basis').
#[inline]
pub fn frozen_glossy_share(
    ctx: &BakeContext,
    region: u32,
    uv: Vec2,
    n: Vec3,
    wi: Vec3,
    wo: Vec3,
) -> f32 {
    let r = &ctx.regions[region as usize];
    crate::bake::path::bounce_kinds::glossy_share(r.frozen.parts(albedo_at(r, uv), n, wi, wo))
}

/// [`frozen_value`] and, when `share`, [`frozen_glossy_share`] (0 otherwise) from one
/// evaluation of the material: a tail vertex needs both where a per-kind limit binds.
#[inline]
pub fn frozen_value_and_share(
    ctx: &BakeContext,
    region: u32,
    uv: Vec2,
    n: Vec3,
    wi: Vec3,
    wo: Vec3,
    share: bool,
) -> (Rgb, f32) {
    let r = &ctx.regions[region as usize];
    value_and_share_at(r, albedo_at(r, uv), n, wi, wo, share)
}

/// A region's bake-time value and, when `share`, its glossy share (0 otherwise) at a point
/// whose texture albedo is `albedo`: the value alone costs no split into parts.
#[inline]
fn value_and_share_at(
    r: &PreparedRegion,
    albedo: Rgb,
    n: Vec3,
    wi: Vec3,
    wo: Vec3,
    share: bool,
) -> (Rgb, f32) {
    if share {
        crate::bake::path::bounce_kinds::value_and_share(r.frozen.parts(albedo, n, wi, wo), true)
    } else {
        (r.frozen.value(albedo, n, wi, wo), 0.0)
    }
}

/// [`frozen_value`] of an editable region as its diffuse and glossy parts, with the
/// region's editable index; `None` for a fixed region (its material is never edited). The
/// diffuse part is the diffuse basis slot's bake-time coefficient over π (times the
/// texture), the glossy part the rest — which can dip below zero away from the lobe where
/// the basis put the specular fit's constant into the diffuse slot: the split is the
/// basis's, so each part scales as the relight reads it off the coefficients.
#[inline]
pub fn frozen_parts(
    ctx: &BakeContext,
    region: u32,
    uv: Vec2,
    n: Vec3,
    wi: Vec3,
    wo: Vec3,
) -> Option<(u16, [Rgb; 2])> {
    match ctx.regions[region as usize].model {
        RegionModel::Editable { .. } => frozen_value_and_parts(ctx, region, uv, n, wi, wo).1,
        RegionModel::Fixed { .. } => None,
    }
}

/// [`frozen_value`] and [`frozen_parts`] from one evaluation of the material (a fixed
/// region's parts are `None`, as there).
#[inline]
pub fn frozen_value_and_parts(
    ctx: &BakeContext,
    region: u32,
    uv: Vec2,
    n: Vec3,
    wi: Vec3,
    wo: Vec3,
) -> (Rgb, Option<(u16, [Rgb; 2])>) {
    let (value, parts, _) = frozen_labelled(ctx, region, uv, n, wi, wo, false);
    (value, parts)
}

/// [`frozen_value_and_parts`] and, when `share`, [`frozen_glossy_share`] (0 otherwise), all
/// from one evaluation of the material.
#[inline]
#[allow(clippy::type_complexity)]
pub fn frozen_labelled(
    ctx: &BakeContext,
    region: u32,
    uv: Vec2,
    n: Vec3,
    wi: Vec3,
    wo: Vec3,
    share: bool,
) -> (Rgb, Option<(u16, [Rgb; 2])>, f32) {
    let r = &ctx.regions[region as usize];
    let albedo = albedo_at(r, uv);
    let (value, share) = value_and_share_at(r, albedo, n, wi, wo, share);
    match r.model {
        RegionModel::Editable { index, .. } => {
            let diffuse = r.tail_diffuse * albedo * FRAC_1_PI;
            (value, Some((index, [diffuse, value - diffuse])), share)
        }
        RegionModel::Fixed { .. } => (value, None, share),
    }
}
