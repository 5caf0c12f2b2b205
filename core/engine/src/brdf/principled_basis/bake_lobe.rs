//! The region's bake-time lobe as one more slot beside the basis, and a relit material's
//! coefficients as a fit to the basis and that slot together.
//!
//! # Why
//!
//! The basis holds every Principled lobe of its range to about 1 % in L2, but L2 does not
//! bound a narrow lobe's far field: at roughness 0.1 the rebuilt lobe ripples by a few
//! hundredths of nothing over the hemisphere, which a large light picks up in every pixel
//! (docs/fidelity.md, "The Principled basis at its lower end"). The material a user looks
//! at first, and most of the time, is the one the scene was baked with. With that lobe
//! itself as a slot (evaluated exactly, as a fixed region is), the unedited image has no
//! basis error at all, and an edit keeps whatever of the bake-time lobe still fits it.
//!
//! # What it is
//!
//! Per channel, `g` is the bake-time material's BRDF ([`CyclesPrincipled`]). An edited
//! material `f` is rebuilt from the basis' slots and `g` together by the fit of
//! [`super::cells`]: least squares plus a chi-square term that keeps the energy of every
//! part of the lobe a light can see. At the bake-time material the relight is the bake's
//! exact lobe (slot `g` at 1, every basis coefficient 0: returned directly, and also the
//! fit's solution, since both of its terms vanish there); an edit far from it (a rough lobe
//! from a smooth bake) gives `g` little weight and is the basis' fit. Never worse than the
//! basis alone in the fit's own measure, since its span holds the basis'.
//!
//! The inner products are direct sums over the quadrature nodes, not the metal curves: the
//! system is nearly singular where the basis almost holds `g` (`‖g − Pg‖²` is a small
//! difference of large numbers), and the curves' interpolation error (a few 10⁻³ of the
//! coefficients) would swamp it. Where the basis holds `g` to rounding, `g`'s slot is left
//! out of the fit.

use std::sync::{Arc, Mutex, Weak};

use rayon::prelude::*;

use super::cells::CellFit;
use super::lobes::DIFFUSE;
use super::quadrature::Node;
use super::{Cosines, PrincipledBasis, PrincipledBasisConfig, MAX_SLOTS, NODES_PER_CHUNK};
use crate::brdf::cycles_principled::CyclesPrincipled;
use crate::brdf::Principled;

/// Below this share of `‖g‖²` the basis holds the bake-time lobe already (`‖g − Pg‖²` is
/// rounding): the bake-time slot is then left out of an edit's fit.
const IN_SPAN: f64 = 1e-10;

/// A region's bake-time lobe on the quadrature nodes, and what the basis holds of it.
pub struct BakeLobe {
    material: Principled,
    /// `g` per channel at every node.
    at_nodes: Vec<[f64; 3]>,
    /// `Pg`'s coefficients per slot (slot 0 multiplies `1/π`) and channel.
    projection: Vec<[f64; 3]>,
    /// `‖g − Pg‖²` per channel, `P` the projection onto the basis (0 where the basis holds
    /// `g`).
    missed: [f64; 3],
    /// `‖g‖²` per channel.
    norm2: [f64; 3],
    /// `g`'s [`Sums::cells`] (its `⟨g, f⟩` entries `‖g‖²` over the cell).
    cells: Vec<f64>,
}

impl BakeLobe {
    /// The bake-time material.
    pub fn material(&self) -> &Principled {
        &self.material
    }

    /// Slot `k`'s coefficient per channel in the basis' projection of the bake-time lobe.
    pub fn projection(&self, k: usize) -> [f64; 3] {
        self.projection.get(k).copied().unwrap_or([0.0; 3])
    }
}

/// Per slot and channel a material's coefficients, the basis' slots first and the bake-time
/// slot last.
pub struct AnchoredCoefficients {
    pub slots: Vec<[f64; 3]>,
    pub below_range: bool,
}

/// Sums over the quadrature for one material `f` (per channel): its coefficients on the
/// basis, `‖f‖²` and, when `g` is given, `⟨f, g⟩`; and the same per cell of
/// [`super::cells`].
struct Sums {
    coefficients: Vec<[f64; 3]>,
    dot_g: [f64; 3],
    norm2: [f64; 3],
    /// Per cell and channel `count() + 3` sums over the cell: `⟨ψ_k, f⟩` per slot (slot 0's
    /// function the constant `1/π`), `⟨g, f⟩`, `∫ f` and `‖f‖²`; at
    /// `[(cell * 3 + ch) * (count() + 3) + j]`. The sums over the domain above are theirs.
    cells: Vec<f64>,
}

impl PrincipledBasis {
    /// `material` as a bake-time slot of a region in this basis.
    pub fn bake_lobe(&self, material: &Principled) -> BakeLobe {
        let g = CyclesPrincipled::new(material);
        let at_nodes: Vec<[f64; 3]> = self
            .nodes
            .par_iter()
            .map(|n| g.eval_cosines(n.c.cos_i, n.c.cos_o, n.c.cos_h, n.c.cos_d))
            .collect();
        // The sums read the values just computed rather than evaluating the BSDF again.
        let sums = self.sums(&|i, _| at_nodes[i], Some(&at_nodes));
        let held = self.held(&sums.coefficients, &sums.coefficients);
        let missed = std::array::from_fn(|c| {
            let m = sums.norm2[c] - held[c];
            if m > IN_SPAN * sums.norm2[c] {
                m
            } else {
                0.0
            }
        });
        BakeLobe {
            material: *material,
            at_nodes,
            projection: sums.coefficients,
            missed,
            norm2: sums.norm2,
            cells: sums.cells,
        }
    }

    /// [`Self::bake_lobe`], shared within the process while anyone holds it: a stack's
    /// bases are rebuilt from its header by more than one reader at load (the front end's
    /// coefficients and the relighter's tail-edit scales), and each lobe is a sum over every
    /// quadrature node. Keyed by the basis' configuration (one basis per configuration,
    /// [`Self::shared`]) and the material; entries nobody holds any more are dropped.
    pub fn shared_bake_lobe(&self, material: &Principled) -> Arc<BakeLobe> {
        type Entry = (PrincipledBasisConfig, Principled, Weak<BakeLobe>);
        static LOBES: Mutex<Vec<Entry>> = Mutex::new(Vec::new());
        let held = {
            let mut lobes = LOBES.lock().unwrap_or_else(|e| e.into_inner());
            lobes.retain(|(_, _, lobe)| lobe.strong_count() > 0);
            lobes
                .iter()
                .find(|(c, m, _)| c == self.config() && m == material)
                .and_then(|(_, _, lobe)| lobe.upgrade())
        };
        if let Some(lobe) = held {
            return lobe;
        }
        // Computed outside the lock: two readers racing on one lobe compute it twice, which
        // is correct, rather than one holding every other lobe's readers up.
        let lobe = Arc::new(self.bake_lobe(material));
        LOBES.lock().unwrap_or_else(|e| e.into_inner()).push((
            self.config().clone(),
            *material,
            Arc::downgrade(&lobe),
        ));
        lobe
    }

    /// The coefficients of material `p` on this basis and the bake-time slot of `lobe`
    /// (module docs): `count() + 1` slots.
    pub fn anchored_coefficients(&self, lobe: &BakeLobe, p: &Principled) -> AnchoredCoefficients {
        let below_range = (p.roughness as f64) < self.config().roughness_min - 1e-9;
        if *p == lobe.material {
            let mut slots = vec![[0.0f64; 3]; self.count() + 1];
            slots[self.count()] = [1.0; 3];
            return AnchoredCoefficients { slots, below_range };
        }
        let g = CyclesPrincipled::new(p);
        let slots = self.anchored_coefficients_of(lobe, principled_brdf(&g));
        AnchoredCoefficients { slots, below_range }
    }

    /// The coefficients of any BRDF `f` (per channel, a function of the four cosines) on
    /// this basis and the bake-time slot of `lobe`: how a region baked in this basis takes
    /// a material given as Blinn–Phong values, whose lobe is projected like any other.
    pub fn anchored_coefficients_of(
        &self,
        lobe: &BakeLobe,
        f: impl Fn(Cosines) -> [f64; 3] + Sync,
    ) -> Vec<[f64; 3]> {
        let sums = self.sums(&|_, c| f(c), Some(&lobe.at_nodes));
        self.fitted(lobe, &sums).0
    }

    /// Per slot and channel the fitted coefficients of the material whose sums are `sums`
    /// (the bake-time slot last, 0 in a channel where the basis holds `g`), and per channel
    /// the relative L2 error they leave.
    fn fitted(&self, lobe: &BakeLobe, sums: &Sums) -> (Vec<[f64; 3]>, [f64; 3]) {
        let n = self.count();
        let mut slots = vec![[0.0f64; 3]; n + 1];
        let mut errors = [0.0; 3];
        for (c, error) in errors.iter_mut().enumerate() {
            let (x, e) = self.cell_fit(lobe, sums, c).solve();
            for (s, v) in slots.iter_mut().zip(&x) {
                s[c] = *v;
            }
            *error = e;
        }
        (slots, errors)
    }

    /// Channel `c`'s fit ([`super::cells`]) over the basis' slots and, unless the basis
    /// holds the bake-time lobe already, that lobe's slot (last).
    fn cell_fit(&self, lobe: &BakeLobe, sums: &Sums, c: usize) -> CellFit {
        let n = self.count();
        let with_g = lobe.missed[c] > 0.0;
        let m = if with_g { n + 1 } else { n };
        let d2 = DIFFUSE * DIFFUSE;
        // ⟨ψ_k, h⟩ from a coefficient vector of h (slot 0's coefficient multiplies 1/π;
        // the specular bases are orthonormal and orthogonal to the constant).
        let dot = |k: usize, coefficients: &[[f64; 3]]| {
            if k == 0 {
                d2 * coefficients[0][c]
            } else {
                coefficients[k][c]
            }
        };
        let mut gram = vec![0.0f64; m * m];
        let mut rhs = vec![0.0f64; m];
        gram[0] = d2;
        for k in 1..n {
            gram[k * m + k] = 1.0;
        }
        for (k, r) in rhs.iter_mut().enumerate().take(n) {
            *r = dot(k, &sums.coefficients);
        }
        if with_g {
            for k in 0..n {
                let v = dot(k, &lobe.projection);
                gram[k * m + n] = v;
                gram[n * m + k] = v;
            }
            gram[n * m + n] = lobe.norm2[c];
            rhs[n] = sums.dot_g[c];
        }
        let cells = self.cell_count();
        let slot_grams = self.cell_grams();
        let stride = n + 3;
        let mut cell_grams = vec![0.0f64; cells * m * m];
        let mut cell_rhs = vec![0.0f64; cells * m];
        let mut cell_integral = vec![0.0f64; cells];
        let mut cell_measure = vec![0.0f64; cells];
        for cell in 0..cells {
            let gc = &mut cell_grams[cell * m * m..(cell + 1) * m * m];
            let basis = &slot_grams[cell * n * n..(cell + 1) * n * n];
            for k in 0..n {
                gc[k * m..k * m + n].copy_from_slice(&basis[k * n..(k + 1) * n]);
            }
            let at = (cell * 3 + c) * stride;
            let fd = &sums.cells[at..at + stride];
            cell_rhs[cell * m..cell * m + n].copy_from_slice(&fd[..n]);
            cell_integral[cell] = fd[n + 1];
            cell_measure[cell] = basis[0] / d2;
            if with_g {
                let gd = &lobe.cells[at..at + stride];
                for k in 0..n {
                    gc[k * m + n] = gd[k];
                    gc[n * m + k] = gd[k];
                }
                gc[n * m + n] = gd[n];
                cell_rhs[cell * m + n] = fd[n];
            }
        }
        CellFit {
            m,
            gram,
            rhs,
            cell_grams,
            cell_rhs,
            cell_integral,
            cell_measure,
            norm2: sums.norm2[c],
        }
    }

    /// The relative L2 error (per channel, under the basis' measure) of material `p` rebuilt
    /// from the basis alone (its least-squares projection, `‖Qf‖² = ‖f‖² − ‖Pf‖²`) and from
    /// the basis with `lobe`'s bake-time slot as a relight fits it ([`super::cells`]: larger
    /// than the projection's where holding the lobe's energy costs its shape).
    pub fn rebuild_error_with_bake_lobe(
        &self,
        lobe: &BakeLobe,
        p: &Principled,
    ) -> ([f64; 3], [f64; 3]) {
        let f = CyclesPrincipled::new(p);
        let f = principled_brdf(&f);
        let sums = self.sums(&|_, c| f(c), Some(&lobe.at_nodes));
        let held = self.held(&sums.coefficients, &sums.coefficients);
        let (_, with) = self.fitted(lobe, &sums);
        let plain = std::array::from_fn(|c| {
            let qf = (sums.norm2[c] - held[c]).max(0.0);
            (qf / sums.norm2[c].max(1e-300)).sqrt()
        });
        (plain, with)
    }

    /// `⟨Pa, Pb⟩` per channel from two coefficient vectors (the bases are orthonormal; slot
    /// 0's function is the constant 1 under the measure, its coefficient multiplies `1/π`).
    fn held(&self, a: &[[f64; 3]], b: &[[f64; 3]]) -> [f64; 3] {
        std::array::from_fn(|c| {
            a.iter()
                .zip(b)
                .enumerate()
                .map(|(k, (x, y))| {
                    if k == 0 {
                        x[c] * DIFFUSE * y[c] * DIFFUSE
                    } else {
                        x[c] * y[c]
                    }
                })
                .sum()
        })
    }

    /// [`Sums`] of `f` over the nodes: in fixed chunks added in order, so the result does not
    /// depend on the thread count. `f` gives the material's value at node `i` (whose cosines
    /// come with it); `g`, when given, holds the bake-time lobe at every node.
    fn sums(
        &self,
        f: &(impl Fn(usize, Cosines) -> [f64; 3] + Sync),
        g: Option<&[[f64; 3]]>,
    ) -> Sums {
        let slots = self.count();
        let ns = self.nspec.max(1);
        let stride = slots + 3;
        let cells = self.cell_count();
        let len = 3 * cells * stride;
        let chunk = |start: usize, nodes: &[Node], phis: &[f64]| {
            let mut acc = vec![0.0f64; len];
            for (i, (node, phi)) in nodes.iter().zip(phis.chunks(ns)).enumerate() {
                let v = f(start + i, node.c);
                let cell = self.cell_of(node);
                for ch in 0..3 {
                    let wf = node.weight * v[ch];
                    if wf == 0.0 {
                        continue;
                    }
                    let at = (cell * 3 + ch) * stride;
                    let sums = &mut acc[at..at + stride];
                    sums[0] += wf * DIFFUSE;
                    for (r, b) in sums[1..slots].iter_mut().zip(phi) {
                        *r += wf * b;
                    }
                    if let Some(g) = g {
                        sums[slots] += wf * g[start + i][ch];
                    }
                    sums[slots + 1] += wf;
                    sums[slots + 2] += wf * v[ch];
                }
            }
            acc
        };
        let partial: Vec<Vec<f64>> = self
            .nodes
            .par_chunks(NODES_PER_CHUNK)
            .zip(self.at_nodes.par_chunks(NODES_PER_CHUNK * ns))
            .enumerate()
            .map(|(k, (nodes, phis))| chunk(k * NODES_PER_CHUNK, nodes, phis))
            .collect();
        let mut total = vec![0.0; len];
        for p in partial {
            total.iter_mut().zip(&p).for_each(|(t, v)| *t += v);
        }
        debug_assert!(slots <= MAX_SLOTS);
        // The domain's sums are the cells' sums, added in cell order.
        let over_domain = |ch: usize, j: usize| -> f64 {
            (0..cells)
                .map(|cell| total[(cell * 3 + ch) * stride + j])
                .sum()
        };
        let coefficients = (0..slots)
            .map(|k| {
                std::array::from_fn(|ch| {
                    let d = over_domain(ch, k);
                    // ⟨1/π, f⟩ to the coefficient that multiplies 1/π.
                    if k == 0 {
                        d / (DIFFUSE * DIFFUSE)
                    } else {
                        d
                    }
                })
            })
            .collect();
        Sums {
            coefficients,
            norm2: std::array::from_fn(|ch| over_domain(ch, slots + 2)),
            dot_g: std::array::from_fn(|ch| over_domain(ch, slots)),
            cells: total,
        }
    }
}

/// A Cycles Principled BSDF as a function of the four cosines, for [`PrincipledBasis::sums`].
fn principled_brdf(f: &CyclesPrincipled) -> impl Fn(Cosines) -> [f64; 3] + Sync + '_ {
    move |c: Cosines| f.eval_cosines(c.cos_i, c.cos_o, c.cos_h, c.cos_d)
}
