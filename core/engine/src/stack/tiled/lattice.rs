//! Lattice entries: a layer's values over one tile stored as the coefficients of bilinear
//! hat functions on a coarse lattice, one set per *segment* of the tile.
//!
//! Why: the layers past the eye vertex's direct light (paths of two or more vertices) are
//! smooth in screen space except where the geometry seen from the eye changes — a region
//! boundary, a crease between two walls of one material. A tile's segment map splits its
//! pixels along exactly those edges (eye region, then a coarse normal class), and inside a
//! segment a few hat coefficients stand in for the pixels. The representation is linear in
//! the coefficients, so a relight of the stored coefficients is exact with respect to what
//! is stored: the approximation is made once, at the bake, where its error is measured.
//!
//! Geometry: lattice nodes every `step` pixels along each side of the tile, from the tile's
//! first pixel up to or past its last one ([`nodes_along`]). Pixel `x` lies in the cell
//! `i = min(x / step, n − 2)` between nodes `i` and `i + 1` with weights `1 − t`, `t`
//! (`t = (x − i·step) / step`); a pixel's value is `Σ hat · coefficient` over the ≤ 4 nodes
//! of its cell, of its own segment. A segment only stores the nodes with non-zero weight at
//! one of its pixels ([`SegmentNodes`]); those follow from the segment map alone, so the
//! file stores the map and the coefficients, never the node lists.
//!
//! The fit ([`LatticeFitter`]) is least squares over the segment's pixels; its normal
//! matrix depends only on the segment map, so it is factored once per segment and shared
//! by every layer and channel. Where a layer is ≥ 0 on a segment its fit there keeps every
//! node coefficient ≥ 0, so the fitted layer is ≥ 0 too ([`super::lattice_sign`]). A node with weak support (few pixels, small hat weights
//! there) is poorly determined by the data, so it is also pulled towards the straight-line
//! extrapolation of its neighbours along each axis: a penalty on second differences, which
//! is zero on any bilinear field, so such fields are still reproduced exactly. Every node
//! gets a negligible ridge besides, so the system is always solvable.
//!
//! This module knows nothing of the bake: the bake hands it each pixel's surface class.

use super::lattice_sign::solve_nonnegative;
use crate::linalg::{cholesky_in_place, cholesky_solve};

/// Most segments in one tile (an entry's covered segments are a 32-bit mask).
pub const MAX_SEGMENTS: usize = 32;

/// Longest tile side a lattice covers: the stack's tile edge (`STACK_TILE`, equal by a
/// test; not imported, so the tile types may import this module).
pub const MAX_TILE_SIDE: u32 = 16;

/// Widest lattice step in pixels: one cell spanning a whole tile.
pub const MAX_LATTICE_STEP: u32 = MAX_TILE_SIDE;

/// Smallest cosine between the normals of two pixels of one region that still share a
/// segment (to its first pixel): about 37°, so a crease between two walls splits a segment
/// and a curved surface splits only where it turns far.
const NORMAL_COS: f32 = 0.8;

/// A node is weakly supported when its diagonal is below this share of a fully supported
/// node's; its smoothness penalty has this weight (relative to a fully supported node's
/// diagonal), enough to decide what the data leaves open.
const WEAK_SHARE: f64 = 0.05;
/// Relative ridge on every node: keeps the system positive definite where hats are
/// linearly dependent on a segment's pixels; far below f32 rounding of the result.
const RIDGE_ALL: f64 = 1e-9;

/// Relative ridge (towards 0) of a weak node none of whose neighbours lines up for a
/// smoothness penalty: only decides what the data leaves fully open, so the fit stays
/// exact wherever the data determines the node.
const RIDGE_ISOLATED: f64 = 1e-6;

/// Marks a lattice node a segment does not store.
const NO_NODE: u16 = u16::MAX;

/// Lattice nodes along a tile side of `len` pixels at `step` pixels apart: one node when
/// the side has one pixel, else enough that the last node is at or past the last pixel.
pub fn nodes_along(len: u32, step: u32) -> u32 {
    if len <= 1 {
        1
    } else {
        (len - 1).div_ceil(step.max(1)) + 1
    }
}

/// The two nodes (index along the axis) of coordinate `x` and their weights.
#[inline]
fn axis_hats(x: u32, step: u32, nodes: u32) -> [(u32, f32); 2] {
    if nodes <= 1 {
        return [(0, 1.0), (0, 0.0)];
    }
    let i = (x / step).min(nodes - 2);
    let t = (x - i * step) as f32 / step as f32;
    [(i, 1.0 - t), (i + 1, t)]
}

/// The nodes one segment stores.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentNodes {
    /// Lattice node indices (row-major over the lattice), ascending: the order of the
    /// segment's coefficients in an entry.
    pub nodes: Vec<u16>,
    /// Per lattice node, its position in `nodes`, or `u16::MAX` when not stored.
    index: Vec<u16>,
}

/// A tile's segment map and the lattice over it: what every lattice entry of the tile
/// shares. Built only through [`TileLattice::new`], which checks the map.
#[derive(Clone, Debug, PartialEq)]
pub struct TileLattice {
    step: u32,
    width: u32,
    height: u32,
    /// Per pixel (row-major), its segment id.
    segments: Vec<u8>,
    /// Per segment id, the nodes it stores.
    layout: Vec<SegmentNodes>,
}

impl TileLattice {
    /// The lattice of a `width × height` tile with nodes every `step` pixels over segment
    /// map `segments` (per pixel row-major, ids from 0 up, every id below the highest used
    /// by at least one pixel). Errors (a message naming what is wrong): a step outside
    /// 1..=[`MAX_LATTICE_STEP`], a size outside 1..=16, a map of another length, an id of
    /// [`MAX_SEGMENTS`] or more, an id with no pixel.
    pub fn new(
        step: u32,
        width: u32,
        height: u32,
        segments: Vec<u8>,
    ) -> Result<TileLattice, String> {
        if !(1..=MAX_LATTICE_STEP).contains(&step) {
            return Err(format!(
                "lattice step {step}; a step is 1 to {MAX_LATTICE_STEP} pixels"
            ));
        }
        let tile = MAX_TILE_SIDE;
        if !(1..=tile).contains(&width) || !(1..=tile).contains(&height) {
            return Err(format!("a lattice over {width}×{height} pixels"));
        }
        let pixels = (width * height) as usize;
        if segments.len() != pixels {
            return Err(format!(
                "segment map of {} pixels for a tile of {pixels}",
                segments.len()
            ));
        }
        let count = segments.iter().map(|&s| s as usize + 1).max().unwrap_or(0);
        if count > MAX_SEGMENTS {
            return Err(format!(
                "segment id {} in the map; at most {MAX_SEGMENTS} segments",
                count - 1
            ));
        }
        let (nx, ny) = (nodes_along(width, step), nodes_along(height, step));
        let lattice_nodes = (nx * ny) as usize;
        let mut used = vec![vec![false; lattice_nodes]; count];
        let mut has_pixel = vec![false; count];
        for y in 0..height {
            for x in 0..width {
                let s = segments[(y * width + x) as usize] as usize;
                has_pixel[s] = true;
                for (node, w) in pixel_hats(x, y, step, nx, ny) {
                    if w > 0.0 {
                        used[s][node] = true;
                    }
                }
            }
        }
        if let Some(s) = has_pixel.iter().position(|h| !h) {
            return Err(format!("segment {s} has no pixel"));
        }
        let layout = used
            .into_iter()
            .map(|u| {
                let mut index = vec![NO_NODE; lattice_nodes];
                let mut nodes = Vec::new();
                for (k, _) in u.iter().enumerate().filter(|(_, u)| **u) {
                    index[k] = nodes.len() as u16;
                    nodes.push(k as u16);
                }
                SegmentNodes { nodes, index }
            })
            .collect();
        Ok(TileLattice {
            step,
            width,
            height,
            segments,
            layout,
        })
    }

    /// Pixels between lattice nodes.
    pub fn step(&self) -> u32 {
        self.step
    }
    /// Tile width and height the lattice covers.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// Per pixel (row-major), its segment id.
    pub fn segments(&self) -> &[u8] {
        &self.segments
    }
    /// Number of segments.
    pub fn segment_count(&self) -> usize {
        self.layout.len()
    }
    /// The nodes segment `s` stores.
    pub fn segment_nodes(&self, s: usize) -> &SegmentNodes {
        &self.layout[s]
    }
    /// Lattice nodes per row and rows of nodes.
    pub fn nodes(&self) -> (u32, u32) {
        (
            nodes_along(self.width, self.step),
            nodes_along(self.height, self.step),
        )
    }
    /// Lattice nodes in all.
    pub fn node_count(&self) -> usize {
        let (nx, ny) = self.nodes();
        (nx * ny) as usize
    }
    /// Bytes the lattice occupies in memory (map and node tables).
    pub fn memory_bytes(&self) -> usize {
        std::mem::size_of::<TileLattice>()
            + self.segments.len()
            + self
                .layout
                .iter()
                .map(|s| std::mem::size_of::<SegmentNodes>() + 2 * (s.nodes.len() + s.index.len()))
                .sum::<usize>()
    }

    /// Values an entry covering the segments of `mask` with `channels` channels stores, or
    /// `None` when the mask is empty or names a segment the tile lacks.
    pub fn coefficient_count(&self, mask: u32, channels: u8) -> Option<usize> {
        if mask == 0 || (self.segment_count() < 32 && mask >> self.segment_count() != 0) {
            return None;
        }
        Some(
            self.covered(mask)
                .map(|s| self.layout[s].nodes.len())
                .sum::<usize>()
                * channels as usize,
        )
    }

    /// Segment ids in `mask`, ascending (the order of an entry's coefficients).
    pub fn covered(&self, mask: u32) -> impl Iterator<Item = usize> + '_ {
        (0..self.segment_count()).filter(move |s| mask & (1 << s) != 0)
    }

    /// The ≤ 4 lattice nodes of pixel `(x, y)` and their weights (a weight may be 0).
    #[inline]
    pub fn hats(&self, x: u32, y: u32) -> [(usize, f32); 4] {
        let (nx, ny) = self.nodes();
        pixel_hats(x, y, self.step, nx, ny)
    }

    /// Per-pixel values (row-major, `channels` interleaved, radiance = value × `scale`) of
    /// an entry covering `mask` whose coefficients are `coef(i)`; pixels of segments not
    /// covered are 0. `mask` must be valid ([`coefficient_count`](Self::coefficient_count)).
    pub fn reconstruct(
        &self,
        mask: u32,
        channels: u8,
        coef: impl Fn(usize) -> f32,
        out: &mut [f32],
    ) {
        let c = channels as usize;
        let starts = self.segment_starts(mask, channels);
        for y in 0..self.height {
            for x in 0..self.width {
                let p = (y * self.width + x) as usize;
                let s = self.segments[p] as usize;
                let px = &mut out[p * c..(p + 1) * c];
                px.fill(0.0);
                let Some(start) = starts[s] else { continue };
                let index = &self.layout[s].index;
                for (node, w) in self.hats(x, y) {
                    if w == 0.0 {
                        continue;
                    }
                    let at = start + index[node] as usize * c;
                    for (ch, v) in px.iter_mut().enumerate() {
                        *v += w * coef(at + ch);
                    }
                }
            }
        }
    }

    /// Per segment id, where an entry covering `mask` starts its coefficients (`None`: not
    /// covered).
    pub fn segment_starts(&self, mask: u32, channels: u8) -> [Option<usize>; MAX_SEGMENTS] {
        let mut starts = [None; MAX_SEGMENTS];
        let mut at = 0usize;
        for s in self.covered(mask) {
            starts[s] = Some(at);
            at += self.layout[s].nodes.len() * channels as usize;
        }
        starts
    }

    /// Adds `weight ·` an entry's coefficients (`coef`, `channels`, covering `mask`) into
    /// node accumulators `acc`: per segment, per lattice node, RGB — `segment_count ×
    /// node_count × 3` floats. A grey entry adds its one value times each weight channel.
    /// Walks the mask's set bits and the coefficients as slices (the relight calls this once
    /// per lattice entry, so its per-entry cost is what a many-entry tile pays).
    ///
    /// # Panics
    /// If `coef` holds fewer values than the mask's segments store
    /// ([`coefficient_count`](Self::coefficient_count)) — impossible for a validated stack.
    pub fn accumulate(
        &self,
        acc: &mut [f32],
        mask: u32,
        channels: u8,
        coef: &[f32],
        weight: [f32; 3],
    ) {
        let nodes = self.node_count();
        let c = channels as usize;
        let mut rest = coef;
        let mut bits = mask;
        while bits != 0 {
            let s = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let Some(segment) = self.layout.get(s) else {
                break;
            };
            let segment_acc = &mut acc[s * nodes * 3..(s + 1) * nodes * 3];
            let (mine, tail) = rest.split_at(segment.nodes.len() * c);
            rest = tail;
            if c == 1 {
                for (&node, &v) in segment.nodes.iter().zip(mine) {
                    let dst = &mut segment_acc[node as usize * 3..node as usize * 3 + 3];
                    dst[0] += weight[0] * v;
                    dst[1] += weight[1] * v;
                    dst[2] += weight[2] * v;
                }
            } else {
                for (&node, v) in segment.nodes.iter().zip(mine.chunks_exact(3)) {
                    let dst = &mut segment_acc[node as usize * 3..node as usize * 3 + 3];
                    dst[0] += weight[0] * v[0];
                    dst[1] += weight[1] * v[1];
                    dst[2] += weight[2] * v[2];
                }
            }
        }
    }

    /// Adds node accumulators `acc` (see [`accumulate`](Self::accumulate)) into per-pixel
    /// interleaved RGB `out`: each pixel its segment's hats. Nodes a segment does not store
    /// hold 0 in `acc` (nothing adds to them) and weigh 0 at its pixels.
    pub fn expand(&self, acc: &[f32], out: &mut [f32]) {
        let (nx, ny) = self.nodes();
        let nodes = (nx * ny) as usize;
        let mut along_x = [[(0u32, 0.0f32); 2]; MAX_LATTICE_STEP as usize];
        for (x, h) in along_x.iter_mut().enumerate().take(self.width as usize) {
            *h = axis_hats(x as u32, self.step, nx);
        }
        for y in 0..self.height {
            let [(y0, wy0), (y1, wy1)] = axis_hats(y, self.step, ny);
            let rows = [(y0 * nx, wy0), (y1 * nx, wy1)];
            for x in 0..self.width {
                let p = (y * self.width + x) as usize;
                let base = self.segments[p] as usize * nodes;
                let mut sum = [0.0f32; 3];
                for &(row, wy) in &rows {
                    for &(col, wx) in &along_x[x as usize] {
                        let w = wx * wy;
                        let a = &acc[(base + (row + col) as usize) * 3..][..3];
                        for ch in 0..3 {
                            sum[ch] += w * a[ch];
                        }
                    }
                }
                let px = &mut out[p * 3..p * 3 + 3];
                for ch in 0..3 {
                    px[ch] += sum[ch];
                }
            }
        }
    }
}

#[inline]
fn pixel_hats(x: u32, y: u32, step: u32, nx: u32, ny: u32) -> [(usize, f32); 4] {
    let [(x0, wx0), (x1, wx1)] = axis_hats(x, step, nx);
    let [(y0, wy0), (y1, wy1)] = axis_hats(y, step, ny);
    let at = |i: u32, j: u32| (j * nx + i) as usize;
    [
        (at(x0, y0), wx0 * wy0),
        (at(x1, y0), wx1 * wy0),
        (at(x0, y1), wx0 * wy1),
        (at(x1, y1), wx1 * wy1),
    ]
}

/// What the segmenting knows of a pixel: the region its eye samples all hit and the unit
/// normal there, or `None` (mixed, textured, the world — one segment of their own).
pub type PixelSurface = Option<(u32, [f32; 3])>;

/// The segment map of a tile's pixels (row-major): pixels share a segment when they have
/// the same region and their normals are within about 37° of the segment's first pixel's;
/// every pixel without a surface shares one segment. `None` when the tile would need more
/// than [`MAX_SEGMENTS`] (it then keeps its layers per pixel).
pub fn segment_map(surfaces: &[PixelSurface]) -> Option<Vec<u8>> {
    let mut seeds: Vec<PixelSurface> = Vec::new();
    let mut map = Vec::with_capacity(surfaces.len());
    for s in surfaces {
        let found = seeds.iter().position(|seed| match (seed, s) {
            (None, None) => true,
            (Some((ra, na)), Some((rb, nb))) => {
                ra == rb && na[0] * nb[0] + na[1] * nb[1] + na[2] * nb[2] >= NORMAL_COS
            }
            _ => false,
        });
        let id = match found {
            Some(id) => id,
            None => {
                if seeds.len() == MAX_SEGMENTS {
                    return None;
                }
                seeds.push(*s);
                seeds.len() - 1
            }
        };
        map.push(id as u8);
    }
    Some(map)
}

/// Factored normal matrices of every segment of a [`TileLattice`]: fits any number of
/// layers over that tile.
pub struct LatticeFitter<'a> {
    lattice: &'a TileLattice,
    /// Per segment, its normal matrix plus penalties and ridge (row-major, n × n): what the
    /// sign-keeping solve works on.
    normals: Vec<Vec<f64>>,
    /// Per segment, the lower Cholesky factor of `normals`.
    factors: Vec<Vec<f64>>,
}

/// Whether a fit keeps the sign of a layer that is ≥ 0 (see [`LatticeFitter::fit`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitSign {
    /// Where the layer is ≥ 0 on a segment (per channel), every node coefficient there is
    /// ≥ 0: the fitted layer never goes below zero where the layer does not.
    KeepNonNegative,
    /// Plain least squares, which can undershoot below zero next to a step or a peak.
    Free,
}

/// One layer fitted over a tile.
#[derive(Clone, Debug, PartialEq)]
pub struct LatticeFit {
    /// Segments covered: those where the layer has a non-zero value.
    pub mask: u32,
    /// Per covered segment in id order, per stored node, `channels` values.
    pub coefficients: Vec<f32>,
    /// The fit at every pixel (row-major, channels interleaved): what the stack will hold.
    pub reconstructed: Vec<f32>,
    /// Segment-channels whose least-squares fit had a negative node on a segment where the
    /// layer is ≥ 0, and so were solved with non-negative nodes instead.
    pub sign_kept: u32,
}

impl<'a> LatticeFitter<'a> {
    /// Builds and factors the normal matrix `Σ_p h(p) h(p)ᵀ` of each segment over its stored
    /// nodes, plus for each node whose diagonal is under [`WEAK_SHARE`] of a fully
    /// supported node's the smoothness penalties of [`weak_node_stencils`] (or, with none,
    /// a small ridge towards 0), and [`RIDGE_ALL`] × that diagonal on every node.
    pub fn new(lattice: &'a TileLattice) -> LatticeFitter<'a> {
        let step = lattice.step as f64;
        let one_axis: f64 = 1.0
            + 2.0
                * (1..lattice.step)
                    .map(|j| (1.0 - j as f64 / step).powi(2))
                    .sum::<f64>();
        let full = one_axis * one_axis;
        let mut normal: Vec<Vec<f64>> = lattice
            .layout
            .iter()
            .map(|s| vec![0.0; s.nodes.len() * s.nodes.len()])
            .collect();
        for y in 0..lattice.height {
            for x in 0..lattice.width {
                let s = lattice.segments[(y * lattice.width + x) as usize] as usize;
                let seg = &lattice.layout[s];
                let n = seg.nodes.len();
                let hats = lattice.hats(x, y);
                for &(a, wa) in &hats {
                    if wa == 0.0 {
                        continue;
                    }
                    for &(b, wb) in &hats {
                        if wb == 0.0 {
                            continue;
                        }
                        let (i, j) = (seg.index[a] as usize, seg.index[b] as usize);
                        normal[s][i * n + j] += wa as f64 * wb as f64;
                    }
                }
            }
        }
        let (nx, ny) = lattice.nodes();
        let normals: Vec<Vec<f64>> = normal
            .into_iter()
            .zip(&lattice.layout)
            .map(|(mut m, seg)| {
                let n = seg.nodes.len();
                let weak: Vec<usize> = (0..n)
                    .filter(|&k| m[k * n + k] < WEAK_SHARE * full)
                    .collect();
                for k in weak {
                    let node = seg.nodes[k] as i64;
                    let (i, j) = (node % nx as i64, node / nx as i64);
                    // Position in the segment of the node `(di, dj)` away, if stored.
                    let at = |di: i64, dj: i64| -> Option<usize> {
                        let (a, b) = (i + di, j + dj);
                        if a < 0 || b < 0 || a >= nx as i64 || b >= ny as i64 {
                            return None;
                        }
                        let idx = seg.index[(b * nx as i64 + a) as usize];
                        (idx != NO_NODE).then_some(idx as usize)
                    };
                    let stencils = weak_node_stencils(&at);
                    if stencils.is_empty() {
                        m[k * n + k] += WEAK_SHARE * full * RIDGE_ISOLATED;
                    }
                    for d in stencils {
                        for &(a, va) in &d {
                            for &(b, vb) in &d {
                                m[a * n + b] += WEAK_SHARE * full * va * vb;
                            }
                        }
                    }
                }
                for k in 0..n {
                    m[k * n + k] += RIDGE_ALL * full;
                }
                m
            })
            .collect();
        let factors = normals
            .iter()
            .zip(&lattice.layout)
            .map(|(m, seg)| {
                let mut f = m.clone();
                cholesky_in_place(&mut f, seg.nodes.len(), 1e-300);
                f
            })
            .collect();
        LatticeFitter {
            lattice,
            normals,
            factors,
        }
    }

    /// The least-squares fit of `data` (the tile's pixels row-major, `channels`
    /// interleaved) on the segments where it is non-zero, keeping the sign where the data is
    /// ≥ 0 ([`FitSign::KeepNonNegative`]); `None` when it is zero everywhere.
    pub fn fit(&self, data: &[f32], channels: u8) -> Option<LatticeFit> {
        self.fit_with(data, channels, FitSign::KeepNonNegative)
    }

    /// The fit of `data` as [`fit`](Self::fit), with the sign handled as `sign` says.
    pub fn fit_with(&self, data: &[f32], channels: u8, sign: FitSign) -> Option<LatticeFit> {
        let l = self.lattice;
        let c = channels as usize;
        let mut mask = 0u32;
        for (p, px) in data.chunks_exact(c).enumerate() {
            if px.iter().any(|v| *v != 0.0) {
                mask |= 1 << l.segments[p];
            }
        }
        if mask == 0 {
            return None;
        }
        let starts = l.segment_starts(mask, channels);
        let total = l.coefficient_count(mask, channels)?;
        let mut rhs = vec![0.0f64; total];
        for y in 0..l.height {
            for x in 0..l.width {
                let p = (y * l.width + x) as usize;
                let s = l.segments[p] as usize;
                let Some(start) = starts[s] else { continue };
                for (node, w) in l.hats(x, y) {
                    if w == 0.0 {
                        continue;
                    }
                    let at = start + l.layout[s].index[node] as usize * c;
                    for ch in 0..c {
                        rhs[at + ch] += w as f64 * data[p * c + ch] as f64;
                    }
                }
            }
        }
        // Per segment and channel, whether the data is ≥ 0 at every pixel of the segment.
        let mut nonnegative = [[true; 3]; MAX_SEGMENTS];
        if sign == FitSign::KeepNonNegative {
            for (p, px) in data.chunks_exact(c).enumerate() {
                let s = l.segments[p] as usize;
                for (ch, v) in px.iter().enumerate() {
                    if *v < 0.0 {
                        nonnegative[s][ch] = false;
                    }
                }
            }
        }
        let mut coefficients = vec![0.0f32; total];
        let mut column = Vec::new();
        let mut constrained = Vec::new();
        let mut sign_kept = 0;
        for s in l.covered(mask) {
            let start = starts[s].unwrap_or(0);
            let n = l.layout[s].nodes.len();
            for ch in 0..c {
                column.clear();
                column.extend((0..n).map(|i| rhs[start + i * c + ch]));
                cholesky_solve(&self.factors[s], n, &mut column);
                if sign == FitSign::KeepNonNegative
                    && nonnegative[s][ch]
                    && column.iter().any(|v| *v < 0.0)
                {
                    // The right-hand side again (the solve overwrote it), only in the rare
                    // case that needs it, rather than a copy per segment and channel.
                    let b: Vec<f64> = (0..n).map(|i| rhs[start + i * c + ch]).collect();
                    constrained.resize(n, 0.0);
                    solve_nonnegative(&self.normals[s], n, &b, &mut constrained);
                    column.copy_from_slice(&constrained);
                    sign_kept += 1;
                }
                for (i, v) in column.iter().enumerate() {
                    coefficients[start + i * c + ch] = *v as f32;
                }
            }
        }
        let mut reconstructed = vec![0.0f32; data.len()];
        l.reconstruct(mask, channels, |i| coefficients[i], &mut reconstructed);
        Some(LatticeFit {
            mask,
            coefficients,
            reconstructed,
            sign_kept,
        })
    }
}

/// The smoothness penalties of a weak node (`at(di, dj)`: the position of the node that far
/// away along the lattice, if the segment stores it), each as (position, factor) terms:
/// per axis a second difference over three stored nodes in a row (centred, else
/// one-sided), zero on any bilinear field; where neither axis has one, a mixed difference
/// over a stored 2 × 2 block (zero on any affine field).
fn weak_node_stencils(at: &dyn Fn(i64, i64) -> Option<usize>) -> Vec<Vec<(usize, f64)>> {
    let mut out = Vec::new();
    for (ax, ay) in [(1i64, 0i64), (0, 1)] {
        let found = [[-1i64, 0, 1], [-2, -1, 0], [0, 1, 2]]
            .iter()
            .find_map(|ts| {
                let v: Option<Vec<usize>> = ts.iter().map(|&t| at(ax * t, ay * t)).collect();
                v
            });
        if let Some(v) = found {
            out.push(vec![(v[0], 1.0), (v[1], -2.0), (v[2], 1.0)]);
        }
    }
    if out.is_empty() {
        for (sx, sy) in [(1i64, 1i64), (-1, 1), (1, -1), (-1, -1)] {
            if let (Some(c), Some(x), Some(y), Some(xy)) =
                (at(0, 0), at(sx, 0), at(0, sy), at(sx, sy))
            {
                out.push(vec![(c, 1.0), (x, -1.0), (y, -1.0), (xy, 1.0)]);
                break;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nodes_reach_the_last_pixel() {
        assert_eq!(nodes_along(16, 4), 5);
        assert_eq!(nodes_along(16, 8), 3);
        assert_eq!(nodes_along(5, 4), 2);
        assert_eq!(nodes_along(1, 4), 1);
        for len in 1..=16 {
            for step in 1..=16 {
                let n = nodes_along(len, step);
                assert!((n - 1) * step >= len - 1);
                for x in 0..len {
                    let [(_, a), (_, b)] = axis_hats(x, step, n);
                    assert!((a + b - 1.0).abs() < 1e-6 && a >= 0.0 && b >= 0.0);
                }
            }
        }
    }

    #[test]
    fn a_map_with_a_gap_or_too_many_ids_is_refused() {
        assert!(TileLattice::new(4, 2, 1, vec![0, 2]).is_err());
        assert!(TileLattice::new(4, 2, 1, vec![0, 40]).is_err());
        assert!(TileLattice::new(0, 2, 1, vec![0, 0]).is_err());
        assert!(TileLattice::new(4, 2, 2, vec![0, 0]).is_err());
        assert!(TileLattice::new(4, 2, 1, vec![1, 0]).is_ok());
    }
}
