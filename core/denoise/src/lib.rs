//! The image Relume shows: the relit image passed through OpenImageDenoise (OIDN) with
//! albedo and normal features, or left as the linear image.
//!
//! Why a crate of its own: OIDN is a C library opened at run time ([`oidn`], through
//! `libloading`), which means `unsafe` foreign calls that the pure engine should not hold;
//! the engine keeps what is plain Rust (the pixel features, `relume_engine::features`), and
//! this crate the loading, the calls and the policy ([`ShownImage`]: which denoiser ran,
//! the fallback and its message) that the command line, the Python bindings and hence the
//! add-on share.

pub mod oidn;

mod mode;
mod report;
mod shown;

pub use mode::DenoiseMode;
pub use report::DenoiseReport;
pub use shown::{FeatureImages, ShownImage};
