//! The real-world models in `../shared/assets` (next to the repository):
//! encodings that must agree, two files of one surface, and the Cornell
//! boxes' materials. Skips with a message when the folder is absent.

use lucent_assets::{MeshPart, load_mesh};
use lucent_geom::{TriMesh, Vec3, triangle_normal};
use std::collections::HashSet;
use std::path::PathBuf;

fn assets() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/assets");
    if dir.join("MANIFEST.tsv").is_file() {
        Some(dir)
    } else {
        eprintln!("skipped: {} is absent", dir.display());
        None
    }
}

fn load(dir: &std::path::Path, rel: &str) -> Vec<MeshPart> {
    match load_mesh(&dir.join(rel)) {
        Ok((parts, _)) => parts,
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn vertex_colour_encodings_load_to_identical_buffers() {
    let Some(dir) = assets() else { return };
    let [ascii, le, be] = [
        "vertex-colors-3-encodings/test_pos_color_ascii.ply",
        "vertex-colors-3-encodings/test_pos_color.ply",
        "vertex-colors-3-encodings/test_pos_color_big_endian.ply",
    ]
    .map(|f| load(&dir, f).remove(0).mesh);
    assert_eq!(ascii.n_triangles(), 224);
    assert!(ascii.colors().is_some() && ascii.normals().is_none() && ascii.uvs().is_none());
    // The binary files hold the same floats bit for bit.
    assert!(le == be, "little- and big-endian differ");
    // The ASCII file prints 6 significant digits, so its positions agree to
    // that precision; indices and 8-bit colours are exact.
    assert_eq!(ascii.indices(), le.indices());
    assert_eq!(ascii.colors(), le.colors());
    let worst = ascii
        .positions()
        .iter()
        .zip(le.positions())
        .map(|(a, b)| (*a - *b).abs().max_element())
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-6, "positions differ by up to {worst}");
}

fn area(m: &TriMesh) -> f32 {
    (0..m.n_triangles())
        .map(|t| 0.5 * triangle_normal(m.triangle(t)).length())
        .sum()
}

/// Undirected edges, as pairs of position bit patterns.
fn edges(m: &TriMesh) -> HashSet<[[u32; 3]; 2]> {
    let key = |p: Vec3| p.to_array().map(f32::to_bits);
    let mut out = HashSet::new();
    for t in m.indices() {
        for k in 0..3 {
            let (a, b) = (
                key(m.positions()[t[k] as usize]),
                key(m.positions()[t[(k + 1) % 3] as usize]),
            );
            out.insert(if a < b { [a, b] } else { [b, a] });
        }
    }
    out
}

#[test]
fn spot_as_quads_and_as_triangles_is_one_surface() {
    let Some(dir) = assets() else { return };
    let quads = load(&dir, "spot-quads/spot_quadrangulated.obj").remove(0).mesh;
    let tris = load(&dir, "spot-cow-textured/cow.obj").remove(0).mesh;
    assert_eq!((quads.n_triangles(), tris.n_triangles()), (5856, 5856));
    assert_eq!(quads.bounds(), tris.bounds());
    // Every quad edge (fan diagonals aside) is an edge of the triangle file,
    // and the areas agree to within what a different diagonal can change.
    let quad_edges = edges(&quads);
    let tri_edges = edges(&tris);
    let shared = quad_edges.intersection(&tri_edges).count();
    assert!(
        shared as f32 >= 0.99 * (quad_edges.len() - 2928) as f32,
        "{shared} of {}",
        quad_edges.len()
    );
    let (a, b) = (area(&quads), area(&tris));
    assert!((a - b).abs() < 1e-3 * a, "{a} vs {b}");
    assert!(quads.uvs().is_some() && tris.uvs().is_some());
}

#[test]
fn cornell_boxes_load_with_their_materials() {
    let Some(dir) = assets() else { return };
    let mcguire = load(&dir, "cornell-box-mcguire/CornellBox-Original.obj");
    let light = mcguire.iter().find(|p| p.material_name.as_deref() == Some("light"));
    let light = light.and_then(|p| p.material.clone()).unwrap_or_default();
    assert_eq!(light.emission, Vec3::new(17.0, 12.0, 4.0));
    assert_eq!(light.kd, Vec3::splat(0.78));
    let left = mcguire.iter().find(|p| p.material_name.as_deref() == Some("leftWall"));
    assert_eq!(
        left.and_then(|p| p.material.as_ref()).map(|m| m.kd),
        Some(Vec3::new(0.63, 0.065, 0.05))
    );
    assert_eq!(mcguire.iter().map(|p| p.mesh.n_triangles()).sum::<usize>(), 36);
    assert!(mcguire.iter().all(|p| p.material.is_some()));
    let tiny = load(&dir, "cornell-box-tinyobjloader/cornell_box.obj");
    assert_eq!(tiny.iter().map(|p| p.mesh.n_triangles()).sum::<usize>(), 36);
    let light = tiny.iter().find(|p| p.material_name.as_deref() == Some("light"));
    let light = light.and_then(|p| p.material.clone()).unwrap_or_default();
    // This file's light has no Ke; its MTL writes the glow as Ka 20.
    assert_eq!((light.ka, light.emission), (Vec3::splat(20.0), Vec3::ZERO));
    let red = tiny.iter().find(|p| p.material_name.as_deref() == Some("red"));
    assert_eq!(red.and_then(|p| p.material.as_ref()).map(|m| m.kd), Some(Vec3::X));
}
