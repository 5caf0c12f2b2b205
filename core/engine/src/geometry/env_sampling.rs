//! Importance sampling of an equirectangular world by hierarchical sample warping over a
//! mip pyramid (the technique of the DDGI importance-sampling note, and of Clarberg et al.'s
//! "wavelet importance sampling" warps): a uniform 2D sample is warped level by level from
//! the 2×2 top of the pyramid down to its finest level, each step choosing a column and then
//! a row in proportion to the sums below them; what is left of the sample places the
//! direction inside the chosen cell.
//!
//! ## Parametrisation and pdf
//!
//! The finest level is an N×N grid over the image's (u, v) square, N = the next power of two
//! of the image's larger side, capped at [`MAX_GRID`] (a 128×64 image gives 128×128 cells,
//! each image row covering two grid rows). Inside a cell the direction is placed uniformly in
//! (φ, z) (z = cos θ = sin of the elevation), not in (u, v): dω = dφ·dz exactly, so the
//! solid-angle pdf is piecewise constant, `p(ω) = P(cell) / (Δφ · Δz(cell))`, with
//! Δφ = 2π/N and Δz the difference of sin(elevation) over the cell's v range. This is the
//! pdf "texel probability × texels per unit area / (2π² sin θ)" of a uniform-in-(u,v)
//! placement with sin θ replaced by its exact mean over the row, so it has no pole
//! singularity (Δz > 0 even for the polar rows) and needs no sin θ guard.
//!
//! ## Cell weights
//!
//! A cell's weight is its solid angle Δφ·Δz times the *largest* luminance of the texels the
//! bilinear lookup reads inside it (the texel footprint dilated by one): the lookup blends
//! up to a texel beyond the one under a point, so a small bright sun (a few texels of 1e3–1e4)
//! also lights up its one-texel fringe; weighting by the max keeps every direction with
//! radiance at a positive pdf. The defensive cosine half of the mixture in
//! [`super::lights::LightSet`] covers the rest anyway (zero-luminance cells get pdf 0 here).
//!
//! The warp runs in f64: a 23-bit f32 uniform loses about one bit per level and axis, so at
//! N = 1024 (10 levels) about 13 bits place the sample inside its cell — plenty for a cell
//! 0.35° wide.

use glam::Vec3;
use std::f64::consts::PI;

use super::texture::Texture;

/// Largest side of the finest grid: 1024² cells hold 11 MB of f64 sums with the pyramid; a
/// larger image is summarised by the max over its texels per cell (still a valid pdf).
pub const MAX_GRID: usize = 1024;

/// Rec. 709 luminance, clamped at 0 (negative texels carry no light to sample).
fn luminance(r: f32, g: f32, b: f32) -> f64 {
    (0.2126 * r as f64 + 0.7152 * g as f64 + 0.0722 * b as f64).max(0.0)
}

/// The mip pyramid of an equirect image's luminance × solid angle, ready for warping.
#[derive(Clone)]
pub struct EnvSampler {
    /// Finest grid side N (a power of two).
    n: usize,
    /// levels[k] is 2^k × 2^k sums, row-major with row 0 the top (the zenith); levels[log2 N]
    /// is the finest grid, normalised so the whole pyramid sums to 1 at its top.
    levels: Vec<Vec<f64>>,
    /// [`row_z`] of each finest row boundary (N + 1) and the solid angle Δφ·Δz of a cell of
    /// each finest row (N): kept so that a sample or a pdf costs no sines (every world light
    /// sample and every BSDF ray that escapes asks for one).
    edge_z: Vec<f64>,
    row_area: Vec<f64>,
}

impl std::fmt::Debug for EnvSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "EnvSampler {{ n: {}, levels: {} }}",
            self.n,
            self.levels.len()
        )
    }
}

/// Elevation z = sin((v − ½)π) of the grid row boundary `edge` (0 = top, N = bottom).
#[inline]
fn row_z(edge: usize, n: usize) -> f64 {
    let v = 1.0 - edge as f64 / n as f64;
    ((v - 0.5) * PI).sin()
}

impl EnvSampler {
    /// Builds the pyramid of `image`; `None` when the image carries no light at all (then
    /// only cosine sampling makes sense).
    pub fn new(image: &Texture) -> Option<EnvSampler> {
        let (w, h) = image.size();
        if w == 0 || h == 0 {
            return None;
        }
        let n = w.max(h).next_power_of_two().clamp(1, MAX_GRID);
        let mut fine = vec![0.0f64; n * n];
        let edge_z: Vec<f64> = (0..=n).map(|edge| row_z(edge, n)).collect();
        let row_area: Vec<f64> = (0..n)
            .map(|row| 2.0 * PI / n as f64 * (edge_z[row] - edge_z[row + 1]).abs())
            .collect();
        // Texel luminance, computed once.
        let lum: Vec<f64> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let c = image.texel(x as isize, y as isize);
                luminance(c.x, c.y, c.z)
            })
            .collect();
        let lum_at = |x: isize, y: isize| {
            let x = x.rem_euclid(w as isize) as usize;
            let y = y.rem_euclid(h as isize) as usize;
            lum[y * w + x]
        };
        for row in 0..n {
            // Image y (from the top) range the bilinear lookup reads for this row's v range:
            // y = (1 − v)·H − ½ with (1 − v) ∈ [row/N, (row+1)/N].
            let y_lo = ((row as f64 / n as f64) * h as f64 - 0.5).floor() as isize;
            let y_hi = (((row + 1) as f64 / n as f64) * h as f64 - 0.5).floor() as isize + 1;
            let solid_angle = row_area[row];
            for col in 0..n {
                let x_lo = ((col as f64 / n as f64) * w as f64 - 0.5).floor() as isize;
                let x_hi = (((col + 1) as f64 / n as f64) * w as f64 - 0.5).floor() as isize + 1;
                let mut m = 0.0f64;
                for y in y_lo..=y_hi {
                    for x in x_lo..=x_hi {
                        m = m.max(lum_at(x, y));
                    }
                }
                fine[row * n + col] = m * solid_angle;
            }
        }
        let total: f64 = fine.iter().sum();
        if !(total > 0.0) || !total.is_finite() {
            return None;
        }
        for v in &mut fine {
            *v /= total;
        }
        // Coarser levels: each cell the sum of its 2×2 children.
        let mut levels = vec![fine];
        let mut side = n;
        while side > 1 {
            let child = levels.last().expect("at least the finest level");
            let half = side / 2;
            let mut parent = vec![0.0f64; half * half];
            for r in 0..half {
                for c in 0..half {
                    parent[r * half + c] = child[2 * r * side + 2 * c]
                        + child[2 * r * side + 2 * c + 1]
                        + child[(2 * r + 1) * side + 2 * c]
                        + child[(2 * r + 1) * side + 2 * c + 1];
                }
            }
            levels.push(parent);
            side = half;
        }
        levels.reverse();
        Some(EnvSampler {
            n,
            levels,
            edge_z,
            row_area,
        })
    }

    /// Side of the finest grid.
    pub fn grid_size(&self) -> usize {
        self.n
    }

    /// Warps (`u1`, `u2`) ∈ [0,1)² into a direction; returns it with its solid-angle pdf.
    pub fn sample(&self, u1: f32, u2: f32) -> (Vec3, f32) {
        let (mut x, mut y) = (u1 as f64, u2 as f64);
        let (mut col, mut row) = (0usize, 0usize);
        for (k, level) in self.levels.iter().enumerate().skip(1) {
            let side = 1usize << k;
            let (c0, r0) = (2 * col, 2 * row);
            let a = level[r0 * side + c0]; // top left
            let b = level[r0 * side + c0 + 1]; // top right
            let c = level[(r0 + 1) * side + c0]; // bottom left
            let d = level[(r0 + 1) * side + c0 + 1]; // bottom right
            let (left, right) = (a + c, b + d);
            // Column first, in proportion to the column sums; then the row given the column.
            let (top, bottom);
            if x * (left + right) < left || right <= 0.0 {
                x = if left > 0.0 {
                    x * (left + right) / left
                } else {
                    0.5
                };
                col = c0;
                (top, bottom) = (a, c);
            } else {
                x = (x * (left + right) - left) / right;
                col = c0 + 1;
                (top, bottom) = (b, d);
            }
            if y * (top + bottom) < top || bottom <= 0.0 {
                y = if top > 0.0 {
                    y * (top + bottom) / top
                } else {
                    0.5
                };
                row = r0;
            } else {
                y = (y * (top + bottom) - top) / bottom;
                row = r0 + 1;
            }
            x = x.clamp(0.0, 1.0 - 1e-12);
            y = y.clamp(0.0, 1.0 - 1e-12);
        }
        let n = self.n;
        // φ = (½ − u)·2π with u = (col + x)/N (Blender's mapping inverted).
        let u = (col as f64 + x) / n as f64;
        let phi = (0.5 - u) * 2.0 * PI;
        let (z_top, z_bottom) = (self.edge_z[row], self.edge_z[row + 1]);
        let z = (z_bottom + (z_top - z_bottom) * y).clamp(-1.0, 1.0);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let dir = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
        (dir, self.cell_pdf(row, col))
    }

    /// Solid-angle pdf of cell (`row`, `col`) of the finest grid.
    fn cell_pdf(&self, row: usize, col: usize) -> f32 {
        let p = self.levels[self.levels.len() - 1][row * self.n + col];
        let area = self.row_area[row];
        if area > 0.0 {
            (p / area) as f32
        } else {
            0.0
        }
    }

    /// The solid-angle pdf with which [`EnvSampler::sample`] draws the unit direction `dir`.
    pub fn pdf(&self, dir: Vec3) -> f32 {
        let n = self.n;
        let (dx, dy, dz) = (dir.x as f64, dir.y as f64, dir.z as f64);
        let u = (0.5 - dy.atan2(dx) / (2.0 * PI)).rem_euclid(1.0);
        let col = ((u * n as f64) as usize).min(n - 1);
        // The row whose z range holds dz (z falls with the row index).
        let v = 0.5 + dz.clamp(-1.0, 1.0).asin() / PI;
        let mut row = (((1.0 - v) * n as f64) as usize).min(n - 1);
        // Round-off at a row boundary: keep the row whose z interval holds dz.
        if row > 0 && dz > self.edge_z[row] {
            row -= 1;
        } else if row + 1 < n && dz < self.edge_z[row + 1] {
            row += 1;
        }
        self.cell_pdf(row, col)
    }
}
