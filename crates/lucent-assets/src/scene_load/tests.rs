//! Tests of scene loading from memory.

use super::*;
use crate::MemorySource;
use lucent_scene::components::{MaterialRef, MeshRef, Name};

const PLY: &[u8] = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

fn n_triangles(scene: &Scene) -> usize {
    scene.world.query::<&Mesh>().iter().map(|m| m.0.n_triangles()).sum()
}

fn load(scene_text: &'static str) -> Result<(Scene, LoadReport), String> {
    let src = MemorySource::new()
        .with_file("scenes/s.toml", scene_text.as_bytes())
        .with_file("meshes/tri.ply", PLY);
    load_scene_from(&src, Path::new("scenes/s.toml")).map_err(|e| e.to_string())
}

#[test]
fn shared_meshes_are_loaded_once_and_materials_resolve() {
    let text = r#"
[[lights]]
type = "directional"
to_light = [0, 2, 0]

[materials.red]
kd = [1, 0, 0]
roughness = 0.25

[[objects]]
mesh = "../meshes/tri.ply"
material = "red"

[[objects]]
name = "second"
mesh = "../meshes/./tri.ply"
translate = [2, 0, 0]

[[objects]]
shape = "sphere"
subdivisions = 1
"#;
    let (scene, report) = load(text).unwrap_or_else(|e| panic!("{e}"));
    let c = scene.counts();
    assert_eq!((c.meshes, c.instances, c.lights, c.cameras), (2, 3, 1, 1));
    assert_eq!(n_triangles(&scene), 1 + 80);
    // red + the default material for the other two.
    assert_eq!(c.materials, 2);
    let names: Vec<String> = scene
        .world
        .query::<(&Name, &MeshRef, &MaterialRef)>()
        .iter()
        .map(|(n, _, _)| n.0.clone())
        .collect();
    assert!(
        names.contains(&"tri".to_owned())
            && names.contains(&"second".to_owned())
            && names.contains(&"sphere".to_owned())
    );
    let red = scene
        .world
        .query::<(&Name, &Material)>()
        .iter()
        .find(|(n, _)| n.0 == "red")
        .map(|(_, m)| m.clone());
    assert_eq!(red.map(|m| (m.kd, m.roughness)), Some((lucent_geom::Vec3::X, 0.25)));
    // The PLY had no normals: smooth ones were added for shading.
    for m in scene.world.query::<&Mesh>().iter() {
        assert!(m.0.normals().is_some());
    }
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    // No camera in the file: it frames the scene.
    let rig = scene.camera().map(|(_, r)| r);
    assert!(rig.is_some_and(|r| r.radius > 1.0 && r.center.is_finite()));
}

#[test]
fn missing_files_are_reported_at_the_reference() {
    let err = load("[[objects]]\nmesh = \"../meshes/nope.ply\"\n")
        .map(|_| ())
        .unwrap_err();
    assert!(
        err.starts_with("scenes/s.toml:2:8: cannot load mesh '../meshes/nope.ply': meshes/nope.ply: "),
        "{err}"
    );
    let err = load("[materials.a]\ntexture = \"wood.png\"\n").map(|_| ()).unwrap_err();
    assert_eq!(
        err,
        "scenes/s.toml:2:11: cannot load texture 'wood.png': scenes/wood.png does not exist"
    );
}

#[test]
fn scenes_without_lights_warn() {
    let (_, report) = load("[[objects]]\nshape = \"cube\"\n").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        report.warnings,
        vec!["scenes/s.toml: no lights: only ambient light will show".to_owned()]
    );
    // An emissive material is a light source for the path tracer.
    let text = "[materials.lamp]\nemission = 4\n[[objects]]\nshape = \"cube\"\nmaterial = \"lamp\"\n";
    let (scene, report) = load(text).unwrap_or_else(|e| panic!("{e}"));
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    assert_eq!(scene.settings.integrator, lucent_scene::Integrator::Whitted);
    let (scene, _) = load("[render]\nintegrator = \"path\"\nmax_depth = 16\n").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        (scene.settings.integrator, scene.settings.max_depth),
        (lucent_scene::Integrator::Path, 16)
    );
}

#[test]
fn non_utf8_scene_is_an_error_with_a_line() {
    let src = MemorySource::new().with_file("s.toml", b"# ok\n\xff\xfe\n");
    let err = load_scene_from(&src, Path::new("s.toml"))
        .map(|_| ())
        .map_err(|e| e.to_string());
    assert_eq!(err, Err("s.toml:2: the scene file is not valid UTF-8 text".to_owned()));
}

#[test]
fn framing_bounds_follow_parent_transforms() {
    use lucent_geom::{Affine3A, Vec3};
    use lucent_scene::components::{Parent, Transform};
    let mut scene = Scene::default();
    let cube = scene.add_mesh("cube", shapes::cuboid());
    let mat = scene.add_material("m", Material::default());
    let parent = scene
        .world
        .spawn((Transform(Affine3A::from_translation(Vec3::new(10.0, 0.0, 0.0))),));
    let child = scene.add_instance("child", cube, mat, Affine3A::IDENTITY);
    let _ = scene.world.insert_one(child, Parent(parent));
    let b = world_bounds(&scene.world);
    assert_eq!(b.center(), Vec3::new(10.0, 0.0, 0.0));
}

/// Instances sharing one mesh each add it where they stand (the mesh's own
/// bounds are worked out once and reused).
#[test]
fn instances_of_one_mesh_bound_the_scene_where_each_stands() {
    use lucent_geom::{Affine3A, Vec3};
    let mut scene = Scene::default();
    let cube = scene.add_mesh("cube", shapes::cuboid());
    let mat = scene.add_material("m", Material::default());
    for x in [-4.0, 0.0, 6.0] {
        scene.add_instance("c", cube, mat, Affine3A::from_translation(Vec3::new(x, 0.0, 0.0)));
    }
    let one = shapes::cuboid().bounds();
    let b = world_bounds(&scene.world);
    assert_eq!(b.min, one.min + Vec3::new(-4.0, 0.0, 0.0));
    assert_eq!(b.max, one.max + Vec3::new(6.0, 0.0, 0.0));
}

#[test]
fn parts_sharing_an_mtl_material_share_its_entity() {
    let obj: &'static [u8] =
        b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\ng a\nusemtl red\nf 1 2 3\ng b\nf 3 2 1\ng c\nusemtl blue\nf 1 3 2\n";
    let src = MemorySource::new()
        .with_file(
            "s.toml",
            b"[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\n[[objects]]\nmesh = \"t.obj\"\n",
        )
        .with_file("t.obj", obj)
        .with_file("m.mtl", b"newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n");
    let (scene, _) = load_scene_from(&src, Path::new("s.toml")).unwrap_or_else(|e| panic!("{e}"));
    let c = scene.counts();
    assert_eq!((c.meshes, c.instances, c.materials), (3, 3, 2));
}

#[test]
fn metallic_keys_make_a_metallic_roughness_material() {
    let text = r#"
[materials.gold]
kd = [1, 0.5, 0.25]
metallic = 1.0
roughness = 0.3

[materials.plain]
kd = 0.5
roughness = 0.3

[[objects]]
mesh = "../meshes/tri.ply"
material = "gold"

[[objects]]
mesh = "../meshes/tri.ply"
material = "plain"
"#;
    let (scene, _) = load(text).unwrap_or_else(|e| panic!("{e}"));
    let mut seen = 0;
    for m in scene.world.query::<&Material>().iter() {
        match &m.pbr {
            Some(p) => {
                assert_eq!(
                    (p.base_color, p.metallic, p.roughness),
                    (Vec3::new(1.0, 0.5, 0.25), 1.0, 0.3)
                );
                assert_eq!(
                    (m.ior, m.kd),
                    (1.5, Vec3::ZERO),
                    "glTF's default ior; a metal has no diffuse"
                );
                seen += 1;
            }
            None => assert_eq!(m.kd, Vec3::splat(0.5)),
        }
    }
    assert_eq!(seen, 1);
    let bad = load("[materials.m]\nmetallic = 2.0\n").map(|_| ());
    assert!(bad.as_ref().is_err_and(|e| e.contains("between 0 and 1")), "{bad:?}");
}

/// A 4x2 Radiance RGBE file (flat, not run-length encoded) whose first texel
/// is `first` (mantissas and exponent) and the rest mid-grey.
fn hdr_file(first: [u8; 4]) -> Vec<u8> {
    let mut f = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
    f.extend_from_slice(&first);
    for _ in 1..8 {
        f.extend_from_slice(&[128, 128, 128, 128]);
    }
    f
}

fn load_with_map(
    scene_text: &'static str,
    map_name: &'static str,
    map: Vec<u8>,
) -> Result<(Scene, LoadReport), String> {
    let src = MemorySource::new()
        .with_file("scenes/s.toml", scene_text.as_bytes())
        .with_file(map_name, map);
    load_scene_from(&src, Path::new("scenes/s.toml")).map_err(|e| e.to_string())
}

#[test]
fn environment_maps_load_with_their_settings() {
    let text = "[environment]\nmap = \"../sky/a.hdr\"\nintensity = 3\nrotation_deg = 45\n";
    let (scene, report) =
        load_with_map(text, "sky/a.hdr", hdr_file([128, 64, 32, 129])).unwrap_or_else(|e| panic!("{e}"));
    let env = &scene.environment;
    let Some(map) = &env.map else { panic!("no map") };
    assert_eq!((map.width(), map.height()), (4, 2));
    // RGBE (128, 64, 32, 129): mantissa / 256 * 2^(129 - 128).
    assert_eq!(map.texel(0, 0), lucent_geom::Vec3::new(1.0, 0.5, 0.25));
    assert_eq!(map.texel(1, 1), lucent_geom::Vec3::splat(0.5));
    assert_eq!((env.intensity, env.rotation_deg), (3.0, 45.0));
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
}

#[test]
fn bad_environment_maps_are_errors_naming_the_file() {
    let text = "[environment]\nmap = \"sky.hdr\"\n";
    let missing = load(text).err().unwrap_or_default();
    assert!(
        missing.starts_with("scenes/s.toml:2:7: cannot load environment map 'sky.hdr': scenes/sky.hdr does not exist"),
        "{missing}"
    );
    let not_image = load_with_map(text, "scenes/sky.hdr", b"hello".to_vec())
        .err()
        .unwrap_or_default();
    assert!(
        not_image.contains("scenes/sky.hdr is not a usable image (not a Radiance HDR or OpenEXR image"),
        "{not_image}"
    );
    let png = crate::encode_png(1, 1, &[1, 2, 3]).unwrap_or_default();
    let wrong = load_with_map(text, "scenes/sky.hdr", png).err().unwrap_or_default();
    assert!(wrong.contains("Png images are not environment maps"), "{wrong}");
    let huge = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 20000 +X 20000\n".to_vec();
    let huge = load_with_map(text, "scenes/sky.hdr", huge).err().unwrap_or_default();
    assert!(
        huge.contains("the image is 20000x20000; environment maps are at most"),
        "{huge}"
    );
    let truncated = hdr_file([1, 1, 1, 128]);
    let truncated = load_with_map(text, "scenes/sky.hdr", truncated[..truncated.len() - 9].to_vec())
        .err()
        .unwrap_or_default();
    assert!(truncated.contains("cannot decode image"), "{truncated}");
}

#[test]
fn non_finite_and_negative_texels_become_black_with_a_warning() {
    // An EXR with a NaN, an infinite and a negative texel.
    let rgb = [
        1.0,
        1.0,
        1.0,
        f32::NAN,
        0.0,
        0.0,
        f32::INFINITY,
        1.0,
        1.0,
        -2.0,
        0.5,
        0.5,
    ];
    let exr = crate::encode_exr(2, 2, &rgb).unwrap_or_default();
    let text = "[environment]\nmap = \"sky.exr\"\n";
    let (scene, report) = load_with_map(text, "scenes/sky.exr", exr).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        report.warnings,
        ["scenes/sky.exr: 3 texels are NaN, infinite or negative; they are black"]
    );
    let Some(map) = &scene.environment.map else {
        panic!("no map")
    };
    assert_eq!(
        map.texels(),
        [
            lucent_geom::Vec3::ONE,
            lucent_geom::Vec3::ZERO,
            lucent_geom::Vec3::ZERO,
            lucent_geom::Vec3::ZERO
        ]
    );
}
