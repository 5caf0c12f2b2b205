//! Edit accuracy of the Principled basis with the bake-time slot against basis size: for
//! bases of several slot counts, bake-time materials across roughness and edits away from
//! them, the relative L2 error (green channel, the basis' measure) of the edited lobe
//! rebuilt from the basis alone and from the basis with the bake-time slot.
//!
//! `cargo run --release -p relume-engine --example bake_lobe_sizes`

use relume_engine::brdf::principled_basis::{PrincipledBasis, PrincipledBasisConfig};
use relume_engine::brdf::Principled;

fn m(base: [f32; 3], metallic: f32, roughness: f32) -> Principled {
    Principled {
        base_color: base,
        metallic,
        roughness,
        ior: 1.5,
        specular_ior_level: 0.5,
    }
}

fn main() {
    let bakes = [
        ("metal r0.1", m([0.9, 0.65, 0.35], 1.0, 0.1)),
        ("metal r0.3", m([0.9, 0.65, 0.35], 1.0, 0.3)),
        ("dielectric r0.15", m([0.3, 0.31, 0.34], 0.0, 0.15)),
        ("dielectric r0.5", m([0.6, 0.6, 0.6], 0.0, 0.5)),
    ];
    for bases in [9usize, 10, 13, 17, 21] {
        let config = PrincipledBasisConfig {
            bases,
            ..PrincipledBasisConfig::default()
        };
        let basis = PrincipledBasis::build(&config).expect("basis builds");
        for (name, bake) in &bakes {
            let lobe = basis.bake_lobe(bake);
            let edits = [
                (
                    "colour",
                    Principled {
                        base_color: [0.3, 0.6, 0.2],
                        ..*bake
                    },
                ),
                (
                    "rough ×1.5",
                    Principled {
                        roughness: (bake.roughness * 1.5).min(1.0),
                        ..*bake
                    },
                ),
                (
                    "rough ×3",
                    Principled {
                        roughness: (bake.roughness * 3.0).min(1.0),
                        ..*bake
                    },
                ),
                (
                    "rough 0.1",
                    Principled {
                        roughness: 0.1,
                        ..*bake
                    },
                ),
                (
                    "metallic flip",
                    Principled {
                        metallic: 1.0 - bake.metallic,
                        ..*bake
                    },
                ),
            ];
            for (edit, p) in edits {
                let (plain, with) = basis.rebuild_error_with_bake_lobe(&lobe, &p);
                println!(
                    "{{\"slots\": {bases}, \"bake\": \"{name}\", \"edit\": \"{edit}\", \"projection\": {:.4}, \"with_bake_lobe\": {:.4}}}",
                    plain[1], with[1]
                );
            }
        }
    }
}
