//! The albedo image for the current materials: what OpenImageDenoise takes as the colour of
//! the surfaces "independent of illumination and viewing angle", recomputed at every edit.
//!
//! A Blinn–Phong surface reflects at most `Kd + Ks` of the light per channel (the rules keep
//! that ≤ 1), with the diffuse part scaled by its albedo texture: that sum is the albedo used
//! here, for editable regions from their current material and for fixed ones from their
//! bake-time one. OIDN asks for values in [0, 1]; a texture brighter than 1 is the one
//! thing that can exceed it, and the feature (never the image) is limited to 1 there.

use rayon::prelude::*;

use super::pixel_features::PixelFeatures;
use crate::brdf::MaterialSpec;
use crate::{RelumeError, Result, Rgb};

/// The albedo image (RGB per pixel, row-major) of `features` with `materials`, the current
/// material of every editable region in the stack's order. Errors: a material count other
/// than the features' editable regions.
pub fn albedo_of(features: &PixelFeatures, materials: &[MaterialSpec]) -> Result<Vec<f32>> {
    if materials.len() != features.editable_regions {
        return Err(RelumeError::invalid(
            "pixel features",
            format!(
                "{} editable materials for features traced with {} editable regions (the scene is not the stack's)",
                materials.len(),
                features.editable_regions
            ),
        ));
    }
    let parts: Vec<(Rgb, Rgb)> = materials
        .iter()
        .map(|m| {
            let b = m.to_blinn_phong();
            (Rgb::from(b.kd), Rgb::from(b.ks))
        })
        .collect();
    let pixels = features.width as usize * features.height as usize;
    let mut out = crate::memory::try_zeroed::<f32>(pixels * 3, "the albedo image")?;
    out.par_chunks_mut(3)
        .zip(features.fixed_albedo.par_chunks(3))
        .enumerate()
        .for_each(|(i, (px, fixed))| {
            let mut a = Rgb::new(fixed[0], fixed[1], fixed[2]);
            for s in features.shares(i) {
                let (kd, ks) = parts[s.region as usize];
                a += kd * Rgb::from(s.texture) + ks * s.coverage;
            }
            let a = a.clamp(Rgb::ZERO, Rgb::ONE);
            px.copy_from_slice(&a.to_array());
        });
    Ok(out)
}
