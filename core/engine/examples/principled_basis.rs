//! Builds the Principled basis (`relume_engine::brdf::principled_basis`) and prints its
//! figures as JSON: build time, the training lobes' errors, the tables' error, and the
//! relative L2 error of lobes rebuilt from their coefficients with the exact bases and with
//! the tables, for metals and dielectrics across roughness (between the training nodes).
//!
//! `cargo run --release -p relume-engine --example principled_basis [-- --small]`

use relume_engine::brdf::principled_basis::{
    Family, PrincipledBasis, PrincipledBasisConfig, QuadratureSize, TableSize,
};

fn main() {
    let small = std::env::args().any(|a| a == "--small");
    let config = if small {
        PrincipledBasisConfig {
            roughness_nodes: 24,
            quadrature: QuadratureSize {
                theta_h: 64,
                theta_d: 20,
                phi_d: 24,
            },
            table: TableSize {
                theta_h: 65,
                s: 33,
                eta: 33,
            },
            ..PrincipledBasisConfig::default()
        }
    } else {
        PrincipledBasisConfig::default()
    };
    let basis = match PrincipledBasis::build(&config) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("principled_basis: {e}");
            std::process::exit(1);
        }
    };
    let mut lobes = vec![];
    for family in [
        Family::Metal { f0: 1.0 },
        Family::Metal { f0: 0.5 },
        Family::Metal { f0: 0.1 },
        Family::Dielectric { ior: 1.5 },
        Family::Dielectric { ior: 1.4 },
    ] {
        for roughness in [0.1, 0.15, 0.25, 0.4, 0.6, 0.8, 1.0] {
            let lobe = PrincipledBasis::lobe(family, roughness);

            let errors = basis.rebuild_errors(&lobe);
            lobes.push(serde_json::json!({
                "family": format!("{family:?}"),
                "roughness": roughness,
                "projection_rel_l2": errors.projection,
                "with_tables_rel_l2": errors.with_tables,
                "tables_alone_rel_l2": errors.tables_alone,
            }));
        }
    }
    let out = serde_json::json!({
        "config": basis.config(),
        "report": basis.report(),
        "lobes": lobes,
    });
    println!("{}", serde_json::to_string_pretty(&out).expect("JSON"));
}
