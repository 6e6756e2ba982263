//! Ray-triangle intersection: the report's Moller-Trumbore test (S8).

use crate::Ray;
use glam::Vec3;

/// Where a ray meets a triangle: distance and barycentric coordinates.
///
/// The hit point is `(1 - u - v) * v0 + u * v1 + v * v2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Barycentric weight of the second vertex.
    pub u: f32,
    /// Barycentric weight of the third vertex.
    pub v: f32,
}

/// Moller-Trumbore ray-triangle test (the seed report's S8).
///
/// Returns the hit with `0 < t < t_max`. Both faces count (no culling).
/// Degenerate triangles (zero area, NaN or infinite vertices) never hit, and
/// nothing here can panic, whatever the inputs.
#[inline]
pub fn intersect_triangle(ray: &Ray, [v0, v1, v2]: [Vec3; 3], t_max: f32) -> Option<TriangleHit> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    // A zero or non-finite determinant means the ray is parallel to a
    // degenerate or non-finite triangle.
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = ray.origin - v0;
    let u = s.dot(p) * inv_det;
    // Written so that NaN fails every test.
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = ray.dir.dot(q) * inv_det;
    if !(v >= 0.0 && u + v <= 1.0) {
        return None;
    }
    let t = e2.dot(q) * inv_det;
    (t > 0.0 && t < t_max).then_some(TriangleHit { t, u, v })
}

/// The geometric normal `(v1 - v0) x (v2 - v0)`, not normalised (its length
/// is twice the area). Counter-clockwise winding faces the viewer.
#[inline]
pub fn triangle_normal([v0, v1, v2]: [Vec3; 3]) -> Vec3 {
    (v1 - v0).cross(v2 - v0)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TRI: [Vec3; 3] = [Vec3::ZERO, Vec3::X, Vec3::Y];

    fn check(origin: [f32; 3], dir: [f32; 3], t_max: f32) -> Option<(f32, f32, f32)> {
        let ray = Ray::new(Vec3::from(origin), Vec3::from(dir));
        intersect_triangle(&ray, TRI, t_max).map(|h| (h.t, h.u, h.v))
    }

    #[test]
    fn hits_inside_with_barycentrics() {
        assert_eq!(
            check([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], f32::INFINITY),
            Some((2.0, 0.25, 0.5))
        );
        // Back face counts too.
        assert_eq!(
            check([0.25, 0.5, -2.0], [0.0, 0.0, 1.0], f32::INFINITY),
            Some((2.0, 0.25, 0.5))
        );
    }

    #[test]
    fn misses_outside_behind_and_beyond_t_max() {
        assert_eq!(check([0.8, 0.8, 1.0], [0.0, 0.0, -1.0], f32::INFINITY), None);
        assert_eq!(check([0.2, 0.2, 1.0], [0.0, 0.0, 1.0], f32::INFINITY), None);
        assert_eq!(check([0.2, 0.2, 1.0], [0.0, 0.0, -1.0], 1.0), None);
        // Parallel to the plane.
        assert_eq!(check([0.2, 0.2, 0.0], [1.0, 0.0, 0.0], f32::INFINITY), None);
    }

    #[test]
    fn degenerate_and_non_finite_input_never_hits_or_panics() {
        let ray = Ray::new(Vec3::new(0.1, 0.1, 1.0), -Vec3::Z);
        let line = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
        assert!(intersect_triangle(&ray, line, f32::INFINITY).is_none());
        let nan = [Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 1.0, 0.0)];
        assert!(intersect_triangle(&ray, nan, f32::INFINITY).is_none());
        let inf = [Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::INFINITY, 0.0)];
        assert!(intersect_triangle(&ray, inf, f32::INFINITY).is_none());
        let nan_ray = Ray::new(Vec3::splat(f32::NAN), -Vec3::Z);
        assert!(intersect_triangle(&nan_ray, TRI, f32::INFINITY).is_none());
    }

    #[test]
    fn normal_follows_counter_clockwise_winding() {
        assert_eq!(triangle_normal(TRI), Vec3::Z);
    }
}
