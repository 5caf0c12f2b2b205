//! Unit tests that need the crate-private kernel choice; the behavioural tests are in
//! `core/engine/tests/relight_*.rs`.

use std::sync::Arc;

use super::kernels::Kernels;
use super::*;
use crate::brdf::{BlinnPhong, MaterialSpec};
use crate::layer_key::{LayerKey, PathVertex};
use crate::stack::{
    Layer, Precision, RegionInfo, StackHeader, TransferStack, STACK_FORMAT_VERSION,
};
use crate::Rgb;

fn header(width: u32, height: u32) -> StackHeader {
    let camera = serde_json::from_str(
        r#"{"projection":"perspective","matrix_world":[[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}"#,
    )
    .unwrap();
    let region = |name: &str, editable| RegionInfo {
        name: name.into(),
        editable,
        material: MaterialSpec::BlinnPhong(BlinnPhong {
            kd: [0.5; 3],
            ks: [0.1; 3],
            ns: 10.0,
        }),
        basis: None,
        textured: false,
        subsurface: None,
        principled_basis: None,
        principled_basis_with_bake_lobe: None,
    };
    StackHeader {
        format_version: STACK_FORMAT_VERSION,
        width,
        height,
        camera,
        spp: 1,
        light_samples: 1,
        bounce_light_samples: None,
        diffuse_bounces: None,
        glossy_bounces: None,
        bounces: 1,
        sampling: "uniform".into(),
        seed: 0,
        regions: vec![region("A", true), region("Walls", false), region("B", true)],
        lights: vec![],
        scene_hash: String::new(),
        precision: Precision::F16,
        light_tint: [1.0; 3],
        light_groups: Vec::new(),
        denoise: Default::default(),
        bounce_cap: 0,
    }
}

/// The SIMD kernels and the portable ones give the same image (up to FMA's single rounding)
/// on odd widths (tails), partial spans, f16 and f32, grey and RGB, full and incremental.
#[test]
fn simd_and_portable_paths_agree() {
    let (w, h) = (37u32, 21u32);
    let e = |region, basis| PathVertex::Editable { region, basis };
    let keys = [
        vec![],
        vec![PathVertex::Fixed],
        vec![e(0, 0)],
        vec![e(0, 1), e(1, 0)],
        vec![e(1, 2), PathVertex::Fixed],
    ];
    let mut layers = Vec::new();
    let mut names = std::collections::HashSet::new();
    let mut x = 12345u32;
    for (i, k) in keys.iter().enumerate() {
        for (j, (ch, prec)) in [
            (1u32, Precision::F16),
            (3, Precision::F32),
            (3, Precision::F16),
        ]
        .into_iter()
        .enumerate()
        {
            // Layer names are unique in a stack: the variants differ by trailing fixed
            // vertices, which weigh 1.
            let mut key = k.clone();
            key.extend(std::iter::repeat_n(PathVertex::Fixed, j));
            if !names.insert(LayerKey::new(key.clone()).layer_name()) {
                continue;
            }
            let vals: Vec<f32> = (0..(w * h * ch) as usize)
                .map(|j| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    // Zero the left third of every row of some layers: partial spans.
                    if i % 2 == 1 && ((j / ch as usize) % w as usize).is_multiple_of(3) {
                        0.0
                    } else {
                        (x % 1000) as f32 / 250.0 - 1.0
                    }
                })
                .collect();
            layers.push(Layer::from_f32(LayerKey::new(key), ch, &vals, prec));
        }
    }
    let stack = Arc::new(TransferStack {
        header: header(w, h),
        layers,
    });
    let fast = Kernels::detect();
    let mut a = CpuRelighter::with_kernels(stack.clone(), fast).unwrap();
    let mut b = CpuRelighter::with_kernels(stack, Kernels::Portable).unwrap();
    let coefs = vec![
        vec![Rgb::new(0.3, 0.5, 0.7), Rgb::new(-0.2, 0.1, 0.4)],
        vec![
            Rgb::new(0.9, 0.2, 0.1),
            Rgb::splat(0.5),
            Rgb::new(0.05, -0.3, 0.6),
        ],
    ];
    let check = |a: &[f32], b: &[f32]| {
        let scale = b.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        for (i, (x, y)) in a.iter().zip(b).enumerate() {
            assert!((x - y).abs() <= 2e-6 * scale, "pixel value {i}: {x} vs {y}");
        }
    };
    let ia = a.relight(&coefs).unwrap().to_vec();
    let ib = b.relight(&coefs).unwrap().to_vec();
    check(&ia, &ib);
    let c1 = vec![Rgb::new(0.1, 0.2, 0.3), Rgb::ZERO, Rgb::ONE];
    let ia = a.relight_region(1, &c1).unwrap().to_vec();
    let ib = b.relight_region(1, &c1).unwrap().to_vec();
    check(&ia, &ib);
}

/// A tiled stack over `w × h` mixing every kind of entry: per-pixel grey and RGB, lattice
/// grey and RGB over one or three segments per tile (steps 3 and 4 alternating, so the
/// lattice shape changes between tiles), layers absent from some tiles; random values.
fn mixed_tiled_stack(w: u32, h: u32, precision: Precision) -> crate::stack::tiled::TiledStack {
    use crate::stack::tiled::{
        tile_rect, tiles_along, TileCoefficients, TileLattice, TileRadiance, TiledStackBuilder,
    };
    let mut x = 2463534242u32;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        (x % 2000) as f32 / 1000.0 - 1.0
    };
    let e = |region, basis| PathVertex::Editable { region, basis };
    let layers: Vec<(LayerKey, u8)> = (0..64u16)
        .map(|i| {
            let key = LayerKey::new(vec![e(i % 2, (i / 2) % 4), e((i / 8) % 2, i / 16)]);
            (key, if i % 3 == 0 { 3 } else { 1 })
        })
        .collect();
    let mut head = header(w, h);
    head.precision = precision;
    let builder = TiledStackBuilder::new(head, layers.clone()).unwrap();
    for t in 0..(tiles_along(w) * tiles_along(h)) as usize {
        let rect = tile_rect(w, h, t);
        let (tw, th) = (rect.width, rect.height);
        // Every third tile one segment, the others three.
        let split = t % 3 != 0;
        let map: Vec<u8> = (0..th)
            .flat_map(|y| {
                (0..tw).map(move |x| match (split, x < tw / 2, y < th / 2) {
                    (false, _, _) => 0,
                    (true, true, _) => 0,
                    (true, false, true) => 1,
                    (true, false, false) => 2,
                })
            })
            .collect();
        let lattice = TileLattice::new(3 + (t as u32 % 2), tw, th, map).unwrap();
        let mut pixels = Vec::new();
        let mut fitted = Vec::new();
        for (i, (_, channels)) in layers.iter().enumerate() {
            if (i + t) % 4 == 0 {
                continue;
            }
            if (i + t) % 3 != 0 {
                let mask = if split {
                    1 + (i as u32 + t as u32) % 7
                } else {
                    1
                };
                let n = lattice.coefficient_count(mask, *channels).unwrap();
                fitted.push((
                    i as u32,
                    *channels,
                    mask,
                    (0..n).map(|_| next()).collect::<Vec<f32>>(),
                ));
            } else {
                let n = rect.pixels() * *channels as usize;
                pixels.push((
                    i as u32,
                    *channels,
                    (0..n).map(|_| next()).collect::<Vec<f32>>(),
                ));
            }
        }
        let radiance: Vec<TileRadiance> = pixels
            .iter()
            .map(|(layer, channels, v)| TileRadiance {
                layer: *layer,
                channels: *channels,
                radiance: v,
            })
            .collect();
        let coefficients: Vec<TileCoefficients> = fitted
            .iter()
            .map(|(layer, channels, mask, v)| TileCoefficients {
                layer: *layer,
                channels: *channels,
                segments: *mask,
                coefficients: v,
            })
            .collect();
        builder
            .insert_with_lattice(t, &radiance, Some(lattice), &coefficients)
            .unwrap();
    }
    builder.finish().unwrap()
}

/// `Σ weights · value` per pixel in f64, entry by entry through [`TiledStack::value`] (a
/// lattice entry evaluated at each pixel): the reference of the tiled sum.
fn reference_sum(stack: &crate::stack::tiled::TiledStack, weights: &[Rgb]) -> Vec<f64> {
    let w = stack.header.width as usize;
    let mut out = vec![0.0f64; w * stack.header.height as usize * 4];
    for (t, tile) in stack.tiles.iter().enumerate() {
        let rect = stack.tile_rect(t);
        for (k, e) in tile.entries.iter().enumerate() {
            let wt = weights[e.layer as usize].to_array();
            for p in 0..rect.pixels() {
                let (x, y) = (
                    rect.x0 as usize + p % rect.width as usize,
                    rect.y0 as usize + p / rect.width as usize,
                );
                for c in 0..3 {
                    out[(y * w + x) * 4 + c] += wt[c] as f64 * stack.value(t, k, p, c) as f64;
                }
            }
        }
    }
    out
}

fn rel_l2(image: &[f32], reference: &[f64]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for (i, (a, b)) in image.iter().zip(reference).enumerate() {
        if i % 4 == 3 {
            assert_eq!(*a, 1.0, "alpha");
            continue;
        }
        num += (*a as f64 - b) * (*a as f64 - b);
        den += b * b;
    }
    (num / den).sqrt()
}

/// Per-pixel and lattice entries, grey and RGB, f16 and f32, edge tiles: the tiled sum with
/// the SIMD and the portable loops equals the entry-by-entry reference, and incremental
/// sums of one changed layer (searched per tile) and of every layer (looked up per entry)
/// equal a full sum at the new weights.
/// An edit's sum over the entries listed for its layers ([`super::region_entries`]) adds
/// the same terms in the same order as the sum that walks every table: the same image, bit
/// for bit, on every kind of entry and both precisions; layers left out of the list are not
/// added even where their delta is not zero.
#[test]
fn listed_edit_sum_equals_the_walked_one() {
    use super::region_entries::RegionEntries;
    use super::tiled_sum::{full_with, incremental_listed, incremental_with};
    let (w, h) = (37u32, 21u32);
    for precision in [Precision::F16, Precision::F32] {
        let stack = mixed_tiled_stack(w, h, precision);
        let n = stack.layers.len();
        let weights: Vec<Rgb> = (0..n)
            .map(|l| Rgb::new(0.3 + 0.01 * l as f32, -0.2, 1.0 - 0.02 * l as f32))
            .collect();
        // Every other layer edited (enough for the walked sum to walk the tables), one of
        // them by zero; the deltas of the others are set too, and must be ignored.
        let edited: Vec<u32> = (0..n as u32).filter(|l| l % 2 == 1).collect();
        let deltas: Vec<Rgb> = (0..n)
            .map(|l| match l {
                1 => Rgb::ZERO,
                _ => Rgb::new(0.1 * l as f32, -0.3, 0.05 + 0.02 * l as f32),
            })
            .collect();
        let changed: Vec<(u32, Rgb)> = edited.iter().map(|&l| (l, deltas[l as usize])).collect();
        let listed = RegionEntries::build(&stack, &edited).unwrap().unwrap();
        for kernels in Kernels::available() {
            let mut walked = vec![0.0f32; (w * h * 4) as usize];
            full_with(&stack, &weights, &mut walked, kernels).unwrap();
            let mut by_list = walked.clone();
            incremental_with(&stack, &changed, &mut walked, kernels).unwrap();
            incremental_listed(&stack, &listed, &deltas, &mut by_list, kernels).unwrap();
            assert!(
                walked
                    .iter()
                    .zip(&by_list)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{precision:?} {kernels:?}: the listed sum differs from the walked one"
            );
        }
    }
}

#[test]
fn tiled_sum_matches_the_reference_on_every_kind_of_entry_and_path() {
    use super::tiled_sum::{full_with, incremental_with};
    let (w, h) = (37u32, 21u32);
    for precision in [Precision::F16, Precision::F32] {
        let stack = mixed_tiled_stack(w, h, precision);
        let entries = stack.tiles.iter().flat_map(|t| &t.entries);
        assert!(entries.clone().any(|e| e.segments != 0 && e.channels == 3));
        assert!(entries.clone().any(|e| e.segments != 0 && e.channels == 1));
        assert!(entries.clone().any(|e| e.segments == 0 && e.channels == 3));
        assert!(entries.clone().any(|e| e.segments == 0 && e.channels == 1));
        let n = stack.layers.len();
        let weights: Vec<Rgb> = (0..n)
            .map(|l| Rgb::new(0.3 + 0.01 * l as f32, -0.2, 1.0 - 0.02 * l as f32))
            .collect();
        let one: Vec<(u32, Rgb)> = vec![(5, Rgb::new(0.5, -1.0, 0.25))];
        let all: Vec<(u32, Rgb)> = (0..n as u32)
            .map(|l| (l, Rgb::new(0.1, 0.2 * (l % 3) as f32, -0.05)))
            .collect();
        let reference = reference_sum(&stack, &weights);
        let mut vector_images = Vec::new();
        for kernels in Kernels::available() {
            let mut image = vec![0.0f32; (w * h * 4) as usize];
            full_with(&stack, &weights, &mut image, kernels).unwrap();
            let err = rel_l2(&image, &reference);
            assert!(err < 1e-6, "{precision:?} {kernels:?}: full {err}");
            if kernels != Kernels::Portable {
                vector_images.push(image.clone());
            }
            let mut current = weights.clone();
            for changed in [&one, &all] {
                incremental_with(&stack, changed, &mut image, kernels).unwrap();
                for (l, d) in changed.iter() {
                    current[*l as usize] += *d;
                }
                let err = rel_l2(&image, &reference_sum(&stack, &current));
                let what = if changed.len() == 1 {
                    "one layer"
                } else {
                    "every layer"
                };
                assert!(
                    err < 1e-6,
                    "{precision:?} {kernels:?}: incremental, {what}: {err}"
                );
            }
        }
        // The AVX2 loops and the ones with 512-bit steps do the same additions per lane in
        // the same order: the same image, bit for bit.
        if let Some((first, rest)) = vector_images.split_first() {
            for image in rest {
                assert!(
                    image
                        .iter()
                        .zip(first)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    "{precision:?}: the vector implementations differ"
                );
            }
        }
    }
}
