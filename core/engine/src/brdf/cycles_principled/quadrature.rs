//! A quadrature over incident directions for a fixed outgoing direction, parametrised by the
//! half vector so that narrow lobes (GGX at roughness 0.05, Blinn–Phong at ns ≈ 3·10⁵) are
//! resolved: θh runs over two uniform pieces, a fine one across the lobe (a few lobe widths)
//! and a coarse one for the tails and the rest of the hemisphere. Shared by the directional
//! albedos of the Cycles model and by the Blinn–Phong fit.

use std::f64::consts::{FRAC_PI_2, PI};

/// One node: the incident direction as the cosines the BRDFs need, and its weight `dω_i`
/// (the Jacobian `4 (ωo·h)` of the half-vector parametrisation included; no cos θi).
#[derive(Clone, Copy, Debug)]
pub struct Node {
    pub cos_i: f64,
    pub cos_h: f64,
    /// `ωo·h = ωi·h`.
    pub cos_d: f64,
    pub d_omega_i: f64,
}

/// Node counts of [`incident_nodes`].
#[derive(Clone, Copy, Debug)]
pub struct Resolution {
    pub fine: usize,
    pub coarse: usize,
    pub phi: usize,
}

impl Resolution {
    /// Accurate to about 1e-3 of a directional albedo for lobe widths down to α = 0.0025.
    pub const FINE: Resolution = Resolution {
        fine: 160,
        coarse: 96,
        phi: 48,
    };
}

/// Calls `f` for every incident node above the surface at outgoing `cos θo`, for a lobe of
/// angular width about `width` radians around the half vector `h = n`.
pub fn incident_nodes(cos_o: f64, width: f64, res: Resolution, mut f: impl FnMut(Node)) {
    let co = cos_o.clamp(1e-6, 1.0);
    let so = (1.0 - co * co).max(0.0).sqrt();
    let split = (12.0 * width.max(1e-4)).min(FRAC_PI_2 * 0.5);
    let dphi = PI / res.phi as f64;
    let pieces = [(0.0, split, res.fine), (split, FRAC_PI_2, res.coarse)];
    for (lo, hi, n) in pieces {
        let dth = (hi - lo) / n as f64;
        for a in 0..n {
            let th = lo + (a as f64 + 0.5) * dth;
            let (sth, cth) = th.sin_cos();
            for b in 0..res.phi {
                let phi = (b as f64 + 0.5) * dphi;
                let cos_d = so * sth * phi.cos() + co * cth;
                if cos_d <= 0.0 {
                    continue;
                }
                let cos_i = 2.0 * cos_d * cth - co;
                if cos_i <= 0.0 {
                    continue;
                }
                // φ over [0, π] stands for [0, 2π] (symmetry about the plane of ωo).
                let d_omega_h = sth * dth * 2.0 * dphi;
                f(Node {
                    cos_i,
                    cos_h: cth,
                    cos_d,
                    d_omega_i: 4.0 * cos_d * d_omega_h,
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_integral_over_the_hemisphere_is_pi() {
        for co in [1.0f64, 0.7, 0.2, 0.02] {
            for width in [0.0025f64, 0.1, 1.0] {
                let mut acc = 0.0;
                incident_nodes(co, width, Resolution::FINE, |n| {
                    acc += n.cos_i * n.d_omega_i
                });
                assert!(
                    (acc - PI).abs() < 2e-3 * PI,
                    "cos θo {co}, width {width}: {acc}"
                );
            }
        }
    }
}
