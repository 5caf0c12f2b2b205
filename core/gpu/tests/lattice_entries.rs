//! Lattice entries on the GPU: on compressed bakes of the assets scenes (the draft and
//! preview presets' bounce compression) and on synthetic stacks mixing per-pixel and
//! lattice entries (f16 and f32, edge tiles, up to 32 segments a tile), the GPU relight
//! matches the CPU tiled relight within 1e-6 relative L2, full and incremental; a tile whose
//! lattice exceeds the kernel's workgroup memory is refused with a clear error, and `auto`
//! falls back to the CPU; the GPU holds the stack as stored.

mod common;

use std::sync::Arc;

use common::*;
use relume_engine::bake::bake_tiled;
use relume_engine::bake::presets::Preset;
use relume_engine::progress::Progress;
use relume_engine::stack::tiled::lattice::nodes_along;
use relume_engine::stack::tiled::validate::validate;
use relume_engine::stack::tiled::{TileLattice, TileValues, TiledStack};
use relume_engine::stack::Precision;
use relume_gpu::device::is_real_gpu;
use relume_gpu::lattice::{block_words, MAX_NODE_SLOTS};
use relume_gpu::tiles::ENTRY_BATCH;
use relume_gpu::{DeviceKind, DevicePreference, GpuError, GpuOptions, GpuRelighter, Relighter};

fn lattice_entries(stack: &TiledStack) -> usize {
    stack
        .tiles
        .iter()
        .flat_map(|t| &t.entries)
        .filter(|e| e.segments != 0)
        .count()
}

/// Asset `name` baked at 40 × 24 (edge tiles 8 pixels wide and high) with `preset`'s
/// bounce compression.
fn compressed(name: &str, preset: Preset, precision: Precision) -> (String, Arc<TiledStack>) {
    let mut settings = small_bake(40, 24, precision);
    settings.compression = preset.values().compression;
    let (stack, _) = bake_tiled(&scene(name), &settings, &Progress::new())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    (
        format!("{name} {} ({precision:?})", preset.name()),
        Arc::new(stack),
    )
}

#[test]
fn compressed_bakes_agree_full_and_incremental() {
    let Some(adapter) = gpu_or_skip("compressed_bakes_agree_full_and_incremental") else {
        return;
    };
    let mut latticed = 0;
    for (preset, precision) in [
        (Preset::Preview, Precision::F16),
        (Preset::Draft, Precision::F32),
    ] {
        for name in ["cornell", "ring"] {
            let (name, stack) = compressed(name, preset, precision);
            latticed += lattice_entries(&stack);
            let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default())
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            let worst = compare_with_cpu(&name, &stack, &mut gpu, 4);
            eprintln!(
                "{name}: {} lattice entries of {}, worst GPU vs CPU {worst:.2e}",
                lattice_entries(&stack),
                stack.entry_count()
            );
        }
    }
    assert!(
        latticed > 0,
        "no bake held a lattice entry: the test proves nothing"
    );
}

/// A small deterministic generator (splitmix64), so the synthetic stacks need no crate.
struct Mix(u64);

impl Mix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// `stack` with a lattice on most tiles (steps 3, 4, 5, 8 and 16; 1 to 32 segments, as
/// many as the kernel holds at that step) and every other entry of those tiles turned into
/// a lattice entry over a random set of segments with random coefficients. Per-pixel entries
/// keep their values.
fn with_lattices(stack: &TiledStack, seed: u64) -> TiledStack {
    let mut rng = Mix(seed);
    let mut out = stack.clone();
    for (t, tile) in out.tiles.iter_mut().enumerate() {
        if t % 4 == 3 || tile.entries.is_empty() {
            continue;
        }
        let rect = stack.tile_rect(t);
        let (w, h) = (rect.width, rect.height);
        let step = [4, 3, 8, 5, 16][t % 5];
        let nodes = (nodes_along(w, step) * nodes_along(h, step)) as usize;
        let most = (MAX_NODE_SLOTS / nodes).min(32).min(rect.pixels());
        // The first tile takes the most segments its step allows (32 at step 4).
        let segments = if t == 0 {
            most
        } else {
            1 + rng.below(most as u64) as usize
        };
        let mut map: Vec<u8> = (0..rect.pixels())
            .map(|_| rng.below(segments as u64) as u8)
            .collect();
        for s in 0..segments {
            map[(s * 7) % rect.pixels()] = s as u8;
        }
        // Every id must own a pixel: place them where the scatter above left them unique.
        let mut ids: Vec<u8> = map.clone();
        ids.sort_unstable();
        ids.dedup();
        if ids.len() != segments {
            for (p, s) in map.iter_mut().enumerate() {
                *s = (p % segments) as u8;
            }
        }
        let lattice = TileLattice::new(step, w, h, map).unwrap();
        let old: Vec<f32> = (0..tile.values.len()).map(|i| tile.values.get(i)).collect();
        let mut values = Vec::new();
        for (k, e) in tile.entries.iter_mut().enumerate() {
            let count = tile_value_count(rect.pixels(), e.channels);
            let start = e.offset as usize;
            let own = &old[start..start + count];
            e.offset = values.len() as u32;
            if k % 2 == 1 {
                let all = if segments == 32 {
                    u32::MAX
                } else {
                    (1u32 << segments) - 1
                };
                let mask = ((rng.next() as u32) & all).max(1);
                e.segments = mask;
                let n = lattice.coefficient_count(mask, e.channels).unwrap();
                values.extend((0..n).map(|_| 2.0 * rng.unit() - 0.25));
            } else {
                values.extend_from_slice(own);
            }
        }
        tile.values = match tile.values {
            TileValues::F16(_) => {
                TileValues::F16(values.iter().map(|&v| half::f16::from_f32(v)).collect())
            }
            TileValues::F32(_) => TileValues::F32(values),
        };
        tile.lattice = Some(lattice);
    }
    validate(std::path::Path::new(""), &out).expect("the synthetic stack is valid");
    out
}

/// Values of a per-pixel entry (the bakes store none other).
fn tile_value_count(pixels: usize, channels: u8) -> usize {
    pixels * channels as usize
}

#[test]
fn synthetic_mixed_stacks_agree_full_and_incremental() {
    let Some(adapter) = gpu_or_skip("synthetic_mixed_stacks_agree_full_and_incremental") else {
        return;
    };
    for precision in [Precision::F16, Precision::F32] {
        let (name, stack) = asset_tiled_sized("textured", 70, 37, precision);
        assert_eq!(lattice_entries(&stack), 0, "{name}: baked uncompressed");
        let stack = Arc::new(with_lattices(&stack, 7));
        assert!(lattice_entries(&stack) > 0, "{name}");
        let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let worst = compare_with_cpu(&name, &stack, &mut gpu, 6);
        eprintln!(
            "{name} with lattices: {} lattice entries of {}, worst GPU vs CPU {worst:.2e}",
            lattice_entries(&stack),
            stack.entry_count()
        );
        // Values spread over several chunks and bind groups: the lattice entries read
        // their coefficients from the right chunk.
        let largest_tile = stack.tiles.iter().map(|t| t.values.bytes()).max().unwrap();
        let options = GpuOptions {
            max_chunk_bytes: Some(largest_tile.div_ceil(4) as u64 * 4),
            ..GpuOptions::default()
        };
        let mut gpu = GpuRelighter::new(stack.clone(), &adapter, options).unwrap();
        let chunks = gpu.layer_bytes_and_chunks().1;
        assert!(chunks > 4, "{name}: {chunks} chunks, one bind group");
        compare_with_cpu(&format!("{name}, {chunks} chunks"), &stack, &mut gpu, 2);
    }
}

/// Tiles of more entries than the kernel reads into workgroup memory at a time: the
/// Cornell box baked at 32×32 into the dense layout holds every layer in every tile, and
/// with lattices on three of its four tiles (the first at 32 segments, past the slots one
/// invocation sums in a register) each tile's entries, per-pixel and lattice ones
/// alternating, run through a full batch and a partial one.
#[test]
fn tiles_of_several_batches_agree_full_and_incremental() {
    let Some(adapter) = gpu_or_skip("tiles_of_several_batches_agree_full_and_incremental") else {
        return;
    };
    let settings = small_bake(32, 32, Precision::F16);
    let (dense, _) =
        relume_engine::bake::bake(&scene("cornell"), &settings, &Progress::new()).expect("cornell");
    let tiled = TiledStack::from_dense(&dense).expect("tiled");
    let stack = Arc::new(with_lattices(&tiled, 11));
    let most = stack.tiles.iter().map(|t| t.entries.len()).max().unwrap();
    assert!(
        most > ENTRY_BATCH,
        "{most} entries in the largest tile: one batch"
    );
    assert!(lattice_entries(&stack) > 0);
    let mut gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
    let worst = compare_with_cpu("cornell 32×32, several batches", &stack, &mut gpu, 4);
    eprintln!(
        "cornell 32×32 with lattices: {most} entries in the largest tile, {} lattice entries \
         of {}, worst GPU vs CPU {worst:.2e}",
        lattice_entries(&stack),
        stack.entry_count()
    );
}

/// Step 1 over 32 segments needs 8192 (segment, node) pairs, past the kernel's limit: the
/// GPU refuses the stack and `auto` relights it on the CPU.
#[test]
fn a_lattice_over_the_workgroup_limit_is_refused() {
    let Some(adapter) = gpu_or_skip("a_lattice_over_the_workgroup_limit_is_refused") else {
        return;
    };
    let (_, stack) = asset_tiled_sized("cornell", 16, 16, Precision::F32);
    let mut stack = (*stack).clone();
    let tile = &mut stack.tiles[0];
    let map: Vec<u8> = (0..256).map(|p| (p % 32) as u8).collect();
    let lattice = TileLattice::new(1, 16, 16, map).unwrap();
    // One lattice entry over every segment, in place of the tile's entries.
    let mut entry = tile.entries[0];
    entry.offset = 0;
    entry.segments = u32::MAX;
    let n = lattice
        .coefficient_count(entry.segments, entry.channels)
        .unwrap();
    tile.entries = vec![entry];
    tile.values = TileValues::F32(vec![0.5; n]);
    tile.lattice = Some(lattice);
    validate(std::path::Path::new(""), &stack).expect("a valid stack");
    let stack = Arc::new(stack);
    match GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()) {
        Err(GpuError::TooLarge { message, .. }) => {
            assert!(message.contains("lattice nodes"), "{message}")
        }
        Err(e) => panic!("another error: {e}"),
        Ok(_) => panic!("a lattice past the workgroup memory was accepted"),
    }
    // `auto` tries a real GPU and falls back, saying why; it does not try a software one.
    let r = Relighter::new(stack, DevicePreference::Auto).unwrap();
    assert_eq!(r.device(), DeviceKind::Cpu);
    if is_real_gpu(adapter.get_info().device_type) {
        let why = r.fallback().expect("a fallback, with its reason");
        assert!(why.contains("lattice nodes"), "{why}");
    }
}

/// The tables grow by a pointer a tile and each lattice tile's block; the values stay the
/// stack's; together no more than the stack in host memory.
#[test]
fn gpu_memory_of_a_compressed_stack_is_the_stack() {
    let Some(adapter) = gpu_or_skip("gpu_memory_of_a_compressed_stack_is_the_stack") else {
        return;
    };
    let (name, stack) = compressed("cornell", Preset::Preview, Precision::F16);
    let gpu = GpuRelighter::new(stack.clone(), &adapter, GpuOptions::default()).unwrap();
    let m = gpu.memory();
    let samples = stack.sample_bytes() as u64;
    assert_eq!(m.values, samples.div_ceil(4).max(1) * 4, "{name}");
    let blocks: u64 = stack.tiles.iter().map(|t| block_words(t) as u64).sum();
    let tiles = stack.tiles.len() as u64;
    assert_eq!(
        m.tables,
        4 * (2 * tiles + 1 + blocks) + 16 * stack.entry_count() as u64,
        "{name}"
    );
    assert!(m.stack() <= stack.memory_bytes() as u64, "{name}: {m:?}");
    eprintln!(
        "{name}: GPU stack {} B (values {} + tables {}), host stack {} B",
        m.stack(),
        m.values,
        m.tables,
        stack.memory_bytes()
    );
}
