//! Per-tile adaptive sampling (`bake/schedule/adaptive.rs`): off at threshold 0 (today's
//! bits), the canonical sums when no tile stops, more samples where the image is noisier,
//! an image mean that agrees with the full bake's within the noise, the same stack for any
//! thread count, and refused by name where it cannot apply (a farm split, a progressive
//! bake).
use crate::common;

use relume_engine::bake::farm::partition::{bake_partition, Partition};
use relume_engine::bake::fields::BakeFields;
use relume_engine::bake::{
    bake, bake_progressive, AdaptiveSampling, BakeReport, BakeSettings, IndirectSampling,
};
use relume_engine::progress::Progress;
use relume_engine::scene::Scene;
use relume_engine::stack::{LayerSamples, TransferStack};
use relume_engine::RelumeError;

const SIZE: u32 = 64;
const SPP: u32 = 16;
const TILE: usize = 16;

fn scene() -> Scene {
    common::cornell(SIZE)
}

/// A custom bake (no denoiser: the unbiased estimate) of the Cornell box.
fn settings(seed: u64, threshold: f32) -> BakeSettings {
    BakeSettings {
        spp: SPP,
        light_samples: 1,
        indirect_samples: 1,
        sampling: IndirectSampling::Mixture,
        seed,
        threads: 2,
        adaptive: AdaptiveSampling {
            threshold,
            min_spp: 0,
        },
        ..BakeSettings::default()
    }
}

fn baked(s: &BakeSettings) -> (TransferStack, BakeReport) {
    bake(&scene(), s, &Progress::new()).unwrap()
}

fn bits(stack: &TransferStack) -> Vec<(String, u32, Vec<u32>)> {
    stack
        .layers
        .iter()
        .map(|l| {
            let v = match &l.samples {
                LayerSamples::F16(v) => v.iter().map(|h| h.to_bits() as u32).collect(),
                LayerSamples::F32(v) => v.iter().map(|f| f.to_bits()).collect(),
            };
            (l.key.layer_name(), l.channels, v)
        })
        .collect()
}

fn assert_same_bits(a: &TransferStack, b: &TransferStack, what: &str) {
    assert_eq!(a.header, b.header, "{what}: headers differ");
    let (x, y) = (bits(a), bits(b));
    assert_eq!(x.len(), y.len(), "{what}: layer counts differ");
    for (p, q) in x.iter().zip(&y) {
        assert!(p == q, "{what}: layer {} differs", p.0);
    }
}

/// The relit image at the bake-time materials, RGB per pixel.
fn image(stack: &TransferStack) -> Vec<[f64; 3]> {
    let rgba = common::relight_at_bake_materials(stack, &scene());
    let stride = rgba.len() / (SIZE * SIZE) as usize;
    rgba.chunks_exact(stride)
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect()
}

/// Pixel indices of tile `t` (raster order of 16 × 16 tiles).
fn tile_pixels(t: usize) -> impl Iterator<Item = usize> {
    let along = SIZE as usize / TILE;
    let (x0, y0) = ((t % along) * TILE, (t / along) * TILE);
    (0..TILE * TILE).map(move |i| (y0 + i / TILE) * SIZE as usize + x0 + i % TILE)
}

fn tiles() -> usize {
    (SIZE as usize / TILE).pow(2)
}

/// Per tile its noise measured from two full bakes of other seeds, on the rule's scale
/// (per pixel the channels' noise of one bake's mean over √intensity, RMS over the tile):
/// the difference of two independent images has √2 times one image's noise.
fn measured_tile_noise(a: &[[f64; 3]], b: &[[f64; 3]]) -> Vec<f64> {
    (0..tiles())
        .map(|t| {
            let mut sum = 0.0;
            for p in tile_pixels(t) {
                let noise: f64 = (0..3)
                    .map(|c| (a[p][c] - b[p][c]).abs() / 2f64.sqrt())
                    .sum();
                let intensity: f64 = (0..3).map(|c| (0.5 * (a[p][c] + b[p][c])).max(0.0)).sum();
                let e = noise / (1e-4 + intensity.sqrt());
                sum += e * e;
            }
            (sum / (TILE * TILE) as f64).sqrt()
        })
        .collect()
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.partial_cmp(b).unwrap());
    s[s.len() / 2]
}

#[test]
fn threshold_zero_is_the_bake_without_adaptive_sampling() {
    let without = BakeSettings {
        adaptive: AdaptiveSampling::default(),
        ..settings(3, 0.0)
    };
    let explicit_zero = settings(3, 0.0);
    // The settings a stack or farm file records keep their bytes.
    let json = serde_json::to_string(&explicit_zero).unwrap();
    assert!(!json.contains("adaptive"), "{json}");
    let (a, ra) = baked(&without);
    let (b, rb) = baked(&explicit_zero);
    assert_same_bits(&a, &b, "threshold 0");
    assert!(ra.adaptive.is_none() && rb.adaptive.is_none());
}

#[test]
fn tiles_that_never_stop_keep_the_bits_of_the_full_bake() {
    // A threshold no tile reaches: every tile takes its rounds (2, 4, 8, 16) and their
    // blocks are combined in the canonical tree, which must give the one-pass sums.
    let (full, _) = baked(&settings(5, 0.0));
    let (rounds, report) = baked(&settings(5, 1e-12));
    let a = report.adaptive.expect("adaptive report");
    assert_eq!(a.tiles_stopped, 0, "{a:?}");
    assert!(a.tile_spp.iter().all(|n| *n == SPP));
    assert_same_bits(&full, &rounds, "adaptive, no tile stopped");
}

/// A threshold between the tiles: the error at n samples is about √(SPP/n) times the noise
/// at `SPP`, so the tiles quieter than the median stop at 8 samples or before, the others
/// (most of them) go on.
fn middle_threshold(noise: &[f64]) -> f32 {
    (median(noise) * 2f64.sqrt()) as f32
}

#[test]
fn noisier_tiles_take_more_samples_and_the_mean_stays_within_the_noise() {
    let (one, _) = baked(&settings(11, 0.0));
    let (two, _) = baked(&settings(12, 0.0));
    let (i1, i2) = (image(&one), image(&two));
    let noise = measured_tile_noise(&i1, &i2);
    let threshold = middle_threshold(&noise);
    let (full, _) = baked(&settings(0, 0.0));
    let (adaptive, report) = baked(&settings(0, threshold));
    let a = report.adaptive.expect("adaptive report");
    eprintln!("threshold {threshold}: {a:?}\nmeasured tile noise {noise:?}");
    let spp = &a.tile_spp;
    assert!(a.tiles_stopped > 0 && a.tiles_stopped < tiles(), "{a:?}");
    assert!(a.sample_share < 1.0);
    // Where the samples went: the tiles that stopped early are the quiet ones.
    let mean_of = |keep: &dyn Fn(u32) -> bool| {
        let v: Vec<f64> = (0..tiles())
            .filter(|t| keep(spp[*t]))
            .map(|t| noise[t])
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (quiet, noisy) = (mean_of(&|n| n < SPP), mean_of(&|n| n == SPP));
    eprintln!("measured noise: stopped tiles {quiet:.4}, full tiles {noisy:.4}");
    assert!(quiet < 0.75 * noisy, "stopped {quiet} vs full {noisy}");
    // Tiles with no light at all (nothing but the black world, if the frame has any) stop
    // at the first check.
    for (t, n) in spp.iter().enumerate() {
        if tile_pixels(t).all(|p| i1[p] == [0.0; 3] && i2[p] == [0.0; 3]) {
            assert!(*n < SPP, "dark tile {t} took {n}");
        }
    }

    // The mean: the adaptive image is the full bake's first n_t samples per tile (same seed),
    // so without bias their difference is noise of variance v_t·(spp/n_t − 1), v_t the
    // variance of a tile's mean at spp, measured from the two other seeds.
    let (ia, ifull) = (image(&adaptive), image(&full));
    let pixels = (SIZE * SIZE) as f64;
    let mut diff = 0.0;
    let mut var = 0.0;
    let mut total = 0.0;
    for (t, n) in spp.iter().enumerate() {
        let sum =
            |img: &[[f64; 3]]| -> f64 { tile_pixels(t).map(|p| img[p].iter().sum::<f64>()).sum() };
        diff += sum(&ia) - sum(&ifull);
        total += sum(&ifull);
        let v = (sum(&i1) - sum(&i2)).powi(2) / 2.0;
        var += v * (SPP as f64 / *n as f64 - 1.0);
    }
    let (diff, sigma) = (diff / pixels, var.sqrt() / pixels);
    let mean = total / pixels;
    eprintln!(
        "image mean {mean:.5}: adaptive − full {diff:.3e} ({:.3} %), noise σ {sigma:.3e} ({:.3} %)",
        100.0 * diff / mean,
        100.0 * sigma / mean
    );
    assert!(sigma > 0.0);
    assert!(diff.abs() <= 4.0 * sigma, "bias {diff} against σ {sigma}");
}

#[test]
fn the_stack_does_not_depend_on_the_thread_count() {
    let one = BakeSettings {
        threads: 1,
        ..settings(21, 0.05)
    };
    let (a, ra) = baked(&one);
    let (b, rb) = baked(&settings(21, 0.05));
    let (ra, rb) = (ra.adaptive.unwrap(), rb.adaptive.unwrap());
    assert!(ra.tiles_stopped > 0 && ra.tiles_stopped < tiles(), "{ra:?}");
    assert_eq!(ra.tile_spp, rb.tile_spp);
    assert_same_bits(&a, &b, "1 and 2 threads");
}

fn refused_as_adaptive(e: RelumeError) {
    match e {
        RelumeError::InvalidValue { what, message } => {
            assert_eq!(what, "adaptive_threshold", "{message}")
        }
        other => panic!("not the named refusal: {other}"),
    }
}

#[test]
fn a_farm_split_and_a_progressive_bake_refuse_adaptive_sampling() {
    let dir = tempfile::tempdir().unwrap();
    for count in [1, 2] {
        let e = bake_partition(
            &scene(),
            None,
            &settings(0, 0.05),
            Partition { index: 0, count },
            None,
            &dir.path().join("part.rpart"),
            &Progress::new(),
        )
        .unwrap_err();
        refused_as_adaptive(e);
    }
    let e = bake_progressive(
        &scene(),
        &settings(0, 0.05),
        &[4, 16],
        &Progress::new(),
        |_, _, _| Ok(()),
    )
    .unwrap_err();
    refused_as_adaptive(e);
}

#[test]
fn the_settings_are_checked_and_a_zero_threshold_clears_the_minimum() {
    for bad in [1.0, -0.1, f32::NAN] {
        refused_as_adaptive(settings(0, bad).validate().unwrap_err());
    }
    let min_without_threshold = BakeSettings {
        adaptive: AdaptiveSampling {
            threshold: 0.0,
            min_spp: 4,
        },
        ..settings(0, 0.0)
    };
    match min_without_threshold.validate().unwrap_err() {
        RelumeError::InvalidValue { what, .. } => assert_eq!(what, "adaptive_min_spp"),
        other => panic!("{other}"),
    }
    let mut fields = BakeFields::default();
    let on = serde_json::json!({"adaptive_threshold": 0.02, "adaptive_min_spp": 8});
    fields.apply(on.as_object().unwrap()).unwrap();
    assert_eq!(
        (fields.adaptive_threshold, fields.adaptive_min_spp),
        (0.02, 8)
    );
    let off = serde_json::json!({"adaptive_threshold": 0.0});
    fields.apply(off.as_object().unwrap()).unwrap();
    assert_eq!(
        (fields.adaptive_threshold, fields.adaptive_min_spp),
        (0.0, 0)
    );
    // The automatic first check: an eighth of spp, at least 4, at most spp.
    let auto = AdaptiveSampling {
        threshold: 0.1,
        min_spp: 0,
    };
    assert_eq!(
        [16, 64, 256, 2].map(|spp| auto.first_check(spp)),
        [4, 8, 32, 2]
    );
}
