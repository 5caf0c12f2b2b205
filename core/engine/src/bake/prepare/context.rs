//! What a bake and its reference render share: geometry, camera, lights, and per region its
//! BRDF model and the *slots* — the (region, basis) pairs a path vertex can take.
//!
//! Slots are numbered editable region by editable region (each with its basis count), then
//! one slot for the fixed region R̂. A layer is a sequence of slots.

use std::collections::HashMap;
use std::sync::Arc;

use crate::bake::path::guide::GuideField;
use crate::bake::path::mixture::DirectionMixture;
use crate::bake::path::surface_brdf::SurfaceBrdf;
use crate::bake::prepare::subsurface::{self, TranslucentRegion};
use crate::bake::settings::BakeSettings;
use crate::brdf::principled_basis::PrincipledBasis;
use crate::brdf::{BasisConfig, BrdfBasis, MaterialSpec, RegionBasis};
use crate::bssrdf::{SssBasis, SubsurfaceInfo};
use crate::geometry::{bvh::SceneGeometry, camera::CameraRays, lights::LightSet, texture::Texture};
use crate::layer_key::PathVertex;
use crate::options::{MAX_BASES, MAX_GROUPS};
use crate::scene::{validate::validate_scene, validate::ValidationReport, Resolution, Scene};
use crate::Rgb;
use crate::{RelumeError, Result};

/// How a region reflects.
#[derive(Clone)]
pub enum RegionModel {
    /// Editable region number `index`, in the basis `basis`.
    Editable { index: u16, basis: RegionBasis },
    /// Part of the fixed region R̂ with this BRDF.
    Fixed { material: SurfaceBrdf },
}

/// A region ready for the integrator.
#[derive(Clone)]
pub struct PreparedRegion {
    pub name: String,
    pub model: RegionModel,
    /// Albedo texture on the diffuse part.
    pub texture: Option<Texture>,
    /// First slot and slot count of this region.
    pub first_slot: u32,
    pub slot_count: u32,
    /// The cosine-and-lobes mixture its indirect directions are drawn from (unused by
    /// uniform sampling; always used beyond the first bounce).
    pub mixture: DirectionMixture,
    /// Its bake-time material: what the bake evaluates at path vertices beyond the first
    /// bounce (the "frozen tail", see [`crate::bake::path::integrator`]), editable regions included
    /// (theirs as the mapped Blinn–Phong, see [`SurfaceBrdf`]).
    pub frozen: SurfaceBrdf,
    /// An editable region's bake-time coefficient of its diffuse basis slot (Kd, plus the
    /// constant of the specular fit when the basis puts it there): the part of the frozen
    /// BRDF the tail-edit layers call diffuse, so that it scales exactly as the relight's
    /// diffuse scale reads it off the coefficients ([`crate::relight::part_scales`]).
    /// Zero for a fixed region.
    pub tail_diffuse: Rgb,
}

/// Everything fixed for a bake.
pub struct BakeContext {
    pub geometry: SceneGeometry,
    pub camera: CameraRays,
    pub lights: LightSet,
    pub regions: Vec<PreparedRegion>,
    /// Path vertex of every slot.
    pub slot_vertex: Vec<PathVertex>,
    pub resolution: Resolution,
    pub settings: BakeSettings,
    pub clip_end: f32,
    /// The guide maps of a guided bake (built by [`BakeContext::build_guide`] when the
    /// settings ask for [`crate::options::IndirectSampling::Guided`]).
    pub guide: Option<GuideField>,
    /// Per scene region, its subsurface data when it is translucent (editable with a
    /// subsurface block or Subsurface Weight > 0).
    pub translucent: Vec<Option<TranslucentRegion>>,
    /// Per scene region, the global slot its diffuse basis uses *at the eye*: the region's
    /// eye-diffuse slot when translucent, its first slot otherwise.
    pub eye_diffuse_slot: Vec<u32>,
    /// What the bounce pre-pass measured when the settings asked for the bounce count the
    /// scene needs ([`crate::bake::prepare::bounces`]); `None` when the count was taken as given.
    pub bounce_estimate: Option<crate::bake::prepare::bounce_budget::BounceEstimate>,
    /// What the bake's threads kept finite so far ([`crate::bake::non_finite`]).
    pub non_finite: crate::bake::non_finite::NonFiniteCounter,
}

impl BakeContext {
    /// Validates `scene` and `settings`, builds (and shares between regions) the BRDF and
    /// subsurface bases, lays out the slots, the lights, the BVH and the camera: everything
    /// that traces nothing. The traced set-up steps (the light entering translucent regions,
    /// the bounce pre-pass, the guide pass) follow in [`super::setup`]. Stops with
    /// [`RelumeError::Cancelled`] soon after `progress` is cancelled.
    pub fn lay_out(
        scene: &Scene,
        settings: &BakeSettings,
        progress: &crate::progress::Progress,
    ) -> Result<(BakeContext, ValidationReport)> {
        settings.validate()?;
        let mut report = validate_scene(scene)?;
        let resolution = settings.resolution.unwrap_or(scene.resolution);
        let mut bases: HashMap<String, Arc<BrdfBasis>> = HashMap::new();
        let mut sss_bases: HashMap<String, Arc<SssBasis>> = HashMap::new();
        let mut translucent: Vec<Option<TranslucentRegion>> = Vec::new();
        let mut regions = Vec::with_capacity(scene.regions.len());
        let mut slot_vertex = Vec::new();
        let mut editable_index = 0u16;
        for (region_index, region) in scene.regions.iter().enumerate() {
            progress.check()?;
            translucent.push(None);
            let texture = region.albedo_texture.as_ref().and_then(Texture::from_ref);
            let material = region.material.to_blinn_phong();
            if region.editable {
                let cfg = basis_config_for(&settings.basis, region.ns_range);
                let basis = match principled_basis_for(settings, region, texture.is_some()) {
                    Ok(Some(pcfg)) => {
                        let b = PrincipledBasis::shared(pcfg)?;
                        let MaterialSpec::Principled(p) = &region.material else {
                            unreachable!("principled_basis_for takes Principled materials only")
                        };
                        let lobe = Arc::new(b.bake_lobe(&p.bsdf));
                        RegionBasis::PrincipledWithBakeLobe(b, lobe)
                    }
                    other => {
                        if let Err(why) = other {
                            report.warnings.push(why);
                        }
                        let key = serde_json::to_string(&cfg).unwrap_or_default();
                        RegionBasis::BlinnPhong(match bases.get(&key) {
                            Some(b) => b.clone(),
                            None => {
                                let b = Arc::new(BrdfBasis::build(&cfg)?);
                                bases.insert(key, b.clone());
                                b
                            }
                        })
                    }
                };
                // A textured region keeps the specular fit's constant apart from the textured
                // diffuse basis: one more slot, after the basis functions.
                let count = basis.count() + usize::from(texture.is_some() && basis.spec_constant());
                if count > MAX_BASES {
                    return Err(RelumeError::Basis(format!(
                        "{count} bases for region \"{}\" (at most {MAX_BASES})",
                        region.name
                    )));
                }
                let first_slot = slot_vertex.len() as u32;
                for b in 0..count {
                    slot_vertex.push(PathVertex::Editable {
                        region: editable_index,
                        basis: b as u16,
                    });
                }
                if region.is_translucent() {
                    let (cfg, samples) =
                        subsurface::basis_config(scene, region_index, region, settings)?;
                    let key = serde_json::to_string(&cfg).unwrap_or_default();
                    let sss = match sss_bases.get(&key) {
                        Some(b) => b.clone(),
                        None => {
                            let b = Arc::new(SssBasis::build(&cfg)?);
                            sss_bases.insert(key, b.clone());
                            b
                        }
                    };
                    let eye_local = count as u32;
                    let first_local = eye_local + 1;
                    let eye_slot = slot_vertex.len() as u32;
                    slot_vertex.push(PathVertex::Editable {
                        region: editable_index,
                        basis: eye_local as u16,
                    });
                    let first_slot = slot_vertex.len() as u32;
                    for k in 0..sss.count() {
                        slot_vertex.push(PathVertex::Subsurface {
                            region: editable_index,
                            basis: (first_local as usize + k) as u16,
                        });
                    }
                    let (eta, bake_ior) = subsurface::bake_eta(&region.material);
                    translucent[region_index] = Some(TranslucentRegion {
                        editable_index,
                        info: SubsurfaceInfo {
                            basis: cfg,
                            bake_ior,
                            eye_diffuse_slot: eye_local,
                            first_slot: first_local,
                            samples,
                        },
                        basis: sss,
                        eye_diffuse_slot: eye_slot,
                        first_slot,
                        eta,
                        points: Default::default(),
                        irradiance: Vec::new(),
                        tree: Default::default(),
                    });
                }
                let (lo, hi) = match &basis {
                    RegionBasis::BlinnPhong(_) => (cfg.ns_min, cfg.ns_max),
                    RegionBasis::Principled(b) | RegionBasis::PrincipledWithBakeLobe(b, _) => {
                        b.config().fitted_ns_range()
                    }
                };
                // The bake-time coefficient of the diffuse slot, which the tail-edit
                // layers split each tail vertex's BRDF by (see `PreparedRegion`).
                let tail_diffuse = basis
                    .fold_bake_lobe(
                        &basis
                            .slot_coefficients(count > basis.count(), &region.material)?
                            .slots,
                    )
                    .first()
                    .copied()
                    .unwrap_or(Rgb::ZERO);
                let with_bake_lobe = basis.bake_lobe_slot().is_some();
                regions.push(PreparedRegion {
                    name: region.name.clone(),
                    tail_diffuse,
                    model: RegionModel::Editable {
                        index: editable_index,
                        basis,
                    },
                    texture,
                    first_slot,
                    slot_count: count as u32,
                    mixture: DirectionMixture::editable(&material, lo, hi),
                    // A region with its bake-time lobe as a slot is evaluated exactly
                    // there, so its tail is too; others see their Blinn–Phong mapping.
                    frozen: if with_bake_lobe {
                        SurfaceBrdf::exact(&region.material)
                    } else {
                        SurfaceBrdf::BlinnPhong(material)
                    },
                });
                editable_index += 1;
            } else {
                // Sampled by its Blinn–Phong mapping's lobe (a valid pdf for any BRDF),
                // evaluated exactly.
                let surface = SurfaceBrdf::exact(&region.material);
                regions.push(PreparedRegion {
                    name: region.name.clone(),
                    tail_diffuse: Rgb::ZERO,
                    model: RegionModel::Fixed {
                        material: surface.clone(),
                    },
                    texture,
                    first_slot: u32::MAX,
                    slot_count: 1,
                    mixture: DirectionMixture::fixed(&material),
                    frozen: surface,
                });
            }
        }
        let fixed_slot = slot_vertex.len() as u32;
        slot_vertex.push(PathVertex::Fixed);
        for r in &mut regions {
            if let RegionModel::Fixed { .. } = r.model {
                r.first_slot = fixed_slot;
            }
        }
        let lights = LightSet::new(scene, settings.light_grouping);
        if lights.groups.len() > MAX_GROUPS {
            return Err(RelumeError::invalid(
                "light groups",
                format!(
                    "{} groups (at most {}): group the lights in the scene file's light_groups",
                    lights.groups.len(),
                    MAX_GROUPS
                ),
            ));
        }
        let geometry = SceneGeometry::build(scene);
        report.triangles = geometry.triangle_count();
        let camera = CameraRays::new(&scene.camera, resolution);
        let clip_end = if scene.camera.clip_end > 0.0 {
            scene.camera.clip_end
        } else {
            f32::INFINITY
        };
        let eye_diffuse_slot = regions
            .iter()
            .zip(&translucent)
            .map(|(r, t)| t.as_ref().map_or(r.first_slot, |t| t.eye_diffuse_slot))
            .collect();
        let ctx = BakeContext {
            geometry,
            camera,
            lights,
            regions,
            slot_vertex,
            resolution,
            settings: settings.clone(),
            clip_end,
            guide: None,
            translucent,
            eye_diffuse_slot,
            bounce_estimate: None,
            non_finite: Default::default(),
        };
        Ok((ctx, report))
    }

    /// Number of slots (editable bases + 1 fixed).
    pub fn slot_count(&self) -> usize {
        self.slot_vertex.len()
    }

    /// Layers one light group can fill: the world, one per slot, with one bounce one per
    /// (eye slot, bounce slot) pair, and with two or more the tail-edit layers
    /// ([`Self::tail_edit_layers_per_group`]).
    pub fn layers_per_group(&self) -> usize {
        let s = self.slot_count();
        let pairs = if self.settings.bounces >= 1 { s * s } else { 0 };
        1 + s + pairs + self.tail_edit_layers_per_group()
    }

    /// Number of editable regions.
    pub fn editable_count(&self) -> usize {
        self.regions
            .iter()
            .filter(|r| matches!(r.model, RegionModel::Editable { .. }))
            .count()
    }

    /// Bins of the tail-edit layers: the monomials s_d^i·s_g^j, i + j ≥ 1, of degree at
    /// most the tail's counted length (bounces − 1, at most
    /// [`crate::bake::path::tail_edits::MAX_TAIL_COUNT`]) plus one for the bounce vertex
    /// ([`crate::bake::path::tail_edits::fold_bounce`]); 0 when there is no tail (fewer
    /// than two bounces) or nothing editable.
    pub fn tail_edit_bins(&self) -> usize {
        if self.settings.bounces < 2 || self.editable_count() == 0 {
            return 0;
        }
        let t =
            (self.settings.bounces as usize - 1).min(crate::bake::path::tail_edits::MAX_TAIL_COUNT);
        crate::bake::path::tail_edits::monomial_bins(t + 1)
    }

    /// Tail-edit layers per light group: per eye part (the fixed region or one part of an
    /// editable region), tail region and bin ([`crate::layer_key::PathVertex::TailEdit`]).
    pub fn tail_edit_layers_per_group(&self) -> usize {
        let bins = self.tail_edit_bins();
        if bins == 0 {
            return 0;
        }
        let regions = self.editable_count();
        (2 * regions + 1) * regions * bins
    }

    /// Layers the bake can fill: [`Self::layers_per_group`] per light group.
    pub fn layer_count(&self) -> usize {
        self.layers_per_group() * self.lights.groups.len()
    }

    /// The subsurface info of every editable region (editable order; `None` if opaque).
    pub fn editable_subsurface(&self) -> Vec<Option<(Arc<SssBasis>, SubsurfaceInfo)>> {
        self.regions
            .iter()
            .zip(&self.translucent)
            .filter(|(r, _)| matches!(r.model, RegionModel::Editable { .. }))
            .map(|(_, t)| t.as_ref().map(|t| (t.basis.clone(), t.info.clone())))
            .collect()
    }

    /// Editable regions' bases, in editable order.
    pub fn editable_bases(&self) -> Vec<RegionBasis> {
        self.regions
            .iter()
            .filter_map(|r| match &r.model {
                RegionModel::Editable { basis, .. } => Some(basis.clone()),
                RegionModel::Fixed { .. } => None,
            })
            .collect()
    }
}

/// The Principled basis configuration an editable region is baked with: the settings' when
/// they ask for one and the region is an opaque, untextured Principled material (`Ok(None)`
/// when they do not ask, or when the material is given as Blinn–Phong values, which the
/// Blinn–Phong basis carries as they are); `Err` says why a Principled material keeps the
/// Blinn–Phong basis and its fitted mapping (a warning for the bake's report).
fn principled_basis_for<'a>(
    settings: &'a BakeSettings,
    region: &crate::scene::Region,
    textured: bool,
) -> std::result::Result<Option<&'a crate::brdf::principled_basis::PrincipledBasisConfig>, String> {
    let Some(cfg) = settings.principled_basis.as_ref() else {
        return Ok(None);
    };
    if !matches!(region.material, MaterialSpec::Principled(_)) {
        // A material given as Blinn–Phong values is that basis' own model: nothing is lost.
        return Ok(None);
    }
    let why = if textured {
        "it is textured (not supported by the Principled basis yet)"
    } else if region.is_translucent() {
        "it is translucent (not supported by the Principled basis yet)"
    } else {
        return Ok(Some(cfg));
    };
    Err(format!(
        "region \"{}\": baked with the Blinn–Phong basis, not the Principled one: {why}",
        region.name
    ))
}

/// The basis configuration for a region: the bake default, with the region's own ns range
/// when it declares one.
pub fn basis_config_for(default: &BasisConfig, ns_range: Option<[f32; 2]>) -> BasisConfig {
    let mut cfg = default.clone();
    if let Some([lo, hi]) = ns_range {
        cfg.ns_min = lo;
        cfg.ns_max = hi;
    }
    cfg
}
