//! The CPU relight against a naive f64 sum, incremental against full, span skipping, errors.

use crate::common;

use std::sync::Arc;

use common::synthetic_stack::*;
use relume_engine::layer_key::{LayerKey, PathVertex};
use relume_engine::relight::{layer_weight, CpuRelighter, FULL_RESUM_EVERY};
use relume_engine::stack::{Layer, LayerSamples, Precision, TransferStack};
use relume_engine::{RelumeError, Rgb};

/// Odd sizes so that the last band is partial (37 = 2·16 + 5 rows) and rows end in SIMD
/// tails (45 = 5·8 + 5 pixels).
const W: usize = 45;
const H: usize = 37;

/// Every one-bounce key of two editable regions with 3 bases, cycling through grey/RGB ×
/// f16/f32, some layers with zero row ranges and zero left columns.
fn mixed_stack(seed: u64) -> TransferStack {
    let mut rng = Rng::new(seed);
    let layers = one_bounce_keys(3)
        .into_iter()
        .enumerate()
        .map(|(i, key)| {
            let ch = if i % 3 == 0 { 3 } else { 1 };
            let prec = if i % 2 == 0 {
                Precision::F16
            } else {
                Precision::F32
            };
            let zero_rows = match i % 4 {
                0 => 0..0,
                1 => 0..10,
                2 => 5..30,
                _ => 20..H,
            };
            random_layer(&mut rng, key, W, H, ch, prec, zero_rows, (i * 7) % 20)
        })
        .collect();
    TransferStack {
        header: header(W as u32, H as u32),
        layers,
    }
}

#[test]
fn counts_come_from_header_and_keys() {
    let r = CpuRelighter::new(Arc::new(mixed_stack(1))).unwrap();
    assert_eq!(r.editable_count(), 2);
    assert_eq!(
        (r.basis_count(0), r.basis_count(1), r.basis_count(2)),
        (3, 3, 0)
    );
    assert_eq!(r.size(), (W, H));
    // Before any relight the image is black with alpha 1.
    assert!(r.image().chunks(4).all(|p| p == [0.0, 0.0, 0.0, 1.0]));
}

#[test]
fn layer_weight_is_the_product_along_the_path() {
    let coefs = vec![
        vec![Rgb::new(0.5, 2.0, 3.0), Rgb::new(0.25, 1.0, -1.0)],
        vec![Rgb::new(4.0, 0.5, 0.1)],
    ];
    assert_eq!(
        layer_weight(&LayerKey::new(vec![]), &coefs, &[]),
        Rgb::ONE,
        "World"
    );
    assert_eq!(
        layer_weight(&LayerKey::new(vec![PathVertex::Fixed]), &coefs, &[]),
        Rgb::ONE
    );
    assert_eq!(
        layer_weight(
            &LayerKey::new(vec![e(0, 1), PathVertex::Fixed, e(1, 0)]),
            &coefs,
            &[]
        ),
        Rgb::new(1.0, 0.5, -0.1)
    );
    assert_eq!(
        layer_weight(&LayerKey::new(vec![e(0, 0), e(0, 0)]), &coefs, &[]),
        Rgb::new(0.25, 4.0, 9.0),
        "a region met twice counts twice"
    );
    let grouped = LayerKey {
        path: vec![e(1, 0)],
        light_group: 3,
    };
    assert_eq!(layer_weight(&grouped, &coefs, &[]), Rgb::new(4.0, 0.5, 0.1));
    // Tail-edit layers: the eye part weighs its scale, the tail term s_b·(s_d^i·s_g^j − 1);
    // with no scales (or scales of 1: the bake-time materials) a tail edit weighs exactly 0.
    let tail = LayerKey::new(vec![
        PathVertex::Part { region: 1, part: 0 },
        PathVertex::TailEdit {
            region: 0,
            diffuse: 1,
            glossy: 1,
            bounce: 1,
        },
    ]);
    assert_eq!(layer_weight(&tail, &coefs, &[]), Rgb::ZERO);
    assert_eq!(layer_weight(&tail, &coefs, &[[Rgb::ONE; 2]; 2]), Rgb::ZERO);
    let scales = [
        [Rgb::new(3.0, 1.0, 1.0), Rgb::new(2.0, 0.5, 1.0)],
        [Rgb::new(3.0, 1.0, 0.0), Rgb::ONE],
    ];
    // eye (region 1, diffuse): (3, 1, 0); bounce (glossy) s_g · (s_d·s_g − 1):
    // (2·5, 0.5·(−0.5), 0).
    assert_eq!(
        layer_weight(&tail, &coefs, &scales),
        Rgb::new(30.0, -0.25, 0.0)
    );
}

#[test]
fn full_relight_matches_f64_reference() {
    let stack = Arc::new(mixed_stack(2));
    let mut r = CpuRelighter::new(stack.clone()).unwrap();
    let mut rng = Rng::new(3);
    for round in 0..3 {
        let coefs = random_coefs(&mut rng, &[3, 3]);
        let img = r.relight(&coefs).unwrap().to_vec();
        // ~57 terms of magnitude ≤ ~20 rounded in f32: a few 1e-7 relative to the largest.
        assert_close(
            &img,
            &reference(&stack, &coefs),
            2e-6,
            &format!("round {round}"),
        );
        let s = r.last_stats();
        assert!(!s.incremental);
        assert_eq!(s.layers_summed, stack.layers.len());
    }
    // More coefficients than the keys use are accepted (a basis whose layers were dropped).
    let mut coefs = random_coefs(&mut rng, &[5, 3]);
    let img = r.relight(&coefs).unwrap().to_vec();
    coefs[0].truncate(3);
    assert_close(&img, &reference(&stack, &coefs), 2e-6, "extra coefficients");
}

#[test]
fn incremental_equals_full_over_random_edits() {
    let stack = Arc::new(mixed_stack(4));
    let mut inc = CpuRelighter::new(stack.clone()).unwrap();
    let mut full = CpuRelighter::new(stack.clone()).unwrap();
    let mut rng = Rng::new(5);
    let mut coefs = random_coefs(&mut rng, &[3, 3]);
    inc.relight(&coefs).unwrap();
    let mut n_incremental = 0;
    // 150 edits: crosses two periodic full re-sums.
    for edit in 1..=150 {
        let region = rng.below(2);
        coefs[region] = random_coefs(&mut rng, &[3]).remove(0);
        if edit % 10 == 0 {
            // An edit that changes one basis only: only layers using it are re-summed.
            coefs[region][1] = Rgb::splat(rng.range(0.0, 1.0));
        }
        let a = inc.relight_region(region, &coefs[region]).unwrap().to_vec();
        let s = inc.last_stats();
        assert_eq!(s.incremental, edit % FULL_RESUM_EVERY != 0, "edit {edit}");
        if s.incremental {
            n_incremental += 1;
            let touching = stack
                .layers
                .iter()
                .filter(|l| l.key.contains_region(region as u16))
                .count();
            assert!(
                s.layers_summed <= touching && s.layers_summed > 0,
                "edit {edit}: {s:?}"
            );
        }
        let b = full.relight(&coefs).unwrap();
        let scale = b.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        let worst = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f32, f32::max)
            / scale;
        assert!(worst <= 1e-5, "edit {edit}: relative difference {worst:e}");
    }
    assert_eq!(n_incremental, 150 - 2);
}

#[test]
fn incremental_skips_unchanged_bases_and_reads_less() {
    let stack = Arc::new(mixed_stack(6));
    let mut r = CpuRelighter::new(stack.clone()).unwrap();
    let mut coefs = random_coefs(&mut Rng::new(7), &[3, 3]);
    r.relight(&coefs).unwrap();
    let full = r.last_stats();
    // Change basis 2 of region 1 only.
    coefs[1][2] = Rgb::new(0.3, 0.2, 0.1);
    r.relight_region(1, &coefs[1]).unwrap();
    let s = r.last_stats();
    let expect = stack
        .layers
        .iter()
        .filter(|l| l.key.path.iter().any(|v| *v == e(1, 2)))
        .count();
    assert_eq!(s.layers_summed, expect);
    assert!(
        s.incremental && s.bytes_read < full.bytes_read / 3,
        "{s:?} vs {full:?}"
    );
    // The same coefficients again: nothing to add.
    r.relight_region(1, &coefs[1]).unwrap();
    assert_eq!(
        (r.last_stats().layers_summed, r.last_stats().bytes_read),
        (0, 0)
    );
    assert_close(
        r.image(),
        &reference(&stack, &coefs),
        2e-6,
        "after no-op edit",
    );
}

#[test]
fn zero_rows_and_columns_are_skipped_and_correct() {
    let mut rng = Rng::new(8);
    let keys = [
        LayerKey::new(vec![]),
        LayerKey::new(vec![e(0, 0)]),
        LayerKey::new(vec![e(1, 1), PathVertex::Fixed]),
        LayerKey::new(vec![PathVertex::Fixed, e(0, 1)]),
    ];
    let layers = vec![
        // All zero: never read.
        random_layer(&mut rng, keys[0].clone(), W, H, 3, Precision::F16, 0..H, 0),
        // Rows 0..30 zero, and the left 13 columns: 7 rows × 37 px × 1 ch × 2 B (the span
        // [13, 45) is widened to whole groups of 8 pixels: [8, 45)).
        random_layer(
            &mut rng,
            keys[1].clone(),
            W,
            H,
            1,
            Precision::F16,
            0..30,
            13,
        ),
        // Rows 3..37 zero: 3 rows × 45 px × 3 ch × 4 B.
        random_layer(&mut rng, keys[2].clone(), W, H, 3, Precision::F32, 3..H, 0),
        // Dense: 37 × 45 × 2 B.
        random_layer(&mut rng, keys[3].clone(), W, H, 1, Precision::F16, 0..0, 0),
    ];
    // A single non-zero pixel in the middle of the dense layer's last row leaves its span
    // as is; a lone value in the all-zero-left layer at x = 40 must still be summed.
    let stack = Arc::new(TransferStack {
        header: header(W as u32, H as u32),
        layers,
    });
    let mut r = CpuRelighter::new(stack.clone()).unwrap();
    let coefs = random_coefs(&mut rng, &[2, 2]);
    let img = r.relight(&coefs).unwrap().to_vec();
    assert_close(&img, &reference(&stack, &coefs), 2e-6, "sparse layers");
    let s = r.last_stats();
    assert_eq!(s.layers_summed, 3, "the all-zero layer is not summed");
    // The tiled layout reads whole 16×16 tiles of the layers present there (the dense
    // layout's row spans are gone): the bytes of the three summed layers' entries.
    let per_layer = r.stack().layer_bytes();
    assert_eq!(per_layer[0], 0, "the all-zero layer is stored nowhere");
    assert_eq!(s.bytes_read, per_layer.iter().sum::<usize>());

    // Interior zeros do not shrink a span; a single isolated value does define one.
    let mut v = vec![0.0f32; W * H];
    v[10 * W + 40] = 2.0;
    v[10 * W + 5] = -1.0;
    v[20 * W + 44] = 3.0;
    let layer = Layer::from_f32(LayerKey::new(vec![e(0, 0)]), 1, &v, Precision::F32);
    let stack = Arc::new(TransferStack {
        header: header(W as u32, H as u32),
        layers: vec![layer],
    });
    let mut r = CpuRelighter::new(stack.clone()).unwrap();
    let coefs = vec![vec![Rgb::new(1.0, 2.0, 3.0)], vec![]];
    let img = r.relight(&coefs).unwrap();
    assert_eq!(
        &img[4 * (10 * W + 40)..4 * (10 * W + 40) + 4],
        &[2.0, 4.0, 6.0, 1.0]
    );
    assert_eq!(
        &img[4 * (10 * W + 5)..4 * (10 * W + 5) + 4],
        &[-1.0, -2.0, -3.0, 1.0]
    );
    assert_eq!(
        &img[4 * (20 * W + 44)..4 * (20 * W + 44) + 4],
        &[3.0, 6.0, 9.0, 1.0]
    );
    // Tiled layout: the tiles holding a value are read whole, the others not at all —
    // (0,0) [16×16], (2,0) [13×16] and (2,1) [13×16] (the right column is 45 − 32 wide).
    assert_eq!(r.last_stats().bytes_read, (16 * 16 + 13 * 16 + 13 * 16) * 4);
}

#[test]
fn zero_weight_layers_are_not_read() {
    let stack = Arc::new(mixed_stack(9));
    let mut r = CpuRelighter::new(stack.clone()).unwrap();
    // Region 0 all zero: every layer through it has weight 0.
    let coefs = vec![
        vec![Rgb::ZERO; 3],
        random_coefs(&mut Rng::new(10), &[3]).remove(0),
    ];
    let img = r.relight(&coefs).unwrap().to_vec();
    assert_close(&img, &reference(&stack, &coefs), 2e-6, "zero region");
    let without = stack
        .layers
        .iter()
        .filter(|l| !l.key.contains_region(0))
        .count();
    assert_eq!(r.last_stats().layers_summed, without);
}

fn expect_invalid(res: Result<CpuRelighter, RelumeError>, needle: &str) {
    match res {
        Err(e) => assert!(
            e.to_string().contains(needle),
            "{e} does not mention {needle:?}"
        ),
        Ok(_) => panic!("expected an error mentioning {needle:?}"),
    }
}

#[test]
fn malformed_stacks_are_refused() {
    let base = mixed_stack(11);
    let with = |f: &dyn Fn(&mut Layer)| {
        let mut s = base.clone();
        f(&mut s.layers[5]);
        CpuRelighter::new(Arc::new(s))
    };
    let name = base.layers[5].key.layer_name();
    expect_invalid(
        with(&|l| match &mut l.samples {
            LayerSamples::F16(v) => v.truncate(v.len() - 1),
            LayerSamples::F32(v) => v.truncate(v.len() - 1),
        }),
        "expected 45×37×",
    );
    expect_invalid(with(&|l| l.channels = 2), "2 channels");
    expect_invalid(with(&|l| l.channels = 4), &name);
    expect_invalid(
        with(&|l| l.key = LayerKey::new(vec![e(2, 0)])),
        "editable region of layer E2b0",
    );
    expect_invalid(
        with(&|l| match &mut l.samples {
            LayerSamples::F16(v) => v[W * 3 + 7] = half::f16::NAN,
            LayerSamples::F32(v) => v[W * 3 + 7] = f32::INFINITY,
        }),
        "pixel (7, 3)",
    );
    expect_invalid(with(&|l| l.scale = f32::NAN), "scale of layer");
}

#[test]
fn bad_coefficients_are_refused() {
    let mut r = CpuRelighter::new(Arc::new(mixed_stack(12))).unwrap();
    let good = random_coefs(&mut Rng::new(13), &[3, 3]);
    // relight_region before any full relight.
    let e0 = r.relight_region(0, &good[0]).unwrap_err().to_string();
    assert!(e0.contains("call relight"), "{e0}");
    let e1 = r.relight(&good[..1]).unwrap_err().to_string();
    assert!(
        e1.contains("1 coefficient lists for 2 editable regions (Bunny, Floor)"),
        "{e1}"
    );
    let e2 = r
        .relight(&[good[0].clone(), good[1][..2].to_vec()])
        .unwrap_err()
        .to_string();
    assert!(e2.contains("Floor") && e2.contains("use 3 bases"), "{e2}");
    let mut nan = good.clone();
    nan[0][1].y = f32::NAN;
    assert!(matches!(
        r.relight(&nan),
        Err(RelumeError::NonFinite { .. })
    ));
    r.relight(&good).unwrap();
    assert!(matches!(
        r.relight_region(2, &good[0]),
        Err(RelumeError::IndexOutOfRange { .. })
    ));
    let mut inf = good[1].clone();
    inf[2].x = f32::INFINITY;
    assert!(matches!(
        r.relight_region(1, &inf),
        Err(RelumeError::NonFinite { .. })
    ));
    // A refused edit leaves the image as it was.
    let before = r.image().to_vec();
    assert!(r.relight_region(1, &good[1][..1]).is_err());
    assert_eq!(r.image(), &before[..]);
}
