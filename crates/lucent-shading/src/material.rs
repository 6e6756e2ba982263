//! The material parameter set shared by every integrator: the report's
//! Phong-style terms, and optionally glTF's metallic-roughness model with
//! its texture maps, normal map, emission map and alpha.

use crate::{Bsdf, Texture};
use lucent_geom::{Vec2, Vec3};
use std::sync::Arc;

/// How a material's alpha (base colour alpha times `Material::alpha`) is
/// used.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored: the surface is opaque (glTF's default).
    #[default]
    Opaque,
    /// An alpha test: where alpha is below the cutoff the surface is not
    /// there at all, for camera, bounce and shadow rays alike (glTF's
    /// `MASK` with `alphaCutoff`, 0.5 by default).
    Mask {
        /// Alpha below this is cut out.
        cutoff: f32,
    },
}

/// glTF's metallic-roughness parameters (specification, section 3.9 and
/// appendix B). The base colour texture is [`Material::diffuse_map`] and
/// the index of refraction is [`Material::ior`].
#[derive(Clone, Debug, PartialEq)]
pub struct MetallicRoughness {
    /// Base colour factor (linear RGB).
    pub base_color: Vec3,
    /// Metalness factor, 0 (dielectric) to 1 (metal).
    pub metallic: f32,
    /// Perceptual roughness factor, 0 (smooth) to 1; GGX `alpha` is its
    /// square.
    pub roughness: f32,
    /// Texture whose blue channel multiplies `metallic` (linear, not sRGB;
    /// glTF packs metallic and roughness into one texture, which is then
    /// both this and `roughness_map`).
    pub metallic_map: Option<Arc<Texture>>,
    /// Texture whose green channel multiplies `roughness` (linear).
    pub roughness_map: Option<Arc<Texture>>,
    /// `KHR_materials_transmission`: the share of the dielectric that
    /// transmits, 0 to 1.
    pub transmission: f32,
}

impl Default for MetallicRoughness {
    /// glTF's defaults: white, fully metallic, fully rough.
    fn default() -> Self {
        Self {
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness: 1.0,
            metallic_map: None,
            roughness_map: None,
            transmission: 0.0,
        }
    }
}

impl MetallicRoughness {
    /// The report's terms that approximate this material for the Whitted
    /// integrator, as `(ka = kd, ks, shininess, kr, kt)`:
    ///
    /// | term | from |
    /// | --- | --- |
    /// | `ka`, `kd` | `base (1 - metallic) (1 - transmission)` |
    /// | `ks` | `F0 = mix(0.04-ish dielectric F0, base, metallic)` |
    /// | `shininess` | `2 / alpha^2 - 2` (the Phong exponent whose lobe is as wide as GGX's), 1 to 10 000 |
    /// | `kr` | `F0` when `roughness < 0.25` (a sharp mirror), else 0 |
    /// | `kt` | `(1 - metallic) transmission` |
    ///
    /// Texture maps other than the base colour, and Fresnel's rise at
    /// grazing angles, are not represented.
    pub fn phong_approximation(&self, ior: f32) -> (Vec3, Vec3, f32, Vec3, Vec3) {
        let unit = |x: f32| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
        let (m, r, t) = (unit(self.metallic), unit(self.roughness), unit(self.transmission));
        let base = self.base_color.max(Vec3::ZERO).min(Vec3::ONE);
        let f0 = Vec3::splat(crate::bsdf::dielectric_f0(ior)).lerp(base, m);
        let kd = base * (1.0 - m) * (1.0 - t);
        let alpha = (r * r).max(1e-2);
        let shininess = (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 1e4);
        let kr = if r < 0.25 { f0 } else { Vec3::ZERO };
        (kd, f0, shininess, kr, Vec3::splat((1.0 - m) * t))
    }
}

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
    /// Texture multiplying Ka and Kd (MTL `map_Kd`), or the base colour of
    /// a metallic-roughness material (sRGB decoded; its alpha channel is
    /// the base alpha).
    pub diffuse_map: Option<Arc<Texture>>,
    /// glTF's metallic-roughness model: when set, the path tracer uses
    /// [`Bsdf::metallic_roughness`] and the report's terms above hold the
    /// Whitted approximation ([`MetallicRoughness::phong_approximation`]).
    pub pbr: Option<MetallicRoughness>,
    /// Tangent-space normal map (linear RGB, `n = 2 c - 1`, green along
    /// the bitangent, OpenGL and glTF's convention).
    pub normal_map: Option<Arc<Texture>>,
    /// Scale of the normal map's x and y (glTF's `normalTexture.scale`).
    pub normal_scale: f32,
    /// Texture multiplying `emission` (sRGB decoded).
    pub emission_map: Option<Arc<Texture>>,
    /// Opacity factor multiplying the base colour texture's alpha (glTF's
    /// base colour factor alpha); only [`AlphaMode::Mask`] uses it.
    pub alpha: f32,
    /// How alpha is used.
    pub alpha_mode: AlphaMode,
    /// glTF's `doubleSided`: the surface emits from both sides (otherwise
    /// only from the side its normals face). Both sides of every surface
    /// are shaded either way.
    pub double_sided: bool,
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
            pbr: None,
            normal_map: None,
            normal_scale: 1.0,
            emission_map: None,
            alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            double_sided: false,
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
        if ks == Vec3::ZERO && kr == Vec3::ZERO && kt == Vec3::ZERO {
            // Diffuse alone (a textured one builds this at every hit).
            return Bsdf::diffuse_only(kd * unit(tint) * scale);
        }
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

    /// Whether anything about the surface varies with texture coordinates.
    pub fn is_textured(&self) -> bool {
        self.diffuse_map.is_some()
            || self.normal_map.is_some()
            || self.emission_map.is_some()
            || self
                .pbr
                .as_ref()
                .is_some_and(|p| p.metallic_map.is_some() || p.roughness_map.is_some())
    }

    /// Whether some hit on this material may be cut out by its alpha test.
    pub fn is_masked(&self) -> bool {
        matches!(self.alpha_mode, AlphaMode::Mask { .. })
    }

    /// Whether the alpha test removes the surface at `uv`: alpha (the
    /// factor times the base colour texture's alpha) below the cutoff.
    #[inline]
    pub fn cut_out(&self, uv: Option<Vec2>) -> bool {
        let AlphaMode::Mask { cutoff } = self.alpha_mode else {
            return false;
        };
        let texture_alpha = match (&self.diffuse_map, uv) {
            (Some(tex), Some(uv)) => tex.sample_alpha(uv),
            _ => 1.0,
        };
        // NaN alpha keeps the surface.
        self.alpha * texture_alpha < cutoff
    }

    /// Emitted radiance at `uv`: `emission` times the emission map.
    #[inline]
    pub fn emission_at(&self, uv: Option<Vec2>) -> Vec3 {
        match (&self.emission_map, uv) {
            (Some(tex), Some(uv)) => self.emission * tex.sample_bilinear(uv),
            _ => self.emission,
        }
    }

    /// The tangent-space normal at `uv` from the normal map (scaled in x
    /// and y by `normal_scale`, normalised), or `None` without a map, UVs
    /// or a usable value.
    #[inline]
    pub fn tangent_space_normal(&self, uv: Option<Vec2>) -> Option<Vec3> {
        let (tex, uv) = (self.normal_map.as_ref()?, uv?);
        let c = tex.sample_bilinear(uv) * 2.0 - Vec3::ONE;
        let n = Vec3::new(c.x * self.normal_scale, c.y * self.normal_scale, c.z);
        n.try_normalize()
    }

    /// The BSDF at a hit with texture coordinates `uv` and vertex colour
    /// `color`: [`Material::bsdf`] with the diffuse texture and vertex
    /// colour as tint, or for a metallic-roughness material
    /// [`Bsdf::metallic_roughness`] with the base colour factor times the
    /// texture and vertex colour, metallic times the blue channel of its
    /// texture and roughness times the green channel of its own.
    #[inline]
    pub fn bsdf_at(&self, uv: Option<Vec2>, color: Option<Vec3>) -> Bsdf {
        let mut tint = self.diffuse_tint(uv);
        if let Some(c) = color {
            tint *= c;
        }
        match &self.pbr {
            None => self.bsdf(tint),
            Some(p) => {
                let (mut metallic, mut roughness) = (p.metallic, p.roughness);
                if let Some(uv) = uv {
                    match (&p.metallic_map, &p.roughness_map) {
                        (Some(m), Some(r)) if Arc::ptr_eq(m, r) => {
                            let c = m.sample_bilinear(uv);
                            metallic *= c.z;
                            roughness *= c.y;
                        }
                        (m, r) => {
                            if let Some(m) = m {
                                metallic *= m.sample_bilinear(uv).z;
                            }
                            if let Some(r) = r {
                                roughness *= r.sample_bilinear(uv).y;
                            }
                        }
                    }
                }
                Bsdf::metallic_roughness(p.base_color * tint, metallic, roughness, p.transmission, self.ior)
            }
        }
    }

    /// A metallic-roughness material with its Whitted approximation filled
    /// in (see [`MetallicRoughness::phong_approximation`]); `ior` 1.5 and
    /// everything else at its default.
    ///
    /// ```
    /// use lucent_shading::{Material, MetallicRoughness, Vec3};
    /// let m = Material::metallic_roughness(MetallicRoughness {
    ///     base_color: Vec3::new(0.8, 0.1, 0.1),
    ///     metallic: 0.0,
    ///     roughness: 0.5,
    ///     ..MetallicRoughness::default()
    /// });
    /// assert_eq!(m.kd, Vec3::new(0.8, 0.1, 0.1));
    /// assert!(m.pbr.is_some() && m.kr == Vec3::ZERO);
    /// ```
    pub fn metallic_roughness(params: MetallicRoughness) -> Material {
        Material::metallic_roughness_with_ior(params, 1.5)
    }

    /// [`Material::metallic_roughness`] for a dielectric of index `ior`
    /// (glTF's `KHR_materials_ior`): the Whitted approximation uses it too.
    pub fn metallic_roughness_with_ior(params: MetallicRoughness, ior: f32) -> Material {
        let (kd, ks, shininess, kr, kt) = params.phong_approximation(ior);
        Material {
            ka: kd,
            kd,
            ks,
            shininess,
            kr,
            kt,
            ior,
            roughness: params.roughness,
            pbr: Some(params),
            ..Material::default()
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

    #[test]
    fn alpha_test_emission_map_and_normal_map() {
        let tex = |rgb: Vec3, alpha: f32| {
            Texture::new(1, 1, vec![rgb])
                .and_then(|t| t.with_alpha(vec![alpha]))
                .map(Arc::new)
                .ok()
        };
        let mut m = Material {
            diffuse_map: tex(Vec3::ONE, 0.4),
            alpha_mode: AlphaMode::Mask { cutoff: 0.5 },
            ..Material::default()
        };
        let uv = Some(Vec2::splat(0.5));
        assert!(m.is_masked() && m.cut_out(uv) && !m.cut_out(None));
        m.alpha_mode = AlphaMode::Opaque;
        assert!(!m.cut_out(uv));
        m.alpha_mode = AlphaMode::Mask { cutoff: 0.3 };
        assert!(!m.cut_out(uv));
        // Emission times its map.
        let lamp = Material {
            emission: Vec3::splat(2.0),
            emission_map: tex(Vec3::new(1.0, 0.5, 0.0), 1.0),
            ..Material::default()
        };
        assert_eq!(lamp.emission_at(uv), Vec3::new(2.0, 1.0, 0.0));
        assert_eq!(lamp.emission_at(None), Vec3::splat(2.0));
        // A flat normal map texel (0.5, 0.5, 1) is the unperturbed normal;
        // the scale tilts x and y.
        let bumpy = Material {
            normal_map: tex(Vec3::new(1.0, 0.5, 1.0), 1.0),
            normal_scale: 0.5,
            ..Material::default()
        };
        let n = bumpy.tangent_space_normal(uv).unwrap_or(Vec3::ZERO);
        assert!(n.abs_diff_eq(Vec3::new(0.5, 0.0, 1.0).normalize(), 1e-6), "{n}");
        assert!(bumpy.is_textured() && !Material::default().is_textured());
    }

    #[test]
    fn metallic_roughness_reads_blue_and_green_and_maps_to_phong() {
        let mr = Texture::new(1, 1, vec![Vec3::new(0.0, 0.5, 0.0)]).map(Arc::new).ok();
        let m = Material::metallic_roughness(MetallicRoughness {
            base_color: Vec3::splat(0.5),
            metallic: 1.0,
            roughness: 1.0,
            metallic_map: mr.clone(),
            roughness_map: mr,
            transmission: 0.0,
        });
        // Blue 0 makes it a dielectric, green 0.5 halves the roughness.
        let textured = m.bsdf_at(Some(Vec2::ZERO), None);
        let expected = Bsdf::metallic_roughness(Vec3::splat(0.5), 0.0, 0.5, 0.0, 1.5);
        assert_eq!(textured, expected);
        // Without UVs the factors apply as they are: a rough metal, whose
        // Whitted terms have no diffuse and a coloured highlight.
        assert_eq!(
            m.bsdf_at(None, None),
            Bsdf::metallic_roughness(Vec3::splat(0.5), 1.0, 1.0, 0.0, 1.5)
        );
        assert_eq!((m.kd, m.ks, m.kr), (Vec3::ZERO, Vec3::splat(0.5), Vec3::ZERO));
        let smooth = MetallicRoughness {
            roughness: 0.1,
            metallic: 0.0,
            ..MetallicRoughness::default()
        };
        let (kd, ks, n, kr, _) = smooth.phong_approximation(1.5);
        assert!(kd == Vec3::ONE && (ks.x - 0.04).abs() < 1e-6 && kr == ks && n > 1000.0);
    }
}
