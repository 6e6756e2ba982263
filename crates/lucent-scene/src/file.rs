//! The TOML scene file: its schema (serde types) and parsing with precise
//! error locations. No IO here: callers pass the text and the path it came
//! from (for messages and for resolving relative mesh and texture paths).
//!
//! The format is documented in `docs/scene-format.md`; every table and key is
//! optional except what an object needs to draw something.

use lucent_geom::Named;
use lucent_geom::{Affine3A, Quat, Vec3};
use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// A parse or validation error in a scene file, located by line and column
/// (both from 1). Displays as `path:line:column: message`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneFileError {
    /// The scene file.
    pub path: PathBuf,
    /// Line number, from 1.
    pub line: usize,
    /// Column number in characters, from 1.
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for SceneFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}: {}",
            self.path.display(),
            self.line,
            self.column,
            self.message
        )
    }
}

impl std::error::Error for SceneFileError {}

/// A parsed and validated scene file.
#[derive(Clone, Debug)]
pub struct SceneFile {
    /// Where the text came from; relative paths inside resolve against its
    /// directory.
    pub path: PathBuf,
    /// The scene description.
    pub desc: SceneDesc,
    text: String,
}

impl SceneFile {
    /// Parses and validates scene text. Every error names `path`, the line
    /// and the column of the offending value.
    pub fn parse(path: &Path, text: &str) -> Result<SceneFile, SceneFileError> {
        let file = |desc| SceneFile {
            path: path.to_owned(),
            desc,
            text: text.to_owned(),
        };
        let desc: SceneDesc = toml::from_str(text).map_err(|e| {
            let span = e.span().unwrap_or(0..0);
            // toml's messages can span lines; keep errors on one line.
            let message = e.message().trim().replace('\n', " ");
            file(SceneDesc::default()).error_at(span, message)
        })?;
        let file = file(desc);
        file.validate()?;
        Ok(file)
    }

    /// An error located at byte range `span` of the text.
    pub fn error_at(&self, span: Range<usize>, message: impl Into<String>) -> SceneFileError {
        let (line, column) = line_column(&self.text, span.start);
        SceneFileError {
            path: self.path.clone(),
            line,
            column,
            message: message.into(),
        }
    }

    /// The directory relative paths in the file are resolved against.
    pub fn base_dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new(""))
    }

    /// `relative` resolved against [`SceneFile::base_dir`].
    pub fn resolve(&self, relative: &str) -> PathBuf {
        self.base_dir().join(relative)
    }

    fn validate(&self) -> Result<(), SceneFileError> {
        let d = &self.desc;
        if let Some(map) = &d.environment.map {
            let ext = Path::new(map.get_ref())
                .extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase);
            if !matches!(ext.as_deref(), Some("hdr" | "exr")) {
                return Err(self.error_at(
                    map.span(),
                    format!("environment map '{}' is neither .hdr nor .exr", map.get_ref()),
                ));
            }
        }
        for obj in &d.objects {
            let span = obj.span();
            let o = obj.get_ref();
            match (&o.mesh, &o.shape) {
                (Some(_), Some(_)) => return Err(self.error_at(span, "an object takes `mesh` or `shape`, not both")),
                (None, None) => return Err(self.error_at(span, "an object needs a `mesh` file or a `shape`")),
                (Some(mesh), None) => {
                    let ext = Path::new(mesh.get_ref())
                        .extension()
                        .and_then(|e| e.to_str())
                        .map(str::to_ascii_lowercase);
                    if !matches!(ext.as_deref(), Some("obj" | "ply")) {
                        return Err(self.error_at(
                            mesh.span(),
                            format!("mesh '{}' is neither .obj nor .ply", mesh.get_ref()),
                        ));
                    }
                }
                (None, Some(_)) => {}
            }
            if o.subdivisions.is_some() && o.shape.as_ref().is_none_or(|s| *s.get_ref() != ShapeKind::Sphere) {
                return Err(self.error_at(span, "`subdivisions` applies only to `shape = \"sphere\"`"));
            }
            if let Some(m) = &o.material
                && !d.materials.contains_key(m.get_ref())
            {
                let known: Vec<&str> = d.materials.keys().map(String::as_str).collect();
                let known = if known.is_empty() {
                    "no materials are defined".to_owned()
                } else {
                    format!("defined: {}", known.join(", "))
                };
                return Err(self.error_at(m.span(), format!("unknown material '{}' ({known})", m.get_ref())));
            }
        }
        Ok(())
    }
}

fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = text.get(..offset).unwrap_or_default();
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before.get(line_start..).map_or(0, |s| s.chars().count()) + 1;
    (line, column)
}

/// The whole file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// `[environment]`: background and ambient light.
    #[serde(default)]
    pub environment: EnvironmentDesc,
    /// `[render]`: default image size and quality.
    #[serde(default)]
    pub render: crate::RenderOverrides,
    /// `[camera]`: the orbit rig; framed automatically when absent.
    pub camera: Option<CameraDesc>,
    /// `[[lights]]`.
    #[serde(default)]
    pub lights: Vec<LightDesc>,
    /// `[materials.NAME]`.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialDesc>,
    /// `[[objects]]`: mesh instances.
    #[serde(default)]
    pub objects: Vec<Spanned<ObjectDesc>>,
}

/// `[environment]`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnvironmentDesc {
    /// Colour of rays that leave the scene (when there is no `map`).
    pub background: Color,
    /// An equirectangular HDR panorama (`.hdr` Radiance RGBE or `.exr`),
    /// relative to the scene file; replaces `background`.
    pub map: Option<Spanned<String>>,
    /// Scale of the map's radiance (at least 0).
    #[serde(deserialize_with = "non_negative")]
    pub intensity: f32,
    /// Rotation of the map about +y, in degrees.
    #[serde(deserialize_with = "finite")]
    pub rotation_deg: f32,
    /// Ambient light Ia.
    pub ambient: Color,
    /// Whether shadows darken the ambient term (the report's black shadows).
    pub shadowed_ambient: bool,
}

impl Default for EnvironmentDesc {
    fn default() -> Self {
        let e = crate::Environment::default();
        Self {
            background: Color(e.background),
            map: None,
            intensity: e.intensity,
            rotation_deg: e.rotation_deg,
            ambient: Color(e.ambient),
            shadowed_ambient: e.shadowed_ambient,
        }
    }
}

/// `[camera]`: the report's orbit rig and field of view.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Point looked at, O; the scene's centre when absent.
    pub center: Option<[f32; 3]>,
    /// Orbit radius R; chosen to frame the scene when absent.
    #[serde(default, deserialize_with = "positive_opt")]
    pub radius: Option<f32>,
    /// Elevation in degrees (-89.9 to 89.9).
    #[serde(default = "default_theta", deserialize_with = "elevation")]
    pub theta_deg: f32,
    /// Azimuth in degrees.
    #[serde(default = "default_phi", deserialize_with = "finite")]
    pub phi_deg: f32,
    /// Vertical field of view in degrees (0 to 180, exclusive).
    #[serde(default = "default_fov", deserialize_with = "fov")]
    pub fov_y_deg: f32,
}

fn default_theta() -> f32 {
    20.0
}
fn default_phi() -> f32 {
    90.0
}
fn default_fov() -> f32 {
    60.0
}

/// `[[lights]]`, told apart by `type`.
#[derive(Clone, Debug, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum LightDesc {
    /// Light from infinitely far away along `to_light` (the report's L).
    Directional {
        /// Direction from surfaces towards the light.
        #[serde(deserialize_with = "direction")]
        to_light: [f32; 3],
        /// Intensity Ip.
        #[serde(default = "Color::white")]
        intensity: Color,
    },
    /// Point light with inverse-square falloff.
    Point {
        /// World position.
        position: [f32; 3],
        /// Intensity at unit distance.
        #[serde(default = "Color::white")]
        intensity: Color,
    },
}

/// `[materials.NAME]`: the report's Phong parameters and Whitted weights.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    /// Ambient reflectance; defaults to `kd`.
    pub ka: Option<Color>,
    /// Diffuse reflectance.
    #[serde(default = "MaterialDesc::default_kd")]
    pub kd: Color,
    /// Specular reflectance (the highlight).
    #[serde(default)]
    pub ks: Color,
    /// Phong exponent n.
    #[serde(default = "MaterialDesc::default_shininess", deserialize_with = "non_negative")]
    pub shininess: f32,
    /// Mirror weight of the reflected ray.
    #[serde(default)]
    pub kr: Color,
    /// Weight of the transmitted ray; also what shadow rays keep.
    #[serde(default)]
    pub kt: Color,
    /// Index of refraction (inside over outside).
    #[serde(default = "MaterialDesc::default_ior", deserialize_with = "positive")]
    pub ior: f32,
    /// Roughness of the mirror lobe for the path tracer, 0 (smooth) to 1.
    #[serde(default, deserialize_with = "roughness")]
    pub roughness: f32,
    /// Emitted radiance.
    #[serde(default)]
    pub emission: Color,
    /// Diffuse texture (the base colour texture of a metallic-roughness
    /// material).
    pub texture: Option<Spanned<TextureDesc>>,
    /// Metalness, 0 to 1: when given (or `metallic_roughness_texture` or
    /// `transmission` is; metallic is then 0), the material is glTF's
    /// metallic-roughness model, with `kd` as the base colour, `texture`
    /// as the base colour texture and `roughness` as its roughness, and
    /// the report's terms are derived from it for the Whitted integrator.
    #[serde(default, deserialize_with = "unit_interval")]
    pub metallic: Option<f32>,
    /// A glTF-style texture whose blue channel multiplies `metallic` and
    /// green channel `roughness` (linear).
    pub metallic_roughness_texture: Option<Spanned<TextureDesc>>,
    /// Share of a metallic-roughness material's dielectric that
    /// transmits, 0 to 1 (`KHR_materials_transmission`).
    #[serde(default, deserialize_with = "unit_interval")]
    pub transmission: Option<f32>,
    /// Tangent-space normal map (linear RGB, OpenGL convention: green
    /// along the bitangent), for any material.
    pub normal_map: Option<Spanned<TextureDesc>>,
    /// Scale of the normal map's x and y (default 1).
    #[serde(default = "MaterialDesc::default_normal_scale", deserialize_with = "finite")]
    pub normal_scale: f32,
    /// Texture multiplying `emission` (sRGB); `emission` defaults to 1
    /// when only the texture is given.
    pub emission_texture: Option<Spanned<TextureDesc>>,
}

impl MaterialDesc {
    fn default_kd() -> Color {
        Color(Vec3::splat(0.8))
    }
    fn default_shininess() -> f32 {
        32.0
    }
    fn default_ior() -> f32 {
        1.0
    }
    fn default_normal_scale() -> f32 {
        1.0
    }
}

/// A texture reference: either a path string or a table with options.
#[derive(Clone, Debug, Deserialize)]
#[serde(
    untagged,
    expecting = "a texture: \"file.png\" or { file = \"file.png\", wrap = \"clamp\" }"
)]
pub enum TextureDesc {
    /// `texture = "file.png"`.
    Path(String),
    /// `texture = { file = "file.png", wrap = "clamp" }`.
    Table {
        /// Image file, relative to the scene file.
        file: String,
        /// `"repeat"` (default), `"clamp"` or `"mirror"`.
        #[serde(default)]
        wrap: WrapDesc,
    },
}

impl TextureDesc {
    /// The image path as written.
    pub fn file(&self) -> &str {
        match self {
            TextureDesc::Path(p) | TextureDesc::Table { file: p, .. } => p,
        }
    }

    /// The wrap mode.
    pub fn wrap(&self) -> lucent_shading::WrapMode {
        match self {
            TextureDesc::Table {
                wrap: WrapDesc::Clamp, ..
            } => lucent_shading::WrapMode::Clamp,
            TextureDesc::Table {
                wrap: WrapDesc::Mirror, ..
            } => lucent_shading::WrapMode::MirroredRepeat,
            _ => lucent_shading::WrapMode::Repeat,
        }
    }
}

/// Texture wrap mode as written in files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WrapDesc {
    /// Tile.
    #[default]
    Repeat,
    /// Repeat edge texels.
    Clamp,
    /// Tile, every other tile mirrored.
    Mirror,
}

/// Procedural shapes an object can use instead of a mesh file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShapeKind {
    /// Unit-radius icosphere (see `subdivisions`).
    Sphere,
    /// Unit cube centred at the origin.
    Cube,
    /// Unit square in the xz plane facing +y.
    Plane,
}

/// `[[objects]]`: one mesh instance.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    /// Name used in messages and statistics.
    pub name: Option<String>,
    /// Mesh file (.obj or .ply), relative to the scene file.
    pub mesh: Option<Spanned<String>>,
    /// A procedural shape instead of a file.
    pub shape: Option<Spanned<ShapeKind>>,
    /// Icosphere subdivision level (0 to 7, default 4).
    #[serde(default, deserialize_with = "subdivisions")]
    pub subdivisions: Option<u32>,
    /// Material name; absent means the file's own materials (OBJ + MTL),
    /// or a default grey.
    pub material: Option<Spanned<String>>,
    /// Translation.
    #[serde(default)]
    pub translate: [f32; 3],
    /// Rotation in degrees about x, then y, then z (fixed axes).
    #[serde(default)]
    pub rotate_deg: [f32; 3],
    /// Uniform or per-axis scale (no zeros).
    #[serde(default)]
    pub scale: Scale,
}

impl ObjectDesc {
    /// The world-from-object transform: translate * rotate * scale.
    pub fn world_from_object(&self) -> Affine3A {
        let [rx, ry, rz] = self.rotate_deg.map(f32::to_radians);
        let rotation = Quat::from_rotation_z(rz) * Quat::from_rotation_y(ry) * Quat::from_rotation_x(rx);
        Affine3A::from_scale_rotation_translation(self.scale.0, rotation, Vec3::from(self.translate))
    }
}

/// A scale: one number or three, none of them zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale(pub Vec3);

impl Default for Scale {
    fn default() -> Self {
        Scale(Vec3::ONE)
    }
}

impl<'de> Deserialize<'de> for Scale {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = d.deserialize_any(TripleVisitor("a scale: a number or [x, y, z]"))?;
        if !v.is_finite() || v.cmpeq(Vec3::ZERO).any() {
            return Err(de::Error::custom("scale factors must be finite and non-zero"));
        }
        Ok(Scale(v))
    }
}

/// A linear RGB colour: one number (grey) or three, finite and non-negative.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Color(pub Vec3);

impl Color {
    /// White, `[1, 1, 1]`.
    pub fn white() -> Color {
        Color(Vec3::ONE)
    }
}

impl<'de> Deserialize<'de> for Color {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = d.deserialize_any(TripleVisitor("a colour: a number or [r, g, b]"))?;
        if !v.is_finite() || v.min_element() < 0.0 {
            return Err(de::Error::custom("colour components must be finite and at least 0"));
        }
        Ok(Color(v))
    }
}

/// Reads a number (splatted) or an array of exactly three numbers.
struct TripleVisitor(&'static str);

impl<'de> Visitor<'de> for TripleVisitor {
    type Value = Vec3;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.0)
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<Vec3, E> {
        Ok(Vec3::splat(v as f32))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<Vec3, E> {
        Ok(Vec3::splat(v as f32))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<Vec3, E> {
        Ok(Vec3::splat(v as f32))
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec3, A::Error> {
        let mut v = [0.0f32; 3];
        for (i, slot) in v.iter_mut().enumerate() {
            *slot = seq
                .next_element::<f32>()?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        if seq.next_element::<de::IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(4, &self));
        }
        Ok(Vec3::from(v))
    }
}

// Range-checked numbers: each fails with the value's own location.

fn checked<'de, D, T>(d: D, ok: impl Fn(T) -> bool, what: &str) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Copy,
{
    let v = T::deserialize(d)?;
    if ok(v) { Ok(v) } else { Err(de::Error::custom(what)) }
}

/// A [`Named`] value given by its name.
pub(crate) fn named<'de, D: Deserializer<'de>, T: Named>(d: D) -> Result<Option<T>, D::Error> {
    let name = String::deserialize(d)?;
    T::from_name(&name)
        .map(Some)
        .ok_or_else(|| de::Error::custom(format!("unknown name `{name}`, expected {}", T::name_list())))
}

pub(crate) fn image_size<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    checked(
        d,
        |v: u32| (1..=16384).contains(&v),
        "image sizes run from 1 to 16384 pixels",
    )
    .map(Some)
}

pub(crate) fn spp<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    checked(d, |v: u32| (1..=65536).contains(&v), "spp runs from 1 to 65536").map(Some)
}

pub(crate) fn depth<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    checked(d, |v: u32| v <= 64, "max_depth runs from 0 to 64").map(Some)
}

pub(crate) fn free_bounces<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    checked(d, |v: u32| v <= 64, "free_delta_bounces runs from 0 to 64").map(Some)
}

pub(crate) fn lighting_scale<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    checked(d, |v: u32| (1..=16).contains(&v), "lighting_scale runs from 1 to 16").map(Some)
}

pub(crate) fn clamp_value<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f32>, D::Error> {
    checked(
        d,
        |v: f32| (0.0..=1e9).contains(&v),
        "clamp_indirect runs from 0 (no clamp) to 1e9",
    )
    .map(Some)
}

pub(crate) fn rr_depth<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    checked(d, |v: u32| (1..=64).contains(&v), "rr_depth runs from 1 to 64").map(Some)
}

fn subdivisions<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    let max = lucent_geom::shapes::MAX_ICOSPHERE_SUBDIVISIONS;
    checked(d, |v: u32| v <= max, "subdivisions run from 0 to 7").map(Some)
}

pub(crate) fn unit_interval<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f32>, D::Error> {
    checked(d, |v: f32| (0.0..=1.0).contains(&v), "must be between 0 and 1").map(Some)
}

fn roughness<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    checked(
        d,
        |v: f32| (0.0..=1.0).contains(&v),
        "roughness must be between 0 and 1",
    )
}

fn finite<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    checked(d, |v: f32| v.is_finite(), "must be a finite number")
}

fn positive<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    checked(d, |v: f32| v.is_finite() && v > 0.0, "must be a finite number above 0")
}

fn positive_opt<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f32>, D::Error> {
    positive(d).map(Some)
}

fn non_negative<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    checked(
        d,
        |v: f32| v.is_finite() && v >= 0.0,
        "must be a finite number of at least 0",
    )
}

fn elevation<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    checked(
        d,
        |v: f32| v.abs() <= 89.9,
        "theta_deg runs from -89.9 to 89.9 (the rig avoids the poles)",
    )
}

fn fov<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
    checked(
        d,
        |v: f32| v > 0.0 && v < 180.0,
        "fov_y_deg must lie strictly between 0 and 180",
    )
}

fn direction<'de, D: Deserializer<'de>>(d: D) -> Result<[f32; 3], D::Error> {
    checked(
        d,
        |v: [f32; 3]| Vec3::from(v).is_finite() && Vec3::from(v) != Vec3::ZERO,
        "a direction must be finite and non-zero",
    )
}

#[cfg(test)]
mod tests;
