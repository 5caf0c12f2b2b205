//! The full CPU relight of a tiled stack alone, for profiling it without the per-region
//! incremental relights `relume bench relight` also runs:
//! `cargo run --release --example relight_full -- STACK [repeats] [--dump FILE] [--stats]
//! [--cpu]`.
//! Prints the min and median of `repeats` full relights at the stack's bake-time
//! materials; `--dump` writes the last image (raw little-endian f32 RGBA) to compare two
//! builds; `--stats` prints the stack's entry mix; `--cpu` times one worker thread by its
//! CPU time, which other processes on a busy machine do not lengthen.
use std::time::Instant;

use relume_engine::materials::{resolve_materials, MaterialsFile};
use relume_engine::relight::group_factors_of;
use relume_engine::relight::tiled_sum::{full, layer_weights};
use relume_engine::stack::bases::StackBases;
use relume_engine::stack::tiled::file::read_tiled;
use relume_engine::Rgb;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let stack = read_tiled(std::path::Path::new(&args[1])).expect("stack");
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(100);
    let dump = args
        .iter()
        .position(|a| a == "--dump")
        .map(|i| args[i + 1].clone());
    if args.iter().any(|a| a == "--stats") {
        stats(&stack);
    }
    let materials = resolve_materials(&stack.header.regions, &MaterialsFile::default()).unwrap();
    let coefs = StackBases::from_header(&stack.header)
        .unwrap()
        .coefficients(&materials)
        .unwrap();
    let keys = stack.layers.iter().map(|l| &l.key);
    let groups = group_factors_of(&stack.header, keys, None).unwrap();
    let weights: Vec<Rgb> = layer_weights(&stack, &coefs, &groups).unwrap();
    let (w, h) = (stack.header.width as usize, stack.header.height as usize);
    let mut image = vec![0.0f32; w * h * 4];
    let mut times = Vec::with_capacity(repeats);
    if args.iter().any(|a| a == "--cpu") {
        // One worker, timed by its own CPU time: other processes on the machine then
        // lengthen the wall time but not the figure.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        pool.install(|| {
            for _ in 0..repeats {
                let t = thread_cpu_ns();
                full(&stack, &weights, &mut image).unwrap();
                times.push((thread_cpu_ns() - t) as f64 * 1e-6);
            }
        });
    } else {
        for _ in 0..repeats {
            let t = Instant::now();
            full(&stack, &weights, &mut image).unwrap();
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    let min = times.iter().copied().fold(f64::INFINITY, f64::min);
    // The CPU clock may tick coarsely; the mean of back-to-back intervals does not care.
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    times.sort_by(f64::total_cmp);
    println!(
        "full_min_ms {min:.3} full_median_ms {:.3} full_mean_ms {mean:.3}",
        times[times.len() / 2]
    );
    if let Some(path) = dump {
        let bytes: Vec<u8> = image.iter().flat_map(|v| v.to_le_bytes()).collect();
        std::fs::write(path, bytes).unwrap();
    }
}

/// This thread's time on a CPU in nanoseconds (Linux: `/proc/thread-self/schedstat`).
fn thread_cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

fn stats(stack: &relume_engine::stack::tiled::TiledStack) {
    let (mut grey, mut rgb, mut lat_grey, mut lat_rgb, mut lat_tiles) = (0, 0, 0, 0, 0);
    let (mut segs, mut nodes_hist) = (0usize, std::collections::BTreeMap::new());
    for t in &stack.tiles {
        if let Some(l) = &t.lattice {
            lat_tiles += 1;
            segs += l.segment_count();
            for s in 0..l.segment_count() {
                *nodes_hist
                    .entry(l.segment_nodes(s).nodes.len())
                    .or_insert(0) += 1;
            }
        }
        for e in &t.entries {
            match (e.segments != 0, e.channels) {
                (false, 1) => grey += 1,
                (false, _) => rgb += 1,
                (true, 1) => lat_grey += 1,
                (true, _) => lat_rgb += 1,
            }
        }
    }
    println!(
        "tiles {} lattice tiles {lat_tiles} segments {segs} entries grey {grey} rgb {rgb} \
         lattice grey {lat_grey} lattice rgb {lat_rgb}",
        stack.tiles.len()
    );
    println!("segment nodes histogram {nodes_hist:?}");
}
