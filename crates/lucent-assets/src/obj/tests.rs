//! Tests of the OBJ parser and MTL materials: polygons, indices, smoothing
//! groups, colours, located errors, missing files.

use super::*;
use crate::mtl::{normalize_mtl, parse_map};
use crate::{MemorySource, load_mesh_from};

const QUAD_OBJ: &[u8] = b"mtllib q.mtl\r\nv 0 0 0\r\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
usemtl shiny\nf 1/1 2/2 3/3 4/4\n";
const QUAD_MTL: &[u8] = b"newmtl shiny\nKa 0.1 0.1 0.1  # comment\nKd 0.5 0.25 0\nKs 0.9 0.9 0.9\nNs 50\nillum 3\nd 0.75\nNi 1.33\nKe 2 3 4\nPr 0.4\nmap_Kd -s 2 2 1 -o 0.5 0 -clamp on -bm 0.3 tex.png\n";

fn load(files: &[(&str, &[u8])], path: &str) -> Result<(Vec<MeshPart>, LoadReport), String> {
    let src = files.iter().fold(MemorySource::new(), |s, (name, bytes)| {
        s.with_file(name, bytes.to_vec())
    });
    load_mesh_from(&src, Path::new(path)).map_err(|e| e.to_string())
}

fn parse_err(text: &[u8]) -> Result<(), String> {
    load(&[("t.obj", text)], "t.obj").map(|_| ())
}

/// `text` as `t.obj`, which must load.
fn load_obj(text: &[u8]) -> (Vec<MeshPart>, LoadReport) {
    load(&[("t.obj", text)], "t.obj").unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn loads_polygons_uvs_and_mtl() {
    let (parts, report) = load(&[("m/q.obj", QUAD_OBJ), ("m/q.mtl", QUAD_MTL)], "m/q.obj").unwrap_or_default();
    assert_eq!(parts.len(), 1);
    let part = &parts[0];
    assert_eq!(part.mesh.indices(), &[[0, 1, 2], [0, 2, 3]], "fanned in file order");
    assert!(part.mesh.uvs().is_some() && part.mesh.colors().is_none());
    assert!(part.normals_computed);
    assert_eq!(part.mesh.normals().map(|n| n[0]), Some(Vec3::Z));
    assert_eq!(part.material_name.as_deref(), Some("shiny"));
    let m = part.material.clone().unwrap_or_default();
    assert_eq!(
        (m.ka, m.kd, m.shininess, m.ior, m.emission),
        (
            Vec3::splat(0.1),
            Vec3::new(0.5, 0.25, 0.0),
            50.0,
            1.33,
            Vec3::new(2.0, 3.0, 4.0)
        )
    );
    assert_eq!((m.kr, m.kt, m.roughness), (Vec3::splat(0.9), Vec3::splat(0.25), 0.4));
    // The texture is missing: a warning and a checkerboard, not an error;
    // its options are kept and the unknown one is a warning.
    let tex = m
        .diffuse_map
        .unwrap_or_else(|| std::sync::Arc::new(lucent_shading::Texture::constant(Vec3::ZERO)));
    assert_eq!(tex.width(), 8);
    assert_eq!((tex.uv_scale, tex.uv_offset), (Vec2::splat(2.0), Vec2::new(0.5, 0.0)));
    assert_eq!(tex.wrap, lucent_shading::WrapMode::Clamp);
    assert_eq!(report.warnings.len(), 2, "{:?}", report.warnings);
    assert!(
        report.warnings[0].contains("map_Kd option -bm 0.3 is not supported"),
        "{:?}",
        report.warnings
    );
    assert_eq!(
        report.warnings[1],
        "m/q.mtl: material 'shiny': texture 'tex.png': m/tex.png does not exist; it shows a checkerboard instead"
    );
}

#[test]
fn map_options_and_file_names_with_spaces() {
    let m = parse_map("-blendu off -s 3 -t 1 1 1 -imfchan r my tex.png");
    assert_eq!(m.file, "my tex.png");
    assert_eq!(m.scale, Vec2::new(3.0, 1.0));
    assert_eq!(m.ignored, vec!["-blendu off", "-t 1 1 1", "-imfchan r"]);
    assert_eq!(parse_map("plain.png").file, "plain.png");
}

#[test]
fn mtl_fields_are_checked_with_lines() {
    assert_eq!(
        normalize_mtl(b"Kd 0.5\nKs 1 0 0 # red\nNs 8\n"),
        Ok("Kd 0.5 0.5 0.5\nKs 1 0 0\nNs 8\n".into())
    );
    assert_eq!(
        normalize_mtl(b"newmtl a\nKa 0.2 0.3\n"),
        Err((2, "`Ka` needs one or three numbers, found '0.2 0.3'".into()))
    );
    assert_eq!(
        normalize_mtl(b"newmtl a\n\nNs shiny\n"),
        Err((3, "`Ns` needs one number, found 'shiny'".into()))
    );
    assert_eq!(
        normalize_mtl(b"Pr rough\n"),
        Err((1, "`Pr` needs one number, found 'rough'".into()))
    );
    assert_eq!(
        normalize_mtl(b"illum 300\n"),
        Err((1, "`illum` needs an integer from 0 to 10, found '300'".into()))
    );
    let (_, report) = load(
        &[("q.obj", QUAD_OBJ), ("q.mtl", b"newmtl shiny\nKd 0.2 x 0.1\n")],
        "q.obj",
    )
    .unwrap_or_default();
    assert_eq!(
        report.warnings,
        vec!["q.obj: line 1: cannot load its MTL file (q.mtl:2: `Kd` needs one or three numbers, found '0.2 x 0.1'); its materials show in magenta".to_owned()]
    );
}

#[test]
fn tr_is_the_complement_of_d() {
    let (parts, _) = load(&[("q.obj", QUAD_OBJ), ("q.mtl", b"newmtl shiny\nTr 0.25\n")], "q.obj").unwrap_or_default();
    assert_eq!(parts[0].material.as_ref().map(|m| m.kt), Some(Vec3::splat(0.25)));
}

#[test]
fn indices_are_made_absolute_and_checked() {
    let (parts, _) = load_obj(b"v 0 0 0\nv 1 0 0 # comment\nv 0 1 0\nvt 0 0\nf -3/1 -2/-1 -1/1 # tri\ng a#1\n");
    assert_eq!(parts[0].mesh.indices(), &[[0, 1, 2]]);
    assert_eq!(
        parse_err(b"v 0 0 0\nf 1//1 1 1\n"),
        Err("t.obj:2: normal index 1 is out of range (0 normals)".into())
    );
    assert_eq!(
        parse_err(b"v 0 0 0\nf 0 1 1\n"),
        Err("t.obj:2: index 0 is not valid (OBJ indices start at 1)".into())
    );
    assert_eq!(
        parse_err(b"v 0 0 0\nf -2147483648 1 1\n"),
        Err("t.obj:2: vertex index -2147483648 is out of range (1 vertices)".into())
    );
    assert_eq!(
        parse_err(b"f 1/2/3/4\n"),
        Err("t.obj:1: '1/2/3/4' has more than three indices".into())
    );
    assert_eq!(
        parse_err(b"v 0 0 0\nf 1 x\n"),
        Err("t.obj:2: 'x' is not an index".into())
    );
    assert_eq!(
        parse_err(b"v 0 0 0\nv 1 2 3\nf 1 2 3\n"),
        Err("t.obj:3: vertex index 3 is out of range (2 vertices)".into())
    );
    // Positive indices may refer forward.
    assert!(parse_err(b"f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").is_ok());
    let (_, report) = load_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\n");
    assert_eq!(report.warnings, ["t.obj: 1 vertices are not used by any face"]);
}

#[test]
fn non_numeric_fields_name_the_line() {
    assert_eq!(
        parse_err(b"v 0 0 0\r\nv 1 0 zero\r\n"),
        Err("t.obj:2: 'zero' is not a number".into())
    );
    assert_eq!(
        parse_err(b"v 0 0 0\nvn 0 1\n"),
        Err("t.obj:2: 'vn' needs 3 numbers, found 2".into())
    );
    assert_eq!(
        parse_err(b"v 0 0\n"),
        Err("t.obj:1: 'v' needs 3, 4 or 6 numbers, found 2".into())
    );
    assert_eq!(
        parse_err(b"s maybe\n"),
        Err("t.obj:1: 'maybe' is not a smoothing group (a number or 'off')".into())
    );
}

#[test]
fn msvc_and_other_non_finite_spellings_reject_the_vertex() {
    // Two triangles over four vertices; the third vertex is not finite.
    for word in crate::number::NON_FINITE_WORDS {
        let text = format!("v 0 0 0\nv 1 0 0\nv 1 {word} 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\nf 1 2 4\n");
        let (parts, report) = load_obj(text.as_bytes());
        let m = parts.first().map(|p| &p.mesh);
        assert_eq!(
            m.map(|m| (m.positions().len(), m.n_triangles())),
            Some((4, 3)),
            "{word}"
        );
        assert!(
            m.is_some_and(|m| m.positions()[2].is_nan()),
            "{word}: the vertex is rejected"
        );
        assert_eq!(
            report.warnings,
            [
                "t.obj: rejected 1 vertices with NaN or infinite coordinates and the 2 triangles that use them \
              (they keep their numbers but are never drawn)"
            ],
            "{word}"
        );
    }
    // (A word that starts with `#`, such as `#IND`, starts a comment.)
    for word in crate::number::NOT_NUMBERS {
        let text = format!("v 0 0 0\nv 1 0 0\nv 1 {word} 0\nf 1 2 3\n");
        assert_eq!(
            parse_err(&text.into_bytes()),
            Err(format!("t.obj:3: '{word}' is not a number")),
            "{word}"
        );
    }
}

#[test]
fn vertex_colours_and_attributes_only_when_given() {
    let (parts, _) = load_obj(b"v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 1 1 0\nf 1 2 3\nf 2 4 3\n");
    let m = &parts[0].mesh;
    assert_eq!(
        m.colors().map(<[Vec3]>::to_vec),
        Some(vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE])
    );
    assert!(m.uvs().is_none(), "no UVs in the file, none stored");
    assert!(parts[0].material.is_none() && parts[0].material_name.is_none());
}

/// A roof: two faces meeting at a ridge, sharing vertices 1 and 2.
const ROOF: &str = "v 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 0 -1\nv 1 0 -1\n";

fn roof(statements: &str) -> Vec<MeshPart> {
    let text = format!("{ROOF}{statements}").into_bytes();
    load(&[("r.obj", &text)], "r.obj").map(|(p, _)| p).unwrap_or_default()
}

#[test]
fn smoothing_groups_decide_shared_normals() {
    // No `s` at all: smooth across the ridge (ridge normal points up).
    let smooth = roof("f 1 3 4 2\nf 2 6 5 1\n");
    assert_eq!(smooth[0].mesh.n_vertices(), 6);
    let up = smooth[0].mesh.normals().map(|n| n[0]).unwrap_or_default();
    assert!((up - Vec3::Y).length() < 1e-6, "{up}");
    // Same group: the same.
    let same = roof("s 1\nf 1 3 4 2\nf 2 6 5 1\n");
    assert_eq!(same[0].mesh.normals(), smooth[0].mesh.normals());
    // Different groups, or `s off`: the ridge vertices split and each face
    // keeps its own normal; the triangles stay in file order.
    for statements in ["s 1\nf 1 3 4 2\ns 2\nf 2 6 5 1\n", "s off\nf 1 3 4 2\nf 2 6 5 1\n"] {
        let parts = roof(statements);
        let m = &parts[0].mesh;
        assert_eq!((m.n_vertices(), m.n_triangles()), (8, 4), "{statements}");
        let n = m.normals().unwrap_or_default();
        let front = Vec3::new(0.0, 1.0, 1.0).normalize();
        assert!((n[0] - front).length() < 1e-6, "{statements}: {}", n[0]);
        assert!((n[4] - Vec3::new(0.0, 1.0, -1.0).normalize()).length() < 1e-6);
    }
}

#[test]
fn groups_and_materials_split_parts_and_missing_ones_are_magenta() {
    let obj: &'static [u8] = b"mtllib none.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\ng a\nusemtl red\nf 1 2 3\ng b\nf 1 2 3\nusemtl blue\nf 3 2 1\nf 1 2\n";
    let (parts, report) = load_obj(obj);
    let names: Vec<(&str, Option<&str>)> = parts
        .iter()
        .map(|p| (p.name.as_str(), p.material_name.as_deref()))
        .collect();
    assert_eq!(names, [("a", Some("red")), ("b", Some("red")), ("b", Some("blue"))]);
    assert!(
        parts
            .iter()
            .all(|p| p.material.as_ref().map(|m| m.kd) == Some(Vec3::new(1.0, 0.0, 1.0)))
    );
    assert_eq!(report.warnings.len(), 2, "{:?}", report.warnings);
    assert!(report.warnings[0].starts_with("t.obj: line 1: cannot load its MTL file (none.mtl: "));
    assert_eq!(
        report.warnings[1],
        "t.obj: 1 faces have fewer than 3 vertices and give no triangles"
    );
    let (_, report) = load_obj(b"v 0 0 0\nusemtl x\nf 1 1 1\n");
    assert!(
        report.warnings[0].contains("names no MTL file"),
        "{:?}",
        report.warnings
    );
}

#[test]
fn pbr_extension_fields_make_a_metallic_roughness_material() {
    // A 1x1 texel of 128 read as linear data (normal and roughness maps)
    // is 128/255, as sRGB colour (map_Kd, map_Ke) about 0.216.
    let png = crate::encode_png(1, 1, &[128, 128, 128]).unwrap_or_default();
    let mtl: &[u8] = b"newmtl shiny\nKd 0.5 0.25 0\nPm 0.75\nPr 0.4\nd 0.9\nmap_Kd t.png\nnorm -bm 2 t.png\nmap_Pr t.png\nmap_Ke t.png\n";
    let (parts, report) = load(&[("q.obj", QUAD_OBJ), ("q.mtl", mtl), ("t.png", &png)], "q.obj").unwrap_or_default();
    let m = parts[0].material.as_ref().expect("material");
    let pbr = m.pbr.as_ref().expect("Pm makes it metallic-roughness");
    assert_eq!(
        (pbr.base_color, pbr.metallic, pbr.roughness),
        (Vec3::new(0.5, 0.25, 0.0), 0.75, 0.4)
    );
    assert!((pbr.transmission - 0.1).abs() < 1e-6 && pbr.metallic_map.is_none());
    let texel = |t: &Option<std::sync::Arc<lucent_shading::Texture>>| t.as_ref().map(|t| t.texel(0, 0).x);
    let linear = 128.0 / 255.0;
    assert_eq!(texel(&pbr.roughness_map), Some(linear));
    assert_eq!(texel(&m.normal_map), Some(linear));
    let srgb = texel(&m.diffuse_map).unwrap_or(0.0);
    assert!((srgb - 0.2158).abs() < 1e-3, "{srgb}");
    assert_eq!(texel(&m.emission_map), Some(srgb));
    assert_eq!(m.emission, Vec3::ONE, "map_Ke alone emits as it is");
    // The Whitted terms come from the metallic-roughness parameters.
    assert_eq!(m.kd, Vec3::new(0.5, 0.25, 0.0) * 0.25 * 0.9);
    assert_eq!(
        report.warnings,
        vec!["q.mtl: material 'shiny': norm option -bm 2 is not supported and is ignored".to_owned()]
    );
    // Without Pm or a metallic/roughness map the material stays the report's.
    let (parts, _) = load(&[("q.obj", QUAD_OBJ), ("q.mtl", QUAD_MTL)], "q.obj").unwrap_or_default();
    assert!(parts[0].material.as_ref().is_some_and(|m| m.pbr.is_none()));
}
