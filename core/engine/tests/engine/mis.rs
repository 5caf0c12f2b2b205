//! Multiple importance sampling of direct light (`bake/path/mis.rs`, issue 15's fireflies on
//! smooth metal): smooth metallic spheres (Principled roughness 0.1–0.3 through the core's
//! mapping) on a diffuse floor under a small bright area light and an HDRI with a sun-like
//! hot spot.
//!
//! - Consistent: for every light kind both strategies reach, what a BSDF ray along a light
//!   sample's direction receives is that sample's radiance, with the pdf light sampling
//!   drew it with (the condition for the weights to sum to one).
//! - Unbiased: the image's mean does not depend on how the lights are sampled (solid angle
//!   or area for the area light, the warped mixture or cosine for the world), which holds
//!   only if the pdf a BSDF ray's hit is weighed with is the one light sampling uses.
//! - No fireflies: the brightest pixel of a bake at few samples, relit at its materials,
//!   stays near the brightest pixel of a converged render of the same scene.
//!
//! `cargo test -p relume-engine --test engine mis -- --nocapture` prints the figures.
use crate::common;

use relume_engine::bake::prepare::context::BakeContext;
use relume_engine::bake::reference::{render_with_context, ReferenceBrdf};
use relume_engine::bake::{bake, BakeSettings, IndirectSampling, LightGrouping};
use relume_engine::brdf::principled::roughness_to_ns;
use relume_engine::brdf::BlinnPhong;
use relume_engine::geometry::lights::{AreaSampling, LightSet, WorldSampling};
use relume_engine::geometry::sampling::mix64;
use relume_engine::progress::Progress;
use relume_engine::Rgb;

use relume_engine::scene::{AreaShape, ImageRef, Light, Resolution, Scene, World};

use common::{bp, bp_rgb, look_at, quad, region, sphere};

const W: u32 = 40;
const H: u32 = 24;

/// A 64×32 sky of radiance ≈ 0.3 (ground 0.1) with a 2×2-texel sun of radiance ≈ `sun` at
/// 35° elevation.
fn sky(sun: f32) -> ImageRef {
    let (w, h) = (64u32, 32u32);
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            let in_sun = (10..12).contains(&y) && (20..22).contains(&x);
            let v = if in_sun {
                [sun, 0.9 * sun, 0.75 * sun]
            } else if y < h / 2 {
                [0.25, 0.3, 0.4]
            } else {
                [0.1, 0.1, 0.1]
            };
            rgb.extend_from_slice(&v);
        }
    }
    ImageRef::Inline {
        width: w,
        height: h,
        rgb,
    }
}

fn metal(roughness: f32) -> relume_engine::brdf::MaterialSpec {
    bp_rgb([0.0; 3], [0.95, 0.8, 0.6], roughness_to_ns(roughness))
}

/// Three metal spheres (roughness 0.1, 0.2 editable, 0.3) on a grey floor, a small area
/// light and a sky whose sun has radiance `sun`.
fn spheres(sun: f32) -> Scene {
    let s = 6.0;
    let mut editable = region("Metal 0.2", true, metal(0.2));
    editable.ns_range = Some([roughness_to_ns(1.0), roughness_to_ns(0.1)]);
    Scene {
        meshes: vec![
            quad(
                "floor",
                [-s, -s, 0.0],
                [s, -s, 0.0],
                [s, s, 0.0],
                [-s, s, 0.0],
                0,
            ),
            sphere("a", [-1.0, 0.0, 0.4], 0.4, 24, 48, 1),
            sphere("b", [0.0, 0.0, 0.4], 0.4, 24, 48, 2),
            sphere("c", [1.0, 0.0, 0.4], 0.4, 24, 48, 3),
        ],
        regions: vec![
            region("Floor", false, bp(0.5, 0.0, 1.0)),
            region("Metal 0.1", false, metal(0.1)),
            editable,
            region("Metal 0.3", false, metal(0.3)),
        ],
        lights: vec![Light::Area {
            position: [0.6, -1.2, 2.4],
            axis_u: [1.0, 0.0, 0.0],
            axis_v: [0.0, 1.0, 0.0],
            shape: AreaShape::Square,
            size_x: 0.05,
            size_y: None,
            power: 60.0,
            color: [1.0, 1.0, 1.0],
            visible_camera: false,
        }],
        world: World::Equirect {
            image: sky(sun),
            strength: 1.0,
        },
        camera: look_at([0.0, -3.6, 1.3], [0.0, 0.0, 0.35], 40.0),
        resolution: Resolution {
            width: W,
            height: H,
        },
        light_groups: Vec::new(),
    }
}

fn materials(scene: &Scene) -> Vec<BlinnPhong> {
    scene
        .regions
        .iter()
        .filter(|r| r.editable)
        .map(|r| r.material.to_blinn_phong())
        .collect()
}

fn settings(spp: u32, seed: u64) -> BakeSettings {
    BakeSettings {
        spp,
        light_samples: 2,
        indirect_samples: 2,
        bounces: 1,
        sampling: IndirectSampling::Mixture,
        seed,
        ..Default::default()
    }
}

/// Mean of every channel of an RGBA image.
fn mean(rgba: &[f32]) -> f64 {
    let rgb: Vec<f64> = rgba
        .chunks(4)
        .flat_map(|p| p[..3].iter().map(|v| *v as f64))
        .collect();
    rgb.iter().sum::<f64>() / rgb.len() as f64
}

fn brightest(rgba: &[f32]) -> f32 {
    rgba.chunks(4)
        .map(|p| p[..3].iter().cloned().fold(0.0, f32::max))
        .fold(0.0, f32::max)
}

fn render(
    scene: &Scene,
    spp: u32,
    seed: u64,
    area: AreaSampling,
    world: WorldSampling,
) -> Vec<f32> {
    let (mut ctx, _) = BakeContext::new(scene, &settings(spp, seed)).unwrap();
    ctx.lights.set_area_sampling(area);
    ctx.lights.set_world_sampling(world);
    render_with_context(
        &ctx,
        &materials(scene),
        ReferenceBrdf::True,
        &Progress::new(),
    )
    .unwrap()
    .rgba
}

/// A deterministic uniform in [0, 1) from a counter.
fn uniform(i: u64) -> f32 {
    (mix64(i) >> 40) as f32 / (1u64 << 24) as f32
}

#[test]
fn a_bsdf_ray_along_a_light_sample_sees_its_radiance_and_pdf() {
    let area = |shape, size_y| Light::Area {
        position: [0.3, 0.2, 2.0],
        axis_u: [1.0, 0.0, 0.0],
        axis_v: [0.0, 1.0, 0.0],
        shape,
        size_x: 0.8,
        size_y,
        power: 50.0,
        color: [1.0, 0.9, 0.8],
        visible_camera: false,
    };
    let lights = vec![
        area(AreaShape::Rectangle, Some(0.4)),
        area(AreaShape::Ellipse, Some(0.5)),
        Light::Point {
            position: [-0.5, 0.4, 1.5],
            power: 100.0,
            color: [1.0; 3],
            radius: 0.2,
        },
        Light::Spot {
            position: [0.6, -0.4, 1.8],
            direction: [-0.3, 0.2, -1.0],
            power: 300.0,
            color: [1.0; 3],
            radius: 0.15,
            spot_size: 1.2,
            spot_blend: 0.4,
        },
        Light::Sun {
            direction: [0.3, 0.2, -1.0],
            strength: 3.0,
            color: [1.0; 3],
            angle: 0.2,
        },
    ];
    let mut scene = spheres(300.0);
    scene.lights = lights;
    for area_sampling in [AreaSampling::SolidAngle, AreaSampling::Area] {
        let mut set = LightSet::new(&scene, LightGrouping::All);
        set.set_area_sampling(area_sampling);
        let (p, n) = (glam::Vec3::new(0.1, 0.0, 0.0), glam::Vec3::Z);
        let origin = p + n * 1e-4;
        let mut checked = vec![0u32; set.len()];
        for (emitter, count) in checked.iter_mut().enumerate() {
            for i in 0..2000u64 {
                let (u1, u2) = (uniform(2 * i), uniform(2 * i + 1));
                let Some(s) = set.sample(emitter, p, n, u1, u2) else {
                    continue;
                };
                let Some(pdf) = s.pdf else {
                    continue;
                };
                if n.dot(s.wi) <= 0.0 || s.radiance_over_pdf == Rgb::ZERO || !pdf.is_finite() {
                    continue;
                }
                let mut seen = None;
                set.emitted_along(p, n, origin, s.wi, None, |e, radiance, pdf| {
                    if e == emitter {
                        seen = Some((radiance, pdf));
                    }
                });
                let (radiance, bsdf_pdf) = seen.unwrap_or_else(|| {
                    panic!(
                        "emitter {emitter}: a ray along its sample {:?} meets nothing",
                        s.wi
                    )
                });
                // Directions at a light's very rim may round either way.
                let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-12);
                assert!(
                    rel(bsdf_pdf, pdf) < 2e-3,
                    "emitter {emitter}: pdf {bsdf_pdf} vs {pdf}"
                );
                let w = radiance / bsdf_pdf;
                assert!(
                    rel(w.x, s.radiance_over_pdf.x) < 2e-3,
                    "emitter {emitter}: radiance/pdf {w:?} vs {:?}",
                    s.radiance_over_pdf
                );
                *count += 1;
            }
        }
        println!("{area_sampling:?}: light samples checked per emitter {checked:?}");
        assert!(checked.iter().all(|c| *c > 100), "{checked:?}");
    }
}

#[test]
fn the_weights_keep_the_image_unbiased_whatever_the_light_sampling() {
    // A dimmer sun than the firefly test's: cosine sampling of a 4000 sun would leave the
    // comparison too noisy to see a percent of bias.
    let scene = spheres(200.0);
    let spp = 512;
    // Two seeds per configuration: their per-pixel differences estimate the standard error
    // of the pair's mean image mean, √(Σ (aᵢ − bᵢ)²) / (2N) over the N channel values.
    let run = |area, world| {
        let a = render(&scene, spp, 1, area, world);
        let b = render(&scene, spp, 2, area, world);
        let n = (a.len() / 4 * 3) as f64;
        let sq: f64 = a
            .chunks(4)
            .zip(b.chunks(4))
            .map(|(p, q)| (0..3).map(|k| ((p[k] - q[k]) as f64).powi(2)).sum::<f64>())
            .sum();
        (0.5 * (mean(&a) + mean(&b)), sq.sqrt() / (2.0 * n))
    };
    let (m1, n1) = run(AreaSampling::SolidAngle, WorldSampling::Mixture);
    let (m2, n2) = run(AreaSampling::Area, WorldSampling::Cosine);
    let diff = (m1 - m2).abs() / m1;
    let noise = (n1 * n1 + n2 * n2).sqrt() / m1;
    println!(
        "image mean, solid-angle + warped world {m1:.5} vs area + cosine world {m2:.5}: \
         {:.3} % apart, standard error {:.3} %",
        100.0 * diff,
        100.0 * noise
    );
    assert!(m1 > 0.0 && m1.is_finite());
    // Four standard errors of the difference.
    assert!(diff <= 4.0 * noise, "{diff} vs noise {noise}");
}

/// The light samples a bounce vertex takes (`bounce_light_samples`) change only the noise:
/// its next-event estimation and the BSDF rays that meet emitters from it are weighed with
/// that vertex's own count, so the image's mean is the same with one sample past the eye as
/// with as many as the eye takes, at three bounces where the later vertices carry much of
/// the light. The two are rendered with the same seeds, so their eye rays and the eye's
/// light samples coincide and the per-pixel differences measure the change alone (a
/// paired comparison: weights built with the eye's count at the later vertices put the
/// means more than twenty standard errors of the differences apart).
#[test]
fn light_samples_past_the_eye_change_the_noise_not_the_mean() {
    let scene = spheres(200.0);
    let render_at = |later: Option<u32>, seed: u64| {
        let settings = BakeSettings {
            light_samples: 4,
            bounce_light_samples: later,
            bounces: 3,
            ..settings(256, seed)
        };
        let (ctx, _) = BakeContext::new(&scene, &settings).unwrap();
        render_with_context(
            &ctx,
            &materials(&scene),
            ReferenceBrdf::True,
            &Progress::new(),
        )
        .unwrap()
        .rgba
    };
    let (mut sum4, mut diffs) = (0.0f64, Vec::new());
    for seed in 1..=2 {
        let (a, b) = (render_at(None, seed), render_at(Some(1), seed));
        for (p, q) in a.chunks(4).zip(b.chunks(4)) {
            for k in 0..3 {
                sum4 += p[k] as f64;
                diffs.push(p[k] as f64 - q[k] as f64);
            }
        }
    }
    let n = diffs.len() as f64;
    let m4 = sum4 / n;
    let d = diffs.iter().sum::<f64>() / n;
    let var = diffs.iter().map(|x| (x - d).powi(2)).sum::<f64>() / (n - 1.0);
    let se = (var / n).sqrt();
    println!(
        "image mean at three bounces with 4 light samples at every vertex {m4:.5}; with 1 \
         past the eye {:.3} % lower, standard error of the paired difference {:.3} %",
        100.0 * d / m4,
        100.0 * se / m4
    );
    assert!(m4 > 0.0 && m4.is_finite() && se.is_finite());
    assert!(d.abs() <= 4.0 * se, "{d} vs standard error {se}");
}

/// A converged image robust to the fireflies of the estimator itself: the per-pixel median
/// of `renders` independent renders of `spp` samples each (a rare huge sample moves one
/// render, not the median).
fn median_render(scene: &Scene, renders: u64, spp: u32) -> Vec<f32> {
    let images: Vec<Vec<f32>> = (0..renders)
        .map(|k| {
            render(
                scene,
                spp,
                100 + k,
                AreaSampling::SolidAngle,
                WorldSampling::Mixture,
            )
        })
        .collect();
    (0..images[0].len())
        .map(|i| {
            let mut v: Vec<f32> = images.iter().map(|im| im[i]).collect();
            v.sort_by(|a, b| a.partial_cmp(b).unwrap());
            0.5 * (v[v.len() / 2 - 1] + v[v.len() / 2])
        })
        .collect()
}

#[test]
fn no_relit_pixel_rises_far_above_the_converged_brightest() {
    let scene = spheres(4000.0);
    let (stack, _) = bake(&scene, &settings(16, 3), &Progress::new()).unwrap();
    let relit = common::relight_at_bake_materials(&stack, &scene);
    let converged = median_render(&scene, 8, 64);
    let (r, c) = (brightest(&relit), brightest(&converged));
    // Share of the squared error the ten worst pixels hold (a firefly-dominated image has
    // nearly all of it there).
    let mut err: Vec<f64> = relit
        .chunks(4)
        .zip(converged.chunks(4))
        .map(|(a, b)| (0..3).map(|k| ((a[k] - b[k]) as f64).powi(2)).sum())
        .collect();
    let total: f64 = err.iter().sum();
    err.sort_by(|a, b| b.partial_cmp(a).unwrap());
    let top10: f64 = err[..10].iter().sum::<f64>() / total;
    let at = relit
        .chunks(4)
        .position(|p| p[..3].iter().cloned().fold(0.0, f32::max) == r)
        .unwrap_or(0) as u32;
    println!(
        "brightest pixel: relit bake (16 spp) {r:.3} at ({}, {}), converged (median of 8 × 64 \
         spp) {c:.3}, ratio {:.3}; ten worst pixels hold {:.1} % of the squared error; means \
         {:.4} / {:.4}",
        at % W,
        at / W,
        r / c,
        100.0 * top10,
        mean(&relit),
        mean(&converged)
    );
    assert!(c > 0.0 && r.is_finite());
    assert!(r <= 1.5 * c, "relit brightest {r} vs converged {c}");
}
