//! [`LiveMaterials`]: the materials and light-group gains of a live relight session (the
//! Python bindings' `Relighter`, hence the add-on), what changed since the last image, and
//! the relights that bring the image up to date. Edits pass the same rules as a materials
//! file ([`resolve_materials`], [`resolve_light_gains`]), so the bindings hold no rule of
//! their own.

use std::collections::BTreeMap;

use crate::brdf::MaterialSpec;
use crate::relight::CpuRelighter;
use crate::stack::bases::StackBases;
use crate::stack::StackHeader;
use crate::{RelumeError, Result, Rgb};

use super::file::{LightGroupEdit, MaterialsFile};
use super::resolve::{resolve_light_gains, resolve_materials};

/// A relighter a live session drives: the CPU one here, the GPU-or-CPU one of `relume-gpu`.
pub trait LiveRelighter {
    /// Its errors; the material rules' refusals convert into it.
    type Error: From<RelumeError>;
    /// Full relight with every editable region's coefficients.
    fn relight_all(&mut self, coefs: &[Vec<Rgb>]) -> std::result::Result<(), Self::Error>;
    /// Incremental relight of one editable region.
    fn relight_one(&mut self, region: usize, coefs: &[Rgb])
        -> std::result::Result<(), Self::Error>;
    /// Light groups' gains, one per group of the stack.
    fn set_gains(&mut self, gains: &[Rgb]) -> std::result::Result<(), Self::Error>;
}

impl LiveRelighter for CpuRelighter {
    type Error = RelumeError;
    fn relight_all(&mut self, coefs: &[Vec<Rgb>]) -> Result<()> {
        self.relight(coefs).map(|_| ())
    }
    fn relight_one(&mut self, region: usize, coefs: &[Rgb]) -> Result<()> {
        self.relight_region(region, coefs).map(|_| ())
    }
    fn set_gains(&mut self, gains: &[Rgb]) -> Result<()> {
        self.set_light_group_gains(gains).map(|_| ())
    }
}

/// The current material of every editable region and the live light-group edits of one
/// stack, with what changed since the image was last brought up to date.
#[derive(Clone, Debug)]
pub struct LiveMaterials {
    /// Names of the editable regions, in editable order.
    editable: Vec<String>,
    /// Current material of every editable region, in editable order: Blinn–Phong values,
    /// or Principled inputs (whose subsurface part drives a translucent region's layers).
    materials: Vec<MaterialSpec>,
    /// Regions changed since the last [`update`](Self::update).
    dirty: Vec<bool>,
    light_groups: BTreeMap<String, LightGroupEdit>,
    gains_dirty: bool,
    /// Whether a full relight has been done (later updates are incremental).
    has_image: bool,
}

impl LiveMaterials {
    /// The bake-time materials of `header`'s editable regions, no light-group edit, no image.
    pub fn new(header: &StackHeader) -> Result<Self> {
        let materials = resolve_materials(&header.regions, &MaterialsFile::default())?;
        let editable = header
            .regions
            .iter()
            .filter(|r| r.editable)
            .map(|r| r.name.clone())
            .collect();
        Ok(LiveMaterials {
            editable,
            dirty: vec![false; materials.len()],
            materials,
            light_groups: BTreeMap::new(),
            gains_dirty: false,
            has_image: false,
        })
    }

    /// Names of the editable regions, in editable order.
    pub fn editable_names(&self) -> &[String] {
        &self.editable
    }

    /// Current material of every editable region, in editable order.
    pub fn materials(&self) -> &[MaterialSpec] {
        &self.materials
    }

    /// Sets editable region `region`'s material. Errors: those of a materials file that
    /// names the region ([`resolve_materials`]: unknown or fixed region, values outside
    /// [`MaterialSpec::validate`]).
    pub fn set_material(
        &mut self,
        header: &StackHeader,
        region: &str,
        spec: MaterialSpec,
    ) -> Result<()> {
        let mut edits = MaterialsFile::default();
        edits.regions.insert(region.to_string(), spec.clone());
        resolve_materials(&header.regions, &edits)?;
        let index = self.editable.iter().position(|n| n == region).unwrap_or(0);
        if self.materials[index] != spec {
            self.materials[index] = spec;
            self.dirty[index] = true;
        }
        Ok(())
    }

    /// Sets light group `name`'s strength and colour. Errors: those of a materials file
    /// with this edit ([`resolve_light_gains`]: unknown group, negative or non-finite values).
    pub fn set_light_group(
        &mut self,
        header: &StackHeader,
        name: &str,
        edit: LightGroupEdit,
    ) -> Result<()> {
        let mut light_groups = self.light_groups.clone();
        light_groups.insert(name.to_string(), edit);
        resolve_light_gains(header, &self.file_with(light_groups.clone()))?;
        self.light_groups = light_groups;
        self.gains_dirty = true;
        Ok(())
    }

    /// Brings `relighter`'s image up to date: a full relight (then the gains, if any group
    /// was edited) the first time, afterwards an incremental relight of every region changed
    /// since and the gains if they changed. Changes stay pending when it fails.
    pub fn update<R: LiveRelighter>(
        &mut self,
        header: &StackHeader,
        bases: &StackBases,
        relighter: &mut R,
    ) -> std::result::Result<(), R::Error> {
        let gains = self.gains(header)?;
        if !self.has_image {
            let coefs = self
                .materials
                .iter()
                .enumerate()
                .map(|(r, m)| bases.region_coefficients(r, m))
                .collect::<Result<Vec<_>>>()?;
            relighter.relight_all(&coefs)?;
            if let Some(g) = &gains {
                relighter.set_gains(g)?;
            }
            self.has_image = true;
        } else {
            for (r, m) in self.materials.iter().enumerate() {
                if self.dirty[r] {
                    relighter.relight_one(r, &bases.region_coefficients(r, m)?)?;
                }
            }
            if self.gains_dirty {
                let g = gains.unwrap_or_else(|| vec![Rgb::ONE; header.light_groups.len()]);
                relighter.set_gains(&g)?;
            }
        }
        self.dirty.iter_mut().for_each(|d| *d = false);
        self.gains_dirty = false;
        Ok(())
    }

    /// The light groups' gains as the relight takes them; `None` when no group was edited.
    pub fn gains(&self, header: &StackHeader) -> Result<Option<Vec<Rgb>>> {
        if self.light_groups.is_empty() {
            Ok(None)
        } else {
            resolve_light_gains(header, &self.file_with(self.light_groups.clone()))
        }
    }

    fn file_with(&self, light_groups: BTreeMap<String, LightGroupEdit>) -> MaterialsFile {
        MaterialsFile {
            regions: BTreeMap::new(),
            light_groups,
        }
    }
}
