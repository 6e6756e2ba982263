//! Scene files: parse, load what they refer to, spawn the entities.

use crate::{AssetError, AssetSource, FileSystem, LoadReport, load_mesh_from, load_texture, normalize_path};
use lucent_geom::{Aabb, shapes};
use lucent_scene::components::{Camera, Light, Material, Mesh, MeshRef, OrbitRig, Texture};
use lucent_scene::hecs::{Entity, World};
use lucent_scene::{
    CameraDesc, LightDesc, MaterialDesc, ObjectDesc, RenderSettings, Scene, SceneFile, ShapeKind, world_from_local,
};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Loads a scene file from disk with everything it refers to.
pub fn load_scene(path: &Path) -> Result<(Scene, LoadReport), AssetError> {
    load_scene_from(&FileSystem, path)
}

/// Loads a scene file and what it refers to from `source`. Relative paths in
/// the file resolve against the file's directory.
///
/// Errors in the file, and failures to load a mesh or texture it names, are
/// reported at the offending value (`file:line:column: message`).
pub fn load_scene_from(source: &dyn AssetSource, path: &Path) -> Result<(Scene, LoadReport), AssetError> {
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
    textures: HashMap<PathBuf, Arc<Texture>>,
    meshes: HashMap<MeshKey, LoadedParts>,
}

impl Loader<'_> {
    fn apply_settings(&mut self) {
        let d = &self.file.desc;
        let env = &mut self.scene.environment;
        env.background = d.environment.background.0;
        env.ambient = d.environment.ambient.0;
        env.shadowed_ambient = d.environment.shadowed_ambient;
        let r = &d.render;
        let s = RenderSettings::default();
        self.scene.settings = RenderSettings {
            width: r.width.unwrap_or(s.width),
            height: r.height.unwrap_or(s.height),
            spp: r.spp.unwrap_or(s.spp),
            max_depth: r.max_depth.unwrap_or(s.max_depth),
            min_weight: r.min_weight.unwrap_or(s.min_weight),
            rr_depth: r.rr_depth.unwrap_or(s.rr_depth),
            shading: r.shading.unwrap_or(s.shading),
            seed: r.seed.unwrap_or(s.seed),
            integrator: r.integrator.unwrap_or(s.integrator),
            denoise: r.denoise.unwrap_or(s.denoise),
        };
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
        let diffuse_map = match &d.texture {
            None => None,
            Some(tex) => {
                let desc = tex.get_ref();
                let path = normalize_path(&self.file.resolve(desc.file()));
                let texture = match self.textures.get(&path) {
                    Some(t) => t.clone(),
                    None => {
                        let mut t = load_texture(self.source, &path).map_err(|e| {
                            self.file.error_at(
                                tex.span(),
                                format!(
                                    "cannot load texture '{}': {}",
                                    desc.file(),
                                    crate::image_io::texture_problem(&e)
                                ),
                            )
                        })?;
                        t.wrap = desc.wrap();
                        let t = Arc::new(t);
                        self.textures.insert(path, t.clone());
                        t
                    }
                };
                Some(texture)
            }
        };
        Ok(Material {
            ka: d.ka.unwrap_or(d.kd).0,
            kd: d.kd.0,
            ks: d.ks.0,
            shininess: d.shininess,
            kr: d.kr.0,
            kt: d.kt.0,
            ior: d.ior,
            roughness: d.roughness,
            emission: d.emission.0,
            diffuse_map,
        })
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
        if self.file.desc.lights.is_empty() && !emissive {
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
        let bounds = world_bounds(&self.scene.world);
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

/// World-space bounds of every instance, parents included.
fn world_bounds(world: &World) -> Aabb {
    let mut q = world.query::<(Entity, &MeshRef)>();
    q.iter().fold(Aabb::EMPTY, |b, (e, m)| {
        let mesh_bounds = world.get::<&Mesh>(m.0).map_or(Aabb::EMPTY, |mesh| mesh.0.bounds());
        b.union(mesh_bounds.transformed(&world_from_local(world, e)))
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
