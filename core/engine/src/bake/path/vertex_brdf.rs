//! The three BRDFs a path vertex can have: the bake's basis values, the true Blinn–Phong
//! (reference), and the basis reconstruction of given materials (projected reference).

use glam::{Vec2, Vec3};

use crate::bake::path::frozen::{albedo_at, cos_half_angle};
pub use crate::bake::path::frozen::{blinn_phong_value, frozen_value};
use crate::bake::path::integrator::VertexBrdf;
use crate::bake::path::surface_brdf::SurfaceBrdf;
use crate::bake::prepare::context::{BakeContext, RegionModel};
use crate::brdf::{BlinnPhong, RegionBasis};
use crate::options::MAX_BASES;
use crate::{RelumeError, Result, Rgb};

/// The bake: every basis function of an editable region (the diffuse one times the albedo
/// texture), or the whole fixed BRDF ρ̂.
pub struct BasisBrdf<'a> {
    pub ctx: &'a BakeContext,
}

impl VertexBrdf for BasisBrdf<'_> {
    fn subsurface(&self) -> bool {
        true
    }

    /// Beyond the first bounce the bake sees the bake-time materials (the frozen tail).
    #[inline]
    fn tail(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb {
        frozen_value(self.ctx, region, uv, n, wi, wo)
    }

    /// The bake labels its tail vertices for the tail-edit layers.
    #[inline]
    fn tail_parts(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
    ) -> Option<(u16, [Rgb; 2])> {
        crate::bake::path::frozen::frozen_parts(self.ctx, region, uv, n, wi, wo)
    }

    /// One evaluation of the bake-time material for both.
    #[inline]
    fn tail_with_parts(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
    ) -> (Rgb, Option<(u16, [Rgb; 2])>) {
        crate::bake::path::frozen::frozen_value_and_parts(self.ctx, region, uv, n, wi, wo)
    }

    #[inline]
    fn tail_is_frozen(&self) -> bool {
        true
    }

    /// Bounces are labelled by the bake-time materials, as the tail sees them.
    #[inline]
    fn glossy_share(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> f32 {
        crate::bake::path::frozen::frozen_glossy_share(self.ctx, region, uv, n, wi, wo)
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
        crate::bake::path::frozen::frozen_value_and_share(self.ctx, region, uv, n, wi, wo, share)
    }

    #[inline]
    fn tail_with_parts_and_share(
        &self,
        region: u32,
        uv: Vec2,
        n: Vec3,
        wi: Vec3,
        wo: Vec3,
        share: bool,
    ) -> (Rgb, Option<(u16, [Rgb; 2])>, f32) {
        crate::bake::path::frozen::frozen_labelled(self.ctx, region, uv, n, wi, wo, share)
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
        let r = &self.ctx.regions[region as usize];
        match &r.model {
            RegionModel::Editable { basis, .. } => {
                let count = basis.count();
                let mut scratch = [0.0f32; MAX_BASES];
                basis.eval(n, wi, wo, &mut scratch[..count]);
                for (o, s) in out.iter_mut().zip(scratch.iter()).take(count) {
                    *o = Rgb::splat(*s);
                }
                if r.texture.is_some() {
                    out[0] *= albedo_at(r, uv);
                }
                if let Some(k) = basis.bake_lobe_slot() {
                    // The bake-time lobe, exactly (untextured: the basis refuses textures).
                    out[k] = r.frozen.value(Rgb::ONE, n, wi, wo);
                } else if r.slot_count as usize > count {
                    // The untextured constant slot of a textured region (see `BakeContext::lay_out`).
                    out[count] = Rgb::splat(scratch[0]);
                }
                (r.first_slot, r.slot_count as usize)
            }
            RegionModel::Fixed { material } => {
                out[0] = material.value(albedo_at(r, uv), n, wi, wo);
                (r.first_slot, 1)
            }
        }
    }
}

/// The reference: given materials for the editable regions (in editable order), evaluated
/// exactly (`projected == false`) or through the basis (`projected == true`, isolating
/// everything but the basis error). Every value goes to slot 0.
pub struct MaterialBrdf<'a> {
    ctx: &'a BakeContext,
    materials: Vec<BlinnPhong>,
    /// Basis coefficients per editable region (projected mode): Kd, Ks·c₀, Ks·c̃ᵢ (i ≥ 1).
    coefficients: Option<Vec<(Rgb, Rgb, Vec<Rgb>)>>,
}

impl<'a> MaterialBrdf<'a> {
    /// Materials of the editable regions, in editable order.
    pub fn new(ctx: &'a BakeContext, materials: Vec<BlinnPhong>, projected: bool) -> Result<Self> {
        let bases = ctx.editable_bases();
        if materials.len() != bases.len() {
            return Err(RelumeError::Materials(format!(
                "{} materials given for {} editable regions",
                materials.len(),
                bases.len()
            )));
        }
        let coefficients = if projected {
            let split = bases
                .iter()
                .zip(&materials)
                .map(|(b, m)| match b {
                    RegionBasis::BlinnPhong(b) => Ok(b.split_coefficients(m)),
                    RegionBasis::Principled(_) | RegionBasis::PrincipledWithBakeLobe(..) => {
                        Err(RelumeError::Materials(
                            "the projected reference reconstructs Blinn–Phong materials in the \
                         Blinn–Phong basis; this scene has a region baked with the Principled \
                         basis"
                                .into(),
                        ))
                    }
                })
                .collect::<Result<Vec<_>>>()?;
            Some(split)
        } else {
            None
        };
        Ok(MaterialBrdf {
            ctx,
            materials,
            coefficients,
        })
    }
}

impl MaterialBrdf<'_> {
    /// The diffuse and glossy parts of the given material at a vertex (their sum is
    /// [`VertexBrdf::tail`]).
    #[inline]
    fn parts(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> [Rgb; 2] {
        let r = &self.ctx.regions[region as usize];
        match &r.model {
            RegionModel::Fixed { material } => material.parts(albedo_at(r, uv), n, wi, wo),
            RegionModel::Editable { index, .. } => SurfaceBrdf::BlinnPhong(
                self.materials[*index as usize],
            )
            .parts(albedo_at(r, uv), n, wi, wo),
        }
    }
}

impl VertexBrdf for MaterialBrdf<'_> {
    /// The reference sees the given materials at every vertex, the exact Blinn–Phong even in
    /// projected mode: the frozen tail is part of what a relight is measured against.
    #[inline]
    fn tail(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> Rgb {
        let r = &self.ctx.regions[region as usize];
        match &r.model {
            RegionModel::Fixed { material } => material.value(albedo_at(r, uv), n, wi, wo),
            RegionModel::Editable { index, .. } => blinn_phong_value(
                &self.materials[*index as usize],
                albedo_at(r, uv),
                cos_half_angle(n, wi, wo),
            ),
        }
    }

    /// Bounces are labelled by the given materials, as its tail sees them.
    #[inline]
    fn glossy_share(&self, region: u32, uv: Vec2, n: Vec3, wi: Vec3, wo: Vec3) -> f32 {
        crate::bake::path::bounce_kinds::glossy_share(self.parts(region, uv, n, wi, wo))
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
        if !share {
            return (self.tail(region, uv, n, wi, wo), 0.0);
        }
        crate::bake::path::bounce_kinds::value_and_share(self.parts(region, uv, n, wi, wo), true)
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
        let r = &self.ctx.regions[region as usize];
        let cos_delta = cos_half_angle(n, wi, wo);
        out[0] = match &r.model {
            RegionModel::Fixed { material } => material.value(albedo_at(r, uv), n, wi, wo),
            RegionModel::Editable { index, basis } => {
                let e = *index as usize;
                match &self.coefficients {
                    None => blinn_phong_value(&self.materials[e], albedo_at(r, uv), cos_delta),
                    Some(coefs) => {
                        let count = basis.count();
                        let mut scratch = [0.0f32; MAX_BASES];
                        basis.eval(n, wi, wo, &mut scratch[..count]);
                        let (kd, ks_c0, rest) = &coefs[e];
                        let mut v = (*kd * albedo_at(r, uv) + *ks_c0) * scratch[0];
                        for i in 1..count {
                            v += rest[i - 1] * scratch[i];
                        }
                        v
                    }
                }
            }
        };
        (0, 1)
    }
}
