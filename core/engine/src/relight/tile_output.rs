//! The two per-pixel loops at the end of every tile of the tiled sum
//! ([`super::tiled_sum`]), after its entries: the lattice's interpolation along x (one row
//! of nodes to a row of pixel columns, [`TileOutputKernels::along_x`]) and the add of the
//! tile's planar R, G, B sums into the RGBA image ([`TileOutputKernels::image_row`]).
//!
//! They cost per pixel, not per stored value, so on a stack with few entries per tile they
//! are most of the relight; written as plain loops they compile to scalar code (an indexed
//! load per column; a stride-4 store per channel). The AVX2 versions do the same arithmetic
//! eight pixels at a time — the row of nodes held in one register and permuted, the planar
//! rows transposed to pixels in registers — so every result is the same, bit for bit.
//!
//! A full sum writes every pixel of the image without reading it: where the image is
//! 16-byte aligned the AVX2 version streams those pixels to memory (non-temporal stores),
//! which spares the read of each line before it is written and leaves the cache to the
//! stack's values. Streamed stores are ordered by [`TileOutputKernels::end_of_band`], which
//! every worker calls before its band of the image is handed back.

/// Widest tile the loops take (the stack's tile side).
pub(crate) const MAX_COLUMNS: usize = 16;

/// Per pixel column of a tile, its two lattice nodes along x and their weights, as lanes
/// (columns from `width` on: node 0, weight 0).
#[derive(Clone, Debug, Default)]
pub(crate) struct ColumnHats {
    pub node: [[u32; MAX_COLUMNS]; 2],
    pub weight: [[f32; MAX_COLUMNS]; 2],
    pub width: usize,
}

/// The loops of one implementation (see the module doc): the relight's kernel types
/// (`super::kernels`) implement it, the portable one with these scalar defaults, the AVX2
/// one with [`x86`]'s loops.
pub(crate) trait TileOutputKernels: Copy {
    /// `out[x] = w0·row[n0] + w1·row[n1]` for each column `x < hats.width`, with `(n0, w0)`,
    /// `(n1, w1)` its hats.
    ///
    /// # Panics
    /// If `out` is shorter than `hats.width` or a hat's node is outside `row`.
    #[inline(always)]
    fn along_x(self, row: &[f32], hats: &ColumnHats, out: &mut [f32]) {
        along_x_scalar(row, hats, out);
    }

    /// Adds one row of a tile's planar sums into its pixels `px` (RGBA, `r.len()` pixels):
    /// `px += (r, g, b)` with alpha as it is; with `reset`, the pixels become
    /// `(0 + r, 0 + g, 0 + b, 1)` without being read.
    ///
    /// # Panics
    /// If `px` does not hold `4 · r.len()` floats or `g`, `b` are shorter than `r`.
    #[inline(always)]
    fn image_row(self, px: &mut [f32], r: &[f32], g: &[f32], b: &[f32], reset: bool) {
        image_row_scalar(px, r, g, b, reset);
    }

    /// Orders this thread's streamed image stores before its later stores (call once a
    /// worker's part of the image is written).
    #[inline(always)]
    fn end_of_band(self) {}
}

#[inline(always)]
pub(crate) fn along_x_scalar(row: &[f32], hats: &ColumnHats, out: &mut [f32]) {
    for (x, v) in out[..hats.width].iter_mut().enumerate() {
        let (n0, n1) = (hats.node[0][x] as usize, hats.node[1][x] as usize);
        *v = hats.weight[0][x] * row[n0] + hats.weight[1][x] * row[n1];
    }
}

#[inline(always)]
pub(crate) fn image_row_scalar(px: &mut [f32], r: &[f32], g: &[f32], b: &[f32], reset: bool) {
    assert_eq!(px.len(), 4 * r.len(), "image row of RGBA pixels");
    let (g, b) = (&g[..r.len()], &b[..r.len()]);
    for (dx, p) in px.chunks_exact_mut(4).enumerate() {
        if reset {
            p.copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
        }
        p[0] += r[dx];
        p[1] += g[dx];
        p[2] += b[dx];
    }
}

/// The AVX2 loops, for the AVX2 kernels' implementation of [`TileOutputKernels`]: to be
/// inlined into a function compiled with AVX2, as the tile loop is.
#[cfg(target_arch = "x86_64")]
pub(crate) mod x86 {
    use std::arch::x86_64::*;

    use super::{along_x_scalar, image_row_scalar, ColumnHats};

    /// Lanes of one vector step.
    const LANES: usize = 8;

    /// [`super::TileOutputKernels::along_x`].
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline(always)]
    pub(crate) unsafe fn along_x(row: &[f32], hats: &ColumnHats, out: &mut [f32]) {
        if row.len() > LANES || hats.width > hats.node[0].len() {
            along_x_scalar(row, hats, out);
            return;
        }
        assert!(out.len() >= hats.width, "along x: a value per column");
        debug_assert!(
            hats.node
                .iter()
                .flatten()
                .all(|&n| (n as usize) < row.len().max(1)),
            "along x: hats inside the row"
        );
        // SAFETY: AVX2 as the caller promises; the masked
        // load reads only `row`'s lanes, and a permute reads only the register (an
        // index past the row would pick a wrong lane, never memory); stores go to
        // `out[..width]` (whole vectors only where 8 columns from there are inside it,
        // else through a buffer).
        unsafe {
            let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
            let mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(row.len() as i32), lane);
            let nodes = _mm256_maskload_ps(row.as_ptr(), mask);
            let mut x = 0;
            while x < hats.width {
                let n0 = _mm256_loadu_si256(hats.node[0][x..].as_ptr().cast());
                let n1 = _mm256_loadu_si256(hats.node[1][x..].as_ptr().cast());
                let w0 = _mm256_loadu_ps(hats.weight[0][x..].as_ptr());
                let w1 = _mm256_loadu_ps(hats.weight[1][x..].as_ptr());
                let v = _mm256_add_ps(
                    _mm256_mul_ps(w0, _mm256_permutevar8x32_ps(nodes, n0)),
                    _mm256_mul_ps(w1, _mm256_permutevar8x32_ps(nodes, n1)),
                );
                let n = (hats.width - x).min(LANES);
                if n == LANES {
                    _mm256_storeu_ps(out.as_mut_ptr().add(x), v);
                } else {
                    let mut buf = [0.0f32; LANES];
                    _mm256_storeu_ps(buf.as_mut_ptr(), v);
                    out[x..x + n].copy_from_slice(&buf[..n]);
                }
                x += LANES;
            }
        }
    }

    /// [`super::TileOutputKernels::image_row`].
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline(always)]
    pub(crate) unsafe fn image_row(px: &mut [f32], r: &[f32], g: &[f32], b: &[f32], reset: bool) {
        let n = r.len();
        assert!(
            px.len() == 4 * n && g.len() >= n && b.len() >= n,
            "image row of RGBA pixels"
        );
        let whole = n / LANES * LANES;
        let stream = reset && (px.as_ptr() as usize).is_multiple_of(16);
        // SAFETY: AVX2 as the caller promises; each step reads lanes x..x + 8 < n of the rows
        // and writes the 8 pixels from x, inside `px` (4·n floats); streamed stores
        // need 16-byte alignment, which `stream` checked for the row's start (every
        // pixel is 16 bytes from there).
        unsafe {
            let zero = _mm256_setzero_ps();
            let alpha = if reset { _mm256_set1_ps(1.0) } else { zero };
            let mut x = 0;
            while x < whole {
                let (mut rv, mut gv, mut bv) = (
                    _mm256_loadu_ps(r.as_ptr().add(x)),
                    _mm256_loadu_ps(g.as_ptr().add(x)),
                    _mm256_loadu_ps(b.as_ptr().add(x)),
                );
                if reset {
                    // 0 + v, as the scalar loop adds into a cleared pixel (turns a
                    // −0 into +0).
                    rv = _mm256_add_ps(zero, rv);
                    gv = _mm256_add_ps(zero, gv);
                    bv = _mm256_add_ps(zero, bv);
                }
                // Planar to pixels: p[k] holds pixel k (low half) and pixel k + 4 (high).
                let rg_lo = _mm256_unpacklo_ps(rv, gv);
                let rg_hi = _mm256_unpackhi_ps(rv, gv);
                let ba_lo = _mm256_unpacklo_ps(bv, alpha);
                let ba_hi = _mm256_unpackhi_ps(bv, alpha);
                let p = [
                    _mm256_shuffle_ps::<0x44>(rg_lo, ba_lo),
                    _mm256_shuffle_ps::<0xEE>(rg_lo, ba_lo),
                    _mm256_shuffle_ps::<0x44>(rg_hi, ba_hi),
                    _mm256_shuffle_ps::<0xEE>(rg_hi, ba_hi),
                ];
                let out = px.as_mut_ptr().add(4 * x);
                for (k, pk) in p.iter().enumerate() {
                    let halves = [_mm256_castps256_ps128(*pk), _mm256_extractf128_ps::<1>(*pk)];
                    for (h, v) in halves.into_iter().enumerate() {
                        let at = out.add(4 * (k + 4 * h));
                        if stream {
                            _mm_stream_ps(at, v);
                        } else if reset {
                            _mm_storeu_ps(at, v);
                        } else {
                            // Alpha as it is (the added lane is 0, but 0 + −0 is +0).
                            let old = _mm_loadu_ps(at);
                            _mm_storeu_ps(at, _mm_blend_ps::<0b1000>(_mm_add_ps(old, v), old));
                        }
                    }
                }
                x += LANES;
            }
        }
        image_row_scalar(
            &mut px[4 * whole..],
            &r[whole..],
            &g[whole..n],
            &b[whole..n],
            reset,
        );
    }

    /// [`super::TileOutputKernels::end_of_band`]: a store fence.
    #[inline(always)]
    pub(crate) fn end_of_band() {
        // SAFETY: SSE is part of x86-64.
        unsafe { _mm_sfence() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scalar image row: a reset pixel is (0 + r, 0 + g, 0 + b, 1); otherwise the sums
    /// are added and alpha is left as it is. (The AVX2 loops are checked against these in
    /// `tile_output_tests.rs`.)
    #[test]
    fn image_row_resets_or_adds() {
        let mut px = vec![1.0, 2.0, 3.0, 0.5];
        image_row_scalar(&mut px, &[1.0], &[1.0], &[-0.0], false);
        assert_eq!(px, vec![2.0, 3.0, 3.0, 0.5]);
        image_row_scalar(&mut px, &[1.0], &[1.0], &[-0.0], true);
        assert_eq!(px, vec![1.0, 1.0, 0.0, 1.0]);
        assert!(px[2].is_sign_positive(), "0 + −0 is +0");
    }

    /// Interpolation along x: each column its two hats.
    #[test]
    fn along_x_weighs_two_nodes() {
        let mut hats = ColumnHats {
            width: 2,
            ..ColumnHats::default()
        };
        hats.node[1] = [1; MAX_COLUMNS];
        hats.weight[0][..2].copy_from_slice(&[1.0, 0.25]);
        hats.weight[1][..2].copy_from_slice(&[0.0, 0.75]);
        let mut out = [0.0; 2];
        along_x_scalar(&[2.0, 6.0], &hats, &mut out);
        assert_eq!(out, [2.0, 5.0]);
    }
}
