//! Shared by the GPU tests: the assets stacks baked small (tiled, and dense for the
//! callers that hand the relighter a dense stack), material edits, the error measure, and
//! the skip when this machine has no adapter at all.
#![allow(dead_code)]

use std::io::Write as _;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use relume_engine::bake::{bake, bake_tiled, BakeSettings};
use relume_engine::brdf::{BlinnPhong, MaterialSpec};
use relume_engine::materials::{resolve_materials, MaterialsFile};
use relume_engine::progress::Progress;
use relume_engine::scene::{file::load_scene, Resolution};
use relume_engine::stack::tiled::TiledStack;
use relume_engine::stack::{bases::StackBases, Precision, StackHeader, TransferStack};
use relume_engine::Rgb;
use relume_gpu::{choose_device, DevicePreference};

/// The agreement issue 14 asks of the GPU and CPU relights of the same tiled stack, which
/// add the same numbers in the same order per pixel (only fused multiply-adds and the
/// drivers' rounding may differ).
pub const TOLERANCE: f64 = 1e-6;

/// The assets scenes.
pub const ASSETS: [&str; 4] = ["cornell", "ring", "textured", "translucent"];

/// Small bake settings: `width × height`, 2 eye samples, `precision`.
pub fn small_bake(width: u32, height: u32, precision: Precision) -> BakeSettings {
    BakeSettings {
        spp: 2,
        light_samples: 1,
        resolution: Some(Resolution { width, height }),
        precision,
        ..Default::default()
    }
}

/// Assets scene `name`.
pub fn scene(name: &str) -> relume_engine::scene::Scene {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets");
    load_scene(&root.join(format!("{name}.scene.json"))).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The assets scenes, each baked at 32×32 with 2 eye samples into the dense layout: a few
/// hundred to a few thousand layer values per pixel, enough to exercise every layer kind
/// (grey, RGB, textured constant, world) while lavapipe sums them in milliseconds.
pub fn assets_stacks(precision: Precision) -> Vec<(String, Arc<TransferStack>)> {
    ASSETS
        .iter()
        .map(|name| {
            let (stack, _) = bake(
                &scene(name),
                &small_bake(32, 32, precision),
                &Progress::new(),
            )
            .unwrap_or_else(|e| panic!("{name}: {e}"));
            (format!("{name} ({precision:?})"), Arc::new(stack))
        })
        .collect()
}

/// Asset scene `name` baked by the streaming bake into the tiled layout at 40×24: 3 × 2
/// tiles, the last column 8 pixels wide and the last row 8 pixels high.
pub fn asset_tiled(name: &str, precision: Precision) -> (String, Arc<TiledStack>) {
    asset_tiled_sized(name, 40, 24, precision)
}

/// Asset scene `name` baked into the tiled layout at `width × height`.
pub fn asset_tiled_sized(
    name: &str,
    width: u32,
    height: u32,
    precision: Precision,
) -> (String, Arc<TiledStack>) {
    let settings = small_bake(width, height, precision);
    let (stack, _) = bake_tiled(&scene(name), &settings, &Progress::new())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    (
        format!("{name} {width}×{height} ({precision:?})"),
        Arc::new(stack),
    )
}

/// The bake-time materials' coefficients, and the bases to make edits with.
pub fn default_coefs(header: &StackHeader) -> (StackBases, Vec<Vec<Rgb>>) {
    let materials = resolve_materials(&header.regions, &MaterialsFile::default()).unwrap();
    let bases = StackBases::from_header(header).unwrap();
    let coefs = bases.coefficients(&materials).unwrap();
    (bases, coefs)
}

/// Edit number `k`: a different Blinn–Phong material for each k (Kd + Ks ≤ 1, ns across
/// the basis range), coloured so that RGB weights differ per channel.
pub fn edit(bases: &StackBases, region: usize, k: usize) -> Vec<Rgb> {
    let t = (k % 7) as f32 / 6.0;
    let m = MaterialSpec::BlinnPhong(BlinnPhong {
        kd: [0.7 * t, 0.5 * (1.0 - t), 0.3],
        ks: [0.2 + 0.1 * t, 0.25, 0.1 + 0.3 * (1.0 - t)],
        ns: 1.0 + 150.0 * t,
    });
    bases.region_coefficients(region, &m).unwrap()
}

/// ‖a − b‖ / ‖b‖ over the RGB channels of two RGBA images (alpha checked to be 1).
pub fn rel_l2(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len());
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (pa, pb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        assert_eq!((pa[3], pb[3]), (1.0, 1.0), "alpha is 1");
        for c in 0..3 {
            num += (pa[c] as f64 - pb[c] as f64).powi(2);
            den += (pb[c] as f64).powi(2);
        }
    }
    assert!(
        den > 0.0,
        "the reference image is black: the test would prove nothing"
    );
    (num / den).sqrt()
}

/// Set (to anything but "" or "0") where a GPU adapter must exist: `scripts/test.sh` sets it
/// when lavapipe (Debian's mesa-vulkan-drivers) is installed, so that a broken driver set-up
/// fails the run instead of skipping every GPU test.
pub const REQUIRE_GPU_VAR: &str = "RELUME_REQUIRE_GPU";

/// GPU tests of this test binary skipped so far for want of an adapter.
static SKIPPED: AtomicUsize = AtomicUsize::new(0);

/// The adapter forced GPU tests run on, or `None` after saying in the test output that
/// `test` is skipped (there is no adapter). Panics instead when `RELUME_REQUIRE_GPU` is set.
pub fn gpu_or_skip(test: &str) -> Option<relume_gpu::wgpu::Adapter> {
    match choose_device(DevicePreference::Gpu) {
        Ok(choice) => {
            eprintln!("{test}: {}", choice.reason);
            choice.adapter
        }
        Err(e) => {
            let required = std::env::var(REQUIRE_GPU_VAR).is_ok_and(|v| !v.is_empty() && v != "0");
            assert!(
                !required,
                "{test}: no GPU adapter ({e}), but {REQUIRE_GPU_VAR} is set: a GPU (or lavapipe, \
                 Debian's mesa-vulkan-drivers) is expected on this machine; check the Vulkan \
                 driver installation (vulkaninfo --summary), or unset {REQUIRE_GPU_VAR} to skip"
            );
            let skipped = SKIPPED.fetch_add(1, Ordering::Relaxed) + 1;
            // Straight to the process's stderr: the test harness captures `eprintln!`, and a
            // skip must show in the output of a passing run.
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED: {test}: no wgpu adapter on this machine ({e}); install Debian's \
                 mesa-vulkan-drivers (lavapipe) to run it [{skipped} skipped in this binary]"
            );
            None
        }
    }
}

/// Full relight, then `edits` single-region edits cycling over the editable regions; the
/// two relighters are compared after every step, images and what they read. Returns the
/// worst error seen.
pub fn compare_with_cpu(
    name: &str,
    stack: &Arc<TiledStack>,
    gpu: &mut relume_gpu::GpuRelighter,
    edits: usize,
) -> f64 {
    let mut cpu = relume_engine::relight::CpuRelighter::from_tiled(stack.clone()).unwrap();
    let (bases, coefs) = default_coefs(&stack.header);
    let mut worst: f64 = 0.0;
    let mut check = |step: &str, g: &[f32], c: &[f32]| {
        let e = rel_l2(g, c);
        assert!(
            e < TOLERANCE,
            "{name}, {step}: GPU vs CPU relative L2 {e:.3e}"
        );
        worst = worst.max(e);
    };
    let c = cpu.relight(&coefs).unwrap().to_vec();
    let g = gpu.relight(&coefs).unwrap().to_vec();
    check("full relight", &g, &c);
    assert!(!gpu.last_stats().incremental);
    assert_eq!(gpu.last_stats(), cpu.last_stats(), "{name}: full relight");
    let n = gpu.editable_count();
    assert_eq!(n, cpu.editable_count(), "{name}");
    for k in 0..edits {
        let region = k % n;
        let new = edit(&bases, region, k);
        let c = cpu.relight_region(region, &new).unwrap().to_vec();
        let g = gpu.relight_region(region, &new).unwrap().to_vec();
        check(&format!("edit {k} of region {region}"), &g, &c);
        assert_eq!(gpu.last_stats(), cpu.last_stats(), "{name}: edit {k}");
    }
    worst
}
