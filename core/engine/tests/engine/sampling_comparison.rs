//! Equal-sample and equal-time comparison of the indirect samplings on the assets scenes:
//! the paper's uniform hemisphere (with surface-sampled area lights and a cosine-sampled
//! world, as the paper had), Relume's mixture (cosine + basis lobes, area lights by solid
//! angle, world by hierarchical warping) and the guided mixture (plus a per-tile map of
//! incoming light from a short first pass). RMSE against a converged render (true BRDF, one
//! bounce), averaged over seeds; the variance reduction is the squared RMSE ratio.
//!
//! `cargo test --release --test engine sampling_comparison -- --nocapture` prints the table and a
//! JSON line per scene. The image is 64 pixels wide by default (CI); set
//! `RELUME_SAMPLING_WIDTH=128` for the README's figures (guiding works per 16-pixel tile, so
//! its gain grows with the resolution), `RELUME_SAMPLING_SAMPLES=16x4x1` for the paper's
//! sample counts and `RELUME_SAMPLING_REFERENCE_SPP` for the reference's eye samples. Times exclude the set-up every method shares (BVH,
//! bases) but include the guide pass.

use std::path::Path;
use std::time::Instant;

use relume_engine::bake::prepare::context::BakeContext;
use relume_engine::bake::reference::{render_with_context, ReferenceBrdf};
use relume_engine::bake::{BakeSettings, IndirectSampling};
use relume_engine::brdf::BlinnPhong;
use relume_engine::geometry::lights::{AreaSampling, WorldSampling};
use relume_engine::progress::Progress;
use relume_engine::scene::file::load_scene;
use relume_engine::scene::{Resolution, Scene};

fn scene(name: &str) -> Scene {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../assets/{name}.scene.json"));
    load_scene(&path).unwrap()
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Method {
    Paper,
    Mixture,
    Guided,
}

/// Eye × light × indirect samples of the compared renders: 8 × 1 × 1 by default (every
/// sample a fresh indirect direction; the guide pass's 4 paths a pixel are ⅓ of the rays),
/// `RELUME_SAMPLING_SAMPLES=16x4x4` for the preview preset's structure (16 guide paths a
/// pixel, ≈ 12 % of the rays).
fn samples() -> (u32, u32, u32) {
    let spec = std::env::var("RELUME_SAMPLING_SAMPLES").unwrap_or_else(|_| "8x1x1".into());
    let v: Vec<u32> = spec.split('x').filter_map(|p| p.parse().ok()).collect();
    assert_eq!(
        v.len(),
        3,
        "RELUME_SAMPLING_SAMPLES={spec}: want EYExLIGHTxINDIRECT"
    );
    (v[0], v[1], v[2])
}

fn width() -> u32 {
    std::env::var("RELUME_SAMPLING_WIDTH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64)
}

/// Renders `width()` pixels wide (the scene's aspect) with `spp` eye samples; returns RGB,
/// seconds (guide pass and tracing) and the guide pass's rays.
fn render(
    scene: &Scene,
    method: Method,
    (spp, light_samples, indirect_samples): (u32, u32, u32),
    seed: u64,
) -> (Vec<f32>, f64, u64) {
    let (w, h) = (scene.resolution.width, scene.resolution.height);
    let width = width();
    let height = ((width as f64 * h as f64 / w as f64).round() as u32).max(1);
    let settings = BakeSettings {
        spp,
        light_samples,
        indirect_samples,
        seed,
        sampling: match method {
            Method::Paper => IndirectSampling::Uniform,
            Method::Mixture => IndirectSampling::Mixture,
            Method::Guided => IndirectSampling::Guided,
        },
        resolution: Some(Resolution { width, height }),
        ..Default::default()
    };
    let (mut ctx, _) = BakeContext::new(scene, &settings).unwrap();
    let (guide_seconds, guide_rays) = ctx.guide.as_ref().map_or((0.0, 0), |g| (g.seconds, g.rays));
    if method == Method::Paper {
        ctx.lights.set_area_sampling(AreaSampling::Area);
        ctx.lights.set_world_sampling(WorldSampling::Cosine);
    }
    let materials: Vec<BlinnPhong> = scene
        .regions
        .iter()
        .filter(|r| r.editable)
        .map(|r| r.material.to_blinn_phong())
        .collect();
    let t = Instant::now();
    let img = render_with_context(&ctx, &materials, ReferenceBrdf::True, &Progress::new()).unwrap();
    let secs = t.elapsed().as_secs_f64() + guide_seconds;
    (
        img.rgba.chunks(4).flat_map(|p| p[..3].to_vec()).collect(),
        secs,
        guide_rays,
    )
}

fn rmse(a: &[f32], b: &[f32]) -> f64 {
    let s: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
    (s / a.len() as f64).sqrt()
}

fn mean(v: &[f32]) -> f64 {
    v.iter().map(|x| *x as f64).sum::<f64>() / v.len() as f64
}

#[test]
fn relume_sampling_against_the_papers_at_equal_samples_and_time() {
    let spp = samples();
    // The reference traces 512 indirect paths a pixel: 64× the 8 × 1 × 1 renders', 8× those
    // of 16 × 4 × 4 (its own noise is in every RMSE and pulls the ratios towards 1).
    let reference_spp = std::env::var("RELUME_SAMPLING_REFERENCE_SPP")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or((512 / spp.2).max(64));
    let seeds = [1u64, 2, 3, 4];
    let mut rows = Vec::new();
    for name in ["cornell", "ring", "hdri", "textured", "translucent"] {
        let s = scene(name);
        let (reference, _, _) = render(&s, Method::Mixture, (reference_spp, spp.1, spp.2), 1000);
        let mut results = Vec::new();
        for method in [Method::Paper, Method::Mixture, Method::Guided] {
            let (mut e2, mut secs, mut bias) = (0.0, 0.0, 0.0);
            for &seed in &seeds {
                let (img, t, _) = render(&s, method, spp, seed);
                assert!(
                    img.iter().all(|v| v.is_finite() && *v >= -1e-6),
                    "{name} {method:?}"
                );
                e2 += rmse(&img, &reference).powi(2);
                secs += t;
                bias += mean(&img);
            }
            let n = seeds.len() as f64;
            results.push((method, (e2 / n).sqrt(), secs / n, bias / n));
        }
        let paper = results[0];
        let mut json = Vec::new();
        for &(method, r, t, m) in &results {
            let var_red = (paper.1 / r).powi(2);
            let time_red = var_red * paper.2 / t;
            json.push(serde_json::json!({
                "method": format!("{method:?}").to_lowercase(), "rmse": r, "seconds": t,
                "variance_reduction_equal_samples": var_red,
                "variance_reduction_equal_time": time_red,
            }));
            println!(
                "{name:>8} {method:>8?}: RMSE {r:.5}  time {t:.3} s  mean {m:.5} (ref {:.5})  \
                 variance ÷{var_red:.2} at equal samples, ÷{time_red:.2} at equal time",
                mean(&reference)
            );
            // Every method is unbiased: its mean over seeds matches the converged mean
            // within what 4 × 8 spp of noise allow (2 % of the image mean, checked loosely).
            assert!(
                (m - mean(&reference)).abs() < 0.03 * mean(&reference) + 1e-4,
                "{name} {method:?}: {m}"
            );
        }
        println!(
            "{}",
            serde_json::json!({"scene": name, "width": width(),
                "samples": [spp.0, spp.1, spp.2],
                "seeds": seeds.len(), "reference_spp": reference_spp, "methods": json})
        );
        rows.push((name, results));
    }
    // The aim: ≥ 2× lower variance than the paper's sampling at equal samples on the
    // HDRI scene (world warping) — checked; the other scenes' figures are printed (the glossy
    // scenes fall short of it: README, "Sampling against the paper's").
    let hdri = &rows.iter().find(|r| r.0 == "hdri").unwrap().1;
    let factor = (hdri[0].1 / hdri[1].1).powi(2);
    assert!(
        factor >= 2.0,
        "hdri: mixture reduces the variance only {factor:.2}×"
    );
    // Guiding must pay on the glossy Cornell box even at this small size (measured ÷1.36 at
    // 64 px, ÷1.78 at 128 px; the run is deterministic, so this cannot flake).
    let cornell = &rows.iter().find(|r| r.0 == "cornell").unwrap().1;
    let guided = (cornell[0].1 / cornell[2].1).powi(2);
    assert!(
        guided >= 1.1,
        "cornell: guided sampling reduces the variance only {guided:.2}×"
    );
}
