//! BRDFs: the Blinn–Phong model of the paper, its PCA basis, and the one mapping from
//! Blender's Principled BSDF to Blinn–Phong.

pub mod basis;
pub mod blinn_phong;
pub mod principled;

use serde::{Deserialize, Serialize};

pub use basis::{BasisConfig, BasisCount, BrdfBasis};
pub use blinn_phong::BlinnPhong;
pub use principled::{principled_to_blinn_phong, Principled};

/// A material as written in a scene file or a materials file: Blinn–Phong values directly,
/// or Principled BSDF inputs that go through [`principled_to_blinn_phong`].
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum MaterialSpec {
    BlinnPhong(BlinnPhong),
    Principled(Principled),
}

impl MaterialSpec {
    /// The Blinn–Phong parameters this material stands for.
    pub fn to_blinn_phong(&self) -> BlinnPhong {
        match self {
            MaterialSpec::BlinnPhong(b) => *b,
            MaterialSpec::Principled(p) => principled_to_blinn_phong(p),
        }
    }
}
