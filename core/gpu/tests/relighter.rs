//! `Relighter`: the device choice and its reason, the same answers and the same refusals
//! on GPU and CPU, the fallback to the CPU, and what happens when every adapter is hidden.

mod common;

use std::process::Command;
use std::sync::Arc;

use common::*;
use relume_engine::relight::CpuRelighter;
use relume_engine::stack::{Precision, TransferStack};
use relume_engine::Rgb;
use relume_gpu::{choose_device, DeviceKind, DevicePreference, GpuError, Relighter};

fn cornell() -> Arc<TransferStack> {
    assets_stacks(Precision::F16).swap_remove(0).1
}

#[test]
fn cpu_preference_is_the_engine_relight() {
    let stack = cornell();
    let (_, coefs) = default_coefs(&stack.header);
    let mut r = Relighter::new(stack.clone(), DevicePreference::Cpu).unwrap();
    assert_eq!(r.device(), DeviceKind::Cpu);
    assert!(
        r.device_reason().starts_with("CPU:"),
        "{}",
        r.device_reason()
    );
    assert!(r.gpu_timings().is_none() && r.fallback().is_none());
    let mut cpu = CpuRelighter::new(stack).unwrap();
    // The same code on the same data: bit for bit.
    assert!(r.relight(&coefs).unwrap() == cpu.relight(&coefs).unwrap());
}

/// `auto` takes a real GPU, and the CPU for a software adapter or none, saying which.
#[test]
fn auto_follows_the_kind_of_adapter() {
    let r = Relighter::new(cornell(), DevicePreference::Auto).unwrap();
    let reason = r.device_reason().to_string();
    eprintln!("auto: {reason}");
    match choose_device(DevicePreference::Gpu) {
        Ok(c)
            if c.adapter
                .as_ref()
                .is_some_and(|a| relume_gpu::device::is_real_gpu(a.get_info().device_type)) =>
        {
            assert_eq!(r.device(), DeviceKind::Gpu, "{reason}");
            assert!(reason.starts_with("GPU: "), "{reason}");
        }
        Ok(_) => {
            assert_eq!(r.device(), DeviceKind::Cpu, "{reason}");
            assert!(
                reason.contains("software rasteriser") || reason.contains("unknown kind"),
                "{reason}"
            );
            assert!(reason.contains("slower than the CPU loop"), "{reason}");
        }
        Err(_) => {
            assert_eq!(r.device(), DeviceKind::Cpu, "{reason}");
            assert!(reason.starts_with("CPU: no GPU adapter"), "{reason}");
        }
    }
}

#[test]
fn forced_gpu_matches_then_falls_back_to_the_cpu_on_request() {
    if gpu_or_skip("forced_gpu_matches_then_falls_back_to_the_cpu_on_request").is_none() {
        return;
    }
    let stack = cornell();
    let (bases, coefs) = default_coefs(&stack.header);
    let mut r = Relighter::new(stack.clone(), DevicePreference::Gpu).unwrap();
    assert_eq!(r.device(), DeviceKind::Gpu);
    assert!(
        r.device_reason().starts_with("GPU"),
        "{}",
        r.device_reason()
    );
    let mut cpu = CpuRelighter::new(stack).unwrap();
    r.relight(&coefs).unwrap();
    let timings = r.gpu_timings().unwrap();
    assert!(timings.edit_to_image_ms > 0.0, "{timings:?}");
    let e1 = edit(&bases, 1, 3);
    cpu.relight(&coefs).unwrap();
    let expected = cpu.relight_region(1, &e1).unwrap().to_vec();
    let before = r.relight_region(1, &e1).unwrap().to_vec();
    assert!(rel_l2(&before, &expected) < TOLERANCE);
    assert_eq!(r.last_stats().incremental, cpu.last_stats().incremental);

    // After the switch the image is recomputed on the CPU for the same materials, and
    // incremental edits go on from it.
    r.fall_back_to_cpu("test: device lost").unwrap();
    assert_eq!(r.device(), DeviceKind::Cpu);
    assert_eq!(r.fallback(), Some("test: device lost"));
    assert!(r
        .device_reason()
        .starts_with("CPU: fell back from the GPU (test: device lost)"));
    assert!(rel_l2(r.image(), &before) < TOLERANCE);
    let e0 = edit(&bases, 0, 5);
    let after = r.relight_region(0, &e0).unwrap().to_vec();
    assert!(rel_l2(&after, cpu.relight_region(0, &e0).unwrap()) < TOLERANCE);
}

/// A malformed edit is refused with the CPU relighter's own message, on either device.
#[test]
fn bad_edits_are_refused_alike_on_gpu_and_cpu() {
    if gpu_or_skip("bad_edits_are_refused_alike_on_gpu_and_cpu").is_none() {
        return;
    }
    let stack = cornell();
    let (_, coefs) = default_coefs(&stack.header);
    let mut gpu = Relighter::new(stack.clone(), DevicePreference::Gpu).unwrap();
    let mut cpu = Relighter::new(stack, DevicePreference::Cpu).unwrap();
    let message = |r: Result<&[f32], GpuError>| match r {
        Err(e @ GpuError::Engine(_)) => e.to_string(),
        other => panic!("expected an engine error, got {:?}", other.map(|_| ())),
    };
    let mut nan = coefs.clone();
    nan[0][0] = Rgb::new(f32::NAN, 0.0, 0.0);
    type Case<'a> = Box<dyn Fn(&mut Relighter) -> String + 'a>;
    let cases: Vec<(&str, Case)> = vec![
        (
            "incremental before full",
            Box::new(|r| message(r.relight_region(0, &coefs[0]))),
        ),
        (
            "one list missing",
            Box::new(|r| message(r.relight(&coefs[1..]))),
        ),
        ("NaN coefficient", Box::new(|r| message(r.relight(&nan)))),
        (
            "too few bases",
            Box::new(|r| message(r.relight_region(0, &coefs[0][..1]))),
        ),
        (
            "no such region",
            Box::new(|r| message(r.relight_region(9, &coefs[0]))),
        ),
    ];
    for (what, case) in &cases {
        let (g, c) = (case(&mut gpu), case(&mut cpu));
        assert_eq!(g, c, "{what}");
        assert_eq!(
            gpu.device(),
            DeviceKind::Gpu,
            "{what}: a bad edit is no GPU failure"
        );
    }
}

/// Runs `child_with_every_adapter_hidden` in a child process whose Vulkan loader finds no
/// driver at all (both the old and the new variable: the loader reads either).
#[test]
fn hidden_adapters_fall_back_to_the_cpu_with_the_reason() {
    let out = Command::new(std::env::current_exe().unwrap())
        .args([
            "--ignored",
            "--exact",
            "child_with_every_adapter_hidden",
            "--nocapture",
        ])
        .env("RELUME_TEST_ADAPTERS_HIDDEN", "1")
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && text.contains("1 passed"), "{text}");
}

/// Only meaningful inside the child process above (ignored otherwise).
#[test]
#[ignore = "run by hidden_adapters_fall_back_to_the_cpu_with_the_reason"]
fn child_with_every_adapter_hidden() {
    assert_eq!(
        std::env::var("RELUME_TEST_ADAPTERS_HIDDEN").as_deref(),
        Ok("1"),
        "run through hidden_adapters_fall_back_to_the_cpu_with_the_reason"
    );
    let auto = choose_device(DevicePreference::Auto).unwrap();
    assert_eq!(auto.kind, DeviceKind::Cpu);
    assert!(
        auto.reason.starts_with("CPU: no GPU adapter"),
        "{}",
        auto.reason
    );
    let forced = choose_device(DevicePreference::Gpu)
        .err()
        .expect("no adapter to force");
    assert!(matches!(forced, GpuError::NoAdapter(_)), "{forced}");
    eprintln!("auto: {}\ngpu: {forced}", auto.reason);
    let stack = cornell();
    let (_, coefs) = default_coefs(&stack.header);
    let mut r = Relighter::new(stack.clone(), DevicePreference::Auto).unwrap();
    assert_eq!(r.device(), DeviceKind::Cpu);
    let mut cpu = CpuRelighter::new(stack.clone()).unwrap();
    assert!(r.relight(&coefs).unwrap() == cpu.relight(&coefs).unwrap());
    assert!(Relighter::new(stack, DevicePreference::Gpu).is_err());
}
