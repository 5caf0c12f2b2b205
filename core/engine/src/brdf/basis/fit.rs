//! Choosing the basis: the count (fixed, or the smallest that meets a tolerance) and the
//! lobe weighting of the PCA that yields it (module docs, "Weighting").

use super::config::{BasisConfig, BasisCount, LobeWeighting};
use super::error::{ErrorMeasures, FitErrors, REPORT_MAX_COUNT};
use super::pca::{capped_scale, Lobes, Pca};
use crate::{RelumeError, Result};

/// Largest count a tolerance search considers.
const MAX_SEARCH_COUNT: usize = 64;

/// The chosen basis: `count` (`N_b`, diffuse included), the PCA whose first `count − 1`
/// bases it keeps, and that PCA's errors.
pub(super) struct Fit {
    pub count: usize,
    pub pca: Pca,
    pub errors: FitErrors,
}

/// The fit `cfg.count` asks for.
pub(super) fn fit(cfg: &BasisConfig, lobes: &Lobes, measures: &ErrorMeasures) -> Result<Fit> {
    // Bases kept for the report and the count search.
    let kwant = match cfg.count {
        BasisCount::Fixed(n) => (n as usize - 1).max(REPORT_MAX_COUNT - 1),
        BasisCount::Tolerance(_) => MAX_SEARCH_COUNT - 1,
    };
    let search = Search {
        cfg,
        kwant,
        lobes,
        measures,
    };
    match cfg.count {
        BasisCount::Fixed(n) => search.count(n as usize),
        BasisCount::Tolerance(tol) => search.tolerance(tol as f64),
    }
}

/// What every candidate PCA is computed from and measured under.
struct Search<'a> {
    cfg: &'a BasisConfig,
    /// Bases each PCA keeps.
    kwant: usize,
    lobes: &'a Lobes,
    measures: &'a ErrorMeasures<'a>,
}

impl Search<'_> {
    /// The PCA under the lobe scales `scale`, with its errors.
    fn pca(&self, scale: &[f64]) -> (Pca, FitErrors) {
        let p = Pca::new(self.lobes, scale, self.kwant);
        let e = self.measures.errors(self.lobes, &p);
        (p, e)
    }

    /// `N_b = n` under the configured weighting.
    fn count(&self, n: usize) -> Result<Fit> {
        let (cfg, lobes) = (self.cfg, self.lobes);
        let scale = match cfg.weighting {
            LobeWeighting::Energy => lobes.energy_scale(),
            LobeWeighting::Unit => lobes.unit_scale(),
            LobeWeighting::Capped(cap) => capped_scale(lobes, n - 1, cap as f64),
        };
        let p = Pca::new(lobes, &scale, self.kwant);
        if n - 1 > p.k {
            return Err(RelumeError::Basis(format!(
                "count {n} asks for {} specular bases but the {} lobes over ns ∈ [{}, {}] \
                 have numerical rank {}: use at most {}",
                n - 1,
                lobes.l,
                cfg.ns_min,
                cfg.ns_max,
                p.k,
                p.k + 1
            )));
        }
        let errors = self.measures.errors(lobes, &p);
        Ok(Fit {
            count: n,
            pca: p,
            errors,
        })
    }

    /// The smallest `N_b` whose worst error is ≤ `tol`: first with the energy or unit
    /// weighting, then, for the capped weighting, one basis fewer at a time while a PCA capped
    /// just under the tolerance still meets it.
    fn tolerance(&self, tol: f64) -> Result<Fit> {
        let (cfg, lobes) = (self.cfg, self.lobes);
        let first = match cfg.weighting {
            LobeWeighting::Energy => lobes.energy_scale(),
            _ => lobes.unit_scale(),
        };
        let (p, e) = self.pca(&first);
        let Some(mut n) = (1..=p.k + 1).find(|&n| e.worst(n) <= tol) else {
            return Err(RelumeError::Basis(format!(
                "tolerance {tol} is not reachable for ns ∈ [{}, {}]: the best count \
                 tried, N_b = {}, has a maximum relative L2 error of {:.4}",
                cfg.ns_min,
                cfg.ns_max,
                p.k + 1,
                e.worst(p.k + 1)
            )));
        };
        let mut best = (p, e);
        if matches!(cfg.weighting, LobeWeighting::Capped(_)) {
            // Capped reweighting at the tolerance often saves a basis or two.
            while n > 2 {
                let (p, e) = self.pca(&capped_scale(lobes, n - 2, 0.97 * tol));
                if e.worst(n - 1) > tol {
                    break;
                }
                n -= 1;
                best = (p, e);
            }
        }
        Ok(Fit {
            count: n,
            pca: best.0,
            errors: best.1,
        })
    }
}
