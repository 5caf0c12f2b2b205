//! `relume bench relight --device gpu|auto` on a GPU: upload, full and incremental edits
//! (edit-to-image: weights write + dispatch + read-back, host clock), the kernel alone
//! (timestamp queries, where the adapter has them) and the read-back alone.
//!
//! On a software adapter (lavapipe) the figures say the relight runs, not how fast a GPU
//! is: the summary marks them with `"software_adapter": true` and a note.

use relume_engine::{RelumeError, Rgb};
use relume_gpu::GpuRelighter;
use serde_json::{json, Value};

use super::median;

/// Median edit-to-image ms and median kernel ms (`None` without timestamps) of `repeats`
/// calls of `edit(i)`.
fn time_edits(
    gpu: &mut GpuRelighter,
    repeats: usize,
    mut edit: impl FnMut(&mut GpuRelighter, usize) -> Result<(), RelumeError>,
) -> Result<(f64, Option<f64>), RelumeError> {
    let mut host = Vec::with_capacity(repeats);
    let mut kernel = Vec::with_capacity(repeats);
    for i in 0..repeats {
        let t = std::time::Instant::now();
        edit(gpu, i)?;
        host.push(t.elapsed().as_secs_f64() * 1e3);
        kernel.extend(gpu.last_timings().kernel_ms);
    }
    let kernel = (!kernel.is_empty()).then(|| median(kernel));
    Ok((median(host), kernel))
}

/// The figures of one stack on the GPU relighter `gpu`.
pub fn figures(
    gpu: &mut GpuRelighter,
    coefs: &[Vec<Rgb>],
    editable_names: &[String],
    repeats: usize,
    reason: &str,
) -> Result<Value, RelumeError> {
    let err = |e: relume_gpu::GpuError| e.into_relume();
    // One untimed relight: the driver finishes compiling the pipeline on first use.
    gpu.relight(coefs).map_err(err)?;
    let (full_ms, full_kernel_ms) = time_edits(gpu, repeats, |g, i| {
        let c: Vec<Vec<Rgb>> = coefs
            .iter()
            .map(|r| {
                r.iter()
                    .map(|v| *v * (1.0 + 1e-3 * (i % 7) as f32))
                    .collect()
            })
            .collect();
        g.relight(&c).map(|_| ()).map_err(err)
    })?;
    let full_bytes = gpu.last_stats().bytes_read;
    let mut per_region = Vec::new();
    for (region, name) in editable_names.iter().enumerate() {
        let (ms, kernel_ms) = time_edits(gpu, repeats, |g, i| {
            let c: Vec<Rgb> = coefs[region]
                .iter()
                .map(|v| *v * (1.0 + 1e-3 * (i % 5 + 1) as f32))
                .collect();
            g.relight_region(region, &c).map(|_| ()).map_err(err)
        })?;
        let stats = gpu.last_stats();
        per_region.push(json!({
            "region": name,
            "ms": ms,
            "kernel_ms": kernel_ms,
            "layers": stats.layers_summed,
            "bytes_read": stats.bytes_read,
        }));
    }
    let readback: Vec<f64> = (0..repeats)
        .map(|_| gpu.time_read_back().map_err(err))
        .collect::<Result<_, _>>()?;
    let incremental_ms = per_region
        .iter()
        .filter_map(|r| r["ms"].as_f64())
        .fold(f64::NAN, f64::min);
    let (gpu_bytes, chunks) = gpu.layer_bytes_and_chunks();
    let (width, height) = gpu.size();
    let stack = gpu.stack();
    let software = !gpu.is_real_gpu();
    Ok(json!({
        "command": "bench relight",
        "device": "gpu",
        "device_reason": reason,
        "adapter": gpu.adapter(),
        "software_adapter": software,
        "note": if software {
            Value::from("software adapter: these figures show the GPU path runs and is correct, not GPU speed")
        } else {
            Value::Null
        },
        "width": width,
        "height": height,
        "layers": stack.layers.len(),
        "stack_sample_bytes": stack.sample_bytes(),
        "gpu_layer_bytes": gpu_bytes,
        "gpu_layer_buffers": chunks,
        "upload_ms": gpu.upload_ms(),
        "full_ms": full_ms,
        "full_kernel_ms": full_kernel_ms,
        "full_bytes_read": full_bytes,
        "readback_ms": median(readback),
        "fastest_incremental_ms": incremental_ms,
        "incremental_per_region": per_region,
        "kernel_note": if gpu.timed() {
            Value::Null
        } else {
            Value::from("the adapter has no TIMESTAMP_QUERY feature: kernel times not measured")
        },
    }))
}
