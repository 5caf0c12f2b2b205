//! The tiled (sparse, per-tile) stack: conversion to and from the dense stack, its file
//! (version 2) and the version-1 fallback, the relight sum over it against the dense CPU
//! relighter, and hostile files.

use std::path::Path;
use std::sync::{Arc, OnceLock};

use relume_engine::bake::presets::Preset;
use relume_engine::bake::{bake, BakeSettings};
use relume_engine::progress::Progress;
use relume_engine::relight::tiled_sum::{full, incremental, layer_weights};
use relume_engine::relight::{group_factors, CpuRelighter};
use relume_engine::scene::file::load_scene;
use relume_engine::scene::Resolution;
use relume_engine::stack::exr_file::write_stack;
use relume_engine::stack::tiled::build::TileRadiance;
use relume_engine::stack::tiled::file::{read_tiled, write_tiled, write_tiled_unchecked};
use relume_engine::stack::tiled::{
    TiledStack, TiledStackBuilder, STACK_FORMAT_VERSION_TILED, STACK_TILE,
};
use relume_engine::stack::{Layer, Precision, TransferStack, STACK_FORMAT_VERSION};
use relume_engine::{RelumeError, Rgb};

/// xorshift64*: deterministic randomness without a dependency.
struct Rng(u64);
impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn f32(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
}

/// A small draft bake of the assets' Cornell box at a size that is not a multiple of 16
/// (edge tiles in both directions), f16. Baked once for all tests.
fn cornell() -> &'static TransferStack {
    static STACK: OnceLock<TransferStack> = OnceLock::new();
    STACK.get_or_init(|| {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/cornell.scene.json");
        let scene = load_scene(&path).unwrap();
        let mut settings = BakeSettings::default();
        Preset::Draft.apply(&mut settings);
        settings.resolution = Some(Resolution {
            width: 72,
            height: 56,
        });
        settings.precision = Precision::F16;
        bake(&scene, &settings, &Progress::new()).unwrap().0
    })
}

/// A synthetic stack with the Cornell bake's header and keys at `width × height`: each
/// layer covers a different rectangle (so many tiles lack it), RGB layers are grey in
/// part of the frame, one layer is zero everywhere, a few values are −0.
fn synthetic(width: u32, height: u32, precision: Precision, seed: u64) -> TransferStack {
    let base = cornell();
    let mut rng = Rng::new(seed);
    let (w, h) = (width as usize, height as usize);
    let layers = base
        .layers
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let ch = l.channels as usize;
            let mut v = vec![0.0f32; w * h * ch];
            if i != 2 {
                let x0 = (i * 7) % w;
                let y0 = (i * 5) % h;
                let x1 = (x0 + 3 + i * 11 % w).min(w);
                let y1 = (y0 + 2 + i * 13 % h).min(h);
                for y in y0..y1 {
                    for x in x0..x1 {
                        let grey = x < w / 2;
                        let g = rng.range(-0.5, 3.0);
                        for c in 0..ch {
                            v[(y * w + x) * ch + c] = if grey { g } else { rng.range(-0.5, 3.0) };
                        }
                    }
                }
                if i % 5 == 1 {
                    v[0] = -0.0;
                }
            }
            Layer::from_f32(l.key.clone(), l.channels, &v, precision)
        })
        .collect();
    let mut header = base.header.clone();
    header.width = width;
    header.height = height;
    header.precision = precision;
    TransferStack { header, layers }
}

fn synthetic_set() -> Vec<TransferStack> {
    vec![
        synthetic(37, 21, Precision::F16, 1),
        synthetic(37, 21, Precision::F32, 2),
        synthetic(16, 48, Precision::F16, 3),
        synthetic(5, 3, Precision::F32, 4),
    ]
}

fn relative_l2(a: &[f32], b: &[f32]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        num += (*x as f64 - *y as f64).powi(2);
        den += (*y as f64).powi(2);
    }
    (num / den.max(1e-300)).sqrt()
}

/// Random coefficients for every basis the stack's layers use.
fn random_coefs(relighter: &CpuRelighter, rng: &mut Rng) -> Vec<Vec<Rgb>> {
    (0..relighter.editable_count())
        .map(|r| {
            (0..relighter.basis_count(r))
                .map(|_| {
                    Rgb::new(
                        rng.range(-0.5, 1.5),
                        rng.range(-0.5, 1.5),
                        rng.range(-0.5, 1.5),
                    )
                })
                .collect()
        })
        .collect()
}

#[test]
fn stack_tile_is_the_bake_tile() {
    assert_eq!(STACK_TILE, relume_engine::bake::schedule::tiles::TILE);
}

#[test]
fn from_dense_to_dense_is_exact() {
    let mut stacks = synthetic_set();
    stacks.push(cornell().clone());
    for dense in &stacks {
        let tiled = TiledStack::from_dense(dense).unwrap();
        assert_eq!(tiled.header.format_version, STACK_FORMAT_VERSION_TILED);
        assert_eq!(tiled.layers.len(), dense.layers.len());
        assert_eq!(tiled.tiles.len(), tiled.tile_count());
        assert!(tiled.sample_bytes() <= dense.sample_bytes());
        let back = tiled.to_dense().unwrap();
        assert_eq!(back.header.format_version, STACK_FORMAT_VERSION);
        assert_eq!(
            &back, dense,
            "{}×{}",
            dense.header.width, dense.header.height
        );
        let per_layer: usize = tiled.layer_bytes().iter().sum();
        assert_eq!(per_layer, tiled.sample_bytes());
    }
    let dense = cornell();
    let tiled = TiledStack::from_dense(dense).unwrap();
    eprintln!(
        "cornell {}×{} draft, {} layers: tiled {} B / dense {} B = {:.3}, {} entries",
        dense.header.width,
        dense.header.height,
        dense.layers.len(),
        tiled.sample_bytes(),
        dense.sample_bytes(),
        tiled.sample_bytes() as f64 / dense.sample_bytes() as f64,
        tiled.entry_count()
    );
}

#[test]
fn tiles_store_only_non_zero_layers_and_grey_where_equal() {
    let dense = synthetic(37, 21, Precision::F16, 7);
    let tiled = TiledStack::from_dense(&dense).unwrap();
    // The all-zero layer is listed but in no tile.
    assert!(tiled
        .tiles
        .iter()
        .all(|t| t.entries.iter().all(|e| e.layer != 2)));
    assert_eq!(tiled.layers[2].key, dense.layers[2].key);
    assert!(tiled.entry_count() < tiled.tile_count() * tiled.layers.len());
    // An RGB layer is grey in a tile of the left half and RGB in the rightmost column.
    let rgb_layers: Vec<u32> = (0..dense.layers.len() as u32)
        .filter(|&l| dense.layers[l as usize].channels == 3)
        .collect();
    if !rgb_layers.is_empty() {
        let entries = tiled.tiles.iter().flat_map(|t| &t.entries);
        let rgb_entries: Vec<u8> = entries
            .filter(|e| rgb_layers.contains(&e.layer))
            .map(|e| e.channels)
            .collect();
        assert!(
            rgb_entries.contains(&1) && rgb_entries.contains(&3),
            "{rgb_entries:?}"
        );
    }
    // value() agrees with the dense layer.
    for (t, tile) in tiled.tiles.iter().enumerate() {
        let rect = tiled.tile_rect(t);
        for (k, e) in tile.entries.iter().enumerate() {
            let layer = &dense.layers[e.layer as usize];
            let lc = layer.channels as usize;
            for p in 0..rect.pixels() {
                let x = rect.x0 as usize + p % rect.width as usize;
                let y = rect.y0 as usize + p / rect.width as usize;
                for c in 0..3 {
                    let d = layer.value((y * 37 + x) * lc + c.min(lc - 1));
                    assert_eq!(tiled.value(t, k, p, c), d);
                }
            }
        }
    }
}

#[test]
fn v2_file_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let mut stacks = synthetic_set();
    stacks.push(cornell().clone());
    for (i, dense) in stacks.iter().enumerate() {
        let tiled = TiledStack::from_dense(dense).unwrap();
        let path = dir.path().join(format!("s{i}.exr"));
        let bytes = write_tiled(&path, &tiled).unwrap();
        assert_eq!(bytes, std::fs::metadata(&path).unwrap().len());
        assert_eq!(read_tiled(&path).unwrap(), tiled);
    }
}

#[test]
fn v1_file_reads_as_from_dense() {
    let dir = tempfile::tempdir().unwrap();
    for (i, dense) in [cornell().clone(), synthetic(37, 21, Precision::F32, 9)]
        .iter()
        .enumerate()
    {
        let path = dir.path().join(format!("v1_{i}.exr"));
        write_stack(&path, dense).unwrap();
        let read = read_tiled(&path).unwrap();
        assert_eq!(read, TiledStack::from_dense(dense).unwrap());
    }
}

#[test]
fn builder_quantises_per_entry_and_relights_like_its_dense_form() {
    // The builder drops −0 like any zero; from_dense keeps it (bit-exact). Clear them.
    let mut base = synthetic(37, 21, Precision::F32, 11);
    for layer in &mut base.layers {
        if let relume_engine::stack::LayerSamples::F32(v) = &mut layer.samples {
            v.iter_mut().for_each(|x| *x += 0.0);
        }
    }
    let tiled32 = TiledStack::from_dense(&base).unwrap();
    for precision in [Precision::F16, Precision::F32] {
        let mut header = base.header.clone();
        header.precision = precision;
        let layers = base
            .layers
            .iter()
            .map(|l| (l.key.clone(), l.channels as u8))
            .collect();
        let builder = TiledStackBuilder::new(header, layers).unwrap();
        // Insert tiles from several threads, in reverse order, RGB given as 3 channels.
        std::thread::scope(|s| {
            for part in 0..3 {
                let (builder, tiled32) = (&builder, &tiled32);
                s.spawn(move || {
                    for t in (0..tiled32.tile_count()).rev().filter(|t| t % 3 == part) {
                        let n = tiled32.tile_rect(t).pixels();
                        let radiance: Vec<(u32, u8, Vec<f32>)> = (0..tiled32.layers.len())
                            .map(|l| {
                                let c = tiled32.layers[l].channels;
                                let k = tiled32.tiles[t]
                                    .entries
                                    .iter()
                                    .position(|e| e.layer == l as u32);
                                let v = (0..n * c as usize)
                                    .map(|i| match k {
                                        Some(k) => {
                                            tiled32.value(t, k, i / c as usize, i % c as usize)
                                        }
                                        None => 0.0,
                                    })
                                    .collect();
                                (l as u32, c, v)
                            })
                            .collect();
                        let inputs: Vec<TileRadiance> = radiance
                            .iter()
                            .map(|(layer, channels, v)| TileRadiance {
                                layer: *layer,
                                channels: *channels,
                                radiance: v,
                            })
                            .collect();
                        builder.insert(t, &inputs).unwrap();
                    }
                });
            }
        });
        assert!(builder.insert(0, &[]).is_err(), "a tile inserted twice");
        let built = builder.finish().unwrap();
        let entries = |s: &TiledStack| -> Vec<(u32, u8)> {
            s.tiles
                .iter()
                .flat_map(|t| t.entries.iter().map(|e| (e.layer, e.channels)))
                .collect()
        };
        assert_eq!(entries(&built), entries(&tiled32));
        if precision == Precision::F32 {
            assert_eq!(built.to_dense().unwrap(), base);
        }
        let weights = vec![Rgb::new(0.7, 1.1, 0.4); built.layers.len()];
        let (w, h) = (37, 21);
        let mut a = vec![0.0f32; w * h * 4];
        let mut b = a.clone();
        full(&built, &weights, &mut a).unwrap();
        full(&tiled32, &weights, &mut b).unwrap();
        let tolerance = if precision == Precision::F16 {
            1e-3
        } else {
            1e-6
        };
        assert!(relative_l2(&a, &b) < tolerance, "{precision:?}");
    }
}

#[test]
fn builder_refuses_bad_input() {
    let base = synthetic(20, 18, Precision::F16, 12);
    let layers: Vec<_> = base
        .layers
        .iter()
        .map(|l| (l.key.clone(), l.channels as u8))
        .collect();
    let builder = TiledStackBuilder::new(base.header.clone(), layers).unwrap();
    let ones = vec![1.0f32; 16 * 16 * 3];
    let input = |layer, channels, n| TileRadiance {
        layer,
        channels,
        radiance: &ones[..n],
    };
    assert!(builder.insert(99, &[]).is_err(), "tile out of range");
    assert!(
        builder.insert(0, &[input(9999, 1, 256)]).is_err(),
        "layer out of range"
    );
    assert!(
        builder.insert(0, &[input(0, 1, 255)]).is_err(),
        "wrong length"
    );
    assert!(
        builder
            .insert(0, &[input(0, 1, 256), input(0, 1, 256)])
            .is_err(),
        "twice"
    );
    let nan = vec![f32::NAN; 256];
    let bad = TileRadiance {
        layer: 0,
        channels: 1,
        radiance: &nan,
    };
    // Not an error: the last guard before the file stores a NaN as 0 (here the whole
    // entry, all zero, is left out) and counts it, so a bake is never lost to one.
    builder.insert(0, &[bad]).unwrap();
    assert_eq!(builder.non_finite_zeroed(), 256, "non-finite counted");
    assert!(builder.insert(0, &[input(0, 1, 256)]).is_err(), "twice");
    assert!(builder.finish().is_err(), "tiles missing");
}

/// Full sum against the dense CPU relighter, then incremental against full.
fn check_sums(dense: &TransferStack, seed: u64) {
    let tiled = TiledStack::from_dense(dense).unwrap();
    let mut relighter = CpuRelighter::new(Arc::new(dense.clone())).unwrap();
    let factors = group_factors(dense, None).unwrap();
    let mut rng = Rng::new(seed);
    let (w, h) = (dense.header.width as usize, dense.header.height as usize);
    let mut image = vec![0.0f32; w * h * 4];
    for round in 0..4 {
        let coefs = random_coefs(&relighter, &mut rng);
        let expected = relighter.relight(&coefs).unwrap().to_vec();
        let weights = layer_weights(&tiled, &coefs, &factors).unwrap();
        full(&tiled, &weights, &mut image).unwrap();
        let err = relative_l2(&image, &expected);
        assert!(err < 1e-6, "round {round}: full vs dense relative L2 {err}");
        assert!(image.chunks(4).all(|p| p[3] == 1.0));

        // Change one region's coefficients; add the weight deltas incrementally.
        if relighter.editable_count() > 0 {
            let region = round % relighter.editable_count();
            let mut new_coefs = coefs.clone();
            new_coefs[region] = random_coefs(&relighter, &mut rng)[region].clone();
            let new_weights = layer_weights(&tiled, &new_coefs, &factors).unwrap();
            let changed: Vec<(u32, Rgb)> = new_weights
                .iter()
                .zip(&weights)
                .enumerate()
                .filter(|(_, (n, o))| n != o)
                .map(|(l, (n, o))| (l as u32, *n - *o))
                .collect();
            incremental(&tiled, &changed, &mut image).unwrap();
            let mut again = vec![0.0f32; w * h * 4];
            full(&tiled, &new_weights, &mut again).unwrap();
            let err = relative_l2(&image, &again);
            assert!(
                err < 1e-6,
                "round {round}: incremental vs full relative L2 {err}"
            );
        }
    }
}

#[test]
fn full_sum_matches_dense_relighter_and_incremental_matches_full() {
    check_sums(cornell(), 21);
    for (i, dense) in synthetic_set().iter().enumerate() {
        check_sums(dense, 30 + i as u64);
    }
}

#[test]
fn sums_refuse_wrong_shapes() {
    let tiled = TiledStack::from_dense(&synthetic(20, 18, Precision::F16, 13)).unwrap();
    let weights = vec![Rgb::ONE; tiled.layers.len()];
    let mut image = vec![0.0f32; 20 * 18 * 4];
    assert!(full(&tiled, &weights[1..], &mut image).is_err());
    assert!(full(&tiled, &weights, &mut image[4..]).is_err());
    assert!(incremental(&tiled, &[(tiled.layers.len() as u32, Rgb::ONE)], &mut image).is_err());
    assert!(layer_weights(&tiled, &[], &[Rgb::ONE]).is_err());
}

fn is_stack_error(e: &RelumeError) -> bool {
    matches!(
        e,
        RelumeError::StackFormat { .. }
            | RelumeError::StackTruncated { .. }
            | RelumeError::StackForeign { .. }
            | RelumeError::OutOfMemory { .. }
    )
}

#[test]
fn truncated_v2_files_give_errors() {
    let dir = tempfile::tempdir().unwrap();
    let tiled = TiledStack::from_dense(cornell()).unwrap();
    let path = dir.path().join("whole.exr");
    write_tiled(&path, &tiled).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.exr");
    for len in [
        0,
        3,
        8,
        40,
        bytes.len() / 4,
        bytes.len() / 2,
        bytes.len() - 1,
    ] {
        std::fs::write(&cut, &bytes[..len]).unwrap();
        let e = read_tiled(&cut).expect_err("a cut file");
        assert!(is_stack_error(&e), "cut at {len}: {e:?}");
    }
}

/// Writes `tiled` changed by `damage` without the writer's checks and reads it back.
fn read_damaged(damage: impl FnOnce(&mut TiledStack)) -> RelumeError {
    let dir = tempfile::tempdir().unwrap();
    let mut tiled = TiledStack::from_dense(&synthetic(37, 21, Precision::F16, 14)).unwrap();
    damage(&mut tiled);
    let path = dir.path().join("damaged.exr");
    write_tiled_unchecked(&path, &tiled).unwrap();
    read_tiled(&path).expect_err("a damaged file")
}

fn first_entry(t: &mut TiledStack) -> &mut relume_engine::stack::tiled::TileLayer {
    t.tiles
        .iter_mut()
        .flat_map(|t| t.entries.iter_mut())
        .next()
        .unwrap()
}

#[test]
fn damaged_v2_tables_give_specific_errors() {
    let message = |e: RelumeError| match e {
        RelumeError::StackFormat { message, .. } => message,
        other => panic!("expected StackFormat, got {other:?}"),
    };
    let m = message(read_damaged(|t| first_entry(t).offset = 7));
    assert!(m.contains("values start at 7"), "{m}");
    let m = message(read_damaged(|t| first_entry(t).layer = 10_000));
    assert!(m.contains("layer id out of range"), "{m}");
    let m = message(read_damaged(|t| first_entry(t).scale = f32::NAN));
    assert!(m.contains("scale"), "{m}");
    let m = message(read_damaged(|t| first_entry(t).channels = 2));
    assert!(m.contains("channels"), "{m}");
    let m = message(read_damaged(|t| {
        let tile = t.tiles.iter_mut().find(|t| t.entries.len() >= 2).unwrap();
        tile.entries.swap(0, 1);
    }));
    assert!(
        m.contains("not strictly increasing") || m.contains("values start"),
        "{m}"
    );
    let m = message(read_damaged(|t| {
        let e = *first_entry(t);
        let tile = t.tiles.iter_mut().find(|t| !t.entries.is_empty()).unwrap();
        tile.entries.push(e);
    }));
    assert!(
        m.contains("strictly increasing") || m.contains("values"),
        "{m}"
    );
    let m = message(read_damaged(|t| {
        t.layers.pop();
    }));
    assert!(m.contains("out of range"), "{m}");
}

#[test]
fn claimed_sizes_beyond_the_file_give_errors() {
    let dir = tempfile::tempdir().unwrap();
    let tiled = TiledStack::from_dense(&synthetic(37, 21, Precision::F16, 15)).unwrap();
    let path = dir.path().join("s.exr");
    write_tiled(&path, &tiled).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    // The dense file's hostile helper rewrites the first part's windows and the header:
    // the `tiles` part then claims 16384² counts (1 GiB) in a file of a few KiB.
    {
        let hostile =
            relume_engine::stack::hostile::with_claimed_size(&bytes, 16384, 16384).unwrap();
        let hostile_path = dir.path().join("hostile.exr");
        std::fs::write(&hostile_path, hostile).unwrap();
        let e = read_tiled(&hostile_path).expect_err("a file claiming 16384²");
        assert!(
            matches!(e, RelumeError::StackTruncated { .. }),
            "claims checked against the file's length first: {e:?}"
        );
    }
}

#[test]
fn other_versions_and_foreign_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("not.exr");
    std::fs::write(&path, b"definitely not an OpenEXR file").unwrap();
    assert!(matches!(
        read_tiled(&path),
        Err(RelumeError::StackForeign { .. })
    ));
    let mut tiled = TiledStack::from_dense(&synthetic(20, 18, Precision::F16, 16)).unwrap();
    tiled.header.format_version = STACK_FORMAT_VERSION_TILED + 1;
    // The writer refuses it; the unchecked writer stores the layout's version (2: no
    // lattice entries) in the attribute but the header's in its JSON, which the reader
    // names.
    assert!(write_tiled(&dir.path().join("v4.exr"), &tiled).is_err());
    let p = dir.path().join("v4.exr");
    write_tiled_unchecked(&p, &tiled).unwrap();
    assert!(matches!(
        read_tiled(&p),
        Err(RelumeError::StackFormat { .. })
    ));
    assert!(matches!(
        read_tiled(&dir.path().join("missing.exr")),
        Err(RelumeError::Io { .. })
    ));
}

#[test]
fn a_cancelled_write_leaves_the_old_file() {
    use relume_engine::stack::tiled::file::write_tiled_cancellable;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.exr");
    std::fs::write(&path, b"old").unwrap();
    let tiled = TiledStack::from_dense(&synthetic(20, 18, Precision::F16, 17)).unwrap();
    let progress = Progress::new();
    progress.cancel();
    assert!(matches!(
        write_tiled_cancellable(&path, &tiled, &progress),
        Err(RelumeError::Cancelled)
    ));
    assert_eq!(std::fs::read(&path).unwrap(), b"old");
}
