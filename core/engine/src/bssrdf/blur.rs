//! The sample-scale blur of the dipole profile (module docs of [`super::basis`], "What is
//! factored"): the profile's exact mass per annulus of the radius grid, and the Gaussian
//! blur matrix that spreads it while keeping every annulus' mass.

use super::dipole::DipoleParams;

/// Mass of `Rd_σ` over every cell (annulus) of the grid: exact, from the disc integral.
pub(super) fn annulus_masses(p: &DipoleParams, edges: &[f64]) -> Vec<f64> {
    edges
        .windows(2)
        .map(|e| p.annulus(e[0] * e[0], (e[1] - e[0]) * (e[1] + e[0])))
        .collect()
}

pub(super) fn apply_blur(blur: &[(usize, Vec<f64>)], masses: &[f64]) -> Vec<f64> {
    blur.iter()
        .map(|(first, w)| w.iter().zip(&masses[*first..]).map(|(w, m)| w * m).sum())
        .collect()
}

/// `e^{−x}·I₀(x)` for x ≥ 0 (Abramowitz & Stegun 9.8.1–9.8.2, relative error < 2·10⁻⁷).
fn i0e(x: f64) -> f64 {
    if x <= 3.75 {
        let t = (x / 3.75) * (x / 3.75);
        let i0 = 1.0
            + t * (3.515_622_9
                + t * (3.089_942_4
                    + t * (1.206_749_2 + t * (0.265_973_2 + t * (0.036_076_8 + t * 0.004_581_3)))));
        i0 * (-x).exp()
    } else {
        let t = 3.75 / x;
        let p = 0.398_942_28
            + t * (0.013_285_92
                + t * (0.002_253_19
                    + t * (-0.001_575_65
                        + t * (0.009_162_81
                            + t * (-0.020_577_06
                                + t * (0.026_355_37 + t * (-0.016_476_33 + t * 0.003_923_77)))))));
        p / x.sqrt()
    }
}

/// Angular average of the 2D Gaussian of standard deviation `sd` between a point at radius r
/// and the ring of radius s: `e^{−(r−s)²/(2sd²)}·i0e(rs/sd²)/(2π sd²)`.
fn ring_gauss(r: f64, s: f64, sd: f64) -> f64 {
    let v = sd * sd;
    (-(r - s) * (r - s) / (2.0 * v)).exp() * i0e(r * s / v) / (2.0 * std::f64::consts::PI * v)
}

/// Sub-rings per cell when averaging the Gaussian over a source cell.
const SUB_RINGS: usize = 6;

/// Unnormalised blur weights from every source cell to radius r: the Gaussian averaged over
/// the cell (SUB_RINGS sub-rings, area-weighted) for cells narrower than sd; cells wider
/// than sd (far out, where the profile varies on scales ≫ ρ) are not blurred (weight
/// 1/area for the cell holding r). Optional column normalisation `norm`.
pub(super) fn blur_row(
    r: f64,
    radii: &[f64],
    edges: &[f64],
    areas: &[f64],
    sd: f64,
    norm: Option<&[f64]>,
) -> (usize, Vec<f64>) {
    let n = radii.len();
    let lo = edges
        .partition_point(|e| *e < r - 8.0 * sd)
        .saturating_sub(1);
    let hi = edges.partition_point(|e| *e <= r + 8.0 * sd).min(n);
    let cell_of_r = edges
        .partition_point(|e| *e <= r)
        .saturating_sub(1)
        .min(n - 1);
    let (lo, hi) = (lo.min(cell_of_r), hi.max(cell_of_r + 1));
    let mut w = vec![0.0; hi - lo];
    for m in lo..hi {
        let (a, b) = (edges[m], edges[m + 1]);
        let v = if b - a > sd {
            if m == cell_of_r {
                1.0 / areas[m]
            } else {
                0.0
            }
        } else {
            let mut acc = 0.0;
            let mut wsum = 0.0;
            for q in 0..SUB_RINGS {
                let s0 = a + (b - a) * q as f64 / SUB_RINGS as f64;
                let s1 = a + (b - a) * (q + 1) as f64 / SUB_RINGS as f64;
                let ws = s1 * s1 - s0 * s0;
                acc += ws * ring_gauss(r, 0.5 * (s0 + s1), sd);
                wsum += ws;
            }
            acc / wsum
        };
        w[m - lo] = v * norm.map_or(1.0, |nm| nm[m]);
    }
    (lo, w)
}

/// The blur matrix on the grid, columns normalised so each source cell's mass is kept:
/// `Σ_j B_jm·area_j = 1`.
pub(super) type BlurRows = Vec<(usize, Vec<f64>)>;

pub(super) fn blur_matrix(
    radii: &[f64],
    edges: &[f64],
    areas: &[f64],
    sd: f64,
) -> (BlurRows, Vec<f64>) {
    let rows: Vec<(usize, Vec<f64>)> = radii
        .iter()
        .map(|&r| blur_row(r, radii, edges, areas, sd, None))
        .collect();
    let mut colsum = vec![0.0f64; radii.len()];
    for (j, (first, w)) in rows.iter().enumerate() {
        for (i, v) in w.iter().enumerate() {
            colsum[first + i] += v * areas[j];
        }
    }
    let norm: Vec<f64> = colsum
        .iter()
        .map(|c| if *c > 0.0 { 1.0 / c } else { 0.0 })
        .collect();
    let rows = rows
        .into_iter()
        .map(|(first, w)| {
            let w = w
                .iter()
                .enumerate()
                .map(|(i, v)| v * norm[first + i])
                .collect();
            (first, w)
        })
        .collect();
    (rows, norm)
}
