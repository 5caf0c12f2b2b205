//! The materials file parser and the material rules on arbitrary text: an error or
//! materials that pass [`MaterialSpec::validate`] or fail it with an error, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(file) = relume_engine::materials::parse_materials(text) {
        for (name, spec) in &file.regions {
            if spec.validate(name).is_ok() {
                // Valid materials map to finite Blinn–Phong values.
                let m = spec.to_blinn_phong();
                assert!(m.ns.is_finite() && m.kd.iter().chain(&m.ks).all(|v| v.is_finite()));
            }
        }
    }
});
