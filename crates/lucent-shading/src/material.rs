//! The material parameter set shared by every integrator.

use crate::Texture;
use lucent_geom::{Vec2, Vec3};
use std::sync::Arc;

/// Surface parameters in the report's terms (an OBJ/MTL-like set).
///
/// The Whitted integrator reads them as the report does: local Phong colour
/// `Ia Ka + Ip Kd (L.N) + Ip Ks (R.V)^n`, plus `kr` times the mirrored ray
/// and `kt` times the refracted ray. The report used Ks as the mirror weight
/// too; Lucent keeps the highlight (`ks`) and the mirror (`kr`) apart so a
/// glossy highlight does not imply a mirror. Colours are linear RGB.
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
