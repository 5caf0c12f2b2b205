//! `relume bake --estimate-only` is bounded: settings past any real bake are refused at
//! once, and Ctrl-C (SIGINT) cancels the forecast within a second with the named error.

mod common;

use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use common::*;

/// Waits for `child` at most `limit`; kills it and returns `None` past that.
fn wait_at_most(child: &mut Child, limit: Duration) -> Option<(ExitStatus, Duration)> {
    let start = Instant::now();
    while start.elapsed() < limit {
        if let Some(status) = child.try_wait().unwrap() {
            return Some((status, start.elapsed()));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

fn spawn(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_relume"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run relume")
}

fn stderr_of(child: Child) -> String {
    String::from_utf8_lossy(&child.wait_with_output().unwrap().stderr).into_owned()
}

#[test]
fn an_estimate_with_four_billion_indirect_samples_is_refused_at_once() {
    let dir = scratch("huge-samples");
    let scene = root().join("assets/cornell.scene.json");
    let out = dir.join("x.exr");
    let mut child = spawn(&[
        "bake",
        s(&scene),
        "-o",
        s(&out),
        "--indirect-samples",
        "4294967295",
        "--estimate-only",
    ]);
    let (status, took) =
        wait_at_most(&mut child, Duration::from_secs(30)).expect("the estimate ran past 30 s");
    let err = stderr_of(child);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(
        err.contains("--indirect-samples") && err.contains("at most 1024"),
        "{err}"
    );
    assert!(took < Duration::from_secs(10), "{took:?}");
}

#[test]
fn ctrl_c_cancels_an_estimate_within_a_second() {
    let dir = scratch("sigint");
    let mut scene: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(root().join("assets/cornell.scene.json")).unwrap(),
    )
    .unwrap();
    let lights = scene["lights"].as_array_mut().unwrap();
    for i in 0..1000 {
        let (u, v) = ((i % 32) as f64 / 31.0, ((i / 32) % 32) as f64 / 31.0);
        lights.push(serde_json::json!({
            "type": "point", "position": [-0.8 + 1.6 * u, -0.8 + 1.6 * v, 0.9],
            "power": 1.0, "color": [1.0, 1.0, 1.0]
        }));
    }
    scene["resolution"] = serde_json::json!({"width": 256, "height": 256});
    let path = dir.join("lights.scene.json");
    std::fs::write(&path, scene.to_string()).unwrap();
    let out = dir.join("x.exr");
    let mut child = spawn(&[
        "bake",
        s(&path),
        "-o",
        s(&out),
        "--light-samples",
        "1024",
        "--indirect-samples",
        "1024",
        "--bounces",
        "8",
        "--estimate-only",
    ]);
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the estimate finished before the signal: make it costlier"
    );
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let (status, took) =
        wait_at_most(&mut child, Duration::from_secs(10)).expect("SIGINT did not stop it");
    let err = stderr_of(child);
    // Cancelled by the engine (a named error, exit status 1), not killed by the signal.
    assert_eq!(status.code(), Some(1), "{status:?}: {err}");
    assert!(err.contains("cancelled"), "{err}");
    assert!(took < Duration::from_secs(1), "{took:?} after SIGINT");
    assert!(!out.exists());
}
