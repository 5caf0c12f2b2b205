//! The tail-edit record of one path: how many of its vertices beyond the first bounce lay
//! on each editable region, and the light each count carried.
//!
//! The frozen tail evaluates those vertices with the bake-time materials. An edit that
//! changes how much a region's material reflects (its diffuse or glossy energy, or both)
//! scales a tail contribution by S^t, S the region's energy now over its energy at bake time
//! and t the number of tail vertices on the region. So the bake counts, per path, the tail
//! vertices on each editable region (no random number is drawn, so the paths and every
//! other layer stay as they were) and sums each contribution by region and count. The
//! relight weighs those sums by S^t − 1 (times the eye and bounce vertices' own scales,
//! whose light the keyed layers already carry), which adds exactly what a single-region
//! albedo edit changes when the counts are below [`MAX_TAIL_COUNT`]. Approximations, each
//! small where the tail is: a region whose diffuse and glossy parts are scaled differently
//! scales its tail vertices by the ratio of its total energy; regions edited together are
//! summed as if edited one at a time (their product terms are left out); counts above
//! [`MAX_TAIL_COUNT`] are weighed as that count.

use crate::options::MAX_GROUPS;
use crate::Rgb;

/// The largest tail count kept apart; longer paths count as this many (their light is a
/// small share: each vertex multiplies it by an albedo).
pub const MAX_TAIL_COUNT: usize = 4;
/// Editable regions one path keeps apart (a path meeting more drops the extra regions'
/// edits).
pub const MAX_TRACKED: usize = 8;

const M: usize = MAX_TAIL_COUNT;

/// One path's tail-edit record (see the module docs).
#[derive(Clone)]
pub struct TailEdits {
    /// Editable regions met so far.
    ids: [u16; MAX_TRACKED],
    n: usize,
    /// Per tracked region, the probability that t of the vertices so far lay on it (t =
    /// 0..=M, the last lumping more), per channel (0 or 1 but for the lumping).
    dist: [[Rgb; M + 1]; MAX_TRACKED],
    /// Light groups in use.
    groups: usize,
    /// Per group, tracked region and count t = 1..=M, the light that arrived with t
    /// vertices on that region.
    sums: [[[Rgb; M]; MAX_TRACKED]; MAX_GROUPS],
}

impl TailEdits {
    /// An empty record for `groups` light groups.
    pub fn new(groups: usize) -> Self {
        TailEdits {
            ids: [0; MAX_TRACKED],
            n: 0,
            dist: [[Rgb::ZERO; M + 1]; MAX_TRACKED],
            groups: groups.min(MAX_GROUPS),
            sums: [[[Rgb::ZERO; M]; MAX_TRACKED]; MAX_GROUPS],
        }
    }

    /// The tracked slot of region `id`, added (no vertex on it yet) when new; `None` when
    /// [`MAX_TRACKED`] regions are tracked already.
    fn slot(&mut self, id: u16) -> Option<usize> {
        if let Some(k) = self.ids[..self.n].iter().position(|&i| i == id) {
            return Some(k);
        }
        if self.n == MAX_TRACKED {
            return None;
        }
        let k = self.n;
        self.ids[k] = id;
        self.dist[k] = [Rgb::ZERO; M + 1];
        self.dist[k][0] = Rgb::ONE;
        self.n += 1;
        Some(k)
    }

    /// The path continues from a vertex of editable region `region`.
    pub fn label(&mut self, region: u16) {
        if let Some(k) = self.slot(region) {
            self.dist[k] = shifted(&self.dist[k]);
        }
    }

    /// Light `piece` of `group` arrived through the vertices counted so far.
    pub fn record(&mut self, group: usize, piece: Rgb) {
        if piece == Rgb::ZERO || group >= self.groups {
            return;
        }
        for k in 0..self.n {
            for t in 1..=M {
                self.sums[group][k][t - 1] += piece * self.dist[k][t];
            }
        }
    }

    /// Light `piece` of `group` reflected towards the path at a vertex of editable region
    /// `region`: it counts one more vertex on that region.
    pub fn record_at(&mut self, group: usize, region: u16, piece: Rgb) {
        if group >= self.groups || piece == Rgb::ZERO {
            return;
        }
        let own = self.slot(region);
        for k in 0..self.n {
            let d = if own == Some(k) {
                shifted(&self.dist[k])
            } else {
                self.dist[k]
            };
            for t in 1..=M {
                self.sums[group][k][t - 1] += piece * d[t];
            }
        }
    }

    /// Every (group, region, count, light) with light, for the bounce vertex to weigh.
    pub fn for_each(&self, mut f: impl FnMut(usize, u16, usize, Rgb)) {
        for g in 0..self.groups {
            for k in 0..self.n {
                for t in 1..=M {
                    let v = self.sums[g][k][t - 1];
                    if v != Rgb::ZERO {
                        f(g, self.ids[k], t, v);
                    }
                }
            }
        }
    }
}

/// The count distribution after one more vertex on the region (the last count lumps).
#[inline]
fn shifted(d: &[Rgb; M + 1]) -> [Rgb; M + 1] {
    let mut out = [Rgb::ZERO; M + 1];
    out[1..(M + 1)].copy_from_slice(&d[..M]);
    out[M] += d[M];
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two vertices on region 0, light at each step, then light reflected by a vertex of
    /// region 1: each piece lands at its counts.
    #[test]
    fn counts_follow_the_regions_met() {
        let mut e = TailEdits::new(1);
        e.label(0);
        e.record(0, Rgb::splat(2.0));
        e.record_at(0, 0, Rgb::splat(0.5));
        e.label(0);
        e.record_at(0, 1, Rgb::splat(0.25));
        let mut got = Vec::new();
        e.for_each(|g, id, t, v| got.push((g, id, t, v.x)));
        assert_eq!(
            got,
            vec![(0, 0, 1, 2.0), (0, 0, 2, 0.75), (0, 1, 1, 0.25)]
        );
    }

    /// Counts above the largest kept count stay at it.
    #[test]
    fn the_last_count_lumps() {
        let mut e = TailEdits::new(1);
        for _ in 0..(M + 2) {
            e.label(3);
        }
        assert_eq!(e.dist[0][M], Rgb::ONE);
        let total: f32 = e.dist[0].iter().map(|v| v.x).sum();
        assert_eq!(total, 1.0);
    }
}
