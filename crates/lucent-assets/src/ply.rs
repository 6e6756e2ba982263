//! PLY loading through ply-rs, straight into typed vertex and face records
//! (no per-element hash maps).
//!
//! Reads ASCII and binary (both endians) files with positions, optional
//! normals (`nx ny nz`), texture coordinates (`u v`, `s t` or
//! `texture_u texture_v`) and colours (`red green blue`, 8-bit or float,
//! taken as sRGB). Faces are lists named `vertex_indices` or `vertex_index`
//! of any integer type; polygons are fan-triangulated in file order. Other
//! elements and properties are read past and ignored.

use crate::{AssetError, AssetSource, LoadReport, MeshPart};
use lucent_geom::{TriMesh, Vec2, Vec3};
use lucent_shading::color::srgb_to_linear;
use ply_rs::parser::Parser;
use ply_rs::ply::{ElementDef, Encoding, Header, Property, PropertyAccess, PropertyType, ScalarType};
use std::io::{BufRead, Cursor};
use std::path::Path;

#[derive(Default)]
struct PlyVertex {
    p: [f32; 3],
    n: [f32; 3],
    uv: [f32; 2],
    c: [f32; 3],
}

fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// A colour channel in 0..1: integers are scaled by their type's maximum.
fn channel(p: &Property) -> f32 {
    let v = match *p {
        Property::UChar(v) => v as f32 / 255.0,
        Property::UShort(v) => v as f32 / 65535.0,
        Property::Char(v) => v as f32 / 127.0,
        _ => scalar(p).unwrap_or(0.0) as f32,
    };
    v.clamp(0.0, 1.0)
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, key: String, property: Property) {
        let v = || scalar(&property).unwrap_or(f64::NAN) as f32;
        match key.as_str() {
            "x" => self.p[0] = v(),
            "y" => self.p[1] = v(),
            "z" => self.p[2] = v(),
            "nx" => self.n[0] = v(),
            "ny" => self.n[1] = v(),
            "nz" => self.n[2] = v(),
            "u" | "s" | "texture_u" => self.uv[0] = v(),
            "v" | "t" | "texture_v" => self.uv[1] = v(),
            "red" | "r" | "diffuse_red" => self.c[0] = channel(&property),
            "green" | "g" | "diffuse_green" => self.c[1] = channel(&property),
            "blue" | "b" | "diffuse_blue" => self.c[2] = channel(&property),
            _ => {}
        }
    }
}

#[derive(Default)]
struct PlyFace {
    indices: Vec<i64>,
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        Self::default()
    }

    fn set_property(&mut self, key: String, property: Property) {
        if key != "vertex_indices" && key != "vertex_index" {
            return;
        }
        self.indices = match property {
            Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
            Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
            Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
            Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
            // Float indices are not valid PLY; mark them out of range.
            Property::ListFloat(v) => vec![-1; v.len()],
            Property::ListDouble(v) => vec![-1; v.len()],
            _ => Vec::new(),
        };
    }
}

/// Elements we do not use: read past, keep nothing.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

fn has(def: &ElementDef, names: &[&str]) -> bool {
    names.iter().all(|n| def.properties.contains_key(*n))
}

fn has_any(def: &ElementDef, groups: &[&[&str]]) -> bool {
    groups.iter().any(|g| has(def, g))
}

pub(crate) fn load_ply(source: &dyn AssetSource, path: &Path, report: &mut LoadReport) -> Result<MeshPart, AssetError> {
    let bytes = source.read(path)?;
    check_header_text(&bytes).map_err(|(line, message)| AssetError::Format {
        path: path.to_owned(),
        location: Some(line),
        message,
    })?;
    let mut reader = Cursor::new(bytes.as_ref());
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| AssetError::format(path, format!("bad PLY header: {}", one_line(&e.to_string()))))?;
    let header_len = reader.position() as usize;
    check_counts_fit(&header, bytes.len() - header_len).map_err(|message| AssetError::format(path, message))?;
    let header_lines = bytes[..header_len].iter().filter(|&&b| b == b'\n').count();
    let mut vertices: Option<(Vec<PlyVertex>, &ElementDef)> = None;
    let mut faces: Vec<PlyFace> = Vec::new();
    let mut lines_before = header_lines;
    for def in header.elements.values() {
        let located = |e: std::io::Error| ascii_error(path, &header, lines_before, &e);
        match def.name.as_str() {
            "vertex" => {
                let v = Parser::<PlyVertex>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(located)?;
                vertices = Some((v, def));
            }
            "face" => {
                faces = Parser::<PlyFace>::new()
                    .read_payload_for_element(&mut reader, def, &header)
                    .map_err(located)?;
            }
            _ => {
                skip_element(&mut reader, def, &header).map_err(located)?;
            }
        }
        lines_before += def.count;
    }
    let Some((vertices, vdef)) = vertices else {
        return Err(AssetError::format(path, "no `vertex` element"));
    };
    if !has(vdef, &["x", "y", "z"]) {
        return Err(AssetError::format(path, "the vertex element lacks x, y or z"));
    }
    let n_vertices = vertices.len() as i64;
    let mut indices = Vec::with_capacity(faces.len());
    let mut short_faces = 0usize;
    for (face_idx, face) in faces.iter().enumerate() {
        if let Some(&bad) = face.indices.iter().find(|&&i| !(0..n_vertices).contains(&i)) {
            return Err(AssetError::format(
                path,
                format!("face {face_idx} uses vertex {bad}, but there are {n_vertices} vertices"),
            ));
        }
        if face.indices.len() < 3 {
            short_faces += 1;
            continue;
        }
        let i = |k: usize| face.indices[k] as u32;
        indices.extend((1..face.indices.len() - 1).map(|k| [i(0), i(k), i(k + 1)]));
    }
    if short_faces > 0 {
        report.warn(
            path,
            format!("{short_faces} faces have fewer than 3 vertices and are skipped"),
        );
    }
    let positions = vertices.iter().map(|v| Vec3::from(v.p)).collect();
    let err = |e: lucent_geom::MeshError| AssetError::format(path, e.to_string());
    let mut mesh = TriMesh::new(positions, indices).map_err(err)?;
    if has(vdef, &["nx", "ny", "nz"]) {
        mesh = mesh
            .with_normals(vertices.iter().map(|v| Vec3::from(v.n).normalize_or_zero()).collect())
            .map_err(err)?;
    }
    if has_any(vdef, &[&["u", "v"], &["s", "t"], &["texture_u", "texture_v"]]) {
        mesh = mesh
            .with_uvs(vertices.iter().map(|v| Vec2::from(v.uv)).collect())
            .map_err(err)?;
    }
    if has_any(
        vdef,
        &[
            &["red", "green", "blue"],
            &["r", "g", "b"],
            &["diffuse_red", "diffuse_green", "diffuse_blue"],
        ],
    ) {
        let colors = vertices.iter().map(|v| Vec3::from(v.c.map(srgb_to_linear))).collect();
        mesh = mesh.with_colors(colors).map_err(err)?;
    }
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(MeshPart {
        name,
        mesh,
        material: None,
    })
}

/// Checks what ply-rs's header parser does not: every digit run must fit a
/// `u64` (its grammar unwraps the parse, so a larger number would panic),
/// element names must be unique (it keeps only the last declaration) and
/// every element needs a property (an empty one would make it materialise
/// `count` records from no data). Returns `(line, message)` for the first
/// problem.
fn check_header_text(bytes: &[u8]) -> Result<(), (usize, String)> {
    let mut names: Vec<String> = Vec::new();
    let mut open_element: Option<(usize, String)> = None;
    for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
        for run in line.split(|b| !b.is_ascii_digit()).filter(|r| !r.is_empty()) {
            let digits = String::from_utf8_lossy(run);
            if digits.parse::<u64>().is_err() {
                return Err((i + 1, format!("number {digits} in the header is too large")));
            }
        }
        let text = String::from_utf8_lossy(line);
        let mut words = text.split_whitespace();
        match words.next() {
            Some("element") | Some("end_header") => {
                if let Some((at, name)) = open_element.take() {
                    return Err((at, format!("element '{name}' has no properties")));
                }
                if let Some(name) = words.next().filter(|_| text.starts_with("element")) {
                    if names.iter().any(|n| n == name) {
                        return Err((i + 1, format!("element '{name}' is declared twice")));
                    }
                    names.push(name.to_owned());
                    open_element = Some((i + 1, name.to_owned()));
                }
            }
            Some("property") => open_element = None,
            _ => {}
        }
        if line.starts_with(b"end_header") {
            break;
        }
    }
    Ok(())
}

/// Fails when the elements' counts cannot fit in the bytes after the
/// header (each ASCII element takes at least two bytes, a value and a line
/// break; each binary one at least the sum of its scalar sizes), so absurd
/// counts are refused before anything is read or allocated. Names the first
/// element that runs past the end.
fn check_counts_fit(header: &Header, payload_len: usize) -> Result<(), String> {
    let mut needed: u128 = 0;
    for def in header.elements.values() {
        let per_element: u128 = match header.encoding {
            Encoding::Ascii => 2,
            _ => def
                .properties
                .values()
                .map(|p| match &p.data_type {
                    PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
                })
                .sum(),
        };
        let element_bytes = per_element * def.count as u128;
        let remaining = (payload_len as u128).saturating_sub(needed);
        if element_bytes > remaining {
            let after = if needed > 0 { " and the elements before it" } else { "" };
            return Err(format!(
                "element '{}' claims {} entries, which need at least {element_bytes} bytes, but only {remaining} follow the header{after}",
                def.name, def.count
            ));
        }
        needed += element_bytes;
    }
    Ok(())
}

fn scalar_size(t: &ScalarType) -> u128 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

fn skip_element<R: BufRead>(reader: &mut R, def: &ElementDef, header: &Header) -> std::io::Result<()> {
    Parser::<Skip>::new()
        .read_payload_for_element(reader, def, header)
        .map(|_| ())
}

fn one_line(s: &str) -> String {
    s.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// ply-rs numbers ASCII lines from the start of each element; translate that
/// into a line of the file.
fn ascii_error(path: &Path, header: &Header, lines_before: usize, e: &std::io::Error) -> AssetError {
    let msg = one_line(&e.to_string());
    let location = (header.encoding == Encoding::Ascii)
        .then(|| msg.strip_prefix("Line ")?.split(':').next()?.parse::<usize>().ok())
        .flatten()
        .map(|i| lines_before + i + 1);
    let message = match location {
        Some(_) => msg.split_once(": ").map_or(msg.clone(), |(_, rest)| rest.to_owned()),
        None => msg,
    };
    let message = if message.is_empty() || message.contains("failed to fill whole buffer") {
        format!("truncated data ({message})")
    } else {
        message
    };
    AssetError::Format {
        path: path.to_owned(),
        location,
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MemorySource, load_mesh_from};

    const ASCII: &[u8] = b"ply\nformat ascii 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 255 255 255\n4 0 1 2 3\n";

    fn load(bytes: &'static [u8]) -> Result<(Vec<MeshPart>, LoadReport), String> {
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
        let (parts, _) = load(b.leak()).unwrap_or_default();
        let m = &parts[0].mesh;
        assert_eq!(m.indices(), &[[0, 1, 2]]);
        assert_eq!(m.normals().map(|n| n[1]), Some(Vec3::Z), "normals are normalised");
    }

    #[test]
    fn errors_name_file_and_line() {
        let bad_index = String::from_utf8_lossy(ASCII)
            .replace("4 0 1 2 3", "3 0 1 9")
            .into_bytes()
            .leak();
        assert_eq!(
            load(bad_index).map(|_| ()),
            Err("t.ply: face 0 uses vertex 9, but there are 4 vertices".into())
        );
        let bad_number = String::from_utf8_lossy(ASCII)
            .replace("1 1 0 0 0 255", "1 x 0 0 0 255")
            .into_bytes()
            .leak();
        let err = load(bad_number).map(|_| ()).unwrap_err();
        assert!(err.starts_with("t.ply:16: "), "{err}");
        let truncated = &ASCII[..ASCII.len() - 12];
        let err = load(truncated).map(|_| ()).unwrap_err();
        assert!(err.starts_with("t.ply:"), "{err}");
        // Counts that cannot fit the file fail before anything is read.
        let huge = b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nend_header\n";
        assert_eq!(
            load(huge).map(|_| ()),
            Err("t.ply: element 'vertex' claims 4000000000 entries, which need at least 16000000000 bytes, but only 0 follow the header".into())
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
        assert!(load(b"ply\nformat ascii 9.0\nend_header\n").is_err());
        assert!(load(b"not a ply").is_err());
    }
}
