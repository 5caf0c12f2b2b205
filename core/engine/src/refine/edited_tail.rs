//! The vertex BRDF of a refinement's second trace: the first two vertices exactly as the
//! bake evaluates them (every basis value, so the relight's weights apply), the tail with
//! the edited materials, up to the bake's bounce cap.

use glam::{Vec2, Vec3};

use crate::bake::path::frozen::{albedo_at, frozen_value};
use crate::bake::path::integrator::VertexBrdf;
use crate::bake::path::surface_brdf::SurfaceBrdf;
use crate::bake::path::vertex_brdf::BasisBrdf;
use crate::bake::prepare::context::{BakeContext, RegionModel};
use crate::brdf::MaterialSpec;
use crate::options::MAX_BASES;
use crate::{RelumeError, Result, Rgb};

/// [`BasisBrdf`] at the keyed vertices; beyond them each editable region has its edited
/// material, built as the bake builds a region's bake-time one
/// ([`crate::bake::prepare::context::PreparedRegion::frozen`]): exactly (Cycles'
/// Principled) where the region's basis holds its bake-time lobe, its Blinn–Phong mapping
/// where the basis is Blinn–Phong. At the bake-time materials its tail is the bake's.
///
/// Its paths go on past the bounces baked to `bounces`, the bake's cap: a bounce budget
/// leaves out later bounces that hold little light at the bake-time materials, and an edit
/// that brightens a material can make them matter (a grey ground made white under a
/// bunny: the ground–bunny bounces past the second).
pub struct EditedTailBrdf<'a> {
    basis: BasisBrdf<'a>,
    /// Per editable region (editable order), its edited surface.
    edited: Vec<SurfaceBrdf>,
    /// The last bounce its paths reach ([`crate::stack::StackHeader::refine_bounces`]).
    bounces: u32,
}

impl<'a> EditedTailBrdf<'a> {
    /// `materials`: one per editable region of `ctx`, in editable order; `bounces`: the
    /// last bounce to trace (at least the bake's own, `ctx.settings.bounces`).
    pub fn new(ctx: &'a BakeContext, materials: &[MaterialSpec], bounces: u32) -> Result<Self> {
        let mut edited = Vec::with_capacity(materials.len());
        for r in &ctx.regions {
            if let RegionModel::Editable { index, basis } = &r.model {
                let Some(m) = materials.get(*index as usize) else {
                    return Err(RelumeError::Materials(format!(
                        "{} materials given for {} editable regions",
                        materials.len(),
                        ctx.editable_count()
                    )));
                };
                edited.push(if basis.bake_lobe_slot().is_some() {
                    SurfaceBrdf::exact(m)
                } else {
                    SurfaceBrdf::BlinnPhong(m.to_blinn_phong())
                });
            }
        }
        if edited.len() != materials.len() {
            return Err(RelumeError::Materials(format!(
                "{} materials given for {} editable regions",
                materials.len(),
                edited.len()
            )));
        }
        Ok(EditedTailBrdf {
            basis: BasisBrdf { ctx },
            edited,
            bounces: bounces.max(ctx.settings.bounces),
        })
    }
}

impl VertexBrdf for EditedTailBrdf<'_> {
    fn subsurface(&self) -> bool {
        self.basis.subsurface()
    }

    #[inline]
    fn bounces(&self, _baked: u32) -> u32 {
        self.bounces
    }

    #[inline]
    fn tail(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb {
        let ctx = self.basis.ctx;
        let r = &ctx.regions[region as usize];
        match &r.model {
            RegionModel::Editable { index, .. } => {
                self.edited[*index as usize].value(albedo_at(r, uv), n, wi, wo)
            }
            RegionModel::Fixed { .. } => frozen_value(ctx, region, uv, n, wi, wo),
        }
    }

    /// Bounces are labelled by the edited materials, as the edited tail sees them: an edit
    /// that makes a region glossy lets paths go on past the diffuse limit as Cycles does.
    #[inline]
    fn glossy_share(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> f32 {
        let ctx = self.basis.ctx;
        let r = &ctx.regions[region as usize];
        match &r.model {
            RegionModel::Editable { index, .. } => crate::bake::path::bounce_kinds::glossy_share(
                self.edited[*index as usize].parts(albedo_at(r, uv), n, wi, wo),
            ),
            RegionModel::Fixed { .. } => {
                crate::bake::path::frozen::frozen_glossy_share(ctx, region, uv, n, wi, wo)
            }
        }
    }

    #[inline]
    fn tail_and_share(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
        share: bool,
    ) -> (Rgb, f32) {
        let ctx = self.basis.ctx;
        let r = &ctx.regions[region as usize];
        match &r.model {
            RegionModel::Editable { index, .. } if share => {
                crate::bake::path::bounce_kinds::value_and_share(
                    self.edited[*index as usize].parts(albedo_at(r, uv), n, wi, wo),
                    true,
                )
            }
            RegionModel::Editable { .. } => (self.tail(region, uv, n, wi, wo), 0.0),
            RegionModel::Fixed { .. } => {
                crate::bake::path::frozen::frozen_value_and_share(ctx, region, uv, n, wi, wo, share)
            }
        }
    }

    #[inline]
    fn eval(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
        out: &mut [Rgb; MAX_BASES],
    ) -> (u32, usize) {
        self.basis.eval(region, uv, n, wi, wo, out)
    }
}
