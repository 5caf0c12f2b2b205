//! The PCA basis of Blinn–Phong lobes. HELPER A: implement.
use serde::{Deserialize, Serialize};
/// Placeholder until helper A lands.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct BasisConfig;
/// Placeholder.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub enum BasisCount { Fixed(u32) }
/// Placeholder.
pub struct BrdfBasis;
