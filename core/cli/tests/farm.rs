//! The farm routes end to end through the `relume` binary: `bake --guide-only`,
//! `bake --partition i/N`, `merge`, and the Open Job Description template run by `openjd`
//! (from PyPI's openjd-cli) — each gives the stack of a one-machine bake, bit for bit.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::*;
use relume_engine::bake::farm::partial::{read_partial_header, PARTIAL_FORMAT_VERSION};
use relume_engine::stack::tiled::file::read_tiled;
use relume_engine::stack::tiled::STACK_FORMAT_VERSION_TILED;

/// Guided, denoised preview with a light group per light, tiny.
const OPTIONS: &[&str] = &[
    "--preset",
    "preview",
    "--resolution",
    "24x20",
    "--light-groups",
    "per-light",
    "--seed",
    "5",
];

/// The merged file is the single bake's file, byte for byte (both are the tiled format,
/// finalised by the same streaming code and written by the same writer).
fn assert_same_stack(a: &Path, b: &Path) {
    let (bytes_a, bytes_b) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap());
    assert!(
        bytes_a == bytes_b,
        "{} ({} bytes) and {} ({} bytes) differ",
        a.display(),
        bytes_a.len(),
        b.display(),
        bytes_b.len()
    );
}

fn single_bake(dir: &Path, scene: &Path) -> PathBuf {
    let single = dir.join("single.exr");
    let mut args = vec!["bake", s(scene), "-o", s(&single)];
    args.extend_from_slice(OPTIONS);
    ok(relume(&args));
    single
}

#[test]
fn guide_partitions_and_merge_on_the_command_line() {
    let dir = scratch("cli");
    let scene = root().join("assets/cornell.scene.json");
    let single = single_bake(&dir, &scene);
    let guide = dir.join("guide.rguide");
    let mut args = vec!["bake", s(&scene), "--guide-only", "-o", s(&guide)];
    args.extend_from_slice(OPTIONS);
    ok(relume(&args));
    let split = |n: usize| -> Vec<PathBuf> {
        (0..n)
            .map(|i| {
                let part = dir.join(format!("part_{n}_{i}.rpart"));
                let p = format!("{i}/{n}");
                let mut args = vec![
                    "bake",
                    s(&scene),
                    "--partition",
                    &p,
                    "--guide",
                    s(&guide),
                    "-o",
                    s(&part),
                    "--json",
                ];
                args.extend_from_slice(OPTIONS);
                let json = json_of(&relume(&args));
                assert_eq!(json["partition"], serde_json::json!([i, n]));
                let header = read_partial_header(&part).unwrap();
                assert_eq!(header.format_version, PARTIAL_FORMAT_VERSION);
                part
            })
            .collect()
    };
    let mut parts = Vec::new();
    for n in [2usize, 3] {
        parts = split(n);
        let merged = dir.join(format!("merged_{n}.exr"));
        let mut args = vec!["merge"];
        // Any order; the scene comes from the parts.
        args.extend(parts.iter().rev().map(|p| s(p)));
        args.extend_from_slice(&["-o", s(&merged)]);
        ok(relume(&args));
        assert_same_stack(&single, &merged);
        let stack = read_tiled(&merged).unwrap();
        assert_eq!(stack.header.format_version, STACK_FORMAT_VERSION_TILED);
    }
    let refused = |args: &[&str]| {
        let out = relume(args);
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let bad = dir.join("bad.exr");
    let before: Vec<Vec<u8>> = parts.iter().map(|p| std::fs::read(p).unwrap()).collect();
    // The merge's forecast is held to the budget before any part's body is read.
    let e = refused(&[
        "merge",
        s(&parts[0]),
        s(&parts[1]),
        s(&parts[2]),
        "-o",
        s(&bad),
        "--memory-budget-mb",
        "1",
    ]);
    assert!(
        e.contains("not enough memory for this merge")
            && e.contains("1.0 MiB is the memory budget"),
        "{e}"
    );
    assert!(!bad.exists(), "a refused merge writes nothing");
    for (part, before) in parts.iter().zip(&before) {
        assert!(
            &std::fs::read(part).unwrap() == before,
            "a refused merge leaves {} as it was",
            part.display()
        );
    }
    let e = refused(&["merge", s(&parts[0]), s(&parts[2]), "-o", s(&bad)]);
    assert!(e.contains("missing") && e.contains("partition 1/3"), "{e}");
    let e = refused(&[
        "merge",
        s(&parts[0]),
        s(&parts[1]),
        s(&parts[1]),
        s(&parts[2]),
        "-o",
        s(&bad),
    ]);
    assert!(
        e.contains("duplicated") && e.contains("part_3_1.rpart"),
        "{e}"
    );
    // A partition of another seed is foreign.
    let foreign = dir.join("foreign.rpart");
    let mut args = vec!["bake", s(&scene), "--partition", "1/3", "-o", s(&foreign)];
    args.extend_from_slice(&OPTIONS[..OPTIONS.len() - 2]);
    args.extend_from_slice(&["--seed", "6"]);
    ok(relume(&args));
    let e = refused(&[
        "merge",
        s(&parts[0]),
        s(&foreign),
        s(&parts[2]),
        "-o",
        s(&bad),
    ]);
    assert!(e.contains("foreign") && e.contains("foreign.rpart"), "{e}");
    // A guide made with other options is refused by the partition.
    let mut args = vec![
        "bake",
        s(&scene),
        "--partition",
        "0/3",
        "--guide",
        s(&guide),
        "-o",
        s(&bad),
    ];
    args.extend_from_slice(&OPTIONS[..OPTIONS.len() - 2]);
    args.extend_from_slice(&["--seed", "6"]);
    let e = refused(&args);
    assert!(e.contains("other bake settings"), "{e}");
    assert!(!bad.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_open_job_description_template_runs_under_openjd() {
    let openjd = std::env::var("RELUME_OPENJD").unwrap_or_else(|_| "openjd".into());
    if Command::new(&openjd).arg("--version").output().is_err() {
        eprintln!(
            "SKIPPED: `{openjd}` not found: install the Open Job Description CLI with \
             `pip install openjd-cli` (scripts/test.sh does) to run the farm template"
        );
        return;
    }
    let dir = scratch("openjd");
    let scene = root().join("assets/cornell.scene.json");
    let single = single_bake(&dir, &scene);
    let template = root().join("farm/openjd/relume-bake.template.yaml");
    let check = Command::new(&openjd)
        .args(["check", s(&template)])
        .output()
        .unwrap();
    assert!(
        check.status.success(),
        "{}",
        String::from_utf8_lossy(&check.stderr)
    );
    let output = dir.join("merged.exr");
    let work = dir.join("work");
    let run = Command::new(&openjd)
        .args(["run", s(&template), "--step", "Merge", "--run-dependencies"])
        .arg("-p")
        .arg(format!("Scene={}", s(&scene.canonicalize().unwrap())))
        .arg("-p")
        .arg(format!("WorkDir={}", s(&work)))
        .arg("-p")
        .arg(format!("Output={}", s(&output)))
        .args(["-p", "Partitions=3"])
        .arg("-p")
        .arg(format!("BakeOptions={}", OPTIONS.join(" ")))
        .arg("-p")
        .arg(format!("Relume={}", env!("CARGO_BIN_EXE_relume")))
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success() && log.contains("Session ended successfully"),
        "{log}"
    );
    assert!(
        log.contains("Chunks run: 5"),
        "guide + 3 partitions + merge: {log}"
    );
    assert_same_stack(&single, &output);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_flamenco_job_type_compiles_and_its_tasks_bake_the_same_stack() {
    // Flamenco cannot run here; node runs the job type's compileJob with stand-ins for
    // Flamenco's author/path API and executes the tasks in dependency order.
    if Command::new("node").arg("--version").output().is_err() {
        eprintln!("SKIPPED: node not found: the Flamenco job type (JavaScript) is not checked");
        return;
    }
    let dir = scratch("flamenco");
    let scene = root().join("assets/cornell.scene.json");
    let single = single_bake(&dir, &scene);
    let output = dir.join("merged.exr");
    let out = Command::new("node")
        .arg(root().join("farm/flamenco/run_locally.js"))
        .args([
            s(&scene),
            s(&output),
            s(&dir.join("work")),
            "4",
            &OPTIONS.join(" "),
        ])
        .arg(env!("CARGO_BIN_EXE_relume"))
        .arg("--run")
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{log}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        log.contains("6 tasks (guide, 4 partitions, merge)"),
        "{log}"
    );
    assert_same_stack(&single, &output);
    let _ = std::fs::remove_dir_all(&dir);
}
