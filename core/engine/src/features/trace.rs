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

/// Samples per pixel side where a pixel is not one surface: 4 × 4 = 16 primary rays, enough
/// that an edge pixel's coverage is within 1/16 of its area (a pixel inside one untextured
/// surface takes 2 × 2, see `TraceContext::pixel`).
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

/// A pixel's samples, summed.
#[derive(Default)]
struct PixelSum {
    normal: Vec3,
    fixed: Rgb,
    shares: Vec<EditableShare>,
}

/// Normals closer than this (cosine) count as one surface for [`TraceContext::pixel`]'s
/// first look.
const SAME_SURFACE_COS: f32 = 0.999;

impl TraceContext<'_> {
    fn row(&self, y: u32) -> Row {
        let w = self.width as usize;
        let mut row = Row {
            normal: vec![0.0; w * 3],
            fixed_albedo: vec![0.0; w * 3],
            shares: Vec::with_capacity(w),
        };
        for x in 0..self.width {
            let (sum, count) = self.pixel(x, y);
            let inv = 1.0 / count as f32;
            let px = x as usize * 3;
            row.normal[px..px + 3].copy_from_slice(&(sum.normal * inv).to_array());
            row.fixed_albedo[px..px + 3].copy_from_slice(&(sum.fixed * inv).to_array());
            let mut shares = sum.shares;
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

    /// The sums of pixel (`x`, `y`) and their sample count. A first look with a 2 × 2 grid;
    /// where its four rays see one untextured surface (the same region, normals within
    /// [`SAME_SURFACE_COS`]) or all miss, the pixel is that surface and they suffice, else
    /// the full `n × n` grid decides (edges, creases, textures). The rule depends on the
    /// scene alone, so the features stay free of noise.
    fn pixel(&self, x: u32, y: u32) -> (PixelSum, u32) {
        if self.n > 2 {
            let mut first = PixelSum::default();
            let mut uniform = true;
            let mut seen: Option<(Option<u32>, Vec3)> = None;
            for j in 0..2 {
                for i in 0..2 {
                    let hit = self.sample(x, y, i, j, 2, &mut first);
                    let key = hit.map(|(r, n, textured)| {
                        uniform &= !textured;
                        (Some(r), n)
                    });
                    let key = key.unwrap_or((None, Vec3::ZERO));
                    match seen {
                        None => seen = Some(key),
                        Some((r, n)) => {
                            uniform &=
                                r == key.0 && (r.is_none() || n.dot(key.1) >= SAME_SURFACE_COS)
                        }
                    }
                }
            }
            if uniform {
                return (first, 4);
            }
        }
        let mut sum = PixelSum::default();
        for j in 0..self.n {
            for i in 0..self.n {
                self.sample(x, y, i, j, self.n, &mut sum);
            }
        }
        (sum, self.n * self.n)
    }

    /// Traces sample (`i`, `j`) of an `n × n` grid in pixel (`x`, `y`) into `sum`; returns
    /// the region hit, its normal and whether it is textured.
    fn sample(
        &self,
        x: u32,
        y: u32,
        i: u32,
        j: u32,
        n: u32,
        sum: &mut PixelSum,
    ) -> Option<(u32, Vec3, bool)> {
        let fx = x as f32 + (i as f32 + 0.5) / n as f32;
        let fy = y as f32 + (j as f32 + 0.5) / n as f32;
        let (origin, dir) = self.camera.ray(fx, fy);
        let hit = self.geometry.intersect(origin, dir, 0.0, self.clip_end)?;
        sum.normal += hit.shading_normal;
        let region = self.regions.get(hit.region as usize)?;
        let tex = region
            .texture
            .as_ref()
            .map_or(Rgb::ONE, |t| t.lookup(hit.uv.x, hit.uv.y));
        match region.editable {
            None => sum.fixed += region.kd * tex + region.ks,
            Some(e) => match sum.shares.iter_mut().find(|s| s.region == e) {
                Some(s) => {
                    s.coverage += 1.0;
                    for (a, t) in s.texture.iter_mut().zip(tex.to_array()) {
                        *a += t;
                    }
                }
                None => sum.shares.push(EditableShare {
                    region: e,
                    coverage: 1.0,
                    texture: tex.to_array(),
                }),
            },
        }
        Some((hit.region, hit.shading_normal, region.texture.is_some()))
    }
}
