//! The closest Blinn–Phong to Cycles' Principled BSDF, tabulated once (docs/principled_fit.md).
//!
//! [`fit`] fits, per roughness row, `ns` and `Kd, Ks` against
//! [`super::cycles_principled::CyclesPrincipled`] (GGX with multiple scattering and Cycles'
//! Fresnel, the diffuse base under the specular layer); [`table`] holds the result, written
//! by `scripts/principled_fit_table.sh`. [`fitted_blinn_phong`] looks a material up:
//!
//! * roughness: linear between rows (`ns` on a log scale); below the first row (0.05) the
//!   first row's `Kd, Ks` with the analytic mapping's growth of `ns`;
//! * metallic: linear (Cycles mixes the metal and dielectric layers linearly, and both use
//!   the row's `ns`);
//! * base colour: per channel, linear between the metal targets' base colours and exactly
//!   linear for dielectrics (their BRDF is linear in the base colour);
//! * dielectric specular F0 (from IOR and Specular IOR Level): linear between the targets'
//!   F0.
//!
//! Metal entries and dielectric entries at base colour 0 have `Kd, Ks ≥ 0`, `Kd + Ks ≤ 1`;
//! a dielectric's base-colour-1 end continues its unconstrained line, and the lookup clamps
//! `Ks` to [0, 1] and `Kd` to [0, 1 − Ks], so every looked-up material keeps Relume's energy
//! rule (the clamp acts only near base colour 1).
//! The fit is an approximation: a Blinn–Phong lobe that depends on the half angle only,
//! normalised as Relume's is, cannot follow GGX's view dependence (it reflects about
//! cos²θo of a mirror's light), so smooth metals stay darker than Cycles'; the measured
//! figures are in docs/principled_fit.md.

pub mod fit;
pub mod grid;
mod table;

pub use grid::{Row, DIELECTRIC_F0, METAL_BASE, ROUGHNESS};

use super::blinn_phong::BlinnPhong;
use super::principled::{dielectric_f0, roughness_to_ns, Principled, NS_MAX, NS_MIN};

/// The checked-in rows, one per entry of [`ROUGHNESS`].
pub fn rows() -> &'static [Row; 20] {
    &table::ROWS
}

/// Segment and fraction of `x` on the increasing grid `g` (clamped to its ends).
fn locate(g: &[f32], x: f32) -> (usize, f32) {
    let x = x.clamp(g[0], g[g.len() - 1]);
    let i = (0..g.len() - 1)
        .find(|&i| x <= g[i + 1])
        .unwrap_or(g.len() - 2);
    (i, ((x - g[i]) / (g[i + 1] - g[i])).clamp(0.0, 1.0))
}

fn lerp2(a: [f32; 2], b: [f32; 2], t: f32) -> [f32; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// `[Kd, Ks]` of one channel in one row.
fn row_channel(row: &Row, metallic: f32, base: f32, f0: f32) -> [f32; 2] {
    let (i, t) = locate(&METAL_BASE, base);
    let metal = lerp2(row.metal[i], row.metal[i + 1], t);
    let (j, u) = locate(&DIELECTRIC_F0, f0);
    let at_base = |e: [[f32; 2]; 2]| lerp2(e[0], e[1], base);
    let diel = lerp2(
        at_base(row.dielectric[j]),
        at_base(row.dielectric[j + 1]),
        u,
    );
    lerp2(diel, metal, metallic)
}

fn or_default(x: f32, default: f32) -> f32 {
    if x.is_nan() {
        default
    } else {
        x
    }
}

/// The fitted Blinn–Phong for Principled inputs (module docs). Total like the analytic
/// mapping: every input gives finite `Kd, Ks ≥ 0`, `Kd + Ks ≤ 1` per channel and `ns` in
/// [`NS_MIN`, `NS_MAX`].
pub fn fitted_blinn_phong(p: &Principled) -> BlinnPhong {
    let rows = rows();
    let r = or_default(p.roughness, 0.5).clamp(0.0, 1.0);
    let m = or_default(p.metallic, 0.0).clamp(0.0, 1.0);
    let f0 = dielectric_f0(p.ior, p.specular_ior_level);
    let (i, t) = locate(&ROUGHNESS, r);
    let ns = fitted_ns(r);
    let mut kd = [0.0f32; 3];
    let mut ks = [0.0f32; 3];
    for c in 0..3 {
        let base = or_default(p.base_color[c], 0.8).clamp(0.0, 1.0);
        let a = row_channel(&rows[i], m, base, f0);
        let b = row_channel(&rows[i + 1], m, base, f0);
        let [d, s] = lerp2(a, b, t);
        let s = if s.is_finite() {
            s.clamp(0.0, 1.0)
        } else {
            0.0
        };
        ks[c] = s;
        kd[c] = if d.is_finite() {
            d.clamp(0.0, 1.0 - s)
        } else {
            0.0
        };
    }
    BlinnPhong {
        kd,
        ks,
        ns: ns.clamp(NS_MIN, NS_MAX),
    }
}

/// The fitted exponent at Principled `roughness` (it depends on roughness alone): linear in
/// `ln ns` between rows, below the first row the analytic mapping's growth. Decreasing in
/// roughness; NaN reads as Blender's default 0.5.
pub fn fitted_ns(roughness: f32) -> f32 {
    let rows = rows();
    let r = or_default(roughness, 0.5).clamp(0.0, 1.0);
    let (i, t) = locate(&ROUGHNESS, r);
    let ns = if r < ROUGHNESS[0] {
        rows[0].ns * (roughness_to_ns(r) / roughness_to_ns(ROUGHNESS[0]))
    } else {
        (rows[i].ns.ln() * (1.0 - t) + rows[i + 1].ns.ln() * t).exp()
    };
    ns.clamp(NS_MIN, NS_MAX)
}

/// The Principled roughness whose fitted exponent ([`fitted_ns`]) is `ns`: the inverse the
/// range warnings and the estimate print, found by bisection on the decreasing curve;
/// exponents beyond the curve's ends give roughness 0 or 1.
pub fn roughness_for_fitted_ns(ns: f32) -> f32 {
    if ns.is_nan() {
        return 0.5;
    }
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    if ns >= fitted_ns(lo) {
        return lo;
    }
    if ns <= fitted_ns(hi) {
        return hi;
    }
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if fitted_ns(mid) > ns {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Maps Principled inputs to Blinn–Phong: the Blinn–Phong fitted to Cycles' Principled BSDF
/// (this module, docs/principled_fit.md), which every caller (bake, relight, CLI, Python,
/// add-on) gets. Total: every input, NaN and ±∞ included, gives finite `Kd, Ks ≥ 0` with
/// `Kd + Ks ≤ 1` per channel and `ns ∈ [NS_MIN, NS_MAX]`. The analytic mapping it replaced
/// is [`super::principled::principled_to_blinn_phong_analytic`].
pub fn principled_to_blinn_phong(p: &Principled) -> BlinnPhong {
    fitted_blinn_phong(p)
}

/// The table as Rust source (what `table.rs` holds), for the generator.
pub fn render_table(rows: &[Row]) -> String {
    let mut s = String::from(
        "//! Generated by `scripts/principled_fit_table.sh` (the ignored test\n\
         //! `brdf::principled_fit::tests::generate_table`); do not edit by hand.\n\n\
         use super::grid::Row;\n\n\
         #[rustfmt::skip]\n\
         pub(super) const ROWS: [Row; 20] = [\n",
    );
    let pair = |p: [f32; 2]| format!("[{:?}, {:?}]", p[0], p[1]);
    for r in rows {
        s += &format!("    Row {{\n        ns: {:?},\n        metal: [", r.ns);
        s += &r
            .metal
            .iter()
            .map(|&p| pair(p))
            .collect::<Vec<_>>()
            .join(", ");
        s += "],\n        dielectric: [\n";
        for d in &r.dielectric {
            s += &format!("            [{}, {}],\n", pair(d[0]), pair(d[1]));
        }
        s += "        ],\n    },\n";
    }
    s += "];\n";
    s
}

#[cfg(test)]
mod tests;
