//! Mirror reflection and Snell refraction of ray directions, and the
//! Fresnel reflectance of a smooth dielectric boundary.

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

/// Exact Fresnel reflectance of unpolarised light at a smooth boundary
/// between two dielectrics: the mean of the s- and p-polarised power
/// reflectances.
///
/// `cos_theta_i` is the cosine of the angle between the incident direction
/// and the normal; only its absolute value is used. `eta` is the relative
/// index **`n_transmitted / n_incident`** (for light arriving from outside a
/// glass of index 1.5 in air, `eta = 1.5`; from inside, `1 / 1.5`). Past the
/// critical angle (total internal reflection) the result is 1. The
/// transmitted fraction of the power is `1 - fresnel_dielectric(..)`.
///
/// Degenerate input never panics: a `cos_theta_i` above 1 is read as 1, and
/// a NaN cosine or an `eta` that is not a positive finite number gives 1
/// (everything reflected, nothing transmitted).
///
/// ```
/// use lucent_shading::optics::fresnel_dielectric;
/// // Normal incidence on glass: ((1.5 - 1) / (1.5 + 1))^2 = 0.04.
/// assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
/// // Inside the glass past the critical angle: total internal reflection.
/// assert_eq!(fresnel_dielectric(0.2, 1.0 / 1.5), 1.0);
/// ```
#[inline]
pub fn fresnel_dielectric(cos_theta_i: f32, eta: f32) -> f32 {
    if cos_theta_i.is_nan() || !(eta > 0.0 && eta.is_finite()) {
        return 1.0;
    }
    if eta == 1.0 {
        // No boundary at all.
        return 0.0;
    }
    let cos_i = cos_theta_i.abs().min(1.0);
    // Snell: sin_t = sin_i / eta, so cos^2 t = 1 - (1 - cos^2 i) / eta^2.
    let cos_t = if eta > 1.0 {
        // = (1 - 1/eta)(1 + 1/eta) + (cos i / eta)^2: two non-negative
        // terms, so no cancellation near grazing incidence (1 - sin^2 t
        // lost every digit there: at eta 1 and cos i = 1e-5 it gave R = 1
        // instead of 0), and no overflow for huge eta.
        let inv = 1.0 / eta;
        ((1.0 - inv) * (1.0 + inv) + (cos_i * inv) * (cos_i * inv)).sqrt()
    } else {
        // Dividing by eta twice: eta^2 underflows to 0 below 1e-19, which
        // made 0 / 0 = NaN at normal incidence.
        let sin2_t = (1.0 - cos_i * cos_i) / eta / eta;
        if sin2_t > 1.0 {
            return 1.0;
        }
        (1.0 - sin2_t).sqrt()
    };
    let s_den = cos_i + eta * cos_t;
    let p_den = eta * cos_i + cos_t;
    if s_den <= 0.0 || p_den <= 0.0 {
        // Both cosines zero: only possible at grazing incidence with
        // eta = 1, where the boundary is invisible.
        return 0.0;
    }
    let r_s = (cos_i - eta * cos_t) / s_den;
    let r_p = (eta * cos_i - cos_t) / p_den;
    0.5 * (r_s * r_s + r_p * r_p)
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
        let d = incoming(40.0);
        let t = refract(d, n, 1.0 / 1.5).expect("entering glass never reflects totally");
        let sin_t = t.x;
        assert!((d.x - 1.5 * sin_t).abs() < 1e-6, "n1 sin1 = n2 sin2");
        assert!((t.length() - 1.0).abs() < 1e-6);
        // IOR 1: the ray goes on unchanged.
        assert!(refract(d, n, 1.0).is_some_and(|t| t.abs_diff_eq(d, 1e-6)));
    }

    #[test]
    fn total_internal_reflection_past_the_critical_angle() {
        let critical = (1.0f32 / 1.5).asin().to_degrees();
        assert!(refract(incoming(critical - 1.0), Vec3::Y, 1.5).is_some());
        assert!(refract(incoming(critical + 1.0), Vec3::Y, 1.5).is_none());
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

    #[test]
    fn fresnel_closed_forms_and_energy() {
        // Normal incidence: ((eta - 1) / (eta + 1))^2 from either side.
        for eta in [1.2f32, 1.5, 2.4] {
            let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
            assert!((fresnel_dielectric(1.0, eta) - r0).abs() < 1e-6);
            assert!((fresnel_dielectric(1.0, 1.0 / eta) - r0).abs() < 1e-6);
        }
        // Brewster's angle (tan theta = eta): the p part vanishes, so R is
        // half the s reflectance, computed here independently from angles.
        let eta = 1.5f32;
        let theta_b = eta.atan();
        let theta_t = (theta_b.sin() / eta).asin();
        let r_s = ((theta_b - theta_t).sin() / (theta_b + theta_t).sin()).powi(2);
        assert!((fresnel_dielectric(theta_b.cos(), eta) - 0.5 * r_s).abs() < 1e-5);
        // Power balance with the transmission coefficients: R + T = 1 where
        // T = (n_t cos_t / n_i cos_i) |t|^2 for each polarisation.
        for deg in [0.0f32, 20.0, 45.0, 70.0, 89.0] {
            let cos_i = deg.to_radians().cos();
            let cos_t = (1.0 - (1.0 - cos_i * cos_i) / (eta * eta)).sqrt();
            let t_s = 2.0 * cos_i / (cos_i + eta * cos_t);
            let t_p = 2.0 * cos_i / (eta * cos_i + cos_t);
            let t = 0.5 * eta * cos_t / cos_i * (t_s * t_s + t_p * t_p);
            assert!((fresnel_dielectric(cos_i, eta) + t - 1.0).abs() < 1e-5, "{deg} degrees");
        }
        // Grazing incidence reflects everything; the sign of cos is ignored.
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
        assert_eq!(fresnel_dielectric(-0.5, 1.5), fresnel_dielectric(0.5, 1.5));
    }

    #[test]
    fn fresnel_total_internal_reflection_and_degenerate_input() {
        let critical = (1.0f32 / 1.5).asin();
        let below = (critical - 0.01).cos();
        let beyond = (critical + 0.01).cos();
        assert!(fresnel_dielectric(below, 1.0 / 1.5) < 1.0);
        assert_eq!(fresnel_dielectric(beyond, 1.0 / 1.5), 1.0);
        assert_eq!(fresnel_dielectric(0.7, 1.0), 0.0);
        assert_eq!(fresnel_dielectric(0.0, 1.0), 0.0);
        for (c, e) in [
            (f32::NAN, 1.5),
            (0.5, f32::NAN),
            (0.5, 0.0),
            (0.5, -1.5),
            (0.5, f32::INFINITY),
        ] {
            assert_eq!(fresnel_dielectric(c, e), 1.0, "({c}, {e})");
        }
        assert!(fresnel_dielectric(7.0, 1.5).is_finite());
    }

    #[test]
    fn fresnel_at_0_and_90_degrees_against_closed_forms_from_either_side() {
        // 0 degrees: ((eta - 1) / (eta + 1))^2, the same from inside; 90
        // degrees: everything reflected. Closed forms in f64.
        for eta in [1.0001f32, 1.05, 1.5, 2.42, 10.0, 1e3, 1e6, 1e20] {
            let e = f64::from(eta);
            let r0 = ((e - 1.0) / (e + 1.0)).powi(2);
            for (side, got) in [
                ("outside", fresnel_dielectric(1.0, eta)),
                ("inside", fresnel_dielectric(1.0, 1.0 / eta)),
            ] {
                assert!(
                    (f64::from(got) - r0).abs() <= 2e-6 * r0.max(1e-3),
                    "eta {eta} {side}: {got} vs {r0}"
                );
            }
            assert_eq!(fresnel_dielectric(0.0, eta), 1.0, "eta {eta} at 90 degrees");
        }
    }

    #[test]
    fn fresnel_at_index_one_is_zero_at_every_angle() {
        // The boundary vanishes: nothing is reflected, up to grazing.
        for k in 0..=100_000 {
            let cos_i = k as f32 / 100_000.0;
            let r = fresnel_dielectric(cos_i, 1.0);
            assert!(r.abs() < 1e-6, "cos {cos_i}: R = {r}");
        }
    }

    #[test]
    fn fresnel_stays_in_0_1_for_extreme_indices() {
        for eta in [
            1e-30f32,
            1e-20,
            1e-6,
            1e-3,
            1e3,
            1e6,
            1e20,
            1e30,
            f32::MAX,
            f32::MIN_POSITIVE,
        ] {
            for k in 0..=1000 {
                let cos_i = k as f32 / 1000.0;
                let r = fresnel_dielectric(cos_i, eta);
                assert!((0.0..=1.0).contains(&r), "eta {eta}, cos {cos_i}: R = {r}");
            }
        }
    }
}
