//! The tiled stack writer's encodings (issue 14, "bake cost"): every compression it offers
//! reads back bit for bit, on a stack whose values span many chunks; compressing the
//! chunks on several threads writes a file of the same size as one thread; and an ignored
//! measurement of each encoding's time and size on a real stack (docs/scale.md).
use std::path::Path;
use std::time::Instant;

use relume_engine::bake::presets::Preset;
use relume_engine::bake::{bake_tiled, BakeSettings};
use relume_engine::options::Precision;
use relume_engine::progress::Progress;
use relume_engine::scene::file::load_scene;
use relume_engine::scene::Resolution;
use relume_engine::stack::tiled::file::{
    read_tiled, write_tiled_with, StackCompression, WriteOptions,
};
use relume_engine::stack::tiled::TiledStack;

const ALL: [StackCompression; 5] = [
    StackCompression::Zip16,
    StackCompression::Zip1,
    StackCompression::Rle,
    StackCompression::Piz,
    StackCompression::Uncompressed,
];

/// A draft bake of the assets' Cornell box at `width × height` (not multiples of 16).
fn cornell(width: u32, height: u32, precision: Precision) -> TiledStack {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/cornell.scene.json");
    let scene = load_scene(&path).unwrap();
    let mut settings = BakeSettings::default();
    Preset::Draft.apply(&mut settings);
    settings.resolution = Some(Resolution { width, height });
    settings.precision = precision;
    settings.threads = 2;
    bake_tiled(&scene, &settings, &Progress::new()).unwrap().0
}

#[test]
fn every_encoding_reads_back_exactly_whatever_the_threads() {
    let dir = tempfile::tempdir().unwrap();
    for (stack, what) in [
        (cornell(200, 136, Precision::F16), "f16"),
        (cornell(72, 40, Precision::F32), "f32"),
    ] {
        let values: usize = stack.tiles.iter().map(|t| t.values.len()).sum();
        // More than a few 16-line chunks of the 4096-wide values part.
        if what == "f16" {
            assert!(values > 4 * 16 * 4096, "{values} values");
        }
        for compression in ALL {
            let mut files = Vec::new();
            for parallel in [true, false] {
                let path = dir
                    .path()
                    .join(format!("{what}-{compression:?}-{parallel}.exr"));
                let options = WriteOptions {
                    compression,
                    parallel,
                };
                let bytes = write_tiled_with(&path, &stack, options, &Progress::new()).unwrap();
                assert_eq!(bytes, std::fs::metadata(&path).unwrap().len());
                assert!(
                    read_tiled(&path).unwrap() == stack,
                    "{what} {compression:?} parallel {parallel}"
                );
                files.push(bytes);
            }
            // The same chunks (the header's attributes come in a hash map's order, so the
            // bytes themselves may differ in order).
            assert_eq!(
                files[0], files[1],
                "{what} {compression:?}: parallel and sequential file sizes"
            );
        }
    }
}

/// `RELUME_WRITE_BENCH_STACK=stack.exr cargo test --release --test engine stack_write -- --ignored
/// --nocapture`: writes that stack with every encoding (two runs each; chunks on all
/// cores, and ZIP16 on one) and prints one JSON line per encoding: min and median seconds,
/// bytes, and the ratio to the values' bytes in memory.
#[test]
#[ignore = "a measurement on a stack named by RELUME_WRITE_BENCH_STACK; run in release on a quiet machine"]
fn encodings_time_and_size() {
    let Ok(path) = std::env::var("RELUME_WRITE_BENCH_STACK") else {
        eprintln!("RELUME_WRITE_BENCH_STACK is not set: nothing measured");
        return;
    };
    let stack = read_tiled(Path::new(&path)).unwrap();
    let dir = tempfile::tempdir_in(Path::new(&path).parent().unwrap()).unwrap();
    let out = dir.path().join("bench.exr");
    let mut cases: Vec<WriteOptions> = ALL
        .iter()
        .map(|&compression| WriteOptions {
            compression,
            parallel: true,
        })
        .collect();
    cases.push(WriteOptions {
        compression: StackCompression::Zip16,
        parallel: false,
    });
    for options in cases {
        let mut times = Vec::new();
        let mut bytes = 0;
        for _ in 0..2 {
            let t = Instant::now();
            bytes = write_tiled_with(&out, &stack, options, &Progress::new()).unwrap();
            times.push(t.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{{\"compression\": \"{:?}\", \"parallel\": {}, \"min_s\": {:.3}, \"median_s\": {:.3}, \"bytes\": {}, \"over_stack\": {:.3}}}",
            options.compression,
            options.parallel,
            times[0],
            (times[0] + times[1]) / 2.0,
            bytes,
            bytes as f64 / stack.sample_bytes() as f64
        );
    }
}
