//! Wavefront OBJ and MTL loading through tobj.
//!
//! Polygons are fan-triangulated, attributes are unified into one index per
//! vertex (vertices on UV seams are split), and MTL materials and their
//! diffuse textures are loaded through the same [`AssetSource`].

use crate::image_io::srgb_to_linear;
use crate::{AssetError, AssetSource, LoadReport, MeshPart, load_texture, normalize_path};
use lucent_geom::{TriMesh, Vec2, Vec3};
use lucent_shading::{Material, Texture};
use std::cell::RefCell;
use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub(crate) fn load_obj(
    source: &dyn AssetSource,
    path: &Path,
    report: &mut LoadReport,
) -> Result<Vec<MeshPart>, AssetError> {
    let bytes = source.read(path)?;
    let dir = path.parent().unwrap_or(Path::new("")).to_owned();
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    // tobj calls this once per `mtllib`; remember where the MTL was, since
    // its texture paths are relative to it.
    let mtl_dir: RefCell<Option<PathBuf>> = RefCell::new(None);
    let load_mtl = |mtl: &Path| {
        let mtl_path = dir.join(mtl);
        let bytes = source.read(&mtl_path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
        *mtl_dir.borrow_mut() = mtl_path.parent().map(Path::to_owned);
        tobj::load_mtl_buf(&mut Cursor::new(bytes.as_ref()))
    };
    let (models, materials) = tobj::load_obj_buf(&mut Cursor::new(bytes.as_ref()), &options, load_mtl)
        .map_err(|e| AssetError::format(path, format!("cannot parse OBJ: {e}")))?;
    // tobj reports an error here only when an `mtllib` could not be loaded.
    let materials = materials.unwrap_or_else(|e| {
        report.warn(
            path,
            format!("cannot load its MTL file ({e}); using the default material"),
        );
        Vec::new()
    });
    let mtl_dir = mtl_dir.into_inner().unwrap_or(dir);
    let mut textures = HashMap::new();
    let materials: Vec<Material> = materials
        .iter()
        .map(|m| convert_material(source, m, &mtl_dir, &mut textures, report))
        .collect();
    let mut parts = Vec::with_capacity(models.len());
    for model in models {
        let mesh =
            convert_mesh(&model.mesh).map_err(|e| AssetError::format(path, format!("object '{}': {e}", model.name)))?;
        if mesh.n_triangles() == 0 {
            continue;
        }
        let material = model.mesh.material_id.and_then(|id| materials.get(id).cloned());
        parts.push(MeshPart {
            name: model.name,
            mesh,
            material,
        });
    }
    Ok(parts)
}

fn triples(v: &[f32]) -> Vec<Vec3> {
    v.chunks_exact(3).map(Vec3::from_slice).collect()
}

fn convert_mesh(m: &tobj::Mesh) -> Result<TriMesh, lucent_geom::MeshError> {
    let indices = m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let mut mesh = TriMesh::new(triples(&m.positions), indices)?;
    if !m.normals.is_empty() {
        mesh = mesh.with_normals(triples(&m.normals).into_iter().map(Vec3::normalize_or_zero).collect())?;
    }
    if !m.texcoords.is_empty() {
        mesh = mesh.with_uvs(m.texcoords.chunks_exact(2).map(Vec2::from_slice).collect())?;
    }
    if !m.vertex_color.is_empty() {
        let colors = triples(&m.vertex_color)
            .into_iter()
            .map(|c| c.clamp(Vec3::ZERO, Vec3::ONE).to_array().map(srgb_to_linear).into())
            .collect();
        mesh = mesh.with_colors(colors)?;
    }
    Ok(mesh)
}

/// Maps MTL fields onto [`Material`]: Ka (default Kd), Kd, Ks, Ns, Ke, Ni;
/// `d < 1` becomes transmission `kt = 1 - d`; illumination models with ray
/// traced reflection (3, 5, 7) set the mirror weight `kr = Ks`.
fn convert_material(
    source: &dyn AssetSource,
    m: &tobj::Material,
    mtl_dir: &Path,
    textures: &mut HashMap<PathBuf, Arc<Texture>>,
    report: &mut LoadReport,
) -> Material {
    let v = |c: Option<[f32; 3]>, default: Vec3| c.map_or(default, Vec3::from).max(Vec3::ZERO);
    let kd = v(m.diffuse, Vec3::splat(0.8));
    let ks = v(m.specular, Vec3::ZERO);
    let mut material = Material {
        ka: v(m.ambient, kd),
        kd,
        ks,
        shininess: m.shininess.filter(|s| s.is_finite()).unwrap_or(32.0).max(0.0),
        kr: if matches!(m.illumination_model, Some(3 | 5 | 7)) {
            ks
        } else {
            Vec3::ZERO
        },
        kt: Vec3::splat((1.0 - m.dissolve.unwrap_or(1.0)).clamp(0.0, 1.0)),
        ior: m.optical_density.filter(|n| n.is_finite() && *n > 0.0).unwrap_or(1.0),
        emission: v(m.emissive, Vec3::ZERO),
        diffuse_map: None,
    };
    if let Some(tex) = &m.diffuse_texture {
        // Options such as `-s 1 1 1` come before the file name.
        let file = tex.split_whitespace().last().unwrap_or_default();
        let tex_path = normalize_path(&mtl_dir.join(file));
        let loaded = match textures.get(&tex_path) {
            Some(t) => t.clone(),
            None => {
                let t = match load_texture(source, &tex_path) {
                    Ok(t) => Arc::new(t),
                    Err(e) => {
                        report.warn(
                            &tex_path,
                            format!("{e}; material '{}' shows a checkerboard instead", m.name),
                        );
                        Arc::new(missing_texture())
                    }
                };
                textures.insert(tex_path, t.clone());
                t
            }
        };
        material.diffuse_map = Some(loaded);
    }
    material
}

/// A magenta and black checkerboard that makes a missing texture obvious.
pub(crate) fn missing_texture() -> Texture {
    let texels = (0..64)
        .map(|i| {
            if (i % 8 + i / 8) % 2 == 0 {
                Vec3::new(1.0, 0.0, 1.0)
            } else {
                Vec3::ZERO
            }
        })
        .collect();
    // 64 texels for 8x8 cannot fail; the constant is only a formality.
    Texture::new(8, 8, texels).unwrap_or_else(|_| Texture::constant(Vec3::new(1.0, 0.0, 1.0)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{MemorySource, load_mesh_from};

    const QUAD_OBJ: &[u8] = b"mtllib q.mtl\r\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
usemtl shiny\nf 1/1 2/2 3/3 4/4\n";
    const QUAD_MTL: &[u8] = b"newmtl shiny\nKa 0.1 0.1 0.1  # comment\nKd 0.5 0.25 0\nKs 0.9 0.9 0.9\nNs 50\nillum 3\nd 0.75\nNi 1.33\nmap_Kd -s 1 1 1 tex.png\n";

    #[test]
    fn loads_polygons_uvs_and_mtl() {
        let src = MemorySource::new()
            .with_file("m/q.obj", QUAD_OBJ)
            .with_file("m/q.mtl", QUAD_MTL);
        let (parts, report) = load_mesh_from(&src, Path::new("m/q.obj"))
            .map_err(|e| e.to_string())
            .unwrap_or_default();
        assert_eq!(parts.len(), 1);
        let part = &parts[0];
        assert_eq!(part.mesh.n_triangles(), 2, "quad fanned into two triangles");
        assert!(part.mesh.uvs().is_some() && part.mesh.normals().is_none());
        let m = part.material.clone().unwrap_or_default();
        assert_eq!(
            (m.ka, m.kd, m.shininess, m.ior),
            (Vec3::splat(0.1), Vec3::new(0.5, 0.25, 0.0), 50.0, 1.33)
        );
        assert_eq!((m.kr, m.kt), (Vec3::splat(0.9), Vec3::splat(0.25)));
        // The texture is missing: a warning and a checkerboard, not an error.
        assert!(m.diffuse_map.is_some_and(|t| t.width() == 8));
        assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
        assert!(report.warnings[0].starts_with("m/tex.png: "), "{:?}", report.warnings);
    }

    #[test]
    fn missing_mtl_is_a_warning_and_bad_indices_an_error() {
        let src = MemorySource::new()
            .with_file("q.obj", QUAD_OBJ)
            .with_file("bad.obj", b"v 0 0 0\nv 1 0 0\nf 1 2 3\n");
        let (parts, report) = load_mesh_from(&src, Path::new("q.obj")).unwrap_or_default();
        assert!(parts[0].material.is_none());
        assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
        let err = load_mesh_from(&src, Path::new("bad.obj"))
            .map(|_| ())
            .map_err(|e| e.to_string());
        assert!(err.is_err_and(|e| e.starts_with("bad.obj: ")));
    }
}
