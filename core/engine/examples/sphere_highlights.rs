//! What a sphere shows of an edited lobe rebuilt from the Principled basis: for a region
//! baked with one material and relit with another, the sum of a glossy sphere's image under
//! one light (a cone of directions) seen from far away, rebuilt over exact, for several
//! light placements. The relight's coefficients (the basis and the bake-time slot) are set
//! beside the basis' least-squares projection alone.
//!
//! This is a model of the relit image, not the relight: it rebuilds the lobe from the
//! basis' tables exactly, where a relight weighs layers the bake estimated (with their
//! noise, denoising and compression). docs/fidelity.md sets its figures beside the spheres
//! Relume relights.
//!
//! `cargo run --release -p relume-engine --example sphere_highlights` (the preview preset's
//! basis size; `-- 21` for another), one JSON line per edit and placement.
//!
//! The image sum is `∫ f·(n·l)·(n·v) dn` over the sphere's normals and the light's cone, a
//! graded grid around each light direction's half vector (fine enough for roughness 0.1).

use std::f64::consts::PI;

use relume_engine::brdf::cycles_principled::CyclesPrincipled;
use relume_engine::brdf::principled_basis::{Cosines, PrincipledBasis, PrincipledBasisConfig};
use relume_engine::brdf::Principled;

type V = [f64; 3];

fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(a: V) -> V {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

fn cross(a: V, b: V) -> V {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Two unit axes perpendicular to `axis` and to each other.
fn frame(axis: V) -> (V, V) {
    let helper = if axis[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let t = unit(cross(axis, helper));
    (t, cross(axis, t))
}

/// `axis` tilted by the angle whose sine and cosine are `(s, c)` toward azimuth `phi` of its
/// `frame`: the frame and the angle's sine and cosine are the caller's, made once per axis
/// and angle rather than once per normal.
fn tilt(axis: V, (t, b): (V, V), (s, c): (f64, f64), phi: f64) -> V {
    let (sp, cp) = phi.sin_cos();
    unit(std::array::from_fn(|i| {
        axis[i] * c + (t[i] * cp + b[i] * sp) * s
    }))
}

/// The sphere's image sum of BRDF `f` (a function of the four cosines) under a light cone of
/// half-angle `radius` around `light`, seen along `view`.
fn image_sum(f: &dyn Fn(Cosines) -> f64, light: V, view: V, radius: f64) -> f64 {
    const RINGS: usize = 6;
    const PER_RING: usize = 12;
    const THETA: usize = 600;
    const PHI: usize = 256;
    // Normal angles around the half vector, graded from 5·10⁻⁴ rad.
    let first = 5e-4;
    let beta = (PI / first).ln_1p();
    let edge = |i: usize| first * (beta * i as f64 / THETA as f64).exp_m1();
    let light_frame = frame(light);
    let mut total = 0.0;
    for ring in 0..RINGS {
        let a = radius * (ring as f64 + 0.5) / RINGS as f64;
        for k in 0..PER_RING {
            let phi = 2.0 * PI * (k as f64 + 0.5) / PER_RING as f64;
            let l = tilt(light, light_frame, a.sin_cos(), phi);
            let h = unit([l[0] + view[0], l[1] + view[1], l[2] + view[2]]);
            let cos_d = dot(l, h);
            let h_frame = frame(h);
            let mut sum = 0.0;
            for i in 0..THETA {
                let (lo, hi) = (edge(i), edge(i + 1));
                let (sin_t, cos_t) = (0.5 * (lo + hi)).sin_cos();
                for j in 0..PHI {
                    let phi = 2.0 * PI * (j as f64 + 0.5) / PHI as f64;
                    let n = tilt(h, h_frame, (sin_t, cos_t), phi);
                    let (cos_i, cos_o) = (dot(n, l), dot(n, view));
                    if cos_i <= 0.0 || cos_o <= 0.0 {
                        continue;
                    }
                    let c = Cosines {
                        cos_i,
                        cos_o,
                        cos_h: cos_t,
                        cos_d,
                    };
                    sum += f(c) * cos_i * cos_o * sin_t * (hi - lo);
                }
            }
            total += sum * a;
        }
    }
    total
}

fn material(base: [f32; 3], metallic: f32, roughness: f32) -> Principled {
    Principled {
        base_color: base,
        metallic,
        roughness,
        ior: 1.5,
        specular_ior_level: 0.5,
    }
}

fn main() {
    let bases = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(17);
    let config = PrincipledBasisConfig {
        bases,
        ..PrincipledBasisConfig::default()
    };
    let basis = PrincipledBasis::shared(&config).expect("the basis builds");
    let n = basis.count();
    let copper = [0.9, 0.65, 0.35];
    let blue = [0.2, 0.35, 0.7];
    let edits = [
        (material(copper, 1.0, 0.3), material(copper, 1.0, 0.1)),
        (material(copper, 1.0, 0.3), material(copper, 1.0, 0.15)),
        (material(copper, 1.0, 0.5), material(copper, 1.0, 0.1)),
        (material(copper, 1.0, 0.3), material(copper, 1.0, 0.5)),
        (material(blue, 0.0, 0.3), material(blue, 0.0, 0.1)),
        (material(blue, 0.0, 0.3), material(blue, 0.0, 0.15)),
        (material(blue, 0.0, 0.3), material(blue, 1.0, 0.3)),
    ];
    // The view and two light placements of blender_tests/support/spheres.py seen from a
    // sphere of that row, and the light on the view's axis.
    let view = unit([0.0, -4.2, 1.1]);
    let placements = [
        ("light in front", unit([0.5, -2.0, 2.5]), 0.2),
        ("light to the side", unit([3.0, 0.3, 0.7]), 0.25),
        ("light at the view", view, 0.1),
    ];
    const GREEN: usize = 1;
    for (bake, edit) in edits {
        let lobe = basis.bake_lobe(&bake);
        let relit = basis.anchored_coefficients(&lobe, &edit).slots;
        let (projection_l2, relit_l2) = basis.rebuild_error_with_bake_lobe(&lobe, &edit);
        let f = CyclesPrincipled::new(&edit);
        let g = CyclesPrincipled::new(&bake);
        let exact = |c: Cosines| f.eval_cosines(c.cos_i, c.cos_o, c.cos_h, c.cos_d)[GREEN];
        let (projected, _) =
            basis.project(|c| f.eval_cosines(c.cos_i, c.cos_o, c.cos_h, c.cos_d)[GREEN]);
        let rebuilt = |with_g: bool| {
            let (relit, projected, g) = (&relit, &projected, &g);
            let basis = &basis;
            move |c: Cosines| {
                let mut v = vec![0.0; n];
                basis.eval(c, &mut v);
                if with_g {
                    let slots: f64 = v.iter().zip(relit).map(|(a, b)| a * b[GREEN]).sum();
                    slots
                        + relit[n][GREEN]
                            * g.eval_cosines(c.cos_i, c.cos_o, c.cos_h, c.cos_d)[GREEN]
                } else {
                    v.iter().zip(projected).map(|(a, b)| a * b).sum()
                }
            }
        };
        let (relit_fn, projected_fn) = (rebuilt(true), rebuilt(false));
        for (placement, light, radius) in placements {
            let reference = image_sum(&exact, light, view, radius);
            println!(
                "{{\"slots\": {bases}, \"bake\": {{\"metallic\": {}, \"roughness\": {}}}, \
                 \"edit\": {{\"metallic\": {}, \"roughness\": {}}}, \"placement\": \"{placement}\", \
                 \"relit_over_exact\": {:.4}, \"projection_over_exact\": {:.4}, \
                 \"relit_l2\": {:.4}, \"projection_l2\": {:.4}}}",
                bake.metallic,
                bake.roughness,
                edit.metallic,
                edit.roughness,
                image_sum(&relit_fn, light, view, radius) / reference,
                image_sum(&projected_fn, light, view, radius) / reference,
                relit_l2[GREEN],
                projection_l2[GREEN],
            );
        }
    }
}
