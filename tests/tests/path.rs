//! The path tracer end to end: an OBJ lamp whose MTL gives `Ke` lights a
//! scene with no `[[lights]]` at all.

use lucent_assets::{MemorySource, load_scene_from};
use lucent_geom::Vec3;
use lucent_render::{Integrator, extract, render};
use std::path::Path;

/// A 2x2 quad at y = 1 wound to face down (-y), with material `lamp`.
const LAMP_OBJ: &[u8] = b"mtllib lamp.mtl\nv -1 1 -1\nv 1 1 -1\nv 1 1 1\nv -1 1 1\nusemtl lamp\nf 1 2 3\nf 1 3 4\n";
const LAMP_MTL: &[u8] = b"newmtl lamp\nKd 0 0 0\nKe 3 2 1\n";
const SCENE: &[u8] = b"[render]\nintegrator = \"path\"\nwidth = 8\nheight = 8\nspp = 2\nmax_depth = 4\n\
[camera]\ncenter = [0.0, 1.0, 0.0]\nradius = 3.0\ntheta_deg = -60.0\nphi_deg = 90.0\nfov_y_deg = 10.0\n\
[[objects]]\nmesh = \"lamp.obj\"\n";

#[test]
fn an_obj_lamp_with_ke_is_an_area_light_seen_from_its_front_only() {
    let src = MemorySource::new()
        .with_file("s.toml", SCENE)
        .with_file("lamp.obj", LAMP_OBJ)
        .with_file("lamp.mtl", LAMP_MTL);
    let (scene, report) = load_scene_from(&src, Path::new("s.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        report.warnings.is_empty(),
        "an emissive MTL is a light: {:?}",
        report.warnings
    );
    assert_eq!(scene.settings.integrator, Integrator::Path);
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let emitters = rs.light_set.emitters();
    assert_eq!(emitters.len(), 2);
    assert!(
        emitters
            .iter()
            .all(|e| e.n == -Vec3::Y && e.radiance == Vec3::new(3.0, 2.0, 1.0))
    );
    // Seen from below (the camera is 60 degrees under the lamp's centre,
    // a 10 degree view inside the quad): every pixel is the lamp's Ke.
    let film = render(&rs, &scene.settings, &|_| {}).film;
    for p in film.to_linear() {
        assert!((p - Vec3::new(3.0, 2.0, 1.0)).abs().max_element() < 1e-6, "{p}");
    }
    // From above, its back: black.
    let mut above = scene.settings;
    above.seed = 1;
    if let Some(cam) = scene.active_camera
        && let Ok(mut rig) = scene.world.get::<&mut lucent_scene::components::OrbitRig>(cam)
    {
        rig.theta = -rig.theta;
    }
    let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
    let film = render(&rs, &above, &|_| {}).film;
    assert!(film.to_linear().iter().all(|p| *p == Vec3::ZERO));
}

// The cheap presets' two bends of the path tracer (`free_delta_bounces`,
// `clamp_indirect`), on scenes with known answers.

mod bends {
    use lucent_geom::{Pcg32, Ray, Vec3};
    use lucent_render::path::PathTracer;
    use lucent_render::{Film, Integrator, RayStats, RenderSettings, extract, render};
    use lucent_scene::fixtures;

    fn settings(max_depth: u32, spp: u32) -> RenderSettings {
        RenderSettings {
            width: 12,
            height: 8,
            spp,
            max_depth,
            integrator: Integrator::Path,
            seed: 3,
            ..RenderSettings::default()
        }
    }

    fn mean(film: &Film) -> Vec3 {
        let px = film.to_linear();
        px.iter().copied().sum::<Vec3>() / px.len() as f32
    }

    #[test]
    fn free_delta_bounces_let_a_short_path_see_past_a_mirror() {
        // Camera ray -> mirror floor -> ceiling: with max_depth 2 the path
        // reaches the ceiling on its last segment and gathers no light
        // there; one free delta bounce makes that the direct light of a
        // depth-3 path, with the very same random numbers and radiance.
        let from = Vec3::new(0.0, 1.0, 1.0);
        let ray = Ray::new(from, (-from).normalize());
        let rs = extract(&fixtures::mirror_under_ceiling()).unwrap_or_else(|e| panic!("{e}"));
        let trace = |s: &RenderSettings| {
            PathTracer::new(&rs, s).trace_primary(ray, &mut Pcg32::new(5, 0), &mut RayStats::default())
        };
        assert_eq!(
            trace(&settings(2, 1)),
            Vec3::ZERO,
            "the ceiling's light is beyond the limit"
        );
        let free = |n: u32| {
            trace(&RenderSettings {
                free_delta_bounces: n,
                ..settings(2, 1)
            })
        };
        assert!(free(1).max_element() > 0.0, "{}", free(1));
        assert_eq!(free(1), trace(&settings(3, 1)));
        // The ceiling is diffuse: a second free bounce has nothing to do.
        assert_eq!(free(8), free(1));
    }

    #[test]
    fn clamp_indirect_caps_only_light_that_bounced() {
        let scene = fixtures::glowing_box(1.0, 1.0);
        let rs = extract(&scene).unwrap_or_else(|e| panic!("{e}"));
        let film = |depth: u32, clamp: f32| {
            let s = RenderSettings {
                clamp_indirect: clamp,
                ..settings(depth, 16)
            };
            render(&rs, &s, &|_| {}).film
        };
        // No clamp, or one no contribution reaches: the same bytes.
        assert_eq!(film(4, 0.0), film(4, 1e9));
        // Depth 2 is emission seen directly plus direct light: nothing to
        // clamp.
        assert_eq!(film(2, 0.0), film(2, 0.01));
        // Depth 3 adds one bounce of indirect light, worth 1 in this
        // furnace (mean 3); capped at 0.05 per contribution, at most two
        // per sample (emission found after two bounces, light sampled at
        // the second surface), the mean stays near the direct part's 2.
        let full = mean(&film(3, 0.0));
        let capped = mean(&film(3, 0.05));
        assert!((full - Vec3::splat(3.0)).abs().max_element() < 0.1, "{full}");
        assert!(capped.max_element() <= 2.0 + 2.0 * 0.05 + 0.05, "{capped}");
        assert!(capped.min_element() > 1.9, "{capped}");
    }
}
