//! Dense symmetric linear algebra for the two PCA bases (the BRDF lobes of [`crate::brdf::basis`]
//! and the subsurface profiles of [`crate::bssrdf::basis`]): Gram matrices, a pivoted
//! Cholesky factor and a Jacobi eigensolver, on row-major `f64` slices.
//!
//! Written out here rather than taken from a crate because both bases are rebuilt from the
//! stack header on every load and must come out bit for bit as they were baked: the exact
//! order of every floating-point operation is part of the stack's meaning, so it must not
//! change with a dependency's version.
//!
//! - [`gram`]: `Fᵀ diag(w) F`, accumulated one sample at a time.
//! - [`cholesky`]: the pivoted Cholesky factor `G ≈ R Rᵀ` that exposes a Gram matrix's
//!   numerical rank.
//! - [`eigen`]: the cyclic Jacobi eigensolver for small symmetric matrices.
//! - [`pca`]: leading eigenpairs of a large PSD Gram matrix through its low-rank factor.
//! - [`dense_solve`]: an SPD system solved in place by its Cholesky factor (the stack's
//!   lattice fits).

pub mod cholesky;
pub mod dense_solve;
pub mod eigen;
pub mod gram;
pub mod pca;

pub use cholesky::pivoted_cholesky;
pub use dense_solve::{cholesky_in_place, cholesky_solve};
pub use eigen::jacobi_eigen;
pub use gram::{gram_matrix, GramAccumulator};
pub use pca::{top_eigenpairs, LowRankGram};
