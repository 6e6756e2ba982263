//! Self-intersection-free origins for secondary rays.
//!
//! A hit point computed in floating point lies a little off the true surface,
//! on either side. Restarting a ray exactly there lets it re-hit the surface
//! it just left ("shadow acne"). The seed report skipped the last object hit,
//! which breaks on concave meshes (a mesh must be able to shadow and reflect
//! itself). Instead we push the origin off the surface along the geometric
//! normal by a distance that scales with the magnitude of the coordinates,
//! which is the scale of their rounding error: a fixed number of ulps away
//! from the origin, a fixed tiny distance near it (Wachter and Binder, "A Fast
//! and Robust Method for Avoiding Self-Intersection", Ray Tracing Gems ch. 6).

use glam::Vec3;

/// Below this magnitude a coordinate is offset by a fixed distance instead of
/// a number of ulps (ulps shrink towards zero).
const ORIGIN_REGION: f32 = 1.0 / 32.0;
/// Fixed offset used near the origin.
const FLOAT_SCALE: f32 = 1.0 / 65536.0;
/// Number of ulps (times the normal component) used elsewhere.
const INT_SCALE: f32 = 256.0;

/// Moves a surface point `p` off the surface to the side `n` points to.
///
/// `n` must be the geometric normal (unit length), flipped towards the side
/// the new ray leaves into: towards the light for shadow rays, the incoming
/// side for reflection, the far side for refraction.
#[inline]
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    let mut res = p;
    for axis in 0..3 {
        let (pa, na) = (p[axis], n[axis]);
        res[axis] = if pa.abs() < ORIGIN_REGION {
            pa + FLOAT_SCALE * na
        } else {
            // `as i32` saturates and maps NaN to 0, so this cannot panic.
            let of = (INT_SCALE * na) as i32;
            let step = if pa < 0.0 { -of } else { of };
            f32::from_bits((pa.to_bits() as i32).wrapping_add(step) as u32)
        };
    }
    res
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_to_the_normal_side_at_every_scale() {
        let n = Vec3::new(0.6, -0.8, 0.0);
        for scale in [1e-6f32, 1e-3, 0.5, 1.0, 1e3, 1e6, 1e30] {
            for sign in [1.0f32, -1.0] {
                let p = Vec3::splat(sign * scale);
                let q = offset_ray_origin(p, n);
                assert!(q.x > p.x, "x at {p:?} -> {q:?}");
                assert!(q.y < p.y, "y at {p:?} -> {q:?}");
                assert_eq!(q.z, p.z);
                // The step is small relative to the coordinate (or to the
                // origin region, inside which it is a fixed distance).
                let rel = ((q - p).abs() / p.abs().max(Vec3::splat(ORIGIN_REGION))).max_element();
                assert!(rel < 1e-3, "offset too large at scale {scale}: {rel}");
            }
        }
    }

    #[test]
    fn non_finite_input_does_not_panic() {
        let q = offset_ray_origin(Vec3::new(f32::NAN, f32::INFINITY, -f32::MAX), Vec3::Y);
        assert!(q.x.is_nan());
    }
}
