//! BRDFs: the Blinn–Phong model of the paper, its PCA basis, the mapping from Blender's
//! Principled BSDF to Blinn–Phong (fitted to Cycles' Principled, evaluated in
//! [`cycles_principled`]; the analytic mapping as fallback), and the material a user edits.

pub mod basis;
pub mod blinn_phong;
pub mod cycles_principled;
pub mod material;
pub mod principled;
pub mod principled_basis;
pub mod principled_fit;
pub mod region_basis;

pub use crate::bssrdf::mapping::Subsurface;
pub use basis::{check_basis_limits, BasisConfig, BasisCount, BrdfBasis};
pub use blinn_phong::BlinnPhong;
pub use material::{MaterialSpec, PrincipledMaterial, ENERGY_SLACK};
pub use principled::Principled;
pub use principled_fit::principled_to_blinn_phong;
pub use region_basis::{RegionBasis, RegionCoefficients};
