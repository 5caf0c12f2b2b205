//! The CPU relighter on the tiled layout: it matches a naive f64 sum of the dense layers on
//! edge tiles, grey/RGB and f16/f32; it shares the stack rather than copying it (memory
//! accounted in bytes); v1 and v2 files relight alike.

use crate::common;

use std::sync::Arc;

use common::synthetic_stack::*;
use relume_engine::relight::CpuRelighter;
use relume_engine::stack::tiled::{file::read_tiled, file::write_tiled, TiledStack};
use relume_engine::stack::{exr_file::write_stack, Precision, TransferStack};
use relume_engine::Rgb;

fn stack(w: usize, h: usize, precision: Precision, seed: u64) -> TransferStack {
    let mut rng = Rng::new(seed);
    let layers = one_bounce_keys(3)
        .into_iter()
        .enumerate()
        .map(|(i, key)| {
            let ch = if i % 3 == 0 { 3 } else { 1 };
            let zero_rows = match i % 4 {
                0 => 0..0,
                1 => 0..h.min(10),
                2 => h.min(5)..h.min(30),
                _ => h.min(20)..h,
            };
            random_layer(
                &mut rng,
                key,
                w,
                h,
                ch,
                precision,
                zero_rows,
                (i * 7) % w.max(1),
            )
        })
        .collect();
    let mut header = header(w as u32, h as u32);
    header.precision = precision;
    TransferStack { header, layers }
}

/// `Σ weight · layer` in f64 over the dense layers (the shared naive reference).
fn naive(stack: &TransferStack, coefs: &[Vec<Rgb>]) -> Vec<f64> {
    reference(stack, coefs).into_iter().flatten().collect()
}

fn rel_l2(image: &[f32], reference: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (px, r) in image.chunks(4).zip(reference.chunks(3)) {
        for c in 0..3 {
            num += (px[c] as f64 - r[c]).powi(2);
            den += r[c] * r[c];
        }
    }
    (num / den.max(1e-30)).sqrt()
}

fn coefs(rng: &mut Rng) -> Vec<Vec<Rgb>> {
    (0..2)
        .map(|_| {
            (0..3)
                .map(|_| {
                    Rgb::new(
                        rng.range(-0.5, 1.0),
                        rng.range(0.0, 1.0),
                        rng.range(0.0, 2.0),
                    )
                })
                .collect()
        })
        .collect()
}

#[test]
fn tiled_relight_matches_a_naive_dense_sum_on_edge_tiles() {
    for (i, (w, h, precision)) in [
        (37, 21, Precision::F16),
        (37, 21, Precision::F32),
        (16, 48, Precision::F16),
        (5, 3, Precision::F32),
    ]
    .into_iter()
    .enumerate()
    {
        let dense = stack(w, h, precision, 10 + i as u64);
        let tiled = Arc::new(TiledStack::from_dense(&dense).unwrap());
        let mut r = CpuRelighter::from_tiled(tiled).unwrap();
        let mut rng = Rng::new(99);
        let c = coefs(&mut rng);
        let err = rel_l2(r.relight(&c).unwrap(), &naive(&dense, &c));
        assert!(err < 1e-6, "{w}×{h} {precision:?}: full {err}");
        let mut c2 = c.clone();
        c2[1] = coefs(&mut rng)[1].clone();
        let err = rel_l2(r.relight_region(1, &c2[1]).unwrap(), &naive(&dense, &c2));
        assert!(err < 1e-6, "{w}×{h} {precision:?}: incremental {err}");
        assert!(r.last_stats().incremental);
        assert!(r.image().chunks(4).all(|p| p[3] == 1.0));
    }
}

#[test]
fn relighter_shares_the_stack_and_adds_little_memory() {
    // Enough layers that the image is small beside them, as in a real bake.
    let dense = stack(96, 80, Precision::F16, 3);
    let tiled = Arc::new(TiledStack::from_dense(&dense).unwrap());
    let r = CpuRelighter::from_tiled(tiled.clone()).unwrap();
    assert!(
        Arc::ptr_eq(r.stack(), &tiled),
        "the relighter copied the stack"
    );
    let stack_bytes = tiled.memory_bytes();
    assert!(stack_bytes >= tiled.sample_bytes());
    let total = stack_bytes + r.own_bytes();
    assert!(
        total as f64 <= 1.2 * stack_bytes as f64,
        "relight memory {total} B for a stack of {stack_bytes} B"
    );
    assert!(tiled.sample_bytes() <= tiled.dense_sample_bytes());
    assert!(tiled.stored_layer_count() <= tiled.layers.len());
}

#[test]
fn v1_and_v2_files_relight_alike() {
    let dir = tempfile::tempdir().unwrap();
    let dense = stack(37, 21, Precision::F16, 5);
    let (v1, v2) = (dir.path().join("v1.exr"), dir.path().join("v2.exr"));
    write_stack(&v1, &dense).unwrap();
    write_tiled(&v2, &TiledStack::from_dense(&dense).unwrap()).unwrap();
    let c = coefs(&mut Rng::new(4));
    let mut a = CpuRelighter::from_tiled(Arc::new(read_tiled(&v1).unwrap())).unwrap();
    let mut b = CpuRelighter::from_tiled(Arc::new(read_tiled(&v2).unwrap())).unwrap();
    let mut d = CpuRelighter::new(Arc::new(dense)).unwrap();
    let ia = a.relight(&c).unwrap().to_vec();
    assert_eq!(ia, b.relight(&c).unwrap());
    assert_eq!(ia, d.relight(&c).unwrap());
}
