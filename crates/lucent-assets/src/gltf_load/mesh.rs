//! glTF primitives to triangle meshes: triangle lists, strips and fans,
//! indexed or not; positions, normals, tangents, texture coordinates (`v`
//! flipped to Lucent's `v` up) and vertex colours; MikkTSpace tangents
//! where a normal-mapped primitive has none. A primitive with
//! `KHR_draco_mesh_compression` takes its indices and compressed
//! attributes from the decoded Draco stream instead of its accessors.

use super::data::Buffers;
use super::draco;
use gltf::Semantic;
use gltf::mesh::Mode;
use lucent_geom::{TriMesh, Vec2, Vec3, Vec4};
use std::collections::HashMap;

/// What a primitive needs besides its geometry.
pub(super) struct PrimitiveNeeds {
    /// Which `TEXCOORD_n` its material's textures read.
    pub(super) uv_set: u32,
    /// Its material has a normal map: compute tangents when the file has
    /// none.
    pub(super) tangents: bool,
}

/// The triangles of one primitive, or `Ok(None)` for a mode that has no
/// triangles (points, lines). Errors are messages prefixed with the JSON
/// pointer of the offending part.
pub(super) fn primitive_mesh(
    buffers: &Buffers,
    views: &[gltf::buffer::View<'_>],
    prim: &gltf::Primitive<'_>,
    ptr: &str,
    needs: &PrimitiveNeeds,
    warnings: &mut Vec<String>,
) -> Result<Option<TriMesh>, String> {
    if !matches!(prim.mode(), Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
        return Ok(None);
    }
    let attr = |s: Semantic| prim.get(&s);
    let at = |name: &str, e: String| format!("{ptr}/attributes/{name}: {e}");
    let draco = match prim.extension_value(draco::EXTENSION) {
        Some(ext) => Some(draco::decode(buffers, views, prim, ext, ptr)?),
        None => None,
    };
    // An attribute's components: from the Draco stream when it holds it,
    // else from its accessor.
    let read = |acc: &gltf::Accessor<'_>, name: &str| -> Result<(Vec<f32>, usize), String> {
        match &draco {
            Some(d) if d.has(name) => {
                let n = match acc.dimensions() {
                    gltf::accessor::Dimensions::Scalar => 1,
                    gltf::accessor::Dimensions::Vec2 => 2,
                    gltf::accessor::Dimensions::Vec3 => 3,
                    gltf::accessor::Dimensions::Vec4 => 4,
                    d => {
                        return Err(at(
                            name,
                            format!("accessor {} has type {d:?}, which is not vertex data", acc.index()),
                        ));
                    }
                };
                Ok((d.read_f32(name, acc, n)?, n))
            }
            _ => buffers.read_f32(acc).map_err(|e| at(name, e)),
        }
    };
    let pos_acc = attr(Semantic::Positions).ok_or_else(|| format!("{ptr}/attributes: has no POSITION"))?;
    let (pos, n) = read(&pos_acc, "POSITION")?;
    if n != 3 {
        return Err(at("POSITION", format!("accessor {} is not VEC3", pos_acc.index())));
    }
    let positions: Vec<Vec3> = pos.chunks_exact(3).map(Vec3::from_slice).collect();
    let n_vertices = positions.len();
    let vec_attr = |s: Semantic, name: &str, want: &[usize]| -> Result<Option<(Vec<f32>, usize)>, String> {
        let Some(acc) = attr(s) else { return Ok(None) };
        let (v, n) = read(&acc, name)?;
        if !want.contains(&n) {
            return Err(at(name, format!("accessor {} has {n} components", acc.index())));
        }
        if v.len() / n != n_vertices {
            return Err(at(
                name,
                format!(
                    "accessor {} has {} elements but POSITION has {n_vertices}",
                    acc.index(),
                    v.len() / n
                ),
            ));
        }
        Ok(Some((v, n)))
    };
    let normals = vec_attr(Semantic::Normals, "NORMAL", &[3])?;
    let tangents = vec_attr(Semantic::Tangents, "TANGENT", &[4])?;
    let uv_name = format!("TEXCOORD_{}", needs.uv_set);
    let uvs = vec_attr(Semantic::TexCoords(needs.uv_set), &uv_name, &[2])?;
    let colors = vec_attr(Semantic::Colors(0), "COLOR_0", &[3, 4])?;

    // Corner indices in file order, then triangles by mode.
    let corners: Vec<u32> = match (prim.indices(), &draco) {
        (acc, Some(d)) => {
            if d.n_points() != n_vertices {
                return Err(at(
                    "POSITION",
                    format!(
                        "accessor {} has {n_vertices} elements but the Draco stream decodes {} points",
                        pos_acc.index(),
                        d.n_points()
                    ),
                ));
            }
            d.indices(acc.as_ref())?
        }
        (Some(acc), None) => {
            let idx = buffers.read_u32(&acc).map_err(|e| format!("{ptr}/indices: {e}"))?;
            if let Some((k, &bad)) = idx.iter().enumerate().find(|&(_, &i)| i as usize >= n_vertices) {
                return Err(format!(
                    "{ptr}/indices: index {bad} at position {k} of accessor {} is past the {n_vertices} vertices",
                    acc.index()
                ));
            }
            idx
        }
        (None, None) => (0..u32::try_from(n_vertices).map_err(|_| format!("{ptr}: too many vertices"))?).collect(),
    };
    let triangles = assemble(&corners, prim.mode());
    if !corners.len().is_multiple_of(3) && prim.mode() == Mode::Triangles {
        warnings.push(format!(
            "{ptr}: {} indices are not a multiple of 3; the last {} are ignored",
            corners.len(),
            corners.len() % 3
        ));
    }
    let err = |e: lucent_geom::MeshError| format!("{ptr}: {e}");
    let mut mesh = TriMesh::new(positions, triangles).map_err(err)?;
    if let Some((v, _)) = normals {
        mesh = mesh
            .with_normals(v.chunks_exact(3).map(Vec3::from_slice).collect())
            .map_err(err)?;
    }
    if let Some((v, _)) = &uvs {
        // glTF's v grows downwards from the image's top; Lucent's upwards.
        mesh = mesh
            .with_uvs(v.chunks_exact(2).map(|c| Vec2::new(c[0], 1.0 - c[1])).collect())
            .map_err(err)?;
    }
    if let Some((v, n)) = colors {
        // Alpha in COLOR_0 is not used.
        mesh = mesh
            .with_colors(v.chunks_exact(n).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
            .map_err(err)?;
    }
    if let Some((v, _)) = tangents {
        mesh = mesh
            .with_tangents(v.chunks_exact(4).map(Vec4::from_slice).collect())
            .map_err(err)?;
    }
    let (bad_vertices, bad_triangles) = mesh.reject_non_finite_vertices();
    if bad_vertices > 0 {
        warnings.push(format!(
            "{ptr}/attributes/POSITION: {bad_vertices} non-finite vertices rejected with the {bad_triangles} triangles that use them"
        ));
    }
    let mut mesh = mesh.with_smooth_normals_if_missing();
    if needs.tangents && mesh.tangents().is_none() && mesh.uvs().is_some() {
        mesh = with_mikktspace_tangents(&mesh).map_err(err)?;
    }
    Ok(Some(mesh))
}

/// Triangles from corner indices: a list, a strip (every other triangle
/// flipped to keep the winding) or a fan.
fn assemble(c: &[u32], mode: Mode) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => (2..c.len())
            .map(|i| {
                if i % 2 == 0 {
                    [c[i - 2], c[i - 1], c[i]]
                } else {
                    [c[i - 1], c[i - 2], c[i]]
                }
            })
            .collect(),
        Mode::TriangleFan => (2..c.len()).map(|i| [c[0], c[i - 1], c[i]]).collect(),
        _ => c.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
    }
}

/// Corner-wise geometry for the `mikktspace` crate.
struct Corners<'m> {
    mesh: &'m TriMesh,
    tangents: Vec<Vec4>,
}

impl mikktspace::Geometry for Corners<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.n_triangles()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        let i = self.mesh.indices()[face][vert] as usize;
        let p = self.mesh.positions()[i];
        // Rejected (NaN) vertices read as the origin; their triangles are
        // never drawn.
        if p.is_finite() { p.into() } else { [0.0; 3] }
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        let i = self.mesh.indices()[face][vert] as usize;
        self.mesh.normals().map_or([0.0, 0.0, 1.0], |n| n[i].into())
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let i = self.mesh.indices()[face][vert] as usize;
        self.mesh.uvs().map_or([0.0; 2], |uv| uv[i].into())
    }
    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        if let Some(t) = self.tangents.get_mut(face * 3 + vert) {
            *t = Vec4::from(tangent);
        }
    }
}

/// The mesh with MikkTSpace tangents (what glTF normal maps are baked
/// against; computed on Lucent's `v`-up coordinates, so the bitangent
/// points up the image, the green channel's direction). Corners of one
/// vertex that get different tangents (UV seams, mirrored halves) become
/// separate vertices.
fn with_mikktspace_tangents(mesh: &TriMesh) -> Result<TriMesh, lucent_geom::MeshError> {
    let mut g = Corners {
        mesh,
        tangents: vec![Vec4::new(1.0, 0.0, 0.0, 1.0); mesh.n_triangles() * 3],
    };
    if !mikktspace::generate_tangents(&mut g) {
        return Ok(mesh.clone());
    }
    let tangents = g.tangents;
    // Re-weld: one vertex per distinct (file vertex, tangent).
    let mut key_to_new: HashMap<(u32, [u32; 4]), u32> = HashMap::new();
    let mut source_of: Vec<u32> = Vec::new();
    let mut new_tangents: Vec<Vec4> = Vec::new();
    let mut triangles = Vec::with_capacity(mesh.n_triangles());
    for (f, tri) in mesh.indices().iter().enumerate() {
        let mut out = [0u32; 3];
        for (k, &v) in tri.iter().enumerate() {
            let t = tangents[f * 3 + k];
            let t = if t.is_finite() {
                t
            } else {
                Vec4::new(1.0, 0.0, 0.0, 1.0)
            };
            let key = (v, t.to_array().map(f32::to_bits));
            out[k] = *key_to_new.entry(key).or_insert_with(|| {
                source_of.push(v);
                new_tangents.push(t);
                (source_of.len() - 1) as u32
            });
        }
        triangles.push(out);
    }
    let pick = |src: &[Vec3]| source_of.iter().map(|&v| src[v as usize]).collect::<Vec<_>>();
    let mut m = TriMesh::new(pick(mesh.positions()), triangles)?;
    if let Some(n) = mesh.normals() {
        m = m.with_normals(pick(n))?;
    }
    if let Some(uv) = mesh.uvs() {
        m = m.with_uvs(source_of.iter().map(|&v| uv[v as usize]).collect())?;
    }
    if let Some(c) = mesh.colors() {
        m = m.with_colors(pick(c))?;
    }
    m.with_tangents(new_tangents)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strips_and_fans_keep_their_winding() {
        assert_eq!(assemble(&[0, 1, 2, 3], Mode::TriangleStrip), vec![[0, 1, 2], [2, 1, 3]]);
        assert_eq!(assemble(&[0, 1, 2, 3], Mode::TriangleFan), vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(assemble(&[0, 1, 2, 3], Mode::Triangles), vec![[0, 1, 2]]);
        assert!(assemble(&[0, 1], Mode::TriangleStrip).is_empty());
    }

    #[test]
    fn mikktspace_tangents_follow_u_and_the_bitangent_follows_v() {
        // A quad in the xy plane facing +z, u along +x, v along +y.
        let m = TriMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .and_then(|m| m.with_normals(vec![Vec3::Z; 4]))
        .and_then(|m| m.with_uvs(vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y]))
        .and_then(|m| with_mikktspace_tangents(&m));
        let m = m.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.n_vertices(), 4, "a flat quad needs no split");
        for t in m.tangents().unwrap_or_default() {
            assert!(t.truncate().abs_diff_eq(Vec3::X, 1e-5), "{t}");
            // Bitangent w * (n x t) = +y, the direction of increasing v.
            assert!((t.w * Vec3::Z.cross(t.truncate())).abs_diff_eq(Vec3::Y, 1e-5));
        }
    }
}
