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
            .all(|e| Vec3::from(e.n) == -Vec3::Y && e.radiance == Vec3::new(3.0, 2.0, 1.0))
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
    let film = lucent_tests::render_with(&scene, &above);
    assert!(film.to_linear().iter().all(|p| *p == Vec3::ZERO));
}
