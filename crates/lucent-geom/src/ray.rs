//! The ray type shared by every crate: an origin and an (unnormalised) direction.

use glam::Vec3;

/// A ray `origin + t * dir`, `t >= 0`.
///
/// The direction need not be unit length: object-space rays keep the scale of
/// their transform, so `t` means the same in every space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point (world or object space, as the caller says).
    pub origin: Vec3,
    /// Direction of travel; not necessarily normalised.
    pub dir: Vec3,
}

impl Ray {
    /// A ray from `origin` along `dir`.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self { origin, dir }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }

    /// The componentwise reciprocal of the direction, as used by slab tests.
    /// A zero component gives an infinity of the matching sign.
    pub fn inv_dir(&self) -> Vec3 {
        Vec3::ONE / self.dir
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_walks_along_the_direction() {
        let r = Ray::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 2.0, 0.0));
        assert_eq!(r.at(0.5), Vec3::new(1.0, 3.0, 3.0));
        assert_eq!(r.inv_dir(), Vec3::new(f32::INFINITY, 0.5, f32::INFINITY));
    }
}
