//! Camera rays with Blender's conventions (`BKE_camera_params_compute_viewplane`): the
//! camera looks along its local −Z with +Y up; the sensor size applies to the fitted
//! dimension (the larger one for `auto`); shift is in units of that dimension.

use glam::{Mat4, Vec3, Vec4};

use crate::scene::{Camera, Projection, Resolution, SensorFit};

/// Blender's `matrix_world` rows → glam (column-major) matrix.
pub fn matrix_from_rows(rows: &[[f32; 4]; 4]) -> Mat4 {
    Mat4::from_cols_array_2d(rows).transpose()
}

/// A camera ready to generate rays for one resolution.
#[derive(Clone, Debug)]
pub struct CameraRays {
    to_world: Mat4,
    projection: Projection,
    width: f32,
    height: f32,
    /// Size of one pixel on the image plane (at distance 1 for perspective).
    pixel_size: f32,
    /// Shift in pixels.
    shift_px: (f32, f32),
    /// Ray start distance (perspective clip start).
    pub clip_start: f32,
}

impl CameraRays {
    /// Prepares rays for `camera` at `resolution`.
    pub fn new(camera: &Camera, resolution: Resolution) -> Self {
        let (w, h) = (resolution.width as f32, resolution.height as f32);
        let horizontal = match camera.sensor_fit {
            SensorFit::Auto => w >= h,
            SensorFit::Horizontal => true,
            SensorFit::Vertical => false,
        };
        let sensor = match camera.sensor_fit {
            SensorFit::Vertical => camera.sensor_height_mm,
            _ => camera.sensor_width_mm,
        };
        let view_fac = if horizontal { w } else { h };
        let extent = match camera.projection {
            Projection::Perspective => sensor / camera.lens_mm,
            Projection::Orthographic => camera.ortho_scale,
        };
        CameraRays {
            to_world: matrix_from_rows(&camera.matrix_world),
            projection: camera.projection,
            width: w,
            height: h,
            pixel_size: extent / view_fac,
            shift_px: (camera.shift_x * view_fac, camera.shift_y * view_fac),
            clip_start: camera.clip_start.max(0.0),
        }
    }

    /// The ray through film position (`x`, `y`) in pixels, (0, 0) the top-left corner of the
    /// image: (origin, unit direction).
    pub fn ray(&self, x: f32, y: f32) -> (Vec3, Vec3) {
        let px = (x - 0.5 * self.width + self.shift_px.0) * self.pixel_size;
        let py = (0.5 * self.height - y + self.shift_px.1) * self.pixel_size;
        match self.projection {
            Projection::Perspective => {
                let origin = self.to_world.transform_point3(Vec3::ZERO);
                let dir = (self.to_world * Vec4::new(px, py, -1.0, 0.0))
                    .truncate()
                    .normalize();
                (origin + dir * self.clip_start, dir)
            }
            Projection::Orthographic => {
                let origin = self.to_world.transform_point3(Vec3::new(px, py, 0.0));
                let dir = (self.to_world * Vec4::new(0.0, 0.0, -1.0, 0.0))
                    .truncate()
                    .normalize();
                (origin + dir * self.clip_start, dir)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(fit: SensorFit) -> Camera {
        Camera {
            projection: Projection::Perspective,
            matrix_world: [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 5.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
            lens_mm: 50.0,
            sensor_width_mm: 36.0,
            sensor_height_mm: 24.0,
            sensor_fit: fit,
            shift_x: 0.0,
            shift_y: 0.0,
            ortho_scale: 6.0,
            clip_start: 0.0,
            clip_end: 100.0,
        }
    }

    #[test]
    fn field_of_view_follows_blender() {
        // Horizontal fov of a 50 mm lens on a 36 mm sensor: 2·atan(18/50) = 39.6°.
        let c = CameraRays::new(
            &camera(SensorFit::Auto),
            Resolution {
                width: 200,
                height: 100,
            },
        );
        let (o, d) = c.ray(200.0, 50.0);
        assert!((o - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-6);
        let half = d.x.atan2(-d.z);
        assert!((half - (18.0f32 / 50.0).atan()).abs() < 1e-5, "{half}");
        // Portrait with auto fit: the sensor width spans the (larger) height.
        let c = CameraRays::new(
            &camera(SensorFit::Auto),
            Resolution {
                width: 100,
                height: 200,
            },
        );
        let (_, d) = c.ray(50.0, 0.0);
        assert!((d.y.atan2(-d.z) - (18.0f32 / 50.0).atan()).abs() < 1e-5);
        // Vertical fit uses the sensor height.
        let c = CameraRays::new(
            &camera(SensorFit::Vertical),
            Resolution {
                width: 200,
                height: 100,
            },
        );
        let (_, d) = c.ray(100.0, 0.0);
        assert!((d.y.atan2(-d.z) - (12.0f32 / 50.0).atan()).abs() < 1e-5);
    }

    #[test]
    fn shift_moves_the_view_by_the_fitted_dimension() {
        let mut cam = camera(SensorFit::Auto);
        cam.shift_x = 0.5;
        let c = CameraRays::new(
            &cam,
            Resolution {
                width: 200,
                height: 100,
            },
        );
        // The centre pixel now looks where the right edge looked.
        let (_, d) = c.ray(100.0, 50.0);
        assert!((d.x.atan2(-d.z) - (18.0f32 / 50.0).atan()).abs() < 1e-5);
    }

    #[test]
    fn orthographic_rays_are_parallel() {
        let mut cam = camera(SensorFit::Auto);
        cam.projection = Projection::Orthographic;
        let c = CameraRays::new(
            &cam,
            Resolution {
                width: 100,
                height: 100,
            },
        );
        let (o0, d0) = c.ray(0.0, 0.0);
        let (o1, d1) = c.ray(100.0, 100.0);
        assert!((d0 - d1).length() < 1e-6);
        assert!((o0.x - -3.0).abs() < 1e-5 && (o0.y - 3.0).abs() < 1e-5);
        assert!((o1.x - 3.0).abs() < 1e-5 && (o1.y - -3.0).abs() < 1e-5);
    }
}
