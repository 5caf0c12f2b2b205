//! The bake: one path-tracing pass that fills every layer of the transfer stack.

pub mod signature;
