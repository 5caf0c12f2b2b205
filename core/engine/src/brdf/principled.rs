//! Principled BSDF → Blinn–Phong (docs/design.md §3).
//!
//! `principled_to_blinn_phong`, the mapping every caller uses, looks up the Blinn–Phong
//! fitted to Cycles' Principled BSDF (module `principled_fit`, docs/principled_fit.md). The
//! **analytic mapping** below ([`principled_to_blinn_phong_analytic`]) is the documented
//! fallback and the baseline of the fit's measurements; the fit keeps its F0
//! (`dielectric_f0`) and its clamping of inputs, and uses its exponent's growth below the
//! fitted roughness range.
//!
//! * **Exponent.** Blender's roughness `r` gives the GGX/Beckmann width `α = r²`; the
//!   Blinn–Phong exponent with the same Beckmann-like width is `ns = 2/α² − 2`. So the paper's
//!   `ns = 200` is `r ≈ 0.32` and `r = 0.1` is `ns ≈ 20,000`. `r = 0` would give `ns = ∞`:
//!   `α` is clamped below at `α_min = √(2/(NS_MAX+2))` (≈ 1.41e-3, `r ≈ 0.0376`) so that
//!   `ns ≤ NS_MAX = 10⁶` (a 0.067° half-width lobe, already sharper than an `f32` cos δ can
//!   resolve). `r = 1` gives `ns = 0`, clamped up to `NS_MIN = 10⁻³` (a nearly constant lobe)
//!   because `ns > 0` is required. The basis then clamps `ns` to its own range when it
//!   computes coefficients (`BrdfBasis::spec_coefficients`) — never silently: the relighters
//!   report every editable material outside its region's baked range
//!   (`StackBases::ns_out_of_range`: the CLI's warnings, `Relighter.warnings` in Python, the
//!   add-on's panel and `status()["range_warnings"]`).
//! * **Specular colour.** Dielectric `F0 = ((ior−1)/(ior+1))²` (0.04 at the default IOR 1.5),
//!   scaled by `2·Specular IOR Level` as Blender's manual describes it (0.5 leaves F0 as the
//!   IOR gives it, 0 removes reflection, 1 doubles it at normal incidence), clamped to ≤ 1.
//!   Metals reflect their base colour: `Ks = mix(F0, base, metallic)` per channel.
//! * **Diffuse.** The dielectric part's diffuse sits under its specular layer and gets the
//!   energy the specular did not take: `Kd = (1 − metallic)·base·(1 − F0)`. With `base ≤ 1`
//!   this already gives `Kd + Ks = 1 − (1−m)(1−base)(1−F0) − m(1−base) ≤ 1`; the mapping
//!   still scales `Kd` down to `1 − Ks` as a guard, so `Kd + Ks ≤ 1` holds per channel for
//!   every input.
//! * **Out-of-range inputs** are clamped, never rejected (the function is total; use
//!   [`Principled::validate`] to get an error instead): base colour to [0, 1] (Blender accepts
//!   values above 1, which would break `Kd + Ks ≤ 1`), metallic and roughness to [0, 1],
//!   Specular IOR Level
//!   to [0, 1], IOR below 1 is mirrored to `1/ior` (same F0). NaN inputs fall back to
//!   Blender's defaults (base 0.8, metallic 0, roughness 0.5, IOR 1.5, level 0.5); an IOR of
//!   +∞ gives F0 = 1.

#![allow(clippy::neg_cmp_op_on_partial_ord)] // `!(x > 0.0)` deliberately rejects NaN too.

use serde::{Deserialize, Serialize};

use super::BlinnPhong;
use crate::{RelumeError, Result};

/// Smallest exponent the mapping returns (roughness 1): `ns` must be > 0.
pub const NS_MIN: f32 = 1e-3;
/// Largest exponent the mapping returns (roughness ≤ ≈0.0376): finite, and a lobe already
/// narrower (0.067° half width) than an `f32` `cos δ` resolves near δ = 0.
pub const NS_MAX: f32 = 1e6;

/// The Principled BSDF inputs Relume reads (Blender names in the docs of each field).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct Principled {
    /// "Base Color", scene-linear.
    pub base_color: [f32; 3],
    /// "Metallic" ∈ [0, 1].
    #[serde(default)]
    pub metallic: f32,
    /// "Roughness" ∈ [0, 1].
    #[serde(default = "half")]
    pub roughness: f32,
    /// "IOR".
    #[serde(default = "ior")]
    pub ior: f32,
    /// "Specular IOR Level" (0.5 leaves F0 as the IOR gives it).
    #[serde(default = "half")]
    pub specular_ior_level: f32,
}
fn half() -> f32 {
    0.5
}
fn ior() -> f32 {
    1.5
}

impl Principled {
    /// Errors (naming `"{what}.field"`) where the mapping would have to clamp or substitute a
    /// value: non-finite inputs, negative base colour, metallic or roughness outside [0, 1],
    /// IOR ≤ 0, Specular IOR Level < 0. Base colour above 1 is accepted (Blender allows it;
    /// the mapping clamps it to 1).
    pub fn validate(&self, what: &str) -> Result<()> {
        let err =
            |field: &str, msg: String| Err(RelumeError::invalid(format!("{what}.{field}"), msg));
        for (c, x) in self.base_color.iter().enumerate() {
            if !x.is_finite() || *x < 0.0 {
                return err(
                    "base_color",
                    format!("channel {c} must be finite and ≥ 0, got {x}"),
                );
            }
        }
        for (name, x) in [("metallic", self.metallic), ("roughness", self.roughness)] {
            if !(0.0..=1.0).contains(&x) {
                return err(name, format!("must be in [0, 1], got {x}"));
            }
        }
        if !self.ior.is_finite() || !(self.ior > 0.0) {
            return err("ior", format!("must be finite and > 0, got {}", self.ior));
        }
        if !self.specular_ior_level.is_finite() || self.specular_ior_level < 0.0 {
            return err(
                "specular_ior_level",
                format!("must be finite and ≥ 0, got {}", self.specular_ior_level),
            );
        }
        Ok(())
    }
}

fn or_default(x: f32, default: f32) -> f32 {
    if x.is_nan() {
        default
    } else {
        x
    }
}

/// Blinn–Phong exponent for a Principled roughness: `ns = 2/α² − 2`, `α = r²`, clamped to
/// [[`NS_MIN`], [`NS_MAX`]] (see the module docs). NaN roughness is treated as 0.5 (ns ≈ 30).
pub fn roughness_to_ns(roughness: f32) -> f32 {
    let r = or_default(roughness, 0.5).clamp(0.0, 1.0) as f64;
    let alpha_min = (2.0 / (NS_MAX as f64 + 2.0)).sqrt();
    let alpha = (r * r).max(alpha_min);
    let ns = 2.0 / (alpha * alpha) - 2.0;
    (ns as f32).clamp(NS_MIN, NS_MAX)
}

/// Dielectric normal-incidence reflectance from IOR and Specular IOR Level (module docs).
pub fn dielectric_f0(ior: f32, specular_ior_level: f32) -> f32 {
    let mut eta = or_default(ior, 1.5) as f64;
    if !(eta > 0.0) {
        eta = 1.5;
    }
    if eta < 1.0 {
        eta = 1.0 / eta;
    }
    // (η−1)/(η+1) written as 1 − 2/(η+1): exact 1 for η = +∞ instead of ∞/∞.
    let r = 1.0 - 2.0 / (eta + 1.0);
    let level = or_default(specular_ior_level, 0.5).clamp(0.0, 1.0) as f64;
    ((r * r) * 2.0 * level).clamp(0.0, 1.0) as f32
}

/// The analytic mapping of the module docs, kept as the documented fallback and the baseline
/// the fit is measured against. Total: every input, NaN and ±∞ included, gives finite
/// `Kd, Ks ≥ 0` with `Kd + Ks ≤ 1` per channel and `ns ∈ [NS_MIN, NS_MAX]`.
pub fn principled_to_blinn_phong_analytic(p: &Principled) -> BlinnPhong {
    let m = or_default(p.metallic, 0.0).clamp(0.0, 1.0);
    let f0 = dielectric_f0(p.ior, p.specular_ior_level);
    let mut kd = [0.0f32; 3];
    let mut ks = [0.0f32; 3];
    for c in 0..3 {
        let base = or_default(p.base_color[c], 0.8).clamp(0.0, 1.0);
        let s = ((1.0 - m) * f0 + m * base).clamp(0.0, 1.0);
        let d = ((1.0 - m) * base * (1.0 - f0)).clamp(0.0, 1.0 - s);
        ks[c] = s;
        kd[c] = d;
    }
    BlinnPhong {
        kd,
        ks,
        ns: roughness_to_ns(p.roughness),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(base: f32, metallic: f32, roughness: f32, ior: f32, level: f32) -> Principled {
        Principled {
            base_color: [base; 3],
            metallic,
            roughness,
            ior,
            specular_ior_level: level,
        }
    }

    fn check(b: &BlinnPhong) {
        for c in 0..3 {
            assert!(b.kd[c].is_finite() && b.ks[c].is_finite(), "{b:?}");
            assert!(b.kd[c] >= 0.0 && b.ks[c] >= 0.0, "{b:?}");
            assert!(b.kd[c] + b.ks[c] <= 1.0 + 1e-6, "{b:?}");
        }
        assert!(
            b.ns.is_finite() && b.ns >= NS_MIN && b.ns <= NS_MAX,
            "{b:?}"
        );
        b.validate("mapped").unwrap();
    }

    #[test]
    fn roughness_edges() {
        // r = 0 must not give Inf: clamped at NS_MAX.
        assert_eq!(roughness_to_ns(0.0), NS_MAX);
        // r = 1: α = 1, ns = 0 → NS_MIN.
        assert_eq!(roughness_to_ns(1.0), NS_MIN);
        // The docs/design.md landmarks: ns = 200 at r ≈ 0.32, r = 0.1 → ns ≈ 20,000.
        let ns = roughness_to_ns(0.3155);
        assert!((ns - 200.0).abs() < 5.0, "{ns}");
        let ns = roughness_to_ns(0.1);
        assert!((ns - 19998.0).abs() < 2.0, "{ns}");
        // Monotone decreasing.
        let mut last = f32::INFINITY;
        for i in 0..=100 {
            let ns = roughness_to_ns(i as f32 / 100.0);
            assert!(ns <= last, "not monotone at r = {}", i as f32 / 100.0);
            last = ns;
        }
        assert_eq!(roughness_to_ns(f32::NAN), roughness_to_ns(0.5));
        assert_eq!(roughness_to_ns(-3.0), NS_MAX);
        assert_eq!(roughness_to_ns(7.0), NS_MIN);
    }

    #[test]
    fn f0_from_ior_and_level() {
        assert!((dielectric_f0(1.5, 0.5) - 0.04).abs() < 1e-6);
        assert_eq!(dielectric_f0(1.0, 0.5), 0.0); // IOR 1: no reflection
        assert_eq!(dielectric_f0(1.5, 0.0), 0.0); // level 0 removes it
        assert!((dielectric_f0(1.5, 1.0) - 0.08).abs() < 1e-6); // level 1 doubles it
        assert!((dielectric_f0(1.0 / 1.5, 0.5) - 0.04).abs() < 1e-6); // η and 1/η agree
        let huge = dielectric_f0(1e30, 0.5);
        assert!(huge > 0.99 && huge <= 1.0, "{huge}");
        assert_eq!(dielectric_f0(f32::INFINITY, 0.5), 1.0);
        assert_eq!(dielectric_f0(f32::INFINITY, 1.0), 1.0); // 2·1 clamped to 1
        assert_eq!(dielectric_f0(f32::NAN, f32::NAN), dielectric_f0(1.5, 0.5));
        assert_eq!(dielectric_f0(0.0, 0.5), dielectric_f0(1.5, 0.5));
    }

    #[test]
    fn metallic_and_base_colour_edges() {
        // Dielectric white: Ks = F0, Kd = 1 − F0 (sum exactly 1).
        let b = principled_to_blinn_phong_analytic(&p(1.0, 0.0, 0.5, 1.5, 0.5));
        check(&b);
        assert!(
            (b.ks[0] - 0.04).abs() < 1e-6 && (b.kd[0] - 0.96).abs() < 1e-6,
            "{b:?}"
        );
        // Metal: no diffuse, Ks = base.
        let b = principled_to_blinn_phong_analytic(&p(0.7, 1.0, 0.2, 1.5, 0.5));
        check(&b);
        assert_eq!(b.kd, [0.0; 3]);
        assert!((b.ks[1] - 0.7).abs() < 1e-6);
        // Metal with black base colour: black, finite.
        let b = principled_to_blinn_phong_analytic(&p(0.0, 1.0, 0.0, 1.5, 0.5));
        check(&b);
        assert_eq!((b.kd, b.ks), ([0.0; 3], [0.0; 3]));
        // Black dielectric: only the F0 reflection.
        let b = principled_to_blinn_phong_analytic(&p(0.0, 0.0, 0.5, 1.5, 0.5));
        check(&b);
        assert_eq!(b.kd, [0.0; 3]);
        // IOR 1: no specular at all, Kd = base.
        let b = principled_to_blinn_phong_analytic(&p(0.6, 0.0, 0.5, 1.0, 0.5));
        check(&b);
        assert_eq!(b.ks, [0.0; 3]);
        assert!((b.kd[2] - 0.6).abs() < 1e-6);
        // Huge IOR with level 1: F0 clamped to 1, a perfect (white) specular, no diffuse.
        let b = principled_to_blinn_phong_analytic(&p(0.6, 0.0, 0.5, 1e30, 1.0));
        check(&b);
        assert!((b.ks[0] - 1.0).abs() < 1e-6 && b.kd[0] < 1e-6, "{b:?}");
        // Base colour > 1 is clamped to 1.
        let b = principled_to_blinn_phong_analytic(&p(5.0, 0.3, 0.5, 1.5, 0.5));
        check(&b);
        assert_eq!(
            b,
            principled_to_blinn_phong_analytic(&p(1.0, 0.3, 0.5, 1.5, 0.5))
        );
    }

    #[test]
    fn nan_and_infinite_inputs_are_total() {
        let nan = f32::NAN;
        let b = principled_to_blinn_phong_analytic(&p(nan, nan, nan, nan, nan));
        check(&b);
        assert_eq!(
            b,
            principled_to_blinn_phong_analytic(&p(0.8, 0.0, 0.5, 1.5, 0.5))
        );
        let inf = f32::INFINITY;
        for x in [inf, -inf] {
            check(&principled_to_blinn_phong_analytic(&p(x, x, x, x, x)));
        }
    }

    #[test]
    fn kd_plus_ks_at_most_one_over_a_grid_of_inputs() {
        let vals = [-0.5f32, 0.0, 0.01, 0.25, 0.5, 0.8, 1.0, 1.5];
        let iors = [0.5f32, 1.0, 1.33, 1.5, 2.417, 10.0, 1e6];
        let mut n = 0;
        for &base in &vals {
            for &m in &vals {
                for &r in &vals {
                    for &ior in &iors {
                        for &level in &vals {
                            let q = Principled {
                                base_color: [base, 1.0 - base, 0.5],
                                metallic: m,
                                roughness: r,
                                ior,
                                specular_ior_level: level,
                            };
                            check(&principled_to_blinn_phong_analytic(&q));
                            n += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(n, 8 * 8 * 8 * 7 * 8);
    }

    #[test]
    fn validate_rejects_out_of_range() {
        assert!(p(0.5, 0.0, 0.5, 1.5, 0.5).validate("mat").is_ok());
        assert!(p(3.0, 0.0, 0.5, 1.5, 0.5).validate("mat").is_ok()); // > 1 allowed
        let e = p(0.5, 1.5, 0.5, 1.5, 0.5)
            .validate("mat")
            .unwrap_err()
            .to_string();
        assert!(e.contains("mat.metallic"), "{e}");
        let e = p(0.5, 0.0, f32::NAN, 1.5, 0.5)
            .validate("mat")
            .unwrap_err()
            .to_string();
        assert!(e.contains("mat.roughness"), "{e}");
        let e = p(-0.1, 0.0, 0.5, 1.5, 0.5)
            .validate("mat")
            .unwrap_err()
            .to_string();
        assert!(e.contains("mat.base_color"), "{e}");
        let e = p(0.5, 0.0, 0.5, 0.0, 0.5)
            .validate("mat")
            .unwrap_err()
            .to_string();
        assert!(e.contains("mat.ior"), "{e}");
        let e = p(0.5, 0.0, 0.5, 1.5, -1.0)
            .validate("mat")
            .unwrap_err()
            .to_string();
        assert!(e.contains("mat.specular_ior_level"), "{e}");
    }
}
