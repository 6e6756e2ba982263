//! "Model only what the scene requires": the renderer specialised on a
//! scene's features gives the same bytes as the general one that
//! `ExtractOptions::all_features` forces, for both integrators.

use lucent_geom::{Affine3A, Named, Vec3, shapes};
use lucent_render::{ExtractOptions, Film, Integrator, RayStats, SceneFeatures, Shading, extract_with, render};
use lucent_scene::Scene;
use lucent_scene::components::{Camera, Light, Material, OrbitRig, Texture};
use lucent_tests::{load_repo_scene, render_scene};
use std::sync::Arc;

/// Renders `scene` specialised and with every feature on, at a small size,
/// with each integrator (Whitted in both shadings), and asserts that the
/// films (sums of linear radiance, to the bit) and the ray counts agree.
/// Returns the specialised features.
fn assert_same_bytes(label: &str, scene: &Scene, (width, height, spp): (u32, u32, u32)) -> SceneFeatures {
    let extract = |all_features| {
        let options = ExtractOptions {
            all_features,
            ..ExtractOptions::default()
        };
        extract_with(scene, &options).unwrap_or_else(|e| panic!("{label}: {e}"))
    };
    let (lean, all) = (extract(false), extract(true));
    assert_eq!(all.features, SceneFeatures::ALL);
    for (integrator, shading) in [
        (Integrator::Whitted, Shading::Gouraud),
        (Integrator::Whitted, Shading::Phong),
        (Integrator::Path, Shading::Phong),
    ] {
        let mut settings = scene.settings;
        (settings.width, settings.height, settings.spp, settings.seed) = (width, height, spp, 3);
        (settings.integrator, settings.shading) = (integrator, shading);
        if integrator == Integrator::Path {
            settings.max_depth = settings.max_depth.clamp(4, 8);
            // The scalar path tracer is the one specialised on the
            // features; the lane tracer has no general variant to compare
            // with (it turns the all-features scene down, as it turns down
            // any scene with alpha tests, vertex colours or tangents).
            settings.lanes = false;
        }
        let run = |rs| -> (Film, RayStats) {
            let out = render(rs, &settings, &|_| {});
            (out.film, out.stats)
        };
        let (a, b) = (run(&lean), run(&all));
        let what = format!("{label}, {} {}", integrator.name(), shading.name());
        assert_eq!(a.1, b.1, "{what}: ray counts");
        assert!(
            a.0 == b.0,
            "{what}: the specialised film differs from the all-features one"
        );
        assert!(
            a.0.to_linear().iter().any(|p| p.max_element() > 0.0),
            "{what}: the image is not black"
        );
    }
    lean.features
}

#[test]
fn the_seed_scene_renders_the_same_specialised() {
    let scene = load_repo_scene("res/scenes/seed.toml");
    let f = assert_same_bytes("seed", &scene, (48, 27, 2));
    assert_eq!(
        f.names(),
        [
            "transmissive",
            "reflective",
            "textured",
            "directional_lights",
            "smooth_normals"
        ]
    );
}

#[test]
fn the_seed_scene_without_its_glass_sphere_renders_the_same_specialised() {
    let mut scene = load_repo_scene("res/scenes/seed.toml");
    assert_eq!(scene.remove_instances("sphere"), 1);
    let f = assert_same_bytes("seed without the sphere", &scene, (48, 27, 2));
    assert!(!f.transmissive && f.reflective && f.textured, "{f:?}");
}

#[test]
fn the_mitsuba_cornell_box_renders_the_same_specialised() {
    let scene = load_repo_scene("res/scenes/cornell-mitsuba.toml");
    let f = assert_same_bytes("cornell-mitsuba", &scene, (24, 24, 4));
    assert_eq!(f.names(), ["transmissive", "reflective", "emissive", "smooth_normals"]);
}

/// A textured floor, a cube with vertex colours, a glowing panel, a point
/// and a directional light: every feature but transmission and mirrors.
fn textured_scene() -> Scene {
    let mut scene = Scene::default();
    let texels = (0..16)
        .map(|i| Vec3::new((i % 4) as f32 / 3.0, (i / 4) as f32 / 3.0, 0.5))
        .collect();
    let texture = Texture::new(4, 4, texels).map(Arc::new).ok();
    assert!(texture.is_some());
    let floor = scene.add_mesh("plane", shapes::plane());
    let checker = scene.add_material(
        "checker",
        Material {
            diffuse_map: texture,
            ks: Vec3::splat(0.2),
            shininess: 20.0,
            ..Material::default()
        },
    );
    scene.add_instance("floor", floor, checker, Affine3A::from_scale(Vec3::splat(4.0)));
    let cube = shapes::cuboid();
    let colours = cube
        .positions()
        .iter()
        .map(|p| (*p + Vec3::splat(0.75)).min(Vec3::ONE))
        .collect();
    let cube = cube.with_colors(colours).unwrap_or_else(|e| panic!("{e}"));
    let cube = scene.add_mesh("cube", cube);
    let white = scene.add_material("white", Material::default());
    scene.add_instance(
        "cube",
        cube,
        white,
        Affine3A::from_translation(Vec3::new(0.0, 0.5, 0.0)),
    );
    let panel = scene.add_mesh("panel", shapes::plane());
    let lamp = scene.add_material(
        "lamp",
        Material {
            kd: Vec3::ZERO,
            emission: Vec3::splat(4.0),
            ..Material::default()
        },
    );
    // Turned to face down onto the cube.
    scene.add_instance(
        "panel",
        panel,
        lamp,
        Affine3A::from_translation(Vec3::new(0.0, 2.5, 0.0)) * Affine3A::from_rotation_x(std::f32::consts::PI),
    );
    scene.add_light(
        "bulb",
        Light::Point {
            position: Vec3::new(1.5, 2.0, 1.0),
            intensity: Vec3::splat(3.0),
        },
    );
    scene.add_light(
        "sun",
        Light::Directional {
            to_light: Vec3::new(0.3, 1.0, 0.2).normalize(),
            intensity: Vec3::splat(0.5),
        },
    );
    scene.add_camera(
        "cam",
        Camera::default(),
        OrbitRig {
            center: Vec3::new(0.0, 0.5, 0.0),
            radius: 5.0,
            ..OrbitRig::default()
        },
    );
    scene.settings.max_depth = 6;
    scene
}

#[test]
fn a_textured_scene_with_vertex_colours_and_lamps_renders_the_same_specialised() {
    let scene = textured_scene();
    let f = assert_same_bytes("textured", &scene, (32, 24, 2));
    assert_eq!(
        f.names(),
        [
            "textured",
            "emissive",
            "point_lights",
            "directional_lights",
            "smooth_normals",
            "vertex_colors"
        ]
    );
    // The texture is read: without it the picture changes.
    let mut plain = textured_scene();
    for m in plain.world.query_mut::<&mut Material>() {
        m.diffuse_map = None;
    }
    let picture = |s: &Scene| render_scene(s, |r| (r.width, r.height) = (32, 24)).to_srgb8();
    assert_ne!(picture(&scene), picture(&plain));
}
