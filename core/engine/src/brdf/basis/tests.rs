use super::*;
use crate::brdf::blinn_phong::lobe;

fn cfg_with(f: impl FnOnce(&mut BasisConfig)) -> BasisConfig {
    let mut c = BasisConfig::default();
    f(&mut c);
    c
}

/// Relative L2 (over a fine uniform sampling of the (θi, θo, φ) domain via δ) of the
/// tabulated reconstruction `Σ c̃_k ρ̃_k` of a lobe, with interpolated coefficients.
fn table_error(b: &BrdfBasis, ns: f32) -> f64 {
    let m = BlinnPhong {
        kd: [0.0; 3],
        ks: [1.0; 3],
        ns,
    };
    let (mut num, mut den) = (0.0, 0.0);
    let n = 40;
    for i in 0..n {
        for o in 0..n {
            for p in 0..2 * n {
                let ti = (i as f64 + 0.5) * FRAC_PI_2 / n as f64;
                let to = (o as f64 + 0.5) * FRAC_PI_2 / n as f64;
                let ph = (p as f64 + 0.5) * PI / (2 * n) as f64;
                let (si, ci) = ti.sin_cos();
                let (so, co) = to.sin_cos();
                let cd = (ci + co) / (2.0 * (1.0 + ci * co + si * so * ph.cos())).sqrt();
                let exact = lobe(ns as f64, cd);
                let approx = b.reconstruct(&m, cd as f32).x as f64;
                num += (exact - approx).powi(2);
                den += exact * exact;
            }
        }
    }
    (num / den).sqrt()
}

#[test]
fn default_config_errors() {
    let b = BrdfBasis::build(&BasisConfig::default()).unwrap();
    let r = b.error_report();
    eprintln!("default: {}", serde_json::to_string(&r).unwrap());
    assert_eq!(b.count(), 6);
    assert_eq!(r.bases, 6);
    assert_eq!(r.pca_measure, "grid");
    assert!(b.spec_constant());
    // Both of the paper's figures (0.7979 % average, 6.747 % maximum) are met, the maximum
    // with margin (< 3 %; the figures are in docs/measurements.md, "BRDF basis").
    assert!(r.avg_rel_l2 <= 0.007979, "{r:?}");
    assert!(r.max_rel_l2 <= 0.06747, "{r:?}");
    assert!(r.max_rel_l2 < 0.03, "{r:?}");
    // N_b = 2..=17: 200 lobes over [1, 200] have numerical rank 16 (eigenvalues below 1e-12
    // of the largest are not kept).
    assert!(
        r.per_count.len() >= 15 && r.per_count[0].bases == 2,
        "{:?}",
        r.per_count
    );
    // Errors fall with the count.
    for w in r.per_count.windows(2) {
        assert!(
            w[1].max_rel_l2 <= w[0].max_rel_l2 * 1.0001,
            "{:?}",
            r.per_count
        );
    }
    assert!(
        r.per_count.last().unwrap().max_rel_l2 < 1e-4,
        "{:?}",
        r.per_count
    );
}

#[test]
fn literal_pca_meets_the_paper_average() {
    let b = BrdfBasis::build(&cfg_with(|c| {
        c.weighting = LobeWeighting::Energy;
        c.constant_in_fit = false;
    }))
    .unwrap();
    let r = b.error_report();
    eprintln!(
        "literal (energy-weighted) PCA: avg {:.5} max {:.5} worst ns {}",
        r.avg_rel_l2, r.max_rel_l2, r.worst_ns
    );
    assert!(r.avg_rel_l2 <= 0.007979, "{r:?}");
    // …but not the maximum: the broadest lobe (ns = 1) is badly represented.
    assert!(r.max_rel_l2 > 0.1 && r.worst_ns == 1.0, "{r:?}");
}

#[test]
fn unit_weighting_without_the_constant() {
    let b = BrdfBasis::build(&cfg_with(|c| {
        c.weighting = LobeWeighting::Unit;
        c.constant_in_fit = false;
    }))
    .unwrap();
    let r = b.error_report();
    eprintln!(
        "unit-weighted PCA, no constant: avg {:.5} max {:.5} worst ns {}",
        r.avg_rel_l2, r.max_rel_l2, r.worst_ns
    );
    // 0.891 % / 6.77 %: the paper's maximum is just missed, and its average too.
    assert!(r.avg_rel_l2 > 0.007979 && r.max_rel_l2 > 0.06747, "{r:?}");
    assert!(r.max_rel_l2 < 0.07 && r.worst_ns == 1.0, "{r:?}");
}

#[test]
fn without_the_constant_no_cap_meets_both_paper_figures() {
    // Direction "another weighting, 5 specular bases": the capped weighting trades average
    // for maximum, and over caps 4–7 % the average stays above 0.7979 % (0.96, 0.89, 0.84,
    // 0.81 %) while the maximum reaches the paper's 6.747 % first.
    for cap in [0.04f32, 0.05, 0.06, 0.07] {
        let b = BrdfBasis::build(&cfg_with(|c| {
            c.weighting = LobeWeighting::Capped(cap);
            c.constant_in_fit = false;
        }))
        .unwrap();
        let r = b.error_report();
        eprintln!(
            "no constant, Capped({cap}): avg {:.5} max {:.5} worst ns {}",
            r.avg_rel_l2, r.max_rel_l2, r.worst_ns
        );
        assert!(
            r.avg_rel_l2 > 0.007979 || r.max_rel_l2 > 0.06747,
            "cap {cap}: {r:?}"
        );
        // The cap is honoured (to the Lawson iteration's accuracy).
        assert!(r.max_rel_l2 < 1.05 * cap as f64, "cap {cap}: {r:?}");
    }
}

#[test]
fn constant_in_fit_lowers_errors_for_every_weighting() {
    for w in [
        LobeWeighting::Energy,
        LobeWeighting::Unit,
        LobeWeighting::Capped(0.029),
    ] {
        let with = BrdfBasis::build(&cfg_with(|c| c.weighting = w)).unwrap();
        let without = BrdfBasis::build(&cfg_with(|c| {
            c.weighting = w;
            c.constant_in_fit = false;
        }))
        .unwrap();
        let (a, b) = (with.error_report(), without.error_report());
        eprintln!(
            "{w:?}: constant avg {:.5} max {:.5} / none avg {:.5} max {:.5}",
            a.avg_rel_l2, a.max_rel_l2, b.avg_rel_l2, b.max_rel_l2
        );
        assert!(with.spec_constant() && !without.spec_constant());
        assert!(a.avg_rel_l2 < b.avg_rel_l2, "{w:?}");
        match w {
            // Both capped searches end at their cap (to the iteration's accuracy), so only
            // the average can tell them apart.
            LobeWeighting::Capped(cap) => {
                let cap = cap as f64;
                assert!(
                    a.max_rel_l2 <= 1.05 * cap && b.max_rel_l2 <= 1.05 * cap,
                    "{w:?}"
                );
            }
            _ => assert!(a.max_rel_l2 <= b.max_rel_l2 * 1.001, "{w:?}"),
        }
        // c₀ (the lobe's mean, times π) is used only with the constant.
        let mut c = vec![0.0f32; 6];
        with.spec_coefficients(1.0, &mut c);
        assert!(c[0] > 0.0);
        without.spec_coefficients(1.0, &mut c);
        assert_eq!(c[0], 0.0);
    }
}

#[test]
fn report_matches_direct_grid_evaluation() {
    // Recompute the default report's errors the slow way: the 54,000 cell centres of the
    // paper's 30×30×60 grid, exact lobes, tabulated bases (`eval`) and exact coefficients.
    let b = BrdfBasis::build(&BasisConfig::default()).unwrap();
    let r = b.error_report();
    let n = b.count();
    let ns: Vec<f64> = (0..200).map(|j| 1.0 + j as f64 * 199.0 / 199.0).collect();
    let coefs: Vec<Vec<f64>> = ns
        .iter()
        .map(|&x| {
            let mut c = vec![0.0; n];
            b.exact_spec_coefficients(x, &mut c);
            c
        })
        .collect();
    let mut num = vec![0.0f64; ns.len()];
    let mut den = vec![0.0f64; ns.len()];
    let mut basis = vec![0.0f32; n];
    // θi ↔ θo symmetric: the pairs below the diagonal count twice.
    for a in 0..30 {
        for o in a..30 {
            let w = if a == o { 1.0 } else { 2.0 };
            for p in 0..60 {
                let ti = (a as f64 + 0.5) * FRAC_PI_2 / 30.0;
                let to = (o as f64 + 0.5) * FRAC_PI_2 / 30.0;
                let ph = (p as f64 + 0.5) * PI / 60.0;
                let (si, ci) = ti.sin_cos();
                let (so, co) = to.sin_cos();
                let cd = ((ci + co) / (2.0 * (1.0 + ci * co + si * so * ph.cos())).sqrt()).min(1.0);
                b.eval(cd as f32, &mut basis);
                for (j, &x) in ns.iter().enumerate() {
                    let exact = lobe(x, cd);
                    let approx: f64 = coefs[j]
                        .iter()
                        .zip(&basis)
                        .map(|(c, &v)| c * v as f64)
                        .sum();
                    num[j] += w * (exact - approx).powi(2);
                    den[j] += w * exact * exact;
                }
            }
        }
    }
    let e: Vec<f64> = num.iter().zip(&den).map(|(a, b)| (a / b).sqrt()).collect();
    let avg = e.iter().sum::<f64>() / e.len() as f64;
    let max = e.iter().cloned().fold(0.0, f64::max);
    eprintln!(
        "direct on the grid: avg {avg:.5} max {max:.5}; report {:.5} {:.5}",
        r.avg_rel_l2, r.max_rel_l2
    );
    assert!(
        (avg - r.avg_rel_l2).abs() < 0.01 * r.avg_rel_l2,
        "{avg} vs {r:?}"
    );
    assert!(
        (max - r.max_rel_l2).abs() < 0.01 * r.max_rel_l2,
        "{max} vs {r:?}"
    );
    assert!(avg <= 0.007979 && max < 0.03);
}

#[test]
fn default_build_is_fast() {
    let b = BrdfBasis::build(&BasisConfig::default()).unwrap();
    let ms = b.error_report().build_ms;
    eprintln!("default build: {ms:.1} ms");
    // Dev profile on a shared 2-core machine: generous bound, the target is < 200 ms.
    assert!(ms < 1500.0, "{ms} ms");
}

#[test]
fn binned_grid_matches_exact_grid_sums() {
    // The grid measure is binned on the δ mesh; compare inner products of lobe pairs with
    // the exact sums over the 54,000 cell centres.
    let cfg = BasisConfig::default();
    let mesh = Mesh::new(cfg.ns_max as f64);
    let atoms = grid_atoms(cfg.grid, &mesh);
    assert!(atoms.x.len() < MESH_BINS + 1);
    assert!((atoms.w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let [gi, go, gp] = cfg.grid.map(|g| g as usize);
    let pairs = [
        (1.0, 1.0),
        (1.0, 200.0),
        (50.0, 120.0),
        (200.0, 200.0),
        (3.0, 17.0),
    ];
    let mut exact = [0.0f64; 5];
    for a in 0..gi {
        for b in 0..go {
            for c in 0..gp {
                let ti = (a as f64 + 0.5) * FRAC_PI_2 / gi as f64;
                let to = (b as f64 + 0.5) * FRAC_PI_2 / go as f64;
                let ph = (c as f64 + 0.5) * PI / gp as f64;
                let (si, ci) = ti.sin_cos();
                let (so, co) = to.sin_cos();
                let cd = (ci + co) / (2.0 * (1.0 + ci * co + si * so * ph.cos())).sqrt();
                for (e, &(p, q)) in exact.iter_mut().zip(&pairs) {
                    *e += lobe(p, cd) * lobe(q, cd) / (gi * go * gp) as f64;
                }
            }
        }
    }
    for (e, &(p, q)) in exact.iter().zip(&pairs) {
        let binned: f64 = atoms
            .x
            .iter()
            .zip(&atoms.w)
            .map(|(&x, &w)| w * lobe(p, x.exp()) * lobe(q, x.exp()))
            .sum();
        let rel = (binned - e).abs() / e;
        assert!(
            rel < 1e-5,
            "ns {p}·{q}: binned {binned} exact {e} rel {rel}"
        );
    }
}

#[test]
fn continuum_cdf_matches_a_dense_grid() {
    let gla = gauss_legendre(8);
    let gld = gauss_legendre(12);
    let n = 90;
    let ts = [0.02, 0.05, 0.2, 0.5, 1.0, 1.4];
    let mut counts = [0usize; 6];
    for a in 0..n {
        for b in 0..n {
            for c in 0..2 * n {
                let ti = (a as f64 + 0.5) * FRAC_PI_2 / n as f64;
                let to = (b as f64 + 0.5) * FRAC_PI_2 / n as f64;
                let ph = (c as f64 + 0.5) * PI / (2 * n) as f64;
                let (si, ci) = ti.sin_cos();
                let (so, co) = to.sin_cos();
                let cd = ((ci + co) / (2.0 * (1.0 + ci * co + si * so * ph.cos())).sqrt()).min(1.0);
                let d = cd.acos();
                for (k, &t) in ts.iter().enumerate() {
                    if d < t {
                        counts[k] += 1;
                    }
                }
            }
        }
    }
    let total = (n * n * 2 * n) as f64;
    for (k, &t) in ts.iter().enumerate() {
        let grid = counts[k] as f64 / total;
        let cdf = continuum_cdf(t, &gla, &gld);
        // The 1° dense grid is itself off by O(h²) and by its discreteness near δ = 0.
        assert!(
            (grid - cdf).abs() < 2e-3 + 0.02 * cdf,
            "t {t}: grid {grid} continuum {cdf}"
        );
    }
    assert_eq!(continuum_cdf(FRAC_PI_2, &gla, &gld), 1.0);
    // Monotone on the mesh and small-δ behaviour ~ t² ln(1/t).
    let mesh = Mesh::new(1e4);
    let mut last = 0.0;
    for i in 0..=MESH_BINS {
        let c = continuum_cdf(mesh.edge(i), &gla, &gld);
        assert!(c >= last - 1e-12, "CDF decreases at bin {i}");
        last = c;
    }
    let r = continuum_cdf(2e-3, &gla, &gld) / continuum_cdf(1e-3, &gla, &gld);
    assert!(r > 3.5 && r < 4.5, "ratio {r}");
}

#[test]
fn jacobi_solves_a_known_matrix() {
    // Eigenvalues of [[2,1,0],[1,2,1],[0,1,2]]: 2+√2, 2, 2−√2.
    let a = [2.0, 1.0, 0.0, 1.0, 2.0, 1.0, 0.0, 1.0, 2.0];
    let (lam, v) = jacobi_eigen(&a, 3);
    let s = 2f64.sqrt();
    for (x, y) in lam.iter().zip([2.0 + s, 2.0, 2.0 - s]) {
        assert!((x - y).abs() < 1e-12, "{lam:?}");
    }
    // A v = λ v for every column.
    for k in 0..3 {
        for i in 0..3 {
            let av: f64 = (0..3).map(|j| a[i * 3 + j] * v[j * 3 + k]).sum();
            assert!((av - lam[k] * v[i * 3 + k]).abs() < 1e-12);
        }
    }
}

#[test]
fn reduced_eigensolver_matches_full_jacobi() {
    // The Gram matrix of 60 lobes over [1, 200]: leading eigenpairs via pivoted Cholesky +
    // small Jacobi must equal those of the full Jacobi.
    let ns: Vec<f64> = (0..60).map(|j| 1.0 + j as f64 * 199.0 / 59.0).collect();
    let mesh = Mesh::new(200.0);
    let atoms = grid_atoms([30, 30, 60], &mesh);
    let f = lobe_matrix(&ns, &atoms.x);
    let l = ns.len();
    let mut g = gram_matrix(&f, &atoms.w, l);
    for j in 0..l {
        for k in 0..l {
            g[j * l + k] /= (f[j].abs() + 1.0) * (f[k].abs() + 1.0); // any symmetric scaling
        }
    }
    let (lf, vf) = jacobi_eigen(&g, l);
    let (lr, vr) = top_eigenpairs(&g, l);
    let r = vr.len() / l;
    for k in 0..8 {
        assert!(
            (lf[k] - lr[k]).abs() <= 1e-9 * lf[0],
            "λ{k}: {} vs {}",
            lf[k],
            lr[k]
        );
        let dot: f64 = (0..l).map(|i| vf[i * l + k] * vr[i * r + k]).sum();
        assert!(
            (dot.abs() - 1.0).abs() < 1e-6,
            "eigenvector {k}: |dot| = {}",
            dot.abs()
        );
    }
}

#[test]
fn wide_range_tolerance() {
    for tol in [0.03f32, 0.01] {
        let cfg = cfg_with(|c| {
            c.ns_max = 10_000.0;
            c.count = BasisCount::Tolerance(tol);
        });
        let b = BrdfBasis::build(&cfg).unwrap();
        let r = b.error_report();
        eprintln!(
            "[1, 1e4] tol {tol}: N_b = {} grid avg {:.5} max {:.5} (ns {}) continuum {:?}/{:?} measure {} {:.0} ms",
            r.bases, r.avg_rel_l2, r.max_rel_l2, r.worst_ns, r.continuum_avg_rel_l2, r.continuum_max_rel_l2, r.pca_measure, r.build_ms
        );
        assert_eq!(r.pca_measure, "continuum");
        assert!(r.max_rel_l2 <= tol as f64 && r.continuum_max_rel_l2.unwrap() <= tol as f64);
        assert!(r.avg_rel_l2.is_finite() && r.worst_ns.is_finite());
        assert!(b.table.iter().all(|x| x.is_finite()) && b.coef.iter().all(|x| x.is_finite()));
        // One fewer basis would not have met the tolerance.
        let fewer = r.per_count.iter().find(|c| c.bases == r.bases - 1);
        if let Some(c) = fewer {
            assert!(
                c.max_rel_l2 > tol as f64 || r.continuum_max_rel_l2.is_some(),
                "{:?}",
                r.per_count
            );
        }
        // The tabulated basis reproduces lobes across the range on a fine sampling.
        for ns in [1.0f32, 3.0, 30.0, 300.0, 3000.0, 10_000.0] {
            let e = table_error(&b, ns);
            assert!(e < 1.5 * tol as f64 + 2e-3, "ns {ns}: tabulated error {e}");
        }
    }
}

#[test]
fn unreachable_tolerance_is_an_error() {
    let cfg = cfg_with(|c| {
        c.lobes = 8;
        c.count = BasisCount::Tolerance(1e-9);
    });
    let e = BrdfBasis::build(&cfg).err().expect("must fail").to_string();
    assert!(e.contains("not reachable") && e.contains("N_b"), "{e}");
}

#[test]
fn invalid_configs_are_rejected() {
    let bad = [
        cfg_with(|c| c.ns_min = 0.0),
        cfg_with(|c| c.ns_min = -1.0),
        cfg_with(|c| c.ns_min = 300.0),
        cfg_with(|c| c.ns_max = f32::INFINITY),
        cfg_with(|c| c.ns_min = f32::NAN),
        cfg_with(|c| c.count = BasisCount::Fixed(0)),
        cfg_with(|c| c.count = BasisCount::Fixed(202)),
        cfg_with(|c| c.count = BasisCount::Tolerance(0.0)),
        cfg_with(|c| c.count = BasisCount::Tolerance(f32::NAN)),
        cfg_with(|c| c.grid = [30, 0, 60]),
        cfg_with(|c| c.lobes = 0),
    ];
    for cfg in bad {
        match BrdfBasis::build(&cfg) {
            Err(RelumeError::Basis(_)) => {}
            Err(e) => panic!("{cfg:?}: wrong error {e}"),
            Ok(_) => panic!("{cfg:?} was accepted"),
        }
    }
}

#[test]
fn reconstruction_converges_with_count() {
    let mut last = [f64::INFINITY; 3];
    for n in [2u32, 4, 6, 10, 16] {
        let b = BrdfBasis::build(&cfg_with(|c| c.count = BasisCount::Fixed(n))).unwrap();
        for (i, ns) in [2.0f32, 40.0, 190.0].into_iter().enumerate() {
            let e = table_error(&b, ns);
            assert!(
                e < last[i] * 1.05 + 1e-4,
                "N_b {n} ns {ns}: {e} after {}",
                last[i]
            );
            last[i] = e;
        }
    }
    assert!(last.iter().all(|&e| e < 2e-3), "{last:?}");
}

#[test]
fn coefficient_interpolation_error() {
    for ns_max in [200.0f32, 10_000.0] {
        let b = BrdfBasis::build(&cfg_with(|c| {
            c.ns_max = ns_max;
            c.count = BasisCount::Fixed(12);
        }))
        .unwrap();
        let n = b.count();
        let mut worst: f64 = 0.0;
        for i in 0..997 {
            let ns = (1.0f64 * (ns_max as f64).powf(i as f64 / 996.0)) as f32;
            let mut ci = vec![0.0f32; n];
            let mut ce = vec![0.0f64; n];
            b.spec_coefficients(ns, &mut ci);
            b.exact_spec_coefficients(ns as f64, &mut ce);
            // Bases are orthogonal (the specular ones orthonormal, the diffuse 1/π of norm
            // 1/π): the coefficient error is the L2 error of the lobe.
            let wk = |k: usize| if k == 0 { 1.0 / PI } else { 1.0 };
            let err: f64 = (0..n)
                .map(|k| ((ci[k] as f64 - ce[k]) * wk(k)).powi(2))
                .sum::<f64>()
                .sqrt();
            let norm: f64 = (0..n).map(|k| (ce[k] * wk(k)).powi(2)).sum::<f64>().sqrt();
            worst = worst.max(err / norm);
        }
        eprintln!("[1, {ns_max}] coefficient interpolation: worst {worst:.2e} of the lobe norm");
        assert!(worst < 1e-4, "{worst}");
    }
}

#[test]
fn eval_shape_and_clamping() {
    let b = BrdfBasis::build(&BasisConfig::default()).unwrap();
    let mut out = vec![9.0f32; 7];
    b.eval(1.0, &mut out);
    assert_eq!(out[0], std::f32::consts::FRAC_1_PI);
    assert_eq!(out[6], 9.0, "writes only count() slots");
    // Below the horizon the bases keep their value at cos δ = 0 (a constant offset with
    // the constant in the fit; 0 without).
    let mut edge = vec![0.0f32; 6];
    b.eval(0.0, &mut edge);
    assert!(edge[1..].iter().any(|&x| x != 0.0));
    for c in [-0.5f32, f32::NAN] {
        b.eval(c, &mut out);
        assert_eq!(out[..6], edge[..]);
    }
    let plain = BrdfBasis::build(&cfg_with(|c| c.constant_in_fit = false)).unwrap();
    for c in [0.0f32, -0.5, f32::NAN] {
        plain.eval(c, &mut out);
        assert!(out[1..6].iter().all(|&x| x == 0.0));
    }
    let mut c = vec![0.0f32; 6];
    let mut d = vec![0.0f32; 6];
    b.spec_coefficients(0.01, &mut c);
    b.spec_coefficients(1.0, &mut d);
    assert_eq!(c, d, "ns below the range is clamped to ns_min");
    b.spec_coefficients(1e9, &mut c);
    b.spec_coefficients(200.0, &mut d);
    assert_eq!(c, d, "ns above the range is clamped to ns_max");
    assert!(c[0] > 0.0, "c₀ is used with the constant in the fit");
}

#[test]
fn reconstruct_matches_blinn_phong_through_directions() {
    use glam::Vec3;
    let b = BrdfBasis::build(&cfg_with(|c| c.count = BasisCount::Fixed(10))).unwrap();
    let n = Vec3::Z;
    let dir = |t: f32, p: f32| Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
    for (kd, ks, ns) in [
        (0.5f32, 0.5f32, 20.0f32),
        (0.0, 1.0, 150.0),
        (0.9, 0.1, 3.0),
    ] {
        let m = BlinnPhong {
            kd: [kd; 3],
            ks: [ks; 3],
            ns,
        };
        let peak = m.eval(n, dir(0.4, 0.0), dir(0.4, PI as f32)).x;
        for (ti, to, dphi) in [
            (0.4f32, 0.4f32, PI as f32),
            (1.55, 1.5, 3.0),
            (1.5697, 1.5697, PI as f32),
            (0.2, 1.2, 2.5),
            (1.56, 0.0, 1.0),
        ] {
            let wi = dir(ti, 0.3);
            let wo = dir(to, 0.3 + dphi);
            let h = (wi + wo).normalize();
            let cd = n.dot(h);
            let r_io = b.reconstruct(&m, cd);
            // Reciprocity: swapping wi and wo gives the same half vector.
            let r_oi = b.reconstruct(&m, n.dot((wo + wi).normalize()));
            assert_eq!(r_io, r_oi);
            let exact = m.eval(n, wi, wo);
            assert!(r_io.is_finite());
            assert!(
                (r_io - exact).abs().max_element() < 0.02 * peak + 1e-3,
                "{m:?} θ {ti} {to}: {r_io} vs {exact}"
            );
        }
    }
}

#[test]
fn material_coefficients_layout() {
    let b = BrdfBasis::build(&BasisConfig::default()).unwrap();
    let m = BlinnPhong {
        kd: [0.1, 0.2, 0.3],
        ks: [0.5, 0.25, 0.0],
        ns: 42.0,
    };
    let c = b.material_coefficients(&m);
    assert_eq!(c.len(), 6);
    let mut s = vec![0.0f32; 6];
    b.spec_coefficients(42.0, &mut s);
    let ks = glam::Vec3::new(0.5, 0.25, 0.0);
    assert!(s[0] > 0.0);
    assert_eq!(c[0], glam::Vec3::new(0.1, 0.2, 0.3) + ks * s[0]);
    for k in 1..6 {
        assert_eq!(c[k], ks * s[k]);
    }
    let (kd, ks0, spec) = b.split_coefficients(&m);
    assert_eq!(kd, glam::Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(ks0, ks * s[0]);
    assert_eq!(spec.len(), 5);
    assert_eq!(kd + ks0, c[0]);
    assert_eq!(spec[..], c[1..]);
    // Without the constant, basis 0 is the diffuse alone.
    let plain = BrdfBasis::build(&cfg_with(|c| c.constant_in_fit = false)).unwrap();
    let (kd, ks0, _) = plain.split_coefficients(&m);
    assert_eq!(ks0, glam::Vec3::ZERO);
    assert_eq!(plain.material_coefficients(&m)[0], kd);
}

#[test]
fn config_serde_defaults() {
    let json = r#"{"ns_min":1.0,"ns_max":200.0,"lobes":200,"grid":[30,30,60],"count":{"Fixed":6}}"#;
    let c: BasisConfig = serde_json::from_str(json).unwrap();
    assert_eq!(c, BasisConfig::default());
    assert!(c.constant_in_fit);
    let json = r#"{"ns_min":1.0,"ns_max":200.0,"lobes":200,"grid":[30,30,60],"count":{"Fixed":6},"constant_in_fit":false}"#;
    let c: BasisConfig = serde_json::from_str(json).unwrap();
    assert!(!c.constant_in_fit);
    let back: BasisConfig = serde_json::from_str(&serde_json::to_string(&c).unwrap()).unwrap();
    assert_eq!(back, c);
}
