//! Loading one mesh file (OBJ or PLY) into triangle meshes.

use crate::{AssetError, AssetSource, FileSystem, LoadReport, obj, ply};
use lucent_geom::{MeshError, TriMesh};
use lucent_shading::Material;
use std::path::Path;

/// One drawable part of a mesh file: an OBJ group with one material, or a
/// whole PLY.
#[derive(Clone, Debug)]
pub struct MeshPart {
    /// Object or group name from the file (may be empty).
    pub name: String,
    /// The triangles, with only the attributes the file gives.
    pub mesh: TriMesh,
    /// The part's material from the file (OBJ + MTL), if any.
    pub material: Option<Material>,
    /// The material's name in the file (`usemtl`), if any.
    pub material_name: Option<String>,
    /// Whether the loader computed the normals because the file gave none
    /// (OBJ files, whose smoothing groups only the loader sees).
    pub normals_computed: bool,
}

/// The positions and triangles of `parts` as one mesh, in part order, so
/// triangle `k` is the file's `k`-th triangle (what ray-for-ray comparisons
/// with other tools need). Other attributes are left out, since parts may
/// differ in which ones they carry.
///
/// ```
/// use lucent_assets::{MeshPart, merged_geometry};
/// use lucent_geom::{TriMesh, Vec3};
/// let tri = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]).unwrap_or_default();
/// let part = |name: &str| MeshPart {
///     name: name.into(),
///     mesh: tri.clone(),
///     material: None,
///     material_name: None,
///     normals_computed: false,
/// };
/// let merged = merged_geometry(&[part("a"), part("b")]).unwrap_or_default();
/// assert_eq!(merged.indices(), &[[0, 1, 2], [3, 4, 5]]);
/// ```
pub fn merged_geometry(parts: &[MeshPart]) -> Result<TriMesh, MeshError> {
    let n_vertices: usize = parts.iter().map(|p| p.mesh.positions().len()).sum();
    if u32::try_from(n_vertices).is_err() {
        return Err(MeshError::TooManyVertices(n_vertices));
    }
    let mut positions = Vec::with_capacity(n_vertices);
    let mut indices = Vec::with_capacity(parts.iter().map(|p| p.mesh.n_triangles()).sum());
    for part in parts {
        // Fits: the total vertex count was checked above.
        let base = positions.len() as u32;
        positions.extend_from_slice(part.mesh.positions());
        indices.extend(part.mesh.indices().iter().map(|t| t.map(|i| i + base)));
    }
    TriMesh::new(positions, indices)
}

/// Loads an OBJ (with its MTL materials and textures) or PLY file from disk.
pub fn load_mesh(path: &Path) -> Result<(Vec<MeshPart>, LoadReport), AssetError> {
    load_mesh_from(&FileSystem, path)
}

/// Loads an OBJ or PLY file (chosen by extension) from `source`.
pub fn load_mesh_from(source: &dyn AssetSource, path: &Path) -> Result<(Vec<MeshPart>, LoadReport), AssetError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let mut report = LoadReport::default();
    let mut parts = match ext.as_deref() {
        Some("obj") => obj::load_obj(source, path, &mut report)?,
        Some("ply") => vec![ply::load_ply(source, path, &mut report)?],
        _ => return Err(AssetError::format(path, "unknown mesh format (expected .obj or .ply)")),
    };
    for part in &mut parts {
        reject_non_finite(path, part, &mut report);
        check_mesh(path, &part.mesh, &mut report);
    }
    Ok((parts, report))
}

/// Rejects vertices with NaN or infinite coordinates, and with them every
/// triangle that uses one, with a warning ([`TriMesh::reject_non_finite_vertices`]:
/// the triangles keep their numbers but are never drawn, bound or used for
/// normals). Normals computed from such a mesh never saw them either.
fn reject_non_finite(path: &Path, part: &mut MeshPart, report: &mut LoadReport) {
    let (n_vertices, n_triangles) = part.mesh.reject_non_finite_vertices();
    if n_vertices > 0 {
        report.warn(
            path,
            format!(
                "rejected {n_vertices} vertices with NaN or infinite coordinates and the \
                 {n_triangles} triangles that use them (they keep their numbers but are never drawn)"
            ),
        );
    }
}

/// Counts what will not render as the file intends, without dropping it.
fn check_mesh(path: &Path, mesh: &TriMesh, report: &mut LoadReport) {
    let positions = mesh.positions();
    let degenerate = (0..mesh.n_triangles())
        .filter(|&t| lucent_geom::triangle_normal(mesh.triangle(t)).length_squared() == 0.0)
        .count();
    if degenerate > 0 {
        report.warn(path, format!("{degenerate} degenerate (zero-area) triangles"));
    }
    let mut used = vec![false; positions.len()];
    for &i in mesh.indices().iter().flatten() {
        used[i as usize] = true;
    }
    let unused = used.iter().filter(|&&u| !u).count();
    if unused > 0 {
        report.warn(path, format!("{unused} vertices are not used by any triangle"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MemorySource;

    #[test]
    fn unknown_extensions_are_refused() {
        let src = MemorySource::new().with_file("a.stl", b"solid");
        let err = load_mesh_from(&src, Path::new("a.stl"))
            .map(|_| ())
            .map_err(|e| e.to_string());
        assert_eq!(
            err,
            Err("a.stl: unknown mesh format (expected .obj or .ply)".to_owned())
        );
    }
}

#[cfg(test)]
mod non_finite_tests {
    use super::*;
    use crate::MemorySource;
    use lucent_geom::{Aabb, Vec3};

    /// A unit square (triangles 0 and 1) plus triangle 2 on a NaN vertex and
    /// triangle 3 on an infinite one, sharing the square's corners.
    const OBJ: &[u8] = b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv nan 0 0\nv 0 inf 0\n\
f 1 2 3\nf 1 3 4\nf 3 2 5\nf 4 3 6\n";
    /// The same in PLY, with -inf.
    const PLY: &[u8] = b"ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\n\
property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0\n1 0 0\n1 1 0\n0 1 0\nnan 0 0\n0 -inf 0\n3 0 1 2\n3 0 2 3\n3 2 1 4\n3 3 2 5\n";

    #[test]
    fn non_finite_vertices_are_rejected_with_a_warning_keeping_triangle_numbers() {
        for (name, bytes) in [("a.obj", OBJ), ("a.ply", PLY)] {
            let src = MemorySource::new().with_file(name, bytes);
            let (parts, report) = load_mesh_from(&src, Path::new(name)).unwrap_or_else(|e| panic!("{e}"));
            let mesh = &parts[0].mesh;
            assert_eq!(mesh.n_triangles(), 4, "{name}: triangle numbers are kept");
            assert_eq!(
                report.warnings,
                vec![format!(
                    "{name}: rejected 2 vertices with NaN or infinite coordinates and the 2 triangles \
                     that use them (they keep their numbers but are never drawn)"
                )]
            );
            // The rejected triangles are all NaN, so nothing downstream
            // (BVH, bounds, normals) can use them.
            for t in [2, 3] {
                assert!(mesh.triangle(t).iter().any(|p| p.is_nan()), "{name}: triangle {t}");
            }
            assert_eq!(mesh.bounds(), Aabb::new(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)), "{name}");
            let normals = mesh
                .normals()
                .map_or_else(|| mesh.compute_smooth_normals(), <[Vec3]>::to_vec);
            for n in &normals[..4] {
                assert!(n.abs_diff_eq(Vec3::Z, 1e-6), "{name}: {n}");
            }
        }
    }
}
