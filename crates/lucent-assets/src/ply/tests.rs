//! Tests of the PLY loader: encodings, attributes, located errors.

use super::*;
use crate::{MemorySource, load_mesh_from};
use lucent_geom::Vec3;

const ASCII: &[u8] = b"ply\nformat ascii 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 255 255 255\n4 0 1 2 3\n";

fn load(bytes: impl Into<std::borrow::Cow<'static, [u8]>>) -> Result<(Vec<MeshPart>, LoadReport), String> {
    let src = MemorySource::new().with_file("t.ply", bytes);
    load_mesh_from(&src, Path::new("t.ply")).map_err(|e| e.to_string())
}

#[test]
fn ascii_quad_with_colours() {
    let (parts, _) = load(ASCII).unwrap_or_default();
    let m = &parts[0].mesh;
    assert_eq!(m.indices(), &[[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.colors().map(|c| c[0]), Some(Vec3::X));
    assert!(m.normals().is_none() && m.uvs().is_none());
}

#[test]
fn binary_big_endian_with_normals_and_extra_element() {
    let mut b = b"ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement extra 1\nproperty short q\n\
element face 1\nproperty list uchar uint vertex_index\nend_header\n"
        .to_vec();
    for p in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        for x in p.iter().chain(&[0., 0., 2.]) {
            b.extend(x.to_be_bytes());
        }
    }
    b.extend(7i16.to_be_bytes());
    b.push(3);
    for i in [0u32, 1, 2] {
        b.extend(i.to_be_bytes());
    }
    let (parts, _) = load(b).unwrap_or_default();
    let m = &parts[0].mesh;
    assert_eq!(m.indices(), &[[0, 1, 2]]);
    assert_eq!(m.normals().map(|n| n[1]), Some(Vec3::Z), "normals are normalised");
}

#[test]
fn errors_name_file_and_line() {
    let bad_index = String::from_utf8_lossy(ASCII)
        .replace("4 0 1 2 3", "3 0 1 9")
        .into_bytes();
    assert_eq!(
        load(bad_index).map(|_| ()),
        Err("t.ply:18: vertex index 9 is out of range (4 vertices)".into())
    );
    let bad_number = String::from_utf8_lossy(ASCII)
        .replace("1 1 0 0 0 255", "1 x 0 0 0 255")
        .into_bytes();
    let err = load(bad_number).map(|_| ()).unwrap_err();
    assert!(err.starts_with("t.ply:16: "), "{err}");
    let truncated = &ASCII[..ASCII.len() - 12];
    let err = load(truncated).map(|_| ()).unwrap_err();
    assert!(err.starts_with("t.ply:"), "{err}");
    // Counts that cannot fit the file fail before anything is read.
    let huge = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nend_header\n";
    assert_eq!(
        load(huge).map(|_| ()),
        Err("t.ply:3: element 'vertex' claims 4000000000 entries, which need at least 16000000000 bytes, but only 0 follow the header".into())
    );
    let twice = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nelement vertex 9\nend_header\n";
    assert_eq!(
        load(twice).map(|_| ()),
        Err("t.ply:5: element 'vertex' is declared twice".into())
    );
    let empty = b"ply\nformat ascii 1.0\nelement vertex 4000000000\nelement face 0\nend_header\n";
    assert_eq!(
        load(empty).map(|_| ()),
        Err("t.ply:3: element 'vertex' has no properties".into())
    );
    let overflow = b"ply\nformat ascii 1.0\nelement vertex 99999999999999999999\nend_header\n";
    assert_eq!(
        load(overflow).map(|_| ()),
        Err("t.ply:3: number 99999999999999999999 in the header is too large".into())
    );
    assert_eq!(
        load(b"ply\nformat ascii 2.0\nend_header\n").map(|_| ()),
        Err("t.ply:2: unsupported PLY format version '2.0' (only 1.0 exists)".into())
    );
    assert_eq!(
        load(b"ply\nformat binary_middle_endian 1.0\nend_header\n").map(|_| ()),
        Err("t.ply:2: unknown PLY format 'binary_middle_endian'".into())
    );
    assert_eq!(
        load(b"not a ply").map(|_| ()),
        Err("t.ply:1: not a PLY file (it does not start with a 'ply' line)".into())
    );
    assert_eq!(
        load(b"ply\nformat ascii 1.0\nelement vertex 1\n").map(|_| ()),
        Err("t.ply:3: the file ends inside the header (no end_header line)".into())
    );
}

/// A binary little-endian triangle: three float vertices, one face of
/// `count` and `indices` (bytes) as the list declaration `list_decl` says.
fn binary_triangle(count: &[u8], indices: &[u8], list_decl: &str) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty {list_decl} vertex_indices\nend_header\n"
    )
    .into_bytes();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        b.extend(v.to_le_bytes());
    }
    b.extend(count);
    b.extend(indices);
    b
}

#[test]
fn binary_errors_give_byte_offsets() {
    let ok = binary_triangle(&[3], &[0u32, 1, 2].map(u32::to_le_bytes).concat(), "list uchar uint");
    let header = ok.len() - 36 - 13;
    assert!(load(ok.clone()).is_ok());
    // Index 7 at the face's third entry.
    let bad = binary_triangle(&[3], &[0u32, 1, 7].map(u32::to_le_bytes).concat(), "list uchar uint");
    assert_eq!(
        load(bad).map(|_| ()),
        Err(format!(
            "t.ply: byte {}: vertex index 7 is out of range (3 vertices)",
            header + 36 + 1 + 8
        ))
    );
    // Cut inside the second vertex: the counts no longer fit.
    let cut: Vec<u8> = ok[..header + 16].to_vec();
    assert_eq!(
        load(cut).map(|_| ()),
        Err(
            "t.ply:3: element 'vertex' claims 3 entries, which need at least 36 bytes, but only 16 follow the header"
                .into()
        )
    );
    let mut cut_face = ok.clone();
    cut_face.truncate(ok.len() - 2);
    assert_eq!(
        load(cut_face).map(|_| ()),
        Err(format!(
            "t.ply: byte {}: truncated: a list of 3 entries runs past the end of the file ('face' entry 0 of 1)",
            header + 36
        ))
    );
}

#[test]
fn any_integer_list_types_and_aliases() {
    let expect = [[0u32, 1, 2]];
    for (decl, count, idx) in [
        (
            "list uint8 int32",
            vec![3u8],
            [0i32, 1, 2].map(i32::to_le_bytes).concat(),
        ),
        (
            "list ushort short",
            3u16.to_le_bytes().to_vec(),
            [0i16, 1, 2].map(i16::to_le_bytes).concat(),
        ),
        ("list int uchar", 3i32.to_le_bytes().to_vec(), vec![0, 1, 2]),
        ("list char uint16", vec![3], [0u16, 1, 2].map(u16::to_le_bytes).concat()),
    ] {
        let b = binary_triangle(&count, &idx, decl);
        let (parts, _) = load(b).unwrap_or_default();
        assert_eq!(parts.first().map(|p| p.mesh.indices()), Some(&expect[..]), "{decl}");
    }
    let float_list = binary_triangle(&[3], &[0; 12], "list uchar float");
    assert_eq!(
        load(float_list).map(|_| ()),
        Err("t.ply:8: face list 'vertex_indices' must have integer count and index types".into())
    );
}

#[test]
fn uv_names_colour_encodings_and_element_order() {
    let head = |props: &str| {
        format!(
            "ply\r\nformat ascii 1.0\r\nobj_info made by hand\r\nelement face 1\r\nproperty list uchar int vertex_index\r\n\
element vertex 3\r\nproperty double x\r\nproperty double y\r\nproperty double z\r\n{props}end_header\r\n3 0 1 2\r\n"
        )
    };
    for (props, rows) in [
        ("property float u\r\nproperty float v\r\n", ["0.25 0.5", "1 0", "0 1"]),
        ("property float s\r\nproperty float t\r\n", ["0.25 0.5", "1 0", "0 1"]),
        (
            "property float texture_u\r\nproperty float texture_v\r\n",
            ["0.25 0.5", "1 0", "0 1"],
        ),
    ] {
        let mut text = head(props);
        for (i, r) in rows.iter().enumerate() {
            text.push_str(&format!("{i} 0 {} {r}\r\n", i * 2));
        }
        let (parts, _) = load(text.into_bytes()).unwrap_or_default();
        let m = &parts[0].mesh;
        assert_eq!(m.indices(), &[[0, 1, 2]], "{props}");
        assert_eq!(
            m.uvs().map(|u| u[0]),
            Some(lucent_geom::Vec2::new(0.25, 0.5)),
            "{props}"
        );
        assert_eq!(m.positions()[2], Vec3::new(2.0, 0.0, 4.0));
        assert!(m.colors().is_none() && m.normals().is_none());
    }
    // The same colours as uchar with alpha, as float, and as ushort.
    let colours = |props: &str, rows: [&str; 3]| {
        let mut text = head(props);
        for (i, r) in rows.iter().enumerate() {
            text.push_str(&format!("{i} 0 0 {r}\r\n"));
        }
        let (parts, _) = load(text.into_bytes()).unwrap_or_default();
        parts[0].mesh.colors().map(<[Vec3]>::to_vec)
    };
    let uchar = colours(
        "property uchar red\r\nproperty uchar green\r\nproperty uchar blue\r\nproperty uchar alpha\r\n",
        ["255 0 51 7", "0 255 0 7", "0 0 255 7"],
    );
    let float = colours(
        "property float r\r\nproperty float g\r\nproperty float b\r\n",
        ["1 0 0.2", "0 1 0", "0 0 1"],
    );
    assert!(uchar.is_some());
    let (u, f) = (uchar.unwrap_or_default(), float.unwrap_or_default());
    assert!(
        u.iter().zip(&f).all(|(a, b)| (*a - *b).abs().max_element() < 1e-6),
        "{u:?} {f:?}"
    );
    assert_eq!(u[1], Vec3::Y);
}

#[test]
fn ascii_value_errors_are_located() {
    let text = String::from_utf8_lossy(ASCII);
    let short = text.replace("1 0 0 0 255 0\n", "1 0 0 0 255\n").into_bytes();
    assert_eq!(
        load(short).map(|_| ()),
        Err(
            "t.ply:15: the line ends before a property of element 'vertex' (fewer values than the header declares)"
                .into()
        )
    );
    let long = text.replace("1 0 0 0 255 0\n", "1 0 0 0 255 0 9\n").into_bytes();
    assert_eq!(
        load(long).map(|_| ()),
        Err("t.ply:15: more values than the header declares for element 'vertex'".into())
    );
    let neg = text.replace("4 0 1 2 3", "4 0 1 -2 3").into_bytes();
    assert_eq!(
        load(neg).map(|_| ()),
        Err("t.ply:18: vertex index -2 is out of range (4 vertices)".into())
    );
    let truncated = text.replace("4 0 1 2 3\n", "").into_bytes();
    assert_eq!(
        load(truncated).map(|_| ()),
        Err("t.ply:18: truncated: the file ends after 0 of 1 'face' entries".into())
    );
}

#[test]
fn warnings_for_short_faces_and_non_finite_vertices() {
    let text = String::from_utf8_lossy(ASCII)
        .replace("element face 1", "element face 2")
        .replace("1 1 0 0 0 255", "nan 1 0 0 0 255")
        .replace("4 0 1 2 3\n", "4 0 1 2 3\n2 0 1\n")
        .into_bytes();
    let (parts, report) = load(text).unwrap_or_default();
    assert_eq!(parts[0].mesh.n_triangles(), 2, "triangles keep their ids");
    assert!(parts[0].mesh.positions()[2].x.is_nan(), "not dropped");
    assert_eq!(report.warnings.len(), 2, "{:?}", report.warnings);
    assert!(report.warnings[0].contains("1 faces have fewer than 3 vertices"));
    assert!(report.warnings[1].contains("rejected 1 vertices with NaN or infinite coordinates"));
}

#[test]
fn long_lines_and_headers_read_in_linear_time() {
    // A 600 kB run of spaces inside a vertex line and a 300 kB comment:
    // both cross the read buffer many times over.
    let mut text = format!(
        "ply\nformat ascii 1.0\ncomment {}\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n",
        "c".repeat(300_000)
    );
    text.push_str(&" ".repeat(600_000));
    text.push_str("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    let (parts, _) = load(text.into_bytes()).unwrap_or_default();
    assert_eq!(parts.first().map(|p| p.mesh.n_triangles()), Some(1));
}
