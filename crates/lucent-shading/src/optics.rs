//! Mirror reflection and Snell refraction of ray directions.

use lucent_geom::Vec3;

/// Mirrors direction `d` about the plane with unit normal `n` (either side).
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Refracts unit direction `d` through a surface with unit normal `n`
/// pointing to the side `d` comes from (`d.n < 0`), where `eta` is the ratio
/// of refractive indices `n_incident / n_transmitted` (Snell's law). Returns
/// `None` for total internal reflection.
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t.is_nan() || sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(eta * d + (eta * cos_i - cos_t) * n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflection_keeps_the_angle() {
        let d = Vec3::new(1.0, -1.0, 0.0).normalize();
        assert!(reflect(d, Vec3::Y).abs_diff_eq(Vec3::new(1.0, 1.0, 0.0).normalize(), 1e-6));
        // The normal's side does not matter.
        assert!(reflect(d, -Vec3::Y).abs_diff_eq(reflect(d, Vec3::Y), 1e-6));
    }

    #[test]
    fn snell_holds_and_normal_incidence_goes_straight() {
        let n = Vec3::Y;
        assert!(refract(-Vec3::Y, n, 1.0 / 1.5).is_some_and(|t| t.abs_diff_eq(-Vec3::Y, 1e-6)));
        let theta_i = 40f32.to_radians();
        let d = Vec3::new(theta_i.sin(), -theta_i.cos(), 0.0);
        let t = refract(d, n, 1.0 / 1.5).expect("entering glass never reflects totally");
        let sin_t = t.x;
        assert!((theta_i.sin() - 1.5 * sin_t).abs() < 1e-6, "n1 sin1 = n2 sin2");
        assert!((t.length() - 1.0).abs() < 1e-6);
        // IOR 1: the ray goes on unchanged.
        assert!(refract(d, n, 1.0).is_some_and(|t| t.abs_diff_eq(d, 1e-6)));
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle() {
        let critical = (1.0f32 / 1.5).asin();
        let n = Vec3::Y;
        let at = |deg: f32| {
            let a = critical + deg.to_radians();
            Vec3::new(a.sin(), -a.cos(), 0.0)
        };
        assert!(refract(at(-1.0), n, 1.5).is_some());
        assert!(refract(at(1.0), n, 1.5).is_none());
    }
}
