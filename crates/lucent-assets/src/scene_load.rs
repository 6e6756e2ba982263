//! Scene files: parse, load what they refer to, spawn the entities.

use crate::{
    AssetError, AssetSource, ColorSpace, FileSystem, LoadReport, load_environment_map, load_mesh_from, normalize_path,
    texture_from_bytes_as,
};
use lucent_geom::{Aabb, Vec3, shapes};
use lucent_scene::Spanned;
use lucent_scene::components::{Camera, Light, Material, Mesh, MeshRef, OrbitRig, Texture};
use lucent_scene::hecs::{Entity, World};
use lucent_scene::{
    CameraDesc, LightDesc, MaterialDesc, ObjectDesc, RenderSettings, Scene, SceneFile, ShapeKind, TextureDesc,
    world_from_local,
};
use lucent_shading::{MetallicRoughness, WrapMode};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Loads a scene file from disk with everything it refers to.
pub fn load_scene(path: &Path) -> Result<(Scene, LoadReport), AssetError> {
    load_scene_from(&FileSystem, path)
}

/// Loads a scene from `source`: a TOML scene file and what it refers to, or
/// a model (`.gltf`, `.glb`, `.obj`, `.ply`, told by the extension) with a
/// scene made around it (see [`crate::model_scene`]). Relative paths in the
/// file resolve against the file's directory.
///
/// Errors in a scene file, and failures to load a mesh or texture it names,
/// are reported at the offending value (`file:line:column: message`); a
/// glTF file's errors name the JSON pointer of the offending part.
pub fn load_scene_from(source: &dyn AssetSource, path: &Path) -> Result<(Scene, LoadReport), AssetError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("gltf" | "glb") => return crate::load_gltf_from(source, path, crate::GltfOptions::default()),
        Some("obj" | "ply") => return crate::model_scene::load_model_scene(source, path),
        _ => {}
    }
    let bytes = source.read(path)?;
    let text = std::str::from_utf8(&bytes).map_err(|e| {
        let line = bytes[..e.valid_up_to()].iter().filter(|&&b| b == b'\n').count() + 1;
        AssetError::Format {
            path: path.to_owned(),
            location: Some(crate::Location::Line(line)),
            message: "the scene file is not valid UTF-8 text".to_owned(),
        }
    })?;
    let file = SceneFile::parse(path, text)?;
    let mut loader = Loader {
        source,
        file: &file,
        scene: Scene::default(),
        report: LoadReport::default(),
        materials: HashMap::new(),
        default_material: None,
        textures: HashMap::new(),
        meshes: HashMap::new(),
    };
    loader.apply_settings();
    loader.load_environment_map()?;
    loader.spawn_materials()?;
    loader.spawn_objects()?;
    loader.spawn_lights();
    loader.spawn_camera();
    let Loader { scene, report, .. } = loader;
    Ok((scene, report))
}

/// What a mesh source turned into: mesh entities and, per part, the
/// material entity its file gave it.
type LoadedParts = Vec<(Entity, Option<Entity>, String)>;

#[derive(Clone, PartialEq, Eq, Hash)]
enum MeshKey {
    File(PathBuf),
    Shape(ShapeKind, u32),
}

struct Loader<'a> {
    source: &'a dyn AssetSource,
    file: &'a SceneFile,
    scene: Scene,
    report: LoadReport,
    materials: HashMap<String, Entity>,
    default_material: Option<Entity>,
    textures: HashMap<(PathBuf, ColorSpace, WrapMode), Arc<Texture>>,
    meshes: HashMap<MeshKey, LoadedParts>,
}

impl Loader<'_> {
    fn apply_settings(&mut self) {
        let d = &self.file.desc;
        let env = &mut self.scene.environment;
        env.background = d.environment.background.0;
        env.intensity = d.environment.intensity;
        env.rotation_deg = d.environment.rotation_deg;
        env.ambient = d.environment.ambient.0;
        env.shadowed_ambient = d.environment.shadowed_ambient;
        self.scene.settings = RenderSettings::default();
        d.render.apply(&mut self.scene.settings);
    }

    /// `[environment] map`: decoded once; an unreadable or unusable file is
    /// an error at the `map` value, bad texels (NaN, infinite, negative) a
    /// warning that counts them.
    fn load_environment_map(&mut self) -> Result<(), AssetError> {
        let Some(map) = &self.file.desc.environment.map else {
            return Ok(());
        };
        let path = normalize_path(&self.file.resolve(map.get_ref()));
        let (env_map, bad) = load_environment_map(self.source, &path).map_err(|e| {
            self.file.error_at(
                map.span(),
                format!(
                    "cannot load environment map '{}': {}",
                    map.get_ref(),
                    crate::image_io::texture_problem(&e)
                ),
            )
        })?;
        if bad > 0 {
            self.report.warn(
                &path,
                format!("{bad} texels are NaN, infinite or negative; they are black"),
            );
        }
        self.scene.environment.map = Some(Arc::new(env_map));
        Ok(())
    }

    fn spawn_materials(&mut self) -> Result<(), AssetError> {
        for (name, desc) in &self.file.desc.materials {
            let material = self.material_from(desc)?;
            let e = self.scene.add_material(name, material);
            self.materials.insert(name.clone(), e);
        }
        Ok(())
    }

    fn material_from(&mut self, d: &MaterialDesc) -> Result<Material, AssetError> {
        let diffuse_map = self.texture(d.texture.as_ref(), ColorSpace::Srgb)?;
        let normal_map = self.texture(d.normal_map.as_ref(), ColorSpace::Linear)?;
        let emission_map = self.texture(d.emission_texture.as_ref(), ColorSpace::Srgb)?;
        let mr_map = self.texture(d.metallic_roughness_texture.as_ref(), ColorSpace::Linear)?;
        // An emission texture alone emits as it is.
        let emission = if emission_map.is_some() && d.emission.0 == Vec3::ZERO {
            Vec3::ONE
        } else {
            d.emission.0
        };
        let base = Material {
            ka: d.ka.unwrap_or(d.kd).0,
            kd: d.kd.0,
            ks: d.ks.0,
            shininess: d.shininess,
            kr: d.kr.0,
            kt: d.kt.0,
            ior: d.ior,
            roughness: d.roughness,
            emission,
            diffuse_map,
            normal_map,
            normal_scale: d.normal_scale,
            emission_map,
            ..Material::default()
        };
        if d.metallic.is_none() && mr_map.is_none() && d.transmission.is_none() {
            return Ok(base);
        }
        let pbr = Material::metallic_roughness(MetallicRoughness {
            base_color: d.kd.0,
            metallic: d.metallic.unwrap_or(0.0),
            roughness: d.roughness,
            metallic_map: mr_map.clone(),
            roughness_map: mr_map,
            transmission: d.transmission.unwrap_or(0.0),
        });
        Ok(Material {
            ior: if d.ior == 1.0 { pbr.ior } else { d.ior },
            ka: pbr.ka,
            kd: pbr.kd,
            ks: pbr.ks,
            shininess: pbr.shininess,
            kr: pbr.kr,
            kt: pbr.kt,
            pbr: pbr.pbr,
            ..base
        })
    }

    /// The texture a material key names, loaded once per file and colour
    /// space; an error is located at the key's value.
    fn texture(
        &mut self,
        tex: Option<&Spanned<TextureDesc>>,
        space: ColorSpace,
    ) -> Result<Option<Arc<Texture>>, AssetError> {
        let Some(tex) = tex else { return Ok(None) };
        let desc = tex.get_ref();
        let path = normalize_path(&self.file.resolve(desc.file()));
        let key = (path, space, desc.wrap());
        if let Some(t) = self.textures.get(&key) {
            return Ok(Some(t.clone()));
        }
        let loaded = self
            .source
            .read(&key.0)
            .and_then(|bytes| texture_from_bytes_as(&bytes, &key.0, space));
        let mut t = loaded.map_err(|e| {
            self.file.error_at(
                tex.span(),
                format!(
                    "cannot load texture '{}': {}",
                    desc.file(),
                    crate::image_io::texture_problem(&e)
                ),
            )
        })?;
        t.set_wrap(desc.wrap());
        let t = Arc::new(t);
        self.textures.insert(key, t.clone());
        Ok(Some(t))
    }

    fn default_material(&mut self) -> Entity {
        *self
            .default_material
            .get_or_insert_with(|| self.scene.add_material("default", Material::default()))
    }

    fn spawn_objects(&mut self) -> Result<(), AssetError> {
        for obj in &self.file.desc.objects {
            let o = obj.get_ref();
            let parts = self.mesh_parts(o)?;
            let base_name = o.name.clone().unwrap_or_else(|| default_name(o));
            let n_parts = parts.len();
            for (mesh, file_material, part_name) in parts {
                let material = match &o.material {
                    Some(name) => self.materials.get(name.get_ref()).copied(),
                    None => file_material,
                };
                let material = match material {
                    Some(m) => m,
                    None => self.default_material(),
                };
                let name = if n_parts > 1 && !part_name.is_empty() {
                    format!("{base_name}/{part_name}")
                } else {
                    base_name.clone()
                };
                self.scene.add_instance(&name, mesh, material, o.world_from_object());
            }
        }
        Ok(())
    }

    /// The mesh entities for an object, loading or generating them once per
    /// file or shape.
    fn mesh_parts(&mut self, o: &ObjectDesc) -> Result<LoadedParts, AssetError> {
        let key = match (&o.mesh, &o.shape) {
            (Some(m), _) => MeshKey::File(normalize_path(&self.file.resolve(m.get_ref()))),
            (None, Some(s)) => MeshKey::Shape(*s.get_ref(), o.subdivisions.unwrap_or(4)),
            // Validation guarantees one of the two.
            (None, None) => return Ok(Vec::new()),
        };
        if let Some(parts) = self.meshes.get(&key) {
            return Ok(parts.clone());
        }
        let parts = match &key {
            MeshKey::Shape(kind, subdivisions) => {
                let mesh = match kind {
                    ShapeKind::Sphere => shapes::icosphere(*subdivisions),
                    ShapeKind::Cube => shapes::cuboid(),
                    ShapeKind::Plane => shapes::plane(),
                };
                let name = format!("{kind:?}").to_lowercase();
                vec![(self.scene.add_mesh(&name, mesh), None, String::new())]
            }
            MeshKey::File(path) => {
                let written = o.mesh.as_ref().map(|m| (m.get_ref().clone(), m.span()));
                let (parts, report) = load_mesh_from(self.source, path).map_err(|e| {
                    let (name, span) = written.clone().unwrap_or_default();
                    self.file.error_at(span, format!("cannot load mesh '{name}': {e}"))
                })?;
                self.report.extend(report);
                let mut loaded = Vec::with_capacity(parts.len());
                // One entity per material of the file, however many parts use it.
                let mut file_materials: HashMap<String, Entity> = HashMap::new();
                for part in parts {
                    let key = part.material_name.clone().unwrap_or_else(|| part.name.clone());
                    let material = part.material.map(|m| {
                        *file_materials
                            .entry(key)
                            .or_insert_with_key(|k| self.scene.add_material(&format!("{}:{k}", path.display()), m))
                    });
                    // Shading needs normals; a file without them gets smooth ones.
                    let mesh = self
                        .scene
                        .add_mesh(&part.name, part.mesh.with_smooth_normals_if_missing());
                    loaded.push((mesh, material, part.name));
                }
                loaded
            }
        };
        self.meshes.insert(key, parts.clone());
        Ok(parts)
    }

    fn spawn_lights(&mut self) {
        // Emissive materials (the scene file's, or an MTL's `Ke`) light the
        // scene for the path tracer.
        let emissive = self
            .scene
            .world
            .query::<&Material>()
            .iter()
            .any(|m| m.emission.max_element() > 0.0);
        if self.file.desc.lights.is_empty() && !emissive && self.scene.environment.map.is_none() {
            self.report
                .warn(&self.file.path, "no lights: only ambient light will show");
        }
        for (i, l) in self.file.desc.lights.iter().enumerate() {
            let light = match *l {
                LightDesc::Directional { to_light, intensity } => Light::Directional {
                    to_light: lucent_geom::Vec3::from(to_light).normalize(),
                    intensity: intensity.0,
                },
                LightDesc::Point { position, intensity } => Light::Point {
                    position: position.into(),
                    intensity: intensity.0,
                },
            };
            self.scene.add_light(&format!("light{i}"), light);
        }
    }

    /// The camera from the file; missing centre and radius frame the scene.
    fn spawn_camera(&mut self) {
        let desc = self.file.desc.camera.clone().unwrap_or(CameraDesc {
            center: None,
            radius: None,
            theta_deg: 20.0,
            phi_deg: 90.0,
            fov_y_deg: 60.0,
        });
        // The scene is framed only where the file leaves the centre or the
        // radius out: the bounds cost a pass over every mesh.
        let bounds = if desc.center.is_some() && desc.radius.is_some() {
            Aabb::EMPTY
        } else {
            world_bounds(&self.scene.world)
        };
        let (center, fit_radius) = if bounds.is_empty() {
            (lucent_geom::Vec3::ZERO, 3.0)
        } else {
            let sphere = 0.5 * bounds.extent().length();
            let half_fov = 0.5 * desc.fov_y_deg.to_radians();
            (bounds.center(), 1.1 * sphere / half_fov.sin())
        };
        let rig = OrbitRig {
            center: desc.center.map_or(center, Into::into),
            radius: desc.radius.unwrap_or(fit_radius),
            theta: desc.theta_deg.to_radians(),
            phi: desc.phi_deg.to_radians(),
        }
        .sanitized();
        let camera = Camera {
            fov_y_deg: desc.fov_y_deg,
        };
        self.scene.add_camera("camera", camera, rig);
    }
}

/// World-space bounds of every instance, parents included. Each mesh's
/// own bounds are worked out once, however many instances share it.
pub(crate) fn world_bounds(world: &World) -> Aabb {
    let mut mesh_bounds: HashMap<Entity, Aabb> = HashMap::new();
    let mut q = world.query::<(Entity, &MeshRef)>();
    q.iter().fold(Aabb::EMPTY, |b, (e, m)| {
        let local = *mesh_bounds
            .entry(m.0)
            .or_insert_with(|| world.get::<&Mesh>(m.0).map_or(Aabb::EMPTY, |mesh| mesh.0.bounds()));
        b.union(local.transformed(&world_from_local(world, e)))
    })
}

fn default_name(o: &ObjectDesc) -> String {
    match (&o.mesh, &o.shape) {
        (Some(m), _) => Path::new(m.get_ref())
            .file_stem()
            .map_or_else(|| "mesh".to_owned(), |s| s.to_string_lossy().into_owned()),
        (None, Some(s)) => format!("{:?}", s.get_ref()).to_lowercase(),
        (None, None) => "object".to_owned(),
    }
}

#[cfg(test)]
mod tests;
