//! The `relume` binary end to end on the assets' Cornell scene at a tiny resolution:
//! bake → relight → reference → compare, the basis report, the benches, and errors.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::*;

#[test]
fn bake_relight_reference_compare() {
    let dir = scratch("pipeline");
    let scene = root().join("assets/cornell.scene.json");
    let stack = dir.join("c.exr");
    let common = [
        "--resolution",
        "40x40",
        "--spp",
        "2",
        "--light-samples",
        "2",
        "--seed",
        "3",
    ];
    let mut args = vec!["bake", s(&scene), "-o", s(&stack), "--json"];
    args.extend(common);
    let bake = json_of(&relume(&args));
    assert!(bake["layers"].as_u64().unwrap() > 10, "{bake}");
    assert!(bake["report"]["rays"].as_u64().unwrap() > 0);

    let mats = dir.join("m.json");
    std::fs::write(
        &mats,
        r#"{"format": "relume-materials", "version": 1, "regions": {"Object": {"model": "blinn_phong", "kd": [0.1, 0.5, 0.1], "ks": [0.5, 0.5, 0.5], "ns": 80}}}"#,
    )
    .unwrap();
    let relit = dir.join("relit.exr");
    let r = json_of(&relume(&[
        "relight",
        s(&stack),
        "--materials",
        s(&mats),
        "-o",
        s(&relit),
        "--png",
        s(&dir.join("relit.png")),
        "--scene",
        s(&scene),
        "--denoise",
        "none",
        "--json",
    ]));
    assert_eq!(r["width"], 40);
    assert_eq!(r["denoise"]["ran"], "none");
    assert!(dir.join("relit.png").exists());

    let reference = dir.join("ref.exr");
    let mut args = vec![
        "reference",
        s(&scene),
        "--materials",
        s(&mats),
        "-o",
        s(&reference),
        "--brdf",
        "projected",
        "--json",
    ];
    args.extend(common);
    json_of(&relume(&args));
    let cmp = json_of(&relume(&["compare", s(&relit), s(&reference), "--json"]));
    let rel = cmp["rel_l2"].as_f64().unwrap();
    assert!(rel < 5e-4, "relit vs projected reference: {rel}");

    // A different seed gives different paths, so a visibly different image.
    let other = dir.join("ref_seed.exr");
    let mut args = vec![
        "reference",
        s(&scene),
        "--materials",
        s(&mats),
        "-o",
        s(&other),
        "--brdf",
        "projected",
        "--json",
        "--seed",
        "4",
    ];
    args.extend(&common[..6]);
    json_of(&relume(&args));
    let cmp = json_of(&relume(&["compare", s(&relit), s(&other), "--json"]));
    assert!(cmp["rel_l2"].as_f64().unwrap() > 1e-3);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn basis_report_as_json() {
    let r = json_of(&relume(&[
        "basis", "--ns-min", "1", "--ns-max", "200", "--bases", "6", "--json",
    ]));
    assert_eq!(r["bases"], 6);
    let avg = r["avg_rel_l2"].as_f64().unwrap();
    let max = r["max_rel_l2"].as_f64().unwrap();
    assert!(
        avg <= 0.007979 && max <= 0.06747,
        "avg {avg} max {max}: the paper reports 0.7979 % / 6.747 %"
    );
    let t = json_of(&relume(&[
        "basis",
        "--ns-min",
        "1",
        "--ns-max",
        "10000",
        "--tolerance",
        "0.03",
        "--json",
    ]));
    assert!(t["max_rel_l2"].as_f64().unwrap() <= 0.03, "{t}");
}

#[test]
fn benches_print_figures() {
    let dir = scratch("bench");
    let scene = root().join("assets/cornell.scene.json");
    let b = json_of(&relume(&[
        "bench",
        "bake",
        s(&scene),
        "--resolution",
        "32x32",
        "--spp",
        "1",
        "--json",
    ]));
    for k in ["effective_rays_per_second", "raw_rays_per_second", "ratio"] {
        assert!(b[k].as_f64().unwrap() > 0.0, "{k}: {b}");
    }
    let stack = dir.join("b.exr");
    json_of(&relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&stack),
        "--resolution",
        "32x32",
        "--spp",
        "1",
        "--json",
    ]));
    let r = json_of(&relume(&[
        "bench",
        "relight",
        s(&stack),
        "--repeats",
        "3",
        "--json",
    ]));
    for k in [
        "full_ms",
        "fastest_incremental_ms",
        "bandwidth_gb_s",
        "bandwidth_bound_ms",
    ] {
        assert!(r[k].as_f64().unwrap() > 0.0, "{k}: {r}");
    }
    // The bound is the faster of the bandwidths measured before and after the relights.
    let both: Vec<f64> = r["bandwidth_gb_s_before_and_after"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(both.len(), 2, "{r}");
    assert!(both.iter().all(|b| *b > 0.0), "{r}");
    assert_eq!(
        r["bandwidth_gb_s"].as_f64().unwrap(),
        both[0].max(both[1]),
        "{r}"
    );
    let regions = r["incremental_per_region"].as_array().unwrap();
    assert_eq!(
        regions.len(),
        2,
        "one incremental figure per editable region: {r}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn errors_are_specific_and_exit_nonzero() {
    let dir = scratch("errors");
    let missing = relume(&[
        "bake",
        "/nonexistent/scene.json",
        "-o",
        s(&dir.join("x.exr")),
    ]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("/nonexistent/scene.json"));

    // A truncated stack.
    let scene = root().join("assets/cornell.scene.json");
    let stack = dir.join("t.exr");
    json_of(&relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&stack),
        "--resolution",
        "16x16",
        "--spp",
        "1",
        "--json",
    ]));
    let bytes = std::fs::read(&stack).unwrap();
    let cut = dir.join("cut.exr");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = relume(&["relight", s(&cut), "-o", s(&dir.join("o.exr"))]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("truncated"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A stack from another scene.
    let mut other: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&scene).unwrap()).unwrap();
    other["lights"][0]["power"] = serde_json::json!(1.0);
    let other_path = dir.join("other.scene.json");
    std::fs::write(&other_path, other.to_string()).unwrap();
    let out = relume(&[
        "relight",
        s(&stack),
        "-o",
        s(&dir.join("o.exr")),
        "--scene",
        s(&other_path),
    ]);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("another scene"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A material for a region that does not exist.
    let mats = dir.join("m.json");
    std::fs::write(&mats, r#"{"format": "relume-materials", "version": 1, "regions": {"Nope": {"model": "blinn_phong", "kd": [0.1, 0.1, 0.1], "ks": [0, 0, 0], "ns": 1}}}"#).unwrap();
    let out = relume(&[
        "relight",
        s(&stack),
        "--materials",
        s(&mats),
        "-o",
        s(&dir.join("o.exr")),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("Nope"));
    assert!(!dir.join("o.exr").exists(), "no output on error");

    let out = relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&dir.join("x.exr")),
        "--resolution",
        "12by12",
    ]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("--resolution"));
    std::fs::remove_dir_all(&dir).ok();
}

/// Bakes a tiny Cornell stack into `dir` and returns (scene, stack).
fn tiny_stack(dir: &Path) -> (PathBuf, PathBuf) {
    let stack = dir.join("tiny.exr");
    let scene = bake_cornell(&stack, "16x16", "1");
    (scene, stack)
}

/// The command failed with exit code 1 (an error, not a signal or a panic) and said `needle`.
fn fails_saying(out: &Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "expected an error exit: {stderr}"
    );
    assert!(stderr.contains(needle), "expected {needle:?} in: {stderr}");
}

#[test]
fn a_hostile_stack_is_an_error_not_an_abort() {
    let dir = scratch("hostile");
    let (_, stack) = tiny_stack(&dir);
    let bytes = std::fs::read(&stack).unwrap();
    let hostile = dir.join("hostile.exr");
    let crafted = relume_engine::stack::hostile::with_claimed_size(&bytes, 16384, 16384).unwrap();
    std::fs::write(&hostile, crafted).unwrap();
    let out = relume(&["relight", s(&hostile), "-o", s(&dir.join("o.exr"))]);
    fails_saying(&out, "claims 16384×16384 pixels");
}

#[test]
fn sizes_counts_and_threads_out_of_range_are_refused() {
    let dir = scratch("ranges");
    let scene = root().join("assets/cornell.scene.json");
    let out_path = dir.join("x.exr");
    let bake = |extra: &[&str]| {
        let mut args = vec!["bake", s(&scene), "-o", s(&out_path)];
        args.extend_from_slice(extra);
        relume(&args)
    };
    fails_saying(&bake(&["--resolution", "100000x100000"]), "1…65536");
    fails_saying(&bake(&["--resolution-scale", "1e10"]), "--resolution-scale");
    fails_saying(&bake(&["--spp", "0"]), "spp: must be ≥ 1");
    fails_saying(&bake(&["--passes", "0"]), "passes");
    fails_saying(&bake(&["--threads", "100000"]), "threads");
    // At 1 MiB the scene's own geometry is already over the budget: refused before its BVH
    // is built, with the same words as a bake over it.
    fails_saying(
        &bake(&["--memory-budget-mb", "1"]),
        "not enough memory for this scene's geometry",
    );
    assert!(!out_path.exists(), "a refused bake wrote a file");
}

#[test]
fn an_output_that_is_an_input_is_refused_and_the_input_survives() {
    let dir = scratch("overwrite");
    let (scene_asset, stack) = tiny_stack(&dir);
    let scene = dir.join("scene.json");
    std::fs::copy(&scene_asset, &scene).unwrap();
    let stack_before = std::fs::read(&stack).unwrap();
    let scene_before = std::fs::read(&scene).unwrap();
    fails_saying(
        &relume(&["relight", s(&stack), "-o", s(&stack)]),
        "is also an input of this command (the stack)",
    );
    let spelled_otherwise = dir.join(".").join("tiny.exr");
    fails_saying(
        &relume(&[
            "relight",
            s(&stack),
            "-o",
            s(&dir.join("o.exr")),
            "--png",
            s(&spelled_otherwise),
        ]),
        "the stack",
    );
    fails_saying(
        &relume(&["bake", s(&scene), "-o", s(&scene)]),
        "(the scene)",
    );
    assert_eq!(std::fs::read(&stack).unwrap(), stack_before);
    assert_eq!(std::fs::read(&scene).unwrap(), scene_before);
}

/// The materials the Python bindings refuse, refused by the command line in the same words
/// (core/py/tests/test_boundary.py checks the Python side with the same texts).
#[test]
fn the_command_line_refuses_the_materials_python_refuses() {
    let dir = scratch("materials-rules");
    let (_, stack) = tiny_stack(&dir);
    let cases = [
        (
            r#"{"model": "blinn_phong", "kd": [0.75, 0.75, 0.75], "ks": [0.5, 0.5, 0.5], "ns": 10}"#,
            r#"invalid region "Object".kd + ks: Kd + Ks = 1.25 > 1 in channel 0: the surface would reflect more light than it receives"#,
        ),
        (
            r#"{"model": "blinn_phong", "kd": [0.2, 0.2, 0.2], "ks": [0.1, 0.1, 0.1], "ns": 0}"#,
            r#"invalid region "Object".ns: the Blinn–Phong exponent must be finite and > 0, got 0"#,
        ),
        (
            r#"{"model": "blinn_phong", "kd": [-0.1, 0.2, 0.2], "ks": [0.1, 0.1, 0.1], "ns": 5}"#,
            r#"invalid region "Object".kd: channel 0 is negative (-0.1); albedos must be ≥ 0"#,
        ),
        (
            r#"{"model": "blinn_phong", "kd": [3e38, 0.2, 0.2], "ks": [0.1, 0.1, 0.1], "ns": 5}"#,
            r#"Kd + Ks = 300000000000000000000000000000000000000 > 1 in channel 0"#,
        ),
        (
            r#"{"model": "principled", "base_color": [0.5, 0.5, 0.5], "roughness": 2}"#,
            r#"invalid region "Object".roughness: must be in [0, 1], got 2"#,
        ),
        (
            r#"{"model": "principled", "base_color": [0.5, 0.5, 0.5], "metallic": 5}"#,
            r#"invalid region "Object".metallic: must be in [0, 1], got 5"#,
        ),
        (
            r#"{"model": "principled", "base_color": [0.5, 0.5, 0.5], "ior": 0}"#,
            r#"invalid region "Object".ior: must be finite and > 0, got 0"#,
        ),
    ];
    for (i, (material, message)) in cases.iter().enumerate() {
        let mats = dir.join(format!("m{i}.json"));
        std::fs::write(
            &mats,
            format!(r#"{{"format": "relume-materials", "version": 1, "regions": {{"Object": {material}}}}}"#),
        )
        .unwrap();
        let out_path = dir.join(format!("o{i}.exr"));
        fails_saying(
            &relume(&[
                "relight",
                s(&stack),
                "--materials",
                s(&mats),
                "-o",
                s(&out_path),
            ]),
            message,
        );
        assert!(!out_path.exists());
    }
}

/// `relight --refine`: a three-bounce stack, walls made mirrors (an edit the tail-edit layers
/// cannot follow): the refinement runs and says so; without the scene it is refused; and
/// `compare --tiles` compares tile means.
#[test]
fn relight_refines_an_edit_of_a_multi_bounce_stack() {
    let dir = scratch("refine");
    let scene = root().join("assets/cornell.scene.json");
    let stack = dir.join("c.exr");
    json_of(&relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&stack),
        "--resolution",
        "24x24",
        "--spp",
        "2",
        "--bounces",
        "3",
        "--json",
    ]));
    // No bounce budget: the cap is the bounces baked, and a refinement traces to it.
    let info = json_of(&relume(&["info", s(&stack), "--json"]));
    assert_eq!(info["bounces"], 3, "{info}");
    assert_eq!(info["refine_bounces"], 3, "{info}");
    let mats = dir.join("m.json");
    std::fs::write(
        &mats,
        r#"{"format": "relume-materials", "version": 1, "regions": {"White walls": {"model": "blinn_phong", "kd": [0, 0, 0], "ks": [0.9, 0.9, 0.9], "ns": 150}}}"#,
    )
    .unwrap();
    let relight = |out: &Path, refine: &str, scene_arg: bool| {
        let mut args = vec![
            "relight",
            s(&stack),
            "--materials",
            s(&mats),
            "-o",
            s(out),
            "--denoise",
            "none",
            "--refine",
            refine,
            "--json",
        ];
        if scene_arg {
            args.extend(["--scene", s(&scene)]);
        }
        relume(&args)
    };
    let plain = dir.join("plain.exr");
    let r = json_of(&relight(&plain, "0", true));
    assert!(r["refine"].is_null(), "{r}");
    let refined = dir.join("refined.exr");
    let r = json_of(&relight(&refined, "0.2", true));
    assert_eq!(r["refine"]["needed"], true, "{r}");
    assert!(r["refine"]["passes"].as_u64().unwrap() >= 1, "{r}");
    assert_eq!(r["refine"]["bake_samples"], 2, "{r}");
    let cmp = json_of(&relume(&["compare", s(&refined), s(&plain), "--json"]));
    assert!(
        cmp["rel_l2"].as_f64().unwrap() > 0.0,
        "the refinement changed nothing: {cmp}"
    );
    let tiles = json_of(&relume(&[
        "compare",
        s(&refined),
        s(&plain),
        "--tiles",
        "4",
        "--json",
    ]));
    assert_eq!(tiles["tiles"], 4);
    assert_eq!(tiles["pixels"], 36, "{tiles}"); // 6 × 6 tiles of 4 × 4
    assert!(tiles["mean_ratio"].as_f64().unwrap().is_finite());
    let out = relight(&dir.join("no_scene.exr"), "1", false);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("needs --scene"), "{}", stderr(&out));
    std::fs::remove_dir_all(&dir).ok();
}
