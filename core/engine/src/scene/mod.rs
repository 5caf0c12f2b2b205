//! The scene model: what a bake needs and nothing more.
//!
//! Coordinates and units follow Blender: world space, Z up, metres (any scale works),
//! light power in W, sun strength in W/m², colours scene-linear Rec.709. The same structs
//! are the scene file ([`file`]): what the add-on exports is what the core bakes.

pub mod file;
pub mod hash;
pub mod validate;

use serde::{Deserialize, Serialize};

use crate::brdf::MaterialSpec;

/// A whole scene: geometry, regions (one per material), lights, world, camera, resolution.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Scene {
    pub meshes: Vec<Mesh>,
    pub regions: Vec<Region>,
    #[serde(default)]
    pub lights: Vec<Light>,
    #[serde(default)]
    pub world: World,
    pub camera: Camera,
    pub resolution: Resolution,
    /// Named groups of lights (Blender's light groups), for bakes whose lights stay live.
    #[serde(default)]
    pub light_groups: Vec<LightGroupSpec>,
}

/// A named group of lights: indices into `Scene::lights`, and whether the world is in it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LightGroupSpec {
    pub name: String,
    #[serde(default)]
    pub lights: Vec<u32>,
    #[serde(default)]
    pub world: bool,
}

/// Output image size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Resolution {
    pub width: u32,
    pub height: u32,
}

impl Resolution {
    /// Largest side a scene or a bake may have (OpenEXR and the camera handle more; the
    /// bound keeps sizes, and what a hostile file can claim, in a range that is checked).
    pub const MAX_SIDE: u32 = 65536;
    /// Largest factor a resolution scale may have.
    pub const MAX_SCALE: f64 = 16.0;

    /// Errors (naming `what`) unless each side is 1…[`Self::MAX_SIDE`].
    pub fn validate(&self, what: &str) -> crate::Result<()> {
        let ok = |v: u32| (1..=Self::MAX_SIDE).contains(&v);
        if ok(self.width) && ok(self.height) {
            Ok(())
        } else {
            Err(crate::RelumeError::invalid(
                what,
                format!(
                    "{}×{} (each side must be 1…{})",
                    self.width,
                    self.height,
                    Self::MAX_SIDE
                ),
            ))
        }
    }

    /// Each side multiplied by `scale` and rounded (at least 1). Errors: a scale that is not
    /// finite or not in (0, [`Self::MAX_SCALE`]], or a result outside [`Self::validate`].
    pub fn scaled(self, scale: f64) -> crate::Result<Resolution> {
        if !(scale.is_finite() && scale > 0.0 && scale <= Self::MAX_SCALE) {
            return Err(crate::RelumeError::invalid(
                "resolution scale",
                format!("{scale} (must be in (0, {}])", Self::MAX_SCALE),
            ));
        }
        let side = |v: u32| (v as f64 * scale).round().clamp(1.0, u32::MAX as f64) as u32;
        let r = Resolution {
            width: side(self.width),
            height: side(self.height),
        };
        r.validate("scaled resolution")?;
        Ok(r)
    }
}

/// A triangle mesh in world space.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Mesh {
    #[serde(default)]
    pub name: String,
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex shading normals; the geometric normal is used where absent.
    #[serde(default)]
    pub normals: Option<Vec<[f32; 3]>>,
    /// Per-vertex texture coordinates (Blender's active UV map).
    #[serde(default)]
    pub uvs: Option<Vec<[f32; 2]>>,
    pub indices: Vec<[u32; 3]>,
    /// Region of every triangle, unless `triangle_regions` is given.
    #[serde(default)]
    pub region: u32,
    /// Region per triangle (one per material slot in Blender), overriding `region`.
    #[serde(default)]
    pub triangle_regions: Option<Vec<u32>>,
}

impl Mesh {
    /// The region of triangle `t`.
    pub fn region_of(&self, t: usize) -> u32 {
        match &self.triangle_regions {
            Some(r) => r[t],
            None => self.region,
        }
    }
}

/// One material of the scene. Editable regions keep their BRDF free (relit live); all
/// fixed regions together form the fixed region R̂ whose BRDF is baked in.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Region {
    pub name: String,
    #[serde(default)]
    pub editable: bool,
    /// The material at bake time: it is the BRDF of a fixed region, and the default
    /// material of an editable one.
    pub material: MaterialSpec,
    /// Optional RGB albedo texture multiplying the diffuse part only.
    #[serde(default)]
    pub albedo_texture: Option<ImageRef>,
    /// Range of the Blinn–Phong exponent the region's basis must cover (editable regions);
    /// the bake's default range when absent. A narrower range needs fewer bases.
    #[serde(default)]
    pub ns_range: Option<[f32; 2]>,
    /// Subsurface scattering settings of a translucent region (scene format 2). An editable
    /// region is translucent when this is present or when its material's Subsurface Weight is
    /// above 0; it then keeps subsurface layers so its Subsurface Weight, Radius, Scale, IOR
    /// and Base Color stay editable. Not written when absent (older files and hashes unchanged).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subsurface: Option<SubsurfaceSettings>,
}

impl Region {
    /// Whether the bake keeps subsurface layers for this region: editable, and either a
    /// `subsurface` block or a material with Subsurface Weight > 0.
    pub fn is_translucent(&self) -> bool {
        self.editable
            && (self.subsurface.is_some()
                || matches!(&self.material, MaterialSpec::Principled(p) if p.subsurface.weight > 0.0))
    }
}

/// How a translucent region's subsurface layers are baked; every field optional.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct SubsurfaceSettings {
    /// Surface samples spread uniformly by area (the bake's `subsurface_samples` when absent,
    /// 65 536 by default). More samples resolve shorter mean free paths (ρ = √(A/(πN))).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<u32>,
    /// Range of the mean free path (radius × scale, scene units) the subsurface basis covers;
    /// edits outside it are clamped. Default: the bake-time material's channels, ×½ to ×2,
    /// widened to at least the sample radius ρ and at most the region's diameter.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mfp_range: Option<[f32; 2]>,
    /// Range of the IOR the basis covers (default [1, 2]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ior_range: Option<[f32; 2]>,
    /// Fixed number of subsurface bases (1–24), instead of the tolerance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bases: Option<u32>,
    /// Worst relative L2 error of the profile the basis count is chosen for (default 10⁻⁴).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f32>,
}

/// A float RGB image, inline or as a path to an OpenEXR file (relative to the scene file).
/// After [`file::load_scene`] every image is inline.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ImageRef {
    Inline {
        width: u32,
        height: u32,
        /// Row-major, top row first, RGB triples, scene-linear.
        rgb: Vec<f32>,
    },
    Path {
        path: String,
    },
}

/// The shape of an area light, as in Blender.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AreaShape {
    Square,
    Rectangle,
    Disk,
    Ellipse,
}

/// A light, in Cycles' units.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Light {
    /// Emits `power` W uniformly in all directions (intensity power/4π W/sr), from a sphere
    /// of `radius` m (0: a true point).
    Point {
        position: [f32; 3],
        power: f32,
        #[serde(default = "white")]
        color: [f32; 3],
        #[serde(default)]
        radius: f32,
    },
    /// A point light masked to a cone around `direction` (Blender's local −Z): `spot_size` is
    /// the full cone angle in radians, `spot_blend` ∈ [0, 1] the smooth fraction. Intensity
    /// inside the cone equals that of a point light of the same power, as in Cycles.
    Spot {
        position: [f32; 3],
        direction: [f32; 3],
        power: f32,
        #[serde(default = "white")]
        color: [f32; 3],
        #[serde(default)]
        radius: f32,
        spot_size: f32,
        #[serde(default)]
        spot_blend: f32,
    },
    /// A distant light: `direction` is the direction the light travels (Blender's local −Z),
    /// `strength` the irradiance in W/m² on a surface facing it, `angle` the angular diameter
    /// in radians.
    Sun {
        direction: [f32; 3],
        strength: f32,
        #[serde(default = "white")]
        color: [f32; 3],
        #[serde(default)]
        angle: f32,
    },
    /// A one-sided Lambertian emitter of total power `power` W, centred at `position`, spanned
    /// by the unit axes `axis_u` (size_x) and `axis_v` (size_y), emitting along
    /// −(axis_u × axis_v) (Blender's local −Z).
    Area {
        position: [f32; 3],
        axis_u: [f32; 3],
        axis_v: [f32; 3],
        shape: AreaShape,
        size_x: f32,
        #[serde(default)]
        size_y: Option<f32>,
        power: f32,
        #[serde(default = "white")]
        color: [f32; 3],
        /// Seen by camera rays (Blender's object Ray Visibility → Camera, on by default;
        /// scene format 3, absent = off as older files baked): the front face shows radiance
        /// P/(π·A)·color, as Cycles renders a visible area light. Lights are not opaque in
        /// Cycles: the surface behind still shows.
        #[serde(default)]
        visible_camera: bool,
    },
    /// An emissive surface (scene format 3): every triangle of region `region` emits
    /// radiance `strength · color` from both faces — Cycles' convention for an Emission
    /// shader or the Principled BSDF's Emission (strength 1 of white shows as 1.0; Blender's
    /// "W/m²" label aside, the value is radiance in W/(m²·sr) scaled as Cycles scales it).
    /// Its light is sampled by next-event estimation (uniform by area, the area pdf
    /// converted to solid angle) and, with `visible_camera`, seen directly. The region
    /// itself still reflects with its material (black for a pure Emission shader).
    Emissive {
        region: u32,
        strength: f32,
        #[serde(default = "white")]
        color: [f32; 3],
        #[serde(default)]
        visible_camera: bool,
    },
}

fn white() -> [f32; 3] {
    [1.0, 1.0, 1.0]
}

/// The world (background) lighting.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum World {
    /// Constant radiance `color × strength` from every direction.
    Color {
        color: [f32; 3],
        #[serde(default = "one")]
        strength: f32,
    },
    /// An equirectangular environment in Blender's default mapping (Z up; the image centre
    /// faces +X, the top row is the zenith: see [`crate::geometry::environment`]), scaled by
    /// `strength`.
    Equirect {
        image: ImageRef,
        #[serde(default = "one")]
        strength: f32,
    },
}

fn one() -> f32 {
    1.0
}

impl Default for World {
    fn default() -> Self {
        World::Color {
            color: [0.0; 3],
            strength: 1.0,
        }
    }
}

/// Camera projection.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Projection {
    Perspective,
    Orthographic,
}

/// Which sensor dimension the field of view follows, as in Blender.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum SensorFit {
    #[default]
    Auto,
    Horizontal,
    Vertical,
}

/// A Blender camera: it looks along its local −Z with +Y up.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Camera {
    pub projection: Projection,
    /// Camera-to-world matrix, rows of Blender's `matrix_world` (row-major).
    pub matrix_world: [[f32; 4]; 4],
    /// Focal length in mm (perspective).
    #[serde(default = "default_lens")]
    pub lens_mm: f32,
    #[serde(default = "default_sensor")]
    pub sensor_width_mm: f32,
    #[serde(default = "default_sensor_h")]
    pub sensor_height_mm: f32,
    #[serde(default)]
    pub sensor_fit: SensorFit,
    /// Lens shift, in units of the fitted image dimension (the larger one for `auto`), as in
    /// Blender.
    #[serde(default)]
    pub shift_x: f32,
    #[serde(default)]
    pub shift_y: f32,
    /// Width of the view along the fitted dimension (orthographic).
    #[serde(default = "default_ortho")]
    pub ortho_scale: f32,
    #[serde(default = "default_clip_start")]
    pub clip_start: f32,
    #[serde(default = "default_clip_end")]
    pub clip_end: f32,
}

fn default_lens() -> f32 {
    50.0
}
fn default_sensor() -> f32 {
    36.0
}
fn default_sensor_h() -> f32 {
    24.0
}
fn default_ortho() -> f32 {
    6.0
}
fn default_clip_start() -> f32 {
    1e-4
}
fn default_clip_end() -> f32 {
    1e30
}

impl Scene {
    /// Number of triangles over all meshes.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.indices.len()).sum()
    }
    /// Indices of the editable regions, in scene order; position in this list is the
    /// editable index used in layer keys.
    pub fn editable_regions(&self) -> Vec<usize> {
        (0..self.regions.len())
            .filter(|&r| self.regions[r].editable)
            .collect()
    }
}
