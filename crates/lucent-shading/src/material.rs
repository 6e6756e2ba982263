//! The material parameter set shared by every integrator.

use crate::{Bsdf, Texture};
use lucent_geom::{Vec2, Vec3};
use std::sync::Arc;

/// Surface parameters in the report's terms (an OBJ/MTL-like set).
///
/// The Whitted integrator reads them as the report does: local Phong colour
/// `Ia Ka + Ip Kd (L.N) + Ip Ks (R.V)^n`, plus `kr` times the mirrored ray
/// and `kt` times the refracted ray. The report used Ks as the mirror weight
/// too; Lucent keeps the highlight (`ks`) and the mirror (`kr`) apart so a
/// glossy highlight does not imply a mirror. Colours are linear RGB.
///
/// The path tracer reads the same fields through [`Material::bsdf`].
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Ambient reflectance Ka.
    pub ka: Vec3,
    /// Diffuse reflectance Kd.
    pub kd: Vec3,
    /// Specular (highlight) reflectance Ks.
    pub ks: Vec3,
    /// Phong exponent n (MTL `Ns`).
    pub shininess: f32,
    /// Weight of the mirror-reflected ray (0 = no reflection ray).
    pub kr: Vec3,
    /// Weight of the transmitted ray; also how much light a shadow ray keeps
    /// when it crosses this surface (0 = opaque, 1 = clear).
    pub kt: Vec3,
    /// Index of refraction of the inside relative to the outside.
    pub ior: f32,
    /// Roughness of the mirror (`kr`) lobe for the path tracer, 0 (smooth)
    /// to 1; the GGX `alpha` is `roughness^2`. Whitted ignores it.
    pub roughness: f32,
    /// Emitted radiance (MTL `Ke`), added unshadowed.
    pub emission: Vec3,
    /// Texture multiplying Ka and Kd (MTL `map_Kd`).
    pub diffuse_map: Option<Arc<Texture>>,
}

impl Default for Material {
    /// A matte mid-grey: Ka = Kd = 0.8, no highlight, opaque.
    fn default() -> Self {
        Self {
            ka: Vec3::splat(0.8),
            kd: Vec3::splat(0.8),
            ks: Vec3::ZERO,
            shininess: 1.0,
            kr: Vec3::ZERO,
            kt: Vec3::ZERO,
            ior: 1.0,
            roughness: 0.0,
            emission: Vec3::ZERO,
            diffuse_map: None,
        }
    }
}

impl Material {
    /// Whether shadow and refraction rays pass through (`kt` above zero).
    pub fn is_transmissive(&self) -> bool {
        self.kt.max_element() > 0.0
    }

    /// Whether the surface spawns mirror rays.
    pub fn is_reflective(&self) -> bool {
        self.kr.max_element() > 0.0
    }

    /// The physically based BSDF for this material; `tint` is
    /// [`diffuse_tint`](Material::diffuse_tint) at the hit (texture colour,
    /// or white).
    ///
    /// | fields | lobe |
    /// | --- | --- |
    /// | `kd` | Lambertian, albedo `kd * tint` |
    /// | `ks`, `shininess` n | normalised Phong lobe `ks (n+2)/(2 pi) cos^n alpha` around the mirror direction |
    /// | `kr`, `roughness` 0 | smooth mirror of reflectance `kr` (Fresnel 1) |
    /// | `kr`, `roughness` r > 0 | GGX conductor, `alpha = r^2`, reflectance `kr` (Fresnel 1) |
    /// | `kt`, `ior` | smooth dielectric, `eta = ior` (inside over outside), weighted by `kt` |
    /// | `ka`, `emission` | not a BSDF: ambient is ignored, emission is the integrator's |
    ///
    /// Each of `kd`, `ks`, `kr`, `kt` is first clamped to `[0, 1]` per
    /// channel (NaN reads as 0) and `tint` too. When `kd + ks + kr + kt`
    /// exceeds 1 in some channel, all four are divided by that largest
    /// channel sum, computed without the tint so the split between lobes is
    /// the same across a texture. Every lobe reflects (or transmits) at most
    /// its weight, so the mixture never creates energy. `roughness` only
    /// shapes the `kr` lobe; transmission stays smooth.
    ///
    /// ```
    /// use lucent_shading::{Bsdf, Material, Vec3};
    /// let glass = Material { kd: Vec3::ZERO, kt: Vec3::ONE, ior: 1.5, ..Material::default() };
    /// assert_eq!(glass.bsdf(Vec3::ONE), Bsdf::dielectric(1.5));
    /// let over = Material { kd: Vec3::splat(0.8), kr: Vec3::splat(0.8), ..Material::default() };
    /// let half = Material { kd: Vec3::splat(0.5), kr: Vec3::splat(0.5), ..Material::default() };
    /// assert_eq!(over.bsdf(Vec3::ONE), half.bsdf(Vec3::ONE));
    /// ```
    pub fn bsdf(&self, tint: Vec3) -> Bsdf {
        let unit = |v: Vec3| v.max(Vec3::ZERO).min(Vec3::ONE);
        let (kd, ks, kr, kt) = (unit(self.kd), unit(self.ks), unit(self.kr), unit(self.kt));
        let most = (kd + ks + kr + kt).max_element();
        let scale = if most > 1.0 { 1.0 / most } else { 1.0 };
        let roughness = if self.roughness.is_nan() {
            0.0
        } else {
            self.roughness.clamp(0.0, 1.0)
        };
        Bsdf::mix(
            kd * unit(tint) * scale,
            ks * scale,
            self.shininess,
            kr * scale,
            roughness * roughness,
            kt * scale,
            self.ior,
        )
    }

    /// The texture colour at `uv`, or white without a texture (or UVs).
    pub fn diffuse_tint(&self, uv: Option<Vec2>) -> Vec3 {
        match (&self.diffuse_map, uv) {
            (Some(tex), Some(uv)) => tex.sample_bilinear(uv),
            _ => Vec3::ONE,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tint_needs_both_texture_and_uv() {
        let tex = Texture::new(1, 1, vec![Vec3::new(0.5, 0.25, 1.0)]).map(Arc::new).ok();
        let m = Material {
            diffuse_map: tex,
            ..Material::default()
        };
        assert_eq!(m.diffuse_tint(None), Vec3::ONE);
        assert_eq!(m.diffuse_tint(Some(Vec2::ZERO)), Vec3::new(0.5, 0.25, 1.0));
        assert_eq!(Material::default().diffuse_tint(Some(Vec2::ZERO)), Vec3::ONE);
        assert!(!m.is_transmissive() && !m.is_reflective());
    }
}
