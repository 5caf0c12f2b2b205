//! OpenImageDenoise 2, opened at run time: finding and opening the library ([`library`]),
//! and one device with its filter ([`device`]). The only `unsafe` code of Relume's
//! denoising lives here.

pub mod device;
pub mod library;

pub use device::{DeviceChoice, OidnDenoiser, Quality};
pub use library::{LibrarySearch, OidnApi, ENV_VAR, LIBRARY_NAMES};
