//! `lucent info` end to end: every model of `../shared/assets/MANIFEST.tsv`
//! reports the manifest's triangle count, scenes report their entities,
//! and failures are one `error:` line with exit code 1.

mod common;

use common::{lucent, repo_root};
use serde_json::Value;
use std::path::Path;

/// Runs `lucent info FILE`: the parsed JSON, or the exit code and stderr.
fn info(file: &Path) -> Result<Value, (Option<i32>, String)> {
    let out = lucent()
        .arg("info")
        .arg(file)
        .output()
        .map_err(|e| (None, e.to_string()))?;
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    if !out.status.success() {
        return Err((out.status.code(), stderr));
    }
    serde_json::from_slice(&out.stdout).map_err(|e| (Some(0), format!("not JSON: {e}")))
}

/// The manifest's rows with a `KEY=N` count: each row's file and that
/// count; `None` (after saying so) where the shared assets are absent.
fn manifest_counts(key: &str) -> Option<(std::path::PathBuf, Vec<(String, u64)>)> {
    let dir = repo_root().join("../shared/assets");
    let Ok(manifest) = std::fs::read_to_string(dir.join("MANIFEST.tsv")) else {
        eprintln!("skipped: {} is absent", dir.display());
        return None;
    };
    let prefix = format!("{key}=");
    let rows = manifest
        .lines()
        .skip(1)
        .filter_map(|row| {
            let cols: Vec<&str> = row.split('\t').collect();
            let count = cols.get(3)?.split_whitespace().find_map(|c| c.strip_prefix(&prefix))?;
            Some(((*cols.first()?).to_owned(), count.parse().ok()?))
        })
        .collect();
    Some((dir, rows))
}

#[test]
fn every_manifest_model_reports_its_triangle_count() {
    let Some((dir, rows)) = manifest_counts("tris") else {
        return;
    };
    let mut checked = 0;
    for (file, tris) in rows {
        let json = info(&dir.join(&file)).unwrap_or_else(|e| panic!("{file}: {e:?}"));
        assert_eq!(json["kind"], "mesh", "{file}");
        assert_eq!(json["triangles"].as_u64(), Some(tris), "{file}");
        let vertices = json["vertices"].as_u64().unwrap_or(0);
        assert!(vertices >= 3, "{file}: {vertices} vertices");
        let attributes = json["attributes"].as_array().cloned().unwrap_or_default();
        assert_eq!(attributes.first().and_then(Value::as_str), Some("positions"), "{file}");
        let min = &json["bbox"]["min"];
        let max = &json["bbox"]["max"];
        for k in 0..3 {
            assert!(min[k].as_f64() <= max[k].as_f64(), "{file}: bbox {min} {max}");
        }
        checked += 1;
    }
    assert_eq!(checked, 20, "the manifest lists 20 models");
}

#[test]
fn gltf_files_report_their_manifest_triangle_counts() {
    let Some((dir, rows)) = manifest_counts("gltf_tris") else {
        return;
    };
    let mut checked = 0;
    for (file, tris) in rows {
        // The boxes are Draco-compressed (KHR_draco_mesh_compression).
        let json = info(&dir.join(&file)).unwrap_or_else(|(code, stderr)| panic!("{file}: {code:?} {stderr}"));
        assert_eq!(json["kind"], "scene", "{file}");
        assert_eq!(json["instanced_triangles"].as_u64(), Some(tris), "{file}");
        assert_eq!(json["warnings"].as_array().map(Vec::len), Some(0), "{file}: {json}");
        checked += 1;
    }
    assert_eq!(checked, 3, "the manifest lists 3 glTF files");
}

#[test]
fn mesh_info_lists_attributes_materials_and_warnings() {
    let dir = repo_root().join("../shared/assets");
    if !dir.is_dir() {
        eprintln!("skipped: {} is absent", dir.display());
        return;
    }
    let cow = info(&dir.join("spot-cow-textured/cow.obj")).unwrap_or_default();
    assert_eq!(cow["attributes"], serde_json::json!(["positions", "normals", "uvs"]));
    assert_eq!(cow["materials"][0]["name"], "material_1");
    assert_eq!(cow["materials"][0]["diffuse_map"]["width"], 1024);
    let colours = info(&dir.join("cycloidal-vertex-colors/cycloidal.ply")).unwrap_or_default();
    assert_eq!(colours["attributes"], serde_json::json!(["positions", "colors"]));
    let cornell = info(&dir.join("cornell-box-mcguire/CornellBox-Original.obj")).unwrap_or_default();
    let light = cornell["materials"]
        .as_array()
        .and_then(|m| m.iter().find(|m| m["name"] == "light").cloned())
        .unwrap_or_default();
    assert_eq!(light["emission"], serde_json::json!([17.0, 12.0, 4.0]));
    // Its two box bottoms reuse earlier vertices, so 8 go unused.
    let warnings = cornell["warnings"].as_array().cloned().unwrap_or_default();
    assert!(
        warnings.iter().any(|w| w
            .as_str()
            .is_some_and(|w| w.ends_with("8 vertices are not used by any face"))),
        "{warnings:?}"
    );
}

#[test]
fn scene_info_counts_entities_and_features() {
    let json = info(Path::new("res/scenes/seed.toml")).unwrap_or_default();
    assert_eq!(json["kind"], "scene");
    assert_eq!(json["entities"]["directional_lights"], 1);
    assert_eq!(json["entities"]["cameras"], 1);
    assert!(json["entities"]["instances"].as_u64() >= Some(4), "{json}");
    let features = json["features"].as_array().cloned().unwrap_or_default();
    for f in ["textures", "refraction", "directional_lights", "uvs"] {
        assert!(features.iter().any(|x| x == f), "{f} missing from {features:?}");
    }
    // What the renderer turns on: the extract's SceneFeatures, in order.
    assert_eq!(
        json["render_features"],
        serde_json::json!([
            "transmissive",
            "reflective",
            "textured",
            "directional_lights",
            "smooth_normals"
        ])
    );
    let cornell = info(Path::new("res/scenes/cornell-mitsuba.toml")).unwrap_or_default();
    assert_eq!(
        cornell["render_features"],
        serde_json::json!(["transmissive", "reflective", "emissive", "smooth_normals"])
    );
    // Issue 14's heavy scene: at least 2 M triangles through instancing of
    // four stored meshes.
    let heavy = info(Path::new("res/scenes/heavy.toml")).unwrap_or_default();
    assert!(heavy["instanced_triangles"].as_u64() >= Some(2_000_000), "{heavy}");
    assert_eq!(heavy["entities"]["meshes"], 4, "{heavy}");
}

#[test]
fn failures_are_one_error_line_with_exit_code_1() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("info");
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 zero\n").unwrap();
    for (file, expected) in [
        (
            bad.clone(),
            format!("error: {}:2: 'zero' is not a number", bad.display()),
        ),
        (
            dir.join("none.ply"),
            format!("error: {}: ", dir.join("none.ply").display()),
        ),
        (dir.join("x.stl"), "unknown file type".to_owned()),
    ] {
        let (code, stderr) = info(&file).map(|_| ()).unwrap_err();
        assert_eq!(code, Some(1), "{stderr}");
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(stderr.contains(&expected), "{stderr} lacks {expected}");
    }
}
