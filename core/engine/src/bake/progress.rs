//! Progress and cancellation, re-exported where the bake first defined them: they now live
//! on the ground floor ([`crate::progress`]), so the stack file's writer can be cancelled
//! without importing the bake.

pub use crate::progress::*;
