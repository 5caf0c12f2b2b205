//! The emitters a light set samples, prepared from the scene's lights: their kinds and
//! shapes ([`Emitter`], [`AreaPlane`], a spot's cone), the emitters the camera sees
//! directly ([`Visible`]) and how square and rectangular lights and an image world are
//! sampled ([`AreaSampling`], [`WorldSampling`]).

use glam::Vec3;
use std::f32::consts::PI;

use super::groups::untinted;
use crate::scene::{AreaShape, Light, Scene};
use crate::Rgb;

#[derive(Clone, Debug)]
pub(super) enum Emitter {
    Point {
        position: Vec3,
        intensity: Rgb,
        radius: f32,
        spot: Option<Spot>,
    },
    Sun {
        to_light: Vec3,
        cos_half: f32,
        radiance_over_pdf: Rgb,
    },
    Area {
        shape: AreaPlane,
        radiance_times_area: Rgb,
        /// Surface area, m² (0 for a degenerate light, which then emits nothing).
        area: f32,
    },
    /// An emissive region's triangles, sampled uniformly by area (two-sided emission).
    Mesh {
        /// The scene region whose triangles these are (what a BSDF ray's hit names).
        region: u32,
        /// Total area, m².
        area: f32,
        /// Per triangle: v0, e1 = v1 − v0, e2 = v2 − v0, unit normal.
        triangles: Vec<[Vec3; 4]>,
        /// Cumulative area fraction per triangle (last = 1).
        cdf: Vec<f32>,
        /// Radiance times the total area (the area pdf is 1/A).
        radiance_times_area: Rgb,
    },
    World,
}

/// Where an area light lies: its centre, unit axes `u`, `v`, the normal it emits along (one
/// side only), half sizes along the axes, and whether it is a disk or an ellipse (else a
/// square or a rectangle). Shared by the light as sampled and the light as seen.
#[derive(Clone, Copy, Debug)]
pub(super) struct AreaPlane {
    pub(super) centre: Vec3,
    pub(super) u: Vec3,
    pub(super) v: Vec3,
    pub(super) normal: Vec3,
    pub(super) half_u: f32,
    pub(super) half_v: f32,
    pub(super) elliptic: bool,
}

/// A square or rectangle whose diagonal is below this fraction of its distance is sampled
/// by area even under [`AreaSampling::SolidAngle`]: its solid angle Ω ≈ A·cos θ/d² falls
/// below 10⁻⁶ sr, where the spherical-rectangle formula (four dihedral angles summing to
/// 2π + Ω, in f64) starts losing Ω's digits to rounding — seen from 1 m, a side of 10⁻⁷ m
/// came out 2 % too bright and one of 10⁻⁸ m (Ω ≈ 10⁻¹⁶, all rounding) black or up to
/// 10²⁹× too bright, depending on where it stood — while
/// the area sample's weight L·A·cos θ_l/d² varies by under 0.1 % across so small a light.
const SMALL_RECT_RATIO: f32 = 1e-3;

impl AreaPlane {
    /// Whether a light sampled under `sampling` is drawn uniformly in solid angle from `p`
    /// (a square or rectangle that is not small as seen from `p`), else uniformly by area.
    /// The light's sample and its pdf for a BSDF-sampled hit both ask this.
    pub(super) fn by_solid_angle(&self, p: Vec3, sampling: AreaSampling) -> bool {
        if self.elliptic || sampling != AreaSampling::SolidAngle {
            return false;
        }
        let diagonal2 = 4.0 * (self.half_u * self.half_u + self.half_v * self.half_v);
        diagonal2 >= SMALL_RECT_RATIO * SMALL_RECT_RATIO * (p - self.centre).length_squared()
    }

    /// Whether a ray from `origin` along unit `dir` meets the light's front face before
    /// distance `t_hit` (the light emits along `normal`, so the ray meets it head-on).
    pub(super) fn front_face_hit(&self, origin: Vec3, dir: Vec3, t_hit: f32) -> bool {
        let denom = dir.dot(self.normal);
        if !(denom < 0.0) {
            return false;
        }
        let t = (self.centre - origin).dot(self.normal) / denom;
        if !(t > 0.0 && t < t_hit) {
            return false;
        }
        let q = origin + dir * t - self.centre;
        let (a, b) = (q.dot(self.u) / self.half_u, q.dot(self.v) / self.half_v);
        if self.elliptic {
            a * a + b * b <= 1.0
        } else {
            a.abs() <= 1.0 && b.abs() <= 1.0
        }
    }
}

/// An emitter the camera sees directly ([`LightSet::seen_directly`]).
#[derive(Clone, Debug)]
pub(super) enum Visible {
    /// A visible area light's front face.
    Area {
        shape: AreaPlane,
        radiance: Rgb,
        group: usize,
    },
    /// Every triangle of a region (the camera ray's own hit tells).
    Region {
        region: u32,
        radiance: Rgb,
        group: usize,
    },
}

/// How square and rectangular area lights are sampled (disks and ellipses always by area).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum AreaSampling {
    /// Uniformly on the light's surface: weight L·A·cos θ_l/d², which varies across a
    /// close or large light.
    Area,
    /// Uniformly in the solid angle the light subtends (the default): weight L·Ω for every
    /// sample. See `cargo test --test engine area_sampling -- --nocapture` for the measured gain.
    #[default]
    SolidAngle,
}

/// How an image world is sampled (a constant world is always sampled by cosine).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WorldSampling {
    /// Cosine-weighted around the normal only (the reference for variance measurements).
    Cosine,
    /// ½ hierarchical warping of the image's luminance + ½ cosine (the default): far lower
    /// variance than cosine alone where a small bright sun sits in a dim sky
    /// (`tests/engine/env_sampling.rs`; the figure is in docs/measurements.md, "Figures that were in
    /// code comments").
    #[default]
    Mixture,
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Spot {
    axis: Vec3,
    cos_half: f32,
    smooth: f32,
}

impl Spot {
    /// Cycles' smoothstep cone for the unit direction `wi` from a shading point towards the
    /// light: 1 inside, 0 outside, the blend between.
    pub(super) fn mask(&self, wi: Vec3) -> f32 {
        let cos = (-wi).dot(self.axis);
        if self.smooth > 0.0 {
            let t = ((cos - self.cos_half) / self.smooth).clamp(0.0, 1.0);
            t * t * (3.0 - 2.0 * t)
        } else if cos > self.cos_half {
            1.0
        } else {
            0.0
        }
    }
}

/// The emitter the camera sees for `light`, when its `visible_camera` is on (group `group`).
pub(super) fn visible_emitter(
    light: &Light,
    tint: Rgb,
    group: usize,
    scene: &Scene,
) -> Option<Visible> {
    match light {
        Light::Area {
            visible_camera: true,
            ..
        } => match prepare(light, tint, scene)? {
            Emitter::Area {
                shape,
                radiance_times_area,
                area,
            } if area > 0.0 => Some(Visible::Area {
                shape,
                radiance: radiance_times_area / area,
                group,
            }),
            _ => None,
        },
        Light::Emissive {
            region,
            strength,
            color,
            visible_camera: true,
        } => Some(Visible::Region {
            region: *region,
            radiance: untinted(Rgb::from(*color), tint) * strength.max(0.0),
            group,
        }),
        _ => None,
    }
}

pub(super) fn prepare(light: &Light, tint: Rgb, scene: &Scene) -> Option<Emitter> {
    let colour = |c: &[f32; 3]| untinted(Rgb::from(*c), tint);
    match light {
        Light::Emissive {
            region,
            strength,
            color,
            ..
        } => {
            let mut triangles = Vec::new();
            let mut cdf = Vec::new();
            let mut total = 0.0f64;
            for mesh in &scene.meshes {
                for (t, idx) in mesh.indices.iter().enumerate() {
                    if mesh.region_of(t) != *region {
                        continue;
                    }
                    let get = |k: u32| mesh.positions.get(k as usize).map(|p| Vec3::from(*p));
                    let (Some(v0), Some(v1), Some(v2)) = (get(idx[0]), get(idx[1]), get(idx[2]))
                    else {
                        continue;
                    };
                    let (e1, e2) = (v1 - v0, v2 - v0);
                    let c = e1.cross(e2);
                    let a = 0.5 * c.length();
                    if !(a > 0.0) || !a.is_finite() {
                        continue;
                    }
                    total += a as f64;
                    triangles.push([v0, e1, e2, c.normalize()]);
                    cdf.push(total);
                }
            }
            if triangles.is_empty() || !(*strength > 0.0) {
                // Keep the emitter count equal to the light count (groups index by light).
                return Some(Emitter::Mesh {
                    region: *region,
                    area: 1.0,
                    triangles: vec![[Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]],
                    cdf: vec![1.0],
                    radiance_times_area: Rgb::ZERO,
                });
            }
            Some(Emitter::Mesh {
                region: *region,
                area: total as f32,
                triangles,
                cdf: cdf.iter().map(|c| (c / total) as f32).collect(),
                radiance_times_area: colour(color) * (*strength * total as f32),
            })
        }
        Light::Point {
            position,
            power,
            color,
            radius,
        } => Some(Emitter::Point {
            position: Vec3::from(*position),
            intensity: colour(color) * (*power / (4.0 * PI)),
            radius: *radius,
            spot: None,
        }),
        Light::Spot {
            position,
            direction,
            power,
            color,
            radius,
            spot_size,
            spot_blend,
        } => {
            let cos_half = (0.5 * spot_size).cos();
            Some(Emitter::Point {
                position: Vec3::from(*position),
                intensity: colour(color) * (*power / (4.0 * PI)),
                radius: *radius,
                spot: Some(Spot {
                    axis: Vec3::from(*direction).normalize(),
                    cos_half,
                    smooth: (1.0 - cos_half) * spot_blend,
                }),
            })
        }
        Light::Sun {
            direction,
            strength,
            color,
            angle,
        } => {
            let half = 0.5 * angle;
            let cos_half = half.cos();
            // Irradiance S from a uniform disk of half-angle h: L = S/(π sin²h); ∫ L dω over the
            // cone = L·2π(1 − cos h) = S·2/(1 + cos h) → S as h → 0.
            let factor = if half > 1e-6 {
                2.0 / (1.0 + cos_half)
            } else {
                1.0
            };
            Some(Emitter::Sun {
                to_light: -Vec3::from(*direction).normalize(),
                cos_half: if half > 1e-6 { cos_half } else { 1.0 },
                radiance_over_pdf: colour(color) * (*strength * factor),
            })
        }
        Light::Area {
            position,
            axis_u,
            axis_v,
            shape,
            size_x,
            size_y,
            power,
            color,
            ..
        } => {
            let u = Vec3::from(*axis_u).normalize();
            let v = Vec3::from(*axis_v).normalize();
            let (sx, sy) = match shape {
                AreaShape::Square | AreaShape::Disk => (*size_x, *size_x),
                AreaShape::Rectangle | AreaShape::Ellipse => (*size_x, size_y.unwrap_or(*size_x)),
            };
            let elliptic = matches!(shape, AreaShape::Disk | AreaShape::Ellipse);
            let area = if elliptic {
                PI * sx * sy / 4.0
            } else {
                sx * sy
            };
            // L = P/(π A); the area pdf is 1/A, so radiance/pdf (before cos/d²) is L·A = P/π.
            Some(Emitter::Area {
                shape: AreaPlane {
                    centre: Vec3::from(*position),
                    u,
                    v,
                    normal: -u.cross(v).normalize(),
                    half_u: 0.5 * sx,
                    half_v: 0.5 * sy,
                    elliptic,
                },
                radiance_times_area: colour(color)
                    * (*power / PI)
                    * if area > 0.0 { 1.0 } else { 0.0 },
                area,
            })
        }
    }
}
