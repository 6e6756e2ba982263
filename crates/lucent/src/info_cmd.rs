//! `lucent info FILE`: what a mesh or scene file contains, as one JSON
//! object on stdout (the fields are documented in docs/mesh-files.md).
//!
//! Meshes (`.obj`, `.ply`): vertices, triangles, attributes, bounding box,
//! parts, materials and load warnings. Scenes (`.toml`): entity counts by
//! kind, the features they use, the features the renderer's extract step
//! turns on (`lucent_render::SceneFeatures`), render settings and warnings. Errors leave
//! through `main` as one `error:` line with exit code 1.

use anyhow::{Result, bail};
use clap::Args;
use lucent_assets::{LoadReport, MeshPart, load_mesh, load_scene};
use lucent_geom::Named;
use lucent_geom::{Aabb, TriMesh, Vec3};
use lucent_scene::Scene;
use lucent_scene::components::{Light, Material, MaterialRef, Mesh, MeshRef, Parent};
use serde_json::{Value, json};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Arguments of `lucent info`.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// A mesh (.obj, .ply), scene (.toml) or glTF (.gltf, .glb) file.
    file: PathBuf,
}

pub fn run(args: InfoArgs) -> Result<()> {
    let ext = args
        .file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let info = match ext.as_deref() {
        Some("obj" | "ply") => mesh_info(&args.file)?,
        Some("toml" | "gltf" | "glb") => scene_info(&args.file)?,
        _ => bail!(
            "{}: unknown file type (expected .obj, .ply, .toml, .gltf or .glb)",
            args.file.display()
        ),
    };
    println!("{info}");
    Ok(())
}

/// The names whose flag is set.
fn set<'a>(flags: impl IntoIterator<Item = (bool, &'a str)>) -> impl Iterator<Item = &'a str> {
    flags.into_iter().filter_map(|(on, name)| on.then_some(name))
}

fn attributes(m: &TriMesh) -> Vec<&'static str> {
    set([
        (true, "positions"),
        (m.normals().is_some(), "normals"),
        (m.uvs().is_some(), "uvs"),
        (m.colors().is_some(), "colors"),
        (m.tangents().is_some(), "tangents"),
    ])
    .collect()
}

/// An `f32` as the shortest decimal that reads back to it (0.725, not
/// 0.7250000238418579); non-finite values become JSON null.
fn num(x: f32) -> Value {
    format!("{x}").parse::<f64>().map_or(Value::Null, Value::from)
}

fn vec3(v: Vec3) -> Value {
    Value::Array(v.to_array().into_iter().map(num).collect())
}

fn bbox(b: Aabb) -> Value {
    if b.is_empty() {
        return Value::Null;
    }
    json!({ "min": vec3(b.min), "max": vec3(b.max) })
}

fn material_json(name: &str, m: &Material) -> Value {
    json!({
        "name": name,
        "ka": vec3(m.ka),
        "kd": vec3(m.kd),
        "ks": vec3(m.ks),
        "shininess": num(m.shininess),
        "kr": vec3(m.kr),
        "kt": vec3(m.kt),
        "ior": num(m.ior),
        "roughness": num(m.roughness),
        "emission": vec3(m.emission),
        "diffuse_map": m.diffuse_map.as_ref().map(|t| json!({ "width": t.width(), "height": t.height() })),
    })
}

fn mesh_info(path: &Path) -> Result<Value> {
    let (parts, report) = load_mesh(path)?;
    let vertices: usize = parts.iter().map(|p| p.mesh.n_vertices()).sum();
    let triangles: usize = parts.iter().map(|p| p.mesh.n_triangles()).sum();
    let bounds = parts.iter().fold(Aabb::EMPTY, |b, p| b.union(p.mesh.bounds()));
    // Attributes every part has.
    let common: BTreeSet<&str> = parts
        .iter()
        .map(|p| attributes(&p.mesh).into_iter().collect::<BTreeSet<_>>())
        .reduce(|a, b| &a & &b)
        .unwrap_or_default();
    let mut materials: Vec<Value> = Vec::new();
    let mut seen: BTreeSet<&str> = BTreeSet::new();
    for p in &parts {
        if let (Some(name), Some(m)) = (&p.material_name, &p.material)
            && seen.insert(name)
        {
            materials.push(material_json(name, m));
        }
    }
    let part_json: Vec<Value> = parts.iter().map(part_info).collect();
    let attributes: Vec<&str> = ["positions", "normals", "uvs", "colors"]
        .into_iter()
        .filter(|a| common.contains(a))
        .collect();
    Ok(json!({
        "kind": "mesh",
        "file": path.display().to_string(),
        "vertices": vertices,
        "triangles": triangles,
        "attributes": attributes,
        "bbox": bbox(bounds),
        "parts": part_json,
        "materials": materials,
        "warnings": report.warnings,
    }))
}

fn part_info(p: &MeshPart) -> Value {
    json!({
        "name": p.name,
        "vertices": p.mesh.n_vertices(),
        "triangles": p.mesh.n_triangles(),
        "attributes": attributes(&p.mesh),
        "normals_computed": p.normals_computed,
        "material": p.material_name,
    })
}

fn scene_info(path: &Path) -> Result<Value> {
    let (scene, report) = load_scene(path)?;
    Ok(scene_json(path, &scene, &report))
}

fn scene_json(path: &Path, scene: &Scene, report: &LoadReport) -> Value {
    let w = &scene.world;
    let c = scene.counts();
    let mut n_point = 0;
    let mut n_directional = 0;
    let mut n_spot = 0;
    for light in w.query::<&Light>().iter() {
        match light {
            Light::Point { .. } => n_point += 1,
            Light::Directional { .. } => n_directional += 1,
            Light::Spot { .. } => n_spot += 1,
        }
    }
    let mut features: BTreeSet<&str> = BTreeSet::new();
    for (mesh_ref, material_ref) in w.query::<(&MeshRef, Option<&MaterialRef>)>().iter() {
        if let Ok(mesh) = w.get::<&Mesh>(mesh_ref.0) {
            features.extend(set([
                (mesh.0.colors().is_some(), "vertex_colors"),
                (mesh.0.uvs().is_some(), "uvs"),
            ]));
        }
        if let Some(m) = material_ref.and_then(|m| w.get::<&Material>(m.0).ok()) {
            features.extend(set([
                (m.diffuse_map.is_some(), "textures"),
                (m.is_reflective(), "reflection"),
                (m.is_transmissive(), "refraction"),
                (m.emission.max_element() > 0.0, "emission"),
                (m.pbr.is_some(), "metallic_roughness"),
                (m.normal_map.is_some(), "normal_maps"),
                (m.is_masked(), "alpha_mask"),
            ]));
        }
    }
    features.extend(set([
        (w.query::<&Parent>().iter().count() > 0, "hierarchy"),
        (n_point > 0, "point_lights"),
        (n_directional > 0, "directional_lights"),
        (n_spot > 0, "spot_lights"),
    ]));
    // What the renderer specialises on, from the extract's own analysis
    // (null when the scene cannot be extracted, e.g. without a camera).
    let render_features = lucent_render::scene_features(scene, &lucent_render::ExtractOptions::default())
        .ok()
        .map(|f| f.names());
    let s = &scene.settings;
    json!({
        "kind": "scene",
        "file": path.display().to_string(),
        "entities": {
            "meshes": c.meshes,
            "instances": c.instances,
            "materials": c.materials,
            "point_lights": n_point,
            "directional_lights": n_directional,
            "spot_lights": n_spot,
            "cameras": c.cameras,
        },
        "instanced_triangles": c.instanced_triangles,
        "features": features,
        "render_features": render_features,
        "settings": {
            "width": s.width,
            "height": s.height,
            "spp": s.spp,
            "max_depth": s.max_depth,
            "shading": s.shading.name(),
        },
        "warnings": report.warnings,
    })
}
