//! [`PixelFeatures::trace`]: the features of every pixel from primary rays through the scene.
//!
//! Samples sit on a regular `n × n` grid inside each pixel (a box pixel filter, as the
//! bake's eye samples are uniform in the pixel): OpenImageDenoise asks that the features be
//! anti-aliased like the colour and free of noise, and a fixed grid is both (what it leaves
//! is the grid's aliasing along edges, the same for every edit).

use glam::Vec3;
use rayon::prelude::*;

use super::pixel_features::{EditableShare, PixelFeatures};
use crate::geometry::{bvh::SceneGeometry, camera::CameraRays, texture::Texture};
use crate::memory::try_with_capacity;
use crate::scene::{Resolution, Scene};
use crate::{RelumeError, Result, Rgb};

/// Samples per pixel side: 4 × 4 = 16 primary rays a pixel, enough that an edge pixel's
/// coverage is within 1/16 of its area.
pub const FEATURE_SAMPLES_PER_AXIS: u32 = 4;

/// What one scene region contributes at a hit.
struct RegionAlbedo {
    /// Position among the editable regions; `None` for a fixed region.
    editable: Option<u16>,
    texture: Option<Texture>,
    /// A fixed region's bake-time Blinn–Phong (the diffuse part is scaled by the texture).
    kd: Rgb,
    ks: Rgb,
}

/// One row's features, merged into the image afterwards.
struct Row {
    normal: Vec<f32>,
    fixed_albedo: Vec<f32>,
    /// Per pixel, its shares.
    shares: Vec<Vec<EditableShare>>,
}

impl PixelFeatures {
    /// Traces the features of `scene` at `width × height` (the stack's size; the scene's
    /// camera) with `samples_per_axis²` rays a pixel. Errors: a size or sample count of 0,
    /// or memory the allocator refuses.
    pub fn trace(scene: &Scene, width: u32, height: u32, samples_per_axis: u32) -> Result<Self> {
        if width == 0 || height == 0 || samples_per_axis == 0 || samples_per_axis > 64 {
            return Err(RelumeError::invalid(
                "pixel features",
                format!(
                    "{width}×{height} pixels at {samples_per_axis}² samples; each must be at least 1 (samples at most 64²)"
                ),
            ));
        }
        let regions = region_albedos(scene);
        let editable_regions = regions.iter().filter(|r| r.editable.is_some()).count();
        let geometry = SceneGeometry::build(scene);
        let camera = CameraRays::new(&scene.camera, Resolution { width, height });
        let clip_end = if scene.camera.clip_end > 0.0 {
            scene.camera.clip_end
        } else {
            f32::INFINITY
        };
        let pixels = width as usize * height as usize;
        let ctx = TraceContext {
            geometry: &geometry,
            camera: &camera,
            clip_end,
            regions: &regions,
            width,
            n: samples_per_axis,
        };
        let rows: Vec<Row> = (0..height).into_par_iter().map(|y| ctx.row(y)).collect();

        let mut normal = try_with_capacity(pixels * 3, "the pixel features' normals")?;
        let mut fixed_albedo = try_with_capacity(pixels * 3, "the pixel features' albedo")?;
        let mut starts = try_with_capacity(pixels + 1, "the pixel features' index")?;
        let share_count: usize = rows
            .iter()
            .map(|r| r.shares.iter().map(Vec::len).sum::<usize>())
            .sum();
        let mut shares = try_with_capacity(share_count, "the pixel features' region shares")?;
        starts.push(0u32);
        for row in rows {
            normal.extend_from_slice(&row.normal);
            fixed_albedo.extend_from_slice(&row.fixed_albedo);
            for s in row.shares {
                shares.extend_from_slice(&s);
                starts.push(u32::try_from(shares.len()).map_err(|_| {
                    RelumeError::invalid("pixel features", "more than 2³² region shares")
                })?);
            }
        }
        Ok(PixelFeatures {
            width,
            height,
            normal,
            fixed_albedo,
            starts,
            shares,
            editable_regions,
        })
    }
}

fn region_albedos(scene: &Scene) -> Vec<RegionAlbedo> {
    let mut next_editable = 0u16;
    scene
        .regions
        .iter()
        .map(|r| {
            let m = r.material.to_blinn_phong();
            let editable = r.editable.then(|| {
                next_editable += 1;
                next_editable - 1
            });
            RegionAlbedo {
                editable,
                texture: r.albedo_texture.as_ref().and_then(Texture::from_ref),
                kd: Rgb::from(m.kd),
                ks: Rgb::from(m.ks),
            }
        })
        .collect()
}

struct TraceContext<'a> {
    geometry: &'a SceneGeometry,
    camera: &'a CameraRays,
    clip_end: f32,
    regions: &'a [RegionAlbedo],
    width: u32,
    n: u32,
}

impl TraceContext<'_> {
    fn row(&self, y: u32) -> Row {
        let w = self.width as usize;
        let mut row = Row {
            normal: vec![0.0; w * 3],
            fixed_albedo: vec![0.0; w * 3],
            shares: Vec::with_capacity(w),
        };
        let inv = 1.0 / (self.n * self.n) as f32;
        for x in 0..self.width {
            let mut normal = Vec3::ZERO;
            let mut fixed = Rgb::ZERO;
            let mut shares: Vec<EditableShare> = Vec::new();
            for j in 0..self.n {
                for i in 0..self.n {
                    let fx = x as f32 + (i as f32 + 0.5) / self.n as f32;
                    let fy = y as f32 + (j as f32 + 0.5) / self.n as f32;
                    let (origin, dir) = self.camera.ray(fx, fy);
                    let Some(hit) = self.geometry.intersect(origin, dir, 0.0, self.clip_end) else {
                        continue;
                    };
                    normal += hit.shading_normal;
                    let Some(region) = self.regions.get(hit.region as usize) else {
                        continue;
                    };
                    let tex = region
                        .texture
                        .as_ref()
                        .map_or(Rgb::ONE, |t| t.lookup(hit.uv.x, hit.uv.y));
                    match region.editable {
                        None => fixed += region.kd * tex + region.ks,
                        Some(e) => match shares.iter_mut().find(|s| s.region == e) {
                            Some(s) => {
                                s.coverage += 1.0;
                                for (a, t) in s.texture.iter_mut().zip(tex.to_array()) {
                                    *a += t;
                                }
                            }
                            None => shares.push(EditableShare {
                                region: e,
                                coverage: 1.0,
                                texture: tex.to_array(),
                            }),
                        },
                    }
                }
            }
            let px = x as usize * 3;
            row.normal[px..px + 3].copy_from_slice(&(normal * inv).to_array());
            row.fixed_albedo[px..px + 3].copy_from_slice(&(fixed * inv).to_array());
            for s in &mut shares {
                s.coverage *= inv;
                for t in &mut s.texture {
                    *t *= inv;
                }
            }
            shares.sort_by_key(|s| s.region);
            row.shares.push(shares);
        }
        row
    }
}
