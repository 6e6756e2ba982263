//! Small scenes built in code, by name, for tests, examples and
//! benchmarks across the crates, so each need not hand-build its own.
//!
//! A fixture is a plain [`Scene`] with the default environment unless it
//! says otherwise; callers change what their test needs (settings,
//! environment, extra entities) on the returned value. A test that needs a
//! scene of its own shape (a concave mesh, one triangle, a scale sweep)
//! builds it, and says why.
//!
//! ```
//! use lucent_scene::fixtures;
//! let scene = fixtures::ball_under_sun();
//! assert_eq!(scene.counts().instances, 1);
//! assert!(scene.camera().is_some());
//! ```

use crate::components::{Camera, Light, Material, OrbitRig};
use crate::{Environment, Scene};
use lucent_geom::{Affine3A, Quat, TriMesh, Vec3, shapes};

/// An environment that adds no light: black background, no ambient term,
/// so only the scene's own lights and emitters show.
pub fn dark() -> Environment {
    Environment {
        background: Vec3::ZERO,
        ambient: Vec3::ZERO,
        shadowed_ambient: false,
        ..Environment::default()
    }
}

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

/// A white (albedo 1) sphere of flat facets (an icosphere, 2 subdivisions,
/// radius 1) at the origin under `environment`, seen by a 50-degree camera
/// on the default rig: a furnace test, since a white convex object under a
/// uniform sky reflects exactly what it receives.
pub fn furnace_sphere(environment: Environment) -> Scene {
    let mut scene = Scene {
        environment,
        ..Scene::default()
    };
    let ball = shapes::icosphere(2);
    let flat = TriMesh::new(ball.positions().to_vec(), ball.indices().to_vec()).unwrap_or_default();
    let mesh = scene.add_mesh("ball", flat);
    let white = scene.add_material(
        "white",
        Material {
            kd: Vec3::ONE,
            ..Material::default()
        },
    );
    scene.add_instance("ball", mesh, white, Affine3A::IDENTITY);
    scene.add_camera("cam", Camera { fov_y_deg: 50.0 }, OrbitRig::default());
    scene
}

/// A closed box (the unit cube scaled to 4 wide) turned inside out, its
/// walls diffuse of `albedo` and all emitting `emission`, seen from inside
/// (flat normals, 100-degree camera) in a black environment: the path
/// tracer's white furnace, whose pixels converge to a geometric series.
pub fn glowing_box(albedo: f32, emission: f32) -> Scene {
    let mut scene = Scene {
        environment: dark(),
        ..Scene::default()
    };
    let cube = shapes::cuboid();
    let inward = cube.indices().iter().map(|&[a, b, c]| [a, c, b]).collect();
    let mesh = scene.add_mesh(
        "box",
        TriMesh::new(cube.positions().to_vec(), inward).unwrap_or_default(),
    );
    let mat = scene.add_material(
        "wall",
        Material {
            kd: Vec3::splat(albedo),
            emission: Vec3::splat(emission),
            ..Material::default()
        },
    );
    scene.add_instance("box", mesh, mat, Affine3A::from_scale(Vec3::splat(4.0)));
    let rig = OrbitRig {
        center: Vec3::ZERO,
        radius: 1.0,
        theta: 0.2,
        phi: 1.0,
    };
    scene.add_camera("cam", Camera { fov_y_deg: 100.0 }, rig);
    scene
}

/// A floor of `material`: the unit plane scaled to 100 wide at y = 0,
/// facing up, seen by the default camera; no lights.
pub fn floor(material: Material) -> Scene {
    let mut scene = Scene::default();
    let plane = scene.add_mesh("plane", shapes::plane());
    let mat = scene.add_material("floor", material);
    scene.add_instance("floor", plane, mat, Affine3A::from_scale(Vec3::splat(100.0)));
    scene.add_camera("cam", Camera::default(), OrbitRig::default());
    scene
}

/// [`floor`] with a ceiling of `ceiling` (the same plane facing down) at
/// `height`: two parallel planes for light to bounce between.
pub fn floor_and_ceiling(floor_material: Material, ceiling: Material, height: f32) -> Scene {
    let mut scene = floor(floor_material);
    let plane = scene.add_mesh("ceiling", shapes::plane());
    let mat = scene.add_material("ceiling", ceiling);
    let xf = Affine3A::from_scale_rotation_translation(
        Vec3::splat(100.0),
        Quat::from_rotation_x(std::f32::consts::PI),
        Vec3::new(0.0, height, 0.0),
    );
    scene.add_instance("ceiling", plane, mat, xf);
    scene
}

/// A varnished floor (diffuse 0.4 beside a smooth mirror lobe of 0.4) at
/// y = 0 under a diffuse ceiling (albedo 0.5) at y = 2 that faces down,
/// lit by a unit point light between them, in a [`dark`] environment: a
/// surface that is both diffuse and a mirror, like the seed scene's floor.
pub fn varnished_floor_under_ceiling() -> Scene {
    let varnished = Material {
        kd: Vec3::splat(0.4),
        kr: Vec3::splat(0.4),
        ..Material::default()
    };
    floor_under_lit_ceiling(varnished)
}

/// A mirror floor (reflectance 0.8) at y = 0 under a diffuse ceiling
/// (albedo 0.5) at y = 2 that faces down, lit by a unit point light between
/// them, in a [`dark`] environment: paths that must pass a mirror before
/// they reach diffuse light.
pub fn mirror_under_ceiling() -> Scene {
    let mirror = Material {
        kd: Vec3::ZERO,
        kr: Vec3::splat(0.8),
        ..Material::default()
    };
    floor_under_lit_ceiling(mirror)
}

/// `floor` at y = 0 under a diffuse ceiling (albedo 0.5) at y = 2 that
/// faces down, a unit point light between them, in a [`dark`] environment.
fn floor_under_lit_ceiling(floor: Material) -> Scene {
    let grey = Material {
        kd: Vec3::splat(0.5),
        ..Material::default()
    };
    let mut scene = floor_and_ceiling(floor, grey, 2.0);
    scene.environment = dark();
    scene.add_light(
        "bulb",
        Light::Point {
            position: Vec3::new(0.0, 1.0, 0.0),
            intensity: Vec3::ONE,
        },
    );
    scene
}
