//! `relume relight --denoise oidn|linear|none`: none and linear write the relit image bit
//! for bit; oidn with the scene denoises with albedo and normal features when OIDN is found
//! (RELUME_OIDN_LIBRARY, here the bpy wheel's copy), and falls back to the linear image with
//! a one-line note when it is not.
mod common;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use common::{json_of, ok, relume_env, root, s, scratch, stderr};
use relume_engine::image_io::read_rgb_exr;
use relume_engine::materials::{resolve_materials, MaterialsFile};
use relume_engine::relight::CpuRelighter;
use relume_engine::stack::{bases::StackBases, tiled::file::read_tiled};

/// The `lib` folder of the bpy wheel `python3` would import (found without importing it).
fn bpy_lib_dir() -> Option<PathBuf> {
    let out = std::process::Command::new("python3")
        .args([
            "-c",
            "import importlib.util, os; s = importlib.util.find_spec('bpy'); \
             print(os.path.join(list(s.submodule_search_locations)[0], 'lib') if s and s.submodule_search_locations else '')",
        ])
        .output()
        .ok()?;
    let dir = String::from_utf8(out.stdout).ok()?.trim().to_string();
    (!dir.is_empty() && Path::new(&dir).is_dir()).then(|| PathBuf::from(dir))
}

/// The relit image (RGB) of `stack` at its bake-time materials, summed in this process.
fn relit_here(stack: &Path) -> Vec<f32> {
    let stack = Arc::new(read_tiled(stack).unwrap());
    let materials = resolve_materials(&stack.header.regions, &MaterialsFile::default()).unwrap();
    let coefs = StackBases::from_header(&stack.header)
        .unwrap()
        .coefficients(&materials)
        .unwrap();
    CpuRelighter::from_tiled(stack)
        .unwrap()
        .relight(&coefs)
        .unwrap()
        .chunks_exact(4)
        .flat_map(|p| p[..3].to_vec())
        .collect()
}

fn relight(stack: &Path, out: &Path, extra: &[&str], env: &[(&str, &str)]) -> std::process::Output {
    let mut args = vec![
        "relight",
        s(stack),
        "-o",
        s(out),
        "--device",
        "cpu",
        "--json",
    ];
    args.extend(extra);
    relume_env(&args, env)
}

#[test]
fn none_and_linear_write_the_relit_image_bit_for_bit_and_a_missing_oidn_falls_back() {
    let dir = scratch("none");
    let stack = dir.join("c.exr");
    let scene = common::bake_cornell(&stack, "24x24", "2");
    let exact = relit_here(&stack);
    let missing = [(
        "RELUME_OIDN_LIBRARY",
        "/nonexistent/libOpenImageDenoise.so.2",
    )];
    for mode in ["none", "linear"] {
        let out = dir.join(format!("{mode}.exr"));
        let r = json_of(&relight(&stack, &out, &["--denoise", mode], &missing));
        assert_eq!(
            (r["denoise"]["asked"].as_str(), r["denoise"]["ran"].as_str()),
            (Some(mode), Some(mode))
        );
        let written = read_rgb_exr(&out).unwrap().2;
        let same = written
            .iter()
            .zip(&exact)
            .all(|(a, b)| a.to_bits() == b.to_bits());
        assert!(
            same && written.len() == exact.len(),
            "{mode}: not the relit image bit for bit"
        );
    }
    // OIDN asked for (the default) and not found: the linear image, and one line saying why.
    if relume_denoise_found_elsewhere() {
        eprintln!("SKIPPED the fallback half: an OpenImageDenoise is on the system library path");
        return;
    }
    let out = dir.join("fallback.exr");
    let run = ok(relight(&stack, &out, &["--scene", s(&scene)], &missing));
    let r: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(r["denoise"]["asked"], "oidn");
    assert_eq!(r["denoise"]["ran"], "linear");
    let note = stderr(&run);
    assert_eq!(note.lines().count(), 1, "{note}");
    assert!(
        note.starts_with("note: linear (OpenImageDenoise did not run: OpenImageDenoise 2 was not found; tried /nonexistent/libOpenImageDenoise.so.2 (RELUME_OIDN_LIBRARY): no such file"),
        "{note}"
    );
    let written = read_rgb_exr(&out).unwrap().2;
    assert!(written
        .iter()
        .zip(&exact)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    std::fs::remove_dir_all(&dir).ok();
}

/// Whether the system's loader finds an OIDN by name (then the fallback cannot be shown).
fn relume_denoise_found_elsewhere() -> bool {
    relume_denoise::oidn::LibrarySearch {
        dirs: vec![],
        system: true,
    }
    .open()
    .is_ok()
}

#[test]
fn oidn_with_the_scene_denoises_with_features_and_stays_finite() {
    let Some(lib) = bpy_lib_dir() else {
        eprintln!("SKIPPED oidn_with_the_scene: no bpy wheel and so no OpenImageDenoise here (pip install bpy)");
        return;
    };
    let dir = scratch("oidn");
    let stack = dir.join("c.exr");
    let scene = common::bake_cornell(&stack, "32x32", "2");
    let out = dir.join("oidn.exr");
    let env = [("RELUME_OIDN_LIBRARY", s(&lib))];
    let r = json_of(&relight(&stack, &out, &["--scene", s(&scene)], &env));
    let d = &r["denoise"];
    assert_eq!(d["ran"], "oidn", "{d}");
    assert_eq!(d["features"], "albedo+normal", "{d}");
    assert!(d["note"].is_null(), "{d}");
    assert!(d["version"].as_str().unwrap().starts_with('2'), "{d}");
    let written = read_rgb_exr(&out).unwrap().2;
    assert!(written.iter().all(|v| v.is_finite()));
    assert_ne!(written, relit_here(&stack), "OIDN changed nothing");

    // Without the scene: OIDN on colour alone, and the report says what it lacked.
    let r = json_of(&relight(&stack, &dir.join("colour.exr"), &[], &env));
    assert_eq!(r["denoise"]["ran"], "oidn");
    assert_eq!(r["denoise"]["features"], "none");
    assert!(r["denoise"]["note"]
        .as_str()
        .unwrap()
        .contains("pass --scene"));
    let _ = root();
    std::fs::remove_dir_all(&dir).ok();
}
