//! Primary rays of the report's pinhole camera (S1) placed by the orbit rig (S2).

use lucent_geom::{Affine3A, Ray};
use lucent_scene::camera::{Camera, Intrinsics, OrbitRig};

/// A pinhole camera for one image size, placed in the space of its rig
/// (render space for [`RenderScene::render_rig`](crate::RenderScene::render_rig)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PinholeCamera {
    /// Camera to render space: the rig's frame and position.
    pub render_from_camera: Affine3A,
    /// Focal lengths and principal point in pixels.
    pub intrinsics: Intrinsics,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl PinholeCamera {
    /// The camera of `rig` with `camera`'s field of view for a
    /// `width` x `height` image.
    pub fn new(camera: &Camera, rig: &OrbitRig, width: u32, height: u32) -> Self {
        Self {
            render_from_camera: rig.sanitized().world_from_camera(),
            intrinsics: camera.intrinsics(width, height),
            width,
            height,
        }
    }

    /// Render-space ray through continuous image point `(col, row)` (row 0 at
    /// the top; pixel centres at `+0.5`), with a unit direction.
    #[inline]
    pub fn ray(&self, col: f32, row: f32) -> Ray {
        let d = Camera::camera_ray_dir(&self.intrinsics, self.width, self.height, col, row);
        Ray::new(
            self.render_from_camera.translation.into(),
            self.render_from_camera.transform_vector3(d).normalize(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::Vec3;

    #[test]
    fn centre_ray_looks_at_the_orbit_centre_and_right_is_right() {
        let rig = OrbitRig {
            center: Vec3::new(1.0, 0.0, 0.0),
            radius: 4.0,
            theta: 0.0,
            phi: std::f32::consts::FRAC_PI_2,
        };
        // Camera at (1, 0, 4) looking down -z: picture right is world +x.
        let cam = PinholeCamera::new(&Camera { fov_y_deg: 90.0 }, &rig, 200, 100);
        let c = cam.ray(100.0, 50.0);
        assert!(c.origin.abs_diff_eq(Vec3::new(1.0, 0.0, 4.0), 1e-5));
        assert!(c.dir.abs_diff_eq(-Vec3::Z, 1e-6));
        assert!(cam.ray(200.0, 50.0).dir.x > 0.5, "right edge looks to +x");
        assert!(cam.ray(100.0, 0.0).dir.y > 0.5, "top edge looks up");
    }
}
