//! Primary rays of the report's pinhole camera (S1) placed by the orbit rig (S2).

use lucent_geom::{Affine3A, Ray, Vec3};
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

    /// [`PinholeCamera::ray`] through the sixteen image points
    /// (`col[k]`, `row[k]`), bit for bit, as loops over the sixteen that
    /// the compiler vectorises: the origin, and the unit directions'
    /// x, y and z rows. The same operations in the same order (no fused
    /// multiply-add), so the same roundings.
    #[inline(always)]
    pub fn rays_in_lanes(&self, col: &[f32; 16], row: &[f32; 16]) -> (Vec3, [[f32; 16]; 3]) {
        let m = &self.render_from_camera.matrix3;
        let (ax, ay, az) = (m.x_axis, m.y_axis, m.z_axis);
        let mut dir = [[0.0f32; 16]; 3];
        for l in 0..16 {
            let d = Camera::camera_ray_dir(&self.intrinsics, self.width, self.height, col[l], row[l]);
            // glam's `Mat3A * Vec3A`: x axis, plus y axis, plus z axis.
            let r = [
                ax.x * d.x + ay.x * d.y + az.x * d.z,
                ax.y * d.x + ay.y * d.y + az.y * d.z,
                ax.z * d.x + ay.z * d.y + az.z * d.z,
            ];
            // glam's `normalize`: times the reciprocal of the length.
            let inv = 1.0 / (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
            for c in 0..3 {
                dir[c][l] = r[c] * inv;
            }
        }
        (self.render_from_camera.translation.into(), dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_in_lanes_are_the_single_rays_bit_for_bit() {
        let mut rng = lucent_geom::Pcg32::new(5, 1);
        for (width, height, fov, theta, phi) in [
            (640, 360, 40.0, 0.28, 1.57),
            (256, 256, 90.0, -1.2, 4.0),
            (7, 3000, 1.0, 0.0, 0.0),
        ] {
            let rig = OrbitRig {
                center: Vec3::new(0.3, -2.0, 7.0),
                radius: 5.2,
                theta,
                phi,
            };
            let cam = PinholeCamera::new(&Camera { fov_y_deg: fov }, &rig, width, height);
            for _ in 0..200 {
                let col: [f32; 16] = std::array::from_fn(|_| rng.next_f32() * (width as f32 + 2.0) - 1.0);
                let row: [f32; 16] = std::array::from_fn(|_| rng.next_f32() * (height as f32 + 2.0) - 1.0);
                let (origin, dir) = cam.rays_in_lanes(&col, &row);
                for l in 0..16 {
                    let one = cam.ray(col[l], row[l]);
                    assert_eq!(
                        origin.to_array().map(f32::to_bits),
                        one.origin.to_array().map(f32::to_bits)
                    );
                    let lane = [dir[0][l], dir[1][l], dir[2][l]].map(f32::to_bits);
                    assert_eq!(lane, one.dir.to_array().map(f32::to_bits), "({}, {})", col[l], row[l]);
                }
            }
        }
    }

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
