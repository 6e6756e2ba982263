//! The extremes suite, end to end (issue 8): whole scenes rendered at scales
//! from 1e-6 to 1e6 and far from the origin, cameras at the edges of their
//! ranges, and long accumulations. Each case prints its figure on stderr
//! (`cargo test -p lucent-tests --test extremes -- --nocapture`) and asserts
//! its pass condition. `cargo xtask extremes` runs the same tests in a
//! release build with `LUCENT_EXTREMES_FULL=1`, which turns on the sizes too
//! slow for the normal suite (a 16384-pixel-wide image, 1e6 samples per
//! pixel). The guarantees are written up in docs/robustness.md.

use lucent_geom::{Affine3A, Named, Vec3, shapes};
use lucent_render::{Film, RenderSettings, Shading, extract, render};
use lucent_scene::Scene;
use lucent_scene::components::{Camera, Light, Material, Name, OrbitRig};
use lucent_tests::{extremes_full, load_repo_scene, place_scene as place, render_with};

/// How far apart two images of one size are.
#[derive(Clone, Copy, Debug)]
struct ImageError {
    /// Mean absolute difference of 8-bit sRGB channels, in levels.
    mean_levels: f64,
    /// Fraction of pixels with some channel off by more than 8 levels.
    fraction_off: f64,
}

fn image_error(a: &Film, b: &Film) -> ImageError {
    assert_eq!((a.width(), a.height()), (b.width(), b.height()));
    let (a, b) = (a.to_srgb8(), b.to_srgb8());
    let sum: u64 = a.iter().zip(&b).map(|(x, y)| u64::from(x.abs_diff(*y))).sum();
    let n_off = a
        .chunks(3)
        .zip(b.chunks(3))
        .filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > 8))
        .count();
    ImageError {
        mean_levels: sum as f64 / a.len().max(1) as f64,
        fraction_off: n_off as f64 / (a.len() / 3).max(1) as f64,
    }
}

/// A closed mesh (an icosphere) resting on a floor board, lit from the side
/// so it casts a long shadow and shows its terminator.
fn sphere_on_floor() -> Scene {
    let mut scene = Scene::default();
    let ball = scene.add_mesh("ball", shapes::icosphere(4));
    let cube = scene.add_mesh("cube", shapes::cuboid());
    let white = scene.add_material(
        "white",
        Material {
            kd: Vec3::splat(0.8),
            ks: Vec3::splat(0.3),
            shininess: 30.0,
            ..Material::default()
        },
    );
    let floor = scene.add_material(
        "floor",
        Material {
            kd: Vec3::new(0.5, 0.4, 0.3),
            kr: Vec3::splat(0.3),
            ..Material::default()
        },
    );
    scene.add_instance(
        "ball",
        ball,
        white,
        Affine3A::from_translation(Vec3::new(0.0, 1.0, 0.0)),
    );
    scene.add_instance(
        "floor",
        cube,
        floor,
        Affine3A::from_scale_rotation_translation(
            Vec3::new(8.0, 0.1, 8.0),
            lucent_geom::Quat::IDENTITY,
            Vec3::new(0.0, -0.05, 0.0),
        ),
    );
    scene.add_light(
        "sun",
        Light::Directional {
            to_light: Vec3::new(0.6, 0.5, 0.3).normalize(),
            intensity: Vec3::ONE,
        },
    );
    scene.add_camera(
        "cam",
        Camera { fov_y_deg: 45.0 },
        OrbitRig {
            center: Vec3::new(0.0, 0.8, 0.0),
            radius: 5.0,
            theta: 0.35,
            phi: 1.2,
        },
    );
    scene
}

/// One placement of the scale case and what it measured.
#[derive(Clone, Copy, Debug)]
struct ScaleRow {
    scale: f32,
    /// Translation in units of the scene's own size (times `scale` in world units).
    offset: f32,
    /// NaN or infinite pixels.
    n_non_finite: usize,
    /// Against the render at unit scale at the origin.
    vs_unit: ImageError,
    /// Against the same placed scene moved back to the origin (its
    /// coordinates keep the rounding they got far away), so only the
    /// renderer's own error far from the origin is left.
    vs_rounded_at_origin: ImageError,
}

/// Renders `make()` at scales 1e-6 to 1e6, each at the origin and 1e3 and
/// 1e6 of its own sizes away from it, and compares with unit scale.
fn scale_case(name: &str, make: impl Fn() -> Scene, settings: RenderSettings) -> Vec<ScaleRow> {
    let reference = render_with(&make(), &settings);
    assert_eq!(reference.stats().n_non_finite, 0);
    let mut rows = Vec::new();
    for scale in [1e-6f32, 1e-3, 1.0, 1e3, 1e6] {
        for offset in [0.0f32, 1e3, 1e6] {
            let translate = Vec3::new(1.0, -1.0, 1.0) * offset * scale;
            let mut scene = make();
            place(&mut scene, scale, translate);
            let film = render_with(&scene, &settings);
            // Moving back by exactly -translate keeps the rounding the
            // coordinates got (the subtraction of nearby floats is exact).
            place(&mut scene, 1.0, -translate);
            let rounded = render_with(&scene, &settings);
            let row = ScaleRow {
                scale,
                offset,
                n_non_finite: film.stats().n_non_finite,
                vs_unit: image_error(&reference, &film),
                vs_rounded_at_origin: image_error(&rounded, &film),
            };
            eprintln!(
                "scale {name}: scale {scale:e}, {offset:e} sizes from the origin: {} NaN/Inf pixels; \
                 vs unit scale {:.3} levels mean, {:.3}% pixels off by > 8; \
                 vs the same rounded scene at the origin {:.3} levels, {:.3}%",
                row.n_non_finite,
                row.vs_unit.mean_levels,
                100.0 * row.vs_unit.fraction_off,
                row.vs_rounded_at_origin.mean_levels,
                100.0 * row.vs_rounded_at_origin.fraction_off,
            );
            rows.push(row);
        }
    }
    rows
}

/// The scale case's pass conditions: no NaN anywhere; the same picture as at
/// unit scale (mean error under 0.5 of 256 levels, under 0.5% of pixels off
/// by more than 8 levels) at every scale up to 1e3 sizes from the origin;
/// at 1e6 sizes away f32 itself rounds the scene's coordinates to 1/16 of
/// its size, so there the renderer must add no visible error to that
/// rounding (same bound against the rounded scene rendered at the origin).
fn check_scale_rows(rows: &[ScaleRow]) {
    for r in rows {
        assert_eq!(r.n_non_finite, 0, "scale {}: {r:?}", r.scale);
        let within = |e: ImageError| e.mean_levels < 0.5 && e.fraction_off < 0.005;
        assert!(within(r.vs_rounded_at_origin), "{r:?}");
        if r.offset <= 1e3 {
            assert!(within(r.vs_unit), "{r:?}");
        }
    }
}

#[test]
fn seed_scene_looks_the_same_at_every_scale() {
    let settings = RenderSettings {
        width: 160,
        height: 90,
        spp: 1,
        ..load_repo_scene("res/scenes/seed.toml").settings
    };
    check_scale_rows(&scale_case(
        "seed",
        || load_repo_scene("res/scenes/seed.toml"),
        settings,
    ));
}

#[test]
fn closed_mesh_looks_the_same_at_every_scale() {
    for shading in [Shading::Phong, Shading::Gouraud] {
        let settings = RenderSettings {
            width: 160,
            height: 120,
            spp: 1,
            shading,
            ..RenderSettings::default()
        };
        check_scale_rows(&scale_case(shading.name(), sphere_on_floor, settings));
    }
}

/// Accumulation: `n` samples per pixel summed by the film against the same
/// samples rendered one at a time and summed here exactly (f64). Returns
/// the largest relative difference over pixels and channels for the film,
/// and for the same samples summed in f32 in the same order (what the film
/// did before it summed in f64).
fn accumulation_drift(n: u32) -> (f64, f64) {
    use lucent_geom::DVec3;
    use lucent_render::render_samples;
    let scene = load_repo_scene("res/scenes/seed.toml");
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let settings = RenderSettings {
        width: 2,
        height: 2,
        ..scene.settings
    };
    let mut film = Film::new(2, 2);
    render_samples(&rs, &settings, &mut film, 0..n, &|_| {});
    let mut exact = [DVec3::ZERO; 4];
    let mut single = [Vec3::ZERO; 4];
    let mut one = Film::new(2, 2);
    for s in 0..n {
        one.clear();
        render_samples(&rs, &settings, &mut one, s..s + 1, &|_| {});
        for i in 0..4 {
            let px = one.pixel(i as u32 % 2, i as u32 / 2);
            exact[i] += px.as_dvec3();
            single[i] += px;
        }
    }
    let rel = |got: DVec3, mean: DVec3| ((got - mean).abs() / mean.abs().max(DVec3::splat(1e-12))).max_element();
    let (mut drift, mut drift_f32) = (0.0f64, 0.0f64);
    for i in 0..4 {
        let mean = exact[i] / f64::from(n);
        drift = drift.max(rel(film.pixel(i as u32 % 2, i as u32 / 2).as_dvec3(), mean));
        drift_f32 = drift_f32.max(rel((single[i] / n as f32).as_dvec3(), mean));
    }
    (drift, drift_f32)
}

#[test]
fn long_accumulation_does_not_drift() {
    let n = if extremes_full() { 1_000_000 } else { 100_000 };
    let (drift, drift_f32) = accumulation_drift(n);
    eprintln!(
        "accumulation: {n} samples per pixel, largest relative drift {drift:.3e} (the same samples summed in f32: {drift_f32:.3e})"
    );
    // The mean is rounded to f32 once at the end (2^-24 = 6e-8 relative).
    assert!(drift < 1e-6, "drift {drift:e} after {n} samples");
}

/// A matte white surface lit by one directional light at `light_deg` from
/// its normal (+y for the plane; for the sphere, from the camera's side),
/// no ambient light, seen from `camera_theta` above the horizon: a lit
/// pixel has exactly `n.l` radiance, a shadowed one 0.
fn lit_surface(sphere: bool, light_deg: f32, camera_theta: f32) -> Scene {
    let mut scene = Scene::default();
    scene.environment.ambient = Vec3::ZERO;
    let mesh = if sphere {
        // Flat facets (no vertex normals): shading normal = geometric.
        let ball = shapes::icosphere(3);
        lucent_geom::TriMesh::new(ball.positions().to_vec(), ball.indices().to_vec()).unwrap_or_else(|e| panic!("{e}"))
    } else {
        shapes::plane()
    };
    let mesh = scene.add_mesh("surface", mesh);
    let white = scene.add_material(
        "white",
        Material {
            ka: Vec3::ZERO,
            kd: Vec3::ONE,
            ks: Vec3::ZERO,
            ..Material::default()
        },
    );
    let size = if sphere { 1.0 } else { 40.0 };
    scene.add_instance("surface", mesh, white, Affine3A::from_scale(Vec3::splat(size)));
    let a = light_deg.to_radians();
    scene.add_light(
        "sun",
        Light::Directional {
            to_light: Vec3::new(a.sin() * 0.6, a.cos(), a.sin() * 0.8),
            intensity: Vec3::ONE,
        },
    );
    scene.add_camera(
        "cam",
        Camera { fov_y_deg: 40.0 },
        OrbitRig {
            center: Vec3::ZERO,
            radius: if sphere { 4.0 } else { 6.0 },
            theta: camera_theta,
            phi: 0.9,
        },
    );
    scene
}

/// What the self-intersection case counts over one image.
#[derive(Clone, Copy, Debug, Default)]
struct SelfHits {
    /// Pixels whose camera ray hits the surface where it faces the light.
    lit: usize,
    /// Of those, pixels darker than half their `n.l`: wrongly shadowed.
    shadowed: usize,
    /// Mirror rays (from the hit, offset as the renderer does) that hit
    /// the surface again: a plane or a convex sphere can never see itself.
    reflection_rehits: usize,
    /// Refracted rays into the sphere whose next hit is their own triangle
    /// or closer than 1e-5 of the radius: spurious.
    refraction_rehits: usize,
}

fn self_hits(scene: &Scene, scale: f32, sphere: bool) -> SelfHits {
    use lucent_geom::{Ray, offset_ray_origin_scaled, triangle_normal};
    use lucent_shading::optics::{reflect, refract};
    let (width, height) = (120, 90);
    let settings = RenderSettings {
        width,
        height,
        spp: 1,
        shading: Shading::Phong,
        ..RenderSettings::default()
    };
    let rs = extract(scene).unwrap_or_else(|e| panic!("{e}"));
    let film = render(&rs, &settings, &|_| {}).film;
    let camera = lucent_render::PinholeCamera::new(&rs.camera, &rs.render_rig(), width, height);
    let to_light = match rs.lights[0] {
        Light::Directional { to_light, .. } => to_light.normalize(),
        Light::Point { .. } | Light::Spot { .. } => unreachable!("directional only"),
    };
    let mut out = SelfHits::default();
    for row in 0..height {
        for col in 0..width {
            let ray = camera.ray(col as f32 + 0.5, row as f32 + 0.5);
            let Some(hit) = rs.bvh.intersect(&ray, f32::INFINITY) else {
                continue;
            };
            let inst = &rs.instances[hit.instance as usize];
            let mesh = &rs.meshes[inst.mesh as usize];
            let corners = mesh
                .triangle(hit.prim as usize)
                .map(|p| inst.render_from_object.transform_point3(p));
            let mut ng = triangle_normal(corners).normalize();
            if ng.dot(ray.dir) > 0.0 {
                ng = -ng;
            }
            let p = corners[0] * (1.0 - hit.u - hit.v) + corners[1] * hit.u + corners[2] * hit.v;
            let magnitude = corners.iter().fold(0.0f32, |m, c| m.max(c.abs().max_element()));
            let cos = ng.dot(to_light);
            if cos > 1e-3 {
                out.lit += 1;
                if film.pixel(col, row).x < 0.5 * cos {
                    out.shadowed += 1;
                }
            }
            let mirrored = Ray::new(offset_ray_origin_scaled(p, ng, magnitude), reflect(ray.dir, ng));
            if rs.bvh.intersect(&mirrored, f32::INFINITY).is_some() {
                out.reflection_rehits += 1;
            }
            if sphere && let Some(t) = refract(ray.dir, ng, 1.0 / 1.5) {
                let inside = Ray::new(offset_ray_origin_scaled(p, -ng, magnitude), t.normalize());
                let next = rs.bvh.intersect(&inside, f32::INFINITY);
                if next.is_none_or(|n| n.prim == hit.prim || n.t < 1e-5 * scale) {
                    out.refraction_rehits += 1;
                }
            }
        }
    }
    out
}

#[test]
fn no_shadow_acne_or_self_hits_at_any_scale_or_angle() {
    let mut n_lit = 0;
    for sphere in [false, true] {
        for (light_deg, camera_theta) in [(0.0f32, 0.6f32), (60.0, 0.6), (89.0, 0.6), (89.9, 0.6), (30.0, 0.02)] {
            for scale in [1e-6f32, 1e-3, 1.0, 1e3, 1e6] {
                for offset in [0.0f32, 1e3] {
                    let mut scene = lit_surface(sphere, light_deg, camera_theta);
                    place(&mut scene, scale, Vec3::new(1.0, -1.0, 1.0) * offset * scale);
                    let h = self_hits(&scene, scale, sphere);
                    let what = if sphere { "sphere" } else { "plane" };
                    if h.shadowed + h.reflection_rehits + h.refraction_rehits > 0 {
                        eprintln!(
                            "self-intersection: {what}, light {light_deg} deg, camera {camera_theta} rad, scale {scale:e}, {offset:e} sizes away: {h:?}"
                        );
                    }
                    assert!(h.lit > 1000, "{what} should fill much of the picture: {h:?}");
                    assert_eq!(
                        (h.shadowed, h.reflection_rehits, h.refraction_rehits),
                        (0, 0, 0),
                        "{what}, light {light_deg}, camera {camera_theta}, scale {scale}, offset {offset}"
                    );
                    n_lit += h.lit;
                }
            }
        }
    }
    eprintln!("self-intersection: {n_lit} lit pixels over all cases, 0 wrongly shadowed, 0 self-hits");
}

/// The sphere-on-floor scene with a clear sphere (`kt` 1, nothing else) of
/// index `ior`, or with no sphere.
fn clear_sphere(ior: Option<f32>) -> Scene {
    let mut scene = sphere_on_floor();
    let Some(ior) = ior else {
        scene.remove_instances("ball");
        return scene;
    };
    for (name, m) in scene.world.query_mut::<(&Name, &mut Material)>() {
        if name.0 == "white" {
            *m = Material {
                ka: Vec3::ZERO,
                kd: Vec3::ZERO,
                ks: Vec3::ZERO,
                kt: Vec3::ONE,
                ior,
                ..Material::default()
            };
        }
    }
    scene
}

#[test]
fn a_clear_surface_of_index_one_disappears_and_extreme_indices_stay_finite() {
    let settings = RenderSettings {
        width: 160,
        height: 120,
        spp: 1,
        max_depth: 8,
        shading: Shading::Phong,
        ..RenderSettings::default()
    };
    let without = render_with(&clear_sphere(None), &settings);
    let with = render_with(&clear_sphere(Some(1.0)), &settings);
    let err = image_error(&without, &with);
    eprintln!(
        "optics: clear sphere of IOR 1 against no sphere: {:.4} levels mean, {:.3}% of pixels off by > 8",
        err.mean_levels,
        100.0 * err.fraction_off
    );
    assert!(err.mean_levels < 0.05 && err.fraction_off < 0.001, "{err:?}");
    // A glass sphere really does change the picture (the check can fail).
    let glass = image_error(&without, &render_with(&clear_sphere(Some(1.5)), &settings));
    assert!(glass.fraction_off > 0.05, "{glass:?}");
    for ior in [1e-3f32, 0.5, 2.42, 1e3, 1e6, 1e30, f32::MAX] {
        let film = render_with(&clear_sphere(Some(ior)), &settings);
        let n = film.stats().n_non_finite;
        eprintln!("optics: clear sphere of IOR {ior:e}: {n} NaN/Inf pixels");
        assert_eq!(n, 0, "IOR {ior}");
    }
}

/// The seed scene, extracted once for the camera cases.
fn seed_render_scene() -> lucent_render::RenderScene {
    extract(&load_repo_scene("res/scenes/seed.toml")).unwrap_or_else(|e| panic!("{e}"))
}

fn render_rs(rs: &lucent_render::RenderScene, width: u32, height: u32) -> Film {
    let settings = RenderSettings {
        width,
        height,
        spp: 1,
        ..RenderSettings::default()
    };
    render(rs, &settings, &|_| {}).film
}

#[test]
fn the_orbit_rig_at_the_poles_and_radii_near_zero_and_huge() {
    use std::f32::consts::FRAC_PI_2;
    let mut rs = seed_render_scene();
    let home = rs.rig;
    let limit = lucent_scene::camera::THETA_LIMIT;
    // At and past the poles the rig is held at 89.9 degrees: the same
    // picture as at the limit, never a flipped or NaN frame.
    rs.rig.theta = limit;
    let at_limit = render_rs(&rs, 64, 36).to_srgb8();
    for theta in [
        FRAC_PI_2,
        -FRAC_PI_2,
        FRAC_PI_2 + 1e-7,
        3.0,
        1e30,
        f32::INFINITY,
        f32::NAN,
    ] {
        rs.rig = OrbitRig { theta, ..home };
        let rig = rs.rig.sanitized();
        let [x, y, z] = rig.axes();
        let orthonormal = [x.dot(y), y.dot(z), z.dot(x)].iter().all(|d| d.abs() < 1e-6)
            && [x, y, z].iter().all(|a| (a.length() - 1.0).abs() < 1e-6);
        assert!(orthonormal && rig.position().is_finite(), "theta {theta}: {rig:?}");
        let film = render_rs(&rs, 64, 36);
        assert_eq!(film.stats().n_non_finite, 0, "theta {theta}");
        if theta > 0.0 && theta.is_finite() {
            assert_eq!(film.to_srgb8(), at_limit, "theta {theta} is the north limit");
        }
    }
    // Radii from zero (the camera at the orbit centre, inside the scene)
    // to far beyond the scene (which then covers under a pixel).
    for radius in [0.0f32, -1.0, 1e-30, 1e-9, 1e-4, 1e3, 1e7, 1e30, f32::INFINITY, f32::NAN] {
        rs.rig = OrbitRig { radius, ..home };
        let film = render_rs(&rs, 64, 36);
        let stats = film.stats();
        eprintln!(
            "camera: radius {radius:e} (used {:e}): {} NaN/Inf pixels, mean luminance {:.4}",
            rs.rig.sanitized().radius,
            stats.n_non_finite,
            stats.mean_rgb.dot(Vec3::new(0.2126, 0.7152, 0.0722))
        );
        assert_eq!(stats.n_non_finite, 0, "radius {radius}");
    }
    // From 1e7 away the whole scene is far under a pixel: the picture is
    // the background, give or take one pixel.
    rs.rig = OrbitRig { radius: 1e7, ..home };
    let far = render_rs(&rs, 64, 36);
    let background = rs.environment.background;
    let n_other = (0..36)
        .flat_map(|y| (0..64).map(move |x| (x, y)))
        .filter(|&(x, y)| !far.pixel(x, y).abs_diff_eq(background, 1e-6))
        .count();
    assert!(n_other <= 1, "{n_other} pixels are not background");
}

#[test]
fn one_pixel_and_16384_pixel_wide_images() {
    let rs = seed_render_scene();
    // One pixel sees along the view axis: the centre pixel of a 3x3 image.
    let one = render_rs(&rs, 1, 1);
    let three = render_rs(&rs, 3, 3);
    assert_eq!(one.pixel(0, 0), three.pixel(1, 1));
    assert_eq!(one.stats().n_non_finite, 0);
    // A 16384-pixel-wide strip: the field of view is vertical, so its
    // middle 1024 columns see exactly what a 1024-wide image sees.
    let height = if extremes_full() { 512 } else { 8 };
    let wide = render_rs(&rs, 16384, height);
    let narrow = render_rs(&rs, 1024, height);
    assert_eq!(wide.stats().n_non_finite, 0);
    let mut n_diff = 0;
    for y in 0..height {
        for x in 0..1024 {
            n_diff += usize::from(wide.pixel(x + (16384 - 1024) / 2, y) != narrow.pixel(x, y));
        }
    }
    eprintln!(
        "camera: 16384x{height} image: {} NaN/Inf pixels, middle 1024 columns differ from a 1024-wide image in {n_diff} pixels",
        wide.stats().n_non_finite
    );
    assert_eq!(n_diff, 0);
}

#[test]
fn fields_of_view_near_0_and_near_180_degrees() {
    let mut rs = seed_render_scene();
    // Odd sizes: the centre pixel's ray is the view axis at any field of
    // view, so the centre pixel never changes.
    rs.camera.fov_y_deg = 40.0;
    let reference = render_rs(&rs, 33, 33).pixel(16, 16);
    for fov in [
        1e-30f32,
        1e-6,
        1e-3,
        0.1,
        90.0,
        179.0,
        179.999,
        180.0,
        1e3,
        0.0,
        -5.0,
        f32::NAN,
    ] {
        rs.camera.fov_y_deg = fov;
        let film = render_rs(&rs, 33, 33);
        let stats = film.stats();
        // Near 0 degrees every pixel sees (nearly) the same point.
        let spread = (0..33)
            .flat_map(|y| (0..33).map(move |x| (x, y)))
            .map(|(x, y)| (film.pixel(x, y) - film.pixel(16, 16)).abs().max_element())
            .fold(0.0f32, f32::max);
        eprintln!(
            "camera: fov {fov:e} deg: {} NaN/Inf pixels, largest difference from the centre pixel {spread:.2e}",
            stats.n_non_finite
        );
        assert_eq!(stats.n_non_finite, 0, "fov {fov}");
        assert_eq!(film.pixel(16, 16), reference, "fov {fov}: the centre pixel moved");
        if fov.abs() <= 1e-3 {
            assert!(spread < 0.02, "fov {fov}: spread {spread}");
        }
    }
}

#[test]
fn non_finite_vertices_are_rejected_at_load_and_never_reach_the_renderer() {
    // A unit square plus two triangles on a NaN and an infinite vertex; no
    // [camera] table, so the camera is fitted to the scene's bounds.
    let obj: &[u8] = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv nan 0 0\nv 0 inf 0\n\
f 1 2 3\nf 1 3 4\nf 3 2 5\nf 4 3 6\n";
    let toml: &[u8] = b"[[lights]]\ntype = \"directional\"\nto_light = [0, 0, 1]\n[[objects]]\nmesh = \"a.obj\"\n";
    let src = lucent_assets::MemorySource::new()
        .with_file("s.toml", toml)
        .with_file("a.obj", obj);
    let (scene, report) =
        lucent_assets::load_scene_from(&src, std::path::Path::new("s.toml")).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("geometry: non-finite vertices: {:?}", report.warnings);
    assert!(report.warnings.iter().any(|w| w.contains("rejected 2 vertices")));
    let (_, rig) = scene.camera().unwrap_or_else(|| panic!("a camera"));
    assert!(
        (rig.center - Vec3::new(0.5, 0.5, 0.0)).length() < 1e-6 && rig.radius < 10.0,
        "the camera frames the square: {rig:?}"
    );
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(rs.meshes[0].n_triangles(), 4, "triangle numbers are kept");
    assert_eq!(rs.bvh.meshes()[0].n_triangles(), 2, "only the square reaches the BVH");
    let film = render(
        &rs,
        &RenderSettings {
            width: 32,
            height: 32,
            ..scene.settings
        },
        &|_| {},
    )
    .film;
    assert_eq!(film.stats().n_non_finite, 0);
}

/// Closest hits through the BVH and by brute force, over a grid of rays
/// through `mesh`'s bounds and rays at every triangle's centroid, from
/// several sides: (rays, hits, disagreements, non-finite hits).
fn bvh_agrees_with_brute_force(mesh: &lucent_geom::TriMesh) -> (usize, usize, usize, usize) {
    use lucent_accel::{BuildParams, MeshBvh};
    let bvh = MeshBvh::build(mesh, &BuildParams::default());
    let b = mesh.bounds();
    let (c, r) = (b.center(), b.extent().length().max(1e-30));
    let mut out = (0, 0, 0, 0);
    let mut tally = |ray: lucent_geom::Ray| {
        let (a, bf) = (
            bvh.intersect(&ray, f32::INFINITY),
            bvh.intersect_brute_force(&ray, f32::INFINITY),
        );
        out.0 += 1;
        out.1 += usize::from(a.is_some());
        out.2 += usize::from(a.map(|h| h.t) != bf.map(|h| h.t));
        out.3 += usize::from(a.is_some_and(|h| !(h.t.is_finite() && h.u.is_finite() && h.v.is_finite())));
    };
    for dir in [
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        Vec3::new(1.0, 2.0, 3.0).normalize(),
        -Vec3::ONE.normalize(),
    ] {
        let (u, v) = (dir.any_orthonormal_pair().0, dir.any_orthonormal_pair().1);
        for i in 0..64 {
            for j in 0..64 {
                let off = (i as f32 / 63.0 - 0.5) * u + (j as f32 / 63.0 - 0.5) * v;
                tally(lucent_geom::Ray::new(c + r * (off - 2.0 * dir), dir));
            }
        }
        for t in 0..mesh.n_triangles() {
            let [p0, p1, p2] = mesh.triangle(t);
            tally(lucent_geom::Ray::new((p0 + p1 + p2) / 3.0 - 2.0 * r * dir, dir));
        }
    }
    out
}

#[test]
fn degenerate_needle_and_sliver_triangles_and_a_million_in_one_point() {
    use lucent_geom::TriMesh;
    // Degenerate: points, collinear corners, repeated indices, mixed with
    // proper triangles; they are never hit and break nothing.
    let mut p = vec![
        Vec3::ZERO,
        Vec3::X,
        Vec3::Y,
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.5, 0.5, 0.0),
    ];
    p.push(Vec3::new(0.25, 0.25, 0.0));
    let degenerate = vec![[0, 0, 0], [0, 1, 3], [1, 1, 2], [0, 1, 2], [4, 4, 5], [2, 4, 1]];
    let mesh = TriMesh::new(p, degenerate).unwrap_or_else(|e| panic!("{e}"));
    let (rays, hits, disagree, bad) = bvh_agrees_with_brute_force(&mesh);
    eprintln!(
        "geometry: degenerate mix: {rays} rays, {hits} hits, {disagree} BVH/brute-force disagreements, {bad} non-finite hits"
    );
    assert_eq!((disagree, bad), (0, 0));
    assert!(hits > 0);
    // Needles (one edge 1e-7 of the others) and slivers (a vertex 1e-7 off
    // the opposite edge), at several scales.
    for scale in [1e-6f32, 1.0, 1e6] {
        let mut p = Vec::new();
        let mut t = Vec::new();
        for k in 0..1000u32 {
            let x = k as f32 * 1e-3;
            let base = p.len() as u32;
            // Needle: long along z, 1e-7 wide.
            p.extend([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1e-7, 0.0, 0.0),
                Vec3::new(x, 0.0, 1.0),
            ]);
            // Sliver: 1 wide, its third corner 1e-7 off the base.
            p.extend([
                Vec3::new(0.0, x, 0.5),
                Vec3::new(1.0, x, 0.5),
                Vec3::new(0.5, x + 1e-7, 0.5),
            ]);
            t.extend([[base, base + 1, base + 2], [base + 3, base + 4, base + 5]]);
        }
        let p = p.into_iter().map(|v| v * scale).collect();
        let mesh = TriMesh::new(p, t).unwrap_or_else(|e| panic!("{e}"));
        let (rays, hits, disagree, bad) = bvh_agrees_with_brute_force(&mesh);
        eprintln!(
            "geometry: needles and slivers at scale {scale:e}: {rays} rays, {hits} hits, {disagree} disagreements, {bad} non-finite hits"
        );
        assert_eq!((disagree, bad), (0, 0), "scale {scale}");
        // Rays along y meet every needle, along z every sliver, the
        // diagonals both: most centroid rays hit.
        assert!(hits >= 4000, "scale {scale}: {hits} hits");
    }
    // A million triangles in one point, at the origin and far from it: the
    // build ends with a bounded tree and rays through the point find
    // nothing.
    let n = 1_000_000u32;
    for at in [Vec3::ZERO, Vec3::splat(1e6)] {
        let mesh = TriMesh::new(vec![at; 3], vec![[0, 1, 2]; n as usize]).unwrap_or_else(|e| panic!("{e}"));
        let start = std::time::Instant::now();
        let bvh = lucent_accel::MeshBvh::build(&mesh, &lucent_accel::BuildParams::default());
        let built = start.elapsed();
        let stats = bvh.stats();
        let ray = lucent_geom::Ray::new(at - Vec3::Z, Vec3::Z);
        let start = std::time::Instant::now();
        let hit = bvh.intersect(&ray, f32::INFINITY);
        let occluded = bvh.occluded(&ray, f32::INFINITY);
        eprintln!(
            "geometry: {n} triangles in one point at {at}: built in {built:.2?} ({} nodes, depth {}, largest leaf {}), a ray through it in {:.2?}: hit {hit:?}",
            stats.n_nodes,
            stats.max_depth,
            stats.max_leaf_size,
            start.elapsed()
        );
        assert!(hit.is_none() && !occluded);
        assert!(stats.max_depth <= 64, "{stats:?}");
    }
}
