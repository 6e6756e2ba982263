//! Axis-aligned bounding boxes and the ray-box slab test.

use glam::{Affine3A, Vec3};

/// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`, so
/// growing it by any point gives that point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// `1 + 2 * gamma(3)` (pbrt): scaling the far slab distance by this keeps the
/// slab test conservative under float rounding, so a ray that grazes a box
/// face is never rejected by the box while it hits a triangle inside.
const SLAB_ROUNDING: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

impl Aabb {
    /// The empty box (contains nothing, is the identity of [`Aabb::union`]).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    /// A box from two corners, given in any order.
    pub fn new(a: Vec3, b: Vec3) -> Self {
        Self {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// The smallest box containing every point; empty for no points.
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.grown(p))
    }

    /// Whether the box contains no point.
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// This box grown to contain `p`.
    pub fn grown(self, p: Vec3) -> Self {
        Self {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The smallest box containing both boxes.
    pub fn union(self, other: Aabb) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Size along each axis (negative for the empty box).
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// Centre point.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Half the surface area, the quantity the SAH compares; 0 when empty.
    pub fn half_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// Index (0, 1, 2) of the longest axis.
    pub fn largest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    /// Whether `p` lies inside or on the boundary.
    pub fn contains(&self, p: Vec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// The box around this box after an affine transform (Arvo's method:
    /// exact for the transformed corners, no eight-corner loop).
    pub fn transformed(&self, m: &Affine3A) -> Aabb {
        if self.is_empty() {
            return Self::EMPTY;
        }
        let t = Vec3::from(m.translation);
        let (mut lo, mut hi) = (t, t);
        let cols = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
        for (axis, col) in cols.iter().enumerate() {
            let col = Vec3::from(*col);
            let a = col * self.min[axis];
            let b = col * self.max[axis];
            lo += a.min(b);
            hi += a.max(b);
        }
        Aabb { min: lo, max: hi }
    }

    /// Slab test. Returns the entry distance when the ray (given by its
    /// origin and reciprocal direction) overlaps the box within `[0, t_max]`.
    ///
    /// A ray parallel to a slab and lying in one of its planes gives
    /// 0 * inf = NaN for that plane; the slab then does not limit the ray
    /// (it touches the box's face: the conservative answer). The near and
    /// far planes are picked by the direction's sign and a NaN never wins a
    /// comparison, as in the wide tree's four-box test. (Taking `min`/`max`
    /// of the two planes instead, which drop a NaN operand, made the far
    /// plane's infinity the entry distance: a ray along a box's edge, such
    /// as one aimed at the corner of a flat mesh, missed it.)
    #[inline]
    pub fn intersect_ray(&self, origin: Vec3, inv_dir: Vec3, t_max: f32) -> Option<f32> {
        let mut enter = 0.0f32;
        let mut exit = t_max;
        for axis in 0..3 {
            let (near, far) = if inv_dir[axis] < 0.0 {
                (self.max[axis], self.min[axis])
            } else {
                (self.min[axis], self.max[axis])
            };
            let a = (near - origin[axis]) * inv_dir[axis];
            let b = (far - origin[axis]) * inv_dir[axis];
            if a > enter {
                enter = a;
            }
            if b < exit {
                exit = b;
            }
        }
        (enter <= exit * SLAB_ROUNDING).then_some(enter)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn empty_box_is_identity_of_union() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(Aabb::EMPTY.union(b), b);
        assert_eq!(Aabb::EMPTY.half_area(), 0.0);
        assert_eq!(b.half_area(), 3.0);
    }

    #[test]
    fn rays_along_a_face_or_edge_of_the_box_hit_it() {
        // A flat box (a single triangle's bounds), and rays along +z through
        // its corner, along its edges and through its inside.
        let b = Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0));
        for (x, y) in [(0.0, 0.0), (1.0, 1.0), (0.0, 0.5), (0.5, 1.0), (0.5, 0.5)] {
            let o = Vec3::new(x, y, -3.0);
            assert_eq!(b.intersect_ray(o, Vec3::ONE / Vec3::Z, f32::INFINITY), Some(3.0), "{o}");
            // Going the other way, or starting outside the slab, misses.
            assert_eq!(b.intersect_ray(o, Vec3::ONE / -Vec3::Z, f32::INFINITY), None, "{o}");
        }
        let outside = Vec3::new(-1e-6, 0.0, -3.0);
        assert_eq!(b.intersect_ray(outside, Vec3::ONE / Vec3::Z, f32::INFINITY), None);
    }

    #[test]
    fn slab_test_hits_misses_and_grazes() {
        let b = Aabb::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let o = Vec3::new(-5.0, 0.0, 0.0);
        let d = Vec3::X;
        assert_eq!(b.intersect_ray(o, Vec3::ONE / d, f32::INFINITY), Some(4.0));
        assert_eq!(b.intersect_ray(o, Vec3::ONE / d, 3.0), None);
        assert_eq!(b.intersect_ray(o, Vec3::ONE / -d, f32::INFINITY), None);
        // A ray running exactly in the face plane y = 1 (0 * inf = NaN inside).
        let o = Vec3::new(-5.0, 1.0, 0.0);
        assert_eq!(b.intersect_ray(o, Vec3::ONE / d, f32::INFINITY), Some(4.0));
        // Origin inside the box enters at 0.
        assert_eq!(b.intersect_ray(Vec3::ZERO, Vec3::ONE / d, 10.0), Some(0.0));
    }

    #[test]
    fn transformed_box_contains_transformed_corners() {
        let b = Aabb::new(Vec3::new(-1.0, -2.0, -3.0), Vec3::new(1.0, 2.0, 3.0));
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 1.0, 0.5),
            Quat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.7),
            Vec3::new(10.0, -4.0, 2.0),
        );
        let tb = b.transformed(&m);
        for i in 0..8 {
            let c = Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            let p = m.transform_point3(c);
            assert!(tb.grown(p) == tb || (tb.grown(p).half_area() - tb.half_area()).abs() < 1e-3);
        }
    }
}
