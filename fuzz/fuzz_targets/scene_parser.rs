//! The scene file parser and validation on arbitrary text: an error or a scene, never a
//! panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(scene) =
        relume_engine::scene::file::parse_scene(text, Path::new("fuzz.scene.json"), Path::new("/nonexistent"))
    {
        let _ = relume_engine::scene::validate::validate_scene(&scene);
    }
});
