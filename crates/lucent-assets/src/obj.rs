//! Wavefront OBJ loading with our own single-pass parser; materials come
//! from MTL files through tobj (see `mtl.rs`).
//!
//! tobj 4.0.5 drops smoothing groups, reports number errors without a line,
//! reads index 0 as "missing" and wraps relative indices that reach before
//! the first vertex, so the geometry is parsed here: `v` (with optional
//! `r g b` colours), `vt`, `vn`, `f` (any polygon size, fan-triangulated in
//! file order so triangle ids are stable; negative indices), `g`/`o`,
//! `usemtl`, `mtllib` and `s`. Every error names the line. Corners are
//! unified into one index per distinct (position, uv, normal) so vertices
//! split only at attribute seams; where the file gives no normal, the
//! smoothing group joins the key and the loader computes area- and angle-weighted
//! normals, so `s off` faces are flat and groups do not blend.

use crate::mtl::{MaterialSet, fallback_material, load_materials};
use crate::{AssetError, AssetSource, LoadReport, Location, MeshPart};
use lucent_geom::{TriMesh, Vec2, Vec3};
use lucent_shading::color::srgb_to_linear;
use std::collections::hash_map::Entry;
use std::collections::{HashMap, HashSet};
use std::path::Path;

/// No index (a corner without uv or normal, or an empty chain).
const NONE: u32 = u32::MAX;
/// The smoothing key of faces under `s off`.
const FLAT: u32 = u32::MAX;

/// One face: its corners in `Parsed::corners`, its line and smoothing
/// group (0 until an `s` statement, `FLAT` under `s off`).
struct Face {
    first: u32,
    n: u32,
    line: u32,
    smoothing: u32,
}

/// A run of faces with one group name and one material.
struct PartRec {
    name: String,
    material: Option<String>,
    faces: std::ops::Range<usize>,
}

/// Everything the file says, with indices made absolute and 0-based.
#[derive(Default)]
struct Parsed {
    positions: Vec<Vec3>,
    colors: Option<Vec<Vec3>>,
    uvs: Vec<Vec2>,
    normals: Vec<Vec3>,
    /// (position, uv, normal), `NONE` where absent.
    corners: Vec<[u32; 3]>,
    faces: Vec<Face>,
    parts: Vec<PartRec>,
    mtllibs: Vec<(usize, String)>,
    /// Statements we do not use (curves, `vp`, ...), with an example.
    ignored: (usize, String),
}

type LineError = (usize, String);

pub(crate) fn load_obj(
    source: &dyn AssetSource,
    path: &Path,
    report: &mut LoadReport,
) -> Result<Vec<MeshPart>, AssetError> {
    let bytes = source.read(path)?;
    let parsed = parse_obj(&bytes).map_err(|(line, message)| AssetError::at(path, Location::Line(line), message))?;
    if parsed.ignored.0 > 0 {
        report.warn(
            path,
            format!(
                "{} statements ignored (unsupported, e.g. '{}')",
                parsed.ignored.0, parsed.ignored.1
            ),
        );
    }
    // Parts keep only the vertices their faces use, so count the others here.
    let mut used = vec![false; parsed.positions.len()];
    for c in &parsed.corners {
        if let Some(u) = used.get_mut(c[0] as usize) {
            *u = true;
        }
    }
    let unused = used.iter().filter(|&&u| !u).count();
    if unused > 0 {
        report.warn(path, format!("{unused} vertices are not used by any face"));
    }
    let uses_materials = parsed.parts.iter().any(|p| p.material.is_some());
    let materials = if uses_materials {
        load_materials(source, path, &parsed.mtllibs, report)
    } else {
        MaterialSet::default()
    };
    let mut unifier = Unifier::new(parsed.positions.len());
    let mut parts = Vec::with_capacity(parsed.parts.len());
    let mut short_faces = 0;
    // In order of first use; the set keeps the check linear when a file
    // names many materials its MTL lacks.
    let mut missing_materials: Vec<&str> = Vec::new();
    let mut missing_seen: HashSet<&str> = HashSet::new();
    for rec in &parsed.parts {
        let built = build_part(&parsed, rec, &mut unifier, &mut short_faces)
            .map_err(|(line, message)| AssetError::at(path, Location::Line(line), message))?;
        let Some((mesh, normals_computed)) = built else {
            continue;
        };
        let material = rec.material.as_ref().map(|name| match materials.get(name) {
            Some(m) => m.clone(),
            None => {
                if missing_seen.insert(name.as_str()) {
                    missing_materials.push(name);
                }
                fallback_material()
            }
        });
        parts.push(MeshPart {
            name: rec.name.clone(),
            mesh,
            material,
            material_name: rec.material.clone(),
            normals_computed,
        });
    }
    if !missing_materials.is_empty() && materials.loaded_any {
        report.warn(
            path,
            format!(
                "material(s) {} not found in its MTL files; shown in magenta",
                name_list(&missing_materials)
            ),
        );
    }
    if short_faces > 0 {
        report.warn(
            path,
            format!("{short_faces} faces have fewer than 3 vertices and give no triangles"),
        );
    }
    Ok(parts)
}

/// At most this many names are listed in one warning.
const LISTED_NAMES: usize = 10;

/// `a, b, c`, or the first [`LISTED_NAMES`] and how many more.
fn name_list(names: &[&str]) -> String {
    let shown = names[..names.len().min(LISTED_NAMES)].join(", ");
    match names.len().checked_sub(LISTED_NAMES) {
        Some(more) if more > 0 => format!("{shown} and {more} more"),
        _ => shown,
    }
}

/// The line without its comment: a `#` at the start of a word begins one
/// (so `usemtl mat#1` keeps its name).
pub(crate) fn strip_comment(line: &str) -> &str {
    let mut prev_is_space = true;
    for (i, c) in line.char_indices() {
        if c == '#' && prev_is_space {
            return line[..i].trim();
        }
        prev_is_space = c.is_whitespace();
    }
    line.trim()
}

/// A coordinate; MSVC's spellings of non-finite values (`1.#IND`, `-1.#INF`)
/// read as what they stand for (see `number.rs`).
fn number(word: &str, line: usize) -> Result<f32, LineError> {
    crate::number::parse_f32_str(word).ok_or_else(|| (line, format!("'{word}' is not a number")))
}

fn parse_obj(bytes: &[u8]) -> Result<Parsed, LineError> {
    let text = String::from_utf8_lossy(bytes);
    let mut p = Parsed::default();
    let mut name = String::new();
    let mut material: Option<String> = None;
    let mut smoothing = 0u32;
    let mut part_start = 0usize;
    let mut values = [0.0f32; 7];
    for (i, raw) in text.split('\n').enumerate() {
        let line_no = i + 1;
        let line = strip_comment(raw);
        let mut words = line.split_ascii_whitespace();
        let Some(keyword) = words.next() else { continue };
        match keyword {
            "v" | "vt" | "vn" => {
                let mut n = 0;
                for w in words {
                    if n == values.len() {
                        return Err((line_no, format!("too many numbers after '{keyword}'")));
                    }
                    values[n] = number(w, line_no)?;
                    n += 1;
                }
                push_vertex_data(&mut p, keyword, &values[..n], line_no)?;
            }
            "f" => {
                let first = p.corners.len();
                for w in words {
                    p.corners.push(parse_corner(w, &p, line_no)?);
                }
                p.faces.push(Face {
                    first: first as u32,
                    n: (p.corners.len() - first) as u32,
                    line: line_no as u32,
                    smoothing,
                });
            }
            "g" | "o" | "usemtl" => {
                let rest = line[keyword.len()..].trim();
                let (new_name, new_material) = if keyword == "usemtl" {
                    (name.clone(), Some(rest.to_owned()))
                } else {
                    (rest.to_owned(), material.clone())
                };
                if new_name != name || new_material != material {
                    close_part(&mut p, &name, &material, &mut part_start);
                    (name, material) = (new_name, new_material);
                }
            }
            "s" => {
                let w = words.next().unwrap_or("off");
                smoothing = match w {
                    "off" => FLAT,
                    "on" => 1,
                    _ => match w.parse::<u32>() {
                        Ok(0) => FLAT,
                        Ok(n) if n != FLAT => n,
                        _ => return Err((line_no, format!("'{w}' is not a smoothing group (a number or 'off')"))),
                    },
                };
            }
            "mtllib" => {
                let rest = line[keyword.len()..].trim();
                if !rest.is_empty() {
                    p.mtllibs.push((line_no, rest.to_owned()));
                }
            }
            "l" | "p" => {}
            other => {
                if p.ignored.0 == 0 {
                    p.ignored.1 = other.chars().take(20).collect();
                }
                p.ignored.0 += 1;
            }
        }
    }
    close_part(&mut p, &name, &material, &mut part_start);
    Ok(p)
}

fn close_part(p: &mut Parsed, name: &str, material: &Option<String>, part_start: &mut usize) {
    if p.faces.len() > *part_start {
        p.parts.push(PartRec {
            name: name.to_owned(),
            material: material.clone(),
            faces: *part_start..p.faces.len(),
        });
    }
    *part_start = p.faces.len();
}

fn push_vertex_data(p: &mut Parsed, keyword: &str, v: &[f32], line: usize) -> Result<(), LineError> {
    match (keyword, v.len()) {
        ("v", 3 | 4) => {
            p.positions.push(Vec3::new(v[0], v[1], v[2]));
            if let Some(c) = &mut p.colors {
                c.push(Vec3::ONE);
            }
        }
        ("v", 6) => {
            let colors = p.colors.get_or_insert_with(|| vec![Vec3::ONE; p.positions.len()]);
            let c = |x: f32| srgb_to_linear(x.clamp(0.0, 1.0));
            colors.push(Vec3::new(c(v[3]), c(v[4]), c(v[5])));
            p.positions.push(Vec3::new(v[0], v[1], v[2]));
        }
        ("vt", 1..=3) => p.uvs.push(Vec2::new(v[0], v.get(1).copied().unwrap_or(0.0))),
        ("vn", 3) => p.normals.push(Vec3::new(v[0], v[1], v[2])),
        _ => {
            let expected = match keyword {
                "v" => "3, 4 or 6",
                "vt" => "1 to 3",
                _ => "3",
            };
            return Err((line, format!("'{keyword}' needs {expected} numbers, found {}", v.len())));
        }
    }
    Ok(())
}

const KINDS: [(&str, &str); 3] = [
    ("vertex", "vertices"),
    ("texture coordinate", "texture coordinates"),
    ("normal", "normals"),
];

/// One face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`, made absolute and
/// 0-based. Positive indices are checked against the totals later (they may
/// refer forward); negative ones against what precedes this line.
fn parse_corner(word: &str, p: &Parsed, line: usize) -> Result<[u32; 3], LineError> {
    let mut out = [NONE; 3];
    let seen = [p.positions.len(), p.uvs.len(), p.normals.len()];
    for (k, part) in word.split('/').enumerate() {
        if k > 2 {
            return Err((line, format!("'{word}' has more than three indices")));
        }
        if part.is_empty() {
            if k == 0 {
                return Err((line, format!("'{word}' has no vertex index")));
            }
            continue;
        }
        let n: i64 = part.parse().map_err(|_| (line, format!("'{part}' is not an index")))?;
        let absolute = match n {
            0 => return Err((line, "index 0 is not valid (OBJ indices start at 1)".to_owned())),
            n if n < 0 => seen[k] as i64 + n,
            n => n - 1,
        };
        if absolute < 0 || absolute >= i64::from(NONE) {
            let (one, many) = KINDS[k];
            return Err((line, format!("{one} index {n} is out of range ({} {many})", seen[k])));
        }
        out[k] = absolute as u32;
    }
    Ok(out)
}

/// Maps (position, uv, normal, smoothing key) to output vertices of one
/// part without hashing in the common case: `first[v]` heads a chain,
/// through `next`, of the output vertices made from position `v`. Real
/// meshes give a position a handful of keys, but a hostile file can give
/// one position a key per corner (`s 1`, `f 1 2 3`, `s 2`, `f 1 2 3`...),
/// which made the chain walk quadratic (40 000 smoothing groups on one
/// triangle: 46 s). So a chain holds at most [`CHAIN_LIMIT`] vertices and
/// a position's further keys go to a hash map.
struct Unifier {
    first: Vec<u32>,
    next: Vec<u32>,
    keys: Vec<(u32, u32, u64)>,
    src: Vec<u32>,
    overflow: HashMap<(u32, (u32, u32, u64)), u32>,
}

/// The longest chain walked before the hash map takes over.
const CHAIN_LIMIT: usize = 16;

impl Unifier {
    fn new(n_positions: usize) -> Self {
        Self {
            first: vec![NONE; n_positions],
            next: Vec::new(),
            keys: Vec::new(),
            src: Vec::new(),
            overflow: HashMap::new(),
        }
    }

    /// The output vertex for a corner, and whether it is new.
    #[inline]
    fn vertex(&mut self, v: u32, key: (u32, u32, u64)) -> (u32, bool) {
        let mut i = self.first[v as usize];
        let mut walked = 0;
        while i != NONE {
            if self.keys[i as usize] == key {
                return (i, false);
            }
            i = self.next[i as usize];
            walked += 1;
        }
        let new = self.keys.len() as u32;
        if walked >= CHAIN_LIMIT {
            match self.overflow.entry((v, key)) {
                Entry::Occupied(e) => return (*e.get(), false),
                Entry::Vacant(e) => {
                    e.insert(new);
                }
            }
            // Not linked into the chain, which stays at the limit.
            self.next.push(NONE);
        } else {
            self.next.push(self.first[v as usize]);
            self.first[v as usize] = new;
        }
        self.keys.push(key);
        self.src.push(v);
        (new, true)
    }

    /// Forgets the part's vertices, touching only what it used.
    fn reset(&mut self) {
        for &v in &self.src {
            self.first[v as usize] = NONE;
        }
        self.next.clear();
        self.keys.clear();
        self.src.clear();
        self.overflow.clear();
    }
}

/// The part's mesh and whether its normals were computed, or `None` when
/// it has no triangles.
fn build_part(
    p: &Parsed,
    rec: &PartRec,
    unifier: &mut Unifier,
    short_faces: &mut usize,
) -> Result<Option<(TriMesh, bool)>, LineError> {
    unifier.reset();
    let faces = &p.faces[rec.faces.clone()];
    let corners_of = |f: &Face| &p.corners[f.first as usize..(f.first + f.n) as usize];
    let has_uvs = faces.iter().any(|f| corners_of(f).iter().any(|c| c[1] != NONE));
    let mut positions = Vec::new();
    let mut uvs = Vec::new();
    let mut normals = Vec::new();
    let mut colors = Vec::new();
    let mut computed = Vec::new();
    let mut indices = Vec::with_capacity(faces.len());
    let mut poly: Vec<u32> = Vec::new();
    for (face_idx, f) in faces.iter().enumerate() {
        let line = f.line as usize;
        if f.n < 3 {
            *short_faces += 1;
            continue;
        }
        poly.clear();
        for c in corners_of(f) {
            let [v, vt, vn] = *c;
            for (k, (idx, total)) in [(v, p.positions.len()), (vt, p.uvs.len()), (vn, p.normals.len())]
                .into_iter()
                .enumerate()
            {
                if idx != NONE && idx as usize >= total {
                    let (one, many) = KINDS[k];
                    return Err((
                        line,
                        format!("{one} index {} is out of range ({total} {many})", idx + 1),
                    ));
                }
            }
            // Without a normal in the file, the smoothing group decides
            // which faces share the vertex (and so its computed normal);
            // under `s off` every face gets a key of its own.
            let smoothing = match (vn, f.smoothing) {
                (NONE, FLAT) => (1u64 << 32) | face_idx as u64,
                (NONE, s) => u64::from(s),
                _ => 0,
            };
            let (out, new) = unifier.vertex(v, (vt, vn, smoothing));
            if new {
                positions.push(p.positions[v as usize]);
                if has_uvs {
                    uvs.push(if vt == NONE { Vec2::ZERO } else { p.uvs[vt as usize] });
                }
                normals.push(if vn == NONE {
                    Vec3::ZERO
                } else {
                    p.normals[vn as usize].normalize_or_zero()
                });
                computed.push(vn == NONE);
                if let Some(c) = &p.colors {
                    colors.push(c[v as usize]);
                }
            }
            poly.push(out);
        }
        indices.extend(poly[1..].windows(2).map(|w| [poly[0], w[0], w[1]]));
    }
    if indices.is_empty() {
        return Ok(None);
    }
    let err = |e: lucent_geom::MeshError| (rec_line(faces), e.to_string());
    let mut mesh = TriMesh::new(positions, indices).map_err(err)?;
    let any_computed = computed.iter().any(|&c| c);
    if any_computed {
        let smooth = mesh.compute_smooth_normals();
        for ((n, s), c) in normals.iter_mut().zip(smooth).zip(&computed) {
            if *c {
                *n = s;
            }
        }
    }
    mesh = mesh.with_normals(normals).map_err(err)?;
    if has_uvs {
        mesh = mesh.with_uvs(uvs).map_err(err)?;
    }
    if p.colors.is_some() {
        mesh = mesh.with_colors(colors).map_err(err)?;
    }
    Ok(Some((mesh, any_computed)))
}

fn rec_line(faces: &[Face]) -> usize {
    faces.first().map_or(0, |f| f.line as usize)
}

#[cfg(test)]
mod tests;
