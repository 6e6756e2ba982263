//! PLY loading: our own header parser (`ply_header.rs`) and body reader
//! (`ply_body.rs`), which streams the body straight into typed buffers.
//!
//! ply-rs, which read the header until issue 21, refused headers real
//! exporters write (CR-only line ends, padded lines, bare banner lines)
//! and named its own line count in errors; its body reader allocated a key
//! per value and held bun_zipper.ply to about 60 MB/s. The body reader
//! here works on a fixed buffer with no allocation per element. Supported:
//! ASCII and binary (both endians), every scalar type and alias, positions,
//! optional normals (`nx ny nz`), texture coordinates (`u v`, `s t` or
//! `texture_u texture_v`), colours (`red green blue`, integer or float,
//! alpha ignored, taken as sRGB), faces as `vertex_indices` or
//! `vertex_index` lists of any integer types, fan-triangulated in file
//! order. Other elements and properties are read past; elements may come in
//! any order.

use crate::ply_body::{Body, Buffers, Input, Ty, read_body};
use crate::ply_header::{ElementDef, Encoding, Header, PropertyType, find_header_end, parse_header};
use crate::{AssetError, AssetSource, LoadReport, Location, MeshPart};
use lucent_geom::TriMesh;
use std::path::Path;

/// Where a value of the vertex element goes (index into a record).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Slot {
    X,
    Y,
    Z,
    Nx,
    Ny,
    Nz,
    U,
    V,
    R,
    G,
    B,
}

pub(crate) const N_SLOTS: usize = 11;

/// How to read one property of an element.
#[derive(Clone, Debug)]
pub(crate) enum PropPlan {
    /// A scalar; kept in `slot` times `scale`, or skipped when `slot` is
    /// `None`.
    Scalar { ty: Ty, slot: Option<Slot>, scale: f32 },
    /// A list; `indices` marks the face's vertex list, others are skipped.
    List { count: Ty, item: Ty, indices: bool },
}

/// What an element is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Vertex,
    Face,
    Other,
}

/// How to read one element of the body.
#[derive(Clone, Debug)]
pub(crate) struct ElementPlan {
    pub name: String,
    pub count: usize,
    pub kind: Kind,
    pub props: Vec<PropPlan>,
}

/// Which optional vertex attributes the file gives.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Attributes {
    pub normals: bool,
    pub uvs: bool,
    pub colors: bool,
}

pub(crate) fn load_ply(source: &dyn AssetSource, path: &Path, report: &mut LoadReport) -> Result<MeshPart, AssetError> {
    let file = source.open(path)?;
    let mut input = Input::new(file.reader);
    let span = find_header_end(&mut input, path)?;
    let header = parse_header(&input.available()[..span.len], path, report)?;
    let payload_len = file.len.saturating_sub(span.len as u64);
    check_counts_fit(&header, payload_len)
        .map_err(|(line, message)| AssetError::at(path, Location::Line(line), message))?;
    let (plans, attributes) = plan(&header, path, report)?;
    input.consume(span.len);
    let n_vertices = plans.iter().find(|p| p.kind == Kind::Vertex).map_or(0, |p| p.count);
    let mut buffers = Buffers::with_capacity(&plans, attributes);
    let body = Body {
        plans: &plans,
        encoding: header.encoding,
        n_vertices,
        header_lines: span.lines,
        line_end: span.body_line_end,
        file_len: file.len,
    };
    read_body(&mut input, &body, &mut buffers).map_err(|(location, message)| AssetError::Format {
        path: path.to_owned(),
        location,
        message,
    })?;
    if buffers.short_faces > 0 {
        report.warn(
            path,
            format!(
                "{} faces have fewer than 3 vertices and give no triangles",
                buffers.short_faces
            ),
        );
    }
    let mesh = into_mesh(buffers).map_err(|e| AssetError::format(path, e.to_string()))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(MeshPart {
        name,
        mesh,
        material: None,
        material_name: None,
        normals_computed: false,
    })
}

fn into_mesh(b: Buffers) -> Result<TriMesh, lucent_geom::MeshError> {
    let mut mesh = TriMesh::new(b.positions, b.indices)?;
    if let Some(n) = b.normals {
        mesh = mesh.with_normals(n)?;
    }
    if let Some(uv) = b.uvs {
        mesh = mesh.with_uvs(uv)?;
    }
    if let Some(c) = b.colors {
        mesh = mesh.with_colors(c)?;
    }
    Ok(mesh)
}

/// Chooses what to read from each element: the vertex attributes come in
/// complete groups only (an `nx` without `ny`/`nz` is ignored).
fn plan(header: &Header, path: &Path, report: &mut LoadReport) -> Result<(Vec<ElementPlan>, Attributes), AssetError> {
    let mut plans = Vec::with_capacity(header.elements.len());
    let mut attributes = Attributes::default();
    let mut saw_vertex = false;
    for def in &header.elements {
        let kind = match def.name.as_str() {
            "vertex" => Kind::Vertex,
            "face" => Kind::Face,
            _ => Kind::Other,
        };
        let props = match kind {
            Kind::Vertex => {
                saw_vertex = true;
                let (props, attrs) = plan_vertex(def).map_err(|m| AssetError::at(path, Location::Line(def.line), m))?;
                attributes = attrs;
                props
            }
            Kind::Face => plan_face(def, path, report)?,
            Kind::Other => {
                if def.name == "tristrips" {
                    report.warn(
                        path,
                        "triangle strips (element 'tristrips') are not supported and are skipped",
                    );
                }
                def.properties.iter().map(|p| skip_plan(p.ty)).collect()
            }
        };
        plans.push(ElementPlan {
            name: def.name.clone(),
            count: def.count,
            kind,
            props,
        });
    }
    if !saw_vertex {
        return Err(AssetError::at(
            path,
            Location::Line(header.end_line),
            "the header declares no `vertex` element",
        ));
    }
    Ok((plans, attributes))
}

fn skip_plan(t: PropertyType) -> PropPlan {
    match t {
        PropertyType::Scalar(ty) => PropPlan::Scalar {
            ty,
            slot: None,
            scale: 1.0,
        },
        PropertyType::List(count, item) => PropPlan::List {
            count,
            item,
            indices: false,
        },
    }
}

const NORMALS: &[&[&str; 3]] = &[&["nx", "ny", "nz"], &["normal_x", "normal_y", "normal_z"]];
const UVS: &[&[&str; 2]] = &[
    &["u", "v"],
    &["s", "t"],
    &["texture_u", "texture_v"],
    &["texture_s", "texture_t"],
];
const COLORS: &[&[&str; 3]] = &[
    &["red", "green", "blue"],
    &["r", "g", "b"],
    &["diffuse_red", "diffuse_green", "diffuse_blue"],
];

/// The first name group whose properties are all scalars of the element.
fn group<'n, const N: usize>(def: &ElementDef, groups: &[&'n [&'n str; N]]) -> Option<&'n [&'n str; N]> {
    groups.iter().copied().find(|g| {
        g.iter()
            .all(|n| def.property(n).is_some_and(|p| matches!(p.ty, PropertyType::Scalar(_))))
    })
}

fn plan_vertex(def: &ElementDef) -> Result<(Vec<PropPlan>, Attributes), String> {
    let Some(xyz) = group(def, &[&["x", "y", "z"]]) else {
        return Err("the vertex element lacks scalar x, y or z properties".to_owned());
    };
    let normals = group(def, NORMALS);
    let uvs = group(def, UVS);
    let colors = group(def, COLORS);
    let slot_of = |name: &str| {
        let find = |g: Option<&[&str]>, slots: &[Slot]| g?.iter().position(|n| *n == name).map(|i| slots[i]);
        find(Some(xyz), &[Slot::X, Slot::Y, Slot::Z])
            .or_else(|| find(normals.map(|g| &g[..]), &[Slot::Nx, Slot::Ny, Slot::Nz]))
            .or_else(|| find(uvs.map(|g| &g[..]), &[Slot::U, Slot::V]))
            .or_else(|| find(colors.map(|g| &g[..]), &[Slot::R, Slot::G, Slot::B]))
    };
    let props = def
        .properties
        .iter()
        .map(|p| match p.ty {
            PropertyType::Scalar(ty) => {
                let slot = slot_of(&p.name);
                let scale = match slot {
                    Some(Slot::R | Slot::G | Slot::B) => color_scale(ty),
                    _ => 1.0,
                };
                PropPlan::Scalar { ty, slot, scale }
            }
            list => skip_plan(list),
        })
        .collect();
    let attributes = Attributes {
        normals: normals.is_some(),
        uvs: uvs.is_some(),
        colors: colors.is_some(),
    };
    Ok((props, attributes))
}

/// Integer colour channels are fractions of their type's maximum.
fn color_scale(ty: Ty) -> f32 {
    match ty {
        Ty::U8 => 1.0 / 255.0,
        Ty::I8 => 1.0 / 127.0,
        Ty::U16 => 1.0 / 65535.0,
        Ty::I16 => 1.0 / 32767.0,
        Ty::U32 => 1.0 / 4_294_967_295.0,
        Ty::I32 => 1.0 / 2_147_483_647.0,
        Ty::F32 | Ty::F64 => 1.0,
    }
}

fn plan_face(def: &ElementDef, path: &Path, report: &mut LoadReport) -> Result<Vec<PropPlan>, AssetError> {
    let index_list = ["vertex_indices", "vertex_index"]
        .into_iter()
        .find(|n| def.property(n).is_some());
    if index_list.is_none() {
        report.warn(
            path,
            "the face element has no vertex_indices list; the mesh has no triangles",
        );
    }
    def.properties
        .iter()
        .map(|p| match p.ty {
            PropertyType::List(count, item) if Some(p.name.as_str()) == index_list => {
                if !count.is_integer() || !item.is_integer() {
                    return Err(AssetError::at(
                        path,
                        Location::Line(p.line),
                        format!("face list '{}' must have integer count and index types", p.name),
                    ));
                }
                Ok(PropPlan::List {
                    count,
                    item,
                    indices: true,
                })
            }
            PropertyType::Scalar(_) if Some(p.name.as_str()) == index_list => Err(AssetError::at(
                path,
                Location::Line(p.line),
                format!("face property '{}' must be a list", p.name),
            )),
            t => Ok(skip_plan(t)),
        })
        .collect()
}

/// Fails when the elements' counts cannot fit in the bytes after the
/// header (each ASCII entry takes at least two bytes per property, a digit
/// and a separator; each binary one at least the sum of its scalar sizes), so absurd
/// counts are refused before anything is read or allocated. Names the first
/// element that runs past the end, with its line.
fn check_counts_fit(header: &Header, payload_len: u64) -> Result<(), (usize, String)> {
    let mut needed: u128 = 0;
    for def in &header.elements {
        let per_element: u128 = match header.encoding {
            Encoding::Ascii => 2 * def.properties.len().max(1) as u128,
            _ => def
                .properties
                .iter()
                .map(|p| match p.ty {
                    PropertyType::Scalar(t) | PropertyType::List(t, _) => t.size() as u128,
                })
                .sum(),
        };
        let element_bytes = per_element * def.count as u128;
        let remaining = (payload_len as u128).saturating_sub(needed);
        if element_bytes > remaining {
            let after = if needed > 0 { " and the elements before it" } else { "" };
            return Err((
                def.line,
                format!(
                    "element '{}' claims {} entries, which need at least {element_bytes} bytes, but only {remaining} follow the header{after}",
                    def.name, def.count
                ),
            ));
        }
        needed += element_bytes;
    }
    Ok(())
}

#[cfg(test)]
mod exporter_quirks;
#[cfg(test)]
mod tests;
