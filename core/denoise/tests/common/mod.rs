//! Shared by the denoise tests: where OIDN is (the bpy wheel's copy, as CI installs it), the
//! Cornell asset scene at a test size, a bake and a relight of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::Arc;

use relume_denoise::oidn::{LibrarySearch, ENV_VAR};
use relume_engine::bake::{bake_tiled, BakeSettings};
use relume_engine::brdf::MaterialSpec;
use relume_engine::materials::{resolve_materials, MaterialsFile};
use relume_engine::progress::Progress;
use relume_engine::relight::CpuRelighter;
use relume_engine::scene::{file::load_scene, Resolution, Scene};
use relume_engine::stack::bases::StackBases;
use relume_engine::stack::tiled::TiledStack;

pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The `lib` folder of the bpy wheel that `python3` imports, when there is one (found
/// without importing bpy).
pub fn bpy_lib_dir() -> Option<PathBuf> {
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

/// The search the tests use: [`ENV_VAR`], the bpy wheel's folder, the system. `None` (and
/// a message saying why the test is skipped) only when OIDN cannot be opened at all.
pub fn oidn_search(test: &str) -> Option<LibrarySearch> {
    let search = LibrarySearch::with_dirs(bpy_lib_dir().into_iter().collect());
    match search.open() {
        Ok(_) => Some(search),
        Err(e) => {
            eprintln!(
                "SKIPPED {test}: OpenImageDenoise is not on this machine ({e}); \
                 `pip install bpy` or set {ENV_VAR}"
            );
            None
        }
    }
}

/// The Cornell asset scene (assets/cornell.scene.json) at `size`².
pub fn cornell(size: u32) -> Scene {
    let mut scene = load_scene(&repo_root().join("assets/cornell.scene.json")).unwrap();
    scene.resolution = Resolution {
        width: size,
        height: size,
    };
    scene
}

/// A one-bounce bake of `scene` with the stack's linear denoiser off.
pub fn bake(scene: &Scene, spp: u32, light: u32, indirect: u32, seed: u64) -> Arc<TiledStack> {
    let settings = BakeSettings {
        spp,
        light_samples: light,
        indirect_samples: indirect,
        seed,
        ..BakeSettings::default()
    };
    Arc::new(bake_tiled(scene, &settings, &Progress::new()).unwrap().0)
}

/// The bake-time materials of `stack`'s editable regions, with `edits` applied.
pub fn materials(stack: &TiledStack, edits: &[(&str, MaterialSpec)]) -> Vec<MaterialSpec> {
    let mut file = MaterialsFile::default();
    for (name, m) in edits {
        file.regions.insert(name.to_string(), m.clone());
    }
    resolve_materials(&stack.header.regions, &file).unwrap()
}

/// The relit image (RGBA) of `stack` with `materials`.
pub fn relight(stack: &Arc<TiledStack>, materials: &[MaterialSpec]) -> Vec<f32> {
    let coefs = StackBases::from_header(&stack.header)
        .unwrap()
        .coefficients(materials)
        .unwrap();
    CpuRelighter::from_tiled(stack.clone())
        .unwrap()
        .relight(&coefs)
        .unwrap()
        .to_vec()
}
