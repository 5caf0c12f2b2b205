//! Never crash, never lose work: hostile stack files give named errors before anything of
//! their claimed size is allocated, a bake over its memory budget is refused before it
//! traces, the stack header's floats round-trip exactly, a cancel holds at every stage of a
//! bake (within a second, the previous stack byte for byte intact), and temp files of dead
//! writers are cleaned up.

use crate::common;

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::*;
use relume_engine::bake::prepare::estimate::estimate_bake;
use relume_engine::bake::to_file::bake_to_file;
use relume_engine::bake::{bake, bake_progressive_tiled, doubling_passes, BakeSettings, Denoise};
use relume_engine::brdf::{BasisConfig, BasisCount};
use relume_engine::progress::{Progress, Stage};
use relume_engine::stack::exr_file::{read_stack, write_stack};
use relume_engine::stack::hostile::with_claimed_size;
use relume_engine::RelumeError;

fn small_stack_file(dir: &Path) -> std::path::PathBuf {
    let scene = cornell(16);
    let (stack, _) = bake(
        &scene,
        &BakeSettings {
            spp: 1,
            light_samples: 1,
            ..BakeSettings::default()
        },
        &Progress::new(),
    )
    .unwrap();
    let path = dir.join("small.relume.exr");
    write_stack(&path, &stack).unwrap();
    path
}

#[test]
fn a_stack_claiming_more_pixels_than_its_file_holds_is_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_stack_file(dir.path());
    let bytes = std::fs::read(&path).unwrap();
    for (w, h) in [(16384, 16384), (65536, 65536), (65536, 16), (4096, 4096)] {
        let hostile = dir.path().join(format!("claims-{w}x{h}.exr"));
        std::fs::write(&hostile, with_claimed_size(&bytes, w, h).unwrap()).unwrap();
        let t = Instant::now();
        let e = read_stack(&hostile).unwrap_err();
        assert!(
            matches!(e, RelumeError::StackTruncated { .. }),
            "{w}×{h}: {e}"
        );
        assert!(e.to_string().contains("claims"), "{e}");
        assert!(
            t.elapsed() < Duration::from_secs(1),
            "{w}×{h} took {:?}",
            t.elapsed()
        );
    }
    // Beyond the largest side any stack may have: refused by the size rule itself.
    let hostile = dir.path().join("claims-huge.exr");
    std::fs::write(
        &hostile,
        with_claimed_size(&bytes, 100_000, 100_000).unwrap(),
    )
    .unwrap();
    let e = read_stack(&hostile).unwrap_err();
    assert!(e.to_string().contains("1…65536"), "{e}");
    // The untouched file still reads.
    read_stack(&path).unwrap();
}

#[test]
fn a_bake_over_its_memory_budget_is_refused_before_tracing_with_the_estimate() {
    let scene = cornell(64);
    let progress = Progress::new();
    let t = Instant::now();
    let e = bake(
        &scene,
        &BakeSettings {
            spp: 1,
            memory_budget: Some(1 << 20),
            ..BakeSettings::default()
        },
        &progress,
    )
    .unwrap_err();
    let text = e.to_string();
    assert!(
        matches!(e, RelumeError::OutOfMemory { budget: true, .. }),
        "{text}"
    );
    assert!(
        text.contains("64×64") && text.contains("layers reached"),
        "{text}"
    );
    assert!(text.contains("1.0 MiB"), "{text}");
    assert!(!progress.is_started(), "tracing started before the refusal");
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
}

#[test]
fn the_estimate_counts_the_layers_the_bake_reaches() {
    let scene = cornell(48);
    let settings = BakeSettings {
        spp: 2,
        light_samples: 2,
        ..BakeSettings::default()
    };
    let (stack, report) = bake(&scene, &settings, &Progress::new()).unwrap();
    let est = report.estimate.expect("the bake reports its estimate");
    let reached = report.layers_grey + report.layers_rgb;
    // The probe traces one sample at a sparse grid: it may miss a layer only a few pixels
    // reach, never invent one.
    assert!(
        est.layers_reached <= reached && est.layers_reached as f64 >= 0.9 * reached as f64,
        "probe {} layers, bake {reached}",
        est.layers_reached
    );
    // The dense layout's size (what `bake` expands to) and the tiled stack's (what the
    // streaming bake holds and the forecast's `stack_bytes` now models).
    let stack_bytes = stack.sample_bytes() as f64;
    let ratio = est.dense_stack_bytes as f64 / stack_bytes;
    assert!(
        (0.75..=1.25).contains(&ratio),
        "dense stack estimate / actual = {ratio}"
    );
    // The tiled stack's forecast is an upper bound: its entries come from a region model
    // that over-counts (loosest on small frames, where every tile neighbours every region).
    let ratio = est.stack_bytes as f64 / report.stored_bytes as f64;
    assert!(ratio >= 1.0, "tiled stack estimate / actual = {ratio}");
}

/// A progressive bake keeps each tile's sample sums between its passes, and its forecast
/// models them: what the bake accounted at its peak (the stack, the rows in flight and the
/// kept sums) stays within the forecast peak, and a one-pass forecast keeps nothing.
#[test]
fn a_progressive_bake_s_forecast_covers_the_tile_sums_it_keeps() {
    let scene = cornell(48);
    let settings = BakeSettings {
        spp: 4,
        light_samples: 2,
        ..BakeSettings::default()
    };
    let passes = doubling_passes(settings.spp, 3);
    let (_, report, reports) =
        bake_progressive_tiled(&scene, &settings, &passes, &Progress::new(), |_, _, _| {
            Ok(())
        })
        .unwrap();
    assert_eq!(reports.len(), passes.len());
    let est = report.estimate.expect("the bake reports its estimate");
    assert!(est.kept_sums_bytes > 0);
    assert!(report.peak_accounted_bytes > 0);
    assert!(
        report.peak_accounted_bytes as u64 <= est.peak_bytes,
        "accounted {} over the forecast peak {}",
        report.peak_accounted_bytes,
        est.peak_bytes
    );
    let one_pass = estimate_bake(&scene, &settings, 1, &Progress::new()).unwrap();
    assert_eq!(one_pass.kept_sums_bytes, 0);
}

#[test]
fn the_translucent_header_round_trips_across_sample_counts() {
    let mut scene = cornell(8);
    make_object_translucent(&mut scene);
    let mut settings = BakeSettings::default();
    let mut failures = Vec::new();
    // Every count up to 2^16, then a prime stride (so every residue of small moduli and
    // every binade of ρ is visited) up to 2^22: the exhaustive walk over all four million
    // counts took over a minute of the test run for no added reach.
    let counts = (1_000..=65_536u32).chain((65_537..=4_194_304u32).step_by(97));
    for samples in counts {
        settings.subsurface_samples = samples;
        let (cfg, _) = relume_engine::bake::prepare::subsurface::basis_config(
            &scene,
            1,
            &scene.regions[1],
            &settings,
        )
        .unwrap();
        let json = serde_json::to_string(&cfg).unwrap();
        let back: relume_engine::bssrdf::basis::SssBasisConfig =
            serde_json::from_str(&json).unwrap();
        if back != cfg && failures.len() < 5 {
            failures.push(samples);
        }
    }
    assert!(
        failures.is_empty(),
        "no exact round trip for samples {failures:?}"
    );
}

/// Makes the Cornell box's "Object" (region 1) a translucent Principled wax.
fn make_object_translucent(scene: &mut relume_engine::scene::Scene) {
    scene.regions[1].material =
        relume_engine::brdf::MaterialSpec::Principled(relume_engine::brdf::PrincipledMaterial {
            bsdf: relume_engine::brdf::Principled {
                base_color: [0.8, 0.6, 0.5],
                metallic: 0.0,
                roughness: 0.5,
                ior: 1.4,
                specular_ior_level: 0.5,
            },
            subsurface: relume_engine::brdf::Subsurface {
                weight: 1.0,
                radius: [1.0, 0.5, 0.25],
                scale: 0.05,
            },
        });
}

/// A bake long enough that each stage lasts a noticeable time in a debug build.
fn stage_scene() -> (relume_engine::scene::Scene, BakeSettings) {
    let scene = cornell(192);
    let settings = BakeSettings {
        spp: 2,
        light_samples: 1,
        basis: BasisConfig {
            count: BasisCount::Fixed(8),
            ..BasisConfig::default()
        },
        denoise: Denoise {
            direct_iterations: 2,
            bounce_iterations: 4,
        },
        ..BakeSettings::default()
    };
    (scene, settings)
}

#[test]
fn a_cancel_holds_at_every_stage_and_leaves_the_previous_stack_intact() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_stack_file(dir.path());
    let before = std::fs::read(&path).unwrap();
    let (scene, settings) = stage_scene();
    let scene = Arc::new(scene);
    for stage in [
        Stage::Setup,
        Stage::Tracing,
        Stage::Assembly,
        Stage::Denoising,
        Stage::Finishing,
        Stage::Writing,
    ] {
        let progress = Arc::new(Progress::new());
        let job = {
            let (scene, settings, path, progress) = (
                scene.clone(),
                settings.clone(),
                path.clone(),
                progress.clone(),
            );
            std::thread::spawn(move || {
                bake_to_file(&scene, &settings, 1, &path, &progress, |_, _| {})
            })
        };
        // Cancel as soon as the bake reaches the stage.
        let deadline = Instant::now() + Duration::from_secs(300);
        while progress.stage() != stage && !job.is_finished() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_micros(200));
        }
        let reached = progress.stage() == stage;
        let asked = Instant::now();
        progress.cancel();
        let result = job.join().unwrap();
        let took = asked.elapsed();
        assert!(reached, "the bake never showed stage {stage:?}");
        match result {
            Err(RelumeError::Cancelled) => {}
            Err(e) => panic!("{stage:?}: cancel gave another error: {e}"),
            Ok(_) => panic!("{stage:?}: a cancel during the stage returned a success"),
        }
        assert!(
            took < Duration::from_secs(1),
            "{stage:?}: the cancel took {took:?}"
        );
        assert_eq!(
            std::fs::read(&path).unwrap(),
            before,
            "{stage:?}: the stack changed"
        );
        eprintln!(
            "cancel at {}: returned after {:.0} ms",
            stage.name(),
            took.as_secs_f64() * 1e3
        );
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "temp files left: {leftovers:?}");
}

#[test]
fn temp_files_of_dead_writers_are_removed_by_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_stack_file(dir.path());
    // A pid far above any Linux pid_max default (4 194 304): no such process.
    let dead = dir.path().join(".small.relume.exr.tmp-4194999-0");
    let alive = dir
        .path()
        .join(format!(".small.relume.exr.tmp-{}-77", std::process::id()));
    let other = dir.path().join(".other.exr.tmp-4194999-0");
    for p in [&dead, &alive, &other] {
        std::fs::write(p, b"partial").unwrap();
    }
    let stack = read_stack(&path).unwrap();
    write_stack(&path, &stack).unwrap();
    assert!(!dead.exists(), "a dead writer's temp file survived");
    assert!(alive.exists(), "a live writer's temp file was removed");
    assert!(other.exists(), "another target's temp file was removed");
}

#[test]
fn bad_settings_are_refused_with_the_field_named() {
    let scene = cornell(8);
    let cases: [(BakeSettings, &str); 4] = [
        (
            BakeSettings {
                spp: 0,
                ..BakeSettings::default()
            },
            "spp",
        ),
        (
            BakeSettings {
                threads: 100_000,
                ..BakeSettings::default()
            },
            "threads",
        ),
        (
            BakeSettings {
                resolution: Some(relume_engine::scene::Resolution {
                    width: 100_000,
                    height: 100_000,
                }),
                ..BakeSettings::default()
            },
            "resolution",
        ),
        (
            BakeSettings {
                drop_budget: f32::NAN,
                ..BakeSettings::default()
            },
            "drop_budget",
        ),
    ];
    for (settings, field) in cases {
        let e = bake(&scene, &settings, &Progress::new()).unwrap_err();
        assert!(e.to_string().contains(field), "{field}: {e}");
    }
    let dir = tempfile::tempdir().unwrap();
    let e = bake_to_file(
        &scene,
        &BakeSettings::default(),
        0,
        &dir.path().join("s.exr"),
        &Progress::new(),
        |_, _| {},
    )
    .err()
    .unwrap();
    assert!(e.to_string().contains("passes"), "{e}");
}

#[test]
fn a_cancel_during_the_subsurface_set_up_returns_within_a_second() {
    let mut scene = cornell(32);
    make_object_translucent(&mut scene);
    // Millions of subsurface samples: seconds of set-up, each sample lit from every light.
    let settings = BakeSettings {
        spp: 1,
        light_samples: 8,
        subsurface_samples: 4_000_000,
        ..BakeSettings::default()
    };
    let progress = Arc::new(Progress::new());
    let job = {
        let (progress, scene, settings) = (progress.clone(), scene.clone(), settings.clone());
        std::thread::spawn(move || bake(&scene, &settings, &progress).map(|_| ()))
    };
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(
        progress.stage(),
        Stage::Setup,
        "the set-up ended before the cancel"
    );
    let asked = Instant::now();
    progress.cancel();
    let result = job.join().unwrap();
    let took = asked.elapsed();
    assert!(matches!(result, Err(RelumeError::Cancelled)), "{result:?}");
    assert!(took < Duration::from_secs(1), "the cancel took {took:?}");
    eprintln!(
        "cancel during subsurface set-up: returned after {:.0} ms",
        took.as_secs_f64() * 1e3
    );
}
