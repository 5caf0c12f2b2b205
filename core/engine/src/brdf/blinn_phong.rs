//! Blinn–Phong, eq. (15) of the paper, with the lobe normalisation Relume uses.
//!
//! # Normalisation
//!
//! The paper writes the BRDF as `ρ = Kd/π + Ks·(ns+2)/(2π)·cos^ns δ` (eq. 15), δ the angle
//! between the normal and the half vector. `(ns+2)/(2π)·cos^ns δ` is the *normalised
//! half-vector distribution* (∫ D cos δ dω_h = 1), not a normalised BRDF: used as a BRDF its
//! directional albedo tends to **4** at normal incidence for large `ns`
//! (`tests::paper_normalisation_is_not_energy_conserving`), so
//! `Kd + Ks ≤ 1` (eq. 16) would not keep a surface from reflecting more than it receives.
//!
//! Relume uses the same shape with the microfacet factor 1/4 (the Jacobian
//! `dω_h/dω_i = 1/(4 cos θ_d)` without the `cos θ_i cos θ_o` denominator):
//!
//! `f_s(δ) = (ns+2)/(8π)·cos^ns δ`   ([`lobe`])
//!
//! Its directional albedo is `≈ ns/(ns+4)` at normal incidence for large ns and falls towards
//! grazing; it is ≤ 1 for every ns and angle (tested over ns ∈ [1, 10⁴] and θo up to
//! 89.9°), so with `Kd + Ks ≤ 1` per channel the BRDF conserves energy. The PCA of
//! [`super::basis`] and its relative errors are invariant under a constant scale of the
//! lobes, so this choice changes nothing about the basis errors the paper reports; it only
//! rescales the coefficients by 1/4.

#![allow(clippy::neg_cmp_op_on_partial_ord)] // `!(x > 0.0)` deliberately rejects NaN too.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::{RelumeError, Result};

/// Blinn–Phong parameters: `Kd`, `Ks` RGB albedos, `ns` the exponent.
///
/// `Kd, Ks ≥ 0` and `Kd + Ks ≤ 1` per channel keep the surface energy conserving (see the
/// module docs); `ns > 0`: `ns = 1` is a very broad lobe, `ns = 200` the paper's sharpest
/// (≈ Principled roughness 0.32), `ns = 10⁴` a 0.67° half-width lobe (roughness ≈ 0.12).
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct BlinnPhong {
    pub kd: [f32; 3],
    pub ks: [f32; 3],
    pub ns: f32,
}

/// The specular lobe with `Ks = 1`: `(ns+2)/(8π)·cos^ns δ`, as a function of `cos δ`.
///
/// Computed as `exp(ns·ln cos δ)` so that `ns` from 0 to 10⁶ and more neither underflows to a
/// NaN (`0^0`, `pow` of denormals) nor overflows: the result is finite and ≥ 0 for every
/// finite `ns ≥ 0`. `cos δ ≤ 0` (half vector below the surface) and NaN give 0; values above
/// 1 (rounding of a normalised half vector) are treated as 1.
pub fn lobe(ns: f64, cos_delta: f64) -> f64 {
    if !(cos_delta > 0.0) || !(ns >= 0.0) || !ns.is_finite() {
        return 0.0;
    }
    let c = cos_delta.min(1.0);
    let norm = (ns + 2.0) / (8.0 * std::f64::consts::PI);
    norm * (ns * c.ln()).exp()
}

impl BlinnPhong {
    /// The BRDF value `Kd/π + Ks·f_s(δ)` (no cosine factor) for unit vectors `n`, `wi`, `wo`
    /// (both directions pointing away from the surface).
    ///
    /// Zero when `wi` or `wo` is at or below the surface. The half vector is normalised only
    /// when `|wi + wo|² > 1e-12`; otherwise (`wi ≈ −wo`, which can only happen at grazing
    /// angles) the specular term is undefined and only the diffuse term is returned.
    /// Symmetric in `wi`, `wo` (reciprocity), since the half vector is.
    pub fn eval(&self, n: Vec3, wi: Vec3, wo: Vec3) -> Vec3 {
        let cos_i = n.dot(wi);
        let cos_o = n.dot(wo);
        if !(cos_i > 0.0) || !(cos_o > 0.0) {
            return Vec3::ZERO;
        }
        let kd = Vec3::from(self.kd);
        let ks = Vec3::from(self.ks);
        let diffuse = kd * std::f32::consts::FRAC_1_PI;
        let h = wi + wo;
        let len2 = h.length_squared();
        if !(len2 > 1e-12) {
            return diffuse;
        }
        let cos_delta = n.dot(h) / len2.sqrt();
        diffuse + ks * lobe(self.ns as f64, cos_delta as f64) as f32
    }

    /// Checks that every value is finite, `Kd, Ks ≥ 0` and `ns > 0`; the error names the field
    /// (`"{what}.kd"` …). `Kd + Ks ≤ 1` is *not* enforced: it is a physical constraint a user
    /// may deliberately break (the relight stays linear), and the Principled mapping already
    /// guarantees it.
    pub fn validate(&self, what: &str) -> Result<()> {
        for (name, v) in [("kd", self.kd), ("ks", self.ks)] {
            for (c, x) in v.iter().enumerate() {
                if !x.is_finite() {
                    return Err(RelumeError::invalid(
                        format!("{what}.{name}"),
                        format!("channel {c} is not finite ({x})"),
                    ));
                }
                if *x < 0.0 {
                    return Err(RelumeError::invalid(
                        format!("{what}.{name}"),
                        format!("channel {c} is negative ({x}); albedos must be ≥ 0"),
                    ));
                }
            }
        }
        if !self.ns.is_finite() || !(self.ns > 0.0) {
            return Err(RelumeError::invalid(
                format!("{what}.ns"),
                format!(
                    "the Blinn–Phong exponent must be finite and > 0, got {}",
                    self.ns
                ),
            ));
        }
        Ok(())
    }

    /// Directional albedo `∫ f(wi, wo) cos θ_i dω_i` per RGB channel for an outgoing direction
    /// at `cos θ_o`, by an `n × n` midpoint quadrature over the half vector (used by the
    /// energy tests; `n = 400` gives about 1e-4 absolute accuracy for ns up to 10⁴).
    ///
    /// Integrating over the half vector `h` (`dω_i = 4 (wo·h) dω_h`) with
    /// `θ_h = (π/2)·u²` concentrates nodes where the lobe lives, so a 0.67° lobe (ns = 10⁴)
    /// still gets ~50 nodes across its width.
    pub fn directional_albedo(&self, cos_theta_o: f64, n: usize) -> [f64; 3] {
        let (d, s) = albedo_parts(self.ns as f64, cos_theta_o, n, lobe);
        std::array::from_fn(|c| self.kd[c] as f64 * d + self.ks[c] as f64 * s)
    }
}

/// (diffuse albedo of `1/π`, albedo of `spec(ns, cos δ)`) at `cos θ_o` by the half-vector
/// quadrature of [`BlinnPhong::directional_albedo`].
pub(crate) fn albedo_parts(
    ns: f64,
    cos_theta_o: f64,
    n: usize,
    spec: impl Fn(f64, f64) -> f64,
) -> (f64, f64) {
    use std::f64::consts::{FRAC_PI_2, PI};
    let n = n.max(8);
    let co = cos_theta_o.clamp(0.0, 1.0);
    let so = (1.0 - co * co).max(0.0).sqrt();
    // wo = (so, 0, co); h = (sin θh cos φ, sin θh sin φ, cos θh), φ ∈ [0, π] doubled.
    let du = 1.0 / n as f64;
    let dphi = PI / n as f64;
    let (mut acc_d, mut acc_s) = (0.0, 0.0);
    for a in 0..n {
        let u = (a as f64 + 0.5) * du;
        let th = FRAC_PI_2 * u * u;
        let jac = PI * u * du; // dθh/du·du
        let (sth, cth) = th.sin_cos();
        let f_s = spec(ns, cth);
        let mut row_d = 0.0;
        let mut row_s = 0.0;
        for b in 0..n {
            let phi = (b as f64 + 0.5) * dphi;
            let wo_h = so * sth * phi.cos() + co * cth;
            if wo_h <= 0.0 {
                continue;
            }
            let cos_i = 2.0 * wo_h * cth - co;
            if cos_i <= 0.0 {
                continue;
            }
            let w = cos_i * 4.0 * wo_h;
            row_d += w;
            row_s += w * f_s;
        }
        let wgt = 2.0 * dphi * jac * sth;
        acc_d += row_d * wgt / PI;
        acc_s += row_s * wgt;
    }
    (acc_d, acc_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(theta: f32, phi: f32) -> Vec3 {
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    #[test]
    fn lobe_is_finite_and_non_negative_everywhere() {
        for ns in [0.0, 1e-3, 1.0, 200.0, 1e4, 1e5, 1e6, 1e9] {
            for c in [
                -1.0,
                -1e-9,
                0.0,
                1e-300,
                1e-6,
                0.5,
                0.999_999,
                1.0,
                1.0 + 1e-7,
            ] {
                let v = lobe(ns, c);
                assert!(v.is_finite() && v >= 0.0, "lobe({ns}, {c}) = {v}");
                if c <= 0.0 {
                    assert_eq!(v, 0.0);
                }
            }
            // The peak is the normalisation.
            let peak = (ns + 2.0) / (8.0 * std::f64::consts::PI);
            assert!((lobe(ns, 1.0) - peak).abs() <= 1e-12 * peak);
        }
        assert_eq!(lobe(f64::NAN, 0.5), 0.0);
        assert_eq!(lobe(1.0, f64::NAN), 0.0);
    }

    #[test]
    fn eval_is_reciprocal() {
        let m = BlinnPhong {
            kd: [0.3, 0.2, 0.1],
            ks: [0.5, 0.6, 0.7],
            ns: 37.0,
        };
        let n = Vec3::Z;
        for (ti, pi, to, po) in [
            (0.1f32, 0.0f32, 0.7f32, 3.0f32),
            (1.2, 1.0, 0.3, -2.0),
            (1.55, 0.2, 1.5, 3.3),
            (0.0, 0.0, 0.9, 1.0),
        ] {
            let wi = dir(ti, pi);
            let wo = dir(to, po);
            let a = m.eval(n, wi, wo);
            let b = m.eval(n, wo, wi);
            assert!(
                (a - b).abs().max_element() <= 1e-6 * a.max_element().max(1.0),
                "{a} {b}"
            );
        }
    }

    #[test]
    fn eval_is_finite_at_extreme_exponents_and_grazing_angles() {
        let n = Vec3::Z;
        for ns in [1e-3f32, 1.0, 200.0, 1e4, 1e5] {
            let m = BlinnPhong {
                kd: [0.5; 3],
                ks: [0.5; 3],
                ns,
            };
            let g = std::f32::consts::FRAC_PI_2;
            for t in [0.0f32, 0.5, 1.5, g - 1e-4, g - 1e-6] {
                for to in [0.0f32, 1.0, g - 1e-4] {
                    let v = m.eval(n, dir(t, 0.0), dir(to, std::f32::consts::PI));
                    assert!(
                        v.is_finite() && v.min_element() >= 0.0,
                        "ns {ns} θ {t} {to}: {v}"
                    );
                }
            }
            // Mirror configuration: the peak, finite even for ns = 1e5.
            let v = m.eval(n, dir(0.3, 0.0), dir(0.3, std::f32::consts::PI));
            assert!(v.is_finite() && v.x > 0.5 / std::f32::consts::PI);
        }
        // Below the surface and exactly opposite directions.
        let m = BlinnPhong {
            kd: [0.5; 3],
            ks: [0.5; 3],
            ns: 10.0,
        };
        assert_eq!(m.eval(n, dir(2.0, 0.0), Vec3::Z), Vec3::ZERO);
        assert_eq!(m.eval(n, Vec3::Z, dir(1.6, 0.0)), Vec3::ZERO);
        let g = Vec3::new(1.0, 0.0, 1e-7).normalize();
        let opp = Vec3::new(-1.0, 0.0, 1e-7).normalize();
        let v = m.eval(n, g, opp);
        assert!(v.is_finite());
    }

    #[test]
    fn white_furnace_diffuse_albedo_is_one() {
        let m = BlinnPhong {
            kd: [1.0; 3],
            ks: [0.0; 3],
            ns: 10.0,
        };
        for deg in [0.0f64, 30.0, 60.0, 85.0, 89.9] {
            let a = m.directional_albedo(deg.to_radians().cos(), 400);
            for c in a {
                assert!((c - 1.0).abs() < 1e-3, "θo {deg}°: albedo {c}");
            }
        }
    }

    #[test]
    fn energy_is_conserved_with_kd_plus_ks_one() {
        // Kd + Ks = 1 in every channel, from all-diffuse-ish to all-specular.
        let m0 = BlinnPhong {
            kd: [0.0, 0.5, 0.9],
            ks: [1.0, 0.5, 0.1],
            ns: 1.0,
        };
        let mut worst: f64 = 0.0;
        for ns in [1.0f32, 2.0, 5.0, 20.0, 200.0, 2000.0, 10000.0] {
            let m = BlinnPhong { ns, ..m0 };
            for deg in [0.0f64, 30.0, 60.0, 85.0, 89.9] {
                let a = m.directional_albedo(deg.to_radians().cos(), 400);
                for c in a {
                    assert!(
                        c.is_finite() && c <= 1.0 + 2e-3,
                        "ns {ns} θo {deg}°: albedo {c}"
                    );
                    worst = worst.max(c);
                }
            }
        }
        assert!(
            worst > 0.5,
            "the test must exercise albedos near 1, got {worst}"
        );
    }

    #[test]
    fn paper_normalisation_is_not_energy_conserving() {
        // Eq. (15) as printed: (ns+2)/(2π)·cos^ns δ, i.e. 4× Relume's lobe.
        let paper = |ns: f64, c: f64| {
            if c <= 0.0 {
                0.0
            } else {
                (ns + 2.0) / (2.0 * std::f64::consts::PI) * (ns * c.ln()).exp()
            }
        };
        let (_, a_paper) = albedo_parts(100.0, 1.0, 400, paper);
        let (_, a_relume) = albedo_parts(100.0, 1.0, 400, lobe);
        eprintln!("albedo at ns = 100, θo = 0: paper eq. (15) {a_paper:.4}, Relume {a_relume:.4}");
        // Analytic at θo = 0 (for large ns): ns/(ns+4) for Relume, 4× that for the paper.
        assert!(
            a_paper > 3.8 && a_paper < 3.9,
            "paper albedo at ns=100: {a_paper}"
        );
        assert!(
            a_relume <= 1.0 && (a_relume - 100.0 / 104.0).abs() < 2e-3,
            "{a_relume}"
        );
    }

    #[test]
    fn validate_names_the_field() {
        let ok = BlinnPhong {
            kd: [0.2; 3],
            ks: [0.3; 3],
            ns: 10.0,
        };
        assert!(ok.validate("m").is_ok());
        let e = BlinnPhong { ns: 0.0, ..ok }
            .validate("m")
            .unwrap_err()
            .to_string();
        assert!(e.contains("m.ns"), "{e}");
        let e = BlinnPhong {
            kd: [0.2, -0.1, 0.0],
            ..ok
        }
        .validate("m")
        .unwrap_err()
        .to_string();
        assert!(e.contains("m.kd") && e.contains("negative"), "{e}");
        let e = BlinnPhong {
            ks: [f32::NAN, 0.0, 0.0],
            ..ok
        }
        .validate("m")
        .unwrap_err()
        .to_string();
        assert!(e.contains("m.ks"), "{e}");
        assert!(BlinnPhong {
            ns: f32::INFINITY,
            ..ok
        }
        .validate("m")
        .is_err());
    }
}
