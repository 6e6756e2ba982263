//! The report's camera: pinhole intrinsics (S1) and the orbit rig (S2).
//!
//! The rig puts the camera on a sphere of radius `R` around a centre `O`,
//! at elevation `theta` and azimuth `phi`, looking at `O`:
//!
//! ```text
//! position = (R cos(theta) cos(phi), R sin(theta), R cos(theta) sin(phi)) + O
//! x axis   = (-sin(phi), 0, cos(phi))
//! y axis   = (-sin(theta) cos(phi), cos(theta), -sin(theta) sin(phi))
//! z axis   = (-cos(theta) cos(phi), -sin(theta), -cos(theta) sin(phi))
//! ```
//!
//! The frame is right-handed with z looking at `O`, y up and therefore x
//! pointing to the *left* of the picture. A camera-space ray for the report's
//! pixel coordinates `(u, v)` (measured along x and y) is
//! `((u - u0) / fx, (v - v0) / fy, 1)`; see [`Camera::camera_ray_dir`] for
//! how image rows and columns map onto `(u, v)`.

use lucent_geom::{Affine3A, Mat3A, Vec3, Vec3A};

/// Elevation limit: the rig keeps `|theta|` at most this far from the
/// horizon (89.9 degrees), so the frame never degenerates at the poles.
pub const THETA_LIMIT: f32 = 89.9 * std::f32::consts::PI / 180.0;
/// Smallest orbit radius: small enough to frame a scene of 1e-6 units
/// (1e-4, the earlier limit, pulled such a camera far out of its scene).
pub const MIN_RADIUS: f32 = 1e-9;
/// Largest orbit radius.
pub const MAX_RADIUS: f32 = 1e7;

/// Pinhole intrinsics. The report used a 300x300 image with
/// `fx = fy = u0 = v0 = 150`, a 90 degree field of view; Lucent derives the
/// focal length from the vertical field of view and the image height
/// (square pixels), with the principal point at the image centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Vertical field of view in degrees (0 to 180, exclusive).
    pub fov_y_deg: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Self { fov_y_deg: 90.0 }
    }
}

/// Focal lengths and principal point in pixels, as in the report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Intrinsics {
    /// Horizontal focal length.
    pub fx: f32,
    /// Vertical focal length.
    pub fy: f32,
    /// Principal point along the camera's x axis.
    pub u0: f32,
    /// Principal point along the camera's y axis.
    pub v0: f32,
}

impl Camera {
    /// Intrinsics for a `width` x `height` image.
    pub fn intrinsics(&self, width: u32, height: u32) -> Intrinsics {
        // A NaN field of view would make every ray NaN (a picture of only
        // the background); like the rig, it falls back to the default.
        let fov_deg = if self.fov_y_deg.is_nan() {
            Camera::default().fov_y_deg
        } else {
            self.fov_y_deg
        };
        let fov = fov_deg.clamp(1e-3, 179.999).to_radians();
        let fy = 0.5 * height as f32 / (0.5 * fov).tan();
        Intrinsics {
            fx: fy,
            fy,
            u0: 0.5 * width as f32,
            v0: 0.5 * height as f32,
        }
    }

    /// Camera-space direction through image point `(col, row)` (continuous
    /// pixel coordinates, row 0 at the top, pixel centres at `+0.5`).
    ///
    /// The report's `(u, v)` run along the camera's x and y axes, which point
    /// left and up in the picture, so `u = width - col` and
    /// `v = height - row`; then the direction is the report's
    /// `((u - u0) / fx, (v - v0) / fy, 1)`.
    #[inline]
    pub fn camera_ray_dir(k: &Intrinsics, width: u32, height: u32, col: f32, row: f32) -> Vec3 {
        let u = width as f32 - col;
        let v = height as f32 - row;
        Vec3::new((u - k.u0) / k.fx, (v - k.v0) / k.fy, 1.0)
    }
}

/// The report's orbit rig (S2): camera on a sphere around `center`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrbitRig {
    /// The point looked at, `O`.
    pub center: Vec3,
    /// Distance from `O`, `R`.
    pub radius: f32,
    /// Elevation above the horizontal plane through `O`, radians.
    pub theta: f32,
    /// Azimuth in the horizontal plane, radians (0 = +x side of `O`).
    pub phi: f32,
}

impl Default for OrbitRig {
    fn default() -> Self {
        Self {
            center: Vec3::ZERO,
            radius: 3.0,
            theta: 0.3,
            phi: std::f32::consts::FRAC_PI_2,
        }
    }
}

impl OrbitRig {
    /// This rig with `theta` and `radius` clamped to safe ranges and
    /// non-finite values replaced by defaults, so the pose is always finite.
    pub fn sanitized(self) -> Self {
        let d = Self::default();
        let finite_or = |x: f32, y: f32| if x.is_finite() { x } else { y };
        Self {
            center: if self.center.is_finite() { self.center } else { d.center },
            radius: finite_or(self.radius, d.radius).clamp(MIN_RADIUS, MAX_RADIUS),
            theta: finite_or(self.theta, d.theta).clamp(-THETA_LIMIT, THETA_LIMIT),
            phi: finite_or(self.phi, d.phi).rem_euclid(std::f32::consts::TAU),
        }
    }

    /// Camera position `(R cos(theta) cos(phi), R sin(theta), R cos(theta) sin(phi)) + O`.
    pub fn position(&self) -> Vec3 {
        let (st, ct) = self.theta.sin_cos();
        let (sp, cp) = self.phi.sin_cos();
        self.center + self.radius * Vec3::new(ct * cp, st, ct * sp)
    }

    /// The camera's x, y and z axes in world space, exactly as the report
    /// writes them.
    pub fn axes(&self) -> [Vec3; 3] {
        let (st, ct) = self.theta.sin_cos();
        let (sp, cp) = self.phi.sin_cos();
        [
            Vec3::new(-sp, 0.0, cp),
            Vec3::new(-st * cp, ct, -st * sp),
            Vec3::new(-ct * cp, -st, -ct * sp),
        ]
    }

    /// The report's camera-to-world matrix: columns x, y, z and position.
    pub fn world_from_camera(&self) -> Affine3A {
        let [x, y, z] = self.axes();
        Affine3A {
            matrix3: Mat3A::from_cols(Vec3A::from(x), Vec3A::from(y), Vec3A::from(z)),
            translation: Vec3A::from(self.position()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_fields_of_view_give_finite_intrinsics() {
        for fov in [f32::NAN, f32::INFINITY, -f32::INFINITY, 0.0, -5.0, 1e-30, 180.0, 1e9] {
            let k = Camera { fov_y_deg: fov }.intrinsics(33, 33);
            assert!(k.fx.is_finite() && k.fx > 0.0 && k.fx == k.fy, "{fov}: {k:?}");
        }
        let nan = Camera { fov_y_deg: f32::NAN }.intrinsics(300, 300);
        assert_eq!(nan, Camera::default().intrinsics(300, 300));
    }

    #[test]
    fn report_intrinsics_for_300_square_at_90_degrees() {
        let k = Camera { fov_y_deg: 90.0 }.intrinsics(300, 300);
        assert!((k.fx - 150.0).abs() < 1e-3 && (k.fy - 150.0).abs() < 1e-3);
        assert_eq!((k.u0, k.v0), (150.0, 150.0));
    }

    #[test]
    fn axes_are_orthonormal_right_handed_and_look_at_the_centre() {
        for (theta, phi) in [(0.0, 0.0), (0.3, 1.2), (-1.0, 4.0), (THETA_LIMIT, 2.0)] {
            let rig = OrbitRig {
                center: Vec3::new(1.0, 2.0, 3.0),
                radius: 5.0,
                theta,
                phi,
            };
            let [x, y, z] = rig.axes();
            for (a, b) in [(x, y), (y, z), (z, x)] {
                assert!(a.dot(b).abs() < 1e-6);
            }
            assert!(x.cross(y).abs_diff_eq(z, 1e-6), "right-handed");
            let to_center = (rig.center - rig.position()).normalize();
            assert!(to_center.abs_diff_eq(z, 1e-5), "z looks at O");
            assert!((rig.position() - rig.center).length() - 5.0 < 1e-4);
        }
    }

    #[test]
    fn matrix_is_the_reports() {
        let rig = OrbitRig {
            center: Vec3::new(0.5, -1.0, 2.0),
            radius: 2.0,
            theta: 0.4,
            phi: 0.9,
        };
        let (st, ct) = 0.4f32.sin_cos();
        let (sp, cp) = 0.9f32.sin_cos();
        #[rustfmt::skip]
        let report = [
            [-sp, -st * cp, -ct * cp, 2.0 * ct * cp + 0.5],
            [0.0, ct, -st, 2.0 * st - 1.0],
            [cp, -st * sp, -ct * sp, 2.0 * ct * sp + 2.0],
        ];
        let m = rig.world_from_camera();
        let cols = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis, m.translation];
        for (row, expected) in report.iter().enumerate() {
            for (col, e) in expected.iter().enumerate() {
                assert!((cols[col][row] - e).abs() < 1e-6, "row {row} col {col}");
            }
        }
    }

    #[test]
    fn image_columns_run_left_to_right_rows_top_to_bottom() {
        let cam = Camera { fov_y_deg: 90.0 };
        let k = cam.intrinsics(300, 300);
        // Centre pixel looks straight ahead.
        let d = Camera::camera_ray_dir(&k, 300, 300, 150.0, 150.0);
        assert_eq!(d, Vec3::Z);
        // Left edge of the picture is +x in camera space (x points left), top is +y.
        let left = Camera::camera_ray_dir(&k, 300, 300, 0.0, 150.0);
        assert_eq!(left, Vec3::new(1.0, 0.0, 1.0));
        let top = Camera::camera_ray_dir(&k, 300, 300, 150.0, 0.0);
        assert_eq!(top, Vec3::new(0.0, 1.0, 1.0));
    }

    #[test]
    fn sanitized_rig_is_finite_at_the_extremes() {
        let rig = OrbitRig {
            center: Vec3::splat(f32::NAN),
            radius: 0.0,
            theta: 10.0,
            phi: f32::INFINITY,
        }
        .sanitized();
        assert!(rig.world_from_camera().is_finite());
        assert_eq!(rig.theta, THETA_LIMIT);
        assert_eq!(rig.radius, MIN_RADIUS);
    }
}
