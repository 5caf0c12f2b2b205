//! Relight timing at the paper's size, printed (not asserted: timings depend on the machine
//! and on what else runs). Run with `--nocapture` to see the figures:
//! `cargo test -p relume-engine --test engine relight_perf -- --nocapture`
//! (`--ignored` adds the 183-layer stack).
//!
//! What is asserted is what must hold anywhere: the incremental update reads fewer bytes
//! than the full sum, and both agree.

use crate::common;

use std::sync::Arc;
use std::time::Instant;

use common::synthetic_stack::*;
use relume_engine::relight::{bandwidth::measure_read_bandwidth, CpuRelighter};
use relume_engine::stack::{Precision, TransferStack};

/// A 512² f16 stack of the first `n` one-bounce keys of two editable regions with 6 bases
/// (the paper's configuration), 1 in 3 of them RGB (the paper: 29 of 84), dense.
fn paper_stack(n: usize) -> TransferStack {
    let (w, h) = (512, 512);
    let mut rng = Rng::new(42);
    let layers = one_bounce_keys(6)
        .into_iter()
        .take(n)
        .enumerate()
        .map(|(i, key)| {
            let ch = if i % 3 == 0 { 3 } else { 1 };
            random_layer(&mut rng, key, w, h, ch, Precision::F16, 0..0, 0)
        })
        .collect();
    TransferStack {
        header: header(w as u32, h as u32),
        layers,
    }
}

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

fn measure(n: usize) {
    let stack = Arc::new(paper_stack(n));
    let grey = stack.layers.iter().filter(|l| l.channels == 1).count();
    let t = Instant::now();
    let mut r = CpuRelighter::new(stack.clone()).unwrap();
    let build_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut rng = Rng::new(1);
    let coefs = random_coefs(&mut rng, &[6, 6]);
    r.relight(&coefs).unwrap();

    let full: Vec<f64> = (0..15)
        .map(|_| {
            let t = Instant::now();
            r.relight(&coefs).unwrap();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let full_stats = r.last_stats();

    // Alternate two materials of region 0; stay below the periodic full re-sum.
    let alt = [random_coefs(&mut rng, &[6]).remove(0), coefs[0].clone()];
    let inc: Vec<f64> = (0..20)
        .map(|i| {
            let t = Instant::now();
            r.relight_region(0, &alt[i % 2]).unwrap();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let inc_stats = r.last_stats();
    assert!(inc_stats.incremental && inc_stats.bytes_read < full_stats.bytes_read);

    let gbs = measure_read_bandwidth(64 << 20, 5);
    let bound_full = full_stats.bytes_read as f64 / (gbs * 1e9) * 1e3;
    let bound_inc = inc_stats.bytes_read as f64 / (gbs * 1e9) * 1e3;
    eprintln!(
        "relight 512², {n} f16 layers ({grey} grey + {} RGB), {} threads, build {build_ms:.1} ms",
        n - grey,
        rayon::current_num_threads()
    );
    eprintln!("  read bandwidth {gbs:.1} GB/s (best of 5 over 64 MiB)");
    eprintln!(
        "  full:        {:.2} ms median ({:.2} min), {} layers, {:.1} MB, bandwidth bound {:.2} ms → {:.2}× bound",
        median_ms(full.clone()),
        full.iter().cloned().fold(f64::INFINITY, f64::min),
        full_stats.layers_summed,
        full_stats.bytes_read as f64 / 1e6,
        bound_full,
        median_ms(full.clone()) / bound_full
    );
    eprintln!(
        "  incremental: {:.2} ms median ({:.2} min), {} layers, {:.1} MB, bandwidth bound {:.2} ms (region 0)",
        median_ms(inc.clone()),
        inc.iter().cloned().fold(f64::INFINITY, f64::min),
        inc_stats.layers_summed,
        inc_stats.bytes_read as f64 / 1e6,
        bound_inc
    );
}

#[test]
fn relight_timing_84_layers() {
    measure(84);
}

#[test]
#[ignore = "183 layers × 512² take ~160 MB and a few seconds to build; run with --ignored"]
fn relight_timing_183_layers() {
    measure(183);
}
