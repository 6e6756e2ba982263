//! MTL materials through tobj, after a checking pass that gives every
//! problem a line, and their `map_Kd` textures with options.
//!
//! Fields used: Ka (default Kd), Kd, Ks, Ns, Ke (emission), Ni, d or Tr
//! (`d < 1` gives transmission `kt = 1 - d`), illum (3, 5 and 7 set the
//! mirror weight `kr = Ks`), Pr (roughness, clamped to 0..1), and the
//! texture statements map_Kd, map_Ke, norm (or map_Bump/bump, read as a
//! tangent-space normal map), map_Pr and map_Pm, each with `-s` (uv
//! scale), `-o` (uv offset) and `-clamp on|off`; other options are read
//! past with a warning. The PBR extension's `Pm`, `map_Pm` or `map_Pr`
//! make the material glTF's metallic-roughness model (table in
//! docs/mesh-files.md): base colour Kd and map_Kd, metallic Pm (times
//! map_Pm), roughness Pr (times map_Pr; without Pr, the roughness matching
//! Ns), transmission `1 - d`. A missing MTL, material or texture is a warning and shows in
//! magenta, never an error; a texture's warning says which case it is (the
//! file does not exist, is a directory, or is not a usable image).

use crate::{AssetSource, ColorSpace, LoadReport, normalize_path, texture_from_bytes_as};
use lucent_geom::{Vec2, Vec3};
use lucent_shading::{Material, MetallicRoughness, Texture, WrapMode};
use std::collections::{HashMap, HashSet};
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The materials of an OBJ file's MTL libraries, by name.
#[derive(Default)]
pub(crate) struct MaterialSet {
    by_name: HashMap<String, Material>,
    /// Whether at least one MTL file loaded.
    pub loaded_any: bool,
}

impl MaterialSet {
    pub(crate) fn get(&self, name: &str) -> Option<&Material> {
        self.by_name.get(name)
    }
}

/// Loads every `mtllib` of the OBJ at `obj_path`; failures are warnings.
pub(crate) fn load_materials(
    source: &dyn AssetSource,
    obj_path: &Path,
    mtllibs: &[(usize, String)],
    report: &mut LoadReport,
) -> MaterialSet {
    let dir = obj_path.parent().unwrap_or(Path::new(""));
    let mut set = MaterialSet::default();
    if mtllibs.is_empty() {
        report.warn(
            obj_path,
            "uses materials but names no MTL file (mtllib); they show in magenta",
        );
    }
    let mut textures = HashMap::new();
    // Each library once, however often the OBJ names it: otherwise the
    // work is the OBJ's size times the MTL's.
    let mut read: HashSet<PathBuf> = HashSet::new();
    for (line, lib) in mtllibs {
        let mtl_path = normalize_path(&dir.join(lib));
        if !read.insert(mtl_path.clone()) {
            continue;
        }
        let parsed = source.read(&mtl_path).map_err(|e| e.to_string()).and_then(|bytes| {
            let text = normalize_mtl(&bytes).map_err(|(l, m)| format!("{}:{l}: {m}", mtl_path.display()))?;
            tobj::load_mtl_buf(&mut Cursor::new(text.as_bytes()))
                .map(|(materials, _)| materials)
                .map_err(|e| format!("{}: {e}", mtl_path.display()))
        });
        match parsed {
            Ok(materials) => {
                set.loaded_any = true;
                for m in &materials {
                    let material = convert_material(source, m, &mtl_path, &mut textures, report);
                    set.by_name.entry(m.name.clone()).or_insert(material);
                }
            }
            Err(why) => report.warn(
                obj_path,
                format!("line {line}: cannot load its MTL file ({why}); its materials show in magenta"),
            ),
        }
    }
    set
}

/// Rewrites MTL text so tobj reads it safely, and checks what tobj would
/// reject without a line: colour statements (`Ka`, `Kd`, `Ks`, `Ke`, `Tf`)
/// take one number (grey, expanded to three, as the MTL specification says;
/// tobj 4.0.5 panics on fewer than three) or three; `Ns`, `Ni`, `d`, `Tr`, `Pr`
/// take a number, `illum` a small integer, `newmtl` and `map_*` an
/// argument. Problems are `(line, message)`. Inline `#` comments are
/// dropped.
pub(crate) fn normalize_mtl(bytes: &[u8]) -> Result<String, (usize, String)> {
    let text = String::from_utf8_lossy(bytes);
    let mut out = String::with_capacity(text.len() + 64);
    for (i, raw) in text.lines().enumerate() {
        let line = crate::obj::strip_comment(raw);
        let mut words = line.split_whitespace();
        let keyword = words.next().unwrap_or_default();
        let values: Vec<&str> = words.collect();
        let numbers: Option<Vec<f32>> = values.iter().map(|v| v.parse().ok()).collect();
        let bad = |what: &str| Err((i + 1, format!("`{keyword}` needs {what}, found '{}'", values.join(" "))));
        match keyword {
            "Ka" | "Kd" | "Ks" | "Ke" | "Tf" => match numbers.as_deref() {
                Some([g]) => out.push_str(&format!("{keyword} {g} {g} {g}")),
                Some([r, g, b]) => out.push_str(&format!("{keyword} {r} {g} {b}")),
                _ => return bad("one or three numbers"),
            },
            "Ns" | "Ni" | "d" | "Tr" | "Pr" | "Pm" => match numbers.as_deref() {
                Some([_]) => out.push_str(line),
                _ => return bad("one number"),
            },
            "illum" => match values.as_slice() {
                [v] if v.parse::<u8>().is_ok() => out.push_str(line),
                _ => return bad("an integer from 0 to 10"),
            },
            k if k == "newmtl" || k.starts_with("map_") || k == "bump" || k == "norm" => {
                if values.is_empty() {
                    return bad("an argument");
                }
                out.push_str(line);
            }
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    Ok(out)
}

fn convert_material(
    source: &dyn AssetSource,
    m: &tobj::Material,
    mtl_path: &Path,
    textures: &mut HashMap<(PathBuf, ColorSpace), Arc<Texture>>,
    report: &mut LoadReport,
) -> Material {
    let v = |c: Option<[f32; 3]>, default: Vec3| c.map_or(default, Vec3::from).max(Vec3::ZERO);
    let kd = v(m.diffuse, Vec3::splat(0.8));
    let ks = v(m.specular, Vec3::ZERO);
    // `Tr` is transparency, the complement of `d`; `d` wins when both appear.
    let tr = m.unknown_param.get("Tr").and_then(|t| t.parse::<f32>().ok());
    let opacity = m.dissolve.or(tr.map(|t| 1.0 - t)).unwrap_or(1.0);
    // `Pr` (PBR extension): roughness, checked to be a number by
    // `normalize_mtl`; clamped to its range here.
    let pr = m
        .unknown_param
        .get("Pr")
        .and_then(|t| t.parse::<f32>().ok())
        .map(|r| r.clamp(0.0, 1.0));
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
        kt: Vec3::splat((1.0 - opacity).clamp(0.0, 1.0)),
        ior: m.optical_density.filter(|n| n.is_finite() && *n > 0.0).unwrap_or(1.0),
        roughness: pr.unwrap_or(0.0),
        emission: v(m.emissive, Vec3::ZERO),
        ..Material::default()
    };
    let mut maps = Maps {
        source,
        mtl_path,
        material: &m.name,
        textures,
        report,
    };
    if let Some(spec) = &m.diffuse_texture {
        material.diffuse_map = maps.load("map_Kd", spec, ColorSpace::Srgb);
    }
    let param = |key: &str| m.unknown_param.get(key).map(String::as_str);
    let normal = param("norm").or(m.normal_texture.as_deref());
    if let Some(spec) = normal {
        material.normal_map = maps.load("norm", spec, ColorSpace::Linear);
    }
    if let Some(spec) = param("map_Ke") {
        material.emission_map = maps.load("map_Ke", spec, ColorSpace::Srgb);
        // A map with no `Ke` to scale would show nothing: it emits as it is.
        if material.emission == Vec3::ZERO {
            material.emission = Vec3::ONE;
        }
    }
    // The PBR extension: `Pm` or a metallic or roughness map make the
    // material glTF's metallic-roughness model.
    let pm = param("Pm")
        .and_then(|t| t.parse::<f32>().ok())
        .map(|x| x.clamp(0.0, 1.0));
    let (map_pm, map_pr) = (param("map_Pm"), param("map_Pr"));
    if pm.is_some() || map_pm.is_some() || map_pr.is_some() {
        // Without `Pr`, the roughness whose GGX lobe is as wide as the
        // Phong lobe of `Ns` (the inverse of the Whitted mapping).
        let roughness = pr.unwrap_or_else(|| (2.0 / (material.shininess + 2.0)).sqrt().sqrt().clamp(0.0, 1.0));
        let params = MetallicRoughness {
            base_color: kd,
            metallic: pm.unwrap_or(if map_pm.is_some() { 1.0 } else { 0.0 }),
            roughness: if map_pr.is_some() && pr.is_none() {
                1.0
            } else {
                roughness
            },
            metallic_map: map_pm.and_then(|spec| maps.load("map_Pm", spec, ColorSpace::Linear)),
            roughness_map: map_pr.and_then(|spec| maps.load("map_Pr", spec, ColorSpace::Linear)),
            transmission: (1.0 - opacity).clamp(0.0, 1.0),
        };
        let pbr = Material::metallic_roughness(params);
        material = Material {
            ior: material.ior,
            emission: material.emission,
            diffuse_map: material.diffuse_map,
            normal_map: material.normal_map,
            emission_map: material.emission_map,
            ..pbr
        };
    }
    material
}

/// Loads an MTL statement's texture once per file and colour space; a
/// texture that cannot be loaded is a warning and a checkerboard.
struct Maps<'a, 'r> {
    source: &'a dyn AssetSource,
    mtl_path: &'a Path,
    material: &'a str,
    textures: &'a mut HashMap<(PathBuf, ColorSpace), Arc<Texture>>,
    report: &'r mut LoadReport,
}

impl Maps<'_, '_> {
    fn load(&mut self, statement: &str, spec: &str, space: ColorSpace) -> Option<Arc<Texture>> {
        let (mtl_path, name) = (self.mtl_path, self.material);
        let map = parse_map(spec);
        if map.file.is_empty() {
            self.report.warn(
                mtl_path,
                format!("material '{name}': {statement} names no file; it is ignored"),
            );
            return None;
        }
        for option in &map.ignored {
            self.report.warn(
                mtl_path,
                format!("material '{name}': {statement} option {option} is not supported and is ignored"),
            );
        }
        let mtl_dir = mtl_path.parent().unwrap_or(Path::new(""));
        let tex_path = normalize_path(&mtl_dir.join(&map.file));
        let key = (tex_path, space);
        let base = match self.textures.get(&key) {
            Some(t) => t.clone(),
            None => {
                let loaded = self
                    .source
                    .read(&key.0)
                    .and_then(|bytes| texture_from_bytes_as(&bytes, &key.0, space));
                let t = match loaded {
                    Ok(t) => Arc::new(t),
                    Err(e) => {
                        self.report.warn(
                            mtl_path,
                            format!(
                                "material '{name}': texture '{}': {}; it shows a checkerboard instead",
                                map.file,
                                crate::image_io::texture_problem(&e)
                            ),
                        );
                        Arc::new(missing_texture())
                    }
                };
                self.textures.insert(key, t.clone());
                t
            }
        };
        let wrap = if map.clamp { WrapMode::Clamp } else { WrapMode::Repeat };
        Some(
            if map.scale == Vec2::ONE && map.offset == Vec2::ZERO && wrap == base.wrap && wrap == base.wrap_v {
                base
            } else {
                let mut t = (*base).clone();
                t.set_wrap(wrap);
                t.uv_scale = map.scale;
                t.uv_offset = map.offset;
                Arc::new(t)
            },
        )
    }
}

/// A `map_Kd` statement's options and file name.
#[derive(Debug, PartialEq)]
pub(crate) struct MapSpec {
    pub file: String,
    pub scale: Vec2,
    pub offset: Vec2,
    pub clamp: bool,
    /// Options read past, as written (e.g. `-bm 0.5`).
    pub ignored: Vec<String>,
}

/// Splits `-s 2 2 1 -clamp on tex file.png` into options and the file
/// name (the rest of the line, which may contain spaces).
pub(crate) fn parse_map(spec: &str) -> MapSpec {
    let words: Vec<&str> = spec.split_whitespace().collect();
    let mut map = MapSpec {
        file: String::new(),
        scale: Vec2::ONE,
        offset: Vec2::ZERO,
        clamp: false,
        ignored: Vec::new(),
    };
    let mut i = 0;
    // Numbers following an option, at most `max`.
    let numbers = |i: &mut usize, max: usize| {
        let mut out = Vec::new();
        while out.len() < max && *i + 1 < words.len() {
            match words[*i + 1].parse::<f32>() {
                Ok(x) => {
                    out.push(x);
                    *i += 1;
                }
                Err(_) => break,
            }
        }
        out
    };
    while i < words.len() && words[i].starts_with('-') && words[i].len() > 1 {
        let option = words[i];
        match option {
            "-s" | "-o" => {
                let n = numbers(&mut i, 3);
                let uv = Vec2::new(
                    n.first().copied().unwrap_or(if option == "-s" { 1.0 } else { 0.0 }),
                    n.get(1).copied().unwrap_or(if option == "-s" { 1.0 } else { 0.0 }),
                );
                if option == "-s" {
                    map.scale = uv;
                } else {
                    map.offset = uv;
                }
            }
            "-clamp" => {
                if let Some(v) = words.get(i + 1) {
                    map.clamp = *v == "on";
                    i += 1;
                }
            }
            _ => {
                // Arities from the MTL specification; unknown options take
                // the numbers and on/off words that follow.
                let start = i;
                match option {
                    "-blendu" | "-blendv" | "-cc" | "-imfchan" | "-type" => i += 1,
                    "-mm" => {
                        numbers(&mut i, 2);
                    }
                    "-t" => {
                        numbers(&mut i, 3);
                    }
                    _ => {
                        numbers(&mut i, 3);
                        if matches!(words.get(i + 1), Some(&"on" | &"off")) {
                            i += 1;
                        }
                    }
                }
                let end = (i + 1).min(words.len());
                map.ignored.push(words[start..end].join(" "));
            }
        }
        i += 1;
    }
    map.file = words.get(i..).unwrap_or_default().join(" ");
    map
}

/// The material of a part whose `usemtl` could not be resolved: plain
/// magenta, so the problem is visible.
pub(crate) fn fallback_material() -> Material {
    let magenta = Vec3::new(1.0, 0.0, 1.0);
    Material {
        ka: magenta,
        kd: magenta,
        ..Material::default()
    }
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
