//! `--preset` on bake / reference / bench bake, and `relume report` end to end at 16².

mod common;

use std::path::{Path, PathBuf};

use common::*;
use relume_engine::bake::presets::Preset;
use relume_engine::brdf::BasisCount;
use relume_engine::stack::tiled::file::read_tiled;

/// The assets' Cornell scene with its resolution set to `w`×`h`.
fn small_cornell(dir: &Path, w: u32, h: u32) -> PathBuf {
    let text = std::fs::read_to_string(root().join("assets/cornell.scene.json")).unwrap();
    let mut scene: serde_json::Value = serde_json::from_str(&text).unwrap();
    scene["resolution"] = serde_json::json!({"width": w, "height": h});
    let path = dir.join("cornell.scene.json");
    std::fs::write(&path, scene.to_string()).unwrap();
    path
}

#[test]
fn bake_with_a_preset_uses_its_values_and_flags_override_them() {
    let dir = scratch("bake");
    let scene = small_cornell(&dir, 32, 24);
    // Draft: its samples, its basis tolerance, half the scene's resolution.
    let stack = dir.join("draft.exr");
    let bake = json_of(&relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&stack),
        "--preset",
        "draft",
        "--json",
    ]));
    assert_eq!(
        (
            bake["report"]["width"].as_u64(),
            bake["report"]["height"].as_u64()
        ),
        (Some(16), Some(12))
    );
    let h = read_tiled(&stack).unwrap().header;
    let d = Preset::Draft.values();
    assert_eq!(
        (h.spp, h.light_samples, h.sampling.as_str()),
        (d.spp, d.light_samples, "mixture")
    );
    for r in h.regions.iter().filter(|r| r.editable) {
        let count = r.basis.as_ref().unwrap().count;
        assert!(
            matches!(count, BasisCount::Tolerance(t) if t == d.basis_tolerance),
            "{count:?}"
        );
    }
    // Explicit flags win; what they do not name stays the preset's.
    let stack = dir.join("override.exr");
    json_of(&relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&stack),
        "--preset",
        "preview",
        "--spp",
        "2",
        "--sampling",
        "uniform",
        "--bases",
        "6",
        "--resolution",
        "10x8",
        "--json",
    ]));
    let h = read_tiled(&stack).unwrap().header;
    let p = Preset::Preview.values();
    assert_eq!((h.width, h.height, h.spp), (10, 8, 2));
    assert_eq!(
        (h.light_samples, h.sampling.as_str()),
        (p.light_samples, "uniform")
    );
    for r in h.regions.iter().filter(|r| r.editable) {
        assert!(matches!(
            r.basis.as_ref().unwrap().count,
            BasisCount::Fixed(6)
        ));
    }
    // An unknown preset names the ones there are.
    let out = relume(&[
        "bake",
        s(&scene),
        "-o",
        s(&dir.join("x.exr")),
        "--preset",
        "ultra",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("draft") && err.contains("preview") && err.contains("final"),
        "{err}"
    );
    assert!(!dir.join("x.exr").exists());
}

#[test]
fn reference_and_bench_bake_take_the_preset_too() {
    let dir = scratch("reference");
    let scene = small_cornell(&dir, 24, 24);
    let image = dir.join("ref.exr");
    let r = json_of(&relume(&[
        "reference",
        s(&scene),
        "-o",
        s(&image),
        "--preset",
        "draft",
        "--spp",
        "1",
        "--json",
    ]));
    assert_eq!(
        (r["width"].as_u64(), r["height"].as_u64()),
        (Some(12), Some(12))
    );
    let b = json_of(&relume(&[
        "bench",
        "bake",
        s(&scene),
        "--preset",
        "draft",
        "--spp",
        "1",
        "--json",
    ]));
    assert!(
        b["effective_rays_per_second"].as_f64().unwrap() > 0.0,
        "{b}"
    );
}

#[test]
fn report_runs_end_to_end_at_16_squared_and_caches_its_reference() {
    let dir = scratch("report");
    let out = dir.join("report");
    let chart = dir.join("chart.png");
    let cornell = root().join("assets/cornell.scene.json");
    let ring = root().join("assets/ring.scene.json");
    let argv = [
        "report",
        s(&cornell),
        s(&ring),
        "--resolution",
        "16x16",
        "--reference-spp",
        "16",
        "--relight-repeats",
        "2",
        "--out",
        s(&out),
        "--chart",
        s(&chart),
        "--json",
    ];
    let report = json_of(&relume(&argv));
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6, "2 scenes × 3 presets");
    for (row, preset) in rows
        .iter()
        .zip(["draft", "preview", "final"].iter().cycle())
    {
        assert_eq!(row["preset"], *preset);
        let side = if *preset == "draft" { 8 } else { 16 };
        assert_eq!(
            (row["width"].as_u64(), row["height"].as_u64()),
            (Some(side), Some(side))
        );
        for key in [
            "bake_seconds",
            "relight_ms",
            "stack_file_bytes",
            "rel_l2",
            "rel_l2_raw",
        ] {
            let v = row[key].as_f64().unwrap_or(f64::NAN);
            assert!(v.is_finite() && v >= 0.0, "{key}: {row}");
        }
        assert!(row["rel_l2_raw"].as_f64().unwrap() > 0.0, "{row}");
        assert!(row["rel_l2"].as_f64() <= row["rel_l2_raw"].as_f64());
    }
    for r in report["references"].as_array().unwrap() {
        assert_eq!(r["cached"], false);
        assert!(r["noise_rel_l2"].as_f64().unwrap() > 0.0, "{r}");
    }
    let md = std::fs::read_to_string(out.join("presets.md")).unwrap();
    assert!(
        md.contains("| cornell | preview |") && md.contains("| ring | final |"),
        "{md}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("presets.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 6);
    let png = std::fs::read(&chart).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert!(
        !out.join("stacks").exists(),
        "stacks are deleted after measuring"
    );
    // A second run renders no reference: it comes from the cache, identical.
    let again = json_of(&relume(&argv));
    for (a, b) in report["references"]
        .as_array()
        .unwrap()
        .iter()
        .zip(again["references"].as_array().unwrap())
    {
        assert_eq!(b["cached"], true);
        assert_eq!(a["noise_rel_l2"], b["noise_rel_l2"]);
    }
    // The bakes use the same seed: the same images, so the same errors.
    for (a, b) in rows.iter().zip(again["rows"].as_array().unwrap()) {
        assert_eq!(a["rel_l2_raw"], b["rel_l2_raw"]);
    }
}

#[test]
fn report_redraw_draws_the_committed_presets_json() {
    // The README's chart: `relume report --redraw` from docs/report/presets.json, no bake.
    let dir = scratch("redraw");
    std::fs::copy(
        root().join("docs/report/presets.json"),
        dir.join("presets.json"),
    )
    .unwrap();
    let chart = dir.join("chart.png");
    let out = relume(&["report", "--redraw", "--out", s(&dir), "--chart", s(&chart)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let md = std::fs::read_to_string(dir.join("presets.md")).unwrap();
    assert!(md.contains("| cornell | preview | 512×512 |"), "{md}");
    let png = std::fs::read(&chart).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    // IHDR: width and height, big-endian, at bytes 16..24.
    let size = |i: usize| u32::from_be_bytes(png[i..i + 4].try_into().unwrap());
    assert_eq!((size(16), size(20)), (960, 600));
}
