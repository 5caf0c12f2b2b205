//! The pieces of Cycles' GGX microfacet reflection (Blender 4.x/5.x `bsdf_microfacet.h`,
//! `bsdf_util.h`), written from the published formulas: the GGX normal distribution, the
//! height-correlated Smith masking-shadowing term, the exact dielectric Fresnel and the
//! Schlick / F82-tint metallic Fresnel, and Cycles' closed forms for the hemispherical
//! average of each Fresnel (used by its multiple-scattering compensation).

use std::f64::consts::PI;

/// GGX (Trowbridge–Reitz) distribution of microfacet normals, `α²/(π(1 + (α² − 1)cos²θh)²)`.
pub fn ggx_d(alpha: f64, cos_h: f64) -> f64 {
    if !(cos_h > 0.0) {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = 1.0 + (a2 - 1.0) * cos_h * cos_h;
    a2 / (PI * t * t)
}

/// Smith's Λ for GGX: `(√(1 + α² tan²θ) − 1)/2`.
pub fn ggx_lambda(alpha: f64, cos_theta: f64) -> f64 {
    let c2 = (cos_theta * cos_theta).max(1e-300);
    let tan2 = (1.0 / c2 - 1.0).max(0.0);
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Height-correlated masking-shadowing `1/(1 + Λ(θi) + Λ(θo))` (Cycles' `bsdf_G`).
pub fn ggx_g(alpha: f64, cos_i: f64, cos_o: f64) -> f64 {
    1.0 / (1.0 + ggx_lambda(alpha, cos_i) + ggx_lambda(alpha, cos_o))
}

/// The single-scattering GGX reflection with Fresnel 1: `D·G/(4 cos θi cos θo)`; 0 below the
/// surface.
pub fn ggx_single(alpha: f64, cos_i: f64, cos_o: f64, cos_h: f64) -> f64 {
    if !(cos_i > 0.0) || !(cos_o > 0.0) {
        return 0.0;
    }
    ggx_d(alpha, cos_h) * ggx_g(alpha, cos_i, cos_o) / (4.0 * cos_i * cos_o)
}

/// Unpolarised Fresnel reflectance of a dielectric interface of relative index `eta ≥ 1` at
/// `cos θ` (light arriving from the outside), 1 under total internal reflection.
pub fn fresnel_dielectric(cos: f64, eta: f64) -> f64 {
    let c = cos.abs();
    let g2 = eta * eta - 1.0 + c * c;
    if g2 <= 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

/// `((η − 1)/(η + 1))²`.
pub fn f0_from_ior(eta: f64) -> f64 {
    let r = (eta - 1.0) / (eta + 1.0);
    r * r
}

/// The IOR with a given normal-incidence reflectance, F0 limited to 0.99 as Cycles does.
pub fn ior_from_f0(f0: f64) -> f64 {
    let s = f0.clamp(0.0, 0.99).sqrt();
    (1.0 + s) / (1.0 - s)
}

/// Cycles' fitted hemispherical average of the dielectric Fresnel for `eta ≥ 1`
/// (`fresnel_dielectric_Fss`): an approximation Cycles itself uses, so it is kept as is.
pub fn fresnel_dielectric_average(eta: f64) -> f64 {
    if eta < 1.0 {
        return 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607));
    }
    (eta - 1.0) / (4.08567 + 1.00071 * eta)
}

/// Schlick's Fresnel `F0 + (1 − F0)(1 − cos)⁵`: the F82-tint model with a white tint, which
/// is what the Principled BSDF's metallic layer uses at its default Specular Tint.
pub fn fresnel_schlick(cos: f64, f0: f64) -> f64 {
    let s = (1.0 - cos).clamp(0.0, 1.0);
    let s2 = s * s;
    f0 + (1.0 - f0) * s2 * s2 * s
}

/// Hemispherical (cosine-weighted) average of [`fresnel_schlick`]: `F0 + (1 − F0)/21`.
pub fn fresnel_schlick_average(f0: f64) -> f64 {
    f0 + (1.0 - f0) / 21.0
}

/// Multiple-scattering Fresnel factor of Kulla & Conty as Cycles uses it:
/// `Fms = Fss·Eavg/(1 − Fss(1 − Eavg))`.
pub fn multiscatter_fresnel(f_avg: f64, e_avg: f64) -> f64 {
    f_avg * e_avg / (1.0 - f_avg * (1.0 - e_avg))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ggx_distribution_is_normalised() {
        // ∫ D cos θh dω_h = 1 for every α.
        for alpha in [0.05f64, 0.2, 0.5, 1.0] {
            let n = 20000;
            let mut acc = 0.0;
            for k in 0..n {
                // θ = atan(α·tan(πu/2)) spreads nodes where the lobe lives.
                let u = (k as f64 + 0.5) / n as f64;
                let t = (std::f64::consts::FRAC_PI_2 * u).tan();
                let th = (alpha * t).atan();
                let dth_du = alpha * std::f64::consts::FRAC_PI_2 * (1.0 + t * t)
                    / (1.0 + alpha * alpha * t * t);
                acc += ggx_d(alpha, th.cos()) * th.cos() * th.sin() * 2.0 * PI * dth_du / n as f64;
            }
            assert!((acc - 1.0).abs() < 2e-3, "α {alpha}: {acc}");
        }
    }

    #[test]
    fn fresnel_limits() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-12);
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-12);
        assert!((fresnel_dielectric(1.0, 1.0)).abs() < 1e-12);
        assert!((ior_from_f0(f0_from_ior(1.5)) - 1.5).abs() < 1e-9);
        assert_eq!(fresnel_schlick(1.0, 0.3), 0.3);
        assert_eq!(fresnel_schlick(0.0, 0.3), 1.0);
        // The hemispherical average of the exact dielectric Fresnel against Cycles' fit.
        for eta in [1.2f64, 1.5, 2.0, 3.0] {
            let n = 20000;
            let exact: f64 = (0..n)
                .map(|k| {
                    let mu = (k as f64 + 0.5) / n as f64;
                    2.0 * mu * fresnel_dielectric(mu, eta) / n as f64
                })
                .sum();
            let fit = fresnel_dielectric_average(eta);
            assert!((exact - fit).abs() < 0.01, "η {eta}: {exact} vs {fit}");
        }
        let n = 20000;
        let schlick: f64 = (0..n)
            .map(|k| {
                let mu = (k as f64 + 0.5) / n as f64;
                2.0 * mu * fresnel_schlick(mu, 0.5) / n as f64
            })
            .sum();
        assert!((schlick - fresnel_schlick_average(0.5)).abs() < 1e-6);
    }
}
