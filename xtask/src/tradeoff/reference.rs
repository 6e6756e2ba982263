//! The converged reference of a scene: rendered once by the path tracer,
//! cached under `target/tradeoff/cache/`, with an estimate of its own noise.
//!
//! Cache key: a 64-bit FNV-1a hash over, in order,
//! 1. the scene file's bytes;
//! 2. the bytes of every file the scene names (any string in the TOML that
//!    is the path of an existing file, relative to the scene) and of every
//!    file beside it in its folder (an OBJ's MTL and textures);
//! 3. the reference settings, as text ([`RefSettings::describe`]);
//! 4. the renderer's code: every file under `src/` of lucent-geom,
//!    lucent-accel, lucent-shading, lucent-scene, lucent-assets and
//!    lucent-render except `quality.rs` (the presets, which the reference
//!    does not use), their `Cargo.toml`s, the workspace `Cargo.lock` and
//!    this file (how the reference is rendered), in path order, each
//!    preceded by its path.
//!
//! Changing any of these renders the reference again; the compiler version
//! and profile are not part of the key (the output is deterministic across
//! them as far as we have seen; delete the cache folder to force a render).
//! The cache holds `STEM-KEY.exr` (linear radiance) and `STEM-KEY.txt`
//! (what went into it and the measured noise).

use super::imaging::Image;
use lucent_geom::{DVec3, Vec3};
use lucent_render::{Film, Integrator, RenderScene, RenderSettings, render_samples};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Seed of the reference's sample streams: not the presets' (the scene's
/// seed, 0 in ours), so the reference's noise is independent of theirs.
pub const REF_SEED: u64 = 0x7eff_5eed;

/// The crates whose code decides the pixels.
const RENDER_CRATES: [&str; 6] = [
    "lucent-geom",
    "lucent-accel",
    "lucent-shading",
    "lucent-scene",
    "lucent-assets",
    "lucent-render",
];

/// How the reference is rendered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefSettings {
    /// Size (the scene's).
    pub width: u32,
    /// Size (the scene's).
    pub height: u32,
    /// Samples per pixel in all.
    pub spp: u32,
    /// Rendered as this many independent batches of `spp / chunks` samples;
    /// their spread estimates the reference's noise.
    pub chunks: u32,
    /// Path length limit (Mitsuba's meaning).
    pub max_depth: u32,
    /// Russian roulette start.
    pub rr_depth: u32,
}

impl RefSettings {
    /// One line, also hashed into the cache key.
    pub fn describe(&self) -> String {
        format!(
            "path tracer, {}x{}, {} spp in {} batches, max depth {}, roulette from bounce {}, seed {REF_SEED:#x}",
            self.width, self.height, self.spp, self.chunks, self.max_depth, self.rr_depth
        )
    }

    /// Render settings of one batch.
    pub fn render_settings(&self, scene_settings: &RenderSettings) -> RenderSettings {
        RenderSettings {
            width: self.width,
            height: self.height,
            spp: self.spp / self.chunks.max(1),
            max_depth: self.max_depth,
            rr_depth: self.rr_depth,
            seed: REF_SEED,
            integrator: Integrator::Path,
            ..*scene_settings
        }
    }
}

/// A reference image and what is known of it.
#[derive(Clone, Debug)]
pub struct Reference {
    /// Mean radiance.
    pub image: Image,
    /// Estimated RMSE of the reference against the exact image, from the
    /// spread of its batches (standard error of their mean, RMS over pixels
    /// and channels).
    pub noise_rmse: f64,
    /// Wall time of its render, seconds.
    pub render_s: f64,
    /// Whether it came from the cache.
    pub cached: bool,
    /// The cache key, 16 hex digits.
    pub key: String,
}

/// 64-bit FNV-1a, stable across Rust versions (unlike `DefaultHasher`).
#[derive(Clone, Copy, Debug)]
pub struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// Adds bytes, then their length, so concatenations cannot collide by
    /// moving a boundary.
    pub fn add(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        for b in (bytes.len() as u64).to_le_bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// The hash as 16 hex digits.
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// The files a scene depends on: those its TOML names and their neighbours.
pub fn scene_inputs(scene_file: &Path, scene_text: &str) -> Vec<PathBuf> {
    let dir = scene_file.parent().unwrap_or(Path::new("."));
    let mut named = Vec::new();
    if let Ok(value) = scene_text.parse::<toml::Table>() {
        collect_strings(&toml::Value::Table(value), &mut named);
    }
    let mut files = Vec::new();
    for s in named {
        let p = dir.join(&s);
        if !p.is_file() {
            continue;
        }
        files.push(p.clone());
        if let Some(Ok(entries)) = p.parent().map(std::fs::read_dir) {
            files.extend(entries.flatten().map(|e| e.path()).filter(|q| q.is_file()));
        }
    }
    files.sort();
    files.dedup();
    files
}

fn collect_strings(v: &toml::Value, out: &mut Vec<String>) {
    match v {
        toml::Value::String(s) => out.push(s.clone()),
        toml::Value::Array(a) => a.iter().for_each(|x| collect_strings(x, out)),
        toml::Value::Table(t) => t.values().for_each(|x| collect_strings(x, out)),
        _ => {}
    }
}

/// Files under the renderer crates that do not change the reference.
const NOT_RENDERER: [&str; 1] = ["crates/lucent-render/src/quality.rs"];

/// The renderer's source files, in path order (see the module docs).
pub fn renderer_inputs(root: &Path) -> Vec<PathBuf> {
    let mut files = vec![root.join("Cargo.lock"), root.join("xtask/src/tradeoff/reference.rs")];
    for c in RENDER_CRATES {
        let dir = root.join("crates").join(c);
        files.push(dir.join("Cargo.toml"));
        walk(&dir.join("src"), &mut files);
    }
    files.retain(|f| !NOT_RENDERER.iter().any(|n| f.ends_with(n)));
    files.sort();
    files
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// The cache key of a scene's reference, and a manifest of what went in.
pub fn cache_key(
    root: &Path,
    scene_file: &Path,
    scene_bytes: &[u8],
    settings: &RefSettings,
    renderer: &[PathBuf],
) -> Result<(String, String), String> {
    let mut h = Fnv::default();
    let mut manifest = String::new();
    h.add(scene_bytes);
    let _ = writeln!(manifest, "scene {}", scene_file.display());
    let text = String::from_utf8_lossy(scene_bytes);
    let rel = |p: &Path| p.strip_prefix(root).unwrap_or(p).display().to_string();
    for f in scene_inputs(scene_file, &text) {
        let bytes = std::fs::read(&f).map_err(|e| format!("{}: {e}", f.display()))?;
        h.add(rel(&f).as_bytes());
        h.add(&bytes);
        let _ = writeln!(manifest, "input {}", rel(&f));
    }
    h.add(settings.describe().as_bytes());
    let _ = writeln!(manifest, "settings {}", settings.describe());
    let mut code = Fnv::default();
    for f in renderer {
        let bytes = std::fs::read(f).map_err(|e| format!("{}: {e}", f.display()))?;
        code.add(rel(f).as_bytes());
        code.add(&bytes);
    }
    h.add(code.hex().as_bytes());
    let _ = writeln!(manifest, "renderer {} files, hash {}", renderer.len(), code.hex());
    Ok((h.hex(), manifest))
}

/// Renders the reference in `settings.chunks` batches and estimates its
/// noise from their spread. `progress` is told each finished batch.
pub fn render_reference(
    rs: &RenderScene,
    scene_settings: &RenderSettings,
    settings: &RefSettings,
    progress: &dyn Fn(u32, f64),
) -> (Image, f64, f64) {
    let start = Instant::now();
    let batch = settings.render_settings(scene_settings);
    let n = (settings.width * settings.height) as usize;
    let mut sum = vec![DVec3::ZERO; n];
    let mut sum_sq = vec![DVec3::ZERO; n];
    let chunks = settings.chunks.max(1);
    for i in 0..chunks {
        let mut film = Film::new(settings.width, settings.height);
        // Batches continue one sample sequence, so together they are one
        // render of `spp` samples.
        let first = i * batch.spp;
        render_samples(rs, &batch, &mut film, first..first + batch.spp, &|_| {});
        for ((s, q), p) in sum.iter_mut().zip(&mut sum_sq).zip(film.to_linear()) {
            let p = p.as_dvec3();
            *s += p;
            *q += p * p;
        }
        progress(i + 1, start.elapsed().as_secs_f64());
    }
    let k = f64::from(chunks);
    let pixels: Vec<Vec3> = sum.iter().map(|s| (*s / k).as_vec3()).collect();
    (
        Image {
            width: settings.width,
            height: settings.height,
            pixels,
        },
        batch_noise(&sum, &sum_sq, chunks),
        start.elapsed().as_secs_f64(),
    )
}

/// RMS standard error of the mean of `k` batches, from per-pixel sums and
/// sums of squares: per channel, the batches' sample variance over `k`.
pub fn batch_noise(sum: &[DVec3], sum_sq: &[DVec3], k: u32) -> f64 {
    if k < 2 || sum.is_empty() {
        return f64::NAN;
    }
    let k = f64::from(k);
    let mut total = 0.0;
    for (s, q) in sum.iter().zip(sum_sq) {
        let mean = *s / k;
        let var = ((*q - *s * mean) / (k - 1.0)).max(DVec3::ZERO);
        total += (var / k).element_sum();
    }
    (total / (3.0 * sum.len() as f64)).sqrt()
}

/// Reads a cached reference: `Ok(None)` when absent or unreadable.
pub fn load_cached(exr: &Path) -> Option<(Image, f64, f64)> {
    let bytes = std::fs::read(exr).ok()?;
    let (width, height, rgb) = lucent_assets::decode_exr(&bytes, exr).ok()?;
    let meta = std::fs::read_to_string(exr.with_extension("txt")).ok()?;
    let field = |name: &str| -> Option<f64> {
        meta.lines()
            .find_map(|l| l.strip_prefix(name).and_then(|v| v.trim().parse().ok()))
    };
    let pixels = rgb.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
    Some((
        Image { width, height, pixels },
        field("noise_rmse ")?,
        field("render_s ")?,
    ))
}

/// Writes the reference and its manifest into the cache.
pub fn store(exr: &Path, image: &Image, noise_rmse: f64, render_s: f64, manifest: &str) -> Result<(), String> {
    if let Some(dir) = exr.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let rgb: Vec<f32> = image.pixels.iter().flat_map(|p| p.to_array()).collect();
    lucent_assets::save_exr(exr, image.width, image.height, &rgb).map_err(|e| e.to_string())?;
    let text = format!("{manifest}noise_rmse {noise_rmse}\nrender_s {render_s}\n");
    let txt = exr.with_extension("txt");
    std::fs::write(&txt, text).map_err(|e| format!("{}: {e}", txt.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("lucent-tradeoff-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("meshes")).unwrap_or_else(|e| panic!("{e}"));
        dir
    }

    #[test]
    fn cache_key_follows_scene_assets_settings_and_code() {
        let dir = scratch("key");
        let scene = dir.join("s.toml");
        let text = "[[objects]]\nmesh = \"meshes/a.obj\"\n";
        std::fs::write(&scene, text).unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(dir.join("meshes/a.obj"), "v 0 0 0\n").unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(dir.join("meshes/a.mtl"), "newmtl m\n").unwrap_or_else(|e| panic!("{e}"));
        let code = dir.join("code.rs");
        std::fs::write(&code, "fn main() {}\n").unwrap_or_else(|e| panic!("{e}"));
        let settings = RefSettings {
            width: 8,
            height: 4,
            spp: 64,
            chunks: 4,
            max_depth: 16,
            rr_depth: 5,
        };
        let key = |text: &str, s: &RefSettings| {
            cache_key(&dir, &scene, text.as_bytes(), s, std::slice::from_ref(&code)).unwrap_or_else(|e| panic!("{e}"))
        };
        let (k0, manifest) = key(text, &settings);
        assert_eq!(k0.len(), 16);
        assert!(
            manifest.contains("input meshes/a.obj") && manifest.contains("input meshes/a.mtl"),
            "{manifest}"
        );
        // Same inputs, same key.
        assert_eq!(key(text, &settings).0, k0);
        // The scene file's bytes.
        assert_ne!(key(&format!("{text}# comment\n"), &settings).0, k0);
        // Settings.
        assert_ne!(key(text, &RefSettings { spp: 128, ..settings }).0, k0);
        assert_ne!(
            key(
                text,
                &RefSettings {
                    max_depth: 8,
                    ..settings
                }
            )
            .0,
            k0
        );
        // A named mesh, and a file beside it (the MTL).
        std::fs::write(dir.join("meshes/a.mtl"), "newmtl n\n").unwrap_or_else(|e| panic!("{e}"));
        let k1 = key(text, &settings).0;
        assert_ne!(k1, k0);
        std::fs::write(dir.join("meshes/a.obj"), "v 0 0 1\n").unwrap_or_else(|e| panic!("{e}"));
        let k2 = key(text, &settings).0;
        assert_ne!(k2, k1);
        // The renderer's code.
        std::fs::write(&code, "fn main() { }\n").unwrap_or_else(|e| panic!("{e}"));
        assert_ne!(key(text, &settings).0, k2);
        // The real renderer's files are found.
        let files = renderer_inputs(&crate::root());
        assert!(
            files.iter().any(|f| f.ends_with("crates/lucent-render/src/path.rs")),
            "{files:?}"
        );
        assert!(
            files.iter().any(|f| f.ends_with("xtask/src/tradeoff/reference.rs")),
            "{files:?}"
        );
        assert!(!files.iter().any(|f| f.ends_with("quality.rs")), "{files:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn batch_noise_is_the_standard_error_of_the_mean() {
        // One pixel, batches 1, 3 (all channels): mean 2, sample variance 2,
        // standard error of the mean sqrt(2 / 2) = 1.
        let sum = [DVec3::splat(4.0)];
        let sum_sq = [DVec3::splat(10.0)];
        assert!((batch_noise(&sum, &sum_sq, 2) - 1.0).abs() < 1e-12);
        assert!(batch_noise(&sum, &sum_sq, 1).is_nan());
    }

    #[test]
    fn cache_round_trip() {
        let dir = scratch("cache");
        let exr = dir.join("cache/s-0123.exr");
        let image = Image {
            width: 3,
            height: 2,
            pixels: (0..6).map(|i| Vec3::new(i as f32, 0.5, 2.0)).collect(),
        };
        assert!(load_cached(&exr).is_none());
        store(&exr, &image, 0.0125, 42.5, "scene s.toml\n").unwrap_or_else(|e| panic!("{e}"));
        let (back, noise, secs) = load_cached(&exr).unwrap_or_else(|| panic!("cached"));
        assert_eq!(back, image);
        assert_eq!((noise, secs), (0.0125, 42.5));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
