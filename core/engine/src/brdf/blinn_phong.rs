//! Blinn–Phong, eq. (15) of the paper — see the module-level notes of `basis.rs` for the
//! normalisation Relume uses.
//! HELPER A: implement.

use serde::{Deserialize, Serialize};

/// Blinn–Phong parameters: `Kd`, `Ks` RGB albedos, `ns` the exponent.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct BlinnPhong {
    pub kd: [f32; 3],
    pub ks: [f32; 3],
    pub ns: f32,
}
