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

use glam::{Vec3, Vec3A};

/// Below this magnitude a coordinate is offset by a fixed distance instead of
/// a number of ulps (ulps shrink towards zero).
const ORIGIN_REGION: f32 = 1.0 / 32.0;
/// Fixed offset used near the origin.
const FLOAT_SCALE: f32 = 1.0 / 65536.0;
/// Largest triangle magnitude offset exactly as at unit size.
const UNIT_MAX: f32 = 4.0;
/// Number of ulps (times the normal component) used elsewhere.
const INT_SCALE: f32 = 256.0;

/// Moves a surface point `p` off the surface to the side `n` points to,
/// for geometry of about unit size: [`offset_ray_origin_scaled`] with a
/// magnitude of 1.
///
/// Near the origin this moves `p` by a fixed 1/65536, which is larger than
/// a scene a thousand times smaller than unit size can afford; renderers
/// should pass the triangle's magnitude to [`offset_ray_origin_scaled`].
#[inline]
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    offset_ray_origin_scaled(p, n, 1.0)
}

/// Moves a surface point `p` off the surface to the side `n` points to.
///
/// `n` must be the geometric normal (unit length), flipped towards the side
/// the new ray leaves into: towards the light for shadow rays, the incoming
/// side for reflection, the far side for refraction. `magnitude` is the
/// largest absolute coordinate of the triangle hit (its corners in the same
/// space as `p`), which bounds the rounding error of `p` on every axis,
/// also on an axis where `p` itself is near zero.
///
/// A coordinate far from zero moves by 256 ulps times the normal's
/// component. Inside the origin region ulps shrink towards zero, so it moves
/// by a fixed distance instead. For triangles of unit size (`magnitude`
/// from 1/32 to 4) the region is 1/32 and the distance 1/65536, the
/// constants of Wachter and Binder; both shrink in proportion for smaller
/// geometry and grow in proportion for larger (the distance is then 32 ulps
/// of `magnitude`, several times the rounding error of `p`, which is a few
/// ulps of the corners). So a scene scaled by `s` is offset by `s` times as
/// much, from 1e-6 to 1e6, and unit-size scenes exactly as before.
///
/// ```
/// use lucent_geom::{offset_ray_origin_scaled, Vec3};
/// // A point on a micrometre-sized triangle near the origin.
/// let p = Vec3::new(1e-6, 0.0, 2e-6);
/// let q = offset_ray_origin_scaled(p, Vec3::Y, 3e-6);
/// assert!(q.y > 0.0 && q.y < 1e-8);
/// ```
#[inline]
pub fn offset_ray_origin_scaled(p: Vec3, n: Vec3, magnitude: f32) -> Vec3 {
    Vec3::from(offset_ray_origin_a(Vec3A::from(p), Vec3A::from(n), magnitude))
}

/// [`offset_ray_origin_scaled`] on four-wide vectors, the same numbers in
/// the first three lanes (the fourth is not meaningful): for callers that
/// keep their points in [`Vec3A`], so the offset costs no conversions.
///
/// ```
/// use lucent_geom::{offset_ray_origin_a, offset_ray_origin_scaled, Vec3, Vec3A};
/// let (p, n) = (Vec3::new(3.0, -0.01, 1e-5), Vec3::new(0.6, 0.0, -0.8));
/// let a = offset_ray_origin_a(Vec3A::from(p), Vec3A::from(n), 3.0);
/// assert_eq!(Vec3::from(a), offset_ray_origin_scaled(p, n, 3.0));
/// ```
#[inline]
pub fn offset_ray_origin_a(p: Vec3A, n: Vec3A, magnitude: f32) -> Vec3A {
    let k = offset_scale(magnitude);
    offset_axes(p, n, ORIGIN_REGION * k, FLOAT_SCALE * k)
}

/// The factor both offsets scale by for geometry of coordinate magnitude
/// `magnitude`: 1 for unit-size geometry, proportional to the size outside
/// that range; NaN falls back to 1.
#[inline(always)]
fn offset_scale(magnitude: f32) -> f32 {
    if magnitude < ORIGIN_REGION {
        (magnitude / ORIGIN_REGION).max(0.0)
    } else if magnitude > UNIT_MAX {
        magnitude / UNIT_MAX
    } else {
        1.0
    }
}

/// One coordinate of [`offset_ray_origin_a`]: `pa` moved along `na` (the
/// normal's component on that axis, at most 1 in magnitude) for a triangle
/// of coordinate magnitude `magnitude`. The same offset but for the ulp
/// count, rounded to nearest here where [`offset_ray_origin_a`] truncates
/// (at most one ulp of 256 apart). Written without branches or saturating
/// conversions, so that a loop over lanes of points compiles to vector
/// code: the lane path tracer's offset.
#[inline(always)]
pub fn offset_coord(pa: f32, na: f32, magnitude: f32) -> f32 {
    let k = offset_scale(magnitude);
    let near = pa + FLOAT_SCALE * k * na;
    // `INT_SCALE * na` rounded to the nearest integer by the float adder
    // (1.5 * 2^23 puts the units in the mantissa's last place), for
    // `|na| <= 1` as a unit normal has; unlike `as i32` (truncation with
    // saturation), this stays in vector registers.
    const ROUND: f32 = 12_582_912.0;
    let of = ((INT_SCALE * na + ROUND).to_bits() as i32).wrapping_sub(ROUND.to_bits() as i32);
    let step = if pa < 0.0 { of.wrapping_neg() } else { of };
    let far = f32::from_bits((pa.to_bits() as i32).wrapping_add(step) as u32);
    if pa.abs() < ORIGIN_REGION * k { near } else { far }
}

/// Each axis of `p` moved along `n`: by `fixed * n` where `|p| < region`,
/// else by `INT_SCALE * n` ulps (the step converted as `as i32` does, that
/// is saturating and NaN to 0, and negated by wrapping).
#[cfg(not(target_arch = "x86_64"))]
#[inline]
fn offset_axes(p: Vec3A, n: Vec3A, region: f32, fixed: f32) -> Vec3A {
    Vec3A::from(offset_axes_scalar(Vec3::from(p), Vec3::from(n), region, fixed))
}

/// The portable [`offset_axes`], one axis at a time.
#[cfg(any(test, not(target_arch = "x86_64")))]
#[inline]
fn offset_axes_scalar(p: Vec3, n: Vec3, region: f32, fixed: f32) -> Vec3 {
    let mut res = p;
    for axis in 0..3 {
        let (pa, na) = (p[axis], n[axis]);
        res[axis] = if pa.abs() < region {
            pa + fixed * na
        } else {
            // `as i32` saturates and maps NaN to 0, so this cannot panic.
            let of = (INT_SCALE * na) as i32;
            let step = if pa < 0.0 { of.wrapping_neg() } else { of };
            f32::from_bits((pa.to_bits() as i32).wrapping_add(step) as u32)
        };
    }
    res
}

/// [`offset_axes_scalar`] on all three axes at once in SSE2 (part of every
/// x86-64), branch-free: the same operations in the same order per lane, so
/// the result is equal bit for bit (a test checks it, hostile inputs
/// included). A secondary ray's origin is offset once or twice per path
/// vertex; the scalar form spends about 55 instructions on it, most of them
/// on the saturating conversion and a branch per axis.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code, reason = "SSE2 intrinsics on registers, see SAFETY below")]
#[inline]
fn offset_axes(p: Vec3A, n: Vec3A, region: f32, fixed: f32) -> Vec3A {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of the x86-64 baseline, so the processor has
    // these instructions; they only compute on registers (glam moves the
    // vectors in and out; the fourth lane is never read).
    unsafe {
        let pv: __m128 = p.into();
        let nv: __m128 = n.into();
        let abs = _mm_and_ps(pv, _mm_castsi128_ps(_mm_set1_epi32(0x7fff_ffff)));
        let near = _mm_cmplt_ps(abs, _mm_set1_ps(region));
        let small = _mm_add_ps(pv, _mm_mul_ps(_mm_set1_ps(fixed), nv));
        let s = _mm_mul_ps(_mm_set1_ps(INT_SCALE), nv);
        // `as i32`: NaN gives 0 (zero it first), and values from 2^31 up
        // give i32::MAX, where the conversion gives i32::MIN: flip those.
        let s = _mm_and_ps(s, _mm_cmpord_ps(s, s));
        let over = _mm_castps_si128(_mm_cmpge_ps(s, _mm_set1_ps(2_147_483_648.0)));
        let of = _mm_xor_si128(_mm_cvttps_epi32(s), over);
        // Negated where p < 0: (of ^ -1) - (-1) is the wrapping -of.
        let neg = _mm_castps_si128(_mm_cmplt_ps(pv, _mm_setzero_ps()));
        let step = _mm_sub_epi32(_mm_xor_si128(of, neg), neg);
        let far = _mm_castsi128_ps(_mm_add_epi32(_mm_castps_si128(pv), step));
        let res = _mm_or_ps(_mm_and_ps(near, small), _mm_andnot_ps(near, far));
        Vec3A::from(res)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_axes_at_once_equal_the_scalar_form_bit_for_bit() {
        let mut rng = crate::Pcg32::new(7, 1);
        let specials = [
            0.0f32,
            -0.0,
            1e-40,
            -1e-40,
            1.0 / 32.0,
            -1.0 / 32.0,
            1.0,
            -3.5,
            1e30,
            -1e30,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            8.4e6,
            -2.0e9,
        ];
        let pick = |rng: &mut crate::Pcg32| {
            let r = rng.next_f32();
            if r < 0.3 {
                specials[(rng.next_u32() as usize) % specials.len()]
            } else {
                let e = (rng.next_f32() * 80.0 - 40.0).exp2();
                (rng.next_f32() * 2.0 - 1.0) * e
            }
        };
        for _ in 0..20_000 {
            let p = Vec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng));
            let n = Vec3::new(pick(&mut rng), pick(&mut rng), pick(&mut rng));
            let (region, fixed) = (pick(&mut rng).abs(), pick(&mut rng));
            let (a, b) = (
                Vec3::from(offset_axes(Vec3A::from(p), Vec3A::from(n), region, fixed)),
                offset_axes_scalar(p, n, region, fixed),
            );
            assert_eq!(
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits),
                "{p:?} {n:?} {region} {fixed}"
            );
        }
    }

    #[test]
    fn one_coordinate_at_a_time_is_within_one_ulp_of_the_offset() {
        let mut rng = crate::Pcg32::new(9, 3);
        for _ in 0..50_000 {
            let e = (rng.next_f32() * 60.0 - 30.0).exp2();
            let p = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5) * e;
            let n = Vec3::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5).normalize();
            let magnitude = p.abs().max_element() * (1.0 + rng.next_f32());
            let q = Vec3::from(offset_ray_origin_a(Vec3A::from(p), Vec3A::from(n), magnitude));
            for axis in 0..3 {
                let c = offset_coord(p[axis], n[axis], magnitude);
                // Rounded rather than truncated ulp counts: one ulp apart
                // at most, and never on the other side of `p`.
                let ulps = (c.to_bits() as i64 - q[axis].to_bits() as i64).abs();
                assert!(
                    ulps <= 1,
                    "{p:?} {n:?} {magnitude} axis {axis}: {c} against {}",
                    q[axis]
                );
                assert!((c - p[axis]) * n[axis] >= 0.0, "{p:?} {n:?} axis {axis}");
            }
        }
    }

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
    fn scaled_offsets_follow_the_geometry_from_1e_minus_6_to_1e6() {
        // A point of a triangle whose corners reach `s`, on an axis where p
        // is zero (the origin region) and on one where it is not.
        let n = Vec3::new(0.0, 1.0, 0.0);
        let rel_at = |s: f32, y: f32| {
            let p = Vec3::new(0.25 * s, y * s, 0.5 * s);
            let q = offset_ray_origin_scaled(p, n, s);
            assert_eq!((q.x, q.z), (p.x, p.z));
            (q.y - p.y) / s
        };
        for s in [1e-6f32, 1e-4, 1e-3, 1.0 / 64.0, 1.0, 4.0, 1e3, 1e6] {
            for y in [0.0, 0.5] {
                let rel = rel_at(s, y);
                // Above the surface by more than the rounding error of a
                // coordinate of size s (a few ulps, 2^-24 s each), and by
                // less than 1e-3 of s.
                assert!(rel > 16.0 * f32::EPSILON && rel < 1e-3, "scale {s}, y {y}: {rel}");
            }
        }
        // Scale invariance below and above unit size.
        for (a, b) in [(1e-6f32, 1e-3f32), (1e3, 1e6)] {
            let (ra, rb) = (rel_at(a, 0.0), rel_at(b, 0.0));
            assert!((ra - rb).abs() <= 1e-5 * rb, "{a}: {ra} vs {b}: {rb}");
        }
        // Unit-size geometry: exactly the unit-scale offset.
        let p = Vec3::new(0.01, 2.0, -0.02);
        for m in [1.0 / 32.0, 1.0, 4.0, f32::NAN] {
            assert_eq!(offset_ray_origin_scaled(p, n, m), offset_ray_origin(p, n), "{m}");
        }
    }

    #[test]
    fn non_finite_input_does_not_panic() {
        let q = offset_ray_origin(Vec3::new(f32::NAN, f32::INFINITY, -f32::MAX), Vec3::Y);
        assert!(q.x.is_nan());
    }
}
