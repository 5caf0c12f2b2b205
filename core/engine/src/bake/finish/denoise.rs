//! A linear denoiser for the transfer stack: an edge-avoiding À-trous filter (Dammertz et al.
//! 2010) whose weights come from the eye hits only — region, normal, position — never from
//! the layers' values.
//!
//! Why it may be applied to a stack at all: the relit image is Σ coefficient × layer. A
//! filter whose weights do not depend on the layers is one linear operator F applied alike to
//! every layer, so relit(F(stack)) = F(relit(stack)) for *every* material: editing stays
//! exact with respect to the filtered stack, and the filter costs nothing at relight time.
//! What it costs is bias: light that changes faster than the geometry (the inside of a soft
//! shadow, a caustic's rim) is blurred. That is why the presets apply it to the one-bounce
//! layers (smooth indirect light, most of the noise) with the widest kernel, and to the
//! direct layers with a narrower one or not at all; the report measures the resulting error
//! against a reference of the true BRDF, bias included.
//!
//! Its edge-stops: the region, the normal, the distance from the pixel's tangent plane (where
//! the geometry changes), and the distance over which indirect light can change on one
//! surface ([`super::reach`]: near a wall, a box's foot or a corner it changes within a
//! fraction of the distance to them), so the kernel is wide on open surfaces and narrow where
//! the light has a reason to change. All come from the geometry.
//!
//! Pixels whose eye samples did not all hit the same region (silhouettes), textured regions
//! (the texture is inside the layers; blurring it would blur the texture) and pixels that see
//! the world are passed through unfiltered and feed no neighbour.

use std::ops::Range;

use glam::Vec3;
use rayon::prelude::*;

use crate::bake::finish::drop::RawLayer;
use crate::bake::finish::reach;
use crate::bake::prepare::context::BakeContext;

/// Floats per pixel of the records gathered while tracing: see [`EyeFeatures::EMPTY`].
pub const FEATURE_STRIDE: usize = 9;

/// What the filter knows of a pixel: the eye hits of all its eye samples.
pub struct EyeFeatures {
    pub(in crate::bake) width: usize,
    pub(in crate::bake) height: usize,
    /// The region every eye sample hit, or `None` (mixed, world, or textured: not filtered).
    pub(in crate::bake) region: Vec<Option<u32>>,
    /// One more than the highest region in `region`.
    pub(in crate::bake) region_count: usize,
    normal: Vec<Vec3>,
    position: Vec<Vec3>,
    /// World size of one pixel at the hit (the distance between neighbouring camera rays
    /// there): the unit of the position test, so the filter behaves alike at any scene scale.
    footprint: Vec<f32>,
    /// How far the pixel's indirect light stays alike ([`reach::harmonic_distance`]);
    /// infinite where nothing is near, and for pixels that are not filtered.
    reach: Vec<f32>,
}

/// The fraction of a pixel's [reach](reach::harmonic_distance) at which a neighbour's weight
/// falls to 1/e. Ward's irradiance cache lets a value stand for points within a few tenths of
/// it; smaller keeps more of the light's changes and more noise (the stack compresses
/// less). Chosen by measurement (docs/trade.md, "Trying a retune").
const REACH_SCALE: f32 = 0.25;

impl EyeFeatures {
    /// A pixel's empty record: [`FEATURE_STRIDE`] floats — hit count, lowest and highest
    /// region hit, normal sum, position sum.
    pub const EMPTY: [f32; FEATURE_STRIDE] = [
        0.0,
        f32::INFINITY,
        f32::NEG_INFINITY,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
    ];

    /// Adds one eye hit to a pixel's record.
    #[inline]
    pub fn add(rec: &mut [f32], region: u32, normal: Vec3, position: Vec3) {
        let r = region as f32;
        rec[0] += 1.0;
        rec[1] = rec[1].min(r);
        rec[2] = rec[2].max(r);
        for (a, v) in rec[3..9]
            .iter_mut()
            .zip(normal.to_array().iter().chain(&position.to_array()))
        {
            *a += v;
        }
    }

    /// Merges the record `from` (other eye samples of the same pixel) into `into`.
    #[inline]
    pub fn merge(into: &mut [f32], from: &[f32]) {
        into[0] += from[0];
        into[1] = into[1].min(from[1]);
        into[2] = into[2].max(from[2]);
        for (a, v) in into[3..9].iter_mut().zip(&from[3..9]) {
            *a += v;
        }
    }

    /// Each pixel's [reach](reach::harmonic_distance) (infinite where it is not filtered),
    /// traced. It depends on the pixel's own record only, so a window may gather it from
    /// its tiles' ([`Self::with_reach`]) instead of tracing it again.
    pub fn traced_reach(&self, ctx: &BakeContext) -> Vec<f32> {
        (0..self.region.len())
            .into_par_iter()
            .map(|p| match self.region[p] {
                Some(_) => reach::harmonic_distance(
                    &ctx.geometry,
                    self.position[p],
                    self.normal[p],
                    self.footprint[p],
                ),
                None => f32::INFINITY,
            })
            .collect()
    }

    /// These features with every pixel's reach given (row-major, one per pixel).
    pub fn with_reach(mut self, reach: Vec<f32>) -> EyeFeatures {
        assert_eq!(reach.len(), self.region.len(), "one reach a pixel");
        self.reach = reach;
        self
    }

    /// Features of a window of the frame: `sums` holds the records of the `size.0 × size.1`
    /// pixels whose top-left pixel is `origin` (global coordinates: camera rays and
    /// footprints are the frame's). The filter treats the window's edges like the image's,
    /// so on a window its output is exact at pixels farther than the filter's footprint
    /// radius ([`footprint_radius`]) from every edge that is not the image's: a streaming
    /// bake filters a band of tile rows and keeps its centre.
    ///
    /// The pixels' [reach](reach::harmonic_distance) is left infinite: this is what
    /// [`Self::surface`] needs, which segments the stack's lattice entries, at none of the
    /// rays the reach costs. Filter only once [`Self::with_reach`] has given the reach
    /// ([`Self::traced_reach`], or one traced before for the same pixels).
    pub fn surfaces_from_window_sums(
        ctx: &BakeContext,
        sums: &[f32],
        spp: u32,
        origin: (usize, usize),
        size: (usize, usize),
    ) -> EyeFeatures {
        let (width, height) = size;
        let n = width * height;
        let mut region = vec![None; n];
        let mut normal = vec![Vec3::ZERO; n];
        let mut position = vec![Vec3::ZERO; n];
        let mut footprint = vec![0.0f32; n];
        for p in 0..n {
            let s = &sums[p * FEATURE_STRIDE..(p + 1) * FEATURE_STRIDE];
            let hits = s[0];
            if hits < spp as f32 || hits == 0.0 {
                continue;
            }
            if s[1] != s[2] {
                continue;
            }
            let r = s[1] as u32;
            if ctx
                .regions
                .get(r as usize)
                .is_none_or(|reg| reg.texture.is_some())
            {
                continue;
            }
            let nm = Vec3::new(s[3], s[4], s[5]).normalize_or_zero();
            if nm == Vec3::ZERO {
                continue;
            }
            let x = Vec3::new(s[6], s[7], s[8]) / hits;
            let (px, py) = (
                (origin.0 + p % width) as f32 + 0.5,
                (origin.1 + p / width) as f32 + 0.5,
            );
            let (o1, d1) = ctx.camera.ray(px, py);
            let (o2, d2) = ctx.camera.ray(px + 1.0, py);
            let t = (x - o1).length();
            footprint[p] = ((o2 - o1).length() + t * (d2 - d1).length()).max(1e-30);
            region[p] = Some(r);
            normal[p] = nm;
            position[p] = x;
        }
        let reach = vec![f32::INFINITY; n];
        EyeFeatures {
            width,
            height,
            region_count: region.iter().flatten().max().map_or(0, |r| *r as usize + 1),
            region,
            normal,
            position,
            footprint,
            reach,
        }
    }

    /// Normalised weights of the 5×5 taps of À-trous step `step` (pixels between taps) for
    /// every pixel; all zero for a pixel that is passed through.
    /// Only the pixel rows `rows` are computed; the others' weights are zero.
    fn weights(&self, step: usize, rows: Range<usize>) -> Vec<[f32; 25]> {
        const H: [f32; 5] = [1.0 / 16.0, 0.25, 0.375, 0.25, 1.0 / 16.0];
        let mut all = vec![[0.0f32; 25]; self.width * self.height];
        all[rows.start * self.width..rows.end * self.width]
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, out)| {
                let p = rows.start * self.width + i;
                let mut w = [0.0f32; 25];
                let Some(r) = self.region[p] else {
                    return;
                };
                let (x, y) = ((p % self.width) as isize, (p / self.width) as isize);
                let (np, xp, fp, rp) = (
                    self.normal[p],
                    self.position[p],
                    self.footprint[p],
                    self.reach[p],
                );
                let mut sum = 0.0;
                for j in 0..5 {
                    for i in 0..5 {
                        let qx = x + (i as isize - 2) * step as isize;
                        let qy = y + (j as isize - 2) * step as isize;
                        if qx < 0
                            || qy < 0
                            || qx >= self.width as isize
                            || qy >= self.height as isize
                        {
                            continue;
                        }
                        let q = qy as usize * self.width + qx as usize;
                        if self.region[q] != Some(r) {
                            continue;
                        }
                        let cos = np.dot(self.normal[q]).max(0.0);
                        let w_normal = cos.powi(32);
                        let pixels = ((i as f32 - 2.0).abs().max((j as f32 - 2.0).abs())
                            * step as f32)
                            .max(1.0);
                        let plane = np.dot(self.position[q] - xp).abs() / (fp * pixels);
                        let w_plane = (-plane * plane * 4.0).exp();
                        // The nearer pixel's reach bounds both: light may change that fast
                        // anywhere between them. Infinite reach gives 0 here, weight 1.
                        let apart = (self.position[q] - xp).length()
                            / (REACH_SCALE * rp.min(self.reach[q]));
                        let w_reach = (-apart * apart).exp();
                        let v = H[i] * H[j] * w_normal * w_plane * w_reach;
                        // Bounded by construction: a scene so large that the plane
                        // distance overflows (inf − inf) gives this tap no weight instead
                        // of a NaN that would spread through the window.
                        if !v.is_finite() {
                            continue;
                        }
                        w[j * 5 + i] = v;
                        sum += v;
                    }
                }
                if sum > 0.0 {
                    w.iter_mut().for_each(|v| *v /= sum);
                }
                *out = w;
            });
        all
    }

    /// Filters `layers` in place with `iterations` À-trous steps (steps 1, 2, 4, …: a
    /// footprint of 2·(2^iterations − 1) + 1 pixels). Pixels with no weights keep their value.
    /// Bakes filter sparsely ([`Self::filter_sparse`]); this whole-window form is the
    /// reference the sparse filter is tested against.
    pub fn filter(&self, layers: &mut [&mut RawLayer], iterations: u32) {
        let weights = self.weights_for(iterations);
        layers
            .par_iter_mut()
            .for_each(|layer| self.filter_one(&weights, layer));
    }

    /// The weights of every step of an `iterations`-step filter, computed once and shared
    /// by all the layers filtered with it ([`Self::filter_one`]).
    pub fn weights_for(&self, iterations: u32) -> FilterWeights {
        self.weights_for_rows(iterations, 0..self.height)
    }

    /// [`Self::weights_for`] for a sparse filter ([`Self::filter_sparse`]) whose wanted rows
    /// are `rows`: each step's weights only on the rows that step computes
    /// ([`step_rows`]), zero (never read) elsewhere.
    pub fn weights_for_rows(&self, iterations: u32, rows: Range<usize>) -> FilterWeights {
        FilterWeights {
            steps: (0..iterations)
                .map(|k| {
                    let at = step_rows(&rows, k, iterations, self.height);
                    self.weights(1usize << k, at)
                })
                .collect(),
        }
    }

    /// Filters one layer in place with every step of `weights`. Each layer is filtered on
    /// its own, so the result is the same whatever the layers around it.
    pub fn filter_one(&self, weights: &FilterWeights, layer: &mut RawLayer) {
        for (k, w) in weights.steps.iter().enumerate() {
            let step = 1usize << k;
            let c = layer.channels as usize;
            let src = &layer.data;
            // A region on which the layer is zero stays zero (weights never cross
            // regions): skip its pixels. Pair layers live on one eye region each.
            let mut live = vec![false; self.region_count];
            for (p, r) in self.region.iter().enumerate() {
                if let Some(r) = r {
                    if !live[*r as usize] && src[p * c..p * c + c].iter().any(|v| *v != 0.0) {
                        live[*r as usize] = true;
                    }
                }
            }
            if !live.iter().any(|l| *l) {
                continue;
            }
            let mut out = src.clone();
            for (p, wp) in w.iter().enumerate() {
                if wp[12] == 0.0 || !self.region[p].is_some_and(|r| live[r as usize]) {
                    continue;
                }
                let (x, y) = ((p % self.width) as isize, (p / self.width) as isize);
                let mut acc = [0.0f32; 3];
                for (t, &wt) in wp.iter().enumerate() {
                    if wt == 0.0 {
                        continue;
                    }
                    let qx = x + (t as isize % 5 - 2) * step as isize;
                    let qy = y + (t as isize / 5 - 2) * step as isize;
                    let q = qy as usize * self.width + qx as usize;
                    for (a, v) in acc.iter_mut().zip(&src[q * c..q * c + c]) {
                        *a += wt * v;
                    }
                }
                out[p * c..p * c + c].copy_from_slice(&acc[..c]);
            }
            layer.data = out;
        }
    }
}

/// The pixel rows step `k` of an `iterations`-step sparse filter computes so that the
/// rows `wanted` come out exact: `wanted` widened on each side by the tap reach of the
/// later steps (2·step each), within the `height` rows there are.
pub fn step_rows(wanted: &Range<usize>, k: u32, iterations: u32, height: usize) -> Range<usize> {
    let later: usize = (k + 1..iterations).map(|j| 2 * (1usize << j)).sum();
    wanted.start.saturating_sub(later)..(wanted.end + later).min(height)
}

/// The per-step tap weights of one filter ([`EyeFeatures::weights_for`]).
pub struct FilterWeights {
    pub(in crate::bake) steps: Vec<Vec<[f32; 25]>>,
}

/// Pixels an `iterations`-step filter reaches on each side: 2·(2^iterations − 1).
pub fn footprint_radius(iterations: u32) -> usize {
    2 * ((1usize << iterations) - 1)
}

impl EyeFeatures {
    /// Pixel `(x, y)`'s region and unit normal where the filter uses them (`None`: mixed,
    /// textured, the world): what the stack's lattice entries are segmented by
    /// ([`crate::stack::tiled::lattice::segment_map`]).
    pub(crate) fn surface(&self, x: usize, y: usize) -> Option<(u32, [f32; 3])> {
        let p = y * self.width + x;
        self.region[p].map(|r| (r, self.normal[p].to_array()))
    }
}

#[cfg(test)]
pub(in crate::bake) mod tests {
    use super::*;
    use crate::layer_key::LayerKey;

    /// A `w`×`h` view of two walls meeting at the middle column: region 0 facing +Z on the
    /// left, region 1 facing +X on the right, one world pixel in the corner (0, 0) and a
    /// silhouette pixel (mixed regions) at (1, 1).
    pub(crate) fn two_walls(w: usize, h: usize) -> EyeFeatures {
        let n = w * h;
        let mut f = EyeFeatures {
            width: w,
            height: h,
            region_count: 2,
            region: vec![None; n],
            normal: vec![Vec3::ZERO; n],
            position: vec![Vec3::ZERO; n],
            footprint: vec![0.01; n],
            reach: vec![f32::INFINITY; n],
        };
        for p in 0..n {
            let (x, y) = (p % w, p / w);
            let left = x < w / 2;
            f.region[p] = Some(if left { 0 } else { 1 });
            f.normal[p] = if left { Vec3::Z } else { Vec3::X };
            f.position[p] = if left {
                Vec3::new(x as f32 * 0.01, y as f32 * 0.01, 0.0)
            } else {
                Vec3::new(0.0, y as f32 * 0.01, x as f32 * 0.01)
            };
        }
        f.region[0] = None;
        f.region[w + 1] = None;
        f
    }

    pub(crate) fn layer(data: Vec<f32>, channels: u32) -> RawLayer {
        RawLayer {
            key: LayerKey::new(vec![]),
            channels,
            data,
        }
    }

    pub(crate) fn noise(i: usize) -> f32 {
        (crate::geometry::sampling::mix64(i as u64) >> 40) as f32 / (1u64 << 24) as f32
    }

    #[test]
    fn the_filter_is_linear_in_the_layers() {
        let f = two_walls(40, 30);
        let n = 40 * 30 * 3;
        let a: Vec<f32> = (0..n).map(noise).collect();
        let b: Vec<f32> = (0..n).map(|i| noise(i + n) * 5.0 - 1.0).collect();
        let mix: Vec<f32> = a.iter().zip(&b).map(|(x, y)| 0.3 * x - 2.0 * y).collect();
        let (mut la, mut lb, mut lm) = (layer(a, 3), layer(b, 3), layer(mix, 3));
        f.filter(&mut [&mut la, &mut lb, &mut lm], 3);
        for i in 0..n {
            let expect = 0.3 * la.data[i] - 2.0 * lb.data[i];
            assert!(
                (lm.data[i] - expect).abs() < 1e-5,
                "{i}: {} vs {expect}",
                lm.data[i]
            );
        }
    }

    #[test]
    fn light_stays_on_its_region_and_flat_light_stays_flat() {
        let (w, h) = (40, 30);
        let f = two_walls(w, h);
        // Constant 2 on the left wall, 0 on the right: after filtering the left wall is
        // still 2 everywhere and the right wall still 0 (no leak across the corner).
        let data: Vec<f32> = (0..w * h)
            .map(|p| if p % w < w / 2 { 2.0 } else { 0.0 })
            .collect();
        let mut l = layer(data.clone(), 1);
        f.filter(&mut [&mut l], 4);
        for (p, (got, want)) in l.data.iter().zip(&data).enumerate() {
            assert!((got - want).abs() < 1e-5, "pixel {p}: {got}");
        }
    }

    #[test]
    fn unfiltered_pixels_pass_through_and_feed_no_neighbour() {
        let (w, h) = (40, 30);
        let f = two_walls(w, h);
        let mut data = vec![1.0f32; w * h];
        data[0] = 1000.0;
        data[w + 1] = -1000.0;
        let mut l = layer(data, 1);
        f.filter(&mut [&mut l], 3);
        assert_eq!((l.data[0], l.data[w + 1]), (1000.0, -1000.0));
        for p in 0..w * h {
            if p != 0 && p != w + 1 {
                assert!((l.data[p] - 1.0).abs() < 1e-5, "pixel {p}: {}", l.data[p]);
            }
        }
    }

    #[test]
    fn light_changing_within_a_short_reach_keeps_its_step() {
        // A step in light across one flat wall (the left one): the tangent-plane test sees
        // no edge. Where the geometry says light can change fast (a reach of one pixel, as
        // at a wall's foot) the step stays; where it cannot (infinite reach) it is blurred.
        let (w, h) = (64, 32);
        let data: Vec<f32> = (0..w * h)
            .map(|p| if p % w < w / 4 { 0.0 } else { 1.0 })
            .collect();
        let at_step = |reach: f32| {
            let mut f = two_walls(w, h);
            f.reach = vec![reach; w * h];
            let mut l = layer(data.clone(), 1);
            f.filter(&mut [&mut l], 3);
            let y = h / 2;
            (l.data[y * w + w / 4 - 1], l.data[y * w + w / 4])
        };
        let (dark, lit) = at_step(f32::INFINITY);
        assert!(dark > 0.1 && lit < 0.9, "no reach limit: {dark} {lit}");
        let (dark, lit) = at_step(0.01);
        assert!(dark < 0.01 && lit > 0.99, "short reach: {dark} {lit}");
    }

    #[test]
    fn noise_on_a_flat_wall_falls_with_each_iteration() {
        let (w, h) = (64, 64);
        let f = two_walls(w, h);
        let data: Vec<f32> = (0..w * h).map(|i| 1.0 + (noise(i) - 0.5)).collect();
        let spread = |d: &[f32]| {
            let left: Vec<f32> = (8..h - 8)
                .flat_map(|y| (8..w / 2 - 8).map(move |x| y * w + x))
                .map(|p| d[p])
                .collect();
            let m = left.iter().sum::<f32>() / left.len() as f32;
            (left.iter().map(|v| (v - m).powi(2)).sum::<f32>() / left.len() as f32).sqrt()
        };
        let before = spread(&data);
        let mut last = before;
        for it in 1..=3 {
            let mut l = layer(data.clone(), 1);
            f.filter(&mut [&mut l], it);
            let s = spread(&l.data);
            assert!(s < 0.6 * last, "iterations {it}: {s} after {last}");
            last = s;
        }
        assert!(last < before / 8.0, "{last} from {before}");
    }
}
