//! The extract step: flattens the ECS world into plain render data.
//!
//! This is the only file of the renderer that names hecs. Everything after
//! it addresses meshes, materials and instances by `u32` index.

use crate::envlight::EnvLight;
use crate::flat::{FlatBvh, MAX_FLAT_TRIANGLES};
use crate::lane::LaneTables;
use crate::lights::{LightSet, emits};
use crate::{Integrator, RenderSettings};
use lucent_accel::{BuildParams, BuildQuality, Instance, MeshBvh, SceneBvh};
use lucent_geom::{Affine3A, Mat3A, TriMesh, Vec3};
use lucent_scene::camera::{Camera, OrbitRig};
use lucent_scene::components::{Light, Material, MaterialRef, Mesh, MeshRef, Name};
use lucent_scene::hecs::Entity;
use lucent_scene::{Environment, Scene, world_from_local};
use rayon::prelude::*;
use std::collections::HashMap;
use std::fmt;
use std::sync::{Arc, OnceLock};

/// One placed mesh, ready for shading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderInstance {
    /// Index into [`RenderScene::meshes`].
    pub mesh: u32,
    /// Index into [`RenderScene::materials`].
    pub material: u32,
    /// Object to render space (world space moved by `-RenderScene::origin`).
    pub render_from_object: Affine3A,
    /// Object-space normals to render space (the inverse transpose).
    pub normal_render_from_object: Mat3A,
    /// The per-vertex arrays of the mesh that shading this instance reads.
    pub reads: VertexReads,
}

impl RenderInstance {
    /// A triangle's corners, given in object space, in render space.
    #[inline]
    pub fn corners_to_render(&self, corners: [Vec3; 3]) -> [Vec3; 3] {
        corners.map(|p| self.render_from_object.transform_point3(p))
    }
}

/// Which per-vertex arrays of an instance's mesh the integrators read at a
/// hit. An array the mesh lacks is never read; one it has is skipped when
/// nothing the instance's material does depends on it (texture coordinates
/// without a texture). The mesh itself is not changed: it is shared with
/// the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VertexReads {
    /// Vertex normals, interpolated into the shading normal.
    pub normals: bool,
    /// Texture coordinates, interpolated for the diffuse texture lookup.
    pub uvs: bool,
    /// Vertex colours, which tint the diffuse (and ambient) colour.
    pub colors: bool,
    /// Vertex tangents, for the material's normal map.
    pub tangents: bool,
}

impl VertexReads {
    /// What `material` on `mesh` needs; with `all` every array the mesh has.
    pub fn of(mesh: &TriMesh, material: &Material, all: bool) -> VertexReads {
        VertexReads {
            normals: mesh.normals().is_some(),
            uvs: mesh.uvs().is_some() && (all || material.is_textured()),
            colors: mesh.colors().is_some(),
            tangents: mesh.tangents().is_some() && (all || material.normal_map.is_some()),
        }
    }
}

/// What the scene contains, so the renderer does only the work it needs.
///
/// [`extract_with`] derives it from the instances (a material or mesh no
/// instance uses counts for nothing) and the lights, and the integrators
/// pick code specialised on it once per render:
///
/// | feature | what is skipped without it |
/// | --- | --- |
/// | `transmissive` | Whitted refraction rays; shadow rays stop at the first surface they meet (any-hit) instead of visiting every surface and multiplying `kt` |
/// | `reflective` | Whitted mirror rays |
/// | `textured` | texture coordinate interpolation and texture lookups (per instance, see [`VertexReads`]); the path tracer's per-hit BSDF set-up |
/// | `emissive` | the light set's table of emissive triangles per instance, and the path tracer's emission lookup and MIS weight at every path vertex |
/// | `alpha_tested` | the alpha test of hits (see `alpha.rs`): closest-hit and any-hit queries are the traversal core's own |
///
/// `point_lights`, `directional_lights`, `smooth_normals` and
/// `vertex_colors` describe the scene for `lucent info`; their work is done
/// per light or per mesh array only where they exist anyway.
/// [`ExtractOptions::all_features`] turns every feature on, which renders
/// the same image by the general code (the baseline to measure against).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneFeatures {
    /// Some material lets light through (refraction rays, attenuating shadows).
    pub transmissive: bool,
    /// Some material is a mirror (reflection rays).
    pub reflective: bool,
    /// Some instance has a textured material on a mesh with texture
    /// coordinates (UV interpolation, texture lookups).
    pub textured: bool,
    /// Some instance's material emits: emissive triangles are area lights.
    pub emissive: bool,
    /// The scene has point (or spot) lights.
    pub point_lights: bool,
    /// The scene has directional lights.
    pub directional_lights: bool,
    /// Some instance's mesh has vertex normals (smooth shading).
    pub smooth_normals: bool,
    /// Some instance's material is alpha-tested (glTF `MASK`): hits are
    /// tested against its alpha before they are accepted.
    pub alpha_tested: bool,
    /// Some instance's mesh has vertex colours.
    pub vertex_colors: bool,
}

impl SceneFeatures {
    /// Every feature on.
    pub const ALL: SceneFeatures = SceneFeatures {
        transmissive: true,
        reflective: true,
        textured: true,
        emissive: true,
        point_lights: true,
        directional_lights: true,
        smooth_normals: true,
        alpha_tested: true,
        vertex_colors: true,
    };

    /// The names of the features that are on, in a fixed order (the names
    /// `lucent info` prints).
    ///
    /// ```
    /// use lucent_render::SceneFeatures;
    /// let f = SceneFeatures { reflective: true, emissive: true, ..SceneFeatures::default() };
    /// assert_eq!(f.names(), ["reflective", "emissive"]);
    /// assert_eq!(SceneFeatures::ALL.names().len(), 9);
    /// ```
    pub fn names(&self) -> Vec<&'static str> {
        [
            ("transmissive", self.transmissive),
            ("reflective", self.reflective),
            ("textured", self.textured),
            ("emissive", self.emissive),
            ("point_lights", self.point_lights),
            ("directional_lights", self.directional_lights),
            ("smooth_normals", self.smooth_normals),
            ("alpha_tested", self.alpha_tested),
            ("vertex_colors", self.vertex_colors),
        ]
        .into_iter()
        .filter_map(|(name, on)| on.then_some(name))
        .collect()
    }

    /// What `instances` of `meshes` and `materials` lit by `lights` need.
    fn analyse(
        meshes: &[Arc<TriMesh>],
        materials: &[Material],
        instances: &[RenderInstance],
        lights: &[Light],
    ) -> Self {
        let mut f = SceneFeatures {
            point_lights: lights
                .iter()
                .any(|l| matches!(l, Light::Point { .. } | Light::Spot { .. })),
            directional_lights: lights.iter().any(|l| matches!(l, Light::Directional { .. })),
            ..SceneFeatures::default()
        };
        for inst in instances {
            let (Some(mesh), Some(m)) = (meshes.get(inst.mesh as usize), materials.get(inst.material as usize)) else {
                continue;
            };
            f.transmissive |= m.is_transmissive();
            f.reflective |= m.is_reflective();
            f.textured |= m.is_textured() && mesh.uvs().is_some();
            f.emissive |= emits(m);
            f.smooth_normals |= mesh.normals().is_some();
            f.vertex_colors |= mesh.colors().is_some();
            f.alpha_tested |= m.is_masked();
        }
        f
    }
}

/// The flattened scene the kernel renders.
#[derive(Clone, Debug)]
pub struct RenderScene {
    /// Meshes, each stored once however many instances use it.
    pub meshes: Vec<Arc<TriMesh>>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Instances; index `i` is instance `i` of [`RenderScene::bvh`].
    pub instances: Vec<RenderInstance>,
    /// Instance names, for messages and statistics.
    pub instance_names: Vec<String>,
    /// Lights, in render space.
    pub lights: Vec<Light>,
    /// Field of view.
    pub camera: Camera,
    /// Camera pose in world space; the viewer changes it between frames
    /// without re-extracting.
    pub rig: OrbitRig,
    /// Where render space's origin lies in world space: near the camera's
    /// orbit centre at extract time (see [`render_origin`]). Instances and
    /// lights are moved by `-origin` and the camera is placed relative to
    /// it, so a scene far from the world origin is traced with small
    /// coordinates, whose rounding errors and ray offsets are those of a
    /// scene at the origin.
    pub origin: Vec3,
    /// Background and ambient light.
    pub environment: Environment,
    /// Two-level BVH over the instances.
    pub bvh: SceneBvh,
    /// What the scene needs.
    pub features: SceneFeatures,
    /// Emissive triangles, lights and the environment, as the path tracer
    /// samples them.
    pub light_set: LightSet,
    /// BVH build settings, kept for the lazily built flat tree.
    build: BuildParams,
    /// Whether the flat tree may be built ([`ExtractOptions::flat_bvh`]).
    allow_flat: bool,
    /// Every instance's triangles in one render-space BVH, built the first
    /// time [`RenderScene::flat_bvh`] asks for it (only the path tracer
    /// does, so Whitted renders and the viewer's start do not pay for it).
    flat_bvh: OnceLock<Option<FlatBvh>>,
    /// The lane tracer's records of this scene, built the first time a
    /// render takes the lanes ([`RenderScene::lane_tables`]).
    lane_tables: OnceLock<Option<LaneTables>>,
}

/// Why a scene could not be extracted.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ExtractError {
    /// `Scene::active_camera` is unset or lacks `Camera` and `OrbitRig`.
    NoCamera,
    /// An instance's `MeshRef` names an entity without a `Mesh`.
    DanglingMesh {
        /// The instance.
        instance: String,
    },
    /// An instance's `MaterialRef` names an entity without a `Material`.
    DanglingMaterial {
        /// The instance.
        instance: String,
    },
    /// An instance's transform is not finite or not invertible.
    SingularTransform {
        /// The instance.
        instance: String,
    },
}

impl fmt::Display for ExtractError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExtractError::NoCamera => write!(f, "the scene has no active camera"),
            ExtractError::DanglingMesh { instance } => write!(f, "instance '{instance}' refers to a missing mesh"),
            ExtractError::DanglingMaterial { instance } => {
                write!(f, "instance '{instance}' refers to a missing material")
            }
            ExtractError::SingularTransform { instance } => {
                write!(
                    f,
                    "instance '{instance}' has a transform that is not finite or not invertible"
                )
            }
        }
    }
}

impl std::error::Error for ExtractError {}

/// How [`extract_with`] builds the render data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ExtractOptions {
    /// Effort of the BVH builds: [`BuildQuality::Fast`] builds sooner and
    /// traces slower, [`BuildQuality::High`] the other way round.
    pub bvh_quality: BuildQuality,
    /// Keep every [`SceneFeatures`] feature on and read every vertex array,
    /// whatever the scene contains: the general renderer, which gives the
    /// same image as the specialised one, more slowly. It is the baseline
    /// that `lucent bench render --all-features` measures the saving
    /// against. Default `false`.
    pub all_features: bool,
    /// Let the path tracer build and use the one-level tree
    /// ([`RenderScene::flat_bvh`]), which traces faster but takes a second
    /// build over every triangle; `false` keeps it on the two-level tree,
    /// for a one-sample preview of a big scene, where that build costs more
    /// than it saves. The image is the same either way. Default `true`.
    pub flat_bvh: bool,
}

impl Default for ExtractOptions {
    fn default() -> Self {
        Self {
            bvh_quality: BuildQuality::Default,
            all_features: false,
            flat_bvh: true,
        }
    }
}

/// Flattens `scene` into render data and builds its BVHs (meshes in
/// parallel) with the default [`ExtractOptions`]. Instances are ordered by
/// entity so the result does not depend on the order hecs stores them in.
pub fn extract(scene: &Scene) -> Result<RenderScene, ExtractError> {
    extract_with(scene, &ExtractOptions::default())
}

/// [`extract`] with explicit options.
///
/// ```
/// use lucent_render::{BuildQuality, ExtractOptions, extract_with};
/// use lucent_scene::{Scene, components::{Camera, OrbitRig}};
/// let mut scene = Scene::default();
/// scene.add_camera("cam", Camera::default(), OrbitRig::default());
/// let options = ExtractOptions { bvh_quality: BuildQuality::Fast, ..ExtractOptions::default() };
/// let rs = extract_with(&scene, &options)?;
/// assert_eq!(rs.n_instanced_triangles(), 0);
/// # Ok::<(), lucent_render::ExtractError>(())
/// ```
pub fn extract_with(scene: &Scene, options: &ExtractOptions) -> Result<RenderScene, ExtractError> {
    let (camera, rig) = scene.camera().ok_or(ExtractError::NoCamera)?;
    let origin = render_origin(&rig);
    let Gathered {
        meshes,
        materials,
        instances,
        instance_names,
        bvh_instances,
        lights,
        features,
    } = gather(scene, origin, options.all_features)?;

    let params = BuildParams::for_quality(options.bvh_quality);
    let blas: Vec<Arc<MeshBvh>> = meshes
        .par_iter()
        .map(|m| Arc::new(MeshBvh::build(m, &params)))
        .collect();
    let bvh = SceneBvh::build(blas, bvh_instances, &params);

    let bounds = bvh.bounds();
    let scene_radius = if bounds.is_empty() {
        0.0
    } else {
        0.5 * bounds.extent().length()
    };
    // Without emissive materials there is no per-instance emitter table to
    // build or to consult: the set holds the point and directional lights.
    let emitting: &[RenderInstance] = if features.emissive { &instances } else { &[] };
    let environment = EnvLight::new(&scene.environment);
    let light_set = LightSet::with_environment(&meshes, &materials, emitting, &lights, environment, scene_radius);
    Ok(RenderScene {
        meshes,
        materials,
        instances,
        instance_names,
        lights,
        camera,
        rig,
        origin,
        environment: scene.environment.clone(),
        bvh,
        features,
        light_set,
        build: params,
        allow_flat: options.flat_bvh,
        flat_bvh: OnceLock::new(),
        lane_tables: OnceLock::new(),
    })
}

/// The [`SceneFeatures`] that [`extract_with`] would find for `scene` and
/// `options` (all of them with [`ExtractOptions::all_features`]), without
/// building any BVH: what `lucent info` lists.
///
/// ```
/// use lucent_render::{ExtractOptions, SceneFeatures, extract, scene_features};
/// use lucent_scene::{Scene, components::*};
/// use lucent_geom::{shapes, Affine3A, Vec3};
/// let mut scene = Scene::default();
/// let mesh = scene.add_mesh("ball", shapes::icosphere(1));
/// let glass = scene.add_material("glass", Material { kt: Vec3::ONE, ..Material::default() });
/// scene.add_instance("ball", mesh, glass, Affine3A::IDENTITY);
/// scene.add_camera("cam", Camera::default(), OrbitRig::default());
/// let features = scene_features(&scene, &ExtractOptions::default())?;
/// assert_eq!(features.names(), ["transmissive", "smooth_normals"]);
/// assert_eq!(features, extract(&scene)?.features);
/// let all = ExtractOptions { all_features: true, ..ExtractOptions::default() };
/// assert_eq!(scene_features(&scene, &all)?, SceneFeatures::ALL);
/// # Ok::<(), lucent_render::ExtractError>(())
/// ```
pub fn scene_features(scene: &Scene, options: &ExtractOptions) -> Result<SceneFeatures, ExtractError> {
    let (_, rig) = scene.camera().ok_or(ExtractError::NoCamera)?;
    Ok(gather(scene, render_origin(&rig), options.all_features)?.features)
}

/// The scene's instances, meshes, materials and lights in render space,
/// and what they need, before any BVH is built.
struct Gathered {
    meshes: Vec<Arc<TriMesh>>,
    materials: Vec<Material>,
    instances: Vec<RenderInstance>,
    instance_names: Vec<String>,
    bvh_instances: Vec<Instance>,
    lights: Vec<Light>,
    features: SceneFeatures,
}

/// Flattens the world's instances and lights into render space (moved by
/// `-origin`) and analyses what they need; `all` turns every feature on.
fn gather(scene: &Scene, origin: Vec3, all: bool) -> Result<Gathered, ExtractError> {
    let render_from_world = Affine3A::from_translation(-origin);
    let world = &scene.world;
    let mut rows: Vec<(Entity, Entity, Entity, String)> = world
        .query::<(Entity, &MeshRef, &MaterialRef, Option<&Name>)>()
        .iter()
        .map(|(e, m, mat, name)| (e, m.0, mat.0, name.map_or_else(|| format!("{e:?}"), |n| n.0.clone())))
        .collect();
    rows.sort_by_key(|r| r.0.to_bits());

    let mut mesh_index: HashMap<Entity, u32> = HashMap::new();
    let mut material_index: HashMap<Entity, u32> = HashMap::new();
    let mut meshes: Vec<Arc<TriMesh>> = Vec::new();
    let mut materials: Vec<Material> = Vec::new();
    let mut instances = Vec::with_capacity(rows.len());
    let mut instance_names = Vec::with_capacity(rows.len());
    let mut bvh_instances = Vec::with_capacity(rows.len());
    for (entity, mesh_e, material_e, name) in rows {
        let mesh = intern(&mut mesh_index, &mut meshes, mesh_e, || {
            world
                .get::<&Mesh>(mesh_e)
                .map(|m| m.0.clone())
                .map_err(|_| ExtractError::DanglingMesh { instance: name.clone() })
        })?;
        let material = intern(&mut material_index, &mut materials, material_e, || {
            world
                .get::<&Material>(material_e)
                .map(|m| (*m).clone())
                .map_err(|_| ExtractError::DanglingMaterial { instance: name.clone() })
        })?;
        let render_from_object = render_from_world * world_from_local(world, entity);
        let bvh_instance = Instance::new(render_from_object, mesh)
            .ok_or_else(|| ExtractError::SingularTransform { instance: name.clone() })?;
        bvh_instances.push(bvh_instance);
        let reads = VertexReads::of(&meshes[mesh as usize], &materials[material as usize], all);
        instances.push(RenderInstance {
            mesh,
            material,
            render_from_object,
            normal_render_from_object: render_from_object.matrix3.inverse().transpose(),
            reads,
        });
        instance_names.push(name);
    }

    let mut lights: Vec<(u64, Light)> = world
        .query::<(Entity, &Light)>()
        .iter()
        .map(|(e, l)| (e.to_bits().get(), l.translated(-origin)))
        .collect();
    lights.sort_by_key(|l| l.0);
    let lights: Vec<Light> = lights.into_iter().map(|(_, l)| l).collect();
    let features = if all {
        SceneFeatures::ALL
    } else {
        SceneFeatures::analyse(&meshes, &materials, &instances, &lights)
    };
    Ok(Gathered {
        meshes,
        materials,
        instances,
        instance_names,
        bvh_instances,
        lights,
        features,
    })
}

/// The origin of render space for a camera rig: its orbit centre rounded
/// to a multiple of the power of two at or above a quarter of the orbit
/// radius. So the origin lies within a quarter radius of what the camera
/// looks at on every axis, and a scene of about the orbit's size has
/// coordinates of about its own size, whose rounding errors and ray offsets
/// are those of the same scene at the world origin. Rounding keeps the
/// origin at zero, and renders unchanged, for scenes whose orbit centre
/// lies within an eighth of a radius of the world origin; powers of two
/// keep the subtraction exact wherever it can be.
///
/// The grid must not be coarse: ray offsets scale with the coordinates, so
/// a small scene several radii from its render origin is offset by a few
/// thousandths of its size, which biases the path tracer (a grid of four
/// radii lost 0.15% of a Cornell box's light at scale 1e-3).
pub fn render_origin(rig: &OrbitRig) -> Vec3 {
    let rig = rig.sanitized();
    let grid = 2f32.powi((0.25 * rig.radius).log2().ceil() as i32);
    let origin = (rig.center / grid).round() * grid;
    if origin.is_finite() { origin } else { Vec3::ZERO }
}

/// The index of `entity`'s item in `items`, fetching and appending it the
/// first time it is seen, so items shared by several instances are stored once.
fn intern<T>(
    index: &mut HashMap<Entity, u32>,
    items: &mut Vec<T>,
    entity: Entity,
    fetch: impl FnOnce() -> Result<T, ExtractError>,
) -> Result<u32, ExtractError> {
    if let Some(&i) = index.get(&entity) {
        return Ok(i);
    }
    items.push(fetch()?);
    let i = (items.len() - 1) as u32;
    index.insert(entity, i);
    Ok(i)
}

impl RenderScene {
    /// Turns the environment map to `rotation_deg` about +y without
    /// re-extracting (the viewer's rotate key).
    pub fn set_environment_rotation(&mut self, rotation_deg: f32) {
        self.environment.rotation_deg = rotation_deg;
        self.light_set.set_environment_rotation(rotation_deg);
    }

    /// Radiance arriving from the unit direction `dir` from outside the
    /// scene: the environment map, or the constant background (black when
    /// neither gives light).
    #[inline]
    pub fn environment_radiance(&self, dir: Vec3) -> Vec3 {
        self.light_set.environment().map_or(Vec3::ZERO, |env| env.eval(dir))
    }

    /// Every instance's triangles in one render-space BVH, which the path
    /// tracer queries instead of the two-level [`RenderScene::bvh`]: built
    /// on the first call (a clone made after that keeps its own copy of the
    /// tree), `None` for heavily instanced or huge scenes (see
    /// [`FlatBvh::build`]) or when extracted without it
    /// ([`ExtractOptions::flat_bvh`]).
    pub fn flat_bvh(&self) -> Option<&FlatBvh> {
        if !self.allow_flat {
            return None;
        }
        self.flat_bvh
            .get_or_init(|| FlatBvh::build(&self.meshes, &self.instances, &self.build, MAX_FLAT_TRIANGLES))
            .as_ref()
    }

    /// The lane tracer's records of this scene (`crate::lane`), built on
    /// the first call and kept: they depend on the scene alone, so each
    /// render (each of the viewer's frames) does not rebuild them. `None`
    /// where the lanes cannot name every triangle.
    pub(crate) fn lane_tables(&self) -> Option<&LaneTables> {
        self.lane_tables.get_or_init(|| LaneTables::build(self)).as_ref()
    }

    /// Builds now what a render with `settings` would otherwise build on
    /// its first call and keep: the path tracer's flat tree
    /// ([`RenderScene::flat_bvh`]) and, where the lane tracer takes the
    /// scene, its triangle records (128 bytes a triangle: 9 ms for the
    /// seed scene's 80 000). A caller that times its renders calls it
    /// first, so that their times are rendering alone, as the two-level
    /// tree's build is not in them.
    ///
    /// ```
    /// use lucent_render::{extract, render, RenderSettings, Integrator};
    /// let rs = extract(&lucent_scene::fixtures::ball_under_sun())?;
    /// let settings = RenderSettings { integrator: Integrator::Path, width: 8, height: 8, spp: 1, ..RenderSettings::default() };
    /// rs.prepare(&settings);
    /// assert!(rs.flat_bvh().is_some());
    /// let prepared = render(&rs, &settings, &|_| {});
    /// let unprepared = render(&extract(&lucent_scene::fixtures::ball_under_sun())?, &settings, &|_| {});
    /// assert_eq!(prepared.film, unprepared.film);
    /// # Ok::<(), lucent_render::ExtractError>(())
    /// ```
    pub fn prepare(&self, settings: &RenderSettings) {
        if settings.integrator == Integrator::Path {
            let _ = self.flat_bvh();
            if settings.lanes {
                let _ = self.lane_tables();
            }
        }
    }

    /// Triangles over all instances.
    pub fn n_instanced_triangles(&self) -> usize {
        self.instances
            .iter()
            .map(|i| self.meshes[i.mesh as usize].n_triangles())
            .sum()
    }

    /// The camera rig in render space ([`RenderScene::origin`] subtracted).
    pub fn render_rig(&self) -> OrbitRig {
        let rig = self.rig.sanitized();
        OrbitRig {
            center: rig.center - self.origin,
            ..rig
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::shapes;

    /// Two instances of one glass ball: built here, not taken from
    /// `fixtures`, because the tests count what the two share.
    fn scene() -> (Scene, Entity, Entity) {
        let mut scene = Scene::default();
        let mesh = scene.add_mesh("ball", shapes::icosphere(1));
        let mat = scene.add_material(
            "glass",
            Material {
                kt: Vec3::splat(0.5),
                ..Material::default()
            },
        );
        scene.add_instance("a", mesh, mat, Affine3A::IDENTITY);
        scene.add_instance("b", mesh, mat, Affine3A::from_translation(Vec3::X * 3.0));
        scene.add_camera("cam", Camera::default(), OrbitRig::default());
        (scene, mesh, mat)
    }

    #[test]
    fn shared_meshes_and_materials_are_stored_once() {
        let (scene, _, _) = scene();
        let rs = extract(&scene).map_err(|e| e.to_string());
        let Ok(rs) = rs else { panic!("{rs:?}") };
        assert_eq!((rs.meshes.len(), rs.materials.len(), rs.instances.len()), (1, 1, 2));
        assert_eq!(rs.bvh.meshes().len(), 1);
        let stored: usize = rs.meshes.iter().map(|m| m.n_triangles()).sum();
        assert_eq!((rs.n_instanced_triangles(), stored), (160, 80));
        assert_eq!(rs.instance_names, vec!["a".to_owned(), "b".to_owned()]);
        assert_eq!(rs.features.names(), ["transmissive", "smooth_normals"]);
    }

    #[test]
    fn features_come_from_what_instances_use_and_all_features_turns_every_one_on() {
        let (mut scene, ball, _) = scene();
        let tex = lucent_scene::components::Texture::new(1, 1, vec![Vec3::ONE])
            .map(Arc::new)
            .ok();
        let textured = Material {
            diffuse_map: tex,
            ..Material::default()
        };
        let lamp = Material {
            emission: Vec3::splat(2.0),
            ..Material::default()
        };
        let mirror = Material {
            kr: Vec3::ONE,
            ..Material::default()
        };
        // A material or mesh no instance uses turns nothing on.
        scene.add_material("unused mirror", mirror.clone());
        let colours = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]])
            .and_then(|m| m.with_colors(vec![Vec3::ONE; 3]))
            .unwrap_or_else(|e| panic!("{e}"));
        scene.add_mesh("unused colours", colours);
        let features = |s: &Scene, all: bool| {
            let options = ExtractOptions {
                all_features: all,
                ..ExtractOptions::default()
            };
            let f = scene_features(s, &options).unwrap_or_else(|e| panic!("{e}"));
            let rs = extract_with(s, &options).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(f, rs.features, "scene_features agrees with extract");
            rs
        };
        let rs = features(&scene, false);
        assert_eq!(rs.features.names(), ["transmissive", "smooth_normals"]);
        // The icosphere has UVs, but nothing textured reads them.
        assert!(rs.meshes[0].uvs().is_some());
        let reads = VertexReads {
            normals: true,
            uvs: false,
            colors: false,
            tangents: false,
        };
        assert!(rs.instances.iter().all(|i| i.reads == reads));
        // No emitter: no per-instance emitter table.
        assert!(rs.light_set.is_empty() && rs.light_set.emitters().is_empty());

        let all = features(&scene, true);
        assert_eq!(all.features, SceneFeatures::ALL);
        assert!(
            all.instances
                .iter()
                .all(|i| i.reads == VertexReads { uvs: true, ..reads })
        );
        assert!(
            rs.light_set.bytes() < all.light_set.bytes(),
            "the emitter table is left out"
        );

        // A textured instance on a mesh with UVs, a lamp, lights of both kinds.
        let tex_m = scene.add_material("tex", textured.clone());
        let lamp_m = scene.add_material("lamp", lamp);
        scene.add_instance("textured", ball, tex_m, Affine3A::IDENTITY);
        scene.add_instance("lamp", ball, lamp_m, Affine3A::from_translation(Vec3::Y * 4.0));
        scene.add_light(
            "sun",
            Light::Directional {
                to_light: Vec3::Y,
                intensity: Vec3::ONE,
            },
        );
        let rs = features(&scene, false);
        assert_eq!(
            rs.features.names(),
            [
                "transmissive",
                "textured",
                "emissive",
                "directional_lights",
                "smooth_normals"
            ]
        );
        let textured_reads: Vec<bool> = rs.instances.iter().map(|i| i.reads.uvs).collect();
        assert_eq!(textured_reads, [false, false, true, false]);
        assert_eq!(rs.light_set.emitters().len(), 80);
        assert!(rs.light_set.emitter(3, 0).is_some() && rs.light_set.emitter(0, 0).is_none());

        // A texture on a mesh without UVs has nothing to look up.
        let (mut bare, _, _) = self::scene();
        let plain = bare.add_mesh(
            "no uvs",
            TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]).unwrap_or_else(|e| panic!("{e}")),
        );
        let tex_m = bare.add_material("tex", textured);
        bare.add_instance("no uvs", plain, tex_m, Affine3A::IDENTITY);
        assert!(!features(&bare, false).features.textured);
    }

    #[test]
    fn render_space_starts_near_a_far_camera_and_at_zero_near_the_origin() {
        let rig = |center: Vec3, radius: f32| OrbitRig {
            center,
            radius,
            ..OrbitRig::default()
        };
        // Around the world origin nothing moves (renders stay as they were):
        // the grid for R = 5.2 is 2, so centres within 1 of zero give zero.
        assert_eq!(render_origin(&rig(Vec3::new(0.0, 0.55, 0.0), 5.2)), Vec3::ZERO);
        assert_eq!(render_origin(&rig(Vec3::splat(0.99), 5.2)), Vec3::ZERO);
        assert_eq!(render_origin(&rig(Vec3::splat(7.0), 5.2)), Vec3::splat(8.0));
        // Far away the origin is a multiple of 2 (the power of two at or
        // above R / 4) within R / 4 of the centre on each axis.
        let far = Vec3::new(1e6 + 0.35, -1e6, 123_456.7);
        let o = render_origin(&rig(far, 5.2));
        assert!((o - far).abs().max_element() <= 1.3, "{o}");
        assert_eq!(o % 2.0, Vec3::ZERO);
        // A small scene far away: 1e-3 units, ten sizes out.
        let small = Vec3::new(0.02, 0.01, -0.02);
        let o_small = render_origin(&rig(small, 4e-3));
        assert!((o_small - small).abs().max_element() <= 1e-3, "{o_small}");
        assert_eq!(render_origin(&rig(Vec3::NAN, 1.0)), Vec3::ZERO);

        // Extract moves instances and point lights by -origin, and the
        // camera follows: the render-space rig looks at the same place.
        let (mut scene, _, _) = scene();
        scene.add_light(
            "bulb",
            Light::Point {
                position: far + Vec3::Y,
                intensity: Vec3::ONE,
            },
        );
        if let Some(mut r) = scene.camera_rig_mut() {
            r.center = far;
        }
        let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
        let o = scene.camera().map_or(Vec3::NAN, |(_, r)| render_origin(&r));
        assert!(o != Vec3::ZERO && (o - far).abs().max_element() <= 16.0, "{o}");
        assert_eq!(rs.origin, o);
        assert_eq!(
            rs.instances[1].render_from_object.translation,
            (Vec3::X * 3.0 - o).into()
        );
        assert_eq!(rs.render_rig().center, far - o);
        assert!(matches!(rs.lights[0], Light::Point { position, .. } if position == far + Vec3::Y - o));
    }

    #[test]
    fn broken_worlds_are_errors_not_panics() {
        let err = |s: &Scene| extract(s).map(|_| ()).map_err(|e| e.to_string());
        let (mut s, _, _) = scene();
        s.active_camera = None;
        assert_eq!(err(&s), Err("the scene has no active camera".to_owned()));

        let (mut s, _, mat) = scene();
        let ghost = s.world.spawn(());
        s.add_instance("ghost", ghost, mat, Affine3A::IDENTITY);
        assert_eq!(err(&s), Err("instance 'ghost' refers to a missing mesh".to_owned()));

        let (mut s, mesh, _) = scene();
        let ghost = s.world.spawn(());
        s.add_instance("bare", mesh, ghost, Affine3A::IDENTITY);
        assert_eq!(err(&s), Err("instance 'bare' refers to a missing material".to_owned()));

        let (mut s, mesh, mat) = scene();
        s.add_instance("flat", mesh, mat, Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0)));
        assert_eq!(
            err(&s),
            Err("instance 'flat' has a transform that is not finite or not invertible".to_owned())
        );
    }
}
