//! Loading one mesh file (OBJ or PLY) into triangle meshes.

use crate::{AssetError, AssetSource, FileSystem, LoadReport, obj, ply};
use lucent_geom::TriMesh;
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

/// Loads an OBJ (with its MTL materials and textures) or PLY file from disk.
pub fn load_mesh(path: &Path) -> Result<(Vec<MeshPart>, LoadReport), AssetError> {
    load_mesh_from(&FileSystem, path)
}

/// Loads an OBJ or PLY file (chosen by extension) from `source`.
pub fn load_mesh_from(source: &dyn AssetSource, path: &Path) -> Result<(Vec<MeshPart>, LoadReport), AssetError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let mut report = LoadReport::default();
    let parts = match ext.as_deref() {
        Some("obj") => obj::load_obj(source, path, &mut report)?,
        Some("ply") => vec![ply::load_ply(source, path, &mut report)?],
        _ => return Err(AssetError::format(path, "unknown mesh format (expected .obj or .ply)")),
    };
    for part in &parts {
        check_mesh(path, &part.mesh, &mut report);
    }
    Ok((parts, report))
}

/// Counts what will not render as the file intends, without dropping it.
fn check_mesh(path: &Path, mesh: &TriMesh, report: &mut LoadReport) {
    let positions = mesh.positions();
    let non_finite = positions.iter().filter(|p| !p.is_finite()).count();
    if non_finite > 0 {
        report.warn(
            path,
            format!("{non_finite} vertices have non-finite coordinates; their triangles are skipped"),
        );
    }
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
