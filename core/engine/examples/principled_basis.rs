//! Builds the Principled basis (`relume_engine::brdf::principled_basis`) and prints its
//! figures as JSON: build time, the training lobes' errors, the tables' error, and the
//! relative L2 error of lobes rebuilt from their coefficients with the exact bases and with
//! the tables, for metals and dielectrics across roughness (between the training nodes).
//!
//! With `--reflectance` it also integrates smooth metals rebuilt from the basis against the
//! exact lobe, over the hemisphere and over cones around the mirror direction (slow: a
//! fine quadrature per view angle).
//!
//! `cargo run --release -p relume-engine --example principled_basis [-- --small] [-- --reflectance]`

use relume_engine::brdf::cycles_principled::CyclesPrincipled;
use relume_engine::brdf::principled_basis::{
    Cosines, Family, PrincipledBasis, PrincipledBasisConfig, QuadratureSize, TableSize,
};
use relume_engine::brdf::Principled;

fn main() {
    let small = std::env::args().any(|a| a == "--small");
    let config = if small {
        PrincipledBasisConfig {
            roughness_nodes: 24,
            quadrature: QuadratureSize {
                theta_h: 64,
                theta_d: 20,
                phi_d: 24,
            },
            table: TableSize {
                theta_h: 65,
                s: 33,
                eta: 33,
            },
            ..PrincipledBasisConfig::default()
        }
    } else {
        PrincipledBasisConfig::default()
    };
    let basis = match PrincipledBasis::build(&config) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("principled_basis: {e}");
            std::process::exit(1);
        }
    };
    let mut lobes = vec![];
    for family in [
        Family::Metal { f0: 1.0 },
        Family::Metal { f0: 0.5 },
        Family::Metal { f0: 0.1 },
        Family::Dielectric { ior: 1.5 },
        Family::Dielectric { ior: 1.4 },
    ] {
        for roughness in [0.1, 0.15, 0.25, 0.4, 0.6, 0.8, 1.0] {
            let lobe = PrincipledBasis::lobe(family, roughness);

            let errors = basis.rebuild_errors(&lobe);
            lobes.push(serde_json::json!({
                "family": format!("{family:?}"),
                "roughness": roughness,
                "projection_rel_l2": errors.projection,
                "with_tables_rel_l2": errors.with_tables,
                "tables_alone_rel_l2": errors.tables_alone,
            }));
        }
    }
    // What a relit edit costs: a material's coefficients (the metal from curves, the
    // dielectric specular and diffuse base projected), fastest of five.
    let timing = |p: Principled| {
        (0..5)
            .map(|_| {
                let t = std::time::Instant::now();
                std::hint::black_box(basis.material_coefficients(&p));
                t.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    };
    let material = |metallic: f32| Principled {
        base_color: [0.8, 0.5, 0.3],
        metallic,
        roughness: 0.35,
        ior: 1.5,
        specular_ior_level: 0.5,
    };
    let reflectance = std::env::args()
        .any(|a| a == "--reflectance")
        .then(|| rebuilt_metal_reflectance(&basis));
    let out = serde_json::json!({
        "rebuilt_metal_reflectance": reflectance,
        "coefficients_ms_metal": timing(material(1.0)),
        "coefficients_ms_dielectric": timing(material(0.0)),
        "config": basis.config(),
        "report": basis.report(),
        "lobes": lobes,
        "diffuse_under_dielectric": diffuse_weights(),
        "diffuse_weight_pca": diffuse_weight_pca(),
    });
    println!("{}", serde_json::to_string_pretty(&out).expect("JSON"));
}

/// Cycles weights a dielectric's diffuse base by `1 − albedo(μo)` of its specular layer, a
/// function of the view alone that a constant diffuse slot cannot follow. Per roughness and
/// IOR: the weight at normal and grazing view, the best constant under the cos measure
/// (for a function of μo alone that measure is `μo dμo`), and the relative L2 error of that
/// constant (what keeping `Kd/π` with the averaged weight would cost the diffuse part).
fn diffuse_weights() -> Vec<serde_json::Value> {
    const NODES: usize = 2000;
    let mut out = vec![];
    for ior in [1.33f32, 1.5, 1.8] {
        for roughness in [0.1f32, 0.3, 0.5, 0.8, 1.0] {
            let m = CyclesPrincipled::new(&Principled {
                base_color: [0.8; 3],
                metallic: 0.0,
                roughness,
                ior,
                specular_ior_level: 0.5,
            });
            let mus: Vec<f64> = (0..NODES)
                .map(|i| (i as f64 + 0.5) / NODES as f64)
                .collect();
            let g: Vec<f64> = mus.iter().map(|&mu| m.diffuse_weight(mu)).collect();
            let w_sum: f64 = mus.iter().sum();
            let c = mus.iter().zip(&g).map(|(mu, g)| mu * g).sum::<f64>() / w_sum;
            let err2: f64 = mus.iter().zip(&g).map(|(mu, g)| mu * (g - c).powi(2)).sum();
            let norm2: f64 = mus.iter().zip(&g).map(|(mu, g)| mu * g * g).sum();
            out.push(serde_json::json!({
                "ior": ior,
                "roughness": roughness,
                "weight_at_normal_view": m.diffuse_weight(1.0),
                "weight_at_grazing_view_0_05": m.diffuse_weight(0.05),
                "best_constant": c,
                "constant_rel_l2": (err2 / norm2).sqrt(),
            }));
        }
    }
    out
}

/// How many functions of μo the diffuse weights `1 − albedo(μo)` of every dielectric of the
/// range need: a PCA (the constant in the fit, as the bases') of the weights at roughness
/// 0.1–1 (24 values uniform in ln r) and IOR 1.1–2.5 (8 values), under `μo dμo`; per count
/// of extra functions, the mean and worst relative L2 of the weights.
fn diffuse_weight_pca() -> Vec<serde_json::Value> {
    use relume_engine::linalg::top_eigenpairs;
    const NODES: usize = 400;
    let mus: Vec<f64> = (0..NODES)
        .map(|i| (i as f64 + 0.5) / NODES as f64)
        .collect();
    let w_sum: f64 = mus.iter().sum();
    let mut fns: Vec<Vec<f64>> = vec![];
    for a in 0..24 {
        let roughness = (0.1f64.ln() * (1.0 - a as f64 / 23.0)).exp() as f32;
        for b in 0..8 {
            let ior = (1.1 + 1.4 * b as f64 / 7.0) as f32;
            let m = CyclesPrincipled::new(&Principled {
                base_color: [0.8; 3],
                metallic: 0.0,
                roughness,
                ior,
                specular_ior_level: 0.5,
            });
            fns.push(mus.iter().map(|&mu| m.diffuse_weight(mu)).collect());
        }
    }
    let l = fns.len();
    let dot = |f: &[f64], g: &[f64]| -> f64 {
        mus.iter()
            .zip(f.iter().zip(g))
            .map(|(mu, (a, b))| mu * a * b)
            .sum::<f64>()
            / w_sum
    };
    // Residuals from the constant (unit norm under the normalised measure).
    let res: Vec<Vec<f64>> = fns
        .iter()
        .map(|f| {
            let m = dot(f, &vec![1.0; NODES]);
            f.iter().map(|v| v - m).collect()
        })
        .collect();
    let mut gram = vec![0.0; l * l];
    for i in 0..l {
        for j in 0..l {
            gram[i * l + j] = dot(&res[i], &res[j]);
        }
    }
    let (lam, v) = top_eigenpairs(&gram, l);
    let rank = lam.len();
    let mut out = vec![];
    for extra in 0..=3usize.min(rank) {
        // Error of function i: ‖r_i‖² − Σ_k (G v_k)_i² / λ_k.
        let errs: Vec<f64> = (0..l)
            .map(|i| {
                let mut e2 = gram[i * l + i];
                for k in 0..extra {
                    let p: f64 = (0..l).map(|j| gram[i * l + j] * v[j * rank + k]).sum();
                    e2 -= p * p / lam[k].max(1e-300);
                }
                (e2.max(0.0) / dot(&fns[i], &fns[i])).sqrt()
            })
            .collect();
        out.push(serde_json::json!({
            "extra_functions": extra,
            "mean_rel_l2": errs.iter().sum::<f64>() / l as f64,
            "worst_rel_l2": errs.iter().cloned().fold(0.0, f64::max),
        }));
    }
    out
}

/// The light a smooth metal (F0 0.9) rebuilt from its coefficients reflects, against the exact
/// lobe: `∫ f cos θi dωi` over the hemisphere and over cones of 2–20° around the mirror
/// direction (what a light of that size centred on the reflection sends back), per roughness
/// and view angle, through the tables and through the exact bases. The relative L2 error the
/// basis is fitted under is dominated by the lobe's peak; these integrals are what a highlight
/// shows.
fn rebuilt_metal_reflectance(basis: &PrincipledBasis) -> Vec<serde_json::Value> {
    use std::f64::consts::PI;
    const POLAR: usize = 4000;
    const AZIMUTH: usize = 720;
    const CONES_DEG: [f64; 4] = [2.0, 5.0, 10.0, 20.0];
    let n = basis.count();
    let mut out = vec![];
    for roughness in [0.1, 0.12, 0.15, 0.2, 0.3] {
        let lobe = PrincipledBasis::lobe(Family::Metal { f0: 0.9 }, roughness);
        let (coef, _) = basis.project(&lobe);
        let rebuilt = |c: Cosines, exact: bool, v: &mut [f64]| -> f64 {
            if exact {
                basis.eval_exact(c, v);
            } else {
                basis.eval(c, v);
            }
            v.iter().zip(&coef).map(|(a, b)| a * b).sum()
        };
        for view_deg in [0.0f64, 20.0, 45.0, 60.0, 75.0] {
            let view = view_deg.to_radians();
            let wo = [view.sin(), 0.0, view.cos()];
            let mirror = [-wo[0], 0.0, wo[2]];
            // A frame around the mirror direction: (0, 1, 0) and mirror × (0, 1, 0).
            let side = [-mirror[2], 0.0, mirror[0]];
            // [exact, tables, exact bases] over the hemisphere, then per cone.
            let mut sums = [[0.0f64; 3]; 1 + CONES_DEG.len()];
            let mut v = vec![0.0; n];
            for a in 0..POLAR {
                // Polar angle from the mirror direction, graded t = π u⁴ (dense at the peak).
                let u = (a as f64 + 0.5) / POLAR as f64;
                let t = PI * u.powi(4);
                let dt = 4.0 * PI * u.powi(3) / POLAR as f64;
                let (st, ct) = t.sin_cos();
                for b in 0..AZIMUTH {
                    let p = 2.0 * PI * (b as f64 + 0.5) / AZIMUTH as f64;
                    let (sp, cp) = p.sin_cos();
                    let wi = [
                        mirror[0] * ct + side[0] * cp * st,
                        sp * st,
                        mirror[2] * ct + side[2] * cp * st,
                    ];
                    if wi[2] <= 0.0 {
                        continue;
                    }
                    let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
                    let hl = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                    let c = Cosines {
                        cos_i: wi[2],
                        cos_o: wo[2],
                        cos_h: h[2] / hl,
                        cos_d: (h[0] * wi[0] + h[1] * wi[1] + h[2] * wi[2]) / hl,
                    };
                    let w = st * dt * (2.0 * PI / AZIMUTH as f64) * c.cos_i;
                    let f = [lobe(c), rebuilt(c, false, &mut v), rebuilt(c, true, &mut v)];
                    for (k, row) in sums.iter_mut().enumerate() {
                        if k == 0 || t < CONES_DEG[k - 1].to_radians() {
                            for (s, fv) in row.iter_mut().zip(f) {
                                *s += fv * w;
                            }
                        }
                    }
                }
            }
            let ratio = |row: &[f64; 3]| [row[1] / row[0], row[2] / row[0]];
            out.push(serde_json::json!({
                "roughness": roughness,
                "view_deg": view_deg,
                "hemisphere_exact": sums[0][0],
                "hemisphere_tables_over_exact": ratio(&sums[0])[0],
                "hemisphere_exact_bases_over_exact": ratio(&sums[0])[1],
                "cones_deg": CONES_DEG,
                "cones_tables_over_exact": sums[1..].iter().map(|r| ratio(r)[0]).collect::<Vec<_>>(),
            }));
        }
    }
    out
}
