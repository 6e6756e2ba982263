//! The report's Phong model (S9), split so it can run per vertex or per pixel.
//!
//! `I = Ia Ka + Ip Kd (L.N) + Ip Ks (R.V)^n` with `R = 2N(N.L) - L`.
//! [`phong_terms`] returns the light-dependent factors `Ip (L.N)` and
//! `Ip (R.V)^n` without the material colours, so Gouraud shading (S10) can
//! evaluate them at the three vertices, interpolate, and still apply a
//! texture per pixel; [`combine`] then applies Ka, Kd and Ks.

use lucent_geom::Vec3;

/// Light-dependent Phong factors for one light (or summed over several).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhongTerms {
    /// `Ip * max(L.N, 0)`.
    pub diffuse: Vec3,
    /// `Ip * max(R.V, 0)^n`, zero when the light is behind the surface.
    pub specular: Vec3,
}

impl std::ops::Add for PhongTerms {
    type Output = PhongTerms;
    fn add(self, o: PhongTerms) -> PhongTerms {
        PhongTerms {
            diffuse: self.diffuse + o.diffuse,
            specular: self.specular + o.specular,
        }
    }
}

impl std::ops::Mul<f32> for PhongTerms {
    type Output = PhongTerms;
    fn mul(self, s: f32) -> PhongTerms {
        PhongTerms {
            diffuse: self.diffuse * s,
            specular: self.specular * s,
        }
    }
}

impl std::ops::Mul<Vec3> for PhongTerms {
    type Output = PhongTerms;
    fn mul(self, s: Vec3) -> PhongTerms {
        PhongTerms {
            diffuse: self.diffuse * s,
            specular: self.specular * s,
        }
    }
}

/// Phong factors for unit normal `n`, unit direction to the light `l`, unit
/// direction to the viewer `v`, exponent `shininess` and light intensity
/// `ip`. A light below the surface (`L.N <= 0`) contributes nothing.
#[inline]
pub fn phong_terms(n: Vec3, l: Vec3, v: Vec3, shininess: f32, ip: Vec3) -> PhongTerms {
    let n_dot_l = n.dot(l);
    if n_dot_l.is_nan() || n_dot_l <= 0.0 {
        return PhongTerms::default();
    }
    let r = 2.0 * n_dot_l * n - l;
    let r_dot_v = r.dot(v).max(0.0);
    // 0^0 would be 1; a zero exponent means a flat highlight only where R.V > 0.
    let spec = if r_dot_v > 0.0 {
        r_dot_v.powf(shininess.max(0.0))
    } else {
        0.0
    };
    PhongTerms {
        diffuse: ip * n_dot_l,
        specular: ip * spec,
    }
}

/// The local colour `Ia Ka + Kd * diffuse + Ks * specular` from (possibly
/// interpolated) terms. `ambient` is `Ia`, already scaled by any shadowing.
#[inline]
pub fn combine(terms: PhongTerms, ambient: Vec3, ka: Vec3, kd: Vec3, ks: Vec3) -> Vec3 {
    ambient * ka + kd * terms.diffuse + ks * terms.specular
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_report_formula() {
        // N tilted 30 degrees from the light; viewer along the mirror direction.
        let l = Vec3::Y;
        let n = Vec3::new(0.5, 3f32.sqrt() / 2.0, 0.0);
        let r = 2.0 * n.dot(l) * n - l;
        let t = phong_terms(n, l, r, 10.0, Vec3::splat(2.0));
        assert!((t.diffuse.x - 2.0 * 3f32.sqrt() / 2.0).abs() < 1e-6);
        assert!((t.specular.x - 2.0).abs() < 1e-5, "viewer on R sees the full highlight");
        // Viewer straight above: R.V = cos(60) = 0.5.
        let t = phong_terms(n, l, Vec3::Y, 3.0, Vec3::ONE);
        assert!((t.specular.x - 0.125).abs() < 1e-6, "{}", t.specular.x);
        let c = combine(t, Vec3::splat(0.1), Vec3::ONE, Vec3::splat(0.5), Vec3::splat(0.4));
        assert!((c.x - (0.1 + 0.5 * 3f32.sqrt() / 2.0 + 0.4 * 0.125)).abs() < 1e-6);
    }

    #[test]
    fn light_below_the_surface_gives_nothing() {
        let t = phong_terms(Vec3::Y, -Vec3::Y, Vec3::Y, 5.0, Vec3::ONE);
        assert_eq!(t, PhongTerms::default());
        let t = phong_terms(Vec3::ZERO, Vec3::Y, Vec3::Y, 5.0, Vec3::ONE);
        assert_eq!(t, PhongTerms::default());
    }
}
