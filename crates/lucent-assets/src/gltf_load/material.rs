//! glTF materials (metallic-roughness, normal, emissive, alpha, double
//! sided, `KHR_materials_ior`, `KHR_materials_transmission`,
//! `KHR_materials_emissive_strength`) and their textures (images decoded
//! once per colour space; samplers' wrap modes and `KHR_texture_transform`
//! applied per use). `occlusionTexture` is read past: ambient occlusion is
//! a rasteriser's stand-in for the shadowing a path tracer computes.

use super::data::{Buffers, read_uri};
use crate::{AssetSource, ColorSpace, texture_from_bytes_as};
use gltf::texture::WrappingMode;
use lucent_geom::{Vec2, Vec3};
use lucent_shading::{AlphaMode, Material, MetallicRoughness, Texture, WrapMode};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// Decoded images and the textures made from them, shared across
/// materials.
pub(super) struct Textures<'a> {
    pub(super) buffers: &'a Buffers,
    pub(super) source: &'a dyn AssetSource,
    pub(super) path: &'a Path,
    /// Skip decoding: every texture is a 1x1 grey (for load timings).
    pub(super) skip_images: bool,
    images: HashMap<(usize, ColorSpace), Arc<Texture>>,
    uses: HashMap<(usize, ColorSpace, [u32; 5], u32), Arc<Texture>>,
}

impl<'a> Textures<'a> {
    pub(super) fn new(buffers: &'a Buffers, source: &'a dyn AssetSource, path: &'a Path, skip_images: bool) -> Self {
        Textures {
            buffers,
            source,
            path,
            skip_images,
            images: HashMap::new(),
            uses: HashMap::new(),
        }
    }

    fn image(&mut self, image: &gltf::Image<'_>, space: ColorSpace) -> Result<Arc<Texture>, String> {
        let key = (image.index(), space);
        if let Some(t) = self.images.get(&key) {
            return Ok(t.clone());
        }
        let ptr = format!("/images/{}", image.index());
        let t = if self.skip_images {
            Texture::constant(Vec3::splat(0.5))
        } else {
            let (bytes, label) = match image.source() {
                gltf::image::Source::View { view, .. } => (
                    self.buffers
                        .view(&view)
                        .map_err(|e| format!("{ptr}/bufferView: {e}"))?
                        .to_vec(),
                    format!("{}{ptr}", self.path.display()),
                ),
                gltf::image::Source::Uri { uri, .. } => (
                    read_uri(uri, self.source, self.path).map_err(|e| format!("{ptr}/uri: {e}"))?,
                    if uri.starts_with("data:") {
                        format!("{}{ptr}", self.path.display())
                    } else {
                        uri.to_owned()
                    },
                ),
            };
            texture_from_bytes_as(&bytes, Path::new(&label), space)
                .map_err(|e| format!("{ptr}: {}", crate::image_io::texture_problem(&e)))?
        };
        let t = Arc::new(t);
        self.images.insert(key, t.clone());
        Ok(t)
    }

    /// The texture a texture reference reads, with its sampler's wrap
    /// modes and its transform; `ptr` points at the reference.
    fn texture(
        &mut self,
        tex: &gltf::Texture<'_>,
        transform: Option<gltf::texture::TextureTransform<'_>>,
        space: ColorSpace,
        ptr: &str,
    ) -> Result<Arc<Texture>, String> {
        let (scale, rotation, offset) = match &transform {
            Some(t) => (Vec2::from(t.scale()), t.rotation(), Vec2::from(t.offset())),
            None => (Vec2::ONE, 0.0, Vec2::ZERO),
        };
        let sampler = tex.sampler();
        let wrap = |w: WrappingMode| match w {
            WrappingMode::ClampToEdge => WrapMode::Clamp,
            WrappingMode::MirroredRepeat => WrapMode::MirroredRepeat,
            WrappingMode::Repeat => WrapMode::Repeat,
        };
        let (ws, wt) = (wrap(sampler.wrap_s()), wrap(sampler.wrap_t()));
        let code = |w: WrapMode| w as u32;
        let key = (
            tex.index(),
            space,
            [scale.x, scale.y, rotation, offset.x, offset.y].map(f32::to_bits),
            code(ws) * 4 + code(wt),
        );
        if let Some(t) = self.uses.get(&key) {
            return Ok(t.clone());
        }
        let base = self
            .image(&tex.source(), space)
            .map_err(|e| format!("{ptr}: texture {}: {e}", tex.index()))?;
        let mut t = (*base).clone();
        t.wrap = ws;
        t.wrap_v = wt;
        if transform.is_some() {
            // glTF's transform works on v-down coordinates: offset `o`,
            // rotation `r` (clockwise there), scale `s`. Conjugated by the
            // flip `v -> 1 - v` it is the same rotation counter-clockwise,
            // the same scale, and this offset.
            let (sin, cos) = rotation.sin_cos();
            t.uv_scale = scale;
            t.uv_rotation = rotation;
            t.uv_offset = Vec2::new(offset.x + sin * scale.y, 1.0 - offset.y - cos * scale.y);
        }
        let t = if t == *base { base } else { Arc::new(t) };
        self.uses.insert(key, t.clone());
        Ok(t)
    }
}

/// Which `TEXCOORD_n` the material's textures read (the first one found;
/// a material whose textures disagree gets a warning and uses the first).
pub(super) fn uv_set(m: &gltf::Material<'_>, warnings: &mut Vec<String>) -> u32 {
    let pbr = m.pbr_metallic_roughness();
    let info_set = |i: &gltf::texture::Info<'_>| {
        i.texture_transform()
            .and_then(|t| t.tex_coord())
            .unwrap_or(i.tex_coord())
    };
    let mut sets: Vec<u32> = Vec::new();
    sets.extend(pbr.base_color_texture().map(|i| info_set(&i)));
    sets.extend(pbr.metallic_roughness_texture().map(|i| info_set(&i)));
    sets.extend(m.normal_texture().map(|n| n.tex_coord()));
    sets.extend(m.emissive_texture().map(|i| info_set(&i)));
    let first = sets.first().copied().unwrap_or(0);
    if sets.iter().any(|&s| s != first) {
        warnings.push(format!(
            "/materials/{}: its textures read different TEXCOORD sets; all read TEXCOORD_{first}",
            m.index().unwrap_or(0)
        ));
    }
    first
}

/// The Lucent material for a glTF material (`ptr` is its JSON pointer).
pub(super) fn convert(
    m: &gltf::Material<'_>,
    ptr: &str,
    textures: &mut Textures<'_>,
    warnings: &mut Vec<String>,
) -> Result<Material, String> {
    let pbr = m.pbr_metallic_roughness();
    let pp = format!("{ptr}/pbrMetallicRoughness");
    let mut info = |i: Option<gltf::texture::Info<'_>>, space, at: String| -> Result<Option<Arc<Texture>>, String> {
        i.map(|i| textures.texture(&i.texture(), i.texture_transform(), space, &at))
            .transpose()
    };
    let base_map = info(
        pbr.base_color_texture(),
        ColorSpace::Srgb,
        format!("{pp}/baseColorTexture"),
    )?;
    let mr_map = info(
        pbr.metallic_roughness_texture(),
        ColorSpace::Linear,
        format!("{pp}/metallicRoughnessTexture"),
    )?;
    let emission_map = info(m.emissive_texture(), ColorSpace::Srgb, format!("{ptr}/emissiveTexture"))?;
    let normal_map = m
        .normal_texture()
        .map(|n| textures.texture(&n.texture(), None, ColorSpace::Linear, &format!("{ptr}/normalTexture")))
        .transpose()?;
    let transmission = m.transmission();
    if transmission
        .as_ref()
        .is_some_and(|t| t.transmission_texture().is_some())
    {
        warnings.push(format!(
            "{ptr}/extensions/KHR_materials_transmission/transmissionTexture: not supported; the factor applies alone"
        ));
    }
    let [r, g, b, a] = pbr.base_color_factor();
    let ior = m.ior().filter(|x| x.is_finite() && *x >= 1.0).unwrap_or(1.5);
    let params = MetallicRoughness {
        base_color: Vec3::new(r, g, b),
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        metallic_map: mr_map.clone(),
        roughness_map: mr_map,
        transmission: transmission.map_or(0.0, |t| t.transmission_factor()),
    };
    let alpha_mode = match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
        gltf::material::AlphaMode::Mask => AlphaMode::Mask {
            cutoff: m.alpha_cutoff().unwrap_or(0.5),
        },
        gltf::material::AlphaMode::Blend => {
            let name = m.name().map_or_else(String::new, |n| format!(" ('{n}')"));
            warnings.push(format!(
                "{ptr}/alphaMode: material{name} is BLEND, approximated by an alpha test at 0.5 (no partial transparency)"
            ));
            AlphaMode::Mask { cutoff: 0.5 }
        }
    };
    let strength = m.emissive_strength().unwrap_or(1.0);
    Ok(Material {
        emission: Vec3::from(m.emissive_factor()) * strength,
        diffuse_map: base_map,
        normal_map,
        normal_scale: m.normal_texture().map_or(1.0, |n| n.scale()),
        emission_map,
        alpha: a,
        alpha_mode,
        double_sided: m.double_sided(),
        ..Material::metallic_roughness_with_ior(params, ior)
    })
}
