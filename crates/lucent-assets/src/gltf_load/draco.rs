//! `KHR_draco_mesh_compression`: a primitive whose geometry is a Draco
//! stream in a buffer view, decoded with the draco-core crate. The
//! extension's `attributes` map names, per glTF attribute, the Draco
//! attribute's unique id; the primitive's accessors still give each
//! attribute's count, type and normalisation, and the decoded counts must
//! agree with them. The accessor counts also bound the decode (Draco
//! limits), so a file cannot make the decoder allocate more than it
//! declares; decoder errors are wrapped with the extension's JSON pointer.

use super::data::Buffers;
use draco_core::{DataType, DecodeLimits, DecoderBuffer, Mesh, MeshDecoder};
use gltf::accessor::Accessor;
use std::collections::HashMap;

/// The extension's name, as in `extensionsRequired`.
pub(super) const EXTENSION: &str = "KHR_draco_mesh_compression";

/// At most this many decoded points or faces per primitive, whatever the
/// accessors say (a quarter of a billion: far past any file Lucent can
/// render, and what `u32` indices with room to spare allow).
const MAX_ELEMENTS: u64 = 1 << 28;

/// A decoded Draco primitive.
pub(super) struct DracoPrimitive {
    mesh: Mesh,
    /// Draco unique id per glTF attribute name.
    ids: HashMap<String, u32>,
    /// `"{primitive}/extensions/KHR_draco_mesh_compression"`.
    ptr: String,
}

/// Decodes the Draco stream of `prim` (its extension object is `ext`);
/// `ptr` is the primitive's JSON pointer.
pub(super) fn decode(
    buffers: &Buffers,
    doc_views: &[gltf::buffer::View<'_>],
    prim: &gltf::Primitive<'_>,
    ext: &gltf::json::Value,
    ptr: &str,
) -> Result<DracoPrimitive, String> {
    let ptr = format!("{ptr}/extensions/{EXTENSION}");
    let view_index = ext
        .get("bufferView")
        .and_then(gltf::json::Value::as_u64)
        .ok_or_else(|| format!("{ptr}/bufferView: missing or not an index"))?;
    let view = usize::try_from(view_index)
        .ok()
        .and_then(|i| doc_views.get(i))
        .ok_or_else(|| {
            format!(
                "{ptr}/bufferView: buffer view {view_index} does not exist ({} buffer views)",
                doc_views.len()
            )
        })?;
    let bytes = buffers.view(view).map_err(|e| format!("{ptr}/bufferView: {e}"))?;
    let attributes = ext
        .get("attributes")
        .and_then(gltf::json::Value::as_object)
        .ok_or_else(|| format!("{ptr}/attributes: missing or not an object"))?;
    let mut ids = HashMap::new();
    for (name, id) in attributes {
        let id = id
            .as_u64()
            .and_then(|i| u32::try_from(i).ok())
            .ok_or_else(|| format!("{ptr}/attributes/{name}: not a Draco attribute id"))?;
        ids.insert(name.clone(), id);
    }
    if !matches!(prim.mode(), gltf::mesh::Mode::Triangles) {
        return Err(format!(
            "{ptr}: a Draco-compressed primitive must have mode TRIANGLES (it has {:?})",
            prim.mode()
        ));
    }
    // The accessors declare the decoded sizes; the decode may not exceed
    // them (nor the absolute ceiling), so it allocates no more than that.
    let points = prim
        .get(&gltf::Semantic::Positions)
        .map_or(0, |a| a.count() as u64)
        .min(MAX_ELEMENTS);
    let faces = prim
        .indices()
        .map_or(points, |a| a.count() as u64 / 3)
        .min(MAX_ELEMENTS);
    let limits = DecodeLimits::default()
        .with_max_points(points)
        .with_max_faces(faces)
        // At most four 4-byte components per attribute, and the stream may
        // carry attributes the primitive does not name (joints, weights):
        // room for eight at least.
        .with_max_decoded_bytes(points.saturating_mul(16).saturating_mul(ids.len().max(8) as u64));
    let mut buffer = DecoderBuffer::new(bytes).with_limits(limits);
    let mut mesh = Mesh::new();
    MeshDecoder::new()
        .decode(&mut buffer, &mut mesh)
        .map_err(|e| format!("{ptr}: the Draco stream in buffer view {view_index} does not decode: {e}"))?;
    Ok(DracoPrimitive { mesh, ids, ptr })
}

impl DracoPrimitive {
    /// Whether glTF attribute `name` is stored in the Draco stream (others
    /// are read from their accessors as usual).
    pub(super) fn has(&self, name: &str) -> bool {
        self.ids.contains_key(name)
    }

    /// The decoded points.
    pub(super) fn n_points(&self) -> usize {
        self.mesh.num_points()
    }

    /// Attribute `name` as `f32` components, `n` per element as its accessor
    /// `acc` says; integer data normalised as the accessor says.
    pub(super) fn read_f32(&self, name: &str, acc: &Accessor<'_>, n: usize) -> Result<Vec<f32>, String> {
        let at = |e: String| format!("{}/attributes/{name}: {e}", self.ptr);
        let id = *self
            .ids
            .get(name)
            .ok_or_else(|| at("not in the Draco stream".to_owned()))?;
        let attr = self
            .mesh
            .attribute_by_unique_id(id)
            .ok_or_else(|| at(format!("the Draco stream has no attribute with id {id}")))?;
        let points = self.mesh.num_points();
        if acc.count() != points {
            return Err(at(format!(
                "accessor {} has {} elements but the Draco stream decodes {points} points",
                acc.index(),
                acc.count()
            )));
        }
        if usize::from(attr.num_components()) != n {
            return Err(at(format!(
                "Draco attribute {id} has {} components but accessor {} has {n}",
                attr.num_components(),
                acc.index()
            )));
        }
        let mut v = attr.read_f32s(points, n);
        let scale = match attr.data_type() {
            DataType::Uint8 => Some((255.0, 0.0)),
            DataType::Uint16 => Some((65535.0, 0.0)),
            DataType::Int8 => Some((127.0, -1.0)),
            DataType::Int16 => Some((32767.0, -1.0)),
            _ => None,
        };
        if acc.normalized()
            && let Some((max, min)) = scale
        {
            for x in &mut v {
                *x = (*x / max).max(min);
            }
        }
        Ok(v)
    }

    /// The decoded triangles' corners (three per face), checked against
    /// the points.
    pub(super) fn indices(&self, acc: Option<&Accessor<'_>>) -> Result<Vec<u32>, String> {
        let faces = self.mesh.faces();
        if let Some(acc) = acc
            && acc.count() != faces.len() * 3
        {
            return Err(format!(
                "{}: accessor {} has {} indices but the Draco stream decodes {} triangles",
                self.ptr,
                acc.index(),
                acc.count(),
                faces.len()
            ));
        }
        let n = self.mesh.num_points();
        let mut out = Vec::with_capacity(faces.len() * 3);
        for (f, face) in faces.iter().enumerate() {
            for p in face {
                if p.0 as usize >= n {
                    return Err(format!(
                        "{}: triangle {f} of the Draco stream names point {} of {n}",
                        self.ptr, p.0
                    ));
                }
                out.push(p.0);
            }
        }
        Ok(out)
    }
}
