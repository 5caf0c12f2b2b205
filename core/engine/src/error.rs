//! One error type for the whole core. Every variant names what was wrong and where, so the
//! command line and the Blender add-on can show it as is.

use std::path::PathBuf;

/// Everything that can go wrong in the core, each with a specific message.
#[derive(Debug, thiserror::Error)]
pub enum RelumeError {
    #[error("I/O error on {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("scene file {path}: {message}")]
    SceneFormat { path: PathBuf, message: String },
    #[error("scene file {path} has format version {found}; this build reads version {supported}")]
    SceneVersion {
        path: PathBuf,
        found: u32,
        supported: u32,
    },
    #[error("non-finite value (NaN or Inf) in {what}")]
    NonFinite { what: String },
    #[error("{what}: index {index} is out of range (there are {len})")]
    IndexOutOfRange {
        what: String,
        index: u64,
        len: usize,
    },
    #[error("the scene is empty: {0}")]
    EmptyScene(String),
    #[error("invalid {what}: {message}")]
    InvalidValue { what: String, message: String },
    #[error("stack file {path}: {message}")]
    StackFormat { path: PathBuf, message: String },
    #[error("stack file {path} is truncated or damaged: {message}")]
    StackTruncated { path: PathBuf, message: String },
    #[error(
        "stack file {path} has stack format version {found}; this build reads version {supported}"
    )]
    StackVersion {
        path: PathBuf,
        found: u32,
        supported: u32,
    },
    #[error("{path} is not a Relume transfer stack: {message}")]
    StackForeign { path: PathBuf, message: String },
    #[error("the stack was baked from another scene (stack hash {stack_hash}, scene hash {scene_hash}): rebake it")]
    StackStale {
        stack_hash: String,
        scene_hash: String,
    },
    #[error("the bake was cancelled")]
    Cancelled,
    #[error("materials: {0}")]
    Materials(String),
    #[error("BRDF basis: {0}")]
    Basis(String),
    #[error("image {path}: {message}")]
    Image { path: PathBuf, message: String },
    /// A large allocation that would not fit: refused before it is tried (an estimate over
    /// the budget) or after the allocator said no — never an abort.
    #[error("not enough memory for {what}: it needs {} but {} {}", crate::byte_size::human_bytes(*needed), crate::byte_size::human_bytes(*available), if *budget { "is the memory budget (see --memory-budget-mb, BakeSettings.memory_budget_mb or the add-on's Memory Budget)" } else { "could be allocated" })]
    OutOfMemory {
        what: String,
        needed: u64,
        available: u64,
        /// True when `available` is the configured budget rather than what the allocator gave.
        budget: bool,
    },
    /// A command whose output path is one of its inputs: refused before anything is read.
    #[error("the output {output} is also an input of this command ({role}): writing it would destroy the input; choose another output path")]
    OutputIsInput { output: PathBuf, role: String },
    /// Two outputs of one command that are one file: the second write would replace the first.
    #[error("the output {output} ({role}) is also {other_role}: the second write would replace the first; choose two different output paths")]
    OutputsCollide {
        output: PathBuf,
        role: String,
        other_role: String,
    },
    /// An existing output that is not a regular file: refused, never replaced or written
    /// through.
    #[error("the output {output} is {kind}, not a regular file: refused (Relume writes a new file and renames it over the output, which would replace it; it does not write through); choose a file path")]
    OutputNotAFile { output: PathBuf, kind: String },
}

/// Result with [`RelumeError`].
pub type Result<T, E = RelumeError> = std::result::Result<T, E>;

impl RelumeError {
    /// Wraps an `std::io::Error` with the path it concerned.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        RelumeError::Io {
            path: path.into(),
            source,
        }
    }
    /// This error with `path` as the stack file it concerns where it names none (a stack
    /// checked in memory before it is written, as a bake does).
    pub fn for_stack_file(self, path: &std::path::Path) -> Self {
        match self {
            RelumeError::StackFormat { path: p, message } if p.as_os_str().is_empty() => {
                RelumeError::StackFormat {
                    path: path.to_path_buf(),
                    message,
                }
            }
            other => other,
        }
    }
    /// Shorthand for [`RelumeError::InvalidValue`].
    pub fn invalid(what: impl Into<String>, message: impl Into<String>) -> Self {
        RelumeError::InvalidValue {
            what: what.into(),
            message: message.into(),
        }
    }
}
