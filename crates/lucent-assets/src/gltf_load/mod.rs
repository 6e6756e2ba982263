//! glTF 2.0 scenes (`.gltf` with external or base64 data, `.glb`): the
//! default scene's node hierarchy becomes entities with `Parent` and
//! `Transform` (a mesh used by several nodes is stored once), its
//! materials Lucent's metallic-roughness materials, its first perspective
//! camera the scene's camera, its `KHR_lights_punctual` lights Lucent's
//! lights. Errors name the file and the JSON pointer of the offending
//! part; problems that do not stop loading go to the [`LoadReport`].
//!
//! Light units: glTF gives point and spot intensities in candela and
//! directional illuminance in lux; Lucent's lights are radiometric, so each
//! is divided by 683 lm/W (the luminous efficacy that defines the candela),
//! the colour multiplying per channel.

mod data;
mod draco;
mod material;
mod mesh;
#[cfg(test)]
mod tests;

use crate::model_scene::{Surroundings, surround};
use crate::{AssetError, AssetSource, LoadReport};
use data::Buffers;
use gltf::khr_lights_punctual::Kind;
use lucent_geom::{Affine3A, Mat4, Vec3};
use lucent_scene::components::{Camera, Light, Material, Name, OrbitRig, Parent, Transform};
use lucent_scene::hecs::Entity;
use lucent_scene::{Scene, world_from_local};
use std::collections::{HashMap, HashSet};
use std::path::Path;

/// Extensions whose meaning Lucent renders (others in `extensionsUsed`
/// are warnings, in `extensionsRequired` errors).
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_draco_mesh_compression",
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_texture_transform",
];

/// Lumens per watt at 555 nm: photometric glTF units to radiometric ones.
const LM_PER_W: f32 = 683.0;

/// Options of [`load_gltf_from`].
#[derive(Clone, Copy, Debug, Default)]
pub struct GltfOptions {
    /// Do not decode images (each texture reads as grey): for timing the
    /// rest of loading.
    pub skip_images: bool,
}

/// Loads a `.gltf` or `.glb` file as a scene, with a camera, lights and
/// settings around it where the file has none (see
/// [`load_scene_from`](crate::load_scene_from)).
pub fn load_gltf_from(
    source: &dyn AssetSource,
    path: &Path,
    options: GltfOptions,
) -> Result<(Scene, LoadReport), AssetError> {
    let bytes = source.read(path)?;
    let fail = |message: String| AssetError::format(path, message);
    check_glb_header(&bytes).map_err(fail)?;
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| fail(document_error(e)))?;
    // Required extensions first: their data may not validate without them
    // (Draco-compressed accessors have no buffer view).
    for (i, ext) in document.extensions_required().enumerate() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            return Err(fail(format!(
                "/extensionsRequired/{i}: extension {ext} is required but not supported"
            )));
        }
    }
    let root = document.into_json();
    precheck(&root).map_err(fail)?;
    validate(&root).map_err(|e| fail(document_error(e)))?;
    let document = gltf::Document::from_json_without_validation(root);
    let mut warnings = Vec::new();
    for ext in document.extensions_used() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            warnings.push(format!(
                "/extensionsUsed: extension {ext} is not supported and is ignored"
            ));
        }
    }
    let buffers = Buffers::load(&document, blob, source, path).map_err(fail)?;
    let mut scene = Scene::default();
    let has_camera;
    let mut n_lights = 0;
    {
        let mut b = Builder {
            scene: &mut scene,
            buffers: &buffers,
            views: document.views().collect(),
            textures: material::Textures::new(&buffers, source, path, options.skip_images),
            warnings: &mut warnings,
            meshes: HashMap::new(),
            materials: HashMap::new(),
            camera: None,
        };
        let root_nodes: Vec<gltf::Node<'_>> = match document.default_scene().or_else(|| document.scenes().next()) {
            Some(s) => s.nodes().collect(),
            None => {
                b.warnings
                    .push("/scenes: the file has no scene; nothing to show".to_owned());
                Vec::new()
            }
        };
        let mut visited = HashSet::new();
        let mut stack: Vec<(gltf::Node<'_>, Option<Entity>)> =
            root_nodes.into_iter().rev().map(|n| (n, None)).collect();
        while let Some((node, parent)) = stack.pop() {
            if !visited.insert(node.index()) {
                b.warnings.push(format!(
                    "/nodes/{}: reached twice in the hierarchy (nodes must form trees); the second is ignored",
                    node.index()
                ));
                continue;
            }
            let entity = b.node(&node, parent).map_err(fail)?;
            if node.light().is_some() {
                n_lights += 1;
            }
            for child in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((child, Some(entity)));
            }
        }
        has_camera = b.camera.is_some();
        if let Some((entity, camera)) = b.camera {
            fit_camera(b.scene, entity, camera);
        }
    }
    let mut report = LoadReport::default();
    for w in warnings {
        report.warn(path, w);
    }
    surround(
        &mut scene,
        &mut report,
        path,
        Surroundings {
            camera: !has_camera,
            lights: n_lights == 0,
        },
    );
    Ok((scene, report))
}

/// Checks what the gltf crate's GLB reader subtracts without checking: a
/// header whose total length is below the header's own 12 bytes (found by
/// the fuzz target: an overflow panic where overflow checks are on, a
/// wrapped length elsewhere).
fn check_glb_header(bytes: &[u8]) -> Result<(), String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let Some(length) = bytes.get(8..12) else {
        return Err(format!(
            "GLB container: the file has {} bytes, fewer than the 12-byte header",
            bytes.len()
        ));
    };
    let length = u32::from_le_bytes([length[0], length[1], length[2], length[3]]);
    if length < 12 {
        return Err(format!(
            "GLB container: byte 8: length {length} is shorter than the 12-byte header"
        ));
    }
    Ok(())
}

/// Checks what gltf-json's validation indexes without checking (it
/// panics on a `POSITION` accessor index past the accessors).
fn precheck(root: &gltf::json::Root) -> Result<(), String> {
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position = prim
                .attributes
                .get(&gltf::json::validation::Checked::Valid(gltf::Semantic::Positions));
            if let Some(i) = position
                && i.value() >= root.accessors.len()
            {
                return Err(format!(
                    "/meshes/{m}/primitives/{p}/attributes/POSITION: accessor {} does not exist ({} accessors)",
                    i.value(),
                    root.accessors.len()
                ));
            }
        }
    }
    Ok(())
}

/// gltf-json's validation, less two of its refusals that the
/// specification does not make: an accessor without a buffer view (it
/// reads as zeros, and a Draco-compressed primitive's accessors have none)
/// and a required extension gltf does not model (Lucent's own
/// [`SUPPORTED_EXTENSIONS`] check has already run).
fn validate(root: &gltf::json::Root) -> Result<(), gltf::Error> {
    use gltf::json::validation::{Error, Validate};
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| {
        let p = path();
        let no_view = error == Error::Missing
            && p.0.strip_prefix("accessors[").is_some_and(|rest| {
                rest.split_once(']')
                    .is_some_and(|(i, tail)| i.bytes().all(|b| b.is_ascii_digit()) && tail == ".bufferView")
            });
        if !no_view && error != Error::Unsupported {
            errors.push((p, error));
        }
    });
    if errors.is_empty() {
        Ok(())
    } else {
        Err(gltf::Error::Validation(errors))
    }
}

/// A readable message for a document that does not parse or validate.
fn document_error(e: gltf::Error) -> String {
    match e {
        gltf::Error::Validation(errors) => {
            let shown: Vec<String> = errors
                .iter()
                .take(3)
                .map(|(p, err)| format!("{}: {err}", json_pointer(&p.to_string())))
                .collect();
            let more = errors.len().saturating_sub(shown.len());
            let tail = if more > 0 {
                format!(" (and {more} more)")
            } else {
                String::new()
            };
            format!("{}{tail}", shown.join("; "))
        }
        gltf::Error::Deserialize(e) => format!("not glTF JSON: {e}"),
        gltf::Error::Binary(e) => format!("GLB container: {e}"),
        other => other.to_string(),
    }
}

/// `meshes[0].primitives[1].attributes["POSITION"]` as the JSON pointer
/// `/meshes/0/primitives/1/attributes/POSITION`.
fn json_pointer(path: &str) -> String {
    let mut out = String::from("/");
    for c in path.chars() {
        match c {
            '.' | '[' => out.push('/'),
            ']' | '"' => {}
            c => out.push(c),
        }
    }
    out.replace("//", "/")
}

struct Builder<'s, 'd> {
    scene: &'s mut Scene,
    buffers: &'d Buffers,
    /// The document's buffer views, by index (Draco streams name theirs).
    views: Vec<gltf::buffer::View<'d>>,
    textures: material::Textures<'d>,
    warnings: &'s mut Vec<String>,
    /// Mesh entity per (mesh, primitive), `None` for primitives without
    /// triangles; shared by every node that uses the mesh.
    meshes: HashMap<(usize, usize), Option<Entity>>,
    /// Material entity per material index (`None`: the default material).
    materials: HashMap<Option<usize>, (Entity, bool, u32)>,
    /// The first perspective camera's node entity and camera.
    camera: Option<(Entity, Camera)>,
}

impl Builder<'_, '_> {
    fn node(&mut self, node: &gltf::Node<'_>, parent: Option<Entity>) -> Result<Entity, String> {
        let ptr = format!("/nodes/{}", node.index());
        let m = Mat4::from_cols_array_2d(&node.transform().matrix());
        let t = Affine3A::from_mat4(m);
        if !t.is_finite() {
            return Err(format!("{ptr}: its transform is not finite"));
        }
        let name = node
            .name()
            .map_or_else(|| format!("node{}", node.index()), str::to_owned);
        let entity = self.scene.world.spawn((Name(name.clone()), Transform(t)));
        if let Some(p) = parent {
            let _ = self.scene.world.insert_one(entity, Parent(p));
        }
        if let Some(mesh) = node.mesh() {
            let prims: Vec<_> = mesh.primitives().collect();
            let single = prims.len() == 1;
            for prim in prims {
                let (material, needs_tangents, uv_set) = self.material(&prim.material())?;
                let key = (mesh.index(), prim.index());
                let mesh_entity = match self.meshes.get(&key) {
                    Some(e) => *e,
                    None => {
                        let pptr = format!("/meshes/{}/primitives/{}", mesh.index(), prim.index());
                        let needs = mesh::PrimitiveNeeds {
                            uv_set,
                            tangents: needs_tangents,
                        };
                        let tri = mesh::primitive_mesh(self.buffers, &self.views, &prim, &pptr, &needs, self.warnings)?;
                        if tri.is_none() {
                            self.warnings
                                .push(format!("{pptr}/mode: points and lines are not rendered"));
                        }
                        let e = tri.map(|t| {
                            let name = mesh
                                .name()
                                .map_or_else(|| format!("mesh{}", mesh.index()), str::to_owned);
                            self.scene.add_mesh(&format!("{name}/{}", prim.index()), t)
                        });
                        self.meshes.insert(key, e);
                        e
                    }
                };
                let Some(mesh_entity) = mesh_entity else { continue };
                if single {
                    let _ = self.scene.world.insert(
                        entity,
                        (
                            lucent_scene::components::MeshRef(mesh_entity),
                            lucent_scene::components::MaterialRef(material),
                        ),
                    );
                } else {
                    let child = self.scene.add_instance(
                        &format!("{name}/{}", prim.index()),
                        mesh_entity,
                        material,
                        Affine3A::IDENTITY,
                    );
                    let _ = self.scene.world.insert_one(child, Parent(entity));
                }
            }
        }
        if let Some(cam) = node.camera()
            && self.camera.is_none()
        {
            match cam.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    let fov = p.yfov().to_degrees();
                    if fov.is_finite() && fov > 0.0 {
                        self.camera = Some((entity, Camera { fov_y_deg: fov }));
                    }
                }
                gltf::camera::Projection::Orthographic(_) => self.warnings.push(format!(
                    "/cameras/{}: orthographic cameras are not supported; it is ignored",
                    cam.index()
                )),
            }
        }
        if let Some(light) = node.light() {
            let c = Vec3::from(light.color()) * (light.intensity() / LM_PER_W);
            let world = world_from_local(&self.scene.world, entity);
            let position = world.translation.into();
            let dir = world.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z);
            let l = match light.kind() {
                Kind::Directional => Light::Directional {
                    to_light: -dir,
                    intensity: c,
                },
                Kind::Point => Light::Point { position, intensity: c },
                Kind::Spot {
                    inner_cone_angle,
                    outer_cone_angle,
                } => Light::Spot {
                    position,
                    direction: dir,
                    intensity: c,
                    inner_cone: inner_cone_angle,
                    outer_cone: outer_cone_angle.min(std::f32::consts::FRAC_PI_2),
                },
            };
            if light.range().is_some() {
                self.warnings.push(format!(
                    "/extensions/KHR_lights_punctual/lights/{}/range: ignored (lights fall off with the squared distance only)",
                    light.index()
                ));
            }
            let name = light
                .name()
                .map_or_else(|| format!("light{}", light.index()), str::to_owned);
            self.scene.add_light(&name, l);
        }
        Ok(entity)
    }

    /// The material entity for a glTF material, whether it has a normal
    /// map, and which texture coordinate set it reads.
    fn material(&mut self, m: &gltf::Material<'_>) -> Result<(Entity, bool, u32), String> {
        if let Some(&e) = self.materials.get(&m.index()) {
            return Ok(e);
        }
        let (mat, name) = match m.index() {
            Some(i) => {
                let mat = material::convert(m, &format!("/materials/{i}"), &mut self.textures, self.warnings)?;
                (mat, m.name().map_or_else(|| format!("material{i}"), str::to_owned))
            }
            // The specification's default material.
            None => (
                Material::metallic_roughness(lucent_shading::MetallicRoughness::default()),
                "default".to_owned(),
            ),
        };
        let uv_set = material::uv_set(m, self.warnings);
        let normal = mat.normal_map.is_some();
        let e = (self.scene.add_material(&name, mat), normal, uv_set);
        self.materials.insert(m.index(), e);
        Ok(e)
    }
}

/// Makes `camera` at `node`'s world transform the scene's camera: the
/// orbit rig is fitted to its position and view direction (roll is lost),
/// orbiting the point on its view axis nearest the scene's centre.
fn fit_camera(scene: &mut Scene, node: Entity, camera: Camera) {
    let world = world_from_local(&scene.world, node);
    let eye: Vec3 = world.translation.into();
    let forward = world.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z);
    let bounds = crate::scene_load::world_bounds(&scene.world);
    let target = if bounds.is_empty() {
        eye + forward
    } else {
        bounds.center()
    };
    let fallback = if bounds.is_empty() {
        1.0
    } else {
        0.5 * bounds.extent().length()
    };
    let along = (target - eye).dot(forward);
    let radius = if along > 1e-6 { along } else { fallback.max(1e-3) };
    let back = -forward;
    let rig = OrbitRig {
        center: eye + forward * radius,
        radius,
        theta: back.y.clamp(-1.0, 1.0).asin(),
        phi: back.z.atan2(back.x),
    }
    .sanitized();
    let e = scene.add_camera("camera", camera, rig);
    scene.active_camera = Some(e);
}
