//! The `Scene`: the ECS world plus the scene-wide settings beside it.

use crate::RenderSettings;
use crate::components::{Camera, Light, Material, MaterialRef, Mesh, MeshRef, Name, OrbitRig, Transform};
use hecs::{Entity, World};
use lucent_geom::{Affine3A, TriMesh, Vec3};
use lucent_shading::EnvironmentMap;
use std::sync::Arc;

/// Light and colour that belong to the whole scene rather than to an entity.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    /// Radiance of rays that leave the scene (linear RGB) when there is no
    /// `map`: a constant environment, which the path tracer samples as a
    /// light (the one-texel map).
    pub background: Vec3,
    /// An HDR panorama of the radiance arriving from every direction
    /// (equirectangular, Mitsuba's convention; see
    /// [`lucent_shading::environment`]). When set it replaces `background`.
    pub map: Option<Arc<EnvironmentMap>>,
    /// Scale of the map's radiance.
    pub intensity: f32,
    /// Rotation of the map about +y in degrees (right-handed: positive turns
    /// +z towards +x), Mitsuba's `to_world` rotation about y.
    pub rotation_deg: f32,
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
            map: None,
            intensity: 1.0,
            rotation_deg: 0.0,
            ambient: Vec3::splat(0.2),
            shadowed_ambient: true,
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

    /// Removes every instance named `name` (the meshes and materials they
    /// used stay); returns how many there were.
    pub fn remove_instances(&mut self, name: &str) -> usize {
        let found: Vec<Entity> = self
            .world
            .query_mut::<(Entity, &Name, &MeshRef)>()
            .into_iter()
            .filter(|(_, n, _)| n.0 == name)
            .map(|(e, _, _)| e)
            .collect();
        for &e in &found {
            let _ = self.world.despawn(e);
        }
        found.len()
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
        // Built by hand, not from `fixtures`: the builder is what is tested.
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
        // Instances only: the material named "grey" stays.
        assert_eq!((scene.remove_instances("a"), scene.remove_instances("grey")), (1, 0));
        assert_eq!((scene.counts().instances, scene.counts().materials), (1, 1));
    }
}
