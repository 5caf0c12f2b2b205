//! `--device auto|gpu|cpu` of `relume relight` and `relume bench relight`: the device and
//! its reason in the summary, GPU = CPU through the binary, and what happens when every
//! Vulkan driver is hidden (auto falls back to the CPU and says why; gpu is an error that
//! says so and points to auto).

mod common;

use std::io::Write as _;
use std::path::PathBuf;

use common::*;

/// Environment that hides every Vulkan driver from the loader (old and new variable).
const HIDE_ADAPTERS: [(&str, &str); 2] = [
    ("VK_ICD_FILENAMES", "/nonexistent/icd.json"),
    ("VK_DRIVER_FILES", "/nonexistent/icd.json"),
];

/// A 24×24 bake of the assets' Cornell box in a fresh scratch folder.
fn small_stack(name: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    let stack = dir.join("s.exr");
    bake_cornell(&stack, "24x24", "2");
    (dir, stack)
}

/// Whether this machine has any adapter `--device gpu` can take; when it has none, says in
/// the test output that `test` skips its GPU part, or fails the test where
/// `RELUME_REQUIRE_GPU` is set (scripts/test.sh sets it when lavapipe is installed).
fn has_adapter(test: &str) -> bool {
    let Err(e) = relume_gpu::choose_device(relume_gpu::DevicePreference::Gpu) else {
        return true;
    };
    let required = std::env::var("RELUME_REQUIRE_GPU").is_ok_and(|v| !v.is_empty() && v != "0");
    assert!(
        !required,
        "{test}: no GPU adapter ({e}), but RELUME_REQUIRE_GPU is set: a GPU (or lavapipe, \
         Debian's mesa-vulkan-drivers) is expected on this machine"
    );
    // Straight to the process's stderr: the test harness captures `eprintln!`.
    let _ = writeln!(
        std::io::stderr(),
        "SKIPPED: {test}: the GPU part, no wgpu adapter on this machine ({e})"
    );
    false
}

#[test]
fn relight_reports_its_device_and_gpu_matches_cpu() {
    let (dir, stack) = small_stack("relight");
    let run = |device: &str| {
        relume(&[
            "relight",
            s(&stack),
            "-o",
            s(&dir.join(format!("{device}.exr"))),
            "--device",
            device,
            "--denoise",
            "none",
            "--json",
        ])
    };
    let cpu = json_of(&run("cpu"));
    assert_eq!(cpu["device"], "cpu");
    assert_eq!(cpu["device_reason"], "CPU: chosen by the caller");

    let auto = json_of(&run("auto"));
    let reason = auto["device_reason"].as_str().unwrap();
    match auto["device"].as_str().unwrap() {
        "gpu" => assert!(reason.starts_with("GPU: "), "{reason}"),
        "cpu" => assert!(
            reason.contains("software rasteriser") || reason.starts_with("CPU: no GPU adapter"),
            "{reason}"
        ),
        other => panic!("device {other}"),
    }

    let gpu = run("gpu");
    if !has_adapter("relight_reports_its_device_and_gpu_matches_cpu") {
        assert!(!gpu.status.success());
        eprintln!(
            "relight --device gpu: SKIPPED the comparison, no adapter ({})",
            stderr(&gpu)
        );
        return;
    }
    let gpu = json_of(&gpu);
    assert_eq!(gpu["device"], "gpu");
    let cmp = json_of(&relume(&[
        "compare",
        s(&dir.join("gpu.exr")),
        s(&dir.join("cpu.exr")),
        "--json",
    ]));
    assert!(cmp["rel_l2"].as_f64().unwrap() < 1e-3, "{cmp}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn hidden_adapters_auto_falls_back_and_gpu_is_a_clear_error() {
    let (dir, stack) = small_stack("hidden");
    let out = dir.join("o.exr");
    let auto = json_of(&relume_env(
        &[
            "relight",
            s(&stack),
            "-o",
            s(&out),
            "--device",
            "auto",
            "--json",
        ],
        &HIDE_ADAPTERS,
    ));
    assert_eq!(auto["device"], "cpu");
    let reason = auto["device_reason"].as_str().unwrap();
    assert!(reason.starts_with("CPU: no GPU adapter"), "{reason}");

    let gpu = relume_env(
        &["relight", s(&stack), "-o", s(&out), "--device", "gpu"],
        &HIDE_ADAPTERS,
    );
    assert_eq!(gpu.status.code(), Some(1));
    let e = stderr(&gpu);
    assert!(
        e.contains("--device gpu: no GPU adapter")
            && e.contains("--device auto falls back to the CPU"),
        "{e}"
    );
    assert!(!e.contains("panicked"), "{e}");

    let bench = relume_env(
        &[
            "bench",
            "relight",
            s(&stack),
            "--device",
            "gpu",
            "--repeats",
            "1",
        ],
        &HIDE_ADAPTERS,
    );
    assert!(!bench.status.success() && stderr(&bench).contains("no GPU adapter"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bench_relight_on_the_gpu_prints_upload_kernel_and_read_back() {
    if !has_adapter("bench_relight_on_the_gpu_prints_upload_kernel_and_read_back") {
        eprintln!("bench relight --device gpu: SKIPPED, no GPU adapter on this machine");
        return;
    }
    let (dir, stack) = small_stack("bench");
    let b = json_of(&relume(&[
        "bench",
        "relight",
        s(&stack),
        "--device",
        "gpu",
        "--repeats",
        "2",
        "--json",
    ]));
    assert_eq!(b["device"], "gpu");
    for k in [
        "upload_ms",
        "full_ms",
        "readback_ms",
        "fastest_incremental_ms",
    ] {
        assert!(b[k].as_f64().unwrap() > 0.0, "{k}: {b}");
    }
    // The kernel time is a number where timestamps exist, else null with the reason.
    assert!(
        b["full_kernel_ms"].as_f64().is_some_and(|t| t > 0.0)
            || (b["full_kernel_ms"].is_null() && b["kernel_note"].is_string()),
        "{b}"
    );
    assert_eq!(
        b["incremental_per_region"].as_array().unwrap().len(),
        2,
        "{b}"
    );
    if b["software_adapter"] == true {
        assert!(b["note"].as_str().unwrap().contains("not GPU speed"), "{b}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
