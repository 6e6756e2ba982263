//! Tests of glTF loading from memory: hierarchy and instancing, data URIs,
//! materials and lights, and bad input located by JSON pointer.

use super::*;
use crate::MemorySource;
use lucent_scene::components::{MaterialRef, Mesh, MeshRef};

/// Base64 (standard alphabet, padded) of `bytes`, for building test files.
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = c
            .iter()
            .enumerate()
            .fold(0u32, |acc, (i, &b)| acc | u32::from(b) << (16 - 8 * i));
        for k in 0..=c.len() {
            out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
        }
        for _ in c.len()..3 {
            out.push('=');
        }
    }
    out
}

/// A triangle: three f32 positions (36 bytes), three u16 indices (6 bytes,
/// padded to 8).
fn triangle_bytes() -> Vec<u8> {
    let mut b = Vec::new();
    for v in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for x in v {
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

/// A glTF document around the triangle; `patch` edits the JSON text.
fn document(uri: &str, patch: impl Fn(String) -> String) -> String {
    let json = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0, 1]}}],
  "nodes": [
    {{"mesh": 0, "translation": [2, 0, 0], "children": [2]}},
    {{"mesh": 0, "name": "second"}},
    {{"camera": 0, "translation": [0, 0, 5]}}
  ],
  "cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "znear": 0.1}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [1, 0.5, 0.25, 1], "metallicFactor": 0.2, "roughnessFactor": 0.6}},
                  "emissiveFactor": [1, 1, 0], "doubleSided": true}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}}
  ],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 6}}
  ],
  "buffers": [{{"byteLength": 44, "uri": "{uri}"}}]
}}"#
    );
    patch(json)
}

fn data_uri() -> String {
    format!("data:application/octet-stream;base64,{}", base64(&triangle_bytes()))
}

fn load_text(text: String) -> Result<(Scene, LoadReport), String> {
    let src = MemorySource::new()
        .with_file("m/t.gltf", text.into_bytes())
        .with_file("m/t.bin", triangle_bytes());
    crate::load_scene_from(&src, Path::new("m/t.gltf")).map_err(|e| e.to_string())
}

#[test]
fn nodes_share_meshes_and_keep_their_hierarchy() {
    for uri in [data_uri(), "t.bin".to_owned()] {
        let (scene, report) = load_text(document(&uri, |s| s)).unwrap_or_else(|e| panic!("{e}"));
        assert!(report.warnings.is_empty(), "{:?}", report.warnings);
        assert_eq!(scene.world.query::<&Mesh>().iter().count(), 1, "one mesh, stored once");
        let instances: Vec<Entity> = scene
            .world
            .query::<(Entity, &MeshRef)>()
            .iter()
            .map(|(e, _)| e)
            .collect();
        assert_eq!(instances.len(), 2);
        let mut xs: Vec<f32> = instances
            .iter()
            .map(|&e| world_from_local(&scene.world, e).translation.x)
            .collect();
        xs.sort_by(f32::total_cmp);
        assert_eq!(xs, vec![0.0, 2.0]);
        // The camera is the child of the first node: at (2, 0, 5), looking
        // down -z, so the rig orbits a point straight ahead of it.
        let (camera, rig) = scene.camera().expect("the file's camera");
        assert!((camera.fov_y_deg - 0.8f32.to_degrees()).abs() < 1e-4);
        assert!(rig.position().abs_diff_eq(Vec3::new(2.0, 0.0, 5.0), 1e-4), "{rig:?}");
        assert!(rig.center.z < 5.0 && (rig.center.x - 2.0).abs() < 1e-4);
        // Materials: the metallic-roughness parameters and emission.
        let mut q = scene.world.query::<&MaterialRef>();
        let m_entity = q.iter().next().map(|m| m.0).expect("a material");
        drop(q);
        let m = scene.world.get::<&Material>(m_entity).expect("material component");
        let pbr = m.pbr.as_ref().expect("metallic-roughness");
        assert_eq!(
            (pbr.base_color, pbr.metallic, pbr.roughness),
            (Vec3::new(1.0, 0.5, 0.25), 0.2, 0.6)
        );
        assert_eq!(
            (m.emission, m.double_sided, m.ior),
            (Vec3::new(1.0, 1.0, 0.0), true, 1.5)
        );
        // No lights in the file: the default environment map, no key light.
        let map = scene.environment.map.as_ref().expect("the default environment");
        assert_eq!((map.width(), map.height()), (1024, 512));
        assert_eq!(scene.settings.tonemap, lucent_scene::Tonemap::Filmic);
        assert_eq!(scene.world.query::<&Light>().iter().count(), 0);
    }
}

#[test]
fn lights_map_photometric_units_and_extensions_are_checked() {
    let with_lights = |s: String| {
        s.replace(
            r#""nodes": [0, 1]}],"#,
            r#""nodes": [0, 1, 3]}],
  "extensionsUsed": ["KHR_lights_punctual", "EXT_fancy"],
  "extensions": {"KHR_lights_punctual": {"lights": [
     {"type": "spot", "intensity": 683, "color": [1, 0.5, 0], "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.5}}]}},"#,
        )
        .replace(
            r#"{"camera": 0, "translation": [0, 0, 5]}"#,
            r#"{"camera": 0, "translation": [0, 0, 5]},
    {"translation": [0, 3, 0], "rotation": [-0.7071068, 0, 0, 0.7071068], "extensions": {"KHR_lights_punctual": {"light": 0}}}"#,
        )
    };
    let (scene, report) = load_text(document(&data_uri(), with_lights)).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        report.warnings,
        vec!["m/t.gltf: /extensionsUsed: extension EXT_fancy is not supported and is ignored".to_owned()]
    );
    let lights: Vec<Light> = scene.world.query::<&Light>().iter().copied().collect();
    match lights.as_slice() {
        [
            Light::Spot {
                position,
                direction,
                intensity,
                inner_cone,
                outer_cone,
            },
        ] => {
            assert!(position.abs_diff_eq(Vec3::new(0.0, 3.0, 0.0), 1e-5));
            // Rotated -90 degrees about x, -z points down.
            assert!(direction.abs_diff_eq(-Vec3::Y, 1e-5), "{direction}");
            assert!(intensity.abs_diff_eq(Vec3::new(1.0, 0.5, 0.0), 1e-6));
            assert_eq!((*inner_cone, *outer_cone), (0.1, 0.5));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(scene.environment.background, Vec3::ZERO, "the file lights itself");
    let required = |s: String| {
        s.replace(
            r#""scene": 0,"#,
            r#""scene": 0, "extensionsRequired": ["EXT_fancy"], "extensionsUsed": ["EXT_fancy"],"#,
        )
    };
    let err = load_text(document(&data_uri(), required)).map(|_| ());
    assert_eq!(
        err,
        Err("m/t.gltf: /extensionsRequired/0: extension EXT_fancy is required but not supported".to_owned())
    );
}

#[test]
fn bad_data_is_an_error_naming_the_json_pointer() {
    type Patch = Box<dyn Fn(String) -> String>;
    let cases: [(&str, Patch); 8] = [
        (
            "/meshes/0/primitives/0/attributes/POSITION: accessor 0 reads past the end of buffer view 0",
            Box::new(|s| s.replace(r#""count": 3, "type": "VEC3""#, r#""count": 4, "type": "VEC3""#)),
        ),
        ("/meshes/0/primitives/0/indices: index 7 at position 1", Box::new(|s| s)),
        (
            "/buffers/0/uri: broken base64 in the data URI at character",
            Box::new(|s| s.replace("base64,AAAA", "base64,A*AA")),
        ),
        (
            "/buffers/0/uri: cannot read 'missing.bin'",
            Box::new(|s| s.replace("t.bin", "missing.bin")),
        ),
        (
            "/buffers/0: byteLength is 4400 but the data has only 44 bytes",
            Box::new(|s| s.replace(r#""byteLength": 44"#, r#""byteLength": 4400"#)),
        ),
        (
            "accessor 1 is misaligned: byte offset 1",
            Box::new(|s| {
                s.replace(
                    r#""componentType": 5123, "count": 3"#,
                    r#""componentType": 5123, "byteOffset": 1, "count": 2"#,
                )
            }),
        ),
        (
            "/meshes/0/primitives/0/attributes/POSITION",
            Box::new(|s| s.replace(r#""POSITION": 0"#, r#""POSITION": 9"#)),
        ),
        (
            "not glTF JSON: expected ident at line 1 column 3",
            Box::new(|_| "[not json".to_owned()),
        ),
    ];
    for (i, (expected, patch)) in cases.into_iter().enumerate() {
        let uri = if i == 3 || i == 4 {
            "t.bin".to_owned()
        } else {
            data_uri()
        };
        let mut text = document(&uri, patch);
        if i == 1 {
            // Index 7 in a 3-vertex mesh.
            let mut bytes = triangle_bytes();
            bytes[38] = 7;
            text = text.replace(
                &data_uri(),
                &format!("data:application/octet-stream;base64,{}", base64(&bytes)),
            );
        }
        let err = load_text(text).map(|_| ()).err().unwrap_or_default();
        assert!(
            err.starts_with("m/t.gltf: ") && err.contains(expected),
            "case {i}: {err}"
        );
    }
}

#[test]
fn shared_gltf_files_load_with_their_triangle_counts() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/assets");
    // The two boxes are Draco-compressed (KHR_draco_mesh_compression).
    for (file, textured) in [("gltf-boxes/Box.glb", false), ("gltf-boxes/BoxTextured.glb", true)] {
        let path = root.join(file);
        if !path.exists() {
            eprintln!("skipped: {} is absent", path.display());
            continue;
        }
        let (scene, report) = crate::load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        assert!(report.warnings.is_empty(), "{file}: {:?}", report.warnings);
        let mut q = scene.world.query::<&Mesh>();
        let meshes: Vec<_> = q.iter().map(|m| m.0.clone()).collect();
        let [mesh] = meshes.as_slice() else {
            panic!("{file}: {} meshes", meshes.len())
        };
        assert_eq!((mesh.n_triangles(), mesh.n_vertices()), (12, 24), "{file}");
        // A unit cube around the origin, with the file's face normals.
        for p in mesh.positions() {
            assert!(p.abs().abs_diff_eq(Vec3::splat(0.5), 1e-6), "{file}: {p}");
        }
        let normals = mesh.normals().expect("the file's normals");
        for n in normals {
            assert!(
                (n.length() - 1.0).abs() < 1e-3 && n.abs().max_element() > 0.999,
                "{file}: {n}"
            );
        }
        assert_eq!(mesh.uvs().is_some(), textured, "{file}");
        let mut q = scene.world.query::<&Material>();
        let m = q.iter().next().expect("the box's material");
        assert_eq!(m.diffuse_map.is_some(), textured, "{file}");
    }
    let file = "gltf-damaged-helmet/DamagedHelmet.gltf";
    let path = root.join(file);
    if !path.exists() {
        eprintln!("skipped: {} is absent", path.display());
        return;
    }
    let (scene, report) = crate::load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
    let n: usize = scene
        .world
        .query::<&MeshRef>()
        .iter()
        .map(|m| scene.world.get::<&Mesh>(m.0).map_or(0, |mesh| mesh.0.n_triangles()))
        .sum();
    assert_eq!(n, 15452, "{file}: {:?}", report.warnings);
    let mut q = scene.world.query::<&Material>();
    let m = q.iter().next().expect("the helmet's material");
    assert!(m.normal_map.is_some() && m.emission_map.is_some() && m.diffuse_map.is_some());
    let mr = m
        .pbr
        .as_ref()
        .and_then(|p| p.metallic_map.as_ref())
        .expect("metallic-roughness map");
    assert_eq!((mr.width(), mr.height()), (2048, 2048));
    drop(q);
    let mut q = scene.world.query::<&Mesh>();
    let mesh = q.iter().next().expect("the helmet's mesh");
    assert!(
        mesh.0.tangents().is_some() && mesh.0.uvs().is_some(),
        "MikkTSpace tangents"
    );
}

/// A GLB container around `json` and `bin`.
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    while !j.len().is_multiple_of(4) {
        j.push(b' ');
    }
    let mut b = bin.to_vec();
    while !b.len().is_multiple_of(4) {
        b.push(0);
    }
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

/// A Draco-compressed triangle whose stream (`bin`, buffer view 0) may be
/// anything; `patch` edits the JSON text.
fn draco_glb(bin: &[u8], patch: impl Fn(String) -> String) -> Vec<u8> {
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
  "extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": ["KHR_draco_mesh_compression"],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 1}}, "indices": 0,
     "extensions": {{"KHR_draco_mesh_compression": {{"bufferView": 0, "attributes": {{"POSITION": 0}}}}}}}}]}}],
  "accessors": [{{"componentType": 5123, "count": 3, "type": "SCALAR"}},
                {{"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}}],
  "bufferViews": [{{"buffer": 0, "byteLength": {}}}],
  "buffers": [{{"byteLength": {}}}]}}"#,
        bin.len(),
        bin.len()
    );
    glb(&patch(json), bin)
}

/// An edit of a test document's JSON text.
type Patch = fn(String) -> String;

fn load_glb(bytes: Vec<u8>) -> Result<(Scene, LoadReport), String> {
    let src = MemorySource::new().with_file("m/d.glb", bytes);
    crate::load_scene_from(&src, Path::new("m/d.glb")).map_err(|e| e.to_string())
}

#[test]
fn bad_draco_data_is_an_error_naming_the_json_pointer() {
    const EXT: &str = "/meshes/0/primitives/0/extensions/KHR_draco_mesh_compression";
    let cases: [(&[u8], Patch, String); 5] = [
        (
            b"not a Draco stream at all",
            |s| s,
            format!("{EXT}: the Draco stream in buffer view 0 does not decode: "),
        ),
        (
            b"DRACO\x02\x02\x01\x01\x00\x00",
            |s| s,
            format!("{EXT}: the Draco stream in buffer view 0 does not decode: "),
        ),
        (
            b"DRACO",
            |s| s.replace(r#""bufferView": 0, "attributes""#, r#""bufferView": 7, "attributes""#),
            format!("{EXT}/bufferView: buffer view 7 does not exist (1 buffer views)"),
        ),
        (
            b"DRACO",
            |s| s.replace(r#""byteLength": 5}],"#, r#""byteLength": 500}],"#),
            format!("{EXT}/bufferView: buffer view 0 (bytes 0 to 500) reads past the end of buffer 0"),
        ),
        (
            b"DRACO",
            |s| {
                s.replace(
                    r#""attributes": {"POSITION": 0}}"#,
                    r#""attributes": {"POSITION": "zero"}}"#,
                )
            },
            format!("{EXT}/attributes/POSITION: not a Draco attribute id"),
        ),
    ];
    for (i, (bin, patch, expected)) in cases.into_iter().enumerate() {
        let err = load_glb(draco_glb(bin, patch)).map(|_| ()).err().unwrap_or_default();
        assert!(err.starts_with(&format!("m/d.glb: {expected}")), "case {i}: {err}");
    }
}

#[test]
fn draco_counts_that_disagree_with_the_accessors_are_errors() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/assets/gltf-boxes/Box.glb");
    let Ok(file) = std::fs::read(&path) else {
        eprintln!("skipped: {} is absent", path.display());
        return;
    };
    // Box.glb's Draco stream: buffer view 0, 118 bytes at the start of BIN.
    let json_len = u32::from_le_bytes([file[12], file[13], file[14], file[15]]) as usize;
    let stream = &file[20 + json_len + 8..20 + json_len + 8 + 118];
    // The document's accessor counts (POSITION's as `N, "type": "T"`) and
    // the Draco attribute its POSITION names.
    let counts = |position: &str, indices: u32, id: u32| {
        let position = format!(r#""count": {position}"#);
        move |s: String| {
            s.replace(r#""count": 3, "type": "VEC3""#, &position)
                .replace(
                    r#""count": 3, "type": "SCALAR""#,
                    &format!(r#""count": {indices}, "type": "SCALAR""#),
                )
                .replace(
                    r#""attributes": {"POSITION": 0}}"#,
                    &format!(r#""attributes": {{"POSITION": {id}}}}}"#),
                )
        }
    };
    let (scene, _) =
        load_glb(draco_glb(stream, counts(r#"24, "type": "VEC3""#, 36, 1))).unwrap_or_else(|e| panic!("{e}"));
    let n: usize = scene.world.query::<&Mesh>().iter().map(|m| m.0.n_triangles()).sum();
    assert_eq!(n, 12);
    let cases = [
        (
            (r#"30, "type": "VEC3""#, 36, 1),
            "/attributes/POSITION: accessor 1 has 30 elements but the Draco stream decodes 24 points",
        ),
        // POSITION declares 3 points: the decode may not make 24.
        (
            (r#"3, "type": "VEC3""#, 36, 1),
            "the Draco stream in buffer view 0 does not decode: Decode limit exceeded",
        ),
        // The accessors bound the decode: 10 triangles declared, 12 in the stream.
        (
            (r#"24, "type": "VEC3""#, 30, 1),
            "the Draco stream in buffer view 0 does not decode: ",
        ),
        (
            (r#"24, "type": "VEC3""#, 36, 5),
            "/attributes/POSITION: the Draco stream has no attribute with id 5",
        ),
        (
            (r#"24, "type": "VEC2""#, 36, 1),
            "/attributes/POSITION: Draco attribute 1 has 3 components but accessor 1 has 2",
        ),
    ];
    for (i, ((position, indices, id), expected)) in cases.into_iter().enumerate() {
        let err = load_glb(draco_glb(stream, counts(position, indices, id)))
            .map(|_| ())
            .err()
            .unwrap_or_default();
        assert!(
            err.starts_with("m/d.glb: /meshes/0/primitives/0/extensions/KHR_draco_mesh_compression")
                && err.contains(expected),
            "case {i}: {err}"
        );
    }
}

#[test]
fn alpha_modes_become_alpha_tests_and_blend_is_a_warning_naming_the_material() {
    let with_mode = |mode: &'static str| {
        move |s: String| {
            s.replace(
                r#""emissiveFactor": [1, 1, 0], "doubleSided": true}"#,
                &format!(r#""emissiveFactor": [1, 1, 0], "doubleSided": true, "name": "leaves", {mode}}}"#),
            )
        }
    };
    let material = |mode: &'static str| {
        let (scene, report) = load_text(document(&data_uri(), with_mode(mode))).unwrap_or_else(|e| panic!("{e}"));
        let mut q = scene.world.query::<&Material>();
        let m = q.iter().next().cloned().expect("a material");
        (m, report.warnings)
    };
    let (m, warnings) = material(r#""alphaMode": "MASK", "alphaCutoff": 0.3"#);
    assert_eq!(m.alpha_mode, lucent_shading::AlphaMode::Mask { cutoff: 0.3 });
    assert!(warnings.is_empty(), "{warnings:?}");
    // The base colour factor's alpha (1) is the alpha: kept at 0.3.
    assert!(m.is_masked() && !m.cut_out(None));
    let (m, _) = material(r#""alphaMode": "MASK""#);
    assert_eq!(
        m.alpha_mode,
        lucent_shading::AlphaMode::Mask { cutoff: 0.5 },
        "the default cutoff"
    );
    let (m, _) = material(r#""alphaMode": "OPAQUE", "alphaCutoff": 0.9"#);
    assert!(!m.is_masked());
    let (m, warnings) = material(r#""alphaMode": "BLEND""#);
    assert_eq!(m.alpha_mode, lucent_shading::AlphaMode::Mask { cutoff: 0.5 });
    assert_eq!(
        warnings,
        vec![
            "m/t.gltf: /materials/0/alphaMode: material ('leaves') is BLEND, approximated by an alpha test at 0.5 (no partial transparency)"
                .to_owned()
        ]
    );
}

#[test]
fn a_glb_header_shorter_than_itself_is_an_error_not_an_overflow() {
    // Found by the glTF fuzz target: length 0 in the GLB header made the
    // gltf crate subtract 12 from it.
    let mut bytes = b"glTF".to_vec();
    bytes.extend_from_slice(&2u32.to_le_bytes());
    bytes.extend_from_slice(&0u32.to_le_bytes());
    bytes.resize(64, 0);
    let err = load_glb(bytes).map(|_| ()).err().unwrap_or_default();
    assert_eq!(
        err,
        "m/d.glb: GLB container: byte 8: length 0 is shorter than the 12-byte header"
    );
    let err = load_glb(b"glTF\x02\0\0\0".to_vec())
        .map(|_| ())
        .err()
        .unwrap_or_default();
    assert!(err.contains("fewer than the 12-byte header"), "{err}");
    // The fuzzer's own inputs.
    for file in ["gltf-glb-length-0.glb", "gltf-glb-length-short.glb"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz").join(file);
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let err = load_glb(bytes).map(|_| ()).err().unwrap_or_default();
        assert!(err.contains("shorter than the 12-byte header"), "{file}: {err}");
    }
}
