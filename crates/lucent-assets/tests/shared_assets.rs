//! The real-world models in `../shared/assets` (next to the repository):
//! encodings that must agree, two files of one surface, the Cornell boxes'
//! materials, and every PLY and an OBJ rewritten as other exporters write
//! them. Skips with a message when the folder is absent.

use lucent_assets::{LoadReport, MemorySource, MeshPart, load_mesh, load_mesh_from};
use lucent_geom::{TriMesh, Vec3, triangle_normal};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

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

fn load_bytes(name: &str, bytes: Vec<u8>) -> Result<(Vec<MeshPart>, LoadReport), String> {
    let source = MemorySource::new().with_file(name, bytes);
    load_mesh_from(&source, Path::new(name)).map_err(|e| e.to_string())
}

/// Every PLY of the folder as the manifest lists it.
fn ply_files(dir: &Path) -> Vec<String> {
    let manifest = std::fs::read_to_string(dir.join("MANIFEST.tsv")).unwrap_or_default();
    manifest
        .lines()
        .filter_map(|l| l.split('\t').next())
        .filter(|p| p.ends_with(".ply"))
        .map(str::to_owned)
        .collect()
}

/// `file` as a Rhinoceros-6-style exporter with a chatty banner would write
/// it: header lines ended by a lone CR, padded, with runs of spaces and a
/// keyword-less banner line after `ply`; an ASCII body's lines end in CR
/// too, a binary body is kept byte for byte.
fn as_quirky_exporter_writes(file: &[u8]) -> Vec<u8> {
    let marker = b"end_header\n";
    let end = file
        .windows(marker.len())
        .position(|w| w == marker)
        .map(|at| at + marker.len());
    let Some(end) = end else { return Vec::new() };
    let (header, body) = file.split_at(end);
    let mut out = Vec::new();
    for (i, line) in String::from_utf8_lossy(header).lines().enumerate() {
        if i == 1 {
            out.extend(b"Created by SomeTool 1.0 - www.example.com\r");
        }
        out.extend(format!("  {} \r", line.split(' ').collect::<Vec<_>>().join("   ")).into_bytes());
    }
    if header.windows(12).any(|w| w == b"format ascii") {
        out.extend(body.iter().map(|&b| if b == b'\n' { b'\r' } else { b }));
    } else {
        out.extend(body);
    }
    out
}

#[test]
fn every_ply_loads_the_same_when_written_with_cr_line_ends_padding_and_a_banner() {
    let Some(dir) = assets() else { return };
    let files = ply_files(&dir);
    assert!(files.len() >= 10, "{files:?}");
    for rel in files {
        let bytes = std::fs::read(dir.join(&rel)).unwrap_or_default();
        let (parts, report) = load_bytes("m.ply", bytes.clone()).unwrap_or_else(|e| panic!("{rel}: {e}"));
        let quirky = as_quirky_exporter_writes(&bytes);
        // No LF left in the header, nor in an ASCII body.
        let ascii = bytes.starts_with(b"ply\nformat ascii");
        let header_end = quirky.windows(11).position(|w| w == b"end_header ").unwrap_or(0);
        let lf_in = |b: &[u8]| b.contains(&b'\n');
        assert!(header_end > 0 && !lf_in(&quirky[..header_end]), "{rel}");
        assert!(!ascii || !lf_in(&quirky), "{rel}");
        let (quirky_parts, quirky_report) = load_bytes("m.ply", quirky).unwrap_or_else(|e| panic!("{rel}: {e}"));
        assert!(parts[0].mesh == quirky_parts[0].mesh, "{rel}: the meshes differ");
        let mut expected =
            vec!["m.ply: line 2: a header line without a PLY keyword, read as a comment: 'Created by SomeTool 1.0 - www.example.com'".to_owned()];
        expected.extend(report.warnings);
        assert_eq!(quirky_report.warnings, expected, "{rel}");
    }
}

#[test]
fn a_real_obj_with_msvc_non_finite_numbers_keeps_its_other_vertices_and_triangles() {
    let Some(dir) = assets() else { return };
    let text = std::fs::read_to_string(dir.join("utah-teapot/teapot.obj")).unwrap_or_default();
    let (parts, report) = load_bytes("t.obj", text.clone().into_bytes()).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        report.warnings.iter().all(|w| !w.contains("NaN")),
        "{:?}",
        report.warnings
    );
    // The first vertex line's x and the tenth's z, as MSVC prints NaN and -inf.
    let mut seen = 0;
    let edited: String = text
        .lines()
        .map(|l| {
            let mut words: Vec<&str> = l.split(' ').collect();
            if words[0] == "v" {
                seen += 1;
                match seen {
                    1 => words[1] = "1.#IND",
                    10 => words[3] = "-1.#INF00",
                    _ => {}
                }
            }
            words.join(" ") + "\n"
        })
        .collect();
    let (edited_parts, edited_report) = load_bytes("t.obj", edited.into_bytes()).unwrap_or_else(|e| panic!("{e}"));
    let rejected: Vec<&String> = edited_report.warnings.iter().filter(|w| w.contains("NaN")).collect();
    assert_eq!(rejected.len(), 1, "{:?}", edited_report.warnings);
    assert!(rejected[0].starts_with("t.obj: rejected "), "{rejected:?}");
    let (m, e) = (&parts[0].mesh, &edited_parts[0].mesh);
    assert_eq!(
        (m.positions().len(), m.n_triangles()),
        (e.positions().len(), e.n_triangles())
    );
    assert_eq!(m.indices(), e.indices(), "triangle numbering is kept");
    let nan = e.positions().iter().filter(|p| p.is_nan()).count();
    assert!(nan >= 2, "{nan} vertices rejected");
    for (a, b) in m.positions().iter().zip(e.positions()) {
        assert!(b.is_nan() || a == b, "{a} vs {b}");
    }
}
