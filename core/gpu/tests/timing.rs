//! A short timing of the tiled relight, GPU (forced: lavapipe where there is no real GPU)
//! against the CPU in the same process, for `docs/measurements.md`. Ignored by default: run
//! it alone, in release (the CPU sum is several times slower in the test profile):
//!
//! `RELUME_TIMING_SIZE=256 cargo test --release -p relume-gpu --test timing -- --ignored --nocapture`

mod common;

use std::time::Instant;

use common::*;
use relume_engine::relight::CpuRelighter;
use relume_engine::stack::Precision;
use relume_engine::Rgb;
use relume_gpu::{GpuOptions, GpuRelighter};

const REPEATS: usize = 7;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

/// Median ms of `REPEATS` calls of `f(i)`.
fn time(mut f: impl FnMut(usize)) -> f64 {
    median(
        (0..REPEATS)
            .map(|i| {
                let t = Instant::now();
                f(i);
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

/// Coefficients perturbed by step `i`, so no relight repeats the previous one.
fn perturbed(coefs: &[Rgb], i: usize) -> Vec<Rgb> {
    coefs
        .iter()
        .map(|v| *v * (1.0 + 1e-3 * (i % 5 + 1) as f32))
        .collect()
}

#[test]
#[ignore = "a timing for docs/measurements.md; run alone, in release"]
fn tiled_relight_gpu_against_cpu() {
    let Some(adapter) = gpu_or_skip("tiled_relight_gpu_against_cpu") else {
        return;
    };
    let size: u32 = std::env::var("RELUME_TIMING_SIZE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(128);
    let (name, stack) = asset_tiled_sized("cornell", size, size, Precision::F16);
    let (_, coefs) = default_coefs(&stack.header);

    let t = Instant::now();
    let options = GpuOptions {
        timestamps: true,
        ..Default::default()
    };
    let mut gpu = GpuRelighter::new(stack.clone(), &adapter, options).unwrap();
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut cpu = CpuRelighter::from_tiled(stack.clone()).unwrap();
    // Untimed first relights: the driver finishes compiling the pipeline on first use.
    gpu.relight(&coefs).unwrap();
    cpu.relight(&coefs).unwrap();
    let scaled = |i: usize| -> Vec<Vec<Rgb>> { coefs.iter().map(|c| perturbed(c, i)).collect() };
    let mut kernel_full = Vec::new();
    let gpu_full = time(|i| {
        gpu.relight(&scaled(i)).unwrap();
        kernel_full.extend(gpu.last_timings().kernel_ms);
    });
    let cpu_full = time(|i| {
        cpu.relight(&scaled(i)).unwrap();
    });
    let regions = gpu.editable_count();
    let (mut gpu_inc, mut cpu_inc, mut inc_bytes) = (Vec::new(), Vec::new(), Vec::new());
    let mut kernel_inc = Vec::new();
    for (region, base) in coefs.iter().enumerate() {
        gpu_inc.push(time(|i| {
            gpu.relight_region(region, &perturbed(base, i)).unwrap();
            kernel_inc.extend(gpu.last_timings().kernel_ms);
        }));
        cpu_inc.push(time(|i| {
            cpu.relight_region(region, &perturbed(base, i)).unwrap();
        }));
        inc_bytes.push(cpu.last_stats().bytes_read);
    }
    let read_back = median(
        (0..REPEATS)
            .map(|_| gpu.time_read_back().unwrap())
            .collect(),
    );
    let e = rel_l2(gpu.image(), cpu.image());
    let m = gpu.memory();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let kernel = |v: Vec<f64>| {
        if v.is_empty() {
            "not timed (no TIMESTAMP_QUERY)".to_string()
        } else {
            format!("{:.3} ms median", median(v))
        }
    };
    eprintln!(
        "{name} on {}: {} layers, {} tile entries, {} B of values ({} B dense)\n\
         GPU memory: stack {} B (values {} + tables {}), image {} B, weights {} B, read-back {} B\n\
         build + upload {build_ms:.1} ms (upload {:.1} ms)\n\
         full relight: GPU {gpu_full:.2} ms (read-back {read_back:.2} ms of it), CPU {cpu_full:.2} ms\n\
         incremental, mean over {regions} regions of the median: GPU {:.2} ms, CPU {:.2} ms \
         (bytes read per edit: {inc_bytes:?})\n\
         per region GPU {gpu_inc:.2?} ms, CPU {cpu_inc:.2?} ms\n\
         compute pass alone: full {}, incremental {}\n\
         last images GPU vs CPU relative L2 {e:.2e}",
        gpu.adapter(),
        stack.layers.len(),
        stack.entry_count(),
        stack.sample_bytes(),
        stack.dense_sample_bytes(),
        m.stack(),
        m.values,
        m.tables,
        m.image,
        m.weights,
        m.readback,
        gpu.upload_ms(),
        mean(&gpu_inc),
        mean(&cpu_inc),
        kernel(kernel_full),
        kernel(kernel_inc),
    );
    assert!(e <= TOLERANCE);
}
