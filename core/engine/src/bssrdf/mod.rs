//! Translucency: the dipole diffuse BSSRDF, factored by PCA so its material can be edited
//! after the bake (Wang Rui et al. 2008, "the translucency paper"; docs/design.md §2).
//!
//! Jensen's BSSRDF for multiple scattering is `S_d = (1/π)·F_t(η, ω_i)·Rd(|x_i − x_o|, σ)·F_t(η, ω_o)`,
//! so the radiance leaving x_o is
//! `L(x_o, ω_o) = (1/π)·F_t(η, ω_o) · ∫_A E′(x_i)·Rd(|x_i − x_o|, σ) dA(x_i)` with
//! `E′(x_i) = ∫ F_t(η, ω_i) L_i cos θ_i dω_i`. Writing `Rd ≈ Σ_k s_k(σ)·b_k(r)` turns the
//! integral into `Σ_k s_k(σ)·B_k(x_o)` with `B_k(x_o) = ∫ E′(x_i) b_k(|x_i − x_o|) dA`: the
//! bake stores B_k per pixel, an edit of σ only recomputes the K numbers s_k.
//!
//! - [`dipole`]: Rd(r, σ), its closed-form disc integral, the area-averaged kernel, Fresnel.
//! - [`mapping`]: Blender's Subsurface Weight / Radius / Scale / IOR / Base Color → σ.
//! - [`basis`]: the PCA basis b_k(r), the projection s_k(σ), the error table.
//! - `blur`: the sample-scale blur of the profile the basis factors.
//! - [`coefficients`]: a translucent region's slot layout and relight weights.
//! - [`samples`]: surface samples of a translucent region and their irradiance.
//! - [`tree`]: the hierarchical (octree) evaluation of B_k at a pixel (Jensen & Buhler 2002).

pub mod basis;
mod blur;
pub mod coefficients;
pub mod dipole;
pub mod mapping;
pub mod samples;
pub mod tree;

pub use basis::{SssBasis, SssBasisConfig, SssErrorRow, MAX_SSS_BASES};
pub use coefficients::{region_slot_coefficients, SubsurfaceInfo};
pub use dipole::DipoleParams;
