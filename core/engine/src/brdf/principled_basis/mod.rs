//! A BRDF basis built from Cycles' Principled specular lobes (issue 15's "stronger option";
//! measured in numpy first, docs/principled_basis_study.md).
//!
//! # Why
//!
//! No Blinn–Phong lobe matches Cycles' Principled BSDF under every lighting: a half-angle
//! lobe has neither GGX's `1/(cos θi cos θo)` nor its grazing Fresnel, so a material fitted
//! to look right with the light in front is 10–30 % off with the light to the side
//! (docs/principled_fit.md). A basis whose functions are combinations of the Principled
//! lobes themselves represents them directly; the relit material's coefficients are then
//! its projection, linear in its Fresnel weights.
//!
//! # What it is
//!
//! * **Training lobes** ([`lobes`]): GGX with height-correlated Smith G, Fresnel and
//!   Kulla–Conty multiple scattering, at roughness values uniform in `ln r` over
//!   `[roughness_min, 1]`, for metals at F0 0…1 and dielectrics at IOR 1.33, 1.5, 1.8.
//! * **Measure** ([`quadrature`]): `cos θi cos θo dωi dωo` by a product rule in (θh, θd, φd)
//!   graded toward θh = 0, normalised to total 1.
//! * **PCA** ([`pca`]): on the Gram matrix, constant in the fit, unit-normalised lobes,
//!   capped (Lawson) weighting; the bases are exact combinations of the lobes.
//! * **Tables** ([`lune`]): every specular basis tabulated together on a 3D grid whose faces
//!   are the horizons, interpolated trilinearly.
//! * **Coefficients** ([`PrincipledBasis::project`]): any lobe's least-squares coefficients
//!   by the quadrature, with its relative error; a metal's from curves in roughness
//!   ([`curves`], [`PrincipledBasis::metal_coefficients`]).
//!
//! Slot 0 is the constant `1/π` (the diffuse slot, as in the Blinn–Phong basis), slots
//! `1..` the specular bases.
//!
//! # Status
//!
//! Built and measured here; the bake and the relighters still use the Blinn–Phong basis
//! ([`super::basis`]). Not yet here: curves for dielectrics (their coefficients come from a
//! projection, milliseconds per IOR and roughness), the diffuse base's `1 − albedo(μo)` weight
//! under a dielectric, f16 tables, and the bake's sampling of these lobes.

pub mod bake_lobe;
mod cache;
mod cells;
mod curves;
mod lobes;
mod lune;
pub mod material;
mod pca;
mod quadrature;

use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use rayon::prelude::*;

pub use lobes::{default_families, Cosines, Family, DIFFUSE};
pub use lune::TableSize;
pub use quadrature::QuadratureSize;

use curves::MetalCurves;
use lobes::{roughness_nodes, LobeSet, Roughness};
use lune::{LuneCoords, LuneTable};
use pca::{capped_pca, LobeGram};
use quadrature::Node;

use crate::error::RelumeError;
use crate::Result;

/// Quadrature nodes per parallel task of a sum over the nodes.
const NODES_PER_CHUNK: usize = 4096;
/// Most functions [`PrincipledBasis::project_many`] projects at once.
const MAX_PARTS: usize = 8;
/// Most slots a basis may have (the constant included).
pub const MAX_SLOTS: usize = 64;

/// How a Principled basis is built.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PrincipledBasisConfig {
    /// The smoothest roughness the basis covers (the range is `[roughness_min, 1]`).
    pub roughness_min: f64,
    /// Training roughness values, uniform in `ln r`.
    pub roughness_nodes: usize,
    /// Slots, the constant included.
    pub bases: usize,
    pub quadrature: QuadratureSize,
    pub table: TableSize,
}

impl Default for PrincipledBasisConfig {
    /// The study's joint metal and dielectric basis at its chosen table size: 21 slots
    /// (1 % mean, 1.2 % worst lobe error in the study) and 129 × 65 × 65 tables.
    fn default() -> Self {
        PrincipledBasisConfig {
            roughness_min: 0.1,
            roughness_nodes: 96,
            bases: 21,
            quadrature: QuadratureSize {
                theta_h: 96,
                theta_d: 40,
                phi_d: 48,
            },
            table: TableSize {
                theta_h: 129,
                s: 65,
                eta: 65,
            },
        }
    }
}

impl PrincipledBasisConfig {
    /// The Blinn–Phong exponents the fitted mapping gives roughness 1 and `roughness_min`:
    /// where a region in this basis spreads its sampling lobes, and how its range is named in
    /// the exponent terms of range warnings and estimates.
    pub fn fitted_ns_range(&self) -> (f32, f32) {
        let ns = crate::brdf::principled_fit::fitted_ns;
        (ns(1.0), ns(self.roughness_min as f32))
    }

    fn check(&self) -> Result<()> {
        let bad = |message: &str| {
            Err(RelumeError::InvalidValue {
                what: "principled basis".into(),
                message: message.into(),
            })
        };
        if !(self.roughness_min >= 0.05 && self.roughness_min < 1.0) {
            return bad("roughness_min must be in [0.05, 1) (GGX below 0.05 is a mirror the quadrature cannot resolve)");
        }
        if self.roughness_nodes < 2 {
            return bad("roughness_nodes must be at least 2");
        }
        if !(2..=MAX_SLOTS).contains(&self.bases) {
            return bad("bases must be between 2 (the constant and one specular basis) and 64");
        }
        let q = self.quadrature;
        if q.theta_h < 8 || q.theta_d < 4 || q.phi_d < 4 {
            return bad("quadrature needs at least 8 × 4 × 4 nodes");
        }
        let t = self.table;
        if t.theta_h < 2 || t.s < 2 || t.eta < 2 {
            return bad("table needs at least 2 nodes per axis");
        }
        Ok(())
    }
}

/// What a build measured: the training lobes' errors and the tables' own error.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct PrincipledBasisReport {
    /// Slots, the constant included.
    pub bases: usize,
    pub lobes: usize,
    /// Relative L2 error of the training lobes under the measure, mean and worst.
    pub lobe_mean: f64,
    pub lobe_worst: f64,
    /// RMS over the measure of (table − exact), over the RMS of the basis, worst basis.
    pub table_worst_basis: f64,
    pub table_bytes: usize,
    /// `∫∫ cos θi cos θo dωi dωo` by the quadrature (π² exactly).
    pub quadrature_total: f64,
    pub quadrature_nodes: usize,
    pub build_seconds: f64,
    /// Whether this process read the basis from the disk cache (the other figures are the
    /// build's that wrote it) instead of building it.
    #[serde(default)]
    pub from_cache: bool,
}

/// Relative L2 errors of a lobe rebuilt from the basis (each over the lobe's norm).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct RebuildErrors {
    /// With the exact bases: the basis' own error for this lobe.
    pub projection: f64,
    /// With the tables, as the bake would evaluate it.
    pub with_tables: f64,
    /// Tables against exact bases, same coefficients: what the tables add.
    pub tables_alone: f64,
}

/// A built basis: the bases as combinations of the training lobes, their tables, and their
/// values at the quadrature nodes (for projections).
pub struct PrincipledBasis {
    config: PrincipledBasisConfig,
    /// The training lobes; made again on first use by a basis read from the cache (only
    /// exact evaluation needs them).
    lobes: OnceLock<LobeSet>,
    /// `‖f_j‖` and `⟨f_j/‖f_j‖, 1⟩` of every training lobe.
    norm: Vec<f64>,
    mean: Vec<f64>,
    nspec: usize,
    /// `φ_k = Σ_j coef[j·nspec + k]·(f_j/‖f_j‖ − ⟨f_j/‖f_j‖, 1⟩)`.
    coef: Vec<f64>,
    lobe_errors: Vec<f64>,
    nodes: Vec<Node>,
    /// `φ_k` at every node, node-major.
    at_nodes: Vec<f64>,
    table: LuneTable,
    curves: Option<MetalCurves>,
    report: PrincipledBasisReport,
    /// Every slot pair's inner product per cell ([`cells`]), made on first use.
    cell_grams: OnceLock<Vec<f64>>,
}

impl PrincipledBasis {
    pub fn build(config: &PrincipledBasisConfig) -> Result<PrincipledBasis> {
        config.check()?;
        let start = Instant::now();
        let rs = roughness_nodes(config.roughness_min, config.roughness_nodes);
        let lobes = LobeSet::new(&rs, &default_families());
        let (nodes, quadrature_total) = quadrature::nodes(config.quadrature);
        let gram = LobeGram::new(&lobes, &nodes);
        let pca = capped_pca(&gram, config.bases - 1);
        let nspec = pca.nspec;
        let mut basis = PrincipledBasis {
            config: config.clone(),
            lobes: OnceLock::from(lobes),
            norm: gram.norm,
            mean: gram.mean,
            nspec,
            coef: pca.coef,
            lobe_errors: pca.errors,
            nodes,
            at_nodes: vec![],
            table: LuneTable {
                size: config.table,
                coords: LuneCoords::new(config.roughness_min.powi(2)),
                nspec: 0,
                values: vec![],
            },
            curves: None,
            cell_grams: OnceLock::new(),
            report: PrincipledBasisReport {
                bases: 1 + nspec,
                lobes: 0,
                lobe_mean: 0.0,
                lobe_worst: 0.0,
                table_worst_basis: 0.0,
                table_bytes: 0,
                quadrature_total,
                quadrature_nodes: 0,
                build_seconds: 0.0,
                from_cache: false,
            },
        };
        basis.at_nodes = basis
            .nodes
            .par_iter()
            .flat_map_iter(|n| {
                let mut v = vec![0.0; nspec];
                basis.eval_exact_specular(n.c, &mut v);
                v
            })
            .collect();
        let coords = basis.table.coords;
        basis.table = LuneTable::fill(config.table, coords, nspec, |c, out| {
            basis.eval_exact_specular(c, out);
            let w = c.cos_i * c.cos_o;
            out.iter_mut().for_each(|v| *v *= w);
        });
        basis.curves = Some(MetalCurves::build(
            config.roughness_min,
            basis.count(),
            |f| basis.project_many(curves::PARTS, f),
        ));
        let errors = &basis.lobe_errors;
        basis.report = PrincipledBasisReport {
            bases: 1 + nspec,
            lobes: errors.len(),
            lobe_mean: errors.iter().sum::<f64>() / errors.len() as f64,
            lobe_worst: errors.iter().cloned().fold(0.0, f64::max),
            table_worst_basis: basis.table_errors().into_iter().fold(0.0, f64::max),
            table_bytes: basis.table.bytes(),
            quadrature_total,
            quadrature_nodes: basis.nodes.len(),
            build_seconds: start.elapsed().as_secs_f64(),
            from_cache: false,
        };
        Ok(basis)
    }

    /// The cache's key of `config` ([`cache::key`]).
    fn cache_key(config: &PrincipledBasisConfig) -> u64 {
        cache::key(&serde_json::to_vec(config).unwrap_or_default())
    }

    /// The array lengths `config` implies, for the cache's checks.
    fn cache_shape(config: &PrincipledBasisConfig, nodes: usize) -> cache::Shape {
        cache::Shape {
            lobes: config.roughness_nodes * default_families().len(),
            nodes,
            table_nodes: config.table.nodes(),
            curve_nodes: curves::CURVE_NODES,
            curve_parts: curves::PARTS,
        }
    }

    /// The basis of `config` from the cache in `dir`, or `None` when it holds none that can
    /// be trusted ([`cache`]).
    fn load_cached(
        dir: &std::path::Path,
        config: &PrincipledBasisConfig,
    ) -> Option<PrincipledBasis> {
        config.check().ok()?;
        let (nodes, _) = quadrature::nodes(config.quadrature);
        let stored = cache::load(
            dir,
            Self::cache_key(config),
            config.bases - 1,
            &Self::cache_shape(config, nodes.len()),
        )?;
        let mut report: PrincipledBasisReport = serde_json::from_slice(&stored.report).ok()?;
        report.from_cache = true;
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(finite(&stored.coef)
            && finite(&stored.norm)
            && finite(&stored.mean)
            && finite(&stored.at_nodes)
            && finite(&stored.curve_values)
            && stored.table.iter().all(|x| x.is_finite()))
        {
            return None;
        }
        let nspec = stored.nspec;
        Some(PrincipledBasis {
            config: config.clone(),
            lobes: OnceLock::new(),
            norm: stored.norm,
            mean: stored.mean,
            nspec,
            coef: stored.coef,
            lobe_errors: stored.lobe_errors,
            nodes,
            at_nodes: stored.at_nodes,
            table: LuneTable {
                size: config.table,
                coords: LuneCoords::new(config.roughness_min.powi(2)),
                nspec,
                values: stored.table,
            },
            curves: Some(MetalCurves::from_parts(
                config.roughness_min,
                1 + nspec,
                stored.curve_e_avg,
                stored.curve_values,
            )),
            report,
            cell_grams: OnceLock::new(),
        })
    }

    /// Writes this basis into the cache in `dir` ([`cache`]).
    fn store_cached(&self, dir: &std::path::Path) -> std::io::Result<()> {
        let curves = self
            .curves
            .as_ref()
            .expect("curves are built with the basis");
        let (e_avg, values) = curves.parts();
        cache::store(
            dir,
            Self::cache_key(&self.config),
            &cache::Stored {
                nspec: self.nspec,
                coef: self.coef.clone(),
                lobe_errors: self.lobe_errors.clone(),
                norm: self.norm.clone(),
                mean: self.mean.clone(),
                at_nodes: self.at_nodes.clone(),
                table: self.table.values.clone(),
                curve_e_avg: e_avg.to_vec(),
                curve_values: values.to_vec(),
                report: serde_json::to_vec(&self.report).unwrap_or_default(),
            },
        )
    }

    /// The basis of `config` from the cache in `dir` when it holds one, else built and
    /// written there (a cache that cannot be written costs only the next process a build).
    pub fn cached_in(
        dir: &std::path::Path,
        config: &PrincipledBasisConfig,
    ) -> Result<PrincipledBasis> {
        if let Some(b) = Self::load_cached(dir, config) {
            return Ok(b);
        }
        let b = PrincipledBasis::build(config)?;
        let _ = b.store_cached(dir);
        Ok(b)
    }

    /// The basis of `config`, made once per process and shared: every bake and every stack
    /// load of the same configuration needs the same basis (the build is deterministic).
    /// Across processes it comes from the disk cache ([`cache`]; built and written there the
    /// first time), so loading a stack builds nothing.
    pub fn shared(config: &PrincipledBasisConfig) -> Result<Arc<PrincipledBasis>> {
        static BUILT: Mutex<Vec<Arc<PrincipledBasis>>> = Mutex::new(Vec::new());
        let mut built = BUILT.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(b) = built.iter().find(|b| &b.config == config) {
            return Ok(b.clone());
        }
        let b = Arc::new(match cache::default_dir() {
            Some(dir) => PrincipledBasis::cached_in(&dir, config)?,
            None => PrincipledBasis::build(config)?,
        });
        built.push(b.clone());
        Ok(b)
    }

    pub fn config(&self) -> &PrincipledBasisConfig {
        &self.config
    }

    /// Slots, the constant included.
    pub fn count(&self) -> usize {
        1 + self.nspec
    }

    pub fn report(&self) -> &PrincipledBasisReport {
        &self.report
    }

    /// The training roughness values.
    pub fn roughness(&self) -> Vec<f64> {
        roughness_nodes(self.config.roughness_min, self.config.roughness_nodes)
    }

    fn lobes(&self) -> &LobeSet {
        self.lobes.get_or_init(|| {
            let rs = roughness_nodes(self.config.roughness_min, self.config.roughness_nodes);
            LobeSet::new(&rs, &default_families())
        })
    }

    /// Every slot's value at `c` from the tables (slot 0 the constant `1/π`).
    pub fn eval(&self, c: Cosines, out: &mut [f64]) {
        out[0] = DIFFUSE;
        self.table.eval(c, &mut out[1..self.count()]);
    }

    /// Every slot's value at `c` from the lobes themselves (exact; slow: every training
    /// lobe is evaluated).
    pub fn eval_exact(&self, c: Cosines, out: &mut [f64]) {
        out[0] = DIFFUSE;
        self.eval_exact_specular(c, &mut out[1..self.count()]);
    }

    fn eval_exact_specular(&self, c: Cosines, out: &mut [f64]) {
        let lobes = self.lobes();
        let mut f = vec![0.0; lobes.len()];
        lobes.eval(c, &mut f);
        out[..self.nspec].fill(0.0);
        for (j, fj) in f.iter().enumerate() {
            let r = fj / self.norm[j] - self.mean[j];
            let row = &self.coef[j * self.nspec..(j + 1) * self.nspec];
            for (o, b) in out.iter_mut().zip(row) {
                *o += r * b;
            }
        }
    }

    /// Least-squares coefficients of `lobe` under the measure, per slot (slot 0 multiplies
    /// `1/π`), and its relative L2 error when rebuilt from them.
    pub fn project(&self, lobe: impl Fn(Cosines) -> f64 + Sync) -> (Vec<f64>, f64) {
        let mut norm2 = 0.0;
        let coefficients = self.project_many(1, |c, out: &mut [f64]| out[0] = lobe(c));
        for n in &self.nodes {
            let f = lobe(n.c);
            norm2 += n.weight * f * f;
        }
        let kept: f64 = coefficients
            .iter()
            .enumerate()
            .map(|(k, c)| if k == 0 { c * DIFFUSE } else { *c })
            .map(|d| d * d)
            .sum();
        let error = if norm2 > 0.0 {
            ((norm2 - kept).max(0.0) / norm2).sqrt()
        } else {
            0.0
        };
        (coefficients, error)
    }

    /// The coefficients of `parts` functions at once (`f` writes their values at a pair):
    /// `parts × count()` values, function-major.
    pub(crate) fn project_many(
        &self,
        parts: usize,
        f: impl Fn(Cosines, &mut [f64]) + Sync,
    ) -> Vec<f64> {
        let slots = self.count();
        let mut dots = self.sum_over_nodes(parts * slots, |node, phi, d| {
            let mut v = [0.0f64; MAX_PARTS];
            let v = &mut v[..parts];
            f(node.c, v);
            for (p, fv) in v.iter().enumerate() {
                if *fv != 0.0 {
                    let wf = node.weight * fv;
                    let row = &mut d[p * slots..(p + 1) * slots];
                    row[0] += wf;
                    for (dk, b) in row[1..].iter_mut().zip(phi) {
                        *dk += wf * b;
                    }
                }
            }
        });
        // The constant basis has value 1 under the measure; slot 0 holds 1/π.
        for p in 0..parts {
            dots[p * slots] /= DIFFUSE;
        }
        dots
    }

    /// Per slot and channel, the coefficients of a metal (Schlick Fresnel from `f0` per
    /// channel, Cycles' Principled at Metallic 1 and white Specular Tint) at `roughness`,
    /// from the curves; `true` when `roughness` lay outside the basis' range and was
    /// clamped to it.
    pub fn metal_coefficients(&self, f0: [f64; 3], roughness: f64) -> (Vec<[f64; 3]>, bool) {
        self.curves
            .as_ref()
            .expect("curves are built with the basis")
            .coefficients(f0, roughness)
    }

    /// The Principled lobe of `family` at `roughness` (for projections and tests).
    pub fn lobe(family: Family, roughness: f64) -> impl Fn(Cosines) -> f64 + Sync {
        let r = Roughness::new(roughness);
        move |c| r.lobe(&family, c)
    }

    /// How well `lobe` is rebuilt from its coefficients ([`Self::project`]), with the exact
    /// bases and with the tables, under the measure.
    pub fn rebuild_errors(&self, lobe: impl Fn(Cosines) -> f64 + Sync) -> RebuildErrors {
        let (coef, projection) = self.project(&lobe);
        let n = self.count();
        let sums = self.sum_over_nodes(3, |node, exact, acc| {
            let mut v = [0.0f64; MAX_SLOTS];
            let v = &mut v[..n];
            self.eval(node.c, v);
            let tabled: f64 = v.iter().zip(&coef).map(|(a, b)| a * b).sum();
            let exact: f64 = coef[0] * DIFFUSE
                + exact
                    .iter()
                    .zip(&coef[1..])
                    .map(|(a, b)| a * b)
                    .sum::<f64>();
            let f = lobe(node.c);
            let w = node.weight;
            acc[0] += w * (tabled - f).powi(2);
            acc[1] += w * (tabled - exact).powi(2);
            acc[2] += w * f * f;
        });
        let (with_tables, tables_alone, norm2) = (sums[0], sums[1], sums[2]);
        let rel = |x: f64| if norm2 > 0.0 { (x / norm2).sqrt() } else { 0.0 };
        RebuildErrors {
            projection,
            with_tables: rel(with_tables),
            tables_alone: rel(tables_alone),
        }
    }

    /// `Σ` over the quadrature nodes of what `add(node, φ at the node, acc)` adds into a
    /// `len`-vector: in parallel over fixed chunks, the chunks' sums added in order, so the
    /// result does not depend on the thread count (a bake must come out bit for bit).
    fn sum_over_nodes(
        &self,
        len: usize,
        add: impl Fn(&Node, &[f64], &mut [f64]) + Sync,
    ) -> Vec<f64> {
        let ns = self.nspec.max(1);
        let partial: Vec<Vec<f64>> = self
            .nodes
            .par_chunks(NODES_PER_CHUNK)
            .zip(self.at_nodes.par_chunks(NODES_PER_CHUNK * ns))
            .map(|(nodes, phis)| {
                let mut acc = vec![0.0; len];
                for (node, phi) in nodes.iter().zip(phis.chunks(ns)) {
                    add(node, phi, &mut acc);
                }
                acc
            })
            .collect();
        let mut total = vec![0.0; len];
        for p in partial {
            total.iter_mut().zip(&p).for_each(|(t, v)| *t += v);
        }
        total
    }

    /// Per specular basis: RMS of (table − exact) over its RMS (1: bases are unit-norm).
    fn table_errors(&self) -> Vec<f64> {
        let ns = self.nspec;
        let sums = self.sum_over_nodes(ns, |node, exact, acc| {
            let mut v = [0.0f64; MAX_SLOTS];
            let v = &mut v[..ns];
            self.table.eval(node.c, v);
            for k in 0..ns {
                acc[k] += node.weight * (v[k] - exact[k]).powi(2);
            }
        });
        sums.into_iter().map(f64::sqrt).collect()
    }
}

#[cfg(test)]
mod tests;
