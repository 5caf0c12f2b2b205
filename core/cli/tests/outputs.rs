//! Outputs never destroy a file: not an input (merge's scene, given or recorded in the
//! parts), not another output of the same command, not a FIFO or a directory; the same bake
//! gives the same bytes; and the exit codes are the ones the README documents.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::*;

/// The command failed with exit code 1 (an error, not a signal or a panic) and said every
/// one of `needles`.
fn fails_saying(out: &Output, needles: &[&str]) {
    let stderr = stderr(out);
    assert_eq!(
        out.status.code(),
        Some(1),
        "expected an error exit: {stderr}"
    );
    for needle in needles {
        assert!(stderr.contains(needle), "expected {needle:?} in: {stderr}");
    }
}

/// The Cornell scene copied into `dir` (so a test may see it overwritten) and a tiny stack
/// baked from it: (scene, stack).
fn scene_and_stack(dir: &Path) -> (PathBuf, PathBuf) {
    let scene = dir.join("scene.json");
    std::fs::copy(root().join("assets/cornell.scene.json"), &scene).unwrap();
    let stack = dir.join("tiny.exr");
    ok(relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&stack),
        "--resolution",
        "16x16",
        "--spp",
        "1",
        "--light-samples",
        "1",
    ]));
    (scene, stack)
}

#[test]
fn merge_refuses_an_output_over_its_scene_or_a_part_and_they_survive() {
    let dir = scratch("merge-over-scene");
    let (scene, _) = scene_and_stack(&dir);
    let parts: Vec<PathBuf> = (0..2).map(|i| dir.join(format!("p{i}.rpart"))).collect();
    for (i, part) in parts.iter().enumerate() {
        let p = format!("{i}/2");
        ok(relume(&[
            "bake",
            s(&scene),
            "--partition",
            &p,
            "-o",
            s(part),
            "--resolution",
            "16x16",
            "--spp",
            "2",
            "--light-samples",
            "1",
        ]));
    }
    let scene_before = std::fs::read(&scene).unwrap();
    let part_before = std::fs::read(&parts[0]).unwrap();
    let merge = |extra: &[&str]| {
        let mut args = vec!["merge", s(&parts[0]), s(&parts[1])];
        args.extend_from_slice(extra);
        relume(&args)
    };
    fails_saying(
        &merge(&["--scene", s(&scene), "-o", s(&scene)]),
        &[s(&scene), "is also an input of this command (the scene)"],
    );
    // No --scene: the scene the parts record is an input all the same.
    fails_saying(
        &merge(&["-o", s(&scene)]),
        &[s(&scene), "(the scene recorded in the partial stacks)"],
    );
    fails_saying(
        &merge(&["-o", s(&parts[0])]),
        &[s(&parts[0]), "(a partial stack)"],
    );
    assert_eq!(std::fs::read(&scene).unwrap(), scene_before);
    assert_eq!(std::fs::read(&parts[0]).unwrap(), part_before);
    // The same merge to a fresh path works.
    ok(merge(&["-o", s(&dir.join("merged.exr"))]));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn two_outputs_of_one_command_that_are_one_file_are_refused() {
    let dir = scratch("two-outputs");
    let (scene, stack) = scene_and_stack(&dir);
    let target = dir.join("x.exr");
    std::fs::write(&target, b"an earlier image the user keeps").unwrap();
    let before = std::fs::read(&target).unwrap();
    let other_spelling = dir.join(".").join("x.exr");
    fails_saying(
        &relume(&[
            "relight",
            s(&stack),
            "-o",
            s(&target),
            "--png",
            s(&other_spelling),
        ]),
        &[
            "x.exr",
            "(the PNG) is also the image",
            "choose two different output paths",
        ],
    );
    fails_saying(
        &relume(&[
            "reference",
            s(&scene),
            "-o",
            s(&target),
            "--png",
            s(&target),
            "--resolution",
            "8x8",
            "--spp",
            "1",
        ]),
        &[s(&target), "(the PNG) is also the image"],
    );
    assert_eq!(std::fs::read(&target).unwrap(), before);

    // The report's chart over the report it redraws, or over its own table.
    let out = dir.join("report");
    std::fs::create_dir_all(&out).unwrap();
    let json = out.join("presets.json");
    let md = out.join("presets.md");
    std::fs::write(&json, b"{\"rows\": []}").unwrap();
    std::fs::write(&md, b"a table the user keeps").unwrap();
    let redraw =
        |chart: &Path| relume(&["report", "--redraw", "--out", s(&out), "--chart", s(chart)]);
    fails_saying(&redraw(&json), &[s(&json), "(the report being redrawn)"]);
    fails_saying(&redraw(&md), &[s(&md), "(the chart) is also the table"]);
    assert_eq!(std::fs::read(&json).unwrap(), b"{\"rows\": []}");
    assert_eq!(std::fs::read(&md).unwrap(), b"a table the user keeps");
    std::fs::remove_dir_all(&dir).ok();
}

#[cfg(unix)]
#[test]
fn an_output_that_is_a_fifo_or_a_directory_is_refused_and_stays() {
    use std::os::unix::fs::FileTypeExt;
    let dir = scratch("special-outputs");
    let (scene, stack) = scene_and_stack(&dir);
    let fifo = dir.join("pipe");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .expect("run mkfifo");
    assert!(made.success(), "mkfifo failed");
    fails_saying(
        &relume(&["relight", s(&stack), "-o", s(&fifo)]),
        &[
            s(&fifo),
            "is a FIFO (named pipe), not a regular file: refused",
            "does not write through",
        ],
    );
    fails_saying(
        &relume(&[
            "relight",
            s(&stack),
            "-o",
            s(&dir.join("ok.exr")),
            "--png",
            s(&fifo),
        ]),
        &[s(&fifo), "is a FIFO (named pipe)"],
    );
    assert!(
        std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo(),
        "the FIFO was replaced"
    );
    assert!(!dir.join("ok.exr").exists(), "refused before any work");

    let folder = dir.join("folder");
    std::fs::create_dir(&folder).unwrap();
    std::fs::write(folder.join("keep.txt"), b"kept").unwrap();
    fails_saying(
        &relume(&["bake", s(&scene), "-o", s(&folder)]),
        &[s(&folder), "is a directory, not a regular file"],
    );
    assert_eq!(std::fs::read(folder.join("keep.txt")).unwrap(), b"kept");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_same_bake_twice_gives_the_same_bytes() {
    let dir = scratch("deterministic");
    let scene = root().join("assets/cornell.scene.json");
    // Three bakes: the attributes' order used to follow a random hash, so two files matched
    // by chance one time in 24 and three one time in 576.
    let files: Vec<Vec<u8>> = (0..3)
        .map(|i| {
            let path = dir.join(format!("b{i}.exr"));
            ok(relume(&[
                "bake",
                s(&scene),
                "-o",
                s(&path),
                "--resolution",
                "24x20",
                "--spp",
                "2",
                "--light-samples",
                "1",
                "--light-groups",
                "per-light",
                "--seed",
                "7",
            ]));
            std::fs::read(&path).unwrap()
        })
        .collect();
    assert!(files[0].len() > 1000, "a stack was written");
    for (i, f) in files.iter().enumerate().skip(1) {
        assert!(*f == files[0], "bake {i} differs from bake 0 byte for byte");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn exit_codes_are_the_documented_ones() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    assert!(
        readme.contains("exits with status 1") && readme.contains("exits with status 2"),
        "the README documents both exit codes"
    );
    // A command line that does not parse: 2, with clap's message (not a Relume error's).
    for args in [
        &["bake", "--no-such-flag"][..],
        &["relight"][..],
        &["bake", "x.json", "-o", "x.exr", "--spp", "many"][..],
    ] {
        let out = relume(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(
            stderr(&out).starts_with("error: "),
            "{args:?}: {}",
            stderr(&out)
        );
    }
    // An error once parsed: 1, naming the file.
    let out = relume(&["info", "/nonexistent/stack.exr"]);
    fails_saying(&out, &["/nonexistent/stack.exr"]);
}
