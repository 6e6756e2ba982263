//! Small scenes built in code, by name, for tests, examples and
//! benchmarks across the crates, so each need not hand-build its own.
//!
//! A fixture is a plain [`Scene`]; callers change what their test needs
//! (settings, environment, extra entities) on the returned value.
//!
//! ```
//! use lucent_scene::fixtures;
//! let scene = fixtures::ball_under_sun();
//! assert_eq!(scene.counts().instances, 1);
//! assert!(scene.camera().is_some());
//! ```

use crate::Scene;
use crate::components::{Camera, Light, Material, OrbitRig};
use lucent_geom::{Affine3A, Vec3, shapes};

/// One white icosphere (2 subdivisions, radius 1) at the origin, lit by a
/// white directional light from straight above, seen by the default camera
/// and rig.
pub fn ball_under_sun() -> Scene {
    let mut scene = Scene::default();
    let mesh = scene.add_mesh("ball", shapes::icosphere(2));
    let white = scene.add_material("white", Material::default());
    scene.add_instance("ball", mesh, white, Affine3A::IDENTITY);
    scene.add_light(
        "sun",
        Light::Directional {
            to_light: Vec3::Y,
            intensity: Vec3::ONE,
        },
    );
    scene.add_camera("cam", Camera::default(), OrbitRig::default());
    scene
}
