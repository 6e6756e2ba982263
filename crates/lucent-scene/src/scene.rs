//! The `Scene`: the ECS world plus the scene-wide settings beside it.

use crate::components::{Camera, Light, Material, MaterialRef, Mesh, MeshRef, Name, OrbitRig, Transform};
use hecs::{Entity, World};
use lucent_geom::{Affine3A, TriMesh, Vec3};
use std::sync::Arc;

/// How the Whitted integrator evaluates the Phong model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Shading {
    /// Lighting at the three vertices, interpolated across the triangle (the
    /// report's S10).
    #[default]
    Gouraud,
    /// Lighting at the hit point with the interpolated normal.
    Phong,
}

impl Shading {
    /// Names as written in scene files and on the command line.
    pub const NAMES: [(&'static str, Shading); 2] = [("gouraud", Shading::Gouraud), ("phong", Shading::Phong)];

    /// The shading mode called `name`.
    pub fn from_name(name: &str) -> Option<Shading> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|&(_, s)| s)
    }

    /// This mode's name.
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, s)| *s == self)
            .map_or("gouraud", |(n, _)| n)
    }
}

/// Which light transport algorithm renders the image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Integrator {
    /// The seed report's Whitted ray tracer: Phong local lighting, shadow
    /// rays, mirror and refraction rays weighted by `kr` and `kt`.
    #[default]
    Whitted,
    /// Unidirectional path tracing of physically based BSDFs, with
    /// next-event estimation and multiple importance sampling.
    Path,
}

impl Integrator {
    /// Names as written in scene files and on the command line.
    pub const NAMES: [(&'static str, Integrator); 2] = [("whitted", Integrator::Whitted), ("path", Integrator::Path)];

    /// The integrator called `name`.
    pub fn from_name(name: &str) -> Option<Integrator> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|&(_, i)| i)
    }

    /// This integrator's name.
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(_, i)| *i == self)
            .map_or("whitted", |(n, _)| n)
    }
}

/// Light and colour that belong to the whole scene rather than to an entity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment {
    /// Radiance of rays that leave the scene (linear RGB).
    pub background: Vec3,
    /// The report's ambient light Ia.
    pub ambient: Vec3,
    /// Report semantics: shadow rays also darken the ambient term, so opaque
    /// shadows are black. When false, ambient light is never shadowed.
    pub shadowed_ambient: bool,
}

impl Default for Environment {
    fn default() -> Self {
        Self {
            background: Vec3::ZERO,
            ambient: Vec3::splat(0.2),
            shadowed_ambient: true,
        }
    }
}

/// Image and quality settings for a render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples (primary rays) per pixel.
    pub spp: u32,
    /// Path length limit. Whitted: the deepest reflection/refraction
    /// recursion (0 traces camera rays and their shadow rays only). Path:
    /// Mitsuba's `max_depth`, the longest path in segments counted from the
    /// camera (1 shows only emitters seen directly, 2 adds direct light, and
    /// so on); a Whitted depth `d` follows the same chains as a path depth
    /// `d + 2`.
    pub max_depth: u32,
    /// Rays whose accumulated weight falls below this are not traced (S11).
    pub min_weight: f32,
    /// Path tracer: Russian roulette may end a path once it has bounced
    /// this many times (Mitsuba's `rr_depth`; 5 by default). Lower is
    /// faster and noisier; it adds no bias.
    pub rr_depth: u32,
    /// Gouraud or per-pixel Phong.
    pub shading: Shading,
    /// Seed of the per-pixel sample streams.
    pub seed: u64,
    /// Whitted (the report's model) or path tracing.
    pub integrator: Integrator,
    /// Denoise the finished image (path tracer only): the app runs Intel
    /// Open Image Denoise guided by the albedo and normal buffers.
    pub denoise: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 360,
            spp: 1,
            max_depth: 5,
            min_weight: 0.01,
            rr_depth: 5,
            shading: Shading::Gouraud,
            seed: 0,
            integrator: Integrator::Whitted,
            denoise: false,
        }
    }
}

/// A scene: the world of entities and the settings that sit beside it.
#[derive(Default)]
pub struct Scene {
    /// All entities.
    pub world: World,
    /// The camera entity rendered from (needs `Camera` and `OrbitRig`).
    pub active_camera: Option<Entity>,
    /// Background and ambient light.
    pub environment: Environment,
    /// Default render settings (a scene file's `[render]` table).
    pub settings: RenderSettings,
}

/// Entity counts by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EntityCounts {
    /// Mesh entities.
    pub meshes: usize,
    /// Material entities.
    pub materials: usize,
    /// Instances (entities drawing a mesh).
    pub instances: usize,
    /// Lights.
    pub lights: usize,
    /// Cameras.
    pub cameras: usize,
    /// Triangles over all instances.
    pub instanced_triangles: usize,
}

impl Scene {
    /// Adds a mesh entity; instances refer to it by the returned entity.
    pub fn add_mesh(&mut self, name: &str, mesh: TriMesh) -> Entity {
        self.world.spawn((Name(name.to_owned()), Mesh(Arc::new(mesh))))
    }

    /// Adds a material entity.
    pub fn add_material(&mut self, name: &str, material: Material) -> Entity {
        self.world.spawn((Name(name.to_owned()), material))
    }

    /// Adds an instance of `mesh` with `material`, placed by `world_from_object`.
    pub fn add_instance(&mut self, name: &str, mesh: Entity, material: Entity, world_from_object: Affine3A) -> Entity {
        self.world.spawn((
            Name(name.to_owned()),
            Transform(world_from_object),
            MeshRef(mesh),
            MaterialRef(material),
        ))
    }

    /// Adds a light.
    pub fn add_light(&mut self, name: &str, light: Light) -> Entity {
        self.world.spawn((Name(name.to_owned()), light))
    }

    /// Adds a camera; it becomes the active one if there was none.
    pub fn add_camera(&mut self, name: &str, camera: Camera, rig: OrbitRig) -> Entity {
        let e = self.world.spawn((Name(name.to_owned()), camera, rig));
        self.active_camera.get_or_insert(e);
        e
    }

    /// The active camera's intrinsics and rig, if there is one.
    pub fn camera(&self) -> Option<(Camera, OrbitRig)> {
        let e = self.active_camera?;
        let mut q = self.world.query_one::<(&Camera, &OrbitRig)>(e);
        q.get().ok().map(|(c, r)| (*c, *r))
    }

    /// Mutable access to the active camera's rig.
    pub fn camera_rig_mut(&mut self) -> Option<hecs::RefMut<'_, OrbitRig>> {
        self.world.get::<&mut OrbitRig>(self.active_camera?).ok()
    }

    /// How many entities of each kind the world holds.
    pub fn counts(&self) -> EntityCounts {
        let mut c = EntityCounts {
            meshes: self.world.query::<&Mesh>().iter().count(),
            materials: self.world.query::<&Material>().iter().count(),
            lights: self.world.query::<&Light>().iter().count(),
            cameras: self.world.query::<&Camera>().iter().count(),
            ..EntityCounts::default()
        };
        for mesh_ref in self.world.query::<&MeshRef>().iter() {
            c.instances += 1;
            if let Ok(mesh) = self.world.get::<&Mesh>(mesh_ref.0) {
                c.instanced_triangles += mesh.0.n_triangles();
            }
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_geom::shapes;

    #[test]
    fn builds_a_scene_and_counts_it() {
        let mut scene = Scene::default();
        let ball = scene.add_mesh("ball", shapes::icosphere(1));
        let grey = scene.add_material("grey", Material::default());
        scene.add_instance("a", ball, grey, Affine3A::IDENTITY);
        scene.add_instance("b", ball, grey, Affine3A::from_translation(Vec3::X));
        scene.add_light(
            "sun",
            Light::Directional {
                to_light: Vec3::Y,
                intensity: Vec3::ONE,
            },
        );
        let cam = scene.add_camera("cam", Camera::default(), OrbitRig::default());
        assert_eq!(scene.active_camera, Some(cam));
        let c = scene.counts();
        assert_eq!(
            (
                c.meshes,
                c.materials,
                c.instances,
                c.lights,
                c.cameras,
                c.instanced_triangles
            ),
            (1, 1, 2, 1, 1, 160)
        );
        if let Some(mut rig) = scene.camera_rig_mut() {
            rig.radius = 9.0;
        }
        assert_eq!(scene.camera().map(|(_, r)| r.radius), Some(9.0));
    }

    #[test]
    fn shading_names_round_trip() {
        for (name, s) in Shading::NAMES {
            assert_eq!(Shading::from_name(name), Some(s));
            assert_eq!(s.name(), name);
        }
        assert_eq!(Shading::from_name("flat"), None);
    }
}
