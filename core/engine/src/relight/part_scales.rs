//! How much each part of an editable material reflects now against at bake time: the
//! scales the tail-edit layers are weighted by.
//!
//! Beyond the first bounce the bake evaluates every vertex with the bake-time materials (the
//! frozen tail); the tail-edit layers ([`crate::layer_key::PathVertex::TailEdit`]) record, per
//! editable region and part (diffuse, glossy), how many of a path's later vertices that part
//! reflected at. An edit that changes how much a part reflects — Kd or Base Color, Ks,
//! metallic, specular level — scales those vertices' light by the ratio of the part's energy
//! now to its energy at bake time, and that ratio is all these layers need.
//!
//! A part's energy is read off the region's basis coefficients — the diffuse slot's
//! coefficient, and the glossy slots' coefficients each times its basis function's albedo
//! (light reflected at normal incidence) — so it is linear in them and computed by the same
//! code for the bake-time materials (from the stack header) and for the current ones: at
//! the bake-time materials every scale is exactly 1 and every tail-edit layer weighs
//! exactly 0. A Kd or Ks edit scales its part's energy exactly; a lobe-shape edit (the
//! exponent, roughness) changes it only as much as the lobe's albedo changes, which is what
//! a tail vertex sees of it on average. A part a region did not have at bake time (energy 0
//! in a channel) scales by 1 there: such an edit keeps the frozen tail.
//!
//! **The Principled basis has one part.** Its specular slots are orthogonal to the constant
//! slot under the basis' measure, so they have no mean: the constant slot's coefficient is
//! the whole BRDF's mean reflectance, and what the other slots add at normal incidence is
//! not an energy at all: read as a glossy energy, a Base Color edit of a roughness-0.2
//! dielectric makes it −28 times its bake-time value, and the relit room negative. There
//! both parts scale by the ratio of the mean reflectance, now to bake time
//! ([`separable_parts`]): exact for an edit that scales the whole BRDF, and for a
//! diffuse-only or specular-only edit the mean of the two parts' changes weighed by their
//! shares, never negative.

use glam::Vec3;

use crate::brdf::RegionBasis;
use crate::layer_key::{LayerKey, PathVertex};
use crate::stack::bases::StackBases;
use crate::stack::StackHeader;
use crate::{Result, Rgb};

/// Below this a bake-time energy counts as absent (its scale stays 1).
const ABSENT: f32 = 1e-6;

/// The diffuse and glossy energy of one editable region for its slot coefficients `coefs`:
/// the diffuse slot's coefficient (slot 0, albedo 1) and the other slots' coefficients
/// weighed by `albedos` (one per slot, the basis functions' albedos; slots beyond it — the
/// eye-diffuse and subsurface slots of a translucent region — do not reflect at later
/// vertices).
pub fn part_energies(coefs: &[Rgb], albedos: &[f32]) -> [Rgb; 2] {
    let diffuse = coefs.first().copied().unwrap_or(Rgb::ZERO);
    let glossy = coefs
        .iter()
        .zip(albedos)
        .skip(1)
        .fold(Rgb::ZERO, |a, (c, w)| a + *c * *w);
    [diffuse, glossy]
}

/// Whether `basis` tells a region's diffuse and glossy energies apart: the Blinn–Phong
/// basis does (its diffuse slot holds Kd and its lobes Ks); the Principled basis does not
/// (module docs), and its regions scale both parts by the ratio of their mean reflectance.
fn separable_parts(basis: &RegionBasis) -> bool {
    matches!(basis, RegionBasis::BlinnPhong(_))
}

/// [`part_energies`] of a region baked in `basis`: both parts the mean reflectance (the
/// constant slot's coefficient) where the basis does not tell them apart.
fn region_energies(basis: &RegionBasis, coefs: &[Rgb], albedos: &[f32]) -> [Rgb; 2] {
    let [diffuse, glossy] = part_energies(coefs, albedos);
    if separable_parts(basis) {
        [diffuse, glossy]
    } else {
        [diffuse, diffuse]
    }
}

/// Each BRDF basis function's albedo at normal incidence (∫ b(n, ω, n) cos θ dω), by a
/// cosine-weighted stratified quadrature fine enough for the sharpest lobe a basis holds;
/// the textured regions' untextured constant slot, which holds the diffuse function, gets
/// the diffuse one's.
pub fn basis_albedos(basis: &RegionBasis, textured: bool) -> Vec<f32> {
    const N: usize = 192;
    let count = basis.count();
    let mut sums = vec![0.0f64; count];
    let mut values = vec![0.0f32; count];
    let n = Vec3::Z;
    for i in 0..N {
        for j in 0..N {
            // Cosine-weighted: sin²θ uniform in [0, 1), φ uniform; ∫ f cos dω = π E[f].
            let u = (i as f32 + 0.5) / N as f32;
            let phi = (j as f32 + 0.5) / N as f32 * std::f32::consts::TAU;
            let r = u.sqrt();
            let wi = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).max(0.0).sqrt());
            basis.eval(n, wi, n, &mut values);
            for (s, v) in sums.iter_mut().zip(&values) {
                *s += *v as f64;
            }
        }
    }
    let scale = std::f64::consts::PI / (N * N) as f64;
    let mut out: Vec<f32> = sums.iter().map(|s| (s * scale) as f32).collect();
    if textured {
        out.push(out.first().copied().unwrap_or(1.0));
    }
    out
}

/// The current scale of each editable region's parts against the bake.
#[derive(Clone)]
pub struct PartScales {
    /// Per editable region, its BRDF slots' albedos ([`basis_albedos`]).
    albedos: Vec<Vec<f32>>,
    /// Per editable region, its part energies at bake time.
    bake: Vec<[Rgb; 2]>,
    /// Per editable region, its basis: a bake-time slot's weight is folded onto the basis
    /// slots ([`RegionBasis::fold_bake_lobe`]) before the energies are read off them.
    bases: Vec<RegionBasis>,
    /// Per editable region, the current scale of its diffuse and its glossy part.
    scales: Vec<[Rgb; 2]>,
}

/// Whether any of `keys` is a tail-edit layer (only those need part scales).
pub fn has_tail_edits<'a>(mut keys: impl Iterator<Item = &'a LayerKey>) -> bool {
    keys.any(|k| {
        k.path
            .iter()
            .any(|v| matches!(v, PathVertex::TailEdit { .. }))
    })
}

impl PartScales {
    /// The bake-time part energies of `header`'s editable regions, from their recorded
    /// materials through the same coefficients a relight computes; every scale 1.
    pub fn for_header(header: &StackHeader) -> Result<PartScales> {
        let bases = StackBases::from_header(header)?;
        let materials: Vec<_> = header
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| r.material.clone())
            .collect();
        let mut albedos = Vec::new();
        let mut bake = Vec::new();
        for (r, m) in materials.iter().enumerate() {
            let basis = &bases.bases[r];
            let a = basis_albedos(basis, bases.textured[r]);
            let coefs = basis.fold_bake_lobe(&bases.region_coefficients(r, m)?);
            bake.push(region_energies(basis, &coefs, &a));
            albedos.push(a);
        }
        let scales = vec![[Rgb::ONE; 2]; bake.len()];
        Ok(PartScales {
            albedos,
            bake,
            bases: bases.bases,
            scales,
        })
    }

    /// The scales for every region's coefficients `coefs` (editable order).
    pub fn set(&mut self, coefs: &[Vec<Rgb>]) {
        for (r, c) in coefs.iter().enumerate().take(self.bake.len()) {
            self.set_region(r, c);
        }
    }

    /// The scales of editable region `region` for its coefficients `coefs`.
    pub fn set_region(&mut self, region: usize, coefs: &[Rgb]) {
        let Some(bake) = self.bake.get(region) else {
            return;
        };
        let basis = &self.bases[region];
        let coefs = basis.fold_bake_lobe(coefs);
        let now = region_energies(basis, &coefs, &self.albedos[region]);
        // A part reflects no less than nothing: a projection's small negative energy for a
        // black material scales by 0.
        let ratio = |n: Rgb, b: Rgb| {
            let r = |n: f32, b: f32| {
                if b.abs() > ABSENT {
                    (n / b).max(0.0)
                } else {
                    1.0
                }
            };
            Rgb::new(r(n.x, b.x), r(n.y, b.y), r(n.z, b.z))
        };
        self.scales[region] = [ratio(now[0], bake[0]), ratio(now[1], bake[1])];
    }

    /// Per editable region, the scale of its diffuse and its glossy part.
    pub fn scales(&self) -> &[[Rgb; 2]] {
        &self.scales
    }
}

/// The weight factor of a tail-edit term: s_b·(s_d^`diffuse`·s_g^`glossy` − 1) per
/// channel, s_b the scale of the bounce vertex's part when it lay on the region (1 for
/// [`crate::layer_key::BOUNCE_ELSEWHERE`]).
#[inline]
pub fn tail_edit_factor([sd, sg]: [Rgb; 2], diffuse: u8, glossy: u8, bounce: u8) -> Rgb {
    let b = match bounce {
        0 => sd,
        1 => sg,
        _ => Rgb::ONE,
    };
    let p = |d: f32, g: f32| d.powi(diffuse as i32) * g.powi(glossy as i32) - 1.0;
    b * Rgb::new(p(sd.x, sg.x), p(sd.y, sg.y), p(sd.z, sg.z))
}
