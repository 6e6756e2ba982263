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
    // cos^2 t = 1 - sin^2 t = (1 - eta^2) + (eta cos i)^2. The second form
    // keeps its precision near grazing incidence, where 1 - sin^2 t
    // cancels (at IOR 1 and 89.94 degrees the first form turned the ray by
    // 1.2e-5 radians), and is exact at eta = 1.
    let cos2_t = (1.0 - eta) * (1.0 + eta) + (eta * cos_i) * (eta * cos_i);
    let cos_t = cos2_t.max(0.0).sqrt();
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

    /// Unit directions at `deg` from the normal +y, coming down onto it.
    fn incoming(deg: f32) -> Vec3 {
        let a = deg.to_radians();
        Vec3::new(a.sin(), -a.cos(), 0.0)
    }

    #[test]
    fn grazing_angles_stay_unit_and_on_their_side() {
        let n = Vec3::Y;
        for deg in [80.0f32, 89.0, 89.9, 89.99, 89.999, 89.9999] {
            let d = incoming(deg);
            let r = reflect(d, n);
            assert!((r.length() - 1.0).abs() < 1e-6 && r.y >= 0.0, "{deg}: {r}");
            assert!(
                (r.y + d.y).abs() < 1e-7 && (r.x - d.x).abs() < 1e-7,
                "{deg}: mirror image"
            );
            // Entering glass at a grazing angle: the critical angle inside.
            let t = refract(d, n, 1.0 / 1.5).expect("entering a denser medium never reflects totally");
            assert!((t.length() - 1.0).abs() < 1e-5 && t.y <= 0.0, "{deg}: {t}");
            let sin_t = t.x;
            assert!((d.x - 1.5 * sin_t).abs() < 1e-5, "{deg}: Snell");
        }
    }

    #[test]
    fn total_internal_reflection_for_every_angle_past_critical() {
        // Leaving glass (1.5) and diamond (2.42) into air.
        for ior in [1.5f32, 2.42] {
            let critical = (1.0 / ior).asin().to_degrees();
            for k in 1..=100 {
                let deg = critical + (90.0 - critical) * k as f32 / 100.0;
                assert!(refract(incoming(deg), Vec3::Y, ior).is_none(), "ior {ior}, {deg} deg");
            }
            for k in 0..100 {
                let deg = critical * k as f32 / 100.0;
                let t = refract(incoming(deg), Vec3::Y, ior);
                assert!(
                    t.is_some_and(|t| (t.length() - 1.0).abs() < 1e-5),
                    "ior {ior}, {deg} deg"
                );
            }
        }
    }

    #[test]
    fn index_one_leaves_every_direction_unchanged() {
        // The ray goes on unchanged, within 1e-6 radians, up to grazing.
        for k in 0..=8999 {
            let deg = k as f32 * 0.01;
            let d = incoming(deg);
            let t = refract(d, Vec3::Y, 1.0).expect("no total reflection at IOR 1");
            let turn = t.normalize().cross(d).length();
            assert!(turn < 1e-6, "{deg} deg: {d} -> {t}, turned by {turn}");
        }
    }

    #[test]
    fn very_high_and_degenerate_indices_stay_finite() {
        for ior in [10.0f32, 1e3, 1e6, 1e20, f32::MAX, f32::INFINITY] {
            for deg in [0.0f32, 30.0, 89.9] {
                let d = incoming(deg);
                // Entering: the ray goes straight down the normal, within
                // sin(theta) / ior.
                let t = refract(d, Vec3::Y, 1.0 / ior).expect("entering never reflects totally");
                assert!(
                    t.is_finite() && (t.length() - 1.0).abs() < 1e-5,
                    "ior {ior}, {deg}: {t}"
                );
                assert!(
                    t.abs_diff_eq(-Vec3::Y, 1.0 / ior.min(1e6) + 1e-6),
                    "ior {ior}, {deg}: {t}"
                );
                // Leaving: totally reflected except (nearly) head on.
                if deg > 0.0 {
                    assert!(refract(d, Vec3::Y, ior).is_none(), "ior {ior}, {deg}");
                }
            }
        }
        // NaN and zero indices: no direction, never NaN.
        for eta in [f32::NAN, 0.0] {
            assert!(refract(incoming(30.0), Vec3::Y, eta).is_none_or(|t| t.is_finite()));
        }
    }
}
