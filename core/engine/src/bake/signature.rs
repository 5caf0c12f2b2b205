//! The layer key, re-exported where the bake first defined it: it now lives on the ground
//! floor ([`crate::layer_key`]), shared by the bake, the stack and the relight.

pub use crate::layer_key::*;
