//! Wavefront OBJ and MTL loading through tobj.
//!
//! Polygons are fan-triangulated, attributes are unified into one index per
//! vertex (vertices on UV seams are split), and MTL materials and their
//! diffuse textures are loaded through the same [`AssetSource`].

use crate::{AssetError, AssetSource, LoadReport, MeshPart, load_texture, normalize_path};
use lucent_geom::{TriMesh, Vec2, Vec3};
use lucent_shading::color::srgb_to_linear;
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
    // its texture paths are relative to it, and why it failed, since tobj's
    // error carries no line.
    let mtl_dir: RefCell<Option<PathBuf>> = RefCell::new(None);
    let mtl_problems: RefCell<Vec<String>> = RefCell::new(Vec::new());
    let load_mtl = |mtl: &Path| {
        let mtl_path = dir.join(mtl);
        let bytes = source.read(&mtl_path).map_err(|e| {
            mtl_problems.borrow_mut().push(e.to_string());
            tobj::LoadError::OpenFileFailed
        })?;
        *mtl_dir.borrow_mut() = mtl_path.parent().map(Path::to_owned);
        let text = normalize_mtl(&bytes).map_err(|(line, message)| {
            mtl_problems
                .borrow_mut()
                .push(format!("{}:{line}: {message}", mtl_path.display()));
            tobj::LoadError::MaterialParseError
        })?;
        tobj::load_mtl_buf(&mut Cursor::new(text.as_bytes()))
    };
    let text = normalize_obj(&bytes).map_err(|(line, message)| AssetError::Format {
        path: path.to_owned(),
        location: Some(line),
        message,
    })?;
    let (models, materials) = tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &options, load_mtl)
        .map_err(|e| AssetError::format(path, format!("cannot parse OBJ: {e}")))?;
    // tobj reports an error here only when an `mtllib` could not be loaded.
    let materials = materials.unwrap_or_else(|e| {
        let why = mtl_problems.borrow().first().cloned().unwrap_or_else(|| e.to_string());
        report.warn(
            path,
            format!("cannot load its MTL file ({why}); using the default material"),
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

/// The line without its comment: a `#` at the start of a word begins one
/// (so `usemtl mat#1` keeps its name).
fn strip_comment(line: &str) -> &str {
    let mut prev_is_space = true;
    for (i, c) in line.char_indices() {
        if c == '#' && prev_is_space {
            return line[..i].trim();
        }
        prev_is_space = c.is_whitespace();
    }
    line.trim()
}

/// Rewrites OBJ text so tobj reads it safely and as the file means it:
/// comments are removed, and every index of a face, line or point becomes
/// an absolute, checked index. tobj 4.0.5 reads index 0 as "missing", wraps
/// relative indices that reach before the first vertex, and can overflow on
/// huge ones; here each is an error `(line, message)` instead.
fn normalize_obj(bytes: &[u8]) -> Result<String, (usize, String)> {
    const KINDS: [(&str, &str); 3] = [
        ("vertex", "vertices"),
        ("texture coordinate", "texture coordinates"),
        ("normal", "normals"),
    ];
    let text = String::from_utf8_lossy(bytes);
    let kind_of = |keyword: &str| match keyword {
        "v" => Some(0),
        "vt" => Some(1),
        "vn" => Some(2),
        _ => None,
    };
    let mut totals = [0usize; 3];
    for line in text.lines() {
        if let Some(k) = line.split_whitespace().next().and_then(kind_of) {
            totals[k] += 1;
        }
    }
    let mut seen = [0usize; 3];
    let mut out = String::with_capacity(text.len());
    for (i, raw) in text.lines().enumerate() {
        let line = strip_comment(raw);
        let mut words = line.split_whitespace();
        let keyword = words.next().unwrap_or_default();
        if let Some(k) = kind_of(keyword) {
            seen[k] += 1;
        }
        if !matches!(keyword, "f" | "l" | "p") {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        out.push_str(keyword);
        for word in words {
            out.push(' ');
            let parts: Vec<&str> = word.split('/').collect();
            if parts.len() > 3 {
                return Err((i + 1, format!("'{word}' has more than three indices")));
            }
            for (k, part) in parts.iter().enumerate() {
                if k > 0 {
                    out.push('/');
                }
                if part.is_empty() {
                    continue;
                }
                let n: i64 = part.parse().map_err(|_| (i + 1, format!("'{part}' is not an index")))?;
                let absolute = match n {
                    0 => return Err((i + 1, "index 0 is not valid (OBJ indices start at 1)".to_owned())),
                    n if n < 0 => seen[k] as i64 + n + 1,
                    n => n,
                };
                if absolute < 1 || absolute > totals[k] as i64 {
                    let (one, many) = KINDS[k];
                    let count = if n < 0 { seen[k] } else { totals[k] };
                    return Err((i + 1, format!("{one} index {n} is out of range ({count} {many})")));
                }
                out.push_str(&absolute.to_string());
            }
        }
        out.push('\n');
    }
    Ok(out)
}

/// Rewrites MTL text so tobj can read it safely: a colour statement (`Ka`,
/// `Kd`, `Ks`, `Ke`, `Tf`) with one number means grey and is expanded to
/// three, as the MTL specification says (tobj 4.0.5 panics on fewer than
/// three). Any other count, or a non-number, is an error `(line, message)`.
/// Inline `#` comments are dropped.
fn normalize_mtl(bytes: &[u8]) -> Result<String, (usize, String)> {
    let text = String::from_utf8_lossy(bytes);
    let mut out = String::with_capacity(text.len() + 64);
    for (i, raw) in text.lines().enumerate() {
        let line = strip_comment(raw);
        let mut words = line.split_whitespace();
        let keyword = words.next().unwrap_or_default();
        if matches!(keyword, "Ka" | "Kd" | "Ks" | "Ke" | "Tf") {
            let values: Vec<&str> = words.collect();
            let numbers: Option<Vec<f32>> = values.iter().map(|v| v.parse().ok()).collect();
            match numbers.as_deref() {
                Some([g]) => out.push_str(&format!("{keyword} {g} {g} {g}")),
                Some([r, g, b]) => out.push_str(&format!("{keyword} {r} {g} {b}")),
                _ => {
                    let message = format!("`{keyword}` needs one or three numbers, found '{}'", values.join(" "));
                    return Err((i + 1, message));
                }
            }
        } else {
            out.push_str(line);
        }
        out.push('\n');
    }
    Ok(out)
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
    fn mtl_colours_with_one_number_are_grey_and_bad_ones_are_located() {
        assert_eq!(
            normalize_mtl(b"Kd 0.5\nKs 1 0 0 # red\nNs 8\n"),
            Ok("Kd 0.5 0.5 0.5\nKs 1 0 0\nNs 8\n".into())
        );
        assert_eq!(
            normalize_mtl(b"newmtl a\nKa 0.2 0.3\n"),
            Err((2, "`Ka` needs one or three numbers, found '0.2 0.3'".into()))
        );
        let src = MemorySource::new()
            .with_file("q.obj", QUAD_OBJ)
            .with_file("q.mtl", b"newmtl shiny\nKd 0.2 x 0.1\n");
        let (_, report) = load_mesh_from(&src, Path::new("q.obj")).unwrap();
        assert_eq!(
            report.warnings,
            vec!["q.obj: cannot load its MTL file (q.mtl:2: `Kd` needs one or three numbers, found '0.2 x 0.1'); using the default material".to_owned()]
        );
    }

    #[test]
    fn obj_indices_are_made_absolute_and_checked() {
        let obj = b"v 0 0 0\nv 1 0 0 # comment\nv 0 1 0\nvt 0 0\nf -3/1 -2/-1 -1/1 # tri\ng a#1\n";
        assert_eq!(
            normalize_obj(obj),
            Ok("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\ng a#1\n".into())
        );
        assert_eq!(
            normalize_obj(b"v 0 0 0\nf 1//1 1 1\n"),
            Err((2, "normal index 1 is out of range (0 normals)".into()))
        );
        assert_eq!(
            normalize_obj(b"v 0 0 0\nf 0 1 1\n"),
            Err((2, "index 0 is not valid (OBJ indices start at 1)".into()))
        );
        assert_eq!(
            normalize_obj(b"v 0 0 0\nf -2147483648 1 1\n"),
            Err((2, "vertex index -2147483648 is out of range (1 vertices)".into()))
        );
        assert_eq!(
            normalize_obj(b"f 1/2/3/4\n"),
            Err((1, "'1/2/3/4' has more than three indices".into()))
        );
        assert_eq!(
            normalize_obj(b"v 0 0 0\nf 1 x\n"),
            Err((2, "'x' is not an index".into()))
        );
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
        assert_eq!(
            err,
            Err("bad.obj:3: vertex index 3 is out of range (2 vertices)".to_owned())
        );
    }
}
