//! Tests of PLY files as real exporters write them (issue 21): MSVC's
//! spellings of non-finite numbers.

use super::*;
use crate::{MemorySource, load_mesh_from};

fn load(bytes: Vec<u8>) -> Result<(Vec<MeshPart>, LoadReport), String> {
    let src = MemorySource::new().with_file("t.ply", bytes.leak());
    load_mesh_from(&src, Path::new("t.ply")).map_err(|e| e.to_string())
}

/// Vertex count, triangle count and warnings of a file that must load.
fn counts(bytes: Vec<u8>) -> (usize, usize, Vec<String>) {
    match load(bytes) {
        Ok((parts, report)) => (
            parts[0].mesh.positions().len(),
            parts[0].mesh.n_triangles(),
            report.warnings,
        ),
        Err(e) => (0, 0, vec![e]),
    }
}

const ASCII_LINES: [&str; 14] = [
    "ply",
    "format ascii 1.0",
    "element vertex 4",
    "property float x",
    "property float y",
    "property float z",
    "element face 2",
    "property list uchar int vertex_indices",
    "end_header",
    "0 0 0",
    "1 0 0",
    "1 1 0",
    "0 1 0",
    "3 0 1 2",
];
const LAST_FACE: &str = "3 0 2 3";

fn ascii(eol: &str, last_face: &str) -> Vec<u8> {
    let mut text = ASCII_LINES.join(eol);
    text.push_str(eol);
    text.push_str(last_face);
    text.push_str(eol);
    text.into_bytes()
}

#[test]
fn msvc_and_other_non_finite_spellings_reject_the_vertex() {
    for word in [
        "1.#IND", "-1.#IND", "1.#QNAN", "-1.#INF", "1.#INF", "1.#INF00", "1.#SNAN", "nan", "NaN", "-inf", "INF",
        "Infinity",
    ] {
        let text = String::from_utf8_lossy(&ascii("\n", LAST_FACE)).replace("1 1 0", &format!("1 {word} 0"));
        let (v, t, warnings) = counts(text.into_bytes());
        assert_eq!((v, t), (4, 2), "{word}: the triangles keep their numbers");
        assert_eq!(
            warnings,
            [
                "t.ply: rejected 1 vertices with NaN or infinite coordinates and the 2 triangles that use them \
              (they keep their numbers but are never drawn)"
            ],
            "{word}"
        );
    }
    for word in ["3.1+e2", "1.2.3", "1.#INFX", "1.#"] {
        let text = String::from_utf8_lossy(&ascii("\n", LAST_FACE)).replace("1 1 0", &format!("1 {word} 0"));
        assert_eq!(
            load(text.into_bytes()).map(|_| ()),
            Err(format!("t.ply:12: '{word}' is not a number"))
        );
    }
}
