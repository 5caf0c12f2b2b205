//! The tail-edit record of one path: how many of its vertices beyond the first bounce
//! reflected through each editable region's diffuse and glossy part, and the light each
//! pair of counts carried.
//!
//! The frozen tail evaluates those vertices with the bake-time materials. An edit that
//! changes how much a region's diffuse part reflects (Kd, Base Color) scales each tail
//! vertex on the region by s_d where it reflected diffusely and by s_g (Ks, metallic,
//! specular level) where glossily: a contribution whose bake-time BRDF at such a vertex
//! splits as f_d + f_g becomes s_d·f_d + s_g·f_g. Over the t vertices of a path on one
//! region that product is a polynomial Σ c_ij s_d^i s_g^j (i + j = t), so the bake carries,
//! per region met, the weight of each (i, j) — each vertex splitting its path's weights by
//! its diffuse share f_d / (f_d + f_g), per channel, with no random number drawn, so the
//! paths and every other layer stay as they were — and sums each contribution by region
//! and (i, j). The relight weighs those sums by s_d^i s_g^j − 1 (times the eye and bounce
//! vertices' own part scales, whose light the keyed layers already carry): exactly what an
//! edit of one region's part energies changes, while a path has at most
//! [`MAX_TAIL_COUNT`] tail vertices on it. Approximations, each small where the tail is:
//! vertices past that count keep their bake-time material; regions edited together are
//! summed as if edited one at a time (their product terms are left out); a lobe-shape edit
//! (exponent, roughness) changes a tail vertex only by its part's energy.
//!
//! The bounce vertex (x″) is keyed already; when it lies on the tail's region its own part
//! scale multiplies the term, s_b·(s_d^i s_g^j − 1), and keeping its part apart would store
//! three layers per pair. [`fold_bounce`] writes the same term in the monomials
//! s_d^a s_g^b − 1 instead, one layer each, so the layers are weighted as before and still
//! weigh exactly 0 at the bake-time materials.

use smallvec::SmallVec;

use crate::options::MAX_GROUPS;
use crate::Rgb;

/// The most tail vertices on one region a path's record keeps apart; later ones on that
/// region keep their bake-time material (each multiplies the light by an albedo, so their
/// share is small). Blender's default light paths give the tail at most three vertices.
pub const MAX_TAIL_COUNT: usize = 4;
/// Editable regions one path keeps apart (a path meeting more keeps the extra regions'
/// bake-time materials).
pub const MAX_TRACKED: usize = 8;

const M: usize = MAX_TAIL_COUNT;
/// Number of (i, j) pairs with i + j ≤ M, (0, 0) included.
const PAIRS: usize = (M + 1) * (M + 2) / 2;
/// Number of tail-edit bins: the pairs but (0, 0).
pub const TAIL_BINS: usize = PAIRS - 1;

/// Number of tail-edit bins of degree at most `degree`: the monomials s_d^i s_g^j with
/// 1 ≤ i + j ≤ `degree`, bin `k` being [`pair_of`]`(k + 1)`.
pub const fn monomial_bins(degree: usize) -> usize {
    (degree + 1) * (degree + 2) / 2 - 1
}

/// Stores tail light `light` of record bin `bin` (tail counts (i, j), [`pair_of`]`(bin + 1)`),
/// already times the eye vertex's BRDF, with the bounce vertex folded in: `emit(bin, value)`
/// per stored bin, each weighed at relight by s_d^a s_g^b − 1. A bounce vertex elsewhere
/// (`on` is `None`) multiplies the light by its BRDF `value`. One on the tail's region, whose
/// BRDF parts are `on` = [f_d, f_g], scales it by s_d or s_g per part:
/// s_d·(s_d^i s_g^j − 1) = (s_d^(i+1) s_g^j − 1) − (s_d − 1), and likewise for the glossy
/// part, so each part's light goes to its monomial one degree up and, negated, to the
/// degree-one monomial of its part.
#[inline]
pub fn fold_bounce(
    bin: usize,
    light: Rgb,
    on: Option<[Rgb; 2]>,
    value: Rgb,
    mut emit: impl FnMut(usize, Rgb),
) {
    match on {
        None => emit(bin, light * value),
        Some([d, g]) => {
            let (i, j) = pair_of(bin + 1);
            let (vd, vg) = (light * d, light * g);
            emit(pair_index(i + 1, j) - 1, vd);
            emit(pair_index(i, j + 1) - 1, vg);
            emit(pair_index(1, 0) - 1, -vd);
            emit(pair_index(0, 1) - 1, -vg);
        }
    }
}

/// The index of (diffuse count `i`, glossy count `j`), i + j ≤ M, among all pairs: by total
/// count, then by glossy count; (0, 0) is 0 and the tail-edit bin of a pair is its index − 1.
#[inline]
pub const fn pair_index(i: usize, j: usize) -> usize {
    let t = i + j;
    t * (t + 1) / 2 + j
}

/// The (diffuse, glossy) counts of pair index `k` ([`pair_index`]'s inverse).
pub const fn pair_of(k: usize) -> (usize, usize) {
    let mut t = 0;
    while (t + 1) * (t + 2) / 2 <= k {
        t += 1;
    }
    let j = k - t * (t + 1) / 2;
    (t - j, j)
}

/// One path's tail-edit record (see the module docs).
#[derive(Clone)]
pub struct TailEdits {
    /// Editable regions met so far (their tracked slots, in order).
    ids: SmallVec<[u16; MAX_TRACKED]>,
    /// Per tracked region, the weight of each (i, j) pair of diffuse and glossy counts among
    /// the tail vertices so far on it, per channel (they sum to 1).
    dist: SmallVec<[[Rgb; PAIRS]; MAX_TRACKED]>,
    /// Light groups in use.
    groups: usize,
    /// Per tracked region and group (row `k · groups + g`), per bin, the light that arrived
    /// with that pair of counts. Rows are added as regions are met: a record is made for
    /// every indirect sample, and one sized for every possible group and region was mostly
    /// zeroing (it showed in the bake's profile).
    sums: SmallVec<[[Rgb; TAIL_BINS]; MAX_TRACKED]>,
}

impl TailEdits {
    /// An empty record for `groups` light groups.
    pub fn new(groups: usize) -> Self {
        TailEdits {
            ids: SmallVec::new(),
            dist: SmallVec::new(),
            groups: groups.min(MAX_GROUPS),
            sums: SmallVec::new(),
        }
    }

    /// The tracked slot of region `id`, added (no vertex on it yet) when new; `None` when
    /// [`MAX_TRACKED`] regions are tracked already.
    fn slot(&mut self, id: u16) -> Option<usize> {
        if let Some(k) = self.ids.iter().position(|&i| i == id) {
            return Some(k);
        }
        if self.ids.len() == MAX_TRACKED {
            return None;
        }
        let k = self.ids.len();
        self.ids.push(id);
        let mut start = [Rgb::ZERO; PAIRS];
        start[0] = Rgb::ONE;
        self.dist.push(start);
        for _ in 0..self.groups {
            self.sums.push([Rgb::ZERO; TAIL_BINS]);
        }
        Some(k)
    }

    /// The path continues from a vertex of editable region `region` whose bake-time BRDF
    /// along the continuation splits as `parts` (diffuse, glossy).
    pub fn label(&mut self, region: u16, parts: [Rgb; 2]) {
        if let Some(k) = self.slot(region) {
            self.dist[k] = split(&self.dist[k], share_of(parts));
        }
    }

    /// Light `piece` of `group` arrived through the vertices labelled so far.
    pub fn record(&mut self, group: usize, piece: Rgb) {
        if piece == Rgb::ZERO || group >= self.groups {
            return;
        }
        for k in 0..self.ids.len() {
            for (s, d) in self.sums[k * self.groups + group]
                .iter_mut()
                .zip(&self.dist[k][1..])
            {
                *s += piece * *d;
            }
        }
    }

    /// Light of `group` reflected towards the path at a vertex of editable region `region`
    /// by its diffuse part (`pieces[0]`) and its glossy part (`pieces[1]`): each counts one
    /// more vertex of its own part.
    pub fn record_at(&mut self, group: usize, region: u16, pieces: [Rgb; 2]) {
        if group >= self.groups || pieces == [Rgb::ZERO; 2] {
            return;
        }
        let own = self.slot(region);
        let total = pieces[0] + pieces[1];
        for k in 0..self.ids.len() {
            let d = &self.dist[k];
            let sums = &mut self.sums[k * self.groups + group];
            if own == Some(k) {
                let with_d = split(d, Rgb::ONE);
                let with_g = split(d, Rgb::ZERO);
                for b in 0..TAIL_BINS {
                    sums[b] += pieces[0] * with_d[b + 1] + pieces[1] * with_g[b + 1];
                }
            } else {
                for (s, w) in sums.iter_mut().zip(&d[1..]) {
                    *s += total * *w;
                }
            }
        }
    }

    /// Every (group, region, bin, light) with light, for the bounce vertex to weigh.
    pub fn for_each(&self, mut f: impl FnMut(usize, u16, usize, Rgb)) {
        for g in 0..self.groups {
            for k in 0..self.ids.len() {
                for (b, v) in self.sums[k * self.groups + g].iter().enumerate() {
                    if *v != Rgb::ZERO {
                        f(g, self.ids[k], b, *v);
                    }
                }
            }
        }
    }
}

/// The diffuse share f_d / (f_d + f_g) per channel (1 where the vertex reflects nothing:
/// its light is 0 then anyway). It leaves [0, 1] where the glossy part dips below zero
/// (see [`crate::bake::path::frozen::frozen_parts`]); the weights stay exact in
/// expectation, and the path's throughput carries the small total, so a large share
/// multiplies a small light (bounded at ±10³ against rounding of a near-zero total).
#[inline]
fn share_of([d, g]: [Rgb; 2]) -> Rgb {
    let s = |d: f32, g: f32| {
        let t = d + g;
        if t > 0.0 {
            (d / t).clamp(-1e3, 1e3)
        } else {
            1.0
        }
    };
    Rgb::new(s(d.x, g.x), s(d.y, g.y), s(d.z, g.z))
}

/// The pair weights after one more vertex on the region, diffuse with weight `share` and
/// glossy with the rest; a pair already at [`MAX_TAIL_COUNT`] vertices stays.
#[inline]
fn split(d: &[Rgb; PAIRS], share: Rgb) -> [Rgb; PAIRS] {
    let rest = Rgb::ONE - share;
    let mut out = [Rgb::ZERO; PAIRS];
    for t in 0..=M {
        for j in 0..=t {
            let i = t - j;
            let w = d[pair_index(i, j)];
            if w == Rgb::ZERO {
                continue;
            }
            if t == M {
                out[pair_index(i, j)] += w;
            } else {
                out[pair_index(i + 1, j)] += w * share;
                out[pair_index(i, j + 1)] += w * rest;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_index_both_ways() {
        for k in 0..PAIRS {
            let (i, j) = pair_of(k);
            assert_eq!(pair_index(i, j), k);
            assert!(i + j <= M);
        }
    }

    /// A diffuse vertex of region 0, light there, then light reflected by a vertex with a
    /// diffuse and a glossy part: each piece lands at its pair of counts.
    #[test]
    fn counts_follow_the_parts() {
        let mut e = TailEdits::new(1);
        e.label(0, [Rgb::ONE, Rgb::ZERO]);
        e.record(0, Rgb::splat(2.0));
        e.record_at(0, 0, [Rgb::splat(0.5), Rgb::splat(0.25)]);
        let mut got = Vec::new();
        e.for_each(|g, id, b, v| got.push((g, id, pair_of(b + 1), v.x)));
        assert_eq!(
            got,
            vec![
                (0, 0, (1, 0), 2.0),
                (0, 0, (2, 0), 0.5),
                (0, 0, (1, 1), 0.25)
            ]
        );
    }

    /// Folding the bounce vertex keeps the relit term: Σ stored value × (s_d^a s_g^b − 1)
    /// equals s_b·(s_d^i s_g^j − 1) × light, s_b the bounce vertex's scaled BRDF over its
    /// bake-time one, for every record bin and scales that are not 1.
    #[test]
    fn folded_bounce_weighs_as_its_part() {
        let (sd, sg) = (1.7f32, 0.45f32);
        let [d, g] = [Rgb::new(0.3, 0.1, 0.2), Rgb::new(0.05, 0.2, 0.4)];
        let light = Rgb::new(2.0, 1.0, 0.5);
        for bin in 0..TAIL_BINS {
            let (i, j) = pair_of(bin + 1);
            let tail = sd.powi(i as i32) * sg.powi(j as i32) - 1.0;
            let want = light * (d * sd + g * sg) * tail;
            let mut got = Rgb::ZERO;
            fold_bounce(bin, light, Some([d, g]), d + g, |b, v| {
                assert!(b < monomial_bins(M + 1));
                let (a, c) = pair_of(b + 1);
                got += v * (sd.powi(a as i32) * sg.powi(c as i32) - 1.0);
            });
            assert!(
                (got - want).abs().max_element() < 1e-4,
                "{bin}: {got} vs {want}"
            );
            let mut elsewhere = Rgb::ZERO;
            fold_bounce(bin, light, None, d + g, |b, v| {
                assert_eq!(b, bin);
                elsewhere += v * tail;
            });
            assert!((elsewhere - light * (d + g) * tail).abs().max_element() < 1e-4);
        }
    }

    /// A half-diffuse vertex splits the weights; a path past the largest count keeps them.
    #[test]
    fn shares_split_and_later_vertices_stay() {
        let mut e = TailEdits::new(1);
        for _ in 0..(M + 2) {
            e.label(3, [Rgb::splat(0.5), Rgb::splat(0.5)]);
        }
        let total: f32 = e.dist[0].iter().map(|v| v.x).sum();
        assert!((total - 1.0).abs() < 1e-6, "{total}");
        assert_eq!(e.dist[0][pair_index(2, 2)].x, 6.0 / 16.0);
    }
}
