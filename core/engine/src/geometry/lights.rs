//! Light sampling in Cycles' units.
//!
//! - Point: radiant intensity I = P/(4π) W/sr (× colour); a radius r > 0 samples a disk of
//!   radius r facing the shading point (a sphere light seen from outside, approximately).
//! - Spot: the point light of the same power, masked by Cycles' smoothstep cone
//!   (t = (cos θ − cos ½size)/((1 − cos ½size)·blend)).
//! - Sun: irradiance S W/m² on a surface facing it; an angular diameter α spreads it
//!   uniformly over a cone of half-angle α/2 (radiance S/(π sin²(α/2))).
//! - Area: one-sided Lambertian, radiance L = P/(π·A) along −(u × v). Squares and rectangles
//!   are sampled uniformly in the solid angle they subtend ([`SphericalRect`]: every sample
//!   weighs L·Ω); disks and ellipses uniformly on their surface (weight L·A·cos θ_l/d²) —
//!   their solid angle has no closed-form uniform parametrization, and a disk is ≈ 0.79 of
//!   its bounding square, so sampling the square and rejecting would lose a fifth of the
//!   samples and add the rejection's variance; [`AreaSampling::Area`] forces surface sampling
//!   for every shape (the reference the solid-angle sampling is measured against).
//! - World: radiance from every direction. A constant world is sampled cosine-weighted
//!   around the normal (zero variance on a diffuse surface). An image world is sampled from
//!   a defensive one-sample mixture, ½ luminance-warped ([`EnvSampler`]) + ½ cosine, with
//!   pdf ½·p_env + ½·p_cos; the cosine half bounds the weight at 2π/cos θ·L where the image
//!   pdf is small.
//!
//! Every sample returns incident radiance divided by the solid-angle pdf, so an estimator
//! is f·cos θ·`radiance_over_pdf` whatever the light, and the pdf itself, so that the bake
//! can weigh it against BSDF-sampled rays that meet the same light (multiple importance
//! sampling; [`LightSet::emitted_along`] gives what such a ray receives).
//!
//! - `set`: [`LightSet`], the scene's emitters and light groups ready for sampling.
//! - `emitters`: the emitters prepared from the scene's lights, and those the camera sees.
//! - `groups`: light groups and the colour each group's emitters share.
//! - `sample`: the light sampler (next-event estimation).
//! - [`bsdf_hits`]: the lights a BSDF-sampled ray meets (the other side of multiple
//!   importance sampling).
//!
//! [`SphericalRect`]: super::spherical_rect::SphericalRect
//! [`EnvSampler`]: super::env_sampling::EnvSampler

pub mod bsdf_hits;
mod emitters;
mod groups;
mod sample;
mod set;

pub use emitters::{AreaSampling, WorldSampling};
pub use groups::{common_tint, LightGroup, DEFAULT_LIGHT_GROUP};
pub use sample::LightSample;
pub use set::LightSet;
