//! Scene validation: a clear, specific error for bad input, and a report of what was
//! tolerated (degenerate triangles skipped, warnings) — never a crash and never a silent fix.

use serde::Serialize;

use super::{ImageRef, Light, Scene, World};
use crate::brdf::MaterialSpec;
use crate::{RelumeError, Result};

/// What validation tolerated.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ValidationReport {
    /// Triangles with (numerically) zero area: skipped by the bake.
    pub degenerate_triangles: usize,
    /// Triangles the bake will use.
    pub triangles: usize,
    /// Human-readable warnings (no light, no editable region, …).
    pub warnings: Vec<String>,
}

/// A triangle is degenerate when the sine of its largest angle's complement is below this:
/// |e1 × e2| ≤ 1e-7·|e1|·|e2| (or an edge of length 0). Slivers above it are kept.
pub const DEGENERATE_SINE: f32 = 1e-7;

fn finite(what: impl FnOnce() -> String, values: &[f32]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(RelumeError::NonFinite { what: what() })
    }
}

/// Whether the triangle (a, b, c) is degenerate (see [`DEGENERATE_SINE`]).
pub fn is_degenerate(a: glam::Vec3, b: glam::Vec3, c: glam::Vec3) -> bool {
    let e1 = b - a;
    let e2 = c - a;
    let cross = e1.cross(e2).length();
    let scale = e1.length() * e2.length();
    !(cross > DEGENERATE_SINE * scale) || !cross.is_finite()
}

/// Checks every value of `scene`; returns what was tolerated.
pub fn validate_scene(scene: &Scene) -> Result<ValidationReport> {
    let mut report = ValidationReport::default();
    if scene.regions.is_empty() {
        return Err(RelumeError::EmptyScene("no region (material)".into()));
    }
    if scene.triangle_count() == 0 {
        return Err(RelumeError::EmptyScene("no triangle in any mesh".into()));
    }
    scene.resolution.validate("resolution")?;
    for region in &scene.regions {
        // Named as a materials file's edit of the region is, so both read the same.
        validate_material(&format!("region \"{}\"", region.name), &region.material)?;
        if let Some(img) = &region.albedo_texture {
            validate_image(&format!("region \"{}\" albedo texture", region.name), img)?;
        }
        validate_subsurface(region, &mut report)?;
        if let Some([lo, hi]) = region.ns_range {
            if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo) {
                return Err(RelumeError::invalid(
                    format!("region \"{}\" ns_range", region.name),
                    format!("[{lo}, {hi}] (need 0 < min < max, finite)"),
                ));
            }
        }
    }
    for (mi, mesh) in scene.meshes.iter().enumerate() {
        let name = if mesh.name.is_empty() {
            format!("mesh {mi}")
        } else {
            format!("mesh {mi} \"{}\"", mesh.name)
        };
        let nv = mesh.positions.len();
        finite(
            || format!("{name} positions"),
            mesh.positions.as_flattened(),
        )?;
        if let Some(n) = &mesh.normals {
            if n.len() != nv {
                return Err(RelumeError::invalid(
                    format!("{name} normals"),
                    format!("{} normals for {nv} vertices", n.len()),
                ));
            }
            finite(|| format!("{name} normals"), n.as_flattened())?;
        }
        if let Some(uv) = &mesh.uvs {
            if uv.len() != nv {
                return Err(RelumeError::invalid(
                    format!("{name} uvs"),
                    format!("{} uvs for {nv} vertices", uv.len()),
                ));
            }
            finite(|| format!("{name} uvs"), uv.as_flattened())?;
        }
        if let Some(tr) = &mesh.triangle_regions {
            if tr.len() != mesh.indices.len() {
                return Err(RelumeError::invalid(
                    format!("{name} triangle_regions"),
                    format!("{} entries for {} triangles", tr.len(), mesh.indices.len()),
                ));
            }
        }
        for (t, tri) in mesh.indices.iter().enumerate() {
            for &i in tri {
                if i as usize >= nv {
                    return Err(RelumeError::IndexOutOfRange {
                        what: format!("{name} triangle {t} vertex index"),
                        index: i as u64,
                        len: nv,
                    });
                }
            }
            let r = mesh.region_of(t);
            if r as usize >= scene.regions.len() {
                return Err(RelumeError::IndexOutOfRange {
                    what: format!("{name} triangle {t} region"),
                    index: r as u64,
                    len: scene.regions.len(),
                });
            }
            let p = |k: usize| glam::Vec3::from(mesh.positions[tri[k] as usize]);
            if is_degenerate(p(0), p(1), p(2)) {
                report.degenerate_triangles += 1;
            } else {
                report.triangles += 1;
            }
        }
    }
    if report.triangles == 0 {
        return Err(RelumeError::EmptyScene(format!(
            "all {} triangles are degenerate (zero area)",
            report.degenerate_triangles
        )));
    }
    let mut emits = false;
    for (li, light) in scene.lights.iter().enumerate() {
        if let Light::Emissive { region, .. } = light {
            if *region as usize >= scene.regions.len() {
                return Err(RelumeError::invalid(
                    format!("light {li}"),
                    format!(
                        "emissive region {region} does not exist ({} regions)",
                        scene.regions.len()
                    ),
                ));
            }
        }
        emits |= validate_light(li, light)?;
    }
    validate_light_groups(scene)?;
    match &scene.world {
        World::Color { color, strength } => {
            finite(
                || "world colour".into(),
                &[color[0], color[1], color[2], *strength],
            )?;
            if color.iter().any(|c| *c < 0.0) || *strength < 0.0 {
                return Err(RelumeError::invalid("world", "negative colour or strength"));
            }
            emits |= color.iter().any(|c| *c > 0.0) && *strength > 0.0;
        }
        World::Equirect { image, strength } => {
            validate_image("world environment image", image)?;
            finite(|| "world strength".into(), &[*strength])?;
            if *strength < 0.0 {
                return Err(RelumeError::invalid("world", "negative strength"));
            }
            emits |= *strength > 0.0;
        }
    }
    if !emits {
        report
            .warnings
            .push("the scene has no light and a black world: every image will be black".into());
    }
    if !scene.regions.iter().any(|r| r.editable) {
        report
            .warnings
            .push("no region is editable: a relight can change nothing".into());
    }
    validate_camera(scene)?;
    Ok(report)
}

/// A region's material passes the materials file's rule ([`MaterialSpec::validate`]), in
/// its words: a scene and a relight edit refuse the same values, and nothing is clamped
/// silently (Principled metallic, roughness outside [0, 1], IOR ≤ 0, negative base colour,
/// Blinn–Phong Kd + Ks > 1, …).
fn validate_material(what: &str, m: &MaterialSpec) -> Result<()> {
    m.validate(what)
}

/// Checks a region's `subsurface` block; warns when a fixed region asks for translucency
/// (its subsurface light is not baked: make it editable).
fn validate_subsurface(region: &super::Region, report: &mut ValidationReport) -> Result<()> {
    let what = |f: &str| format!("region \"{}\" subsurface.{f}", region.name);
    let weight = match &region.material {
        MaterialSpec::Principled(p) => p.subsurface.weight,
        MaterialSpec::BlinnPhong(_) => 0.0,
    };
    if !region.editable && (region.subsurface.is_some() || weight > 0.0) {
        report.warnings.push(format!(
            "region \"{}\" has subsurface scattering but is not editable: only its surface BRDF is baked (mark it editable to bake its translucency)",
            region.name
        ));
    }
    let Some(s) = &region.subsurface else {
        return Ok(());
    };
    if let Some(n) = s.samples {
        if !(16..=4_194_304).contains(&n) {
            return Err(RelumeError::invalid(
                what("samples"),
                format!("{n} (16 to 4 194 304)"),
            ));
        }
    }
    for (name, range, min) in [
        ("mfp_range", s.mfp_range, 0.0f32),
        ("ior_range", s.ior_range, 1.0),
    ] {
        if let Some([lo, hi]) = range {
            if !(lo.is_finite() && hi.is_finite() && lo > min && hi >= lo)
                && !(name == "ior_range" && lo == 1.0 && hi >= lo && hi.is_finite())
            {
                return Err(RelumeError::invalid(
                    what(name),
                    format!("[{lo}, {hi}] (need {min} < min ≤ max, finite)"),
                ));
            }
        }
    }
    if let Some(b) = s.bases {
        if b == 0 || b as usize > crate::bssrdf::MAX_SSS_BASES {
            return Err(RelumeError::invalid(
                what("bases"),
                format!("{b} (1 to {})", crate::bssrdf::MAX_SSS_BASES),
            ));
        }
    }
    if let Some(t) = s.tolerance {
        if !(t > 0.0 && t < 1.0) {
            return Err(RelumeError::invalid(
                what("tolerance"),
                format!("{t} (in (0, 1))"),
            ));
        }
    }
    Ok(())
}

fn validate_image(what: &str, img: &ImageRef) -> Result<()> {
    match img {
        ImageRef::Inline { width, height, rgb } => {
            // Checked, in u64, against the values actually given: a claimed size whose
            // product wraps would otherwise pass here and be allocated (or indexed) later.
            let expect = (*width as u64)
                .checked_mul(*height as u64)
                .and_then(|n| n.checked_mul(3));
            if *width == 0 || *height == 0 || expect != Some(rgb.len() as u64) {
                let needs = match expect {
                    Some(n) => n.to_string(),
                    None => "more than 2⁶⁴".to_string(),
                };
                return Err(RelumeError::invalid(
                    what,
                    format!(
                        "{width}×{height}×3 needs {needs} RGB values, has {} (width and height must be ≥ 1 and match the values given)",
                        rgb.len()
                    ),
                ));
            }
            finite(|| what.to_string(), rgb)?;
            if rgb.iter().any(|v| *v < 0.0) {
                return Err(RelumeError::invalid(what, "negative values"));
            }
            Ok(())
        }
        ImageRef::Path { path } => Err(RelumeError::invalid(
            what,
            format!("image {path} was not loaded"),
        )),
    }
}

/// Returns whether the light emits anything.
fn validate_light(li: usize, light: &Light) -> Result<bool> {
    let what = || format!("light {li}");
    let nonzero = |v: &[f32; 3]| glam::Vec3::from(*v).length_squared() > 0.0;
    let (power, color) = match light {
        Light::Point {
            position,
            power,
            color,
            radius,
        } => {
            finite(
                what,
                &[position[0], position[1], position[2], *power, *radius],
            )?;
            if *radius < 0.0 {
                return Err(RelumeError::invalid(what(), "negative radius"));
            }
            (*power, *color)
        }
        Light::Spot {
            position,
            direction,
            power,
            color,
            radius,
            spot_size,
            spot_blend,
        } => {
            finite(
                what,
                &[
                    position[0],
                    position[1],
                    position[2],
                    direction[0],
                    direction[1],
                    direction[2],
                    *power,
                    *radius,
                    *spot_size,
                    *spot_blend,
                ],
            )?;
            if !nonzero(direction) {
                return Err(RelumeError::invalid(what(), "spot direction is zero"));
            }
            let size_ok = *spot_size > 0.0 && *spot_size <= std::f32::consts::PI;
            if !size_ok || !(0.0..=1.0).contains(spot_blend) || *radius < 0.0 {
                return Err(RelumeError::invalid(
                    what(),
                    "spot_size must be in (0, π], spot_blend in [0, 1], radius ≥ 0",
                ));
            }
            (*power, *color)
        }
        Light::Sun {
            direction,
            strength,
            color,
            angle,
        } => {
            finite(
                what,
                &[direction[0], direction[1], direction[2], *strength, *angle],
            )?;
            if !nonzero(direction) {
                return Err(RelumeError::invalid(what(), "sun direction is zero"));
            }
            if !(0.0..std::f32::consts::PI).contains(angle) {
                return Err(RelumeError::invalid(what(), "sun angle must be in [0, π)"));
            }
            (*strength, *color)
        }
        Light::Area {
            position,
            axis_u,
            axis_v,
            size_x,
            size_y,
            power,
            color,
            ..
        } => {
            finite(
                what,
                &[
                    position[0],
                    position[1],
                    position[2],
                    axis_u[0],
                    axis_u[1],
                    axis_u[2],
                    axis_v[0],
                    axis_v[1],
                    axis_v[2],
                    *size_x,
                    size_y.unwrap_or(1.0),
                    *power,
                ],
            )?;
            let u = glam::Vec3::from(*axis_u);
            let v = glam::Vec3::from(*axis_v);
            if u.cross(v).length() < 1e-6 * u.length() * v.length() || u.length() == 0.0 {
                return Err(RelumeError::invalid(
                    what(),
                    "area light axes are zero or parallel",
                ));
            }
            if *size_x <= 0.0 || size_y.is_some_and(|s| s <= 0.0) {
                return Err(RelumeError::invalid(what(), "area light size must be > 0"));
            }
            (*power, *color)
        }
        Light::Emissive {
            strength, color, ..
        } => {
            finite(what, &[*strength])?;
            (*strength, *color)
        }
    };
    finite(what, &color)?;
    if power < 0.0 || color.iter().any(|c| *c < 0.0) {
        return Err(RelumeError::invalid(what(), "negative power or colour"));
    }
    Ok(power > 0.0 && color.iter().any(|c| *c > 0.0))
}

/// Light groups are edited by name (a materials file's `light_groups`, the add-on's
/// sliders), so two groups of one name would make an edit ambiguous: refused, as is a group
/// naming a light the scene does not have.
fn validate_light_groups(scene: &Scene) -> Result<()> {
    for (g, group) in scene.light_groups.iter().enumerate() {
        if let Some(first) = scene.light_groups[..g]
            .iter()
            .position(|o| o.name == group.name)
        {
            return Err(RelumeError::invalid(
                format!("light group {g} \"{}\"", group.name),
                format!(
                    "duplicate light group name: group {first} has the same name (names must be unique, edits pick a group by name)"
                ),
            ));
        }
        if let Some(&l) = group
            .lights
            .iter()
            .find(|&&l| l as usize >= scene.lights.len())
        {
            return Err(RelumeError::IndexOutOfRange {
                what: format!("light group {g} \"{}\" light", group.name),
                index: l as u64,
                len: scene.lights.len(),
            });
        }
    }
    Ok(())
}

fn validate_camera(scene: &Scene) -> Result<()> {
    let c = &scene.camera;
    finite(|| "camera matrix".into(), c.matrix_world.as_flattened())?;
    finite(
        || "camera".into(),
        &[
            c.lens_mm,
            c.sensor_width_mm,
            c.sensor_height_mm,
            c.shift_x,
            c.shift_y,
            c.ortho_scale,
            c.clip_start,
        ],
    )?;
    let m = crate::geometry::camera::matrix_from_rows(&c.matrix_world);
    let (x, y, z) = (
        m.x_axis.truncate(),
        m.y_axis.truncate(),
        m.z_axis.truncate(),
    );
    if x.cross(y).length() < 1e-8 || z.length() < 1e-8 {
        return Err(RelumeError::invalid(
            "camera matrix",
            "degenerate rotation (zero or parallel axes)",
        ));
    }
    if c.lens_mm <= 0.0
        || c.sensor_width_mm <= 0.0
        || c.sensor_height_mm <= 0.0
        || c.ortho_scale <= 0.0
    {
        return Err(RelumeError::invalid(
            "camera",
            "lens, sensor sizes and ortho_scale must be > 0",
        ));
    }
    Ok(())
}
