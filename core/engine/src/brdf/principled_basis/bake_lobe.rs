//! The region's bake-time lobe as one more slot beside the basis, and a relit material's
//! coefficients as the least-squares projection onto the basis and that slot together.
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
//! Per channel, `g` is the bake-time material's BRDF ([`CyclesPrincipled`]), `P` the
//! orthogonal projection onto the basis under its measure and `q = g − Pg` what the basis
//! misses of `g`. The edited material `f` is projected onto the span of the basis and `g`:
//! `α = ⟨f, q⟩ / ‖q‖²` on the bake-time slot and `P(f − α g)` on the basis. At the bake-time
//! material `α` is exactly 1 and every basis coefficient exactly 0 (the same sums on the
//! same values), so a relight there is the bake's exact lobe; an edit far from it (a rough
//! lobe from a smooth bake) has `α` near 0 and is the plain projection. Never worse than
//! the plain projection in the measure, since its span holds the basis'.
//!
//! Both projections are direct sums over the quadrature nodes, not the metal curves: `‖q‖²`
//! is `‖g‖² − ‖Pg‖²`, a small difference of large numbers that the curves' interpolation
//! error (a few 10⁻³ of the coefficients) would swamp.

use std::sync::{Arc, Mutex, Weak};

use rayon::prelude::*;

use super::lobes::DIFFUSE;
use super::quadrature::Node;
use super::{Cosines, PrincipledBasis, PrincipledBasisConfig, MAX_SLOTS, NODES_PER_CHUNK};
use crate::brdf::cycles_principled::CyclesPrincipled;
use crate::brdf::Principled;

/// Below this share of `‖g‖²` the basis holds the bake-time lobe already (`‖q‖²` is
/// rounding): the bake-time slot then gets no weight and the relight is the projection.
const IN_SPAN: f64 = 1e-10;

/// A region's bake-time lobe on the quadrature nodes, and what the basis holds of it.
pub struct BakeLobe {
    material: Principled,
    /// `g` per channel at every node.
    at_nodes: Vec<[f64; 3]>,
    /// `Pg`'s coefficients per slot (slot 0 multiplies `1/π`) and channel.
    projection: Vec<[f64; 3]>,
    /// `‖q‖²` per channel (0 where the basis holds `g`).
    missed: [f64; 3],
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
/// basis and, when `g` is given, `⟨f, g⟩` and `‖f‖²`.
struct Sums {
    coefficients: Vec<[f64; 3]>,
    dot_g: [f64; 3],
    norm2: [f64; 3],
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
        let sums = self.sums(&|i, _| at_nodes[i], None);
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
        let n = self.count();
        let sums = self.sums(&|_, c| f(c), Some(&lobe.at_nodes));
        let alpha = self.bake_slot_weight(lobe, &sums);
        let mut slots = vec![[0.0f64; 3]; n + 1];
        for c in 0..3 {
            for (k, s) in slots[..n].iter_mut().enumerate() {
                s[c] = sums.coefficients[k][c] - alpha[c] * lobe.projection[k][c];
            }
            slots[n][c] = alpha[c];
        }
        slots
    }

    /// `α = ⟨f, q⟩ / ‖q‖²` per channel (0 where the basis holds the bake-time lobe), from
    /// `f`'s sums with the lobe's values.
    fn bake_slot_weight(&self, lobe: &BakeLobe, sums: &Sums) -> [f64; 3] {
        let onto_pg = self.held(&sums.coefficients, &lobe.projection);
        std::array::from_fn(|c| {
            if lobe.missed[c] > 0.0 {
                (sums.dot_g[c] - onto_pg[c]) / lobe.missed[c]
            } else {
                0.0
            }
        })
    }

    /// The relative L2 error (per channel, under the basis' measure) of material `p` rebuilt
    /// from the basis alone (its projection) and from the basis with `lobe`'s bake-time slot:
    /// `‖Qf‖² = ‖f‖² − ‖Pf‖²` and, with the slot, `‖Qf‖² − α²‖q‖²`.
    pub fn rebuild_error_with_bake_lobe(
        &self,
        lobe: &BakeLobe,
        p: &Principled,
    ) -> ([f64; 3], [f64; 3]) {
        let f = CyclesPrincipled::new(p);
        let f = principled_brdf(&f);
        let sums = self.sums(&|_, c| f(c), Some(&lobe.at_nodes));
        let held = self.held(&sums.coefficients, &sums.coefficients);
        let alpha = self.bake_slot_weight(lobe, &sums);
        let mut plain = [0.0; 3];
        let mut with = [0.0; 3];
        for c in 0..3 {
            let qf = (sums.norm2[c] - held[c]).max(0.0);
            let rest = (qf - alpha[c] * alpha[c] * lobe.missed[c]).max(0.0);
            let n = sums.norm2[c].max(1e-300);
            plain[c] = (qf / n).sqrt();
            with[c] = (rest / n).sqrt();
        }
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
        let len = 3 * slots + 6;
        let chunk = |start: usize, nodes: &[Node], phis: &[f64]| {
            let mut acc = vec![0.0f64; len];
            for (i, (node, phi)) in nodes.iter().zip(phis.chunks(ns)).enumerate() {
                let v = f(start + i, node.c);
                for ch in 0..3 {
                    let wf = node.weight * v[ch];
                    if wf == 0.0 {
                        continue;
                    }
                    let row = &mut acc[ch * slots..(ch + 1) * slots];
                    row[0] += wf;
                    for (r, b) in row[1..].iter_mut().zip(phi) {
                        *r += wf * b;
                    }
                    acc[3 * slots + ch] += wf * v[ch];
                    if let Some(g) = g {
                        acc[3 * slots + 3 + ch] += wf * g[start + i][ch];
                    }
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
        let coefficients = (0..slots)
            .map(|k| {
                std::array::from_fn(|ch| {
                    let d = total[ch * slots + k];
                    if k == 0 {
                        d / DIFFUSE
                    } else {
                        d
                    }
                })
            })
            .collect();
        Sums {
            coefficients,
            norm2: std::array::from_fn(|ch| total[3 * slots + ch]),
            dot_g: std::array::from_fn(|ch| total[3 * slots + 3 + ch]),
        }
    }
}

/// A Cycles Principled BSDF as a function of the four cosines, for [`PrincipledBasis::sums`].
fn principled_brdf(f: &CyclesPrincipled) -> impl Fn(Cosines) -> [f64; 3] + Sync + '_ {
    move |c: Cosines| f.eval_cosines(c.cos_i, c.cos_o, c.cos_h, c.cos_d)
}
