//! Shared by the CLI tests: running the `relume` binary, reading its JSON, the repository
//! root and a scratch folder per test.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `relume` binary of this build with `args`.
pub fn relume(args: &[&str]) -> Output {
    relume_env(args, &[])
}

/// Runs the `relume` binary with `args` and the extra environment `env`.
pub fn relume_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relume"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("run relume")
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The command's stdout as JSON, after checking that it succeeded.
pub fn json_of(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "relume failed: {}", stderr(out));
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

/// The command's output, after checking that it succeeded (both streams shown otherwise).
pub fn ok(out: Output) -> Output {
    assert!(
        out.status.success(),
        "failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    out
}

/// The repository's root (the assets, farm and scripts folders are below it).
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// An empty folder for one test: named after the test binary, this process and `name`, so
/// that suites and concurrent runs never share one; what an earlier run left is removed.
pub fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "relume-{}-{}-{name}",
        env!("CARGO_CRATE_NAME"),
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A path as the `&str` argument the command line takes.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Bakes the assets' Cornell box at `resolution` ("WxH") with `spp` eye samples and one light
/// sample into `stack`; returns the scene file's path.
pub fn bake_cornell(stack: &Path, resolution: &str, spp: &str) -> PathBuf {
    let scene = root().join("assets/cornell.scene.json");
    json_of(&relume(&[
        "bake",
        s(&scene),
        "-o",
        s(stack),
        "--resolution",
        resolution,
        "--spp",
        spp,
        "--light-samples",
        "1",
        "--json",
    ]));
    scene
}
