//! Lattice entries (issue 14's compression of the bounce layers): the fit reproduces what
//! it can represent exactly; a relight of lattice entries is linear and equals the relight
//! of the same stack expanded to pixels; incremental equals full; a real bake's compressed
//! stack relights within the error budget of the uncompressed one under random edits; a
//! file with lying lattice data is refused with a specific error; a stack without lattice
//! entries is still written and read in the version-2 layout.
use crate::common;

use std::path::Path;
use std::sync::Arc;

use common::synthetic_stack::*;
use relume_engine::bake::presets::Preset;
use relume_engine::bake::settings::BounceCompression;
use relume_engine::bake::{bake_tiled, bake_tiled_banded, BakeSettings};
use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::layer_key::LayerKey;
use relume_engine::progress::Progress;
use relume_engine::relight::{tiled_sum, CpuRelighter};
use relume_engine::scene::{file::load_scene, Resolution};
use relume_engine::stack::bases::StackBases;
use relume_engine::stack::exr_file::ATTR_FORMAT_VERSION;
use relume_engine::stack::tiled::file::{read_tiled, write_tiled, write_tiled_unchecked};
use relume_engine::stack::tiled::lattice::{nodes_along, FitSign, LatticeFitter};
use relume_engine::stack::tiled::{
    tile_rect, tiles_along, TileCoefficients, TileLattice, TileRadiance, TiledStack,
    TiledStackBuilder,
};
use relume_engine::stack::Precision;
use relume_engine::{RelumeError, Rgb};

/// A bilinear field `a + b·x + c·y + d·x·y` per segment and channel.
fn bilinear(coef: [f32; 4], x: u32, y: u32) -> f32 {
    let (x, y) = (x as f32, y as f32);
    coef[0] + coef[1] * x + coef[2] * y + coef[3] * x * y
}

/// A segment map of a `w × h` tile: a diagonal split, and a third segment in one corner
/// (ids renumbered by first appearance, so a narrow tile has no gap).
fn split_map(w: u32, h: u32) -> Vec<u8> {
    let corner = (w.min(h) / 2).max(1);
    let mut raw = Vec::new();
    for y in 0..h {
        for x in 0..w {
            raw.push(if x + y < corner {
                0u8
            } else if x > y {
                1
            } else {
                2
            });
        }
    }
    let mut order: Vec<u8> = Vec::new();
    raw.iter()
        .map(|r| match order.iter().position(|o| o == r) {
            Some(i) => i as u8,
            None => {
                order.push(*r);
                order.len() as u8 - 1
            }
        })
        .collect()
}

/// Fits fields drawn by `field` (per segment and channel: a + b·x + c·y + d·x·y) on
/// `split_map(w, h)` by plain least squares and returns the worst error relative to
/// max(|value|, 1). (The sign-keeping fit is exact only where the field's values at the
/// segment's nodes, some outside its pixels, are ≥ 0 as well: see the sign tests.)
fn worst_fit_error(w: u32, h: u32, step: u32, rng: &mut Rng, bilinear_term: f32) -> f32 {
    let map = split_map(w, h);
    let lattice = TileLattice::new(step, w, h, map.clone()).unwrap();
    assert_eq!(
        lattice.node_count() as u32,
        nodes_along(w, step) * nodes_along(h, step)
    );
    let fields: Vec<[[f32; 4]; 3]> = (0..lattice.segment_count())
        .map(|_| {
            [0; 3].map(|_| {
                [
                    rng.range(-1.0, 1.0),
                    rng.range(-0.2, 0.2),
                    rng.range(-0.2, 0.2),
                    rng.range(-bilinear_term, bilinear_term),
                ]
            })
        })
        .collect();
    let mut data = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let s = map[(y * w + x) as usize] as usize;
            for field in &fields[s] {
                data.push(1.0 + bilinear(*field, x, y));
            }
        }
    }
    let fit = LatticeFitter::new(&lattice)
        .fit_with(&data, 3, FitSign::Free)
        .unwrap();
    assert_eq!(fit.mask, (1u32 << lattice.segment_count()) - 1);
    assert_eq!(
        Some(fit.coefficients.len()),
        lattice.coefficient_count(fit.mask, 3)
    );
    data.iter()
        .zip(&fit.reconstructed)
        .map(|(a, b)| (a - b).abs() / a.abs().max(1.0))
        .fold(0.0f32, f32::max)
}

#[test]
fn the_fit_reproduces_an_affine_field_on_each_segment_of_any_shape() {
    let mut rng = Rng::new(5);
    for (w, h, step) in [(16, 16, 4), (16, 16, 8), (5, 16, 4), (16, 3, 2), (1, 7, 4)] {
        for _ in 0..3 {
            let worst = worst_fit_error(w, h, step, &mut rng, 0.0);
            assert!(
                worst < 1e-4,
                "{w}×{h} step {step}: worst relative error {worst}"
            );
        }
    }
}

#[test]
fn the_fit_reproduces_a_bilinear_field_where_weak_nodes_have_neighbours_in_line() {
    // At step 4 every weakly supported node of these segments has three stored nodes in a
    // row along an axis, so its smoothness penalty is zero on a bilinear field. (A weak node
    // with none is pulled by a mixed difference, exact only for affine fields: an
    // approximation that the bake's per-entry error check covers.)
    let mut rng = Rng::new(6);
    for (w, h) in [(16, 16), (12, 16)] {
        for _ in 0..3 {
            let worst = worst_fit_error(w, h, 4, &mut rng, 0.02);
            assert!(worst < 1e-4, "{w}×{h}: worst relative error {worst}");
        }
    }
}

#[test]
fn a_lattice_covers_the_stacks_tiles() {
    assert_eq!(
        relume_engine::stack::tiled::lattice::MAX_TILE_SIDE,
        relume_engine::stack::tiled::STACK_TILE
    );
}

#[test]
fn a_full_tile_segment_is_fitted_exactly() {
    let lattice = TileLattice::new(4, 16, 16, vec![0; 256]).unwrap();
    let data: Vec<f32> = (0..256u32)
        .map(|p| 0.5 + bilinear([0.1, 0.03, -0.02, 0.004], p % 16, p / 16))
        .collect();
    let fit = LatticeFitter::new(&lattice).fit(&data, 1).unwrap();
    assert_eq!(fit.coefficients.len(), 25);
    for (a, b) in data.iter().zip(&fit.reconstructed) {
        assert!((a - b).abs() < 1e-5, "{a} vs {b}");
    }
}

/// Shapes whose plain least-squares fit dips below zero on a 16 × 16 tile of one segment:
/// a step edge inside a lattice cell, a one-pixel peak inside a cell, a bright corner.
fn undershooting_shapes(step: u32) -> Vec<(&'static str, Vec<f32>)> {
    let at = |f: &dyn Fn(u32, u32) -> f32| -> Vec<f32> {
        (0..256u32).map(|p| f(p % 16, p / 16)).collect()
    };
    vec![
        (
            "step edge",
            at(&|x, _| if x > step + 1 { 1.0 } else { 0.0 }),
        ),
        (
            "peak",
            at(&|x, y| {
                if (x, y) == (step + 1, step + 2) {
                    5.0
                } else {
                    0.0
                }
            }),
        ),
        (
            "bright corner",
            at(&|x, y| if x + y <= 2 { 2.0 } else { 0.01 }),
        ),
    ]
}

/// Σ (a − b)² over two images.
fn sq_error(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x as f64 - *y as f64).powi(2))
        .sum()
}

#[test]
fn a_step_or_a_peak_inside_a_segment_is_fitted_without_going_below_zero() {
    for step in [4, 8] {
        let lattice = TileLattice::new(step, 16, 16, vec![0; 256]).unwrap();
        let fitter = LatticeFitter::new(&lattice);
        for (name, data) in undershooting_shapes(step) {
            let free = fitter.fit_with(&data, 1, FitSign::Free).unwrap();
            let lowest_free = free.reconstructed.iter().fold(0.0f32, |m, v| m.min(*v));
            // The shape must be one plain least squares gets wrong, or this proves nothing.
            assert!(
                lowest_free < -1e-3,
                "step {step}, {name}: free fit ≥ {lowest_free}"
            );
            let kept = fitter.fit(&data, 1).unwrap();
            assert!(kept.sign_kept > 0, "step {step}, {name}");
            assert!(kept.coefficients.iter().all(|v| *v >= 0.0));
            let lowest = kept.reconstructed.iter().fold(f32::MAX, |m, v| m.min(*v));
            assert!(lowest >= 0.0, "step {step}, {name}: fit reaches {lowest}");
            // The constrained optimum: no worse than the free fit with its negative nodes
            // clamped to 0 (the cheap repair), no better than the free fit.
            let mut clamped = vec![0.0; 256];
            lattice.reconstruct(
                free.mask,
                1,
                |i| free.coefficients[i].max(0.0),
                &mut clamped,
            );
            let (e_free, e_kept, e_clamped) = (
                sq_error(&free.reconstructed, &data),
                sq_error(&kept.reconstructed, &data),
                sq_error(&clamped, &data),
            );
            assert!(
                e_free <= e_kept * (1.0 + 1e-9) && e_kept <= e_clamped * (1.0 + 1e-6),
                "step {step}, {name}: squared errors free {e_free}, kept {e_kept}, clamped {e_clamped}"
            );
        }
    }
}

#[test]
fn only_the_channels_and_segments_that_are_non_negative_are_constrained() {
    // Channel 0 a step edge ≥ 0 (constrained), channel 1 the same edge minus a constant so
    // the layer is signed there (a PCA basis' layer can be): left as plain least squares.
    let lattice = TileLattice::new(4, 16, 16, vec![0; 256]).unwrap();
    let fitter = LatticeFitter::new(&lattice);
    let edge = |x: u32| if x > 5 { 1.0f32 } else { 0.0 };
    let data: Vec<f32> = (0..256u32)
        .flat_map(|p| {
            let e = edge(p % 16);
            [e, e - 0.5, 0.2 + 0.01 * (p / 16) as f32]
        })
        .collect();
    let kept = fitter.fit(&data, 3).unwrap();
    let free = fitter.fit_with(&data, 3, FitSign::Free).unwrap();
    assert_eq!(kept.sign_kept, 1);
    for (k, f) in kept
        .reconstructed
        .chunks_exact(3)
        .zip(free.reconstructed.chunks_exact(3))
    {
        assert!(k[0] >= 0.0);
        assert_eq!(k[1], f[1]);
        // The smooth, positive third channel needs no constraint: the same fit.
        assert_eq!(k[2], f[2]);
    }
    assert!(free.reconstructed.chunks_exact(3).any(|p| p[0] < 0.0));
}

/// A stack over `w × h` with the one-bounce keys of two bases: smooth layers, the bounce
/// ones as lattice entries on the tiles where `lattice_tile(t)` says so, the rest per
/// pixel; some layers absent from some tiles, some grey.
fn lattice_stack(w: u32, h: u32, precision: Precision, seed: u64) -> TiledStack {
    let mut rng = Rng::new(seed);
    let keys = one_bounce_keys(2);
    let mut header = header(w, h);
    header.precision = precision;
    let layers: Vec<(LayerKey, u8)> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| (k.clone(), if i % 3 == 0 { 3 } else { 1 }))
        .collect();
    let builder = TiledStackBuilder::new(header, layers.clone()).unwrap();
    let count = (tiles_along(w) * tiles_along(h)) as usize;
    for t in 0..count {
        let rect = tile_rect(w, h, t);
        let map = split_map(rect.width, rect.height);
        let lattice = TileLattice::new(4, rect.width, rect.height, map).unwrap();
        let fitter = LatticeFitter::new(&lattice);
        let mut pixel_data: Vec<(u32, u8, Vec<f32>)> = Vec::new();
        let mut fits = Vec::new();
        for (l, (key, channels)) in layers.iter().enumerate() {
            if (l + t) % 5 == 0 {
                continue;
            }
            let c = *channels as usize;
            let field: Vec<[f32; 4]> = (0..c)
                .map(|_| {
                    [
                        rng.range(0.0, 2.0),
                        rng.range(-0.05, 0.05),
                        rng.range(-0.05, 0.05),
                        rng.range(-0.003, 0.003),
                    ]
                })
                .collect();
            let mut data = Vec::new();
            for y in 0..rect.height {
                for x in 0..rect.width {
                    for f in &field {
                        data.push(bilinear(*f, x, y) + rng.range(-0.05, 0.05));
                    }
                }
            }
            if key.path.len() >= 2 && t % 4 != 3 {
                let fit = fitter.fit(&data, *channels).unwrap();
                fits.push((l as u32, *channels, fit));
            } else {
                pixel_data.push((l as u32, *channels, data));
            }
        }
        let radiance: Vec<TileRadiance> = pixel_data
            .iter()
            .map(|(layer, channels, data)| TileRadiance {
                layer: *layer,
                channels: *channels,
                radiance: data,
            })
            .collect();
        let coefficients: Vec<TileCoefficients> = fits
            .iter()
            .map(|(layer, channels, fit)| TileCoefficients {
                layer: *layer,
                channels: *channels,
                segments: fit.mask,
                coefficients: &fit.coefficients,
            })
            .collect();
        builder
            .insert_with_lattice(t, &radiance, Some(lattice), &coefficients)
            .unwrap();
    }
    builder.finish().unwrap()
}

fn coefs(rng: &mut Rng) -> Vec<Vec<Rgb>> {
    random_coefs(rng, &[2, 2])
}

fn relight(stack: &TiledStack, coefs: &[Vec<Rgb>]) -> Vec<f32> {
    let weights = tiled_sum::layer_weights(stack, coefs, &[Rgb::ONE]).unwrap();
    let mut out = vec![0.0; stack.header.width as usize * stack.header.height as usize * 4];
    tiled_sum::full(stack, &weights, &mut out).unwrap();
    out
}

/// Largest |a − b| over RGB, relative to the largest |b|.
fn max_rel_diff(a: &[f32], b: &[f32]) -> f32 {
    let scale = b.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-30);
    a.iter()
        .zip(b)
        .enumerate()
        .filter(|(i, _)| i % 4 != 3)
        .map(|(_, (x, y))| (x - y).abs())
        .fold(0.0, f32::max)
        / scale
}

#[test]
fn relighting_lattice_entries_equals_relighting_them_expanded_to_pixels() {
    for (precision, tolerance) in [(Precision::F32, 2e-6), (Precision::F16, 2e-3)] {
        let stack = lattice_stack(37, 21, precision, 3);
        assert!(stack.tiles.iter().any(|t| t.lattice.is_some()));
        assert!(stack
            .tiles
            .iter()
            .flat_map(|t| &t.entries)
            .any(|e| e.segments != 0));
        let expanded = TiledStack::from_dense(&stack.to_dense().unwrap()).unwrap();
        assert!(expanded.tiles.iter().all(|t| t.lattice.is_none()));
        assert!(stack.sample_bytes() < expanded.sample_bytes());
        let mut rng = Rng::new(9);
        for _ in 0..3 {
            let c = coefs(&mut rng);
            let d = max_rel_diff(&relight(&stack, &c), &relight(&expanded, &c));
            assert!(d < tolerance, "{precision:?}: {d}");
        }
    }
}

#[test]
fn the_relight_of_lattice_entries_is_linear() {
    let stack = lattice_stack(40, 24, Precision::F32, 4);
    let mut rng = Rng::new(2);
    let n = stack.layers.len();
    let w1: Vec<Rgb> = (0..n)
        .map(|_| Rgb::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.f32()))
        .collect();
    let w2: Vec<Rgb> = (0..n)
        .map(|_| Rgb::new(rng.f32(), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)))
        .collect();
    let (a, b) = (0.7f32, -1.3f32);
    let sum = |w: &[Rgb]| {
        let mut out = vec![0.0; 40 * 24 * 4];
        tiled_sum::full(&stack, w, &mut out).unwrap();
        out
    };
    let combined: Vec<Rgb> = w1.iter().zip(&w2).map(|(x, y)| *x * a + *y * b).collect();
    let (r1, r2, r) = (sum(&w1), sum(&w2), sum(&combined));
    let expected: Vec<f32> = r1.iter().zip(&r2).map(|(x, y)| a * x + b * y).collect();
    let d = max_rel_diff(&r, &expected);
    assert!(d < 1e-5, "linearity: {d}");
    // And a lattice entry contributes: zeroing the weights of the lattice-stored bounce
    // layers changes the image.
    let no_bounce: Vec<Rgb> = stack
        .layers
        .iter()
        .zip(&w1)
        .map(|(l, w)| if l.key.path.len() >= 2 { Rgb::ZERO } else { *w })
        .collect();
    assert!(max_rel_diff(&sum(&no_bounce), &r1) > 1e-2);
}

#[test]
fn incremental_relight_of_lattice_entries_equals_the_full_one() {
    let stack = Arc::new(lattice_stack(37, 21, Precision::F16, 8));
    let mut rng = Rng::new(12);
    let mut relighter = CpuRelighter::from_tiled(stack.clone()).unwrap();
    let mut c = coefs(&mut rng);
    relighter.relight(&c).unwrap();
    for region in [0usize, 1, 0] {
        let new: Vec<Rgb> = (0..2)
            .map(|_| Rgb::new(rng.f32(), rng.f32(), rng.range(-0.5, 1.0)))
            .collect();
        let incremental = relighter.relight_region(region, &new).unwrap().to_vec();
        c[region] = new;
        let full = relight(&stack, &c);
        let d = max_rel_diff(&incremental, &full);
        assert!(d < 1e-5, "incremental vs full: {d}");
    }
}

#[test]
fn a_stack_with_lattice_entries_round_trips_through_its_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lattice.exr");
    let stack = lattice_stack(37, 21, Precision::F16, 6);
    write_tiled(&path, &stack).unwrap();
    assert_eq!(file_version(&path), 3);
    assert_eq!(read_tiled(&path).unwrap(), stack);
}

#[test]
fn a_stack_without_lattice_entries_is_written_and_read_as_version_2() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plain.exr");
    let mut rng = Rng::new(1);
    let layers = one_bounce_keys(2)
        .into_iter()
        .map(|k| random_layer(&mut rng, k, 21, 18, 1, Precision::F16, 0..3, 2))
        .collect();
    let dense = relume_engine::stack::TransferStack {
        header: header(21, 18),
        layers,
    };
    let stack = TiledStack::from_dense(&dense).unwrap();
    write_tiled(&path, &stack).unwrap();
    assert_eq!(file_version(&path), 2);
    let back = read_tiled(&path).unwrap();
    assert_eq!(
        back.header.format_version,
        relume_engine::stack::tiled::STACK_FORMAT_VERSION_TILED
    );
    assert_eq!(back, stack);
}

/// The format version attribute of a stack file.
fn file_version(path: &Path) -> i32 {
    let meta = exr::meta::MetaData::read_from_file(path, false).unwrap();
    match meta.headers[0]
        .own_attributes
        .other
        .get(&exr::meta::attribute::Text::from(ATTR_FORMAT_VERSION))
    {
        Some(exr::meta::attribute::AttributeValue::I32(v)) => *v,
        other => panic!("no format version attribute: {other:?}"),
    }
}

/// Writes `stack` unchecked and reads it back.
fn reread(stack: &TiledStack) -> relume_engine::Result<TiledStack> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("hostile.exr");
    write_tiled_unchecked(&path, stack).unwrap();
    read_tiled(&path)
}

fn format_message(r: relume_engine::Result<TiledStack>) -> String {
    match r {
        Err(RelumeError::StackFormat { message, .. }) => message,
        other => panic!("expected a StackFormat error, got {other:?}"),
    }
}

#[test]
fn lying_lattice_data_gives_a_specific_error() {
    let stack = lattice_stack(37, 21, Precision::F16, 7);
    let t = stack
        .tiles
        .iter()
        .position(|t| t.entries.iter().any(|e| e.segments != 0))
        .unwrap();
    let k = stack.tiles[t]
        .entries
        .iter()
        .position(|e| e.segments != 0)
        .unwrap();

    // A mask naming a segment the tile's map lacks.
    let mut bad = stack.clone();
    bad.tiles[t].entries[k].segments |= 1 << 31;
    let m = format_message(reread(&bad));
    assert!(m.contains("segments"), "{m}");
    assert!(relume_engine::stack::tiled::validate::validate(Path::new(""), &bad).is_err());

    // A lattice entry in a tile without a segment map (in memory).
    let mut bad = stack.clone();
    bad.tiles[t].lattice = None;
    let e = relume_engine::stack::tiled::validate::validate(Path::new(""), &bad).unwrap_err();
    assert!(e.to_string().contains("segment map"), "{e}");

    // A full tile's lattice on an edge tile: the maps no longer line up with the tiles.
    let edge = stack.tiles.len() - 1;
    assert_ne!(stack.tile_rect(edge).pixels(), 256);
    let mut bad = stack.clone();
    bad.tiles[edge].lattice = Some(TileLattice::new(4, 16, 16, vec![0; 256]).unwrap());
    let m = format_message(reread(&bad));
    assert!(m.contains("segment") || m.contains("lattice"), "{m}");

    // A non-finite coefficient.
    let mut bad = stack.clone();
    let offset = bad.tiles[t].entries[k].offset as usize;
    if let relume_engine::stack::tiled::TileValues::F16(v) = &mut bad.tiles[t].values {
        v[offset] = half::f16::NAN;
    }
    let m = format_message(reread(&bad));
    assert!(m.contains("non-finite"), "{m}");
}

/// The committed Cornell box at a small size.
fn cornell(size: u32) -> relume_engine::scene::Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/cornell.scene.json");
    let mut scene = load_scene(&path).unwrap();
    scene.resolution = Resolution {
        width: size,
        height: size,
    };
    scene
}

fn preview(size: u32, compression: BounceCompression) -> BakeSettings {
    let mut s = BakeSettings {
        threads: 2,
        seed: 3,
        bounces: 1,
        ..BakeSettings::default()
    };
    Preset::Preview.apply(&mut s);
    s.spp = 4;
    s.resolution = Some(Resolution {
        width: size,
        height: size,
    });
    s.compression = compression;
    s
}

/// ‖a − b‖ / ‖b‖ over RGB.
fn rel_l2(a: &[f32], b: &[f32]) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        if i % 4 == 3 {
            continue;
        }
        num += (*x as f64 - *y as f64).powi(2);
        den += (*y as f64).powi(2);
    }
    (num / den.max(1e-300)).sqrt()
}

#[test]
fn a_compressed_bake_relights_within_its_budget_of_the_uncompressed_one() {
    let scene = cornell(48);
    // The budget is 0.5 % relative L2 under edits: spend a little less at the
    // bake-time materials, where the tolerance is what each tile may spend.
    let budget = 0.005;
    let on = preview(
        48,
        BounceCompression {
            step: Preset::Preview.values().compression.step,
            tolerance: 0.004,
        },
    );
    let (compressed, report) = bake_tiled(&scene, &on, &Progress::new()).unwrap();
    let (plain, plain_report) = bake_tiled(
        &scene,
        &preview(48, BounceCompression::OFF),
        &Progress::new(),
    )
    .unwrap();
    assert_eq!(plain_report.compression_error, 0.0);
    assert_eq!(plain_report.compression_saved_bytes, 0);
    assert!(compressed
        .tiles
        .iter()
        .flat_map(|t| &t.entries)
        .any(|e| e.segments != 0));
    assert!(report.compression_saved_bytes > 0);
    assert_eq!(
        compressed.sample_bytes() + report.compression_saved_bytes,
        plain.sample_bytes()
    );
    assert!(
        report.compression_error > 0.0 && report.compression_error <= 0.004,
        "reported {}",
        report.compression_error
    );
    // The layers and the per-pixel layers are the same: compression is the only change.
    assert_eq!(compressed.layers.len(), plain.layers.len());
    let bake_coefs = common::bake_material_coefs(&plain.header, &scene);
    let mut rng = Rng::new(21);
    let mut a = CpuRelighter::from_tiled(Arc::new(compressed)).unwrap();
    let mut b = CpuRelighter::from_tiled(Arc::new(plain)).unwrap();
    let at_bake = rel_l2(
        a.relight(&bake_coefs).unwrap(),
        b.relight(&bake_coefs).unwrap(),
    );
    assert!(
        (at_bake - report.compression_error).abs() < 0.2 * report.compression_error + 1e-4,
        "relit {at_bake} vs reported {}",
        report.compression_error
    );
    for _ in 0..6 {
        let edited: Vec<Vec<Rgb>> = bake_coefs
            .iter()
            .map(|r| {
                r.iter()
                    .map(|c| {
                        *c * Rgb::new(
                            rng.range(0.0, 2.0),
                            rng.range(0.0, 2.0),
                            rng.range(0.0, 2.0),
                        )
                    })
                    .collect()
            })
            .collect();
        let error = rel_l2(a.relight(&edited).unwrap(), b.relight(&edited).unwrap());
        assert!(error < budget, "relit error under an edit: {error}");
    }
}

/// The editable regions' materials of `scene` with every Ks set to 0 and each Kd scaled by
/// U[0, 1.5] per channel (kept ≤ 1): a diffuse edit.
fn diffuse_edit(scene: &relume_engine::scene::Scene, rng: &mut Rng) -> Vec<MaterialSpec> {
    scene
        .regions
        .iter()
        .filter(|r| r.editable)
        .map(|r| match &r.material {
            MaterialSpec::BlinnPhong(m) => MaterialSpec::BlinnPhong(BlinnPhong {
                kd: m.kd.map(|v| (v * rng.range(0.0, 1.5)).min(1.0)),
                ks: [0.0; 3],
                ns: m.ns,
            }),
            other => other.clone(),
        })
        .collect()
}

/// The lowest relit value of `compressed` over the pixel channels where `plain` is ≥ 0,
/// relative to the largest `plain` value.
fn lowest_where_plain_is_not_negative(compressed: &[f32], plain: &[f32]) -> f32 {
    let scale = plain.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-30);
    compressed
        .iter()
        .zip(plain)
        .enumerate()
        .filter(|(i, (_, p))| i % 4 != 3 && **p >= 0.0)
        .map(|(_, (c, _))| *c)
        .fold(0.0f32, f32::min)
        / scale
}

#[test]
fn a_compressed_bake_relights_below_zero_nowhere_the_uncompressed_one_does_not() {
    // A loose tolerance, so that many bounce layers are fitted (the glossy walls' signed
    // PCA layers among them); f32 storage, so that only the fits differ.
    let scene = cornell(48);
    let settings = |compression| {
        let mut s = preview(48, compression);
        s.precision = Precision::F32;
        s
    };
    let on = BounceCompression {
        step: 4,
        tolerance: 0.1,
    };
    let (compressed, _) = bake_tiled(&scene, &settings(on), &Progress::new()).unwrap();
    let (plain, _) =
        bake_tiled(&scene, &settings(BounceCompression::OFF), &Progress::new()).unwrap();
    assert!(compressed
        .tiles
        .iter()
        .flat_map(|t| &t.entries)
        .any(|e| e.segments != 0));
    let bases = StackBases::from_header(&plain.header).unwrap();
    let bake_coefs = common::bake_material_coefs(&plain.header, &scene);
    let mut a = CpuRelighter::from_tiled(Arc::new(compressed)).unwrap();
    let mut b = CpuRelighter::from_tiled(Arc::new(plain)).unwrap();
    // Under diffuse edits every layer that counts is ≥ 0, so every fit of it keeps its
    // nodes ≥ 0 and the relit image is a sum of non-negative terms: ≥ 0 exactly.
    let mut rng = Rng::new(31);
    for _ in 0..4 {
        let coefs = bases.coefficients(&diffuse_edit(&scene, &mut rng)).unwrap();
        let plain = b.relight(&coefs).unwrap().to_vec();
        assert!(plain.iter().all(|v| *v >= 0.0));
        let lowest = a
            .relight(&coefs)
            .unwrap()
            .iter()
            .fold(0.0f32, |m, v| m.min(*v));
        assert!(lowest >= 0.0, "diffuse edit: {lowest}");
    }
    // At the bake-time materials the glossy walls' signed layers count too; the per-tile
    // guard keeps the tile image ≥ 0 where it is, before the negligible layers are dropped
    // (which it does not see) — so only about rounding and the dropped layers' share below.
    let lowest = lowest_where_plain_is_not_negative(
        a.relight(&bake_coefs).unwrap(),
        b.relight(&bake_coefs).unwrap(),
    );
    assert!(lowest >= -1e-4, "bake-time materials: {lowest}");
}

#[test]
fn a_one_pass_and_a_progressive_bake_compress_alike() {
    let scene = cornell(40);
    let mut s = preview(40, Preset::Preview.values().compression);
    s.precision = Precision::F32;
    let (a, _) = bake_tiled_banded(&scene, &s, Some(1), &Progress::new()).unwrap();
    let (b, _, _) = relume_engine::bake::bake_progressive_tiled(
        &scene,
        &s,
        &[1, s.spp],
        &Progress::new(),
        |_, _, _| Ok(()),
    )
    .unwrap();
    assert!(a.tiles.iter().any(|t| t.lattice.is_some()));
    assert_eq!(a, b);
}

/// Measurement for docs/scale.md, not a check: bakes the scene at
/// `RELUME_MEASURE_SCENE` (default: the assets' Cornell box) at `RELUME_MEASURE_RES`
/// (`WxH`) with the preset `RELUME_MEASURE_PRESET` (default preview; its eye samples
/// overridden by `RELUME_MEASURE_SPP` if set) and one bounce, once uncompressed and once per
/// (`RELUME_MEASURE_STEPS` × `RELUME_MEASURE_TOLS`), and prints per setting the stored
/// bytes, the reported and relit errors (bake-time materials and random edits) and the
/// full relight's time. Run in release on a quiet machine:
/// `cargo test --release -p relume-engine --test engine lattice_stack -- --ignored --nocapture`.
#[test]
#[ignore = "measurement for docs/scale.md: bakes cornell8 k = 8 at several steps and tolerances (minutes in release); the compression's bounds are asserted by the other tests in this file"]
fn measure_compression() {
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or_else(|_| d.to_string());
    let scene_path = env(
        "RELUME_MEASURE_SCENE",
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../assets/cornell.scene.json"
        ),
    );
    let mut scene = load_scene(Path::new(&scene_path)).unwrap();
    let res = env("RELUME_MEASURE_RES", "256x256");
    let (w, h) = res.split_once('x').unwrap();
    scene.resolution = Resolution {
        width: w.parse().unwrap(),
        height: h.parse().unwrap(),
    };
    let settings = |compression: BounceCompression| {
        let mut s = BakeSettings {
            seed: 3,
            bounces: 1,
            ..BakeSettings::default()
        };
        Preset::parse(&env("RELUME_MEASURE_PRESET", "preview"))
            .unwrap()
            .apply(&mut s);
        if let Ok(spp) = std::env::var("RELUME_MEASURE_SPP") {
            s.spp = spp.parse().unwrap();
        }
        s.resolution = Some(scene.resolution);
        s.compression = compression;
        s
    };
    let time_full = |stack: &TiledStack, coefs: &[Vec<Rgb>]| -> f64 {
        let weights = tiled_sum::layer_weights(stack, coefs, &[Rgb::ONE; 64][..]).unwrap();
        let mut out = vec![0.0; stack.header.width as usize * stack.header.height as usize * 4];
        (0..7)
            .map(|_| {
                let t = std::time::Instant::now();
                tiled_sum::full(stack, &weights, &mut out).unwrap();
                t.elapsed().as_secs_f64() * 1e3
            })
            .fold(f64::INFINITY, f64::min)
    };
    let started = std::time::Instant::now();
    let (plain, plain_report) =
        bake_tiled(&scene, &settings(BounceCompression::OFF), &Progress::new()).unwrap();
    let plain_seconds = started.elapsed().as_secs_f64();
    let bake_coefs = common::bake_material_coefs(&plain.header, &scene);
    let mut rng = Rng::new(77);
    let edits: Vec<Vec<Vec<Rgb>>> = (0..8)
        .map(|_| {
            bake_coefs
                .iter()
                .map(|r| {
                    r.iter()
                        .map(|c| {
                            *c * Rgb::new(
                                rng.range(0.0, 2.0),
                                rng.range(0.0, 2.0),
                                rng.range(0.0, 2.0),
                            )
                        })
                        .collect()
                })
                .collect()
        })
        .collect();
    let mut plain_relighter = CpuRelighter::from_tiled(Arc::new(plain.clone())).unwrap();
    let plain_images: Vec<Vec<f32>> = std::iter::once(&bake_coefs)
        .chain(&edits)
        .map(|c| plain_relighter.relight(c).unwrap().to_vec())
        .collect();
    println!(
        "{{\"res\":\"{res}\",\"step\":0,\"stored_mb\":{:.1},\"memory_mb\":{:.1},\"bake_s\":{plain_seconds:.1},\"relight_full_min_ms\":{:.2},\"layers\":{},\"entries\":{}}}",
        plain.sample_bytes() as f64 / 1e6,
        plain.memory_bytes() as f64 / 1e6,
        time_full(&plain, &bake_coefs),
        plain.layers.len(),
        plain.entry_count(),
    );
    drop(plain_relighter);
    let _ = plain_report;
    let by_len = |stack: &TiledStack| {
        let bytes = stack.layer_bytes();
        let mut out = [0usize; 3];
        for (l, b) in stack.layers.iter().zip(bytes) {
            out[l.key.path.len().min(2)] += b;
        }
        out.map(|b| (b as f64 / 1e6 * 10.0).round() / 10.0)
    };
    println!("{{\"plain_mb_by_path_len\":{:?}}}", by_len(&plain));
    for step in env("RELUME_MEASURE_STEPS", "4").split(',') {
        for tol in env("RELUME_MEASURE_TOLS", "0.02").split(',') {
            let compression = BounceCompression {
                step: step.parse().unwrap(),
                tolerance: tol.parse().unwrap(),
            };
            let started = std::time::Instant::now();
            let (stack, report) =
                bake_tiled(&scene, &settings(compression), &Progress::new()).unwrap();
            let seconds = started.elapsed().as_secs_f64();
            let lattice_entries = stack
                .tiles
                .iter()
                .flat_map(|t| &t.entries)
                .filter(|e| e.segments != 0)
                .count();
            let mut relighter = CpuRelighter::from_tiled(Arc::new(stack.clone())).unwrap();
            // Per image (bake-time materials, then the edits): the relit error, and the pixel
            // channels that are < 0 where the uncompressed image is ≥ 0 and the lowest of them.
            let mut negatives = Vec::new();
            let errors: Vec<f64> = std::iter::once(&bake_coefs)
                .chain(&edits)
                .zip(&plain_images)
                .map(|(c, reference)| {
                    let image = relighter.relight(c).unwrap();
                    let below = image
                        .iter()
                        .zip(reference)
                        .enumerate()
                        .filter(|(i, (v, r))| i % 4 != 3 && **r >= 0.0 && **v < 0.0)
                        .count();
                    negatives.push((below, lowest_where_plain_is_not_negative(image, reference)));
                    rel_l2(image, reference)
                })
                .collect();
            println!(
                "{{\"negative_pixel_channels_bake\":{},\"negative_pixel_channels_edits\":{},\"lowest_rel_bake\":{:.3e},\"lowest_rel_edits\":{:.3e}}}",
                negatives[0].0,
                negatives[1..].iter().map(|n| n.0).sum::<usize>(),
                negatives[0].1,
                negatives[1..].iter().map(|n| n.1).fold(0.0f32, f32::min),
            );
            let edit_errors = &errors[1..];
            println!("{{\"mb_by_path_len\":{:?}}}", by_len(&stack));
            println!(
                "{{\"res\":\"{res}\",\"step\":{step},\"tolerance\":{tol},\"stored_mb\":{:.1},\"memory_mb\":{:.1},\"saved_mb\":{:.1},\"bake_s\":{seconds:.1},\"relight_full_min_ms\":{:.2},\"lattice_entries\":{lattice_entries},\"entries\":{},\"reported_error\":{:.5},\"relit_error_bake_materials\":{:.5},\"relit_error_edits_max\":{:.5},\"relit_error_edits_mean\":{:.5}}}",
                stack.sample_bytes() as f64 / 1e6,
                stack.memory_bytes() as f64 / 1e6,
                report.compression_saved_bytes as f64 / 1e6,
                time_full(&stack, &bake_coefs),
                stack.entry_count(),
                report.compression_error,
                errors[0],
                edit_errors.iter().cloned().fold(0.0, f64::max),
                edit_errors.iter().sum::<f64>() / edit_errors.len() as f64,
            );
        }
    }
}
