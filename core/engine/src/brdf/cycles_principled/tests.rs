use super::ggx::*;
use super::*;

fn principled(base: f32, metallic: f32, roughness: f32, level: f32) -> Principled {
    Principled {
        base_color: [base; 3],
        metallic,
        roughness,
        ior: 1.5,
        specular_ior_level: level,
    }
}

const MUS: [f64; 5] = [1.0, 0.7, 0.4, 0.15, 0.05];

#[test]
fn white_metal_reflects_everything_at_every_roughness() {
    // Multiple-scattering compensation with F = 1 restores an albedo of 1 (white furnace).
    for r in [0.05f32, 0.1, 0.3, 0.5, 0.8, 1.0] {
        let m = CyclesPrincipled::new(&principled(1.0, 1.0, r, 0.5));
        for mu in MUS {
            let a = m.directional_albedo(mu)[0];
            assert!((a - 1.0).abs() < 0.01, "r {r} μo {mu}: albedo {a}");
        }
    }
}

#[test]
fn white_dielectric_conserves_energy() {
    let mut lowest: f64 = 1.0;
    for level in [0.25f32, 0.5, 1.0] {
        for r in [0.05f32, 0.2, 0.5, 1.0] {
            let m = CyclesPrincipled::new(&principled(1.0, 0.0, r, level));
            for mu in MUS {
                let a = m.directional_albedo(mu)[0];
                assert!(a <= 1.0 + 0.01, "level {level} r {r} μo {mu}: albedo {a}");
                lowest = lowest.min(a);
            }
        }
    }
    // The layering loses little: the base takes what the coat leaves.
    assert!(lowest > 0.85, "{lowest}");
}

#[test]
fn smooth_limit_matches_fresnel() {
    // At the smallest roughness the specular albedo is the Fresnel of the view angle.
    for mu in [0.9f64, 0.5, 0.2] {
        let metal = CyclesPrincipled::new(&principled(0.5, 1.0, 0.05, 0.5));
        let a = metal.directional_albedo(mu)[0];
        let f = fresnel_schlick(mu, 0.5);
        assert!(
            (a - f).abs() < 0.01 * f.max(0.1),
            "μ {mu}: metal {a} vs Schlick {f}"
        );
        let black = CyclesPrincipled::new(&principled(0.0, 0.0, 0.05, 0.5));
        let a = black.directional_albedo(mu)[0];
        let f = fresnel_dielectric(mu, 1.5);
        assert!(
            (a - f).abs() < 0.03 * f,
            "μ {mu}: dielectric {a} vs Fresnel {f}"
        );
    }
}

#[test]
fn single_scattering_albedo_falls_with_roughness() {
    // E(μ) of GGX with F = 1: 1 in the smooth limit, lower for rough lobes
    // (the energy multiple scattering restores).
    let e = |r: f32, mu: f64| {
        CyclesPrincipled::new(&principled(1.0, 1.0, r, 0.5))
            .energy
            .at(mu)
    };
    assert!(e(0.05, 0.8) > 0.99);
    assert!(e(1.0, 0.8) < e(0.5, 0.8) && e(0.5, 0.8) < e(0.2, 0.8));
    // Known value: at α = 1, D = 1/π and G = 2cos θi/(1 + cos θi) at normal view, so
    // E(1) = ∫ cos θi/(1 + cos θi)·2 d(cos θi)/2 = 1 − ln 2.
    let exact = 1.0 - std::f64::consts::LN_2;
    assert!(
        (e(1.0, 1.0) - exact).abs() < 0.005,
        "{} vs {exact}",
        e(1.0, 1.0)
    );
}

#[test]
fn ggx_lobe_with_fresnel_is_reciprocal() {
    let dir = |t: f64, p: f64| [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
    let lobe = |wi: [f64; 3], wo: [f64; 3]| {
        let h = [wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]];
        let l = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        let cos_d = (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]) / l;
        ggx_single(0.3, wi[2], wo[2], h[2] / l) * fresnel_dielectric(cos_d, 1.5)
    };
    for (ti, pi, to, po) in [
        (0.1, 0.0, 0.7, 3.0),
        (1.2, 1.0, 0.3, -2.0),
        (1.5, 0.2, 1.4, 3.3),
    ] {
        let (a, b) = (
            lobe(dir(ti, pi), dir(to, po)),
            lobe(dir(to, po), dir(ti, pi)),
        );
        assert!(a > 0.0 && (a - b).abs() <= 1e-12 * a, "{a} {b}");
    }
}

#[test]
fn linear_in_metallic() {
    let at = |m: f32| {
        CyclesPrincipled::new(&principled(0.6, m, 0.4, 0.5)).eval_cosines(0.8, 0.6, 0.95, 0.9)
    };
    let (a, b, c) = (at(0.0), at(1.0), at(0.25));
    for k in 0..3 {
        assert!((c[k] - (0.75 * a[k] + 0.25 * b[k])).abs() < 1e-9 * a[k].max(b[k]));
    }
}

#[test]
fn total_on_odd_inputs() {
    for x in [f32::NAN, f32::INFINITY, -1.0, 7.0] {
        let m = CyclesPrincipled::new(&Principled {
            base_color: [x; 3],
            metallic: x,
            roughness: x,
            ior: x,
            specular_ior_level: x,
        });
        let v = m.eval_cosines(0.5, 0.5, 1.0, 0.5);
        assert!(v.iter().all(|c| c.is_finite() && *c >= 0.0), "{x}: {v:?}");
    }
}

#[test]
fn kept_view_tables_are_the_ones_built_for_their_roughness_and_ior() {
    let (alpha, eta) = (0.3f64 * 0.3, 1.45f64);
    let (energy, layer_s) = view_tables(alpha, eta);
    // Kept: the same numbers, and the same as building them afresh.
    let (again, layer_again) = view_tables(alpha, eta);
    assert_eq!(energy.0, again.0);
    assert_eq!(layer_s.0, layer_again.0);
    assert_eq!(energy.0, single_scatter_albedo(alpha).0);
    // Another IOR or roughness is not served the kept pair.
    let (_, other_eta) = view_tables(alpha, 1.9);
    assert_ne!(other_eta.0, layer_s.0);
    let (other_alpha, _) = view_tables(0.5 * 0.5, eta);
    assert_ne!(other_alpha.0, energy.0);
    // A material rebuilt with another colour evaluates as a first build of it does.
    let a = CyclesPrincipled::new(&principled(0.3, 0.4, 0.3, 0.5));
    let b = CyclesPrincipled::new(&principled(0.7, 0.4, 0.3, 0.5));
    let (_, a_diffuse) = a.eval_parts(0.6, 0.8, 0.9, 0.7);
    let (_, b_diffuse) = b.eval_parts(0.6, 0.8, 0.9, 0.7);
    let ratio = 0.7f32 as f64 / 0.3f32 as f64;
    assert!((b_diffuse[0] / a_diffuse[0] - ratio).abs() < 1e-12);
}
