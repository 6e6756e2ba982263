//! Tests of scene-file parsing and its error locations.

use super::*;
use crate::Shading;

fn parse(text: &str) -> Result<SceneFile, SceneFileError> {
    SceneFile::parse(Path::new("scenes/test.toml"), text)
}

/// Parses text that must fail and returns "line:column: message".
fn check_err(text: &str) -> String {
    match parse(text) {
        Ok(_) => "parsed without error".to_owned(),
        Err(e) => {
            assert_eq!(e.path, Path::new("scenes/test.toml"));
            assert!(!e.message.contains('\n'), "one-line message: {:?}", e.message);
            format!("{}:{}: {}", e.line, e.column, e.message)
        }
    }
}

const FULL: &str = r#"
[environment]
background = [0.1, 0.2, 0.3]
ambient = 0.25

[render]
width = 320
height = 180
spp = 4
max_depth = 6
min_weight = 0.02
rr_depth = 3
shading = "phong"
seed = 7
denoise = true

[camera]
center = [0.0, 0.5, 0.0]
radius = 4.0
theta_deg = 15.0
phi_deg = 60.0
fov_y_deg = 50.0

[[lights]]
type = "directional"
to_light = [0.0, 1.0, 0.0]
intensity = 0.9

[[lights]]
type = "point"
position = [1.0, 2.0, 3.0]

[materials.glass]
kd = [0.8, 0.8, 0.8]
kt = 0.5
ior = 1.1

[materials.wood]
kd = [0.5, 0.3, 0.1]
roughness = 0.3
texture = { file = "wood.png", wrap = "clamp" }

[[objects]]
name = "ball"
shape = "sphere"
subdivisions = 3
material = "glass"
translate = [1.0, 0.0, 0.0]
scale = 0.5

[[objects]]
mesh = "../meshes/bunny.ply"
rotate_deg = [0.0, 90.0, 0.0]
scale = [1.0, 2.0, 3.0]
"#;

#[test]
fn parses_every_table() {
    let f = parse(FULL).map_err(|e| e.to_string());
    let Ok(f) = f else {
        panic!("{f:?}");
    };
    let d = &f.desc;
    assert_eq!(d.environment.background.0, Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(d.environment.ambient.0, Vec3::splat(0.25));
    assert_eq!(
        (d.render.width, d.render.height, d.render.spp),
        (Some(320), Some(180), Some(4))
    );
    assert_eq!(d.render.shading, Some(Shading::Phong));
    assert_eq!(d.render.rr_depth, Some(3));
    assert_eq!(d.render.denoise, Some(true));
    for bad in ["rr_depth = 0", "rr_depth = 65"] {
        let e = parse(&format!("[render]\n{bad}\n"))
            .map(|_| ())
            .map_err(|e| e.to_string());
        assert!(
            matches!(&e, Err(m) if m.contains("rr_depth runs from 1 to 64")),
            "{bad}: {e:?}"
        );
    }
    let cam = d.camera.as_ref().map(|c| (c.radius, c.fov_y_deg));
    assert_eq!(cam, Some((Some(4.0), 50.0)));
    assert_eq!(d.lights.len(), 2);
    assert!(matches!(d.lights[1], LightDesc::Point { intensity: Color(i), .. } if i == Vec3::ONE));
    let wood = &d.materials["wood"];
    assert_eq!(
        wood.texture.as_ref().map(|t| t.get_ref().wrap()),
        Some(lucent_shading::WrapMode::Clamp)
    );
    assert_eq!(wood.texture.as_ref().map(|t| t.get_ref().file()), Some("wood.png"));
    assert_eq!(d.materials["glass"].ka.map(|c| c.0), None);
    assert_eq!((wood.roughness, d.materials["glass"].roughness), (0.3, 0.0));
    assert_eq!(d.objects.len(), 2);
    let ball = d.objects[0].get_ref();
    let p = ball.world_from_object().transform_point3(Vec3::X);
    assert!(p.abs_diff_eq(Vec3::new(1.5, 0.0, 0.0), 1e-6));
    let bunny = d.objects[1].get_ref();
    // 90 degrees about y takes +x to -z.
    let p = bunny.world_from_object().transform_point3(Vec3::X);
    assert!(p.abs_diff_eq(Vec3::new(0.0, 0.0, -1.0), 1e-6), "{p}");
    assert_eq!(f.resolve("a.ply"), Path::new("scenes/a.ply"));
}

#[test]
fn empty_file_is_an_empty_scene() {
    let f = parse("").map(|f| f.desc.objects.len());
    assert_eq!(f, Ok(0));
}

#[test]
fn syntax_errors_point_at_the_spot() {
    assert_eq!(
        check_err("[render]\nwidth = 3 4\n"),
        "2:9: string values must be quoted, expected literal string"
    );
    assert!(check_err("[camera\n").starts_with("1:8: "));
}

#[test]
fn unknown_keys_and_bad_values_are_located() {
    assert_eq!(
        check_err("[camera]\nradus = 2.0\n"),
        "2:1: unknown field `radus`, expected one of `center`, `radius`, `theta_deg`, `phi_deg`, `fov_y_deg`"
    );
    assert_eq!(
        check_err("[camera]\nfov_y_deg = 180\n"),
        "2:13: fov_y_deg must lie strictly between 0 and 180"
    );
    assert_eq!(
        check_err("[render]\nshading = \"flat\"\n"),
        "2:11: unknown name `flat`, expected gouraud or phong"
    );
    assert_eq!(
        check_err("[materials.a]\nkd = [1, -1, 0]\n"),
        "2:6: colour components must be finite and at least 0"
    );
    assert_eq!(
        check_err("[materials.a]\nkd = [1, 1]\n"),
        "2:6: invalid length 2, expected a colour: a number or [r, g, b]"
    );
    assert_eq!(
        check_err("[materials.a]\nroughness = 1.5\n"),
        "2:13: roughness must be between 0 and 1"
    );
    assert_eq!(
        check_err("[[objects]]\nshape = \"cube\"\nscale = [1, 0, 1]\n"),
        "3:9: scale factors must be finite and non-zero"
    );
    assert_eq!(
        check_err("[render]\nwidth = 0\n"),
        "2:9: image sizes run from 1 to 16384 pixels"
    );
    assert_eq!(
        check_err("[[lights]]\ntype = \"spot\"\n"),
        "2:8: unknown variant `spot`, expected `directional` or `point`"
    );
}

#[test]
fn semantic_errors_point_at_the_value() {
    let text = "[materials.red]\nkd = [1, 0, 0]\n\n[[objects]]\nshape = \"cube\"\nmaterial = \"yelow\"\n";
    assert_eq!(check_err(text), "6:12: unknown material 'yelow' (defined: red)");
    assert_eq!(
        check_err("[[objects]]\nmesh = \"a.stl\"\n"),
        "2:8: mesh 'a.stl' is neither .obj nor .ply"
    );
    assert_eq!(
        check_err("x = 1\n[[objects]]\nshape = \"cube\"\nmesh = \"a.ply\"\n"),
        "1:1: unknown field `x`, expected one of `environment`, `render`, `camera`, `lights`, `materials`, `objects`"
    );
    assert_eq!(
        check_err("\n[[objects]]\nname = \"nothing\"\n"),
        "2:1: an object needs a `mesh` file or a `shape`"
    );
    assert_eq!(
        check_err("[[objects]]\nshape = \"cube\"\nsubdivisions = 2\n"),
        "1:1: `subdivisions` applies only to `shape = \"sphere\"`"
    );
}

#[test]
fn columns_count_characters_not_bytes() {
    // "é" is two bytes; the bad value is still reported at column 18.
    let text = "[materials.\"é\"]\nkd = 1\n[[objects]]\nshape = \"cube\"\nmaterial = \"ééé\"\n";
    assert!(
        check_err(text).starts_with("5:12: unknown material 'ééé'"),
        "{}",
        check_err(text)
    );
    assert_eq!(line_column("aé\nxé€y", 10), (2, 4));
    // An offset inside a character counts from that character.
    assert_eq!(line_column("aé\nxé€y", 9), (2, 3));
}

#[test]
fn environment_maps_and_tone_curves_parse_and_are_checked() {
    let text =
        "[environment]\nmap = \"sky.hdr\"\nintensity = 2.0\nrotation_deg = -90\n[render]\ntonemap = \"filmic\"\n";
    let f = parse(text).unwrap_or_else(|e| panic!("{e}"));
    let env = &f.desc.environment;
    assert_eq!(env.map.as_ref().map(|m| m.get_ref().as_str()), Some("sky.hdr"));
    assert_eq!((env.intensity, env.rotation_deg), (2.0, -90.0));
    assert_eq!(f.desc.render.tonemap, Some(crate::Tonemap::Filmic));
    let d = parse("").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        (d.desc.environment.intensity, d.desc.environment.rotation_deg),
        (1.0, 0.0)
    );
    assert_eq!(
        check_err("[environment]\nmap = \"sky.png\"\n"),
        "2:7: environment map 'sky.png' is neither .hdr nor .exr"
    );
    assert!(check_err("[environment]\nintensity = -1\n").starts_with("2:13: "));
    assert!(check_err("[render]\ntonemap = \"reinhard\"\n").starts_with("2:11: "));
}
