//! `relume bench bake SCENE`, `relume bench relight STACK.exr` and `relume bench denoise
//! SCENE`: figures, as JSON.

mod bake;
mod denoise;
mod gpu_relight;

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use clap::Subcommand;
use relume_engine::materials::{resolve_materials, MaterialsFile};
use relume_engine::relight::{bandwidth::measure_read_bandwidth, CpuRelighter};
use relume_engine::scene::file::load_scene;
use relume_engine::stack::{
    bases::StackBases,
    tiled::{file::read_tiled, TiledStack},
};
use relume_engine::{RelumeError, Rgb};
use relume_gpu::{DeviceKind, GpuOptions, Relighter};
use serde_json::json;

use super::relight::{device_error, Device};
use bake::bench_bake;

use crate::options::BakeOptions;

#[derive(Subcommand)]
pub enum Bench {
    /// Effective bake rays/s against raw obvhs closest-hit/occlusion rays/s on the same rays.
    Bake {
        scene: PathBuf,
        #[command(flatten)]
        options: BakeOptions,
        #[arg(long)]
        json: bool,
    },
    /// Full and incremental relight times against the memory-bandwidth bound.
    Relight {
        stack: PathBuf,
        /// Timed repetitions (the median is reported).
        #[arg(long, default_value_t = 20)]
        repeats: usize,
        /// Relight device. On the GPU: upload, edit-to-image, kernel (timestamp queries)
        /// and read-back times.
        #[arg(long, value_enum, default_value = "cpu")]
        device: Device,
        #[arg(long)]
        json: bool,
    },
    /// The shown image's cost per size: pixel features traced, albedo per edit, and
    /// OpenImageDenoise (first run and later ones; found as `relume relight` finds it).
    Denoise {
        /// The scene whose features are traced (at each size).
        scene: PathBuf,
        /// Image sizes, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "512x512,1920x1080")]
        sizes: Vec<String>,
        /// Timed repetitions after the first run (min and median are reported).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// OIDN's CPU device even where it would take a GPU.
        #[arg(long)]
        cpu: bool,
        /// OIDN's filter quality: high (its default), balanced or fast.
        #[arg(long, default_value = "high")]
        quality: String,
        #[arg(long)]
        json: bool,
    },
}

pub fn run(bench: Bench) -> Result<(), RelumeError> {
    match bench {
        Bench::Bake {
            scene,
            options,
            json,
        } => {
            let scene = load_scene(&scene)?;
            let figures = bench_bake(&scene, &options.settings(scene.resolution)?)?;
            if json {
                super::print_json(&figures);
            } else {
                println!(
                    "bake: {:.2} Mrays/s effective, raw obvhs {:.2} Mrays/s on the same rays: {:.0} %",
                    figures.effective_rays_per_second / 1e6,
                    figures.raw_rays_per_second / 1e6,
                    figures.ratio * 100.0
                );
            }
            Ok(())
        }
        Bench::Relight {
            stack,
            repeats,
            device,
            json,
        } => bench_relight(&stack, repeats.max(1), device, json),
        Bench::Denoise {
            scene,
            sizes,
            repeats,
            cpu,
            quality,
            json,
        } => {
            let figures = denoise::bench_denoise(
                &load_scene(&scene)?,
                &sizes,
                repeats.max(1),
                cpu,
                &quality,
            )?;
            print_figures(&figures, json);
            Ok(())
        }
    }
}

/// Names of the stack's editable regions, in editable order (the order of the coefficients).
fn editable_region_names(stack: &TiledStack) -> Vec<String> {
    stack
        .header
        .regions
        .iter()
        .filter(|r| r.editable)
        .map(|r| r.name.clone())
        .collect()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn minimum(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

fn bench_relight(
    path: &std::path::Path,
    repeats: usize,
    device: Device,
    json: bool,
) -> Result<(), RelumeError> {
    let t = Instant::now();
    let stack = read_tiled(path)?;
    let load_ms = t.elapsed().as_secs_f64() * 1e3;
    let materials = resolve_materials(&stack.header.regions, &MaterialsFile::default())?;
    let coefs = StackBases::from_header(&stack.header)?.coefficients(&materials)?;
    let editable_names = editable_region_names(&stack);
    let stack = Arc::new(stack);
    let mut reason = "CPU: chosen by the caller".to_string();
    if !matches!(device, Device::Cpu) {
        let options = GpuOptions {
            timestamps: true,
            ..Default::default()
        };
        let mut chosen = Relighter::with_options(stack.clone(), device.preference(), options)
            .map_err(|e| device_error(device, e))?;
        reason = chosen.device_reason().to_string();
        if let Some(gpu) = chosen.gpu() {
            let figures = gpu_relight::figures(gpu, &coefs, &editable_names, repeats, &reason)?;
            print_figures(&figures, json);
            return Ok(());
        }
        debug_assert_eq!(chosen.device(), DeviceKind::Cpu);
    }
    let mut figures = cpu_relight_figures(stack, repeats, &reason)?;
    figures["load_ms"] = json!(load_ms);
    print_figures(&figures, json);
    Ok(())
}

/// The CPU relight figures of `relume bench relight` for `stack` at its bake-time materials:
/// median full relight over `repeats`, one incremental edit per editable region, and the
/// memory-bandwidth bound. `reason` says why the CPU was chosen.
pub fn cpu_relight_figures(
    stack: Arc<TiledStack>,
    repeats: usize,
    reason: &str,
) -> Result<serde_json::Value, RelumeError> {
    let repeats = repeats.max(1);
    let stack_bytes = stack.sample_bytes();
    let stack_memory = stack.memory_bytes();
    let dense_bytes = stack.dense_sample_bytes();
    let tile_entries = stack.entry_count();
    let (width, height, layers) = (stack.header.width, stack.header.height, stack.layers.len());
    let editable_names = editable_region_names(&stack);
    let materials = resolve_materials(&stack.header.regions, &MaterialsFile::default())?;
    let bases = StackBases::from_header(&stack.header)?;
    let coefs = bases.coefficients(&materials)?;
    let mut relighter = CpuRelighter::from_tiled(stack)?;
    relighter.relight(&coefs)?;
    let relight_own = relighter.own_bytes();
    // The bound's bandwidth is measured before and after the full relights: on a shared or
    // virtual machine the memory's speed can change from one minute to the next, and a
    // ratio is only meaningful against the speed the relights ran at.
    let bandwidth_buffer = (256usize << 20).max(2 * stack_bytes);
    let bandwidth_before = measure_read_bandwidth(bandwidth_buffer, 5);
    let mut full = Vec::with_capacity(repeats);
    let mut full_bytes = 0;
    for i in 0..repeats {
        let mut c = coefs.clone();
        // Perturb the weights so no step can be skipped as unchanged.
        for region in &mut c {
            for v in region.iter_mut() {
                *v *= 1.0 + 1e-3 * (i % 7) as f32;
            }
        }
        let t = Instant::now();
        relighter.relight(&c)?;
        full.push(t.elapsed().as_secs_f64() * 1e3);
        full_bytes = relighter.last_stats().bytes_read;
    }
    // Again right after them, so the two measurements bracket the full relights the bound is
    // for; the faster is the bound (the stricter one), and both are reported.
    let bandwidth_after = measure_read_bandwidth(bandwidth_buffer, 5);
    let bandwidth = bandwidth_before.max(bandwidth_after);
    // One incremental edit per editable region: only the layers holding it are re-summed.
    let mut per_region = Vec::new();
    for (region, info) in editable_names.iter().enumerate() {
        let mut times = Vec::with_capacity(repeats);
        let mut bytes = 0;
        for i in 0..repeats {
            let c: Vec<Rgb> = coefs[region]
                .iter()
                .map(|v| *v * (1.0 + 1e-3 * (i % 5 + 1) as f32))
                .collect();
            let t = Instant::now();
            relighter.relight_region(region, &c)?;
            times.push(t.elapsed().as_secs_f64() * 1e3);
            bytes = relighter.last_stats().bytes_read;
        }
        per_region.push(json!({"region": info, "ms": median(times), "bytes_read": bytes}));
    }
    // The first edit of a region keeps where its entries are (two bytes per entry).
    let relight_own_after_edits = relighter.own_bytes();
    // One subsurface slider move per translucent region: Subsurface Scale changes, so the
    // s_k(σ) of three channels are projected again, then the region's layers re-summed.
    let mut subsurface_slider = Vec::new();
    for (region, info) in editable_names.iter().enumerate() {
        let Some((sss, _)) = &bases.subsurface[region] else {
            continue;
        };
        let relume_engine::brdf::MaterialSpec::Principled(base) = &materials[region] else {
            continue;
        };
        let (mut coef_ms, mut relight_ms) = (Vec::new(), Vec::new());
        for i in 0..repeats {
            let mut m = *base;
            m.subsurface.weight = m.subsurface.weight.max(0.5);
            m.subsurface.scale *= 1.0 + 0.05 * (i % 9) as f32 - 0.2;
            let t = Instant::now();
            let c = bases
                .region_coefficients(region, &relume_engine::brdf::MaterialSpec::Principled(m))?;
            coef_ms.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            relighter.relight_region(region, &c)?;
            relight_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        let (c, r) = (median(coef_ms), median(relight_ms));
        subsurface_slider.push(json!({
            "region": info,
            "subsurface_bases": sss.count(),
            "coefficients_ms": c,
            "relight_ms": r,
            "total_ms": c + r,
        }));
    }
    let bound_ms = full_bytes as f64 / (bandwidth * 1e9) * 1e3;
    // The bound above counts the summed layers' samples. A full relight also walks every
    // tile's table of entries (one row per entry, skipped or not) to find them: bytes it
    // reads too, reported beside it rather than folded in, so the sample-only figure stays
    // comparable with earlier runs.
    let table_bytes = tile_entries * std::mem::size_of::<relume_engine::stack::tiled::TileLayer>();
    let bound_with_tables_ms = (full_bytes + table_bytes) as f64 / (bandwidth * 1e9) * 1e3;
    let full_min_ms = minimum(&full);
    let full_ms = median(full);
    // The fastest single-region edit (NaN when the stack has no editable region).
    let incremental_ms = per_region
        .iter()
        .filter_map(|r| r["ms"].as_f64())
        .fold(f64::NAN, f64::min);
    let figures = json!({
        "command": "bench relight",
        "device": "cpu",
        "device_reason": reason,
        "threads": rayon::current_num_threads(),
        "width": width,
        "height": height,
        "layers": layers,
        "stack_sample_bytes": stack_bytes,
        "stack_memory_bytes": stack_memory,
        "dense_equivalent_sample_bytes": dense_bytes,
        "tile_entries": tile_entries,
        "relighter_own_bytes": relight_own,
        "relight_memory_bytes": stack_memory + relight_own,
        "relight_memory_over_stack": (stack_memory + relight_own) as f64 / stack_memory.max(1) as f64,
        "relighter_own_bytes_after_edits": relight_own_after_edits,
        "relight_memory_over_stack_after_edits":
            (stack_memory + relight_own_after_edits) as f64 / stack_memory.max(1) as f64,
        "full_ms": full_ms,
        "full_min_ms": full_min_ms,
        "full_bytes_read": full_bytes,
        "fastest_incremental_ms": incremental_ms,
        "incremental_per_region": per_region,
        "subsurface_slider": subsurface_slider,
        "bandwidth_gb_s": bandwidth,
        "bandwidth_gb_s_before_and_after": [bandwidth_before, bandwidth_after],
        "bandwidth_bound_ms": bound_ms,
        "full_over_bound": full_ms / bound_ms,
        "full_min_over_bound": full_min_ms / bound_ms,
        "entry_table_bytes": table_bytes,
        "bandwidth_bound_with_tables_ms": bound_with_tables_ms,
        "full_min_over_bound_with_tables": full_min_ms / bound_with_tables_ms,
        "fastest_incremental_over_full": incremental_ms / full_ms,
    });
    Ok(figures)
}

fn print_figures(figures: &serde_json::Value, json: bool) {
    if json {
        super::print_json(figures);
    } else {
        println!(
            "{}",
            serde_json::to_string_pretty(figures).unwrap_or_default()
        );
    }
}
