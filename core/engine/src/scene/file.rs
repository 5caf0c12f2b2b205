//! The scene file: JSON, versioned, documented in `docs/scene-format.md`.
//!
//! `{"format": "relume-scene", "version": 2, <the fields of [`Scene`]>}` (version 1 files,
//! which have no translucency, still load). The Blender
//! exporter writes it, the `relume` command line reads it. Images given by path (albedo
//! textures, environment maps) are OpenEXR files relative to the scene file; loading makes
//! them inline so that a loaded [`Scene`] is self-contained.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{ImageRef, Scene, World};
use crate::{RelumeError, Result};

/// The `format` value of every scene file.
pub const SCENE_FORMAT: &str = "relume-scene";
/// The scene file version this build writes. Version 2 adds translucency (a region's
/// `subsurface` block, the Principled `subsurface_*` fields); version 1 files load unchanged.
/// Version 3 adds emitters seen by the camera (`visible_camera` on area lights) and
/// emissive surfaces (`"type": "emissive"` lights); versions 1 and 2 load unchanged.
pub const SCENE_VERSION: u32 = 3;
/// The oldest scene file version this build reads.
pub const SCENE_VERSION_MIN: u32 = 1;

/// What [`save_scene`] writes. Reading goes through [`Probe`] and then [`Scene`] itself:
/// serde's `flatten` buffers the whole document as generic values first, which for a
/// scene of millions of triangles held several times the file's size before any memory
/// forecast could run.
#[derive(Serialize)]
struct SceneFile {
    format: String,
    version: u32,
    #[serde(flatten)]
    scene: Scene,
}

#[derive(Deserialize)]
struct Probe {
    format: Option<String>,
    version: Option<u32>,
}

/// Reads, parses and resolves a scene file (not yet validated: see
/// [`super::validate::validate_scene`]).
pub fn load_scene(path: &Path) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| RelumeError::io(path, e))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    parse_scene(&text, path, dir)
}

/// Parses scene JSON; `path` names it in errors, `dir` resolves relative image paths.
pub fn parse_scene(text: &str, path: &Path, dir: &Path) -> Result<Scene> {
    let fail = |message: String| RelumeError::SceneFormat {
        path: path.to_path_buf(),
        message,
    };
    let probe: Probe =
        serde_json::from_str(text).map_err(|e| fail(format!("not valid JSON: {e}")))?;
    match probe.format.as_deref() {
        Some(SCENE_FORMAT) => {}
        Some(other) => {
            return Err(fail(format!(
                "format is \"{other}\", expected \"{SCENE_FORMAT}\""
            )))
        }
        None => {
            return Err(fail(format!(
                "no \"format\": \"{SCENE_FORMAT}\" key: not a Relume scene file"
            )))
        }
    }
    match probe.version {
        Some(v) if (SCENE_VERSION_MIN..=SCENE_VERSION).contains(&v) => {}
        Some(found) => {
            return Err(RelumeError::SceneVersion {
                path: path.to_path_buf(),
                found,
                supported: SCENE_VERSION,
            })
        }
        None => return Err(fail("no \"version\" key".into())),
    }
    // `format` and `version` were read above; `Scene` ignores them.
    let mut scene: Scene = serde_json::from_str(text).map_err(|e| fail(e.to_string()))?;
    for region in &mut scene.regions {
        if let Some(img) = &mut region.albedo_texture {
            resolve_image(img, dir)?;
        }
    }
    if let World::Equirect { image, .. } = &mut scene.world {
        resolve_image(image, dir)?;
    }
    Ok(scene)
}

fn resolve_image(img: &mut ImageRef, dir: &Path) -> Result<()> {
    if let ImageRef::Path { path } = img {
        let full = dir.join(&*path);
        let (width, height, rgb) = crate::image_io::read_rgb_exr(&full)?;
        *img = ImageRef::Inline { width, height, rgb };
    }
    Ok(())
}

/// Writes `scene` as a version-3 scene file, atomically and by the same rules as every
/// other file Relume writes ([`crate::image_io::write_atomic`]: temp file, fsync, rename;
/// an existing output that is not a regular file is refused, never replaced).
pub fn save_scene(path: &Path, scene: &Scene) -> Result<()> {
    let file = SceneFile {
        format: SCENE_FORMAT.into(),
        version: SCENE_VERSION,
        scene: scene.clone(),
    };
    let text = serde_json::to_string(&file).map_err(|e| RelumeError::SceneFormat {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    crate::image_io::write_atomic(path, |w| {
        use std::io::Write as _;
        w.write_all(text.as_bytes())
            .map_err(|e| RelumeError::io(path, e))
    })
    .map(|_| ())
}

#[cfg(test)]
mod tests {
    /// A scene saved over a FIFO is refused and the FIFO stays (the rename would have
    /// replaced it with a regular file).
    #[cfg(unix)]
    #[test]
    fn saving_a_scene_over_a_fifo_is_refused() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("scene.json");
        let made = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(made.success());
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../assets/cornell.scene.json");
        let scene = super::load_scene(&path).unwrap();
        let e = super::save_scene(&fifo, &scene).unwrap_err();
        assert!(e.to_string().contains("FIFO"), "{e}");
        assert!(std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo());
    }
}
