//! The light entering a translucent region (`E′` at each of its surface samples, see
//! [`super::subsurface`]), traced with the bake's lights and shadow rays, and the octree
//! over the samples. Apart from the region's data because it traces rays through the bake
//! context, which holds that data.

use rayon::prelude::*;

use crate::bake::prepare::context::BakeContext;
use crate::bake::prepare::subsurface::TranslucentRegion;
use crate::bssrdf::dipole::fresnel_transmittance;
use crate::bssrdf::samples::sample_region;
use crate::bssrdf::tree::ScatterTree;
use crate::geometry::sampling::SampleStream;
use crate::scene::Scene;
use crate::Rgb;

/// Samples region `index`, gathers E′ at every sample and builds the octree; stops early
/// with [`crate::RelumeError::Cancelled`] when `progress` is cancelled.
pub fn prepare_light(
    ctx: &BakeContext,
    scene: &Scene,
    index: usize,
    t: &mut TranslucentRegion,
    progress: &crate::progress::Progress,
) -> crate::Result<()> {
    let settings = &ctx.settings;
    progress.check()?;
    t.points = sample_region(scene, index as u32, t.info.samples as usize, settings.seed);
    progress.check()?;
    let groups = ctx.lights.groups.len();
    let light_samples = settings.light_samples.max(1);
    let eta = t.eta;
    let irradiance: Vec<Vec<Rgb>> = t
        .points
        .positions
        .par_iter()
        .enumerate()
        .map(|(i, &p)| {
            if progress.is_cancelled() {
                // Discarded below: no allocation per remaining sample.
                return Vec::new();
            }
            let mut e = vec![Rgb::ZERO; groups];
            let n = t.points.normals[i];
            let ng = t.points.geometric_normals[i];
            let origin = ctx.geometry.offset(p, ng);
            let mut stream = SampleStream::new(
                settings.seed ^ 0x4952_5241_4449_414e,
                (index as u64) << 32 | i as u64,
                0,
            );
            let inv = 1.0 / light_samples as f32;
            for emitter in 0..ctx.lights.len() {
                let base = stream.branch();
                for j in 0..light_samples {
                    let (u1, u2) = base.child(j, light_samples).next2();
                    let Some(s) = ctx.lights.sample(emitter, p, n, u1, u2) else {
                        continue;
                    };
                    let cos = n.dot(s.wi);
                    if cos <= 0.0 || ng.dot(s.wi) <= 0.0 || s.radiance_over_pdf == Rgb::ZERO {
                        continue;
                    }
                    let tmax = if s.distance.is_finite() {
                        s.distance * (1.0 - 1e-4)
                    } else {
                        f32::INFINITY
                    };
                    if ctx.geometry.occluded(origin, s.wi, tmax) {
                        continue;
                    }
                    let ft = fresnel_transmittance(eta, cos as f64) as f32;
                    e[ctx.lights.group_of(emitter)] += s.radiance_over_pdf * (cos * ft * inv);
                }
            }
            e
        })
        .collect();
    progress.check()?;
    t.irradiance = irradiance.into_iter().flatten().collect();
    let area = t.points.area_each as f32;
    let power: Vec<Rgb> = t.irradiance.iter().map(|e| *e * area).collect();
    t.tree = ScatterTree::build(
        &t.points.positions,
        &power,
        groups,
        settings.subsurface_theta,
    );
    Ok(())
}
