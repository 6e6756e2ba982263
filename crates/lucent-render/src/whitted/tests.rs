//! The report's rules, each checked on a small scene with a known answer.

use super::*;
use crate::{extract, render};
use lucent_geom::{Affine3A, TriMesh, shapes};
use lucent_scene::components::{Camera, Light, OrbitRig};
use lucent_scene::{Scene, fixtures};

const SUN: Light = Light::Directional {
    to_light: Vec3::Y,
    intensity: Vec3::ONE,
};

fn matte(k: f32) -> Material {
    Material {
        ka: Vec3::splat(k),
        kd: Vec3::splat(k),
        ..Material::default()
    }
}

/// Clear glass of index `ior`: it only transmits.
fn clear(ior: f32) -> Material {
    Material {
        ka: Vec3::ZERO,
        kd: Vec3::ZERO,
        kt: Vec3::ONE,
        ior,
        ..Material::default()
    }
}

/// A floor (y = 0, 100 wide, Ka = Kd = 0.5) lit from straight above, with
/// the default ambient 0.2 (shadowed), and a 2x2x2 box floating over the origin (y from 1.5 to 3.5).
fn floor_and_box(box_material: Material) -> Scene {
    let mut scene = fixtures::floor(matte(0.5));
    let cube = scene.add_mesh("cube", shapes::cuboid());
    let box_mat = scene.add_material("box", box_material);
    let box_xf =
        Affine3A::from_scale_rotation_translation(Vec3::splat(2.0), Default::default(), Vec3::new(0.0, 2.5, 0.0));
    scene.add_instance("box", cube, box_mat, box_xf);
    scene.add_light("sun", SUN);
    scene
}

fn trace_with(scene: &Scene, settings: &RenderSettings, from: Vec3, to: Vec3) -> (Vec3, RayStats) {
    let rs = extract(scene).unwrap_or_else(|e| panic!("{e}"));
    let mut stats = RayStats::default();
    let c = Whitted::new(&rs, settings).trace_primary(Ray::new(from, (to - from).normalize()), &mut stats);
    (c, stats)
}

fn trace(scene: &Scene, from: Vec3, to: Vec3) -> Vec3 {
    trace_with(scene, &RenderSettings::default(), from, to).0
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

/// A grazing camera ray that reaches the floor at `x` without touching the box.
fn floor_at(scene: &Scene, x: f32) -> Vec3 {
    trace(scene, Vec3::new(x - 10.0, 0.5, 0.3), Vec3::new(x, 0.0, 0.3))
}

#[test]
fn lit_floor_is_ambient_plus_diffuse() {
    let scene = floor_and_box(matte(0.8));
    // Ia Ka + Ip Kd (L.N) = 0.2 * 0.5 + 0.5 * 1.
    assert!(
        close(floor_at(&scene, -5.0), Vec3::splat(0.6)),
        "{}",
        floor_at(&scene, -5.0)
    );
}

#[test]
fn opaque_blockers_cast_black_shadows() {
    let scene = floor_and_box(matte(0.8));
    assert_eq!(floor_at(&scene, 0.0), Vec3::ZERO);
}

#[test]
fn translucent_blockers_attenuate_and_clear_ones_do_not() {
    let glass = |kt: f32| Material {
        kt: Vec3::splat(kt),
        ..matte(0.8)
    };
    // The shadow ray crosses the box's bottom and top: kt twice.
    let half = floor_and_box(glass(0.5));
    assert!(
        close(floor_at(&half, 0.0), Vec3::splat(0.6 * 0.25)),
        "{}",
        floor_at(&half, 0.0)
    );
    let see_through = floor_and_box(glass(1.0));
    assert!(close(floor_at(&see_through, 0.0), Vec3::splat(0.6)));
    // Without the report's shadowed ambient, the ambient term survives.
    let mut scene = floor_and_box(matte(0.8));
    scene.environment.shadowed_ambient = false;
    assert!(close(floor_at(&scene, 0.0), Vec3::splat(0.1)));
}

#[test]
fn concave_meshes_shadow_themselves() {
    // One mesh: a floor square and a roof square above it. The report's
    // "skip the last object hit" rule would light the floor under the roof.
    let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    let positions = vec![
        p(-5.0, 0.0, 5.0),
        p(5.0, 0.0, 5.0),
        p(5.0, 0.0, -5.0),
        p(-5.0, 0.0, -5.0),
        p(-1.0, 2.0, 1.0),
        p(1.0, 2.0, 1.0),
        p(1.0, 2.0, -1.0),
        p(-1.0, 2.0, -1.0),
    ];
    let mesh = TriMesh::new(positions, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
        .map(TriMesh::with_smooth_normals_if_missing)
        .unwrap_or_default();
    let mut scene = Scene::default();
    let m = scene.add_mesh("shed", mesh);
    let mat = scene.add_material("m", matte(0.5));
    scene.add_instance("shed", m, mat, Affine3A::IDENTITY);
    scene.add_light("sun", SUN);
    scene.add_camera("cam", Camera::default(), OrbitRig::default());
    let under = trace(&scene, Vec3::new(-4.0, 0.5, 0.0), Vec3::ZERO);
    let open = trace(&scene, Vec3::new(-4.0, 0.5, 3.0), Vec3::new(-3.0, 0.0, 3.0));
    assert_eq!(under, Vec3::ZERO);
    assert!(close(open, Vec3::splat(0.6)));
}

#[test]
fn mirrors_reflect_what_is_above_them() {
    let red = Material {
        ka: Vec3::new(1.0, 0.0, 0.0),
        kd: Vec3::new(1.0, 0.0, 0.0),
        ..Material::default()
    };
    let mut scene = floor_and_box(red);
    // Make the floor a perfect mirror with no colour of its own.
    let mirror = Material {
        ka: Vec3::ZERO,
        kd: Vec3::ZERO,
        kr: Vec3::ONE,
        ..Material::default()
    };
    let floor_mat = scene.add_material("mirror", mirror);
    let plane = scene.add_mesh("plane", shapes::plane());
    // Replace the floor.
    scene.remove_instances("floor");
    scene.add_instance("floor", plane, floor_mat, Affine3A::from_scale(Vec3::splat(100.0)));
    // From (-3, 3, 0.3) towards the floor at (-1.5, 0, 0.3): the mirrored
    // ray climbs to the box's side at x = -1.
    let c = trace(&scene, Vec3::new(-3.0, 3.0, 0.3), Vec3::new(-1.5, 0.0, 0.3));
    assert!(c.x > 0.1 && c.y == 0.0 && c.z == 0.0, "{c}");
    // Depth 0: no reflection rays at all.
    let settings = RenderSettings {
        max_depth: 0,
        ..RenderSettings::default()
    };
    let (c, stats) = trace_with(&scene, &settings, Vec3::new(-3.0, 3.0, 0.3), Vec3::new(-1.5, 0.0, 0.3));
    assert_eq!((c, stats.reflection), (Vec3::ZERO, 0));
}

/// A red wall at z = -5 and, between it and the viewer, a unit sphere.
fn wall_and_sphere(sphere: Material) -> Scene {
    let mut scene = Scene::default();
    scene.environment.ambient = Vec3::ONE;
    let wall_mesh = scene.add_mesh("wall", shapes::plane());
    let sphere_mesh = scene.add_mesh("sphere", shapes::icosphere(4));
    let red = scene.add_material(
        "red",
        Material {
            ka: Vec3::new(1.0, 0.0, 0.0),
            kd: Vec3::ZERO,
            ..Material::default()
        },
    );
    let glass = scene.add_material("glass", sphere);
    let wall_xf = Affine3A::from_scale_rotation_translation(
        Vec3::splat(50.0),
        lucent_geom::Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
        Vec3::new(0.0, 0.0, -5.0),
    );
    scene.add_instance("wall", wall_mesh, red, wall_xf);
    scene.add_instance("sphere", sphere_mesh, glass, Affine3A::IDENTITY);
    scene.add_camera("cam", Camera::default(), OrbitRig::default());
    scene
}

#[test]
fn objects_behind_a_translucent_sphere_are_dimmed() {
    let from = Vec3::new(0.0, 0.0, 5.0);
    let to = Vec3::new(0.0, 0.0, -5.0);
    let invisible = clear(1.5);
    // Straight through the centre: no bending, full red.
    let c = trace(&wall_and_sphere(invisible.clone()), from, to);
    assert!(close(c, Vec3::X), "{c}");
    // kt = 0.5 on entry and again on exit.
    let dim = Material {
        kt: Vec3::splat(0.5),
        ..invisible.clone()
    };
    let c = trace(&wall_and_sphere(dim), from, to);
    assert!(close(c, Vec3::new(0.25, 0.0, 0.0)), "{c}");
    // Depth 1 reaches the sphere's inside but not the wall.
    let shallow = RenderSettings {
        max_depth: 1,
        ..RenderSettings::default()
    };
    let (c, stats) = trace_with(&wall_and_sphere(invisible), &shallow, from, to);
    assert_eq!((c, stats.refraction), (Vec3::ZERO, 1));
}

#[test]
fn total_internal_reflection_sends_light_back_inside() {
    // A clear glass block (IOR 1.5, x in [-1, 1], y in [1.5, 3.5]) over the
    // lit floor. A ray enters the top face at x = 0.6 at 45 degrees, bends to
    // 28.1 degrees, meets the side face x = 1 at 61.9 degrees (past the
    // 41.8 degree critical angle), is reflected totally, leaves through the
    // bottom at 45 degrees and lands on the floor at x = -1.17, outside the
    // block's shadow: entry, internal reflection and exit are three rays.
    let scene = floor_and_box(clear(1.5));
    let (c, stats) = trace_with(
        &scene,
        &RenderSettings::default(),
        Vec3::new(-0.4, 4.5, 0.3),
        Vec3::new(0.6, 3.5, 0.3),
    );
    assert_eq!(stats.refraction, 3);
    assert!(close(c, Vec3::splat(0.6)), "{c}");
}

#[test]
fn dense_spheres_stay_finite() {
    let from = Vec3::new(0.0, 0.0, 5.0);
    let to = Vec3::new(0.8, 0.0, 0.0);
    // IOR 1: the surface disappears and the ray goes straight to the wall.
    assert!(close(trace(&wall_and_sphere(clear(1.0)), from, to), Vec3::X));
    // A very dense sphere bends the ray towards its centre; it enters and
    // leaves (a sphere cannot trap light) without producing NaN.
    let (c, stats) = trace_with(&wall_and_sphere(clear(50.0)), &RenderSettings::default(), from, to);
    assert!(c.is_finite());
    assert_eq!(stats.refraction, 2);
}

#[test]
fn min_weight_stops_the_recursion() {
    // Two facing mirrors with kr = 0.5: weights 0.5, 0.25, 0.125, ...
    let mirror = Material {
        kr: Vec3::splat(0.5),
        ..Material::default()
    };
    let scene = fixtures::floor_and_ceiling(mirror.clone(), mirror, 1.0);
    let count = |min_weight: f32, max_depth: u32| {
        let settings = RenderSettings {
            min_weight,
            max_depth,
            ..RenderSettings::default()
        };
        trace_with(&scene, &settings, Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.1, 0.0, 0.0))
            .1
            .reflection
    };
    assert_eq!(count(0.2, 30), 2);
    assert_eq!(count(0.1, 30), 3);
    assert_eq!(count(0.0, 7), 7);
}

#[test]
fn gouraud_interpolates_vertex_lighting() {
    // One triangle with three different vertex normals, seen through its
    // centroid: Gouraud gives the mean of the three vertex colours.
    let positions = vec![
        Vec3::new(-1.0, 0.0, 1.0),
        Vec3::new(1.0, 0.0, 1.0),
        Vec3::new(0.0, 0.0, -1.0),
    ];
    let normals = vec![
        Vec3::new(-0.5, 1.0, 0.0).normalize(),
        Vec3::new(0.5, 1.0, 0.3).normalize(),
        Vec3::new(0.0, 1.0, -0.8).normalize(),
    ];
    let mesh = TriMesh::new(positions.clone(), vec![[0, 1, 2]])
        .and_then(|m| m.with_normals(normals.clone()))
        .unwrap_or_default();
    let mut scene = Scene::default();
    scene.environment.ambient = Vec3::ZERO;
    let m = scene.add_mesh("tri", mesh);
    let mat = Material {
        ka: Vec3::ZERO,
        kd: Vec3::splat(0.7),
        ks: Vec3::splat(0.3),
        shininess: 8.0,
        ..Material::default()
    };
    let mat_e = scene.add_material("m", mat.clone());
    scene.add_instance("tri", m, mat_e, Affine3A::IDENTITY);
    let sun = Vec3::new(0.3, 1.0, 0.2).normalize();
    scene.add_light(
        "sun",
        Light::Directional {
            to_light: sun,
            intensity: Vec3::ONE,
        },
    );
    scene.add_camera("cam", Camera::default(), OrbitRig::default());
    let eye = Vec3::new(0.4, 3.0, 2.0);
    let centroid = (positions[0] + positions[1] + positions[2]) / 3.0;
    let expected: Vec3 = (0..3)
        .map(|k| {
            let v = (eye - positions[k]).normalize();
            let t = phong_terms(normals[k], sun, v, 8.0, Vec3::ONE);
            mat.kd * t.diffuse + mat.ks * t.specular
        })
        .sum::<Vec3>()
        / 3.0;
    let gouraud = trace(&scene, eye, centroid);
    assert!(close(gouraud, expected), "{gouraud} vs {expected}");
    let phong_settings = RenderSettings {
        shading: Shading::Phong,
        ..RenderSettings::default()
    };
    let (phong, _) = trace_with(&scene, &phong_settings, eye, centroid);
    let n = (normals[0] + normals[1] + normals[2]).normalize();
    let t = phong_terms(n, sun, (eye - centroid).normalize(), 8.0, Vec3::ONE);
    assert!(close(phong, mat.kd * t.diffuse + mat.ks * t.specular), "{phong}");
    assert!(!close(phong, gouraud), "the two modes differ on curved triangles");
}

#[test]
fn grazing_light_gives_no_shadow_acne_on_a_far_plane() {
    // A plane far from the origin, lit at 85 degrees from its normal: every
    // pixel must see the same unshadowed colour.
    for offset in [0.0f32, 1e3, 1e5] {
        let mut scene = Scene::default();
        scene.environment.ambient = Vec3::ZERO;
        let plane = scene.add_mesh("plane", shapes::plane());
        let mat = scene.add_material("m", matte(1.0));
        let xf = Affine3A::from_scale_rotation_translation(Vec3::splat(40.0), Default::default(), Vec3::splat(offset));
        scene.add_instance("plane", plane, mat, xf);
        let to_light = Vec3::new(85f32.to_radians().sin(), 85f32.to_radians().cos(), 0.0);
        scene.add_light(
            "sun",
            Light::Directional {
                to_light,
                intensity: Vec3::ONE,
            },
        );
        let rig = OrbitRig {
            center: Vec3::splat(offset),
            radius: 10.0,
            theta: 1.2,
            phi: 0.3,
        };
        scene.add_camera("cam", Camera { fov_y_deg: 40.0 }, rig);
        let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
        let settings = RenderSettings {
            width: 48,
            height: 32,
            ..RenderSettings::default()
        };
        let film = render(&rs, &settings, &|_| {}).film;
        let expected = to_light.y;
        for px in film.to_linear() {
            assert!((px.x - expected).abs() < 1e-4, "offset {offset}: {px} vs {expected}");
        }
    }
}

#[test]
fn same_bytes_on_one_and_many_threads() {
    let scene = floor_and_box(Material {
        kt: Vec3::splat(0.5),
        kr: Vec3::splat(0.3),
        ior: 1.3,
        ..matte(0.6)
    });
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let settings = RenderSettings {
        width: 40,
        height: 30,
        spp: 3,
        ..RenderSettings::default()
    };
    let run = |threads: usize| {
        crate::with_threads(threads, || render(&rs, &settings, &|_| {}).film.to_srgb8())
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let one = run(1);
    assert_eq!(one, run(3));
    assert_eq!(one, run(4));
}

#[test]
fn shadow_rays_through_a_shared_edge_attenuate_once() {
    // The box's top face is split along x = z; a vertical shadow ray from
    // (0.4, 0, 0.4) meets that diagonal exactly, where the watertight test
    // reports both triangles. It still crosses the box once on the way in
    // and once on the way out: kt twice, not three times.
    let glass = Material {
        kt: Vec3::splat(0.5),
        ..matte(0.8)
    };
    let scene = floor_and_box(glass);
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let settings = RenderSettings::default();
    let whitted = Whitted::new(&rs, &settings);
    let at = |x: f32, z: f32| {
        let p = Vec3::new(x, 0.0, z);
        let surf = SurfaceInteraction {
            p,
            ng: Vec3::Y,
            ns: Vec3::Y,
            bary: Vec3::new(1.0, 0.0, 0.0),
            corners: [p; 3],
            magnitude: 1.0,
            corner_normals: None,
            uv: None,
            color: None,
            tangent: None,
            instance: &rs.instances[0],
        };
        let ls = LightSample {
            to_light: Vec3::Y,
            distance: f32::INFINITY,
            intensity: Vec3::ONE,
        };
        whitted.shadow::<true>(&surf, &ls, &mut RayStats::default())
    };
    // Off the diagonals, then on the top face's diagonal (x = z), on the
    // bottom face's (x = -z) and on both at the centre.
    for (x, z) in [(0.4, 0.1), (0.4, 0.4), (0.4, -0.4), (0.0, 0.0), (-0.7, -0.7)] {
        assert_eq!(at(x, z), Vec3::splat(0.25), "shadow ray at x = {x}, z = {z}");
    }
}
