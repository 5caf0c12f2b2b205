//! `relume bench denoise SCENE`: what the shown image costs on top of a relight, per image
//! size — the pixel features traced once per loaded stack, the albedo recomputed at each
//! edit, and OpenImageDenoise's first run (its filter set up) and later ones.
//!
//! OIDN's time follows the pixel count, not the picture, so the colour here is a noisy
//! image made from the features (albedo times a cosine, times seeded noise) rather than a
//! bake at every size: the figures need the scene only for its features.

use std::time::Instant;

use relume_denoise::oidn::{DeviceChoice, LibrarySearch, Quality};
use relume_engine::features::{albedo_of, PixelFeatures, FEATURE_SAMPLES_PER_AXIS};
use relume_engine::materials::{resolve_materials, MaterialsFile};
use relume_engine::scene::Scene;
use relume_engine::stack::RegionInfo;
use relume_engine::{RelumeError, Result};
use serde_json::json;

use super::{median, minimum};
use crate::options::parse_resolution;

/// Runs the benchmark; returns the figures as JSON.
pub fn bench_denoise(
    scene: &Scene,
    sizes: &[String],
    repeats: usize,
    cpu_only: bool,
    quality: &str,
) -> Result<serde_json::Value> {
    let quality = Quality::parse(quality).map_err(|e| RelumeError::invalid("--quality", e))?;
    let search = LibrarySearch::with_dirs(vec![]);
    let choice = if cpu_only {
        DeviceChoice::Cpu
    } else {
        DeviceChoice::Default
    };
    let api = search
        .open()
        .map_err(|e| RelumeError::invalid("bench denoise", e))?;
    let regions: Vec<RegionInfo> = scene
        .regions
        .iter()
        .map(|r| RegionInfo {
            name: r.name.clone(),
            editable: r.editable,
            material: r.material.clone(),
            basis: None,
            textured: false,
            subsurface: None,
            principled_basis: None,
            principled_basis_with_bake_lobe: None,
        })
        .collect();
    let materials = resolve_materials(&regions, &MaterialsFile::default())?;
    let mut rows = Vec::new();
    let mut device = String::new();
    let mut version = String::new();
    for size in sizes {
        let res = parse_resolution(size)?;
        let (w, h) = (res.width, res.height);
        let mut scene = scene.clone();
        scene.resolution = res;
        let t = Instant::now();
        let features = PixelFeatures::trace(&scene, w, h, FEATURE_SAMPLES_PER_AXIS)?;
        let features_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut albedo_ms = Vec::new();
        let mut albedo = Vec::new();
        for _ in 0..repeats {
            let t = Instant::now();
            albedo = albedo_of(&features, &materials)?;
            albedo_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let colour = noisy_colour(&albedo, features.normal());
        // A fresh device per size, so "first" includes making the filter as a load does.
        let mut oidn = relume_denoise::oidn::OidnDenoiser::new(api, choice)
            .map_err(|e| RelumeError::invalid("bench denoise", e))?;
        oidn.set_quality(quality);
        device = oidn.device_kind().to_string();
        version = oidn.version_text();
        let run = |oidn: &mut relume_denoise::oidn::OidnDenoiser| -> Result<f64> {
            let t = Instant::now();
            oidn.denoise(
                &colour,
                Some((&albedo, features.normal())),
                true,
                w as usize,
                h as usize,
            )
            .map_err(|e| RelumeError::invalid("bench denoise", e))?;
            Ok(t.elapsed().as_secs_f64() * 1e3)
        };
        let first_ms = run(&mut oidn)?;
        let mut times = Vec::new();
        for _ in 0..repeats {
            times.push(run(&mut oidn)?);
        }
        rows.push(json!({
            "width": w,
            "height": h,
            "features_trace_ms": features_ms,
            "albedo_ms_min": minimum(&albedo_ms),
            "albedo_ms_median": median(albedo_ms.clone()),
            "oidn_first_ms": first_ms,
            "oidn_ms_min": minimum(&times),
            "oidn_ms_median": median(times.clone()),
            "repeats": repeats,
        }));
    }
    Ok(json!({
        "command": "bench denoise",
        "quality": quality.as_str(),
        "library": api.path,
        "version": version,
        "device": device,
        "threads": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        "feature_samples_per_pixel": format!(
            "4, or {} where a pixel is not one untextured surface",
            FEATURE_SAMPLES_PER_AXIS * FEATURE_SAMPLES_PER_AXIS
        ),
        "sizes": rows,
    }))
}

/// A noisy HDR image from the features: albedo × a cosine × noise (seeded, in [0, 2)).
fn noisy_colour(albedo: &[f32], normal: &[f32]) -> Vec<f32> {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    albedo
        .chunks_exact(3)
        .zip(normal.chunks_exact(3))
        .flat_map(|(a, n)| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let noise = (state >> 40) as f32 / (1u64 << 24) as f32 * 2.0;
            let shade = n[2].abs() * 0.8 + 0.2;
            [
                a[0] * shade * noise,
                a[1] * shade * noise,
                a[2] * shade * noise,
            ]
        })
        .collect()
}
