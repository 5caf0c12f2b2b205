//! The GPU relight of the tiled layout on what a bake rarely produces: a synthetic stack
//! (the Cornell box's header and layers, random tiles) mixing grey and RGB entries (an RGB
//! layer stored grey in some tiles), per-entry scales over six decades, f16 subnormals
//! under a large scale, an empty tile and partial edge tiles, in f16 and f32, in one chunk
//! and in many. Then: an incremental image equals the full relight of the same materials,
//! and the GPU holds the stack's bytes plus the image and the weights, no more.

mod common;

use std::path::Path;
use std::sync::Arc;

use common::*;
use relume_engine::relight::CpuRelighter;
use relume_engine::stack::tiled::validate::validate;
use relume_engine::stack::tiled::{StackTile, TileLayer, TileValues, TiledStack};
use relume_engine::stack::Precision;
use relume_gpu::{GpuOptions, GpuRelighter};

/// xorshift64*: deterministic randomness without a dependency.
struct Rng(u64);
impl Rng {
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

/// The Cornell box's layers at 69×37 (5 × 3 tiles; the last column 5 pixels wide, the
/// last row 5 high) with random tiles in `precision`: tile 1 empty; elsewhere each layer
/// present with probability ½, an RGB layer stored RGB or grey, scales in [10⁻³, 10³],
/// values in [−1, 4) with some −0; layer 0, where present, holds f16 subnormals only
/// (6·10⁻⁸ … 6·10⁻⁵) under a scale of 10³, so that a driver flushing them would show.
fn synthetic(precision: Precision, seed: u64) -> Arc<TiledStack> {
    let (_, base) = asset_tiled_sized("cornell", 69, 37, precision);
    let mut stack = (*base).clone();
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    for t in 0..stack.tiles.len() {
        let pixels = stack.tile_rect(t).pixels();
        let mut entries = Vec::new();
        let mut values = Vec::new();
        for (l, info) in stack.layers.iter().enumerate() {
            if t == 1 || rng.f32() < 0.5 {
                continue;
            }
            let channels = if info.channels == 3 && rng.f32() < 0.6 {
                3
            } else {
                1
            };
            let subnormal = l == 0 && precision == Precision::F16;
            let scale = if subnormal {
                1e3
            } else {
                10f32.powf(rng.range(-3.0, 3.0))
            };
            entries.push(TileLayer {
                layer: l as u32,
                channels,
                scale,
                offset: values.len() as u32,
                segments: 0,
            });
            for _ in 0..pixels * channels as usize {
                let v = match rng.f32() {
                    _ if subnormal => rng.range(1.0, 1023.0).floor() * 2f32.powi(-24),
                    r if r < 0.05 => -0.0,
                    _ => rng.range(-1.0, 4.0),
                };
                values.push(v);
            }
        }
        stack.tiles[t] = StackTile {
            entries,
            values: match precision {
                Precision::F16 => {
                    TileValues::F16(values.iter().map(|&v| half::f16::from_f32(v)).collect())
                }
                Precision::F32 => TileValues::F32(values),
            },
            lattice: None,
        };
    }
    validate(Path::new(""), &stack).unwrap();
    assert!(stack.tiles[1].entries.is_empty());
    Arc::new(stack)
}

/// Full relight then 8 edits cycling over the regions, GPU against CPU after each step.
fn agree(name: &str, stack: &Arc<TiledStack>, gpu: &mut GpuRelighter) {
    let mut cpu = CpuRelighter::from_tiled(stack.clone()).unwrap();
    let (bases, coefs) = default_coefs(&stack.header);
    let e = rel_l2(gpu.relight(&coefs).unwrap(), cpu.relight(&coefs).unwrap());
    assert!(e <= TOLERANCE, "{name}, full: relative L2 {e:.3e}");
    assert_eq!(gpu.last_stats(), cpu.last_stats(), "{name}");
    let mut worst = e;
    for k in 0..8 {
        let region = k % gpu.editable_count();
        let c = edit(&bases, region, k);
        let e = rel_l2(
            gpu.relight_region(region, &c).unwrap(),
            cpu.relight_region(region, &c).unwrap(),
        );
        assert!(e <= TOLERANCE, "{name}, edit {k}: relative L2 {e:.3e}");
        assert_eq!(gpu.last_stats(), cpu.last_stats(), "{name}, edit {k}");
        worst = worst.max(e);
    }
    eprintln!("{name}: worst GPU/CPU relative L2 {worst:.2e}");
}

#[test]
fn synthetic_stacks_agree_in_one_chunk_and_in_many() {
    let Some(adapter) = gpu_or_skip("synthetic_stacks_agree_in_one_chunk_and_in_many") else {
        return;
    };
    for precision in [Precision::F16, Precision::F32] {
        let stack = synthetic(precision, 7);
        let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
        assert_eq!(gpu.layer_bytes_and_chunks().1, 1);
        agree(&format!("{precision:?}, one chunk"), &stack, &mut gpu);
        // Chunks the size of the fullest tile: about one 16×16 tile a chunk, 2–3 groups.
        let largest = stack.tiles.iter().map(|t| t.values.bytes()).max().unwrap() as u64;
        let options = GpuOptions {
            max_chunk_bytes: Some(largest.div_ceil(4) * 4),
            timestamps: false,
        };
        let mut gpu = GpuRelighter::new(stack.clone(), &adapter, options).unwrap();
        let chunks = gpu.layer_bytes_and_chunks().1;
        assert!(
            chunks > relume_gpu::layout::CHUNKS_PER_GROUP,
            "{chunks} chunks"
        );
        agree(&format!("{precision:?}, {chunks} chunks"), &stack, &mut gpu);
    }
}

/// The subnormal layer is decoded, not flushed: with layer 0 alone weighted, the GPU
/// image equals the CPU's and is not black.
#[test]
fn f16_subnormals_are_summed_not_flushed() {
    let Some(adapter) = gpu_or_skip("f16_subnormals_are_summed_not_flushed") else {
        return;
    };
    let stack = synthetic(Precision::F16, 11);
    // Keep layer 0 only: the first entry of a tile, when present, values from 0.
    let mut only = (*stack).clone();
    for t in 0..only.tiles.len() {
        let pixels = only.tile_rect(t).pixels();
        let tile = &mut only.tiles[t];
        let n = match tile.entries.first() {
            Some(e) if e.layer == 0 => pixels * e.channels as usize,
            _ => 0,
        };
        tile.entries.truncate(usize::from(n > 0));
        if let TileValues::F16(v) = &mut tile.values {
            v.truncate(n);
        }
    }
    let only = Arc::new(only);
    validate(Path::new(""), &only).unwrap();
    let (_, coefs) = default_coefs(&only.header);
    let mut cpu = CpuRelighter::from_tiled(only.clone()).unwrap();
    let mut gpu = GpuRelighter::new(only.clone(), &adapter, GpuOptions::default()).unwrap();
    // rel_l2 refuses a black reference, so this also proves the layer adds light.
    let e = rel_l2(gpu.relight(&coefs).unwrap(), cpu.relight(&coefs).unwrap());
    assert!(e <= TOLERANCE, "subnormal layer: relative L2 {e:.3e}");
}

/// After several incremental edits the GPU image equals a fresh full relight of the same
/// materials on the GPU (the drift the bookkeeping bounds, far below the tolerance here).
#[test]
fn incremental_equals_full() {
    let Some(adapter) = gpu_or_skip("incremental_equals_full") else {
        return;
    };
    let (name, stack) = asset_tiled("cornell", Precision::F16);
    let (bases, mut coefs) = default_coefs(&stack.header);
    let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
    gpu.relight(&coefs).unwrap();
    for k in 0..10 {
        let region = k % gpu.editable_count();
        coefs[region] = edit(&bases, region, k);
        gpu.relight_region(region, &coefs[region]).unwrap();
        assert!(gpu.last_stats().incremental);
    }
    let incremental = gpu.image().to_vec();
    let full = gpu.relight(&coefs).unwrap();
    let e = rel_l2(&incremental, full);
    assert!(
        e <= TOLERANCE,
        "{name}: incremental vs full relative L2 {e:.3e}"
    );
}

/// The GPU holds the stack as stored — its values (padded to a whole word per chunk) and
/// 16 bytes per entry and 8 per tile of tables, no more than the stack takes in host
/// memory — plus the image (16 bytes a pixel), the weights (16 bytes a layer) and the
/// image's read-back copy.
#[test]
fn gpu_memory_is_the_stack_plus_image_and_weights() {
    let Some(adapter) = gpu_or_skip("gpu_memory_is_the_stack_plus_image_and_weights") else {
        return;
    };
    for precision in [Precision::F16, Precision::F32] {
        let (name, stack) = asset_tiled("cornell", precision);
        let gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
        let m = gpu.memory();
        let pixels = (stack.header.width * stack.header.height) as u64;
        let samples = stack.sample_bytes() as u64;
        assert_eq!(
            m.values,
            samples.div_ceil(4).max(1) * 4,
            "{name}: one chunk"
        );
        assert_eq!(
            m.tables,
            // Tile starts and lattice pointers; no tile has a lattice (no compression).
            4 * (2 * stack.tiles.len() as u64 + 1) + 16 * stack.entry_count() as u64,
            "{name}"
        );
        assert!(m.stack() <= stack.memory_bytes() as u64, "{name}: {m:?}");
        assert_eq!(m.image, 16 * pixels, "{name}");
        assert_eq!(m.weights, 16 * stack.layers.len() as u64, "{name}");
        assert_eq!(m.readback, m.image, "{name}: no timestamps");
        assert!(m.other <= 256, "{name}: {m:?}");
        eprintln!(
            "{name}: GPU {} B = stack {} B (host {} B, dense {} B of samples) + image {} B + \
             weights {} B + read-back {} B + {} B",
            m.total(),
            m.stack(),
            stack.memory_bytes(),
            stack.dense_sample_bytes(),
            m.image,
            m.weights,
            m.readback,
            m.other
        );
    }
}
