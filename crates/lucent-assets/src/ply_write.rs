//! PLY output: a triangle mesh as ASCII or binary PLY (positions, and
//! normals and texture coordinates when the mesh has them).
//!
//! Used to make benchmark inputs and round-trip tests; the writer is the
//! reader's mirror, so every file it writes loads back to the same arrays.

use crate::AssetError;
use lucent_geom::TriMesh;
use std::io::Write;
use std::path::Path;

/// How a PLY body is encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlyFormat {
    /// Text, one element per line.
    Ascii,
    /// Binary, little-endian.
    BinaryLittleEndian,
    /// Binary, big-endian.
    BinaryBigEndian,
}

impl PlyFormat {
    fn name(self) -> &'static str {
        match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// Encodes `mesh` as PLY: float `x y z`, then `nx ny nz` and `u v` when
/// present, and faces as `list uchar uint vertex_indices`. ASCII floats are
/// written with enough digits to read back bit for bit.
///
/// ```
/// use lucent_assets::{PlyFormat, encode_ply};
/// let mesh = lucent_geom::shapes::cuboid();
/// let bytes = encode_ply(&mesh, PlyFormat::BinaryLittleEndian);
/// assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
/// ```
pub fn encode_ply(mesh: &TriMesh, format: PlyFormat) -> Vec<u8> {
    let mut out = Vec::with_capacity(64 + mesh.n_vertices() * 32 + mesh.n_triangles() * 13);
    let mut props = vec!["x", "y", "z"];
    if mesh.normals().is_some() {
        props.extend(["nx", "ny", "nz"]);
    }
    if mesh.uvs().is_some() {
        props.extend(["u", "v"]);
    }
    out.extend(format!("ply\nformat {} 1.0\ncomment written by Lucent\n", format.name()).bytes());
    out.extend(format!("element vertex {}\n", mesh.n_vertices()).bytes());
    for p in &props {
        out.extend(format!("property float {p}\n").bytes());
    }
    out.extend(format!("element face {}\n", mesh.n_triangles()).bytes());
    out.extend(b"property list uchar uint vertex_indices\nend_header\n");
    let mut values: Vec<f32> = Vec::with_capacity(props.len());
    for v in 0..mesh.n_vertices() {
        values.clear();
        values.extend(mesh.positions()[v].to_array());
        if let Some(n) = mesh.normals() {
            values.extend(n[v].to_array());
        }
        if let Some(uv) = mesh.uvs() {
            values.extend(uv[v].to_array());
        }
        match format {
            PlyFormat::Ascii => {
                let words: Vec<String> = values.iter().map(|x| format!("{x:?}")).collect();
                out.extend(words.join(" ").bytes());
                out.push(b'\n');
            }
            PlyFormat::BinaryLittleEndian => values.iter().for_each(|x| out.extend(x.to_le_bytes())),
            PlyFormat::BinaryBigEndian => values.iter().for_each(|x| out.extend(x.to_be_bytes())),
        }
    }
    for tri in mesh.indices() {
        match format {
            PlyFormat::Ascii => {
                // Writing to a Vec cannot fail.
                let _ = writeln!(out, "3 {} {} {}", tri[0], tri[1], tri[2]);
            }
            PlyFormat::BinaryLittleEndian => {
                out.push(3);
                tri.iter().for_each(|i| out.extend(i.to_le_bytes()));
            }
            PlyFormat::BinaryBigEndian => {
                out.push(3);
                tri.iter().for_each(|i| out.extend(i.to_be_bytes()));
            }
        }
    }
    out
}

/// Writes `mesh` to `path` as PLY (see [`encode_ply`]).
pub fn save_ply(path: &Path, mesh: &TriMesh, format: PlyFormat) -> Result<(), AssetError> {
    std::fs::write(path, encode_ply(mesh, format)).map_err(|error| AssetError::Io {
        path: path.to_owned(),
        error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MemorySource, load_mesh_from};
    use lucent_geom::shapes;

    #[test]
    fn every_format_reads_back_to_the_same_arrays() {
        let mesh = shapes::icosphere(2);
        assert!(mesh.normals().is_some());
        for format in [
            PlyFormat::Ascii,
            PlyFormat::BinaryLittleEndian,
            PlyFormat::BinaryBigEndian,
        ] {
            let src = MemorySource::new().with_file("m.ply", encode_ply(&mesh, format));
            let loaded = load_mesh_from(&src, Path::new("m.ply")).map(|(parts, _)| parts);
            let Ok([part]) = loaded.as_deref() else {
                panic!("{format:?}: {:?}", loaded.map(|p| p.len()));
            };
            assert_eq!(part.mesh.positions(), mesh.positions(), "{format:?}");
            assert_eq!(part.mesh.indices(), mesh.indices(), "{format:?}");
            assert_eq!(part.mesh.uvs(), mesh.uvs(), "{format:?}");
            let n = mesh.normals().unwrap_or_default();
            let back = part.mesh.normals().unwrap_or_default();
            assert!(n.iter().zip(back).all(|(a, b)| (*a - *b).length() < 1e-6));
        }
    }
}
